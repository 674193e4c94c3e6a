"""Bridges crossing above a road: the markings of the road on top, as world segments.

A real lane sensor (and CarMaker's, paper §"Line Sensor Model") also reports the
markings of a road passing overhead. Such a bridge is placed by the road: a generated
:class:`~aldm_gym.roads.HighwayRoad` takes arc lengths in its config (``overpasses``),
a map road takes world places (:meth:`~aldm_gym.roads.polyline.PolylineRoad.with_overpasses`).
The road on the bridge is straight and level: two lanes, three continuous markings
(edges and centre line), at ``height`` above the road below, running ``margin`` metres
beyond the lower road's outermost marking on either side.
"""

from __future__ import annotations

import math

import numpy as np

from aldm_gym.types import FloatArray

BRIDGE_OFFSETS = (-3.5, 0.0, 3.5)
"""Lateral offsets of the bridge road's markings from its axis [m] (two 3.5 m lanes)."""

BRIDGE_MARGIN = 30.0
"""How far the bridge's markings run beyond the lower road's outer markings [m]."""


def overpass_lines(
    centre: FloatArray, heading: float, half_width: float, angle: float, height: float
) -> FloatArray:
    """The markings of one bridge as world segments.

    :param centre: world point (2,) where the bridge's axis crosses the lower road's
        middle [m].
    :param heading: the lower road's world heading there [rad].
    :param half_width: half the lower road's width, outermost markings [m].
    :param angle: angle between the bridge's road and the lower road [rad], in
        (0, pi/2]; pi/2 crosses at right angles.
    :param height: height of the bridge's markings above the lower road [m] (> 0).
    :return: ``(3, 5)`` rows ``(x0, y0, x1, y1, z)`` [m].
    """
    direction = heading + angle
    dx, dy = math.cos(direction), math.sin(direction)
    nx, ny = -dy, dx
    half = (half_width + BRIDGE_MARGIN) / math.sin(angle)
    out = np.empty((len(BRIDGE_OFFSETS), 5))
    for i, off in enumerate(BRIDGE_OFFSETS):
        cx = float(centre[0]) + off * nx
        cy = float(centre[1]) + off * ny
        out[i] = (cx - half * dx, cy - half * dy, cx + half * dx, cy + half * dy, height)
    return out
