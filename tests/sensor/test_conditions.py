"""Sensor conditions beyond CarMaker: occlusion, worn paint, range noise, clutter,
overpasses, the camera preset (``docs/sensor.md``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import aldm_gym
from aldm_gym.roads import HighwayRoad, OpenDriveRoad
from aldm_gym.sensor import LineSensor, LineSensorConfig, detect_lanes
from aldm_gym.sensor import conditions as cond
from tests.conftest import pose_on_lane

MAPS = Path(aldm_gym.__file__).parent / "roads" / "maps"
W = 3.75  # lane width of the test roads [m]


@pytest.fixture(scope="module")
def solid_road() -> HighwayRoad:
    """Straight 4-lane road whose lane lines are continuous: every grid point is paint."""
    return HighwayRoad({"curved": False, "length": 1000.0, "lane_line_type": 1})


def _xs_of(frame, marking: int) -> np.ndarray:
    keep = np.repeat(frame.line_marking, np.diff(frame.line_start)) == marking
    return np.sort(frame.all_points[keep, 0])


# ----------------------------------------------------------------- defaults
def test_conditions_are_off_by_default() -> None:
    c = LineSensorConfig()
    assert not c.conditions and not c.noisy and not c.occlusion
    assert c.lateral_noise == 0.0 and c.visibility is None


def test_camera_preset_sets_values_and_explicit_values_win() -> None:
    c = LineSensorConfig(preset="camera")
    assert c.occlusion and c.worn and c.conditions and c.noisy
    assert c.visibility == 150.0 and c.lateral_noise == 0.02
    d = LineSensor({"preset": "camera", "occlusion": False, "visibility": 80.0}).config
    assert d.occlusion is False and d.visibility == 80.0 and d.worn_dash_rate == 0.05


@pytest.mark.parametrize(
    ("cfg", "match"),
    [
        ({"preset": "fog"}, r"sensor\.preset must be one of \['camera'\]"),
        ({"worn_dash_rate": 1.5}, r"sensor\.worn_dash_rate"),
        ({"worn_stretch_rate": 11.0}, r"sensor\.worn_stretch_rate"),
        ({"worn_stretch_length": (50.0, 10.0)}, r"sensor\.worn_stretch_length"),
        ({"worn_stretch_length": (10.0, 900.0)}, r"sensor\.worn_stretch_length"),
        ({"lateral_noise_growth": -0.1}, r"sensor\.lateral_noise_growth"),
        ({"visibility": 0.0}, r"sensor\.visibility"),
        ({"sight_clearance": -1.0}, r"sensor\.sight_clearance"),
        ({"sight_clearance": float("inf")}, r"sensor\.sight_clearance"),
        ({"seam_rate": float("nan")}, r"sensor\.seam_rate"),
        ({"speck_rate": 1000.0}, r"sensor\.speck_rate"),
        ({"occlusion": 1}, r"sensor\.occlusion must be a bool"),
        ({"ocllusion": True}, r"ocllusion.*allowed keys.*occlusion"),
        ({"sight_clearence": 2.0}, r"did you mean 'sight_clearance'"),
    ],
)
def test_bad_condition_settings_are_named(cfg: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        LineSensor(cfg)


def test_bad_occluders_and_overpasses_are_named(solid_road: HighwayRoad) -> None:
    sensor = LineSensor({"occlusion": True})
    with pytest.raises(ValueError, match="occluders"):
        sensor.measure(solid_road, pose_on_lane(solid_road, 300.0, 1), occluders=np.zeros((2, 5)))
    with pytest.raises(ValueError, match=r"road\.overpasses"):
        HighwayRoad({"overpasses": [-5.0]})
    with pytest.raises(ValueError, match="beyond the road"):
        _ = HighwayRoad({"curved": False, "length": 500.0, "overpasses": [900.0]}).overpass_lines
    road = OpenDriveRoad.from_file(MAPS / "two_plus_one.xodr")
    with pytest.raises(ValueError, match=r"overpass\.angle"):
        road.with_overpasses([(0.0, 0.0, 0.0)], angle=0.01)


# ---------------------------------------------------------------- occlusion
def _box_ahead(pose: tuple, ahead: float, length: float, width: float, height: float) -> list:
    """World footprint of a box ``ahead`` metres in front of the sensor (mount_x = 1 m)."""
    x, y, h = pose
    d = 1.0 + ahead
    return [x + d * np.cos(h), y + d * np.sin(h), h, length, width, height]


def test_occlusion_matches_hand_computed_shadows(solid_road: HighwayRoad) -> None:
    pose = pose_on_lane(solid_road, 300.0, 1)
    ego = [pose[0], pose[1], pose[2], 5.0, 2.0, 1.5]  # holds the sensor: hides nothing
    # A truck 30 m ahead: footprint x in [25, 35], |y| <= 1, 4 m tall (above the
    # 1.3 m sensor): a marking at lateral |y_m| is hidden from x = 25 |y_m| / 1 on.
    truck = _box_ahead(pose, 30.0, 10.0, 2.0, 4.0)
    sensor = LineSensor({"occlusion": True})
    clean = LineSensor().measure(solid_road, pose)
    frame = sensor.measure(solid_road, pose, occluders=np.array([ego, truck]))
    grid = sensor.config.x_grid
    for j in range(5):  # markings at y = 5.625, 1.875, -1.875, -5.625, -9.375
        y_m = abs(clean.line(int(np.flatnonzero(clean.line_marking == j)[0])).ds[0, 1])
        expected = grid[grid < 25.0 * y_m]
        np.testing.assert_array_equal(_xs_of(frame, j), expected)
    # A low box (1.0 m, below the sensor) casts a finite shadow: the sight to the
    # marking at |y| = 1.875 leaves the box at t1 = min(35 / x, 1 / 1.875); it is
    # blocked while the sight's height there, 1.3 (1 - t1), is <= 1.0.
    low = _box_ahead(pose, 30.0, 10.0, 2.0, 1.0)
    frame = sensor.measure(solid_road, pose, occluders=np.array([low]))
    t1 = np.minimum(35.0 / grid, 1.0 / 1.875)
    hidden = (grid >= 25.0 * 1.875) & (1.3 * (1.0 - t1) <= 1.0)
    np.testing.assert_array_equal(_xs_of(frame, 1), grid[~hidden])
    np.testing.assert_array_equal(_xs_of(frame, 2), grid[~hidden])


def test_occlusion_takes_vehicles_and_needs_the_setting(solid_road: HighwayRoad) -> None:
    from types import SimpleNamespace

    pose = pose_on_lane(solid_road, 300.0, 1)
    box = _box_ahead(pose, 30.0, 16.0, 2.5, 4.0)
    truck = SimpleNamespace(
        position=np.array(box[:2]), heading=box[2], LENGTH=16.0, WIDTH=2.5
    )  # no HEIGHT: 16 m long, so a truck's 4 m
    on = LineSensor({"occlusion": True})
    by_vehicle = on.measure(solid_road, pose, occluders=[truck])
    by_array = on.measure(solid_road, pose, occluders=np.array([box]))
    np.testing.assert_array_equal(by_vehicle.all_points, by_array.all_points)
    off = LineSensor().measure(solid_road, pose, occluders=[truck])
    assert off.all_points.shape[0] > by_vehicle.all_points.shape[0]


# --------------------------------------------------------------- worn paint
def _world_points(frame) -> set[tuple[int, float]]:
    """(marking, world x rounded to 1 cm) of every point (straight road along world x)."""
    xs = frame.all_points[:, 0] + frame.origin[0]
    mk = np.repeat(frame.line_marking, np.diff(frame.line_start))
    return {(int(m), round(float(x), 2)) for m, x in zip(mk, xs, strict=True)}


@pytest.mark.parametrize("model", ["per_dash", "editor"])
def test_worn_paint_is_fixed_per_road(model: str) -> None:
    road = HighwayRoad({"curved": False, "length": 1500.0, "marking_model": model})
    cfg = {"worn_dash_rate": 0.3, "worn_stretch_rate": 5.0, "worn_stretch_length": (20.0, 60.0)}
    sensor = LineSensor(cfg)
    clean = LineSensor()
    # Two passes 40 m apart (20 grid steps), different generators: the same world
    # points are worn in the overlap, and some are.
    a = sensor.measure(road, pose_on_lane(road, 400.0, 1), rng=np.random.default_rng(1))
    b = sensor.measure(road, pose_on_lane(road, 440.0, 1), rng=np.random.default_rng(2))
    lo, hi = a.origin[0] + 60.0, a.origin[0] + 190.0

    def window(frame) -> set:
        return {p for p in _world_points(frame) if lo <= p[1] <= hi}

    assert window(a) == window(b)
    full = window(clean.measure(road, pose_on_lane(road, 400.0, 1)))
    assert window(a) < full
    # The twin with the other marking model wears the same paint.
    other = road.with_marking_model("editor" if model == "per_dash" else "per_dash")
    assert window(sensor.measure(other, pose_on_lane(other, 400.0, 1))) == window(a)
    # Another wear_seed wears other paint.
    c = LineSensor({**cfg, "wear_seed": 7}).measure(road, pose_on_lane(road, 400.0, 1))
    assert window(c) != window(a)


def test_the_road_key_ignores_last_bit_differences_of_the_geometry() -> None:
    """numpy's SIMD paths build the same road to different last bits on other CPUs:
    its wear and clutter must not change with them."""
    road = HighwayRoad({"seed": 3, "length": 2000.0})
    key = cond.road_key(road, 0)
    twin = HighwayRoad({"seed": 3, "length": 2000.0})
    xy = twin.reference.xy
    xy[1::3] = np.nextafter(xy[1::3], np.inf)  # every third vertex one ulp off
    assert cond.road_key(twin, 0) == key
    moved = HighwayRoad({"seed": 3, "length": 2000.0})
    moved.reference.xy[5, 0] += 0.01  # a real change of the geometry
    assert cond.road_key(moved, 0) != key
    assert cond.road_key(road, 1) != key


def test_worn_dash_share_and_a_worn_dash_is_gone_whole() -> None:
    road = HighwayRoad({"curved": False, "length": 1000.0})
    key = cond.road_key(road, 0)
    draws = np.array([cond._uniform(key, 1, q, cond._SALT_DASH, 0) for q in range(20000)])
    assert abs(np.mean(draws < 0.2) - 0.2) < 0.015
    frame = LineSensor({"worn_dash_rate": 0.5}).measure(road, pose_on_lane(road, 300.0, 1))
    clean = LineSensor().measure(road, pose_on_lane(road, 300.0, 1))
    pieces = {(int(m), int(p)) for m, p in zip(frame.line_marking, frame.line_piece, strict=True)}
    for n in range(clean.n_lines):
        m, p = int(clean.line_marking[n]), int(clean.line_piece[n])
        if (m, p) in pieces:  # a dash is seen whole or not at all
            k = next(
                i
                for i in range(frame.n_lines)
                if (frame.line_marking[i], frame.line_piece[i]) == (m, p)
            )
            np.testing.assert_array_equal(frame.line_points(k), clean.line_points(n))
    assert len(pieces) < clean.n_lines


def test_worn_paint_on_a_map_is_fixed_per_road() -> None:
    road = OpenDriveRoad.from_file(MAPS / "motorway.xodr")
    pose = road.lane_pose("2", -2, 200.0)
    sensor = LineSensor({"worn_dash_rate": 0.3, "worn_stretch_rate": 5.0})
    a = sensor.measure(road, pose, rng=np.random.default_rng(1))
    b = sensor.measure(road, pose, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(a.all_points, b.all_points)
    assert a.all_points.shape[0] < LineSensor().measure(road, pose).all_points.shape[0]


# ----------------------------------------------------------- range noise
def test_lateral_noise_grows_with_range(solid_road: HighwayRoad) -> None:
    sensor = LineSensor({"lateral_noise": 0.02, "lateral_noise_growth": 0.001})
    pose = pose_on_lane(solid_road, 300.0, 1)
    truth = LineSensor().measure(solid_road, pose)
    rng = np.random.default_rng(0)
    near, far = [], []
    for _ in range(400):
        f = sensor.measure(solid_road, pose, rng=rng)
        for j in (1, 2):
            pts = f.all_points[np.repeat(f.line_marking, np.diff(f.line_start)) == j]
            ref = truth.all_points[np.repeat(truth.line_marking, np.diff(truth.line_start)) == j]
            near.append(pts[0, 1] - ref[0, 1])
            far.append(pts[-1, 1] - ref[-1, 1])
    x0, x1 = truth.all_points[:, 0].min(), truth.all_points[:, 0].max()
    # 800 draws: the sample sigma is within ~5 % (1 sd) of the truth; allow 15 %.
    assert np.std(far) == pytest.approx(0.02 + 0.001 * x1, rel=0.15)
    assert np.std(near) == pytest.approx(0.02 + 0.001 * x0, rel=0.15)


def test_visibility_shrinks_the_range(solid_road: HighwayRoad) -> None:
    f = LineSensor({"visibility": 60.0}).measure(solid_road, pose_on_lane(solid_road, 300.0, 1))
    assert f.all_points[:, 0].max() <= 60.0 and f.all_points[:, 0].max() > 57.0


def _sight_brute_force(xs, ys, bounds, clearance):
    """The definition of ``sight_hidden``, checked grid point by grid point."""
    hidden = np.zeros(ys.shape, dtype=bool)
    left = [max(np.nanmax(c), 0.0) if not np.isnan(c).all() else np.nan for c in bounds.T]
    right = [min(np.nanmin(c), 0.0) if not np.isnan(c).all() else np.nan for c in bounds.T]
    for r, k in zip(*np.nonzero(~np.isnan(ys)), strict=True):
        for j in range(k):
            line = ys[r, k] * xs[j] / xs[k]
            if line > left[j] + clearance or line < right[j] - clearance:
                hidden[r, k] = True
    return hidden


def test_sight_hidden_is_its_definition() -> None:
    rng = np.random.default_rng(4)
    xs = 5.52 + 2.0 * np.arange(40)
    for _ in range(20):
        # Markings of a road bending either way (y = a + b x + c x^2), some gaps.
        c = rng.uniform(-1.0 / 500.0, 1.0 / 500.0)
        # Sometimes every marking on one side (the sensor beside the road).
        offsets = np.array([-5.6, -1.9, 1.9, 5.6]) + rng.choice([0.0, 8.0, -8.0])
        bounds = offsets[:, None] + 0.5 * c * xs[None] ** 2
        bounds[rng.random(bounds.shape) < 0.1] = np.nan
        ys = np.vstack([bounds, rng.uniform(-15.0, 15.0, (3, len(xs)))])
        clearance = rng.uniform(0.0, 4.0)
        got = cond.sight_hidden(xs, ys, bounds, clearance)
        np.testing.assert_array_equal(got, _sight_brute_force(xs, ys, bounds, clearance))


def test_sight_clearance_shortens_the_inner_lines_of_a_bend(tmp_path: Path) -> None:
    """R = 250 m left bend, sensor in the middle of three 3.75 m lanes: the inner edge
    (the reference line, 5.625 m to the left) ends where the sight line to it touches the
    circle 2 m inside it (tangents from the sensor and from the point)."""
    xodr = pytest.importorskip("scenariogeneration.xodr")
    radius = 250.0
    spec = xodr.create_road(
        [xodr.Line(200.0), xodr.Arc(1.0 / radius, 1200.0)],
        id=0,
        left_lanes=0,
        right_lanes=3,
        lane_width=W,
    )
    odr = xodr.OpenDrive("bend")
    odr.add_road(spec)
    odr.adjust_roads_and_lanes()
    odr.write_xml(str(tmp_path / "bend.xodr"))
    road = OpenDriveRoad.from_file(tmp_path / "bend.xodr")
    pose = road.lane_pose("0", -2, 600.0)
    open_side = LineSensor().measure(road, pose)
    walled = LineSensor({"sight_clearance": 2.0}).measure(road, pose)
    r_sensor, r_edge, r_wall = radius + 1.5 * W, radius, radius - 2.0
    angle = np.arccos(r_wall / r_sensor) + np.arccos(r_wall / r_edge)
    x_end = r_edge * np.sin(angle)  # 90.6 m, along the sensor's axis
    near = [i for i in range(open_side.n_lines) if open_side.line_points(i)[0, 0] < 6.0]
    first_y = [open_side.line_points(i)[0, 1] for i in near]
    inner = int(open_side.line_marking[near[int(np.argmax(first_y))]])
    outer = int(open_side.line_marking[near[int(np.argmin(first_y))]])
    assert _xs_of(open_side, inner).max() > 195.0
    # The wall stands 2 m along the sensor's y (not along the bend's normal, 0.93 of it
    # there), so the end lies within a few metres of the tangent construction.
    assert abs(_xs_of(walled, inner).max() - x_end) < 4.0
    # The outer lines are seen farther than the inner ones, every point a true one.
    assert _xs_of(walled, outer).max() > _xs_of(walled, inner).max() + 30.0
    assert set(map(tuple, walled.all_points)) <= set(map(tuple, open_side.all_points))


def test_sight_clearance_hides_nothing_on_a_straight_and_not_a_bridge(
    solid_road: HighwayRoad,
) -> None:
    pose = pose_on_lane(solid_road, 300.0, 1)
    plain = LineSensor().measure(solid_road, pose)
    walled = LineSensor({"sight_clearance": 0.0}).measure(solid_road, pose)
    np.testing.assert_array_equal(walled.all_points, plain.all_points)
    # Beside the road (every marking to the left): the sensor's own axis is in the zone.
    x, y, h = pose
    assert h == 0.0  # highway-env's left is -y here
    beside = (x, y + 12.0, h)
    plain = LineSensor().measure(solid_road, beside)
    walled = LineSensor({"sight_clearance": 0.0}).measure(solid_road, beside)
    assert np.all(plain.all_points[:, 1] > 0.0) and plain.all_points[:, 0].max() > 195.0
    np.testing.assert_array_equal(walled.all_points, plain.all_points)
    bridged = HighwayRoad({"curved": False, "length": 1000.0, "overpasses": [400.0]})
    f = LineSensor({"sight_clearance": 0.0}).measure(bridged, pose)
    g = LineSensor().measure(bridged, pose)
    # The bridge's markings run 30 m beyond the road's edges, far outside the zone.
    np.testing.assert_array_equal(f.all_points, g.all_points)
    assert np.sum(f.all_points[:, 2] == 6.0) > 10


# ------------------------------------------------------------------ clutter
@pytest.mark.parametrize(("kind", "rate"), [("seam", 3.0), ("old", 1.5)])
def test_clutter_rates(kind: str, rate: float) -> None:
    # One marking along 400 windows of 1 km: count the clutter items that start inside
    # a window (not at its first point, where one running on from the last would).
    k = 500
    seam, old = (rate / 1000.0, 0.0) if kind == "seam" else (0.0, rate / 1000.0)
    starts = 0
    for w in range(400):
        us = (1000.0 * w + 2.0 * np.arange(k))[None, :]
        ys = np.zeros((1, k))
        cy, src = cond._clutter(ys, us, np.zeros(1, dtype=np.int64), np.zeros(1), 12345, seam, old)
        first = np.argmax(np.isfinite(cy), axis=1)
        starts += int(np.sum(first > 0))
        assert np.all(src == 0)
        off = np.abs(cy[np.isfinite(cy)])
        if kind == "seam" and len(off):
            assert off.min() >= cond.SEAM_OFFSET[0] and off.max() <= cond.SEAM_OFFSET[1]
    expected = rate * 400
    assert abs(starts - expected) < 4 * np.sqrt(expected)


def test_specks_per_frame(solid_road: HighwayRoad) -> None:
    sensor = LineSensor({"speck_rate": 3.0})
    rng = np.random.default_rng(0)
    pose = pose_on_lane(solid_road, 300.0, 1)
    counts = []
    for _ in range(400):
        f = sensor.measure(solid_road, pose, rng=rng)
        specks = (f.line_marking == -1) & (np.diff(f.line_start) == 1)
        counts.append(int(specks.sum()))
    assert np.mean(counts) == pytest.approx(3.0, abs=0.3)


def test_seams_and_old_markings_are_line_objects_near_the_markings(
    solid_road: HighwayRoad,
) -> None:
    sensor = LineSensor({"seam_rate": 10.0, "old_marking_rate": 10.0})
    pose = pose_on_lane(solid_road, 300.0, 1)
    f = sensor.measure(solid_road, pose)
    clutter = [f.line(n) for n in range(f.n_lines) if f.line_marking[n] == -1]
    assert clutter and all(c.n_points >= 1 and c.type == 1 for c in clutter)
    clean = LineSensor().measure(solid_road, pose)
    np.testing.assert_array_equal(
        f.all_points[np.repeat(f.line_marking, np.diff(f.line_start)) >= 0].shape,
        clean.all_points.shape,
    )


# ----------------------------------------------------------------- overpass
def test_overpass_points_are_above_the_road_and_ignored_by_the_aldm() -> None:
    base = {"curved": False, "length": 1000.0}
    bridge = HighwayRoad({**base, "overpasses": [400.0]})
    plain = HighwayRoad(base)
    pose = pose_on_lane(plain, 300.0, 1)
    f = LineSensor().measure(bridge, pose)
    g = LineSensor().measure(plain, pose)
    over = f.line_marking == -1
    assert over.sum() == 3  # three bridge markings crossing the view
    z = f.all_points[np.repeat(over, np.diff(f.line_start)), 2]
    assert len(z) > 10 and np.all(z == 6.0)
    a, b = detect_lanes(f), detect_lanes(g)
    for name in ("ego_left", "ego_right", "left_adjacent", "right_adjacent", "trajectory"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_overpass_on_a_map() -> None:
    road = OpenDriveRoad.from_file(MAPS / "two_plus_one.xodr")
    pose = road.lane_pose("1", -1, 100.0)
    x, y, h = pose
    ahead = (x + 80.0 * np.cos(h), y + 80.0 * np.sin(h), h)
    bridged = road.with_overpasses([ahead], height=5.5)
    f = LineSensor().measure(bridged, pose)
    z = f.all_points[:, 2]
    assert np.sum(z == 5.5) > 10
    np.testing.assert_array_equal(
        f.all_points[z != 5.5], LineSensor().measure(road, pose).all_points
    )


# -------------------------------------------------------------- determinism
def test_every_condition_on_is_deterministic() -> None:
    road = HighwayRoad({"seed": 2, "overpasses": [1100.0]})
    pose = pose_on_lane(road, 1000.0, 1)
    occ = np.array([_box_ahead(pose, 40.0, 16.0, 2.5, 4.0), _box_ahead(pose, 70.0, 5.0, 2.0, 1.5)])
    sensor = LineSensor(
        {
            "preset": "camera",
            "dropout": 0.05,
            "seam_rate": 5.0,
            "speck_rate": 5.0,
            "sight_clearance": 1.0,
        }
    )
    frames = [
        sensor.measure(road, pose, rng=np.random.default_rng(11), occluders=occ) for _ in range(2)
    ]
    a, b = frames
    assert a.all_points.tobytes() == b.all_points.tobytes()
    np.testing.assert_array_equal(a.line_start, b.line_start)
    np.testing.assert_array_equal(a.line_marking, b.line_marking)
    assert np.any(a.all_points[:, 2] > 0.0)
    c = sensor.measure(road, pose, rng=np.random.default_rng(12), occluders=occ)
    assert c.all_points.tobytes() != a.all_points.tobytes()


def test_env_with_every_condition_repeats_with_its_seed() -> None:
    import gymnasium as gym

    config = {
        "sensor": {"preset": "camera", "sight_clearance": 1.0},
        "road": {"overpasses": [400.0, 900.0]},
    }

    def run(seed: int) -> list[bytes]:
        env = gym.make("ALDMHighway-v0", config=config)
        env.reset(seed=seed)
        frames = []
        for _ in range(5):
            env.step(1)
            frames.append(env.unwrapped.frame.all_points.tobytes())
        env.close()
        return frames

    assert run(3) == run(3)
    assert run(3) != run(4)
