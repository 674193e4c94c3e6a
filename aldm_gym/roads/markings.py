"""Painted road markings: type, colour, width, height and dash pattern.

Marking types follow CarMaker's line sensor codes (paper §"Line Sensor Model"):
1 continuous single line, 2 dashed, 3 dotted.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from aldm_gym.types import FloatArray

MARKING_MODELS = ("per_dash", "editor")
"""How painted markings become line objects for the sensor: ``"per_dash"`` (every dash
its own object, as on roads converted from OpenDRIVE or measurements) or ``"editor"``
(one object per marking line, as CarMaker's road editor draws it)."""


class MarkingType(IntEnum):
    """CarMaker line-sensor line type."""

    CONTINUOUS = 1
    DASHED = 2
    DOTTED = 3


class MarkingRole(IntEnum):
    """What a marking is on the road (ground truth; a sensor never reports it)."""

    EDGE_LEFT = 0
    LANE_LINE = 1
    EDGE_RIGHT = 2
    GUARD_RAIL = 3


@dataclass(frozen=True)
class Marking:
    """One longitudinal marking (or barrier) running along the road.

    :ivar index: position in the road's marking list, left to right.
    :ivar offset: left offset from the reference line [m].
    :ivar type: CarMaker line type (1 continuous, 2 dashed, 3 dotted).
    :ivar role: edge line, lane line or guard rail.
    :ivar colour: user-defined colour index (0 white paint, 1 yellow, 2 barrier).
    :ivar width: painted width [m].
    :ivar height: height above the road [m] (0 for paint, > 0 for barriers).
    :ivar dash_length: painted length of one dash along the marking [m].
    :ivar gap_length: unpainted gap between dashes [m].
    :ivar phase: arc length along the marking where the first dash starts [m].
    """

    index: int
    offset: float
    type: MarkingType
    role: MarkingRole
    colour: int = 0
    width: float = 0.15
    height: float = 0.0
    dash_length: float = 6.0
    gap_length: float = 12.0
    phase: float = 0.0

    @property
    def broken(self) -> bool:
        """Whether the marking is painted in pieces (dashed or dotted)."""
        return self.type != MarkingType.CONTINUOUS

    @property
    def period(self) -> float:
        """Dash plus gap [m]."""
        return self.dash_length + self.gap_length

    def piece_index(self, u: FloatArray) -> FloatArray:
        """Index of the dash that arc length ``u`` [m] falls into; 0 for continuous lines."""
        u = np.asarray(u, dtype=np.float64)
        if not self.broken:
            return np.zeros_like(u)
        return np.floor((u - self.phase) / self.period)

    def painted(self, u: FloatArray) -> np.ndarray:
        """Whether arc length ``u`` [m] along the marking lies on paint."""
        u = np.asarray(u, dtype=np.float64)
        if not self.broken:
            return np.ones(u.shape, dtype=bool)
        return np.mod(u - self.phase, self.period) < self.dash_length


class MarkingChain(tuple[int, ...]):
    """The markings that bound one border of a lane one after another ahead of a
    position (a map's border changes marking, e.g. where a broken line becomes solid, or
    where a lane opens beside it), and where each takes over.

    A tuple of marking indices in the order the lane meets them, so it compares, hashes
    and iterates as one. ``starts`` is ``(len, 2)``: the world point [m] (highway-env's
    frame) where each marking starts to bound the lane; row 0 is the position the chain
    was asked from. A marking index may be there before its start, bounding another lane
    (the centre line of a 2+1 road runs on beside the lane that opens between it and
    the lane it bounded): which marking a line is at a given distance ahead follows
    from the starts, not from which markings are there
    (:func:`aldm_gym.sensor.ground_truth.boundary_y`).
    """

    starts: FloatArray

    def __new__(cls, marks: tuple[int, ...] | list[int], starts: FloatArray) -> MarkingChain:
        """:param marks: marking indices in travel order (at least two).
        :param starts: ``(len(marks), 2)`` world points [m] where each takes over."""
        chain = super().__new__(cls, (int(m) for m in marks))
        pts = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
        if len(pts) != len(chain):
            raise ValueError(f"{len(chain)} markings but {len(pts)} start points")
        chain.starts = pts
        return chain

    def __reduce__(self) -> tuple[type, tuple[tuple[int, ...], FloatArray]]:
        """Pickles with its starts."""
        return (MarkingChain, (tuple(self), self.starts))

    def switch_x(self, origin: FloatArray, yaw: float) -> FloatArray:
        """Sensor x [m] (ISO 8855, from ``origin`` [m] facing ``yaw`` [rad], highway-env's
        world frame) of the start of every marking after the first: ``(len - 1,)``."""
        d = self.starts[1:] - np.asarray(origin, dtype=np.float64)[:2]
        return d[:, 0] * math.cos(yaw) + d[:, 1] * math.sin(yaw)
