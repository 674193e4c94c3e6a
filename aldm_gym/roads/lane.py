"""A highway-env lane that follows a lateral offset of a :class:`ReferenceLine`."""

from __future__ import annotations

import math

import numpy as np
from highway_env.road.lane import AbstractLane, LineType

from aldm_gym.roads.reference_line import ReferenceLine
from aldm_gym.types import FloatArray


class ReferenceLane(AbstractLane):
    """A lane of constant width centred at a fixed left offset of a reference line.

    It implements highway-env's lane interface (``position(s, r)``,
    ``local_coordinates(pos) -> (s, r)``, ``heading_at(s)``, ``width_at(s)``) so
    highway-env's vehicles, IDM/MOBIL and rendering use it unchanged.

    Conventions (highway-env's): the longitudinal coordinate ``s`` is the
    *reference line's* arc length [m] (shared by all lanes of the road, so lanes
    can be compared by ``s``); the lateral coordinate ``r`` is positive to the
    driver's right [m] (towards higher lane ids), as for highway-env's
    ``StraightLane``.

    :param reference: the road's reference line.
    :param offset: left offset of the lane centre from the reference line [m].
    :param width: lane width [m].
    :param line_types: highway-env line types (left, right), for rendering.
    :param speed_limit: speed limit [m/s].
    """

    def __init__(
        self,
        reference: ReferenceLine,
        offset: float,
        width: float,
        line_types: tuple[int, int] | None = None,
        speed_limit: float = 36.0,
    ) -> None:
        self.reference = reference
        self.offset = float(offset)
        self.width = float(width)
        self.length = reference.length
        self.line_types = list(line_types or (LineType.STRIPED, LineType.STRIPED))
        self.forbidden = False
        self.priority = 0
        self.speed_limit = speed_limit

    def position(self, longitudinal: float, lateral: float) -> np.ndarray:
        """World position of lane coordinates ``(s [m], r [m], r positive right)``."""
        return self.reference.position(longitudinal, self.offset - lateral)

    def heading_at(self, longitudinal: float) -> float:
        """World heading at ``s`` [rad]."""
        # The scalar path of ReferenceLine.heading_at without its numpy wrapping
        # (IDM steering asks for one heading per vehicle and step).
        if type(longitudinal) is float and math.isfinite(longitudinal):
            return self.reference.pose_at(longitudinal)[2]
        return float(self.reference.heading_at(longitudinal))

    def width_at(self, longitudinal: float) -> float:
        """Lane width [m] (constant)."""
        return self.width

    def local_coordinates(self, position: np.ndarray) -> tuple[float, float]:
        """Lane coordinates ``(s, r)`` [m] of a world position (r positive right)."""
        s, d = self.reference.project(position)
        return s, self.offset - d

    def local_coordinates_many(self, positions: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Vectorised :meth:`local_coordinates` for ``(N, 2)`` positions."""
        s, d = self.reference.project_many(positions)
        return s, self.offset - d

    def to_config(self) -> dict:
        """A description of the lane (the reference line itself is not serialised)."""
        return {
            "class_path": f"{type(self).__module__}.{type(self).__name__}",
            "config": {"offset": self.offset, "width": self.width, "length": self.length},
        }
