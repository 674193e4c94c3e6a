"""Roads: painted-marking geometry and ground truth, generated (HighwayRoad) or read
from an OpenDRIVE map (OpenDriveRoad); both are a :class:`Road`, the protocol the rest
of the package asks (:mod:`aldm_gym.roads.protocol`)."""

from __future__ import annotations

import aldm_gym._numba  # noqa: F401  (numba cache guards, before any kernel is compiled)
from aldm_gym.roads.highway import (
    EDGE,
    MARKING_MODELS,
    MIN_RADIUS_BY_SPEED,
    HighwayRoad,
    RoadConfig,
    curvature_profile,
    generate_highway,
)
from aldm_gym.roads.lane import ReferenceLane
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.roads.markings import Marking, MarkingRole, MarkingType
from aldm_gym.roads.opendrive.parse import SHIPPED_MAPS, shipped_map
from aldm_gym.roads.polyline import MarkingCurve, PolylineMarkings, PolylineRoad
from aldm_gym.roads.position import LanePosition, Pose
from aldm_gym.roads.protocol import MarkedRoad, Road
from aldm_gym.roads.reference_line import ReferenceLine, Segment

__all__ = [
    "EDGE",
    "MARKING_MODELS",
    "MIN_RADIUS_BY_SPEED",
    "SHIPPED_MAPS",
    "HighwayRoad",
    "LanePosition",
    "MarkedRoad",
    "Marking",
    "MarkingCurve",
    "MarkingRole",
    "MarkingType",
    "OpenDriveRoad",
    "PolylineMarkings",
    "PolylineRoad",
    "Pose",
    "ReferenceLane",
    "ReferenceLine",
    "Road",
    "RoadConfig",
    "Segment",
    "curvature_profile",
    "generate_highway",
    "shipped_map",
]
