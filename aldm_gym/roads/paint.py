"""The paint of a road near a point, as world polylines: what a renderer draws.

Both road sources answer the same question here (:func:`painted_pieces`): which pieces
of paint (one per dash of a broken line, one per continuous run) lie near a world
point, as polylines through the same vertices the line sensor samples. A renderer that
draws these pieces draws the markings where the sensor sees them:

* a generated :class:`~aldm_gym.roads.HighwayRoad` paints marking ``j`` at a constant
  offset from the reference line, dashes by the periodic pattern of
  :class:`~aldm_gym.roads.markings.Marking` along the marking's own arc length;
* a :class:`~aldm_gym.roads.polyline.PolylineRoad` (an OpenDRIVE map) paints the
  explicit intervals of :class:`~aldm_gym.roads.polyline.PolylineMarkings`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.roads.highway import HighwayRoad
from aldm_gym.roads.polyline import PolylineRoad
from aldm_gym.roads.position import world_point
from aldm_gym.types import FloatArray


@dataclass(frozen=True)
class PaintedPiece:
    """One painted piece of a marking: a dash, or a continuous run.

    :ivar xy: ``(N >= 2, 2)`` world vertices along the piece [m] (highway-env's world).
    :ivar marking: index of the marking in the road's marking list.
    :ivar type: CarMaker line type (1 continuous, 2 dashed, 3 dotted).
    :ivar colour: colour index (0 white, 1 yellow, 2 barrier, ...).
    :ivar width: painted width [m].
    :ivar height: height above the road [m] (> 0 for curbs and barriers).
    """

    xy: FloatArray
    marking: int
    type: int
    colour: int
    width: float
    height: float


def painted_pieces(road: Any, around: FloatArray, radius: float) -> list[PaintedPiece]:
    """The painted pieces of every marking of ``road`` that come within ``radius`` of ``around``.

    Pieces are cut where they leave the neighbourhood only coarsely (the whole run of
    reference samples, or map chunks, that passes near ``around`` is kept), so a caller
    drawing a window of half-diagonal ``radius`` sees every piece in it.

    :param road: a :class:`~aldm_gym.roads.HighwayRoad` or a
        :class:`~aldm_gym.roads.polyline.PolylineRoad` (e.g. an ``OpenDriveRoad``).
    :param around: world point ``(2,)`` [m].
    :param radius: distance from ``around`` [m] (> 0).
    :raises ValueError: naming the argument that is not a finite point or radius, or
        naming the road type that has no paint.
    """
    around = world_point("around", around)
    if not (math.isfinite(radius) and radius > 0.0):
        raise InputError(f"radius must be a finite number > 0, got {radius!r}")
    if isinstance(road, HighwayRoad):
        return _highway_pieces(road, around, float(radius))
    if isinstance(road, PolylineRoad):
        return _polyline_pieces(road, around, float(radius))
    raise InputError(f"painted_pieces: unsupported road type {type(road).__name__}")


def _cut(xy: FloatArray, u: FloatArray, a: FloatArray, b: FloatArray) -> list[FloatArray]:
    """The parts of polyline ``xy`` (arc length ``u``, increasing) with ``a[k] <= u <=
    b[k]``: interpolated ends and the vertices between, one array per interval (empty
    intervals, after clipping to ``u``'s range, are left out)."""
    a = np.maximum(a, u[0])
    b = np.minimum(b, u[-1])
    keep = b > a
    a, b = a[keep], b[keep]
    if len(a) == 0:
        return []
    i0 = np.searchsorted(u, a, side="right")
    i1 = np.searchsorted(u, b, side="left")
    pa = np.column_stack([np.interp(a, u, xy[:, 0]), np.interp(a, u, xy[:, 1])])
    pb = np.column_stack([np.interp(b, u, xy[:, 0]), np.interp(b, u, xy[:, 1])])
    return [np.vstack([pa[k], xy[i0[k] : i1[k]], pb[k]]) for k in range(len(a))]


def _highway_pieces(road: HighwayRoad, around: FloatArray, radius: float) -> list[PaintedPiece]:
    ref = road.reference
    offsets = np.array([m.offset for m in road.markings])
    reach = radius + float(np.max(np.abs(offsets)))
    near = np.flatnonzero(np.hypot(ref.xy[:, 0] - around[0], ref.xy[:, 1] - around[1]) <= reach)
    if len(near) == 0:
        return []
    lo, hi = int(near[0]), int(near[-1]) + 1
    if hi - lo < 2:
        lo, hi = max(lo - 1, 0), min(hi + 1, len(ref.s))
    s = ref.s[lo:hi]
    pieces = []
    for j, m in enumerate(road.markings):
        # The vertices the sensor samples (reference table offset along its normal) and
        # the arc length along the marking there, which the dash pattern runs on.
        xy = ref.xy[lo:hi] + m.offset * ref.normal[lo:hi]
        u = np.asarray(road.marking_arc_length(j, s), dtype=np.float64)
        if m.broken:
            k0 = math.floor((u[0] - m.phase) / m.period)
            k1 = math.ceil((u[-1] - m.phase) / m.period)
            a = m.phase + m.period * np.arange(k0, k1 + 1, dtype=np.float64)
            b = a + m.dash_length
        else:
            a, b = u[:1], u[-1:]
        pieces += [
            PaintedPiece(piece, j, int(m.type), int(m.colour), m.width, m.height)
            for piece in _cut(xy, u, a, b)
        ]
    return pieces


def _polyline_pieces(road: PolylineRoad, around: FloatArray, radius: float) -> list[PaintedPiece]:
    mk = road.markings
    rows, lo, hi = mk.near(around, radius)
    pieces = []
    for j, a_idx, b_idx in zip(rows.tolist(), lo.tolist(), hi.tolist(), strict=True):
        if b_idx - a_idx < 2:
            continue
        curve = mk.curves[j]
        u0, u1 = float(mk.u[a_idx]), float(mk.u[b_idx - 1])
        paint = mk.paint[mk.paint_start[j] : mk.paint_start[j + 1]]
        # Only the intervals overlapping the near vertex range.
        keep = (paint[:, 1] > u0) & (paint[:, 0] < u1)
        attrs = (j, int(curve.type), int(curve.colour), float(curve.width), float(curve.height))
        pieces += [
            PaintedPiece(piece, *attrs)
            for piece in _cut(mk.xy[a_idx:b_idx], mk.u[a_idx:b_idx], paint[keep, 0], paint[keep, 1])
        ]
    return pieces
