"""The ALDM's API (aldm_gym.sensor.aldm): parameters, bad input, the output contract,
determinism, generated roads."""

from __future__ import annotations

import _synthetic as S
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aldm_gym.sensor.aldm import ALDMParams, _packed, detect_lanes, make_params
from aldm_gym.sensor.aldm_kernels import layout, output
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection, driving_trajectory

from ._aldm_cases import EGO, frame, line_ok, same


# ----------------------------------------------------------------- parameters
def test_unknown_parameter_is_named_with_allowed_keys() -> None:
    pts = frame(0)[1]
    with pytest.raises(ValueError, match=r"serch_length.*allowed keys.*search_length"):
        detect_lanes(pts, serch_length=18.0)


@pytest.mark.parametrize(
    "bad",
    [
        {"mode": "fast"},
        {"search_length": 0.0},
        {"start_points": 2},
        {"n_points": 1},
        {"gate_min": 2.0, "gate_max": 1.0},
        {"noise_std": float("nan")},
        {"output": "raw"},
    ],
)
def test_impossible_parameters_raise(bad: dict) -> None:
    with pytest.raises(ValueError):
        ALDMParams(**bad)


def test_params_instance_and_overrides_combine() -> None:
    base = ALDMParams(mode="paper")
    p = make_params(base, n_points=5)
    assert p.mode == "paper" and p.n_points == 5
    det = detect_lanes(frame(1)[1], base, n_points=5)
    assert det.ego_left.shape == (5, 2)


# ----------------------------------------------------------------- bad input
def test_non_array_and_bad_dtype_raise_type_error() -> None:
    with pytest.raises(TypeError, match="numpy array"):
        detect_lanes([[10.0, 1.0], [12.0, 1.0]])
    with pytest.raises(TypeError, match="dtype"):
        detect_lanes(np.ones((5, 2), dtype=complex))
    with pytest.raises(TypeError, match="dtype"):
        detect_lanes(np.ones((5, 2), dtype=bool))
    with pytest.raises(TypeError, match="dtype"):
        detect_lanes(np.array([["a", "b"]]))


@pytest.mark.parametrize("shape", [(5,), (5, 4), (5, 1), (2, 3, 2)])
def test_wrong_shape_raises_value_error(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match="shape"):
        detect_lanes(np.ones(shape))


@pytest.mark.parametrize("pts", [np.zeros((0, 2)), np.zeros((0, 3)), np.array([[10.0, 1.5]])])
def test_empty_or_too_few_points_give_empty_lines(pts: np.ndarray) -> None:
    for mode in ("robust", "paper"):
        det = detect_lanes(pts, mode=mode)
        for name in LINE_NAMES:
            assert det.line(name).shape == (0, 2)
        assert det.trajectory.shape == (0, 2)
        assert det.source == "aldm"


def test_nan_and_inf_rows_are_dropped() -> None:
    _road, pts = frame(2)
    bad = pts.copy()[:40]
    bad[::3, 0] = np.nan
    bad[1::3, 1] = np.inf
    bad[2::3, 2] = -np.inf
    dirty = np.concatenate([pts, bad])
    for mode in ("robust", "paper"):
        assert same(detect_lanes(dirty, mode=mode), detect_lanes(pts, mode=mode))


def test_integer_input_and_two_columns_work() -> None:
    _road, pts = frame(3)
    det3 = detect_lanes(pts)
    det2 = detect_lanes(np.ascontiguousarray(pts[:, :2]))
    assert same(det3, det2)
    ints = np.round(pts[:, :2]).astype(np.int64)
    assert same(detect_lanes(ints), detect_lanes(ints.astype(np.float64)))


def test_huge_input_is_handled() -> None:
    rng = np.random.default_rng(0)
    _road, pts = frame(4)
    clutter = np.column_stack(
        [rng.uniform(0, 200, 150_000), rng.uniform(-60, 60, 150_000), np.full(150_000, 7.0)]
    )  # 150k points off the road plane (an overpass): ignored via z
    det = detect_lanes(np.concatenate([pts, clutter]))
    assert same(det, detect_lanes(pts))


def test_sensor_frame_duck_typing() -> None:
    _road, pts = frame(5)

    class Frame:
        def points(self) -> np.ndarray:
            return pts

    assert same(detect_lanes(Frame()), detect_lanes(pts))


# ----------------------------------------------------------------- output contract
@pytest.mark.parametrize("mode", ["robust", "paper"])
def test_straight_road_lines_sorted_13_points_within_data(mode: str) -> None:
    road, pts = frame(6)
    det = detect_lanes(pts, mode=mode)
    for name in LINE_NAMES:
        line = det.line(name)
        assert line.shape == (13, 2)
        assert np.all(np.diff(line[:, 0]) > 0)
        # no extrapolation: inside the x range of the measured points
        assert line[0, 0] >= pts[:, 0].min() and line[-1, 0] <= pts[:, 0].max()
    for name in EGO:
        assert line_ok(road, det, name, tol=0.05)
    assert np.all(np.isfinite(det.trajectory)) and len(det.trajectory) > 10


@pytest.mark.parametrize(
    ("n_lines", "radius", "mode"),
    [
        (4, np.inf, "robust"),
        (4, np.inf, "paper"),
        (4, 500.0, "robust"),
        (4, -500.0, "robust"),
        (100, np.inf, "robust"),
        (100, np.inf, "paper"),
        (100, -500.0, "robust"),
    ],
)
def test_carmaker_grid_frame_lines(n_lines: int, radius: float, mode: str) -> None:
    """Every line sampled at the sensor's x grid (exact ties in x, and in y on a straight
    road): the four lines nearest the sensor, on their markings over the whole grid."""
    pts = S.grid_frame(n_lines, radius=radius)
    det = detect_lanes(pts, mode=mode)
    offsets = {"left_adjacent": 5.25, "ego_left": 1.75, "ego_right": -1.75, "right_adjacent": -5.25}
    reach = 199.52 if mode == "robust" else 183.52  # paper: no window past the view range
    for name, offset in offsets.items():
        line = det.line(name)
        assert line.shape == (13, 2)
        assert line[0, 0] == 5.52 and line[-1, 0] == reach
        bend = 0.0 if np.isinf(radius) else line[:, 0] ** 2 / (2.0 * radius)
        np.testing.assert_allclose(line[:, 1], offset + bend, rtol=0.0, atol=0.005)
    assert same(det, detect_lanes(pts[::-1], mode=mode))


def test_all_points_output_holds_measured_points_in_paper_mode() -> None:
    _road, pts = frame(7, noise=0.01)
    det = detect_lanes(pts, mode="paper", n_points=0)
    measured = {tuple(p) for p in pts[:, :2]}
    assert len(det.ego_left) > 13
    assert all(tuple(p) in measured for p in det.ego_left)


def test_trusted_detection_matches_validating_constructor() -> None:
    _road, pts = frame(8, radius=-400, noise=0.03)
    det = detect_lanes(pts)
    checked = LaneDetection(
        **{n: det.line(n) for n in LINE_NAMES}, trajectory=det.trajectory, source="aldm"
    )
    assert same(det, checked)
    for name in (*LINE_NAMES, "trajectory"):
        arr = getattr(det, name)
        assert arr.dtype == np.float64 and arr.flags.c_contiguous


@pytest.mark.parametrize("mode", ["robust", "paper"])
@pytest.mark.parametrize("n_points", [13, 0, 3])
def test_trajectory_is_driving_trajectory_of_the_ego_lines(mode: str, n_points: int) -> None:
    """One trajectory function: the kernel's path is ``driving_trajectory``'s, bit for
    bit, on the whole lines and cut at ``path_range`` (3 points: the numpy fallback)."""
    _road, pts = frame(9, radius=700)
    for reach in (None, 80.0, 30.0):
        det = detect_lanes(pts, mode=mode, n_points=n_points, path_range=reach)
        assert det.found("ego_left") and det.found("ego_right")
        ref = driving_trajectory(det.ego_left, det.ego_right, path_range=reach)
        assert det.trajectory.tobytes() == ref.tobytes()
    assert same(detect_lanes(pts, path_range=None), detect_lanes(pts))
    with pytest.raises(ValueError, match="path_range"):
        detect_lanes(pts, path_range=0.0)


def test_trajectory_follows_the_true_lane_centre() -> None:
    """Behaviour against ground truth: the path is the lane centre (here y = -0.05 m)."""
    road = S.highway(lanes=3, ego_lane=1, radius=np.inf, lateral=0.05)
    pts, _ = S.sample(road, noise=0.02, seed=4)
    for reach, tol in ((None, 0.03), (80.0, 0.1)):  # 80 m: ~5 of the 13 points
        det = detect_lanes(pts, path_range=reach)
        assert det.trajectory[0, 0] == 0.0 and det.trajectory[-1, 0] > 60.0
        np.testing.assert_allclose(det.trajectory[:, 1], -0.05, atol=tol)


def test_one_line_trajectory_uses_lane_width_from_adjacent_line() -> None:
    road = S.highway(lanes=3, ego_lane=1, lane_width=3.25)
    road.markings.pop(2)  # no right ego line at all
    pts, _ = S.sample(road, seed=1)
    det = detect_lanes(pts)
    assert len(det.ego_right) == 0 and det.found("ego_left")
    # path = left line - half the estimated lane width (3.25 m, not the 3.75 default)
    np.testing.assert_allclose(det.trajectory[:, 1], 1.625 - 1.625, atol=0.05)
    # The same function as every detector, given the kernel's width estimate.
    fp, ip = _packed(make_params(None))
    for reach in (np.inf, 80.0):
        width = output.detect_frame(pts, fp, ip, reach)[-1]
        assert 3.2 < width < 3.3
        got = detect_lanes(pts, path_range=reach).trajectory
        want = driving_trajectory(det.ego_left, det.ego_right, width, path_range=reach)
        assert got.tobytes() == want.tobytes()


# ----------------------------------------------------------------- determinism
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), mode=st.sampled_from(["robust", "paper"]))
def test_point_order_never_changes_the_result(seed: int, mode: str) -> None:
    _road, pts = frame(seed % 50, radius=[np.inf, 300.0, -150.0][seed % 3], noise=0.04)
    # exact duplicates and x ties must not matter either
    pts = np.concatenate([pts, pts[:7], pts[7:12] * [1.0, 0.0, 1.0] + [0.0, 1.9, 0.0]])
    perm = np.random.default_rng(seed).permutation(len(pts))
    assert same(detect_lanes(pts, mode=mode), detect_lanes(pts[perm], mode=mode))


finite = st.floats(-250.0, 250.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    data=st.lists(st.tuples(finite, finite, st.floats(-1.0, 1.0)), max_size=80),
    ncols=st.sampled_from([2, 3]),
    mode=st.sampled_from(["robust", "paper"]),
    n_points=st.sampled_from([13, 0, 2]),
)
def test_any_finite_input_gives_finite_output(data, ncols, mode, n_points) -> None:  # type: ignore[no-untyped-def]
    pts = np.array(data, dtype=np.float64).reshape(-1, 3)[:, :ncols]
    det = detect_lanes(np.ascontiguousarray(pts), mode=mode, n_points=n_points)
    for name in (*LINE_NAMES, "trajectory"):
        arr = getattr(det, name)
        assert arr.ndim == 2 and arr.shape[1] == 2 and np.all(np.isfinite(arr))
    for name in LINE_NAMES:
        k = len(det.line(name))
        assert k == 0 or (n_points and k == n_points) or (not n_points and k >= 2)


def test_same_input_bit_identical_output() -> None:
    _road, pts = frame(12, radius=-300, noise=0.05, dropout=0.1)
    assert same(detect_lanes(pts), detect_lanes(pts.copy()))


# ----------------------------------------------------------------- generated roads
def _road_frames(noise: float, dropout: float, n: int = 12):  # type: ignore[no-untyped-def]
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor
    from aldm_gym.sensor.open_loop import sample_poses

    road = HighwayRoad({"min_radius": 400.0, "max_radius": 1500.0, "seed": 3})
    sensor = LineSensor({"lateral_noise": noise, "dropout": dropout})
    poses = sample_poses(road, n, np.random.default_rng(7))
    return road, sensor, poses


def test_generated_roads_per_dash_and_editor_give_the_same_lines() -> None:
    road, sensor, poses = _road_frames(0.0, 0.0, n=6)
    for p in poses:
        a = sensor.measure(road.with_marking_model("per_dash"), p.pose)
        b = sensor.measure(road.with_marking_model("editor"), p.pose)
        assert a.n_lines > b.n_lines  # every dash its own object
        for mode in ("robust", "paper"):
            assert same(detect_lanes(a, mode=mode), detect_lanes(b, mode=mode))


def test_generated_roads_robust_with_noise_and_dropout() -> None:
    from aldm_gym.sensor.ground_truth import score_detection

    road, sensor, poses = _road_frames(0.05, 0.1)
    sensor.seed(0)
    good = 0
    for p in poses:
        frame_ = sensor.measure(road, p.pose)
        sc = score_detection(detect_lanes(frame_), road, frame_, p.lane_id)
        good += sc["ego_left"].correct and sc["ego_right"].correct
    assert good >= len(poses) - 1


def test_both_ego_lines_found_only_beyond_the_start_region() -> None:
    """Both ego lines only in the extended start region (beyond x = 23.52 m) are found."""
    x = np.arange(26.0, 60.0, 2.0)
    pts = np.concatenate([np.column_stack([x, y + 0.0 * x]) for y in (1.8, -1.9)])
    det = detect_lanes(pts)
    assert det.found("ego_left") and det.found("ego_right")
    np.testing.assert_allclose(det.ego_left[:, 1], 1.8, atol=1e-9)
    np.testing.assert_allclose(det.ego_right[:, 1], -1.9, atol=1e-9)


def test_packed_parameters_are_cached_per_instance() -> None:
    p = make_params(noise_std=0.05)
    assert _packed(p) is _packed(p)
    assert _packed(make_params(noise_std=0.06))[0][layout.P.noise_std] == 0.06
    with pytest.raises(TypeError):
        detect_lanes(frame(0)[1], params={"mode": "paper"})  # type: ignore[arg-type]


def test_packed_vectors_follow_the_one_declaration() -> None:
    """``fp``/``ip`` are the named tuples of ``layout`` in order; fields named as an
    ``ALDMParams`` field carry its value, the derived ones their formula."""
    p = make_params(mode="paper", min_radius=200.0, n_points=7, noise_std=0.07)
    fp, ip = _packed(p)
    assert fp.shape == (len(layout.FloatParams._fields),)
    assert ip.shape == (len(layout.IntParams._fields),)
    for name in layout.FloatParams._fields:
        if hasattr(p, name):
            assert fp[getattr(layout.P, name)] == getattr(p, name), name
    assert fp[layout.P.a_max] == 0.5 / 200.0
    assert fp[layout.P.a_std] == 0.5 * p.curvature_prior_std
    assert ip[layout.I.paper] == 1 and ip[layout.I.n_points] == 7 and ip[layout.I.smooth] == 0
    assert ip[layout.I.start_points] == p.start_points


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("search_length", 1e20),
        ("gap_search_length", 1e20),
        ("curvature_prior_std", 1e-300),
        ("heading_prior_std", 1e-300),
        ("guide_curvature_std", 1e-300),
        ("guide_heading_std", 1e-300),
        ("n_points", 1),
        ("mode", "verbatim"),
        ("max_lane_width", 1.0),
    ],
)
def test_parameters_out_of_their_declared_range_name_the_key(key: str, value: object) -> None:
    pts = np.column_stack([np.arange(6.0, 60.0, 2.0), np.full(27, 1.8)])
    with pytest.raises(ValueError, match=rf"aldm\.{key}"):
        detect_lanes(pts, **{key: value})


def test_every_aldm_parameter_declares_its_rule() -> None:
    import dataclasses

    from aldm_gym.config import rules

    assert set(rules(ALDMParams)) == {f.name for f in dataclasses.fields(ALDMParams)}
    assert ALDMParams(n_points=np.int64(5)).n_points == 5
