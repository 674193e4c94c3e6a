"""Line sensor: sampling, field of view, caps, side assignment, mount, noise, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from aldm_gym.roads import HighwayRoad, MarkingType
from aldm_gym.sensor import LineSensor, SensorFrame
from tests.conftest import pose_on_lane


def _frame(road: HighwayRoad, s: float = 300.0, lane: int = 1, **cfg: object) -> SensorFrame:
    return LineSensor(cfg).measure(road, pose_on_lane(road, s, lane), t=1.5)


def test_points_every_2m_from_fov_start_to_range(straight_road: HighwayRoad) -> None:
    f = _frame(straight_road.with_marking_model("editor"))
    pts = f.points()
    assert pts[:, 0].min() == pytest.approx(5.52)
    assert pts[:, 0].max() <= 200.0
    assert pts[:, 0].max() > 198.0
    for n in range(f.n_lines):
        x = f.line_points(n)[:, 0]
        steps = np.diff(x)
        assert np.all(np.isclose(steps % 2.0, 0.0) | np.isclose(steps % 2.0, 2.0))
        assert np.all(np.diff(x) > 0)  # sorted by x


def test_fov_start_and_range_are_configurable(straight_road: HighwayRoad) -> None:
    f = _frame(straight_road, range=80.0, fov_start=10.0, dx=1.0)
    x = f.points()[:, 0]
    assert x.min() >= 10.0 - 1e-9
    assert x.max() <= 80.0 + 1e-9
    assert np.isclose(x.max(), 80.0)


def test_point_cap_per_line(straight_road: HighwayRoad) -> None:
    f = _frame(straight_road.with_marking_model("editor"), dx=0.5, max_points_per_line=50)
    counts = np.diff(f.line_start)
    assert counts.max() == 50
    assert f.points()[:, 0].max() <= 5.52 + 49 * 0.5 + 1e-9


def test_line_cap_per_side(straight_road: HighwayRoad) -> None:
    full = _frame(straight_road)
    capped = _frame(straight_road, max_lines_per_side=3)
    assert full.left.n_lines > 3 and full.right.n_lines > 3
    assert capped.left.n_lines == 3 and capped.right.n_lines == 3
    # The nearest (first) objects are kept.
    np.testing.assert_array_equal(capped.left.lines[0].ds, full.left.lines[0].ds)


def test_per_dash_objects_are_dashes_and_editor_objects_are_markings(
    straight_road: HighwayRoad,
) -> None:
    dash = _frame(straight_road)
    ed = _frame(straight_road.with_marking_model("editor"))
    # The pooled points are the same; only the grouping differs.
    a = dash.points()[np.lexsort(dash.points().T[::-1])]
    b = ed.points()[np.lexsort(ed.points().T[::-1])]
    np.testing.assert_array_equal(a, b)
    assert ed.n_lines == straight_road.lanes_count + 1
    dashed = [ln for ln in dash.lines if ln.type == MarkingType.DASHED]
    assert len(dashed) > 20
    for ln in dashed:
        extent = ln.ds[-1, 0] - ln.ds[0, 0]
        assert extent <= 6.0 + 1e-9  # one 6 m dash, sampled every 2 m
    # Starts of consecutive fully visible dashes of one marking are 18 m apart.
    starts = sorted(ln.ds[0, 0] for ln in dashed if ln.marking == 1 and ln.ds[0, 0] > 6.0)
    np.testing.assert_allclose(np.diff(starts), 18.0, atol=2.0)


def test_side_assignment_by_first_point(straight_road: HighwayRoad) -> None:
    f = _frame(straight_road, lane=1)
    assert all(ln.ds[0, 1] >= 0 for ln in f.left.lines)
    assert all(ln.ds[0, 1] < 0 for ln in f.right.lines)
    # Lane 1 has markings 0, 1 on its left and 2, 3, 4 on its right.
    assert {ln.marking for ln in f.left.lines} == {0, 1}
    assert {ln.marking for ln in f.right.lines} == {2, 3, 4}
    assert f.left.relevant_line is not None and f.left.relevant_line.marking == 1
    assert f.right.relevant_line is not None and f.right.relevant_line.marking == 2


def test_a_line_starting_on_the_middle_axis_goes_left() -> None:
    """Paper §"Line Sensor Model": "Is the beginning of the line on right side of the
    middle axis it is assigned to the right side, otherwise to the left" — y = 0 is
    left (and, nearest to the axis, the left side's relevant line)."""
    from aldm_gym.sensor.line_sensor import _assemble, _assemble_py

    xs = np.array([5.52, 7.52, 9.52])
    ys = np.array([[0.0, 0.1, 0.2], [-1.5, -1.5, -1.5], [2.0, 2.0, 2.0], [-0.0, 0.3, 0.6]])
    m = len(ys)
    zeros = np.zeros(m)
    for kernel in (_assemble, _assemble_py):
        for axis_y in (0.0, -0.0):
            got = kernel(
                xs, ys, np.zeros_like(ys), zeros, zeros, np.ones(m), zeros,
                np.zeros(m, dtype=np.bool_), np.zeros((0, 2)), np.zeros(m + 1, dtype=np.int64),
                np.arange(m), False, np.inf, np.inf, axis_y, np.zeros((3, 0, 0)),
                np.zeros((0, 0)), np.zeros(3), 0.0, 100,
            )  # fmt: skip
            _points, _starts, marking, _piece, n_left, rel_left, rel_right = got
            assert n_left == 3
            assert marking[:n_left].tolist() == [0, 3, 2]  # by x, then |y - axis|
            assert marking[rel_left] == 0 and marking[n_left + rel_right] == 1


def test_sides_are_judged_on_the_cars_middle_axis(straight_road: HighwayRoad) -> None:
    """A sensor mounted 2 m left of the car's middle axis, car centred in lane 1: its
    left line (1.875 m left of the car) is 0.125 m right of the *sensor*, yet left of
    the car's middle axis, so it is the left side's relevant line."""
    f = _frame(straight_road, lane=1, mount_y=2.0)
    assert f.axis_y == -2.0
    left = f.left.relevant_line
    assert left is not None and left.marking == 1
    assert left.ds[0, 1] == pytest.approx(-0.125)
    assert f.right.relevant_line is not None and f.right.relevant_line.marking == 2
    assert np.all(f.side_offsets()[: f.n_left] >= 0) and np.all(f.side_offsets()[f.n_left :] < 0)
    # Looking backwards from the same mount the car's left is the sensor's right.
    back = _frame(straight_road, lane=1, mount_y=2.0, mount_yaw=np.pi, sensor_index=1)
    assert back.axis_y == pytest.approx(2.0)
    assert back.right.relevant_line.marking == 1 and back.left.relevant_line.marking == 2
    # External travel moves the sensor, not the car's axis.
    moved = LineSensor({"mount_y": 2.0}).measure(
        straight_road, pose_on_lane(straight_road, 300.0, 1), ext_travel=(0.0, -1.0, 0.0)
    )
    assert moved.axis_y == -1.0 and moved.left.relevant_line.marking == 1


def test_angle_of_view_limits_the_lateral_reach(straight_road: HighwayRoad) -> None:
    """A point is seen when |y| <= x tan(fov_half_angle) (paper Fig. 1)."""
    narrow = _frame(straight_road, lane=0, fov_half_angle=np.radians(20.0))
    pts = narrow.points()
    assert np.all(np.abs(pts[:, 1]) <= pts[:, 0] * np.tan(np.radians(20.0)) + 1e-12)
    wide = _frame(straight_road, lane=0)
    hidden = np.abs(wide.points()[:, 1]) > wide.points()[:, 0] * np.tan(np.radians(20.0))
    assert hidden.any() and len(pts) == len(wide.points()) - hidden.sum()
    assert narrow.fov_half_angle == np.radians(20.0) and wide.max_lateral == np.inf


def test_default_field_of_view_sees_a_500m_curve_to_the_full_range() -> None:
    """The default angle of view (80°) keeps every marking of a 4-lane road in a
    R = 500 m curve in view to x ~ 200 m; the old 30 m band cut the right ones off."""
    road = HighwayRoad(
        {"segments": ((100.0, 0.0, 0.0), (900.0, -1 / 500, -1 / 500)), "length": 1000.0}
    )
    pose = pose_on_lane(road, 100.0, 3)
    f = LineSensor().measure(road, pose)
    reach = {j: f.points()[np.repeat(f.line_marking, np.diff(f.line_start)) == j][:, 0].max()
             for j in range(road.lanes_count + 1)}  # fmt: skip
    assert min(reach.values()) > 198.0
    band = LineSensor({"fov_half_angle": np.pi / 2, "max_lateral": 30.0}).measure(road, pose)
    assert np.abs(band.points()[:, 1]).max() <= 30.0
    assert np.abs(f.points()[:, 1]).max() > 40.0


def test_p_runs_to_the_last_grid_point_within_range() -> None:
    """p = 0 … ⌊(range − fov_start) / dx⌋: 97 for the defaults (x = 199.52 m)."""
    xs = LineSensor().config.x_grid
    assert len(xs) == 98 and xs[0] == 5.52 and xs[-1] == pytest.approx(199.52)
    assert len(LineSensor({"fov_start": 0.0}).config.x_grid) == 101  # the paper's 0 … 100


def test_relevant_point_list_has_30_points(straight_road: HighwayRoad) -> None:
    f = _frame(straight_road.with_marking_model("editor"))
    assert f.left.relevant_points.shape == (30, 3)
    np.testing.assert_array_equal(f.left.relevant_points, f.left.relevant_line.ds[:30])


def test_lateral_positions_match_the_lane_geometry(straight_road: HighwayRoad) -> None:
    shift = 0.4
    f = LineSensor().measure(straight_road, pose_on_lane(straight_road, 300.0, 1, shift))
    left = f.left.relevant_line.ds
    right = f.right.relevant_line.ds
    np.testing.assert_allclose(left[:, 1], 1.875 - shift, atol=1e-9)
    np.testing.assert_allclose(right[:, 1], -1.875 - shift, atol=1e-9)
    assert np.all(left[:, 2] == 0.0)


def test_frame_fields(straight_road: HighwayRoad) -> None:
    f = LineSensor({"sensor_index": 0}).measure(
        straight_road,
        pose_on_lane(straight_road, 300.0, 1),
        t=2.25,
        ext_rotation=(0.0, 0.01, 0.0),
        ext_travel=(0.1, 0.0, 0.0),
    )
    assert f.timestamp == 2.25
    assert f.sensor_index == 0
    np.testing.assert_array_equal(f.mount_position, [1.0, 0.0, 1.3])
    np.testing.assert_array_equal(f.ext_rotation, [0.0, 0.01, 0.0])
    np.testing.assert_array_equal(f.ext_travel, [0.1, 0.0, 0.0])
    assert f.left.n_lines + f.right.n_lines == f.n_lines == len(f.line_type)
    assert set(np.unique(f.line_type)) <= {1, 2, 3}


def test_backward_sensor_sees_the_road_behind(straight_road: HighwayRoad) -> None:
    back = LineSensor({"sensor_index": 1, "mount_x": -2.0, "mount_yaw": np.pi})
    f = back.measure(straight_road, pose_on_lane(straight_road, 500.0, 1))
    assert f.sensor_index == 1
    assert f.n_lines > 0
    # Looking backwards, the driver's left markings appear on the sensor's right.
    assert f.right.relevant_line.marking == 1
    assert f.left.relevant_line.marking == 2
    # Travel along x of the mount moves the backward sensor towards the rear.
    moved = back.measure(straight_road, pose_on_lane(straight_road, 500.0, 1), ext_travel=(3, 0, 0))
    np.testing.assert_allclose(
        moved.origin - f.origin, -3.0 * _fwd(straight_road, 500.0), atol=1e-9
    )


def _fwd(road: HighwayRoad, s: float) -> np.ndarray:
    h = float(road.reference.heading_at(s))
    return np.array([np.cos(h), np.sin(h)])


def test_external_yaw_turns_the_view(straight_road: HighwayRoad) -> None:
    f = LineSensor().measure(
        straight_road, pose_on_lane(straight_road, 300.0, 1), ext_rotation=(0, 0, 0.05)
    )
    # Turned left by 0.05 rad, a straight marking drifts right as x grows.
    ln = f.left.relevant_line.ds
    slope = np.polyfit(ln[:, 0], ln[:, 1], 1)[0]
    assert slope == pytest.approx(-np.tan(0.05), abs=1e-3)


def test_guard_rail_objects_carry_height() -> None:
    road = HighwayRoad({"guard_rail": True, "curved": False, "length": 600.0})
    f = _frame(road)
    heights = f.line_height
    assert (heights > 0).sum() == 2
    rail = f.all_points[f.line_start[np.argmax(heights)], 2]
    assert rail == pytest.approx(0.75)


def test_noise_and_dropout_are_seeded(straight_road: HighwayRoad) -> None:
    pose = pose_on_lane(straight_road, 300.0, 1)
    cfg = {"lateral_noise": 0.05, "dropout": 0.2}
    a = LineSensor(cfg).measure(straight_road, pose, rng=np.random.default_rng(5))
    b = LineSensor(cfg).measure(straight_road, pose, rng=np.random.default_rng(5))
    c = LineSensor(cfg).measure(straight_road, pose, rng=np.random.default_rng(6))
    clean = LineSensor().measure(straight_road, pose)
    np.testing.assert_array_equal(a.points(), b.points())
    assert a.points().shape != c.points().shape or not np.array_equal(a.points(), c.points())
    kept = len(a.points()) / len(clean.points())
    assert 0.7 < kept < 0.9
    resid = a.points()[:, 1] - np.round(a.points()[:, 1] / 1.875) * 1.875
    assert 0.03 < np.std(resid) < 0.07


def test_curved_road_points_follow_the_marking(curvy_road: HighwayRoad) -> None:
    from aldm_gym.sensor import line_markings, score_line

    for s in (400.0, 1500.0, 2600.0, 3700.0):
        f = LineSensor().measure(
            curvy_road.with_marking_model("editor"), pose_on_lane(curvy_road, s, 2)
        )
        for ln in f.lines:
            sc = score_line(ln.ds[:, :2], curvy_road, f, ln.marking, tol=1e-6, preview_min=0.0)
            assert sc.max_abs_error < 1e-6
        assert line_markings(curvy_road, 2)["ego_left"] == 2


@pytest.mark.parametrize(
    ("cfg", "match"),
    [
        ({"range": -1.0}, "range"),
        ({"fov_start": 300.0}, "fov_start"),
        ({"max_lines_per_side": 101}, "max_lines_per_side"),
        ({"max_points_per_line": 201}, "max_points_per_line"),
        ({"dropout": 1.0}, "dropout"),
        ({"lateral_noise": float("inf")}, "lateral_noise"),
        ({"fov_half_angle": 0.0}, "fov_half_angle"),
        ({"fov_half_angle": 1.6}, "fov_half_angle"),
        ({"max_lateral": -1.0}, "max_lateral"),
        ({"rangee": 100.0}, r"rangee.*allowed keys"),
    ],
)
def test_bad_sensor_config(cfg: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        LineSensor(cfg)


def test_bad_measure_inputs(straight_road: HighwayRoad) -> None:
    s = LineSensor()
    with pytest.raises(ValueError, match="pose"):
        s.measure(straight_road, (1.0, 2.0))
    with pytest.raises(ValueError, match="finite"):
        s.measure(straight_road, (np.nan, 0.0, 0.0))
    with pytest.raises(ValueError, match="ext_travel"):
        s.measure(straight_road, (0.0, 0.0, 0.0), ext_travel=(1.0, 2.0))
    with pytest.raises(TypeError, match="road must be"):
        s.measure("road", (0.0, 0.0, 0.0))  # type: ignore[arg-type]


def test_off_the_road_gives_an_empty_frame(straight_road: HighwayRoad) -> None:
    f = LineSensor().measure(straight_road, (5000.0, 3000.0, 0.0))
    assert f.n_lines == 0
    assert f.points().shape == (0, 3)
    assert f.left.relevant_line is None


# --------------------------------------------------------------------------- kernel
# A frozen copy of the numpy implementation that `_assemble` replaced (world pose,
# paint pattern, noise, grouping, sides, order, caps, relevant line). The compiled
# kernel must give the same frames bit for bit, with the same random draws.


def _numpy_world_pose(sensor: LineSensor, pose: tuple, travel: np.ndarray, ext_yaw: float):
    c = sensor.config
    x, y, h = (float(v) for v in np.asarray(pose, dtype=np.float64))
    cy, sy = np.cos(c.mount_yaw), np.sin(c.mount_yaw)
    tx = cy * travel[0] - sy * travel[1]
    ty = sy * travel[0] + cy * travel[1]
    fwd = np.array([np.cos(h), np.sin(h)])
    left = np.array([np.sin(h), -np.cos(h)])
    origin = np.array([x, y]) + (c.mount_x + tx) * fwd + (c.mount_y + ty) * left
    return origin, h - (c.mount_yaw + ext_yaw)


def _numpy_measure(
    sensor: LineSensor,
    road: HighwayRoad,
    pose: tuple,
    t: float = 0.0,
    rng: np.random.Generator | None = None,
    ext_rotation: tuple = (0.0, 0.0, 0.0),
    ext_travel: tuple = (0.0, 0.0, 0.0),
    s_hint: float | None = None,
) -> SensorFrame:
    c = sensor.config
    rot = np.asarray(ext_rotation, dtype=np.float64)
    travel = np.asarray(ext_travel, dtype=np.float64)
    origin, yaw = _numpy_world_pose(sensor, pose, travel, float(rot[2]))
    xs = c.x_grid
    ys, us = road.sample_markings(origin, yaw, xs, s_hint)
    tab = road.marking_table
    m, k = ys.shape
    with np.errstate(invalid="ignore"):
        rel_u = (us - tab["phase"][:, None]) / tab["period"][:, None]
        piece = np.floor(rel_u)
        on = ~tab["broken"][:, None] | (
            (rel_u - piece) * tab["period"][:, None] < tab["dash"][:, None]
        )
        max_lateral = np.inf if c.max_lateral is None else c.max_lateral
        tan_half = c.tan_half_angle
        in_angle = np.abs(ys) <= xs[None, :] * tan_half if tan_half < np.inf else True
        visible = on & (np.abs(ys) <= max_lateral) & in_angle
    px = np.broadcast_to(xs, (m, k)).copy()
    pz = np.broadcast_to(tab["height"][:, None], (m, k)).copy()
    if c.noisy:
        noise = rng.standard_normal((3, m, k))
        keep = rng.random((m, k)) >= c.dropout
        ys = ys + c.lateral_noise * noise[0]
        px = px + c.longitudinal_noise * noise[1]
        pz = pz + c.height_noise * noise[2]
        visible &= keep
    py = ys
    per_dash = road.marking_model == "per_dash"
    broken = tab["broken"]
    flat = np.flatnonzero(visible.ravel())
    j_of = flat // k
    pc = piece.ravel()[flat]
    pid = np.where(per_dash & broken[j_of], pc, -1.0)
    if len(flat):
        new = np.concatenate([[True], (np.diff(j_of) != 0) | (np.diff(pid) != 0)])
    else:
        new = np.zeros(0, dtype=bool)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(flat)))
    obj_j = j_of[starts]
    pts = np.column_stack([px.ravel()[flat], py.ravel()[flat], pz.ravel()[flat]])
    first = pts[starts] if len(starts) else np.zeros((0, 3))
    # Sides against the car's middle axis, a point on it counting left (paper).
    lateral = c.mount_y + (np.sin(c.mount_yaw) * travel[0] + np.cos(c.mount_yaw) * travel[1])
    yaw_cos = np.cos(c.mount_yaw) if rot[2] == 0.0 else np.cos(c.mount_yaw + rot[2])
    axis_y = float(-lateral * yaw_cos)
    offset = first[:, 1] - axis_y
    is_left = offset >= 0.0
    order = np.lexsort((np.abs(offset), first[:, 0], ~is_left))
    n_left_all = int(is_left.sum())
    cap = c.max_lines_per_side
    keep_o = np.concatenate([order[: min(n_left_all, cap)], order[n_left_all:][:cap]])
    n_left = min(n_left_all, cap)
    counts_k = counts[keep_o]
    line_start = np.concatenate([[0], np.cumsum(counts_k)]).astype(np.int64)
    idx = np.repeat(starts[keep_o] - line_start[:-1], counts_k) + np.arange(line_start[-1])
    first_k = first[keep_o]
    rel = [-1, -1]
    for side, (lo, hi) in enumerate(((0, n_left), (n_left, len(keep_o)))):
        if hi > lo:
            rel[side] = int(np.argmin(np.abs(first_k[lo:hi, 1] - axis_y)))
    mk_j = obj_j[keep_o]
    return SensorFrame(
        timestamp=t,
        sensor_index=c.sensor_index,
        all_points=pts[idx],
        line_start=line_start,
        line_type=tab["type"][mk_j],
        line_colour=tab["colour"][mk_j],
        line_height=tab["height"][mk_j],
        line_width=tab["width"][mk_j],
        line_marking=mk_j.astype(np.int64),
        line_piece=pid[starts][keep_o].astype(np.int64),
        n_left=n_left,
        relevant_left=rel[0],
        relevant_right=rel[1],
        relevant_points=c.relevant_points,
        mount_position=np.array([c.mount_x, c.mount_y, c.mount_z]),
        mount_rotation=np.array([c.mount_roll, c.mount_pitch, c.mount_yaw]),
        ext_rotation=rot,
        ext_travel=travel,
        origin=origin,
        yaw=yaw,
        range=c.range,
        fov_start=c.fov_start,
        fov_half_angle=c.fov_half_angle,
        max_lateral=float(max_lateral),
        axis_y=axis_y,
    )


def _assert_same_frame(got: SensorFrame, want: SensorFrame) -> None:
    import dataclasses

    for f in dataclasses.fields(SensorFrame):
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(b, np.ndarray):
            assert isinstance(a, np.ndarray), f.name
            assert a.dtype == b.dtype and a.shape == b.shape, f.name
            assert a.tobytes() == b.tobytes(), f.name
        else:
            assert type(a) is type(b) and a == b, (f.name, a, b)


_KERNEL_CASES = [
    ({}, {}),
    ({"lateral_noise": 0.05, "dropout": 0.1}, {}),
    ({"lateral_noise": 0.3, "longitudinal_noise": 0.5, "height_noise": 0.02}, {}),
    ({"dropout": 0.6, "max_lines_per_side": 2}, {}),
    ({"max_lines_per_side": 3, "dx": 0.5, "max_points_per_line": 50}, {}),
    ({"max_lateral": 4.0, "range": 120.0, "fov_start": 0.0}, {}),
    ({"fov_half_angle": 0.3, "fov_start": 0.0, "mount_y": -0.4}, {}),
    ({"fov_half_angle": np.pi / 2, "max_lateral": 30.0}, {}),
    ({"mount_y": 0.5, "mount_yaw": np.pi, "sensor_index": 1, "lateral_noise": 0.02}, {}),
    ({"sensor_index": 1, "mount_x": -2.0, "mount_yaw": np.pi, "lateral_noise": 0.1}, {}),
    ({"mount_y": 0.7, "mount_yaw": 0.2}, {"guard_rail": True}),
    ({"lateral_noise": 1.0, "dropout": 0.3}, {"guard_rail": True, "lanes_count": 2}),
    ({}, {"dash_length": 3.0, "gap_length": 9.0, "dash_phase": 1.3, "lane_line_type": 3}),
]


@pytest.mark.parametrize("marking_model", ["per_dash", "editor"])
@pytest.mark.parametrize(("sensor_cfg", "road_cfg"), _KERNEL_CASES)
def test_measure_matches_the_numpy_implementation(
    sensor_cfg: dict, road_cfg: dict, marking_model: str
) -> None:
    road = HighwayRoad({"seed": 5, "min_radius": 150.0, "marking_model": marking_model, **road_cfg})
    sensor = LineSensor(sensor_cfg)
    rng = np.random.default_rng(11)
    for i, s in enumerate(np.linspace(60.0, road.length - 60.0, 25)):
        lane = i % road.lanes_count
        x, y, h = pose_on_lane(road, float(s), lane, float(rng.uniform(-2.5, 2.5)))
        pose = (x, y, h + float(rng.normal(0.0, 0.1)) + (np.pi if i % 7 == 3 else 0.0))
        rot = (0.0, 0.01, float(rng.normal(0.0, 0.05))) if i % 3 else (0.0, 0.0, 0.0)
        travel = (float(rng.normal()), float(rng.normal()), 0.0) if i % 4 else (0.0, 0.0, 0.0)
        seed = int(rng.integers(1 << 30))
        kw = {"ext_rotation": rot, "ext_travel": travel}
        got = sensor.measure(road, pose, 0.1 * i, rng=np.random.default_rng(seed), **kw)
        want = _numpy_measure(sensor, road, pose, 0.1 * i, np.random.default_rng(seed), **kw)
        _assert_same_frame(got, want)
    # The default (validation-free) ext_rotation / ext_travel and an array pose.
    got = sensor.measure(road, np.array(pose), 2.0, rng=np.random.default_rng(3))
    want = _numpy_measure(sensor, road, pose, 2.0, np.random.default_rng(3))
    _assert_same_frame(got, want)


def test_measure_matches_the_numpy_implementation_off_road(straight_road: HighwayRoad) -> None:
    sensor = LineSensor({"lateral_noise": 0.1})
    pose = (5000.0, 3000.0, 0.0)
    got = sensor.measure(straight_road, pose, rng=np.random.default_rng(1))
    _assert_same_frame(
        got, _numpy_measure(sensor, straight_road, pose, 0.0, np.random.default_rng(1))
    )
    assert got.n_lines == 0 and got.line_start.tolist() == [0]


def test_assemble_kernel_matches_its_python_reference(curvy_road: HighwayRoad) -> None:
    from aldm_gym.sensor.line_sensor import _assemble, _assemble_py

    rng = np.random.default_rng(2)
    tab = curvy_road.marking_table
    xs = LineSensor().config.x_grid
    for i, s in enumerate((300.0, 1200.0, 2500.0)):
        x, y, h = pose_on_lane(curvy_road, s, i)
        ys, us = curvy_road.sample_markings(np.array([x, y]), h, xs)
        noise = rng.standard_normal((3, *ys.shape))
        draw = rng.random(ys.shape)
        for per_dash in (True, False):
            for nz, dr in ((noise, draw), (np.zeros((3, 0, 0)), np.zeros((0, 0)))):
                args = (xs, ys, us, tab["height"], tab["phase"], tab["period"], tab["dash"])
                paint = (tab["paint"], tab["paint_start"], np.arange(len(ys)))
                rest = (
                    tab["broken"],
                    *paint,
                    per_dash,
                    np.tan(np.radians(30.0)),
                    30.0,
                    0.4,
                    nz,
                    dr,
                    np.array([0.1, 0.2, 0.0]),
                    0.2,
                    4,
                )
                got = _assemble(*args, *rest)
                want = _assemble_py(*args, *rest)
                for a, b in zip(got, want, strict=True):
                    np.testing.assert_array_equal(a, b)
                    assert np.asarray(a).dtype == np.asarray(b).dtype


def test_a_wrong_s_hint_is_rejected_not_silently_empty() -> None:
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor

    road = HighwayRoad({"seed": 3, "length": 3000.0})
    s = 1200.0
    x, y = road.reference.position(s, road.lane_offset(1))
    pose = (float(x), float(y), float(road.reference.heading_at(s)))
    sensor = LineSensor()
    good = sensor.measure(road, pose, s_hint=s + 1.0)
    assert good.points().shape[0] > 50
    assert np.array_equal(good.points(), sensor.measure(road, pose).points())
    for bad in (s + 500.0, -800.0, float("nan")):
        with pytest.raises(ValueError, match="s_hint"):
            sensor.measure(road, pose, s_hint=bad)
