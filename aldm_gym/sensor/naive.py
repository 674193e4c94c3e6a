"""CarMaker's default lane detection: the relevant line object on each side.

Paper §"Lane Detection Issues": CarMaker keeps one object per side, the one nearest
to the straight line through the vehicle's middle axis, and uses it as the whole
guiding line. On roads where a dashed marking is one object (``"editor"``) this
works; on roads where every dash is an object (``"per_dash"``) the left line is a
single ~6 m dash, and entering a right curve the chosen objects may even belong to
the wrong markings.
"""

from __future__ import annotations

import numpy as np

from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.sensor.trajectory import DEFAULT_LANE_WIDTH
from aldm_gym.types import FloatArray

ADJACENT_MIN_GAP = 2.0
"""Lateral gap [m] beyond the relevant line for a naive adjacent line (cf. ALDM step 6)."""


def _adjacent(frame: SensorFrame, left: bool) -> FloatArray:
    """The object nearest to the axis on a side that starts >= 2 m outside the relevant one.

    CarMaker itself reports only the relevant lines; this is the same naive rule
    applied once more outward, so that lane changes can be tried with it. Distances
    are to the car's middle axis (:meth:`SensorFrame.side_offsets`), as the sensor's
    own side assignment and relevant line.
    """
    lo, hi = (0, frame.n_left) if left else (frame.n_left, frame.n_lines)
    rel = frame.relevant_left if left else frame.relevant_right
    if rel < 0 or hi <= lo:
        return np.zeros((0, 2))
    offset = frame.side_offsets()[lo:hi]
    sign = 1.0 if left else -1.0
    outward = sign * offset >= sign * offset[rel] + ADJACENT_MIN_GAP
    if not outward.any():
        return np.zeros((0, 2))
    cand = np.flatnonzero(outward)
    best = int(cand[np.argmin(np.abs(offset[cand]))])
    return frame.line_points(lo + best)[:, :2]


def naive_detect(
    frame: SensorFrame, lane_width: float = DEFAULT_LANE_WIDTH, path_range: float | None = None
) -> LaneDetection:
    """CarMaker's default lane detection on a line-sensor frame.

    ``ego_left``/``ego_right`` are all points of the relevant object of the left/right
    side (the object whose first point is nearest to the car's middle axis; an
    object starting on the axis is on the left side, as the paper's rule says).
    ``left_adjacent``/``right_adjacent`` apply the same rule to the objects starting
    at least :data:`ADJACENT_MIN_GAP` further out. The trajectory is computed as for
    every detector (:func:`~aldm_gym.sensor.trajectory.driving_trajectory`).

    :param frame: a frame from :meth:`~aldm_gym.sensor.LineSensor.measure`.
    :param lane_width: lane width for the single-line trajectory [m].
    :param path_range: the trajectory fits each ego line up to this x (at least 4
        points) [m]; ``None``: the whole line.
    :raises TypeError: when ``frame`` is not a :class:`SensorFrame`.
    """
    if not isinstance(frame, SensorFrame):
        raise TypeError(f"naive_detect needs a SensorFrame, got {type(frame).__name__}")
    return LaneDetection.from_lines(
        ego_left=frame.relevant_line_points("left")[:, :2],
        ego_right=frame.relevant_line_points("right")[:, :2],
        left_adjacent=_adjacent(frame, True),
        right_adjacent=_adjacent(frame, False),
        source="naive",
        lane_width=lane_width,
        path_range=path_range,
    )
