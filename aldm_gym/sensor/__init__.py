"""Line sensor emulation and lane detection (naive CarMaker default, ALDM, ground truth).

Data flow: road → :class:`LineSensor` → :class:`SensorFrame` → detector →
:class:`LaneDetection`. All coordinates in the ISO 8855 sensor frame (x forward,
y left, z up) [m].
"""

from __future__ import annotations

import aldm_gym._numba  # noqa: F401  (numba cache guards, before any kernel is compiled)
from aldm_gym.sensor.aldm import ALDMParams, detect_lanes
from aldm_gym.sensor.frame import LineObject, SensorFrame, SideLines
from aldm_gym.sensor.ground_truth import (
    LineScore,
    ground_truth_detect,
    line_markings,
    score_detection,
    score_line,
)
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection, driving_trajectory
from aldm_gym.sensor.line_sensor import LineSensor, LineSensorConfig
from aldm_gym.sensor.naive import naive_detect

__all__ = [
    "LINE_NAMES",
    "ALDMParams",
    "LaneDetection",
    "LineObject",
    "LineScore",
    "LineSensor",
    "LineSensorConfig",
    "SensorFrame",
    "SideLines",
    "detect_lanes",
    "driving_trajectory",
    "ground_truth_detect",
    "line_markings",
    "naive_detect",
    "score_detection",
    "score_line",
]
