"""Plain ``StraightLane`` geometry as Python floats, cached per lane.

The network's closest-lane search, the neighbour tables and the vehicles' lane
following take a float-arithmetic fast path on lanes that use ``StraightLane``'s own
geometry; every other lane class goes through its own methods. The fast path spells
``StraightLane.local_coordinates``'s ``np.dot`` as ``a*b + c*d``, which is numpy's
result only where the BLAS kernel does not fuse it
(:data:`~aldm_gym.envs.traffic.scalar.PLAIN_DOT_MATCHES_NUMPY`); elsewhere no lane
takes it.
"""

from __future__ import annotations

import weakref

from highway_env.road.lane import AbstractLane, StraightLane

from aldm_gym.envs.traffic.scalar import PLAIN_DOT_MATCHES_NUMPY

__all__ = ["StraightGeometry", "is_plain_straight", "straight_geometry"]

StraightGeometry = tuple[float, float, float, float, float, float, float, float]
"""``(start_x, start_y, dir_x, dir_y, lat_x, lat_y, length, heading)`` of a straight lane
(positions and length [m], heading [rad])."""

_STRAIGHT_GEOMETRY: dict[int, tuple[weakref.ref[AbstractLane], StraightGeometry]] = {}
"""Geometry of plain StraightLanes by ``id``; entries leave when their lane is collected
(a WeakKeyDictionary lookup costs ~3x more, and this is on the per-vehicle hot path)."""


def is_plain_straight(lane: AbstractLane) -> bool:
    """Whether ``lane`` uses ``StraightLane``'s own geometry (no overridden methods) and
    the float fast path gives its results here (module docstring)."""
    return PLAIN_DOT_MATCHES_NUMPY and type(lane) is StraightLane


def straight_geometry(lane: AbstractLane) -> StraightGeometry | None:
    """The :data:`StraightGeometry` of a plain StraightLane.

    None for any other lane class (including StraightLane subclasses, which may
    override the geometry), and for every lane where the fast path would not give
    numpy's results (module docstring).
    """
    if not is_plain_straight(lane):
        return None
    key = id(lane)
    entry = _STRAIGHT_GEOMETRY.get(key)
    if entry is not None and entry[0]() is lane:
        return entry[1]
    assert isinstance(lane, StraightLane)
    geometry = (
        float(lane.start[0]),
        float(lane.start[1]),
        float(lane.direction[0]),
        float(lane.direction[1]),
        float(lane.direction_lateral[0]),
        float(lane.direction_lateral[1]),
        float(lane.length),
        float(lane.heading),
    )

    def _forget(ref: weakref.ref[AbstractLane], key: int = key) -> None:
        current = _STRAIGHT_GEOMETRY.get(key)
        if current is not None and current[0] is ref:
            del _STRAIGHT_GEOMETRY[key]

    _STRAIGHT_GEOMETRY[key] = (weakref.ref(lane, _forget), geometry)
    return geometry
