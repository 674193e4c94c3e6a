"""The Road protocol: both road kinds answer what the rest of the package asks, and no
code outside ``aldm_gym.roads`` asks which kind of road it holds."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

import aldm_gym
from aldm_gym.errors import OffRoadError
from aldm_gym.roads import (
    HighwayRoad,
    MarkedRoad,
    MarkingCurve,
    OpenDriveRoad,
    PolylineRoad,
    Road,
    shipped_map,
)

PACKAGE = Path(aldm_gym.__file__).parent
ROAD_KINDS = {"HighwayRoad", "OpenDriveRoad", "PolylineRoad"}


@pytest.fixture(scope="module")
def roads() -> dict[str, Road]:
    return {
        "generated": HighwayRoad({"seed": 3, "length": 2000.0}),
        "map": OpenDriveRoad.from_file(shipped_map("motorway")),
    }


def test_both_road_kinds_are_roads_and_a_polyline_road_is_only_marked(roads: dict) -> None:
    for road in roads.values():
        assert isinstance(road, Road) and isinstance(road, MarkedRoad)
    xy = np.column_stack([np.arange(0.0, 100.0), np.zeros(100)])
    poly = PolylineRoad([MarkingCurve(xy, np.array([[0.0, 99.0]]))])
    assert isinstance(poly, MarkedRoad) and not isinstance(poly, Road)


@pytest.mark.parametrize("kind", ["generated", "map"])
def test_lateral_offsets_follow_the_lane_positions(roads: dict, kind: str) -> None:
    road = roads[kind]
    pose = road.sample_poses(1, np.random.default_rng(0), max_shift=0.0, heading_jitter=0.0)[0]
    pos = road.lane_position(pose.pose[:2])
    h = pose.pose[2]
    left = (math.sin(h), -math.cos(h))  # the driver's left in highway-env's world
    xy = np.array([[pose.pose[0] + d * left[0], pose.pose[1] + d * left[1]] for d in (0.0, 1.0)])
    y = road.lateral_offsets(xy, pos)
    np.testing.assert_allclose(y, [pos.offset, pos.offset + 1.0], atol=1e-6)
    assert not road.ends_within(pos, 10.0)
    assert road.ends_within(pos, 1e7)


def test_off_the_map_is_inf_laterally_and_an_off_road_error(roads: dict) -> None:
    road = roads["map"]
    pose = road.sample_poses(1, np.random.default_rng(1))[0]
    pos = road.lane_position(pose.pose[:2])
    assert road.lateral_offsets(np.array([[1e6, 1e6]]), pos)[0] == math.inf
    with pytest.raises(OffRoadError):
        road.lane_position((1e6, 1e6))


def test_only_maps_have_lanes_that_end(roads: dict) -> None:
    generated, on_map = roads["generated"], roads["map"]
    pos = generated.lane_position(generated.sample_poses(1, np.random.default_rng(2))[0].pose[:2])
    assert generated.lane_ends_in(pos) is None
    ends = [
        on_map.lane_ends_in(on_map.lane_position(p.pose[:2]))
        for p in on_map.sample_poses(40, np.random.default_rng(3))
    ]
    assert all(e is not None and e > 0.0 for e in ends)
    assert any(math.isinf(e) for e in ends) and any(math.isfinite(e) for e in ends)


def _isinstance_on_road_kinds(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance":
            names = {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)}
            names |= {n.attr for n in ast.walk(node.args[1]) if isinstance(n, ast.Attribute)}
            if names & ROAD_KINDS:
                found.append(f"{path.relative_to(PACKAGE.parent)}:{node.lineno}")
    return found


def test_no_code_outside_the_roads_package_asks_for_a_road_kind() -> None:
    offenders = [
        hit
        for path in sorted(PACKAGE.rglob("*.py"))
        if "roads" not in path.relative_to(PACKAGE).parts[:1]
        for hit in _isinstance_on_road_kinds(path)
    ]
    assert offenders == []
