"""Bridges read from OpenDRIVE maps: crossings, levels, overpass paint, the sensor's view."""

from __future__ import annotations

import copy
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.roads.opendrive import DEFAULT_BROKEN_PATTERN, OpenDriveMap
from aldm_gym.roads.opendrive.bridges import BRIDGE_CLEARANCE, Crossing, levels
from aldm_gym.sensor import LineSensor, detect_lanes, score_detection
from aldm_gym.sensor.conditions import overpass_rows

xodr = pytest.importorskip("scenariogeneration.xodr")

ANGLE = math.radians(60.0)
"""Angle between the bridge's road and the motorway."""


def _write(
    path: Path,
    bridge_z: tuple[float, float] = (7.0, 0.0),
    bridge_length: float = 120.0,
    mark: str = "solid",
    sections: int = 1,
) -> Path:
    """A 2 km three-lane one-way road (id 1, along +x from the origin, lanes to the
    right, level at 0 m) and an unlinked two-lane road (id 2) crossing it at 60° through
    the middle of its lanes at x = 500 m, at height ``a + b s`` (``bridge_z = (a, b)``),
    in ``sections`` equal lane sections."""
    road = xodr.create_road([xodr.Line(2000)], id=1, left_lanes=0, right_lanes=3, lane_width=3.75)
    road.planview.set_start_point(0.0, 0.0, 0.0)
    solid = xodr.RoadMark(xodr.RoadMarkType.solid, 0.15)
    centre_mark = xodr.RoadMark(xodr.RoadMarkType.broken, 0.15) if mark == "broken" else solid
    lanes = xodr.Lanes()
    before: list = []
    for k in range(sections):
        centre = xodr.Lane(a=0.0)
        centre.add_roadmark(centre_mark)
        section = xodr.LaneSection(k * bridge_length / sections, centre)
        sides = []
        for add in (section.add_left_lane, section.add_right_lane):
            side = xodr.Lane(xodr.LaneType.driving, a=3.5)
            side.add_roadmark(solid)
            add(side)
            sides.append(side)
        linker = xodr.LaneLinker()
        for old, new in zip(before, sides, strict=False):
            linker.add_link(old, new)
        lanes.add_lanesection(section, linker if before else None)
        before = sides
    plan = xodr.PlanView()
    plan.add_geometry(xodr.Line(bridge_length))
    bridge = xodr.Road(2, plan, lanes)
    half = 0.5 * bridge_length
    plan.set_start_point(500.0 - half * math.cos(ANGLE), -5.625 + half * math.sin(ANGLE), -ANGLE)
    bridge.add_elevation(0.0, bridge_z[0], bridge_z[1], 0.0, 0.0)
    odr = xodr.OpenDrive("bridge")
    odr.add_road(road)
    odr.add_road(bridge)
    odr.adjust_roads_and_lanes()
    odr.write_xml(str(path))
    return path


@pytest.fixture(scope="module")
def maps(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same two roads as a bridge, a climbing bridge, a flat crossing, and a
    level difference just under the clearance."""
    d = tmp_path_factory.mktemp("bridges")
    return {
        "bridge": _write(d / "bridge.xodr"),
        "climbing": _write(d / "climbing.xodr", bridge_z=(6.0, 0.05)),
        "flat": _write(d / "flat.xodr", bridge_z=(0.0, 0.0)),
        "low": _write(d / "low.xodr", bridge_z=(BRIDGE_CLEARANCE - 0.01, 0.0)),
        "broken": _write(d / "broken.xodr", mark="broken"),
        "sections": _write(d / "sections.xodr", sections=3),
    }


def test_elevation_is_read(maps: dict[str, Path]) -> None:
    odr = OpenDriveMap.from_file(maps["climbing"])
    (record,) = odr.roads["2"].elevation
    assert (record.s, record.a, record.b, record.c, record.d) == (0.0, 6.0, 0.05, 0.0, 0.0)
    assert odr.roads["1"].elevation == ()


def test_a_bridge_is_found_where_the_reference_lines_cross(maps: dict[str, Path]) -> None:
    odr = OpenDriveMap.from_file(maps["climbing"])
    (c,) = odr.bridges["2"]
    # The bridge passes (500, -5.625) at its middle (s = 60 m) heading -60°; it meets
    # the motorway's reference line (y = 0) 5.625 / sin 60° m earlier.
    s_upper = 60.0 - 5.625 / math.sin(ANGLE)
    assert c.upper == "2" and c.lower == "1"
    assert c.s_upper == pytest.approx(s_upper, abs=1e-9)
    assert c.s_lower == pytest.approx(500.0 - 5.625 / math.tan(ANGLE), abs=1e-9)
    assert c.z_upper == pytest.approx(6.0 + 0.05 * s_upper, abs=1e-12)
    assert c.z_lower == 0.0
    assert odr.hidden == frozenset()


def test_the_bridge_is_not_driven_and_its_paint_is_overpass(maps: dict[str, Path]) -> None:
    odr = OpenDriveMap.from_file(maps["bridge"])
    flat = OpenDriveMap.from_file(maps["flat"])
    assert {key[0] for key in odr.lanes} == {"1"}
    assert {key[0] for key in flat.lanes} == {"1", "2"}
    assert all(m.road_ids == ("1",) for m in odr.markings)
    assert len(flat.markings) == len(odr.markings) + 3
    assert flat.overpass_lines.shape == (0, 5)
    # Three continuous lines of 120 m in segments of at most 2 m, all at 7 m.
    lines = odr.overpass_lines
    assert lines.shape == (3 * 60, 5)
    np.testing.assert_array_equal(lines[:, 4], 7.0)
    assert np.hypot(lines[:, 2] - lines[:, 0], lines[:, 3] - lines[:, 1]).max() <= 2.0 + 1e-9
    # Each line's segments join end to start.
    for k in range(3):
        seg = lines[60 * k : 60 * (k + 1)]
        np.testing.assert_array_equal(seg[1:, :2], seg[:-1, 2:4])
    # A level difference under the clearance is a flat crossing.
    assert OpenDriveMap.from_file(maps["low"]).bridges == {}


def test_a_line_across_lane_sections_is_one_stretch(maps: dict[str, Path]) -> None:
    """Three lane sections on the bridge: still three lines of 120 m, one object each."""
    one = OpenDriveMap.from_file(maps["bridge"]).overpass_lines
    three = OpenDriveMap.from_file(maps["sections"]).overpass_lines
    joined = np.all(three[1:, :2] == three[:-1, 2:4], axis=1)
    assert np.count_nonzero(~joined) + 1 == 3
    np.testing.assert_allclose(three, one, atol=1e-9)
    road = OpenDriveRoad.from_file(maps["sections"])
    frame = LineSensor().measure(road, road.lane_pose("1", -2, 400.0))
    assert np.count_nonzero(frame.line_marking == -1) == 3


def test_a_broken_line_on_the_bridge_is_dashes(maps: dict[str, Path]) -> None:
    odr = OpenDriveMap.from_file(maps["broken"])
    lines = odr.overpass_lines
    joined = np.all(lines[1:, :2] == lines[:-1, 2:4], axis=1)
    runs = np.split(lines, np.flatnonzero(~joined) + 1)
    lengths = [np.hypot(r[:, 2] - r[:, 0], r[:, 3] - r[:, 1]).sum() for r in runs]
    # The broken centre line in dashes of the reader's default pattern (the last one
    # may be cut by the road's end), the two solid edges whole.
    dash = DEFAULT_BROKEN_PATTERN[0]
    assert sorted(lengths)[-2:] == pytest.approx([120.0, 120.0])
    dashes = sorted(lengths)[:-2]
    assert len(dashes) >= 5
    assert all(0.0 < d <= dash + 1e-9 for d in dashes)
    assert sum(d == pytest.approx(dash) for d in dashes) >= len(dashes) - 2


def test_a_climbing_bridge_keeps_its_height_over_the_road_below(maps: dict[str, Path]) -> None:
    odr = OpenDriveMap.from_file(maps["climbing"])
    lines = odr.overpass_lines
    mid = 0.5 * (lines[:, :2] + lines[:, 2:4])
    # Height of the segment's middle over the motorway (level at 0): 6 + 0.05 s, with s
    # the bridge's reference arc length of the middle (its projection on the axis).
    start = np.array([500.0 - 60.0 * math.cos(ANGLE), -5.625 + 60.0 * math.sin(ANGLE)])
    axis = np.array([math.cos(ANGLE), -math.sin(ANGLE)])
    s = (mid - start) @ axis
    np.testing.assert_allclose(lines[:, 4], 6.0 + 0.05 * s, atol=1e-9)


def test_levels_drive_the_larger_network() -> None:
    lengths = {"a": 1000.0, "b": 200.0, "c": 300.0, "d": 50.0}
    linked = {frozenset(("b", "c"))}

    def cross(upper: str, lower: str) -> Crossing:
        return Crossing(upper, 1.0, 7.0, lower, 2.0, 0.0)

    # b over a: a's network (1000 m) beats b + c (500 m): b is a bridge.
    bridges, hidden = levels(lengths, linked, [cross("b", "a")])
    assert set(bridges) == {"b"} and hidden == frozenset()
    # a over d: d is hidden under the larger a, and a stays driven.
    bridges, hidden = levels(lengths, linked, [cross("a", "d")])
    assert bridges == {} and hidden == frozenset({"d"})
    # A tie drives the lower road.
    bridges, hidden = levels({"a": 10.0, "b": 10.0}, set(), [cross("a", "b")])
    assert set(bridges) == {"a"} and hidden == frozenset()


def test_levels_take_a_road_linked_to_itself() -> None:
    """A ring (a road that is its own predecessor and successor, as esmini's
    ``circle_300m.xodr``) is one network with the roads linked to it."""
    lengths = {"ring": 300.0, "spur": 100.0, "far": 1000.0}
    linked = {frozenset(("ring",)), frozenset(("ring", "spur"))}
    over = Crossing("far", 10.0, 7.0, "spur", 20.0, 0.0)
    bridges, hidden = levels(lengths, linked, [over])
    assert bridges == {} and hidden == frozenset({"spur"})
    over = Crossing("spur", 20.0, 7.0, "far", 10.0, 0.0)
    bridges, hidden = levels({"ring": 900.0, "spur": 200.0, "far": 1000.0}, linked, [over])
    # ring + spur (1100 m) outrank far: the spur over it is driven, far hidden
    assert bridges == {} and hidden == frozenset({"far"})


def test_levels_within_one_network_drive_the_larger_road() -> None:
    """An interchange: ramps join the motorway (m1, m2, up on its bridge) and the small
    road (s) under it, so all are one network; the motorway's lane-metres win."""
    lengths = {"s": 400.0, "m1": 1000.0, "m2": 1000.0, "ramp": 200.0}
    linked = {frozenset(("m1", "m2")), frozenset(("ramp", "s")), frozenset(("ramp", "m2"))}
    weights = {"s": 2 * 400.0, "m1": 3 * 1000.0, "m2": 3 * 1000.0, "ramp": 200.0}
    over = Crossing("m1", 900.0, 7.0, "s", 200.0, 0.0)
    bridges, hidden = levels(lengths, linked, [over], weights)
    assert bridges == {} and hidden == frozenset({"s"})


def test_a_road_under_only_a_bridge_is_driven() -> None:
    """A bridge spans the motorway and a small road beside it: the small road is not
    under anything driven, so it is driven, and the bridge is seen from both."""
    lengths = {"m": 2000.0, "b": 160.0, "r3": 80.0, "r4": 80.0, "side": 200.0}
    linked = {frozenset(("b", "r3")), frozenset(("b", "r4"))}
    over_m = Crossing("b", 70.0, 7.0, "m", 500.0, 0.0)
    over_side = Crossing("b", 110.0, 7.0, "side", 100.0, 0.0)
    bridges, hidden = levels(lengths, linked, [over_m, over_side])
    assert hidden == frozenset()
    assert bridges == {"b": (over_m, over_side)}


def test_merged_rows_follow_the_painted_line() -> None:
    """A chain of short segments is one row; its y is the line's, its z its segment's."""
    xs = np.arange(5.0, 60.0, 2.0)
    # A straight line y = 10 - 0.5 x from x = 0 to 40 in 1 m steps (sensor at the
    # origin, heading 0; world y is mirrored: the sensor's y is minus world y).
    x = np.arange(0.0, 41.0)
    world_y = -(10.0 - 0.5 * x)
    z = np.where(x[:-1] < 20.0, 6.0, 6.1)
    chain = np.stack([x[:-1], world_y[:-1], x[1:], world_y[1:], z], axis=1)
    lone = np.array([[30.0, 5.0, 50.0, 5.0, 8.0]])
    rows, heights = overpass_rows(np.vstack([chain, lone]), np.zeros(2), 0.0, xs)
    assert rows.shape == (2, len(xs))
    inside = xs <= 40.0
    np.testing.assert_allclose(rows[0, inside], 10.0 - 0.5 * xs[inside], atol=1e-12)
    assert np.isnan(rows[0, ~inside]).all()
    # Grid points at odd x from 5 to 39, each on two 1 m segments: 16 on segments at
    # 6.0 m, 20 on segments at 6.1 m.
    assert heights[0] == pytest.approx((16 * 6.0 + 20 * 6.1) / 36, abs=1e-12)
    np.testing.assert_array_equal(rows[1, (xs >= 30.0) & (xs <= 50.0)], -5.0)
    assert heights[1] == 8.0
    # A height step above OVERPASS_Z_STEP splits the chain.
    chain[25:, 4] = 7.0
    rows, heights = overpass_rows(chain, np.zeros(2), 0.0, xs)
    assert rows.shape == (2, len(xs))
    assert heights == pytest.approx([(16 * 6.0 + 5 * 6.1) / 21, 7.0], abs=1e-12)


def test_the_sensor_sees_the_bridge_and_the_aldm_ignores_it(maps: dict[str, Path]) -> None:
    road = OpenDriveRoad.from_file(maps["bridge"])
    flat = OpenDriveRoad.from_file(maps["flat"])
    sensor = LineSensor()
    seen = 0
    for s in (350.0, 400.0, 450.0):
        pose = road.lane_pose("1", -2, s)
        frame = sensor.measure(road, pose)
        points = [frame.line_points(i) for i in range(frame.n_lines)]
        high = [p for p in points if np.any(p[:, 2] != 0.0)]
        seen += len(high)
        for p in high:
            np.testing.assert_array_equal(p[:, 2], 7.0)
            # On the bridge's lines: straight at 60° to the motorway, from its left ahead
            # to its right, so in the sensor frame y = y0 - x tan(60°).
            slope = np.diff(p[:, 1]) / np.diff(p[:, 0])
            np.testing.assert_allclose(slope, -math.tan(ANGLE), rtol=1e-9)
        lane = road.lane_position(pose[:2]).lane
        score = score_detection(detect_lanes(frame), road, frame, lane)
        assert score["ego_left"].correct and score["ego_right"].correct
        # The ALDM drops the bridge by its height: the same detection as without it.
        bare = copy.copy(road)
        bare.overpass_lines = np.zeros((0, 5))
        a, b = detect_lanes(frame), detect_lanes(sensor.measure(bare, pose))
        for name in ("ego_left", "ego_right", "left_adjacent", "right_adjacent", "trajectory"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert seen == 9  # three bridge lines in every frame
    # On the flat crossing the same lines lie on the road and are not dropped.
    frame = sensor.measure(flat, flat.lane_pose("1", -2, 400.0))
    assert all(np.all(frame.line_points(i)[:, 2] == 0.0) for i in range(frame.n_lines))


def test_with_overpasses_adds_to_the_maps_own(maps: dict[str, Path]) -> None:
    road = OpenDriveRoad.from_file(maps["bridge"])
    more = road.with_overpasses([(200.0, 5.0, 0.0)])
    assert len(more.overpass_lines) == len(road.overpass_lines) + 3
    np.testing.assert_array_equal(
        more.overpass_lines[: len(road.overpass_lines)], road.overpass_lines
    )


def test_the_env_drives_under_the_bridge(maps: dict[str, Path]) -> None:
    env = gym.make("ALDMHighway-v0", config={"road": {"xodr": str(maps["bridge"])}})
    try:
        env.reset(seed=3)
        road = env.unwrapped.highway
        assert len(road.overpass_lines) == 180
        assert {key[0] for key in road.lanes} == {"1"}
        correct, high = [], 0
        for _ in range(40):
            _, _, term, trunc, info = env.step(1)
            det = info["detection"]
            correct.append(det["ego_left"]["correct"] == 1.0 and det["ego_right"]["correct"] == 1.0)
            high += int(np.sum(env.unwrapped.frame.all_points[:, 2] == 7.0))
            if term or trunc:
                break
        assert len(correct) == 40 and all(correct)
        assert high > 100  # the bridge was in view
    finally:
        env.close()


def test_the_render_draws_the_bridge_overhead(maps: dict[str, Path]) -> None:
    from aldm_gym.envs.rendering import BRIDGE_COLOUR

    def bridge_pixels(path: Path) -> int:
        config = {
            "road": {"xodr": str(path)},
            "scaling": 4.0,
            "centering_position": [0.2, 0.5],
            "vehicles_count": 3,
        }
        env = gym.make("ALDMHighway-v0", config=config, render_mode="rgb_array")
        try:
            env.reset(seed=0)
            while env.unwrapped.vehicle.position[0] < 420.0:
                env.step(1)
            img = env.render()
        finally:
            env.close()
        return int(np.all(img == np.array(BRIDGE_COLOUR), axis=2).sum())

    # Three lines across the window's 75 m height, 2 px wide.
    assert bridge_pixels(maps["bridge"]) > 3 * 2 * 200
    assert bridge_pixels(maps["flat"]) == 0


def test_the_shipped_bridges_map() -> None:
    path = Path(aldm_gym.__file__).parent / "roads" / "maps" / "bridges.xodr"
    road = OpenDriveRoad.from_file(path)
    bridges = road.map.bridges
    assert sorted(bridges) == ["3", "4"]
    assert [c.lower for c in bridges["3"]] == ["1"] and [c.lower for c in bridges["4"]] == ["2"]
    assert bridges["3"][0].z_upper - bridges["3"][0].z_lower == pytest.approx(6.5)
    # The climbing bridge: 7 m up where it crosses the middle lane, 2 % grade.
    climb = bridges["4"][0]
    assert 6.7 < climb.z_upper - climb.z_lower < 7.0
    # 100 m before the climbing bridge, in the bend's exit: the bridge is seen, the
    # ALDM's lines are the true ones.
    pose = road.lane_pose("2", -2, 300.0)
    frame = LineSensor().measure(road, pose)
    z = frame.all_points[:, 2]
    assert np.sum((z > 6.5) & (z < 7.2)) > 20
    lane = road.lane_position(pose[:2]).lane
    score = score_detection(detect_lanes(frame), road, frame, lane)
    assert score["ego_left"].correct and score["ego_right"].correct
