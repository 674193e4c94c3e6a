"""Shared fixtures: small seeded roads and a default sensor."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np
import pytest

from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor


def pose_on_lane(road: HighwayRoad, s: float, lane_id: int, shift: float = 0.0) -> tuple:
    """Vehicle pose ``(x, y, heading)`` at arc length ``s`` in a lane, ``shift`` [m] to the left."""
    p = road.reference.position(s, road.lane_offset(lane_id) + shift)
    return float(p[0]), float(p[1]), float(road.reference.heading_at(s))


@pytest.fixture(scope="session")
def straight_road() -> HighwayRoad:
    """A straight 4-lane, 1 km per-dash road."""
    return HighwayRoad({"curved": False, "length": 1000.0})


@pytest.fixture(scope="session")
def curvy_road() -> HighwayRoad:
    """The default generated road (4 lanes, curves R >= 500 m), per-dash."""
    return HighwayRoad({"seed": 3})


@pytest.fixture()
def sensor() -> LineSensor:
    """A noiseless default sensor."""
    return LineSensor()


@pytest.fixture()
def rng() -> np.random.Generator:
    """A seeded generator."""
    return np.random.default_rng(1234)
