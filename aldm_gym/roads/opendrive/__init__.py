"""OpenDRIVE (.xodr) reader: parse, reference-line geometry, lanes and painted markings.

``OpenDriveMap.from_file(path)`` gives the map's marking lines (world polylines with
their painted intervals, chained across lane sections and linked roads) and its lanes.
"""

from __future__ import annotations

from aldm_gym.roads.opendrive.map import DEFAULT_SAMPLE_STEP, LaneKey, LaneRecord, OpenDriveMap
from aldm_gym.roads.opendrive.marks import DEFAULT_BROKEN_PATTERN, MarkingLine
from aldm_gym.roads.opendrive.parse import (
    SHIPPED_MAPS,
    OpenDriveFile,
    parse_file,
    shipped_map,
)
from aldm_gym.roads.opendrive.plan_view import PlanView

__all__ = [
    "DEFAULT_BROKEN_PATTERN",
    "DEFAULT_SAMPLE_STEP",
    "SHIPPED_MAPS",
    "LaneKey",
    "LaneRecord",
    "MarkingLine",
    "OpenDriveFile",
    "OpenDriveMap",
    "PlanView",
    "parse_file",
    "shipped_map",
]
