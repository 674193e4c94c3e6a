"""OpenDRIVE (.xodr) reader: parse, reference-line geometry, lanes and painted markings."""

from __future__ import annotations

from aldm_gym.roads.opendrive.geometry import PlanView
from aldm_gym.roads.opendrive.parse import OpenDriveFile, parse_file

__all__ = ["OpenDriveFile", "PlanView", "parse_file"]
