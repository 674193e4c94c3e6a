"""LaneDetection container: validation, resampling, trajectory."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from aldm_gym.roads import OpenDriveRoad
from aldm_gym.sensor import LaneDetection, LineSensor, detect_lanes, driving_trajectory
from aldm_gym.sensor.lane_detection import LINE_NAMES, paint_types


def _line(y0: float, curv: float = 0.0, x0: float = 5.52, x1: float = 120.0) -> np.ndarray:
    x = np.arange(x0, x1, 2.0)
    return np.column_stack([x, y0 + 0.5 * curv * x**2])


def test_lines_are_sorted_and_validated() -> None:
    pts = _line(1.8)[::-1]
    det = LaneDetection(ego_left=pts)
    assert np.all(np.diff(det.ego_left[:, 0]) > 0)
    with pytest.raises(ValueError, match=r"ego_right.*shape"):
        LaneDetection(ego_right=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="NaN"):
        LaneDetection(ego_left=np.array([[1.0, np.nan], [2.0, 0.0]]))


def test_resample_gives_n_equally_spaced_points() -> None:
    det = LaneDetection(ego_left=_line(1.8, 1e-3), ego_right=_line(-1.9, x1=40.0))
    r = det.resample(13)
    assert r.ego_left.shape == (13, 2) and r.ego_right.shape == (13, 2)
    assert np.allclose(np.diff(r.ego_left[:, 0]), np.diff(r.ego_left[:, 0])[0])
    assert r.ego_left[0, 0] == det.ego_left[0, 0] and r.ego_left[-1, 0] == det.ego_left[-1, 0]
    assert r.left_adjacent.shape == (0, 2)
    with pytest.raises(ValueError, match="n >= 2"):
        det.resample(1)


def test_trajectory_is_midway_and_single_line_offsets_half_a_lane() -> None:
    left, right = _line(1.9, 1e-3), _line(-1.85, 1e-3)
    traj = driving_trajectory(left, right)
    assert traj[0, 0] == 0.0
    expected = 0.5 * (1.9 - 1.85) + 0.5 * 1e-3 * traj[:, 0] ** 2
    np.testing.assert_allclose(traj[:, 1], expected, atol=1e-6)
    only_left = driving_trajectory(left, np.zeros((0, 2)), lane_width=3.5)
    np.testing.assert_allclose(
        only_left[:, 1], 1.9 - 1.75 + 0.5e-3 * only_left[:, 0] ** 2, atol=1e-6
    )
    only_right = driving_trajectory(np.zeros((0, 2)), right, lane_width=3.5)
    np.testing.assert_allclose(
        only_right[:, 1], -1.85 + 1.75 + 0.5e-3 * only_right[:, 0] ** 2, atol=1e-6
    )
    assert driving_trajectory(np.zeros((0, 2)), np.zeros((0, 2))).shape == (0, 2)


def test_as_array_for_observations() -> None:
    det = LaneDetection.from_lines(ego_left=_line(1.8), ego_right=_line(-1.9))
    pts, valid = det.as_array(13)
    assert pts.shape == (4, 13, 2)
    np.testing.assert_array_equal(valid, [False, True, True, False])
    assert np.all(pts[0] == 0)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 40), st.just(2)), elements=st.floats(-300, 300)))
def test_any_finite_line_resamples_to_finite_points(pts: np.ndarray) -> None:
    det = LaneDetection.from_lines(ego_left=pts, ego_right=pts + np.array([0.0, -3.5]))
    r = det.resample(13)
    assert r.ego_left.shape in ((13, 2), (0, 2))
    assert np.all(np.isfinite(r.ego_left))
    assert np.all(np.isfinite(det.trajectory))


# --------------------------------------------------------------------------- path fit
def _polynomial_trajectory(
    left: np.ndarray, right: np.ndarray, lane_width: float = 3.75, spacing: float = 2.0
) -> np.ndarray:
    """The previous ``driving_trajectory``: ``Polynomial.fit`` per line (frozen copy)."""
    from aldm_gym.sensor.trajectory import fit_cubic

    fl, fr = fit_cubic(left), fit_cubic(right)
    if fl is None and fr is None:
        return np.zeros((0, 2))
    x_end = float(min(line[-1, 0] for line in (left, right) if len(line)))
    if x_end <= 0.0:
        return np.zeros((0, 2))
    xs = np.linspace(0.0, x_end, max(2, int(np.ceil(x_end / spacing)) + 1))
    if fl is not None and fr is not None:
        ys = 0.5 * (fl(xs) + fr(xs))
    elif fl is not None:
        ys = fl(xs) - 0.5 * lane_width
    else:
        ys = fr(xs) + 0.5 * lane_width
    return np.column_stack([xs, ys])


def _sensor_lines() -> list[tuple[np.ndarray, np.ndarray]]:
    """ALDM ego lines (13 points, and all measured points) along roads with R >= 100 m."""
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor
    from aldm_gym.sensor.aldm import detect_lanes, make_params
    from tests.conftest import pose_on_lane

    out = []
    for seed, r_min in ((0, 500.0), (7, 100.0)):
        road = HighwayRoad({"seed": seed, "min_radius": r_min})
        sensor = LineSensor({"lateral_noise": 0.05, "dropout": 0.1}, seed=seed)
        for s in np.linspace(100.0, road.length - 300.0, 30):
            frame = sensor.measure(road, pose_on_lane(road, float(s), 1, 0.3))
            det = detect_lanes(frame, make_params(None))
            out.append((det.ego_left, det.ego_right))
            out.append((det.left_adjacent, det.ego_left))
            rel = (frame.relevant_line_points("left"), frame.relevant_line_points("right"))
            out.append(tuple(np.ascontiguousarray(p[:, :2]) for p in rel))
    return out


def test_compiled_path_fit_is_within_1e_9_m_of_polynomial_fit() -> None:
    """On sensor lines (whole, and cut at 80 m as the env does) the compiled QR fit
    gives ``Polynomial.fit``'s path to rounding: same x samples, y within 1e-9 m."""
    worst = 0.0
    n_fitted = 0
    for left, right in _sensor_lines():
        for cut in (np.inf, 80.0):
            lines = [
                ln if len(ln) <= 4 else ln[: max(int((ln[:, 0] <= cut).sum()), 4)]
                for ln in (left, right)
            ]
            want = _polynomial_trajectory(*lines)
            got = driving_trajectory(*lines)
            assert got.shape == want.shape
            np.testing.assert_array_equal(got[:, 0], want[:, 0])
            if len(got):
                worst = max(worst, float(np.max(np.abs(got[:, 1] - want[:, 1]))))
                n_fitted += 1
    assert n_fitted > 200
    assert worst < 1e-9


def test_path_fit_falls_back_to_fit_cubic_bit_for_bit() -> None:
    """Short, unsorted, repeated-x lines take ``fit_cubic``, as before, bit for bit."""
    rng = np.random.default_rng(3)
    good = _line(-1.9, 1e-3)
    for trial in range(100):
        k = int(rng.integers(1, 12))
        kind = trial % 3
        if kind == 0:
            x = np.sort(rng.uniform(0.0, 60.0, min(k, 3)))  # fewer than 4 points
        elif kind == 1:
            x = np.sort(rng.integers(0, 4, k + 4).astype(float))  # repeated x
        else:
            x = rng.uniform(0.0, 60.0, k + 4)  # unsorted
        line = np.column_stack([x, 1.8 + 0.01 * x + rng.normal(0.0, 0.05, len(x))])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rank warnings of degenerate fits
            for left, right in ((line, np.zeros((0, 2))), (np.zeros((0, 2)), line)):
                want = _polynomial_trajectory(left, right)
                assert driving_trajectory(left, right).tobytes() == want.tobytes()
            # A mixed pair: the fallback line as before, the sorted one compiled.
            want = _polynomial_trajectory(line, good)
            got = driving_trajectory(line, good)
            np.testing.assert_array_equal(got[:, 0], want[:, 0])
            np.testing.assert_allclose(got[:, 1], want[:, 1], rtol=0.0, atol=1e-9)


def test_path_kernels_match_their_python_references() -> None:
    from aldm_gym.sensor import trajectory as t

    rng = np.random.default_rng(8)
    for trial in range(50):
        lines = []
        for side in (1.0, -1.0):
            k = int(rng.choice([0, 4, 5, 13, 60]))
            x = np.sort(rng.uniform(5.0, 200.0, k))
            lines.append(np.column_stack([x, side * 1.8 + 2e-3 * x**2 + rng.normal(0, 0.1, k)]))
        reach = (np.inf, 80.0, 20.0)[trial % 3]
        ok_c, got = t.fit_path(lines[0], lines[1], 3.75, 2.0, reach)
        ok_p, want = t.fit_path_py(lines[0], lines[1], 3.75, 2.0, reach)
        assert ok_c == ok_p
        assert got.tobytes() == want.tobytes()
        for line in lines:
            assert t._cut_length(line, reach) == t._cut_length_py(line, reach)
        if len(lines[0]):
            xq = np.linspace(0.0, 100.0, 51)
            a = t._cubic_values(lines[0], xq)
            assert a.tobytes() == t._cubic_values_py(lines[0], xq).tobytes()


# --------------------------------------------------------------------------- path range
def near_path(left: np.ndarray, right: np.ndarray, lane_width: float, max_x: float) -> np.ndarray:
    """The environment's near-range path (frozen copy of ``envs.highway.near_path``):
    each line cut to its points with x <= ``max_x`` (at least its first 4), then the
    whole-line ``driving_trajectory``."""

    def cut(line: np.ndarray) -> np.ndarray:
        if len(line) <= 4:
            return line
        k = max(int(np.searchsorted(line[:, 0], max_x, side="right")), 4)
        return line[:k]

    return driving_trajectory(cut(left), cut(right), lane_width)


@pytest.mark.parametrize("reach", [0.5, 7.0, 30.0, 80.0, 1e9, np.inf])
def test_cut_length_is_searchsorted_with_at_least_4_points(reach: float) -> None:
    from aldm_gym.sensor import trajectory as t

    rng = np.random.default_rng(2)
    for k in (0, 1, 4, 5, 13, 100):
        x = np.sort(np.round(rng.uniform(0.0, 100.0, k)))  # repeated x too
        line = np.column_stack([x, np.zeros(k)])
        want = k if k <= 4 else max(int(np.searchsorted(x, reach, side="right")), 4)
        assert t._cut_length(line, reach) == t._cut_length_py(line, reach) == want


def test_path_range_is_the_fit_of_the_cut_lines() -> None:
    """``path_range`` = ``near_path``: compiled lines, fallback lines and single lines."""
    rng = np.random.default_rng(4)
    good = _line(-1.9, 1e-3)
    short = good[:3]
    repeated = np.repeat(_line(1.8, 1e-3, x1=60.0), 2, axis=0)  # x not increasing
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # rank warnings of degenerate fits
        for left in (_line(1.8, 2e-3), short, repeated, np.zeros((0, 2))):
            for right in (good, short, np.zeros((0, 2))):
                right = right + np.column_stack(
                    [np.zeros(len(right)), rng.normal(0, 0.05, len(right))]
                )
                for reach in (10.0, 80.0, 1e9):
                    want = near_path(left, right, 3.5, reach)
                    got = driving_trajectory(left, right, 3.5, path_range=reach)
                    assert got.tobytes() == want.tobytes()
                assert (
                    driving_trajectory(left, right, 3.5, path_range=None).tobytes()
                    == driving_trajectory(left, right, 3.5).tobytes()
                )
    for bad in (0.0, -5.0, float("nan")):
        with pytest.raises(ValueError, match="path_range"):
            driving_trajectory(good, good, path_range=bad)


def test_path_range_keeps_the_path_exact_near_the_car_in_a_tight_curve() -> None:
    """Against the true lane centre on a circle of R = 250 m: one cubic over the whole
    200 m view is off by almost 1 m near the car; the fit of the first 80 m by 1 cm."""
    radius = 250.0
    x = np.arange(5.52, 200.0, 2.0)

    # Circle through the origin tangent to x, centre (0, R): y = R - sqrt(R^2 - x^2).
    def arc(offset: float) -> np.ndarray:
        r = radius - offset
        xs = x[x < 0.97 * r]
        return np.column_stack([xs, radius - np.sqrt(r * r - xs * xs)])

    left, right = arc(1.875), arc(-1.875)
    near = driving_trajectory(left, right, path_range=80.0)
    whole = driving_trajectory(left, right)
    for path in (near, whole):
        assert path[0, 0] == 0.0
    sel = near[:, 0] <= 40.0
    true_near = radius - np.sqrt(radius**2 - near[sel, 0] ** 2)
    err_near = np.abs(near[sel, 1] - true_near).max()
    sel_w = whole[:, 0] <= 40.0
    err_whole = np.abs(whole[sel_w, 1] - (radius - np.sqrt(radius**2 - whole[sel_w, 0] ** 2))).max()
    assert err_near < 0.02 and err_whole > 0.5


def _detector_frames():  # type: ignore[no-untyped-def]
    """Seeded frames (road, frame, true lane) on a tight and a gentle road, noisy too."""
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor
    from aldm_gym.sensor.open_loop import sample_poses

    for seed, rcfg in ((3, {"min_radius": 100.0, "max_radius": 250.0}), (2, {})):
        base = HighwayRoad({**rcfg, "seed": seed, "length": 3000.0})
        poses = sample_poses(base, 6, np.random.default_rng(seed))
        for model in ("per_dash", "editor"):
            road = base.with_marking_model(model)
            for noise, drop in ((0.0, 0.0), (0.1, 0.2)):
                sensor = LineSensor({"lateral_noise": noise, "dropout": drop}, seed=seed)
                for p in poses:
                    yield road, sensor.measure(road, p.pose), p.lane_id


@pytest.mark.parametrize("name", ["aldm", "naive", "ground_truth"])
def test_detector_path_range_80_is_the_env_near_path_bit_for_bit(name: str) -> None:
    """``make_detector(name, path_range=80)``'s trajectory is what the environment's
    ``near_path(det.ego_left, det.ego_right, lane_width, 80)`` gives. The lane width
    of a one-line path is the road's for naive and ground truth; the ALDM uses its own
    estimate (checked in ``test_aldm``), so only its two-line frames are compared here."""
    from aldm_gym.sensor.detectors import make_detector

    near_det = make_detector(name, path_range=80.0)
    whole_det = make_detector(name)
    compared = 0
    for road, frame, lane_id in _detector_frames():
        det = near_det(frame, road, lane_id)
        whole = whole_det(frame, road, lane_id)
        for line in LaneDetection.__dataclass_fields__:
            if line not in ("trajectory", "source"):
                assert np.array_equal(getattr(det, line), getattr(whole, line))
        if name == "aldm" and not (det.found("ego_left") and det.found("ego_right")):
            continue
        want = near_path(det.ego_left, det.ego_right, road.lane_width, 80.0)
        assert det.trajectory.tobytes() == want.tobytes()
        compared += 1
    assert compared >= 40


@pytest.mark.parametrize(
    ("centre", "left"),
    [
        ("solid", 1),
        ("broken", 2),
        ("solid_broken", 2),  # broken on the right lane's side: it may be crossed from there
        ("broken_solid", 1),
        ("solid_solid", 1),
    ],
)
def test_paint_types_read_the_line_objects_under_the_ego_lines(
    tmp_path: Path, centre: str, left: int
) -> None:
    """On a two-way road of two lanes each way, the right lanes' lines as the sensor's
    line objects give them: the centre line as written (a double line by the stripe on
    the car's side), the lane line dashed (per dash and as one object), the edge line
    continuous; a line with no object under it, or none, is 0."""
    xodr = pytest.importorskip("scenariogeneration.xodr")
    mark = getattr(xodr, f"std_roadmark_{centre}")()
    road = xodr.create_road(
        [xodr.Line(1000)], id=0, left_lanes=2, right_lanes=2, lane_width=3.5, center_road_mark=mark
    )
    odr = xodr.OpenDrive(centre)
    odr.add_road(road)
    odr.adjust_roads_and_lanes()
    odr.write_xml(str(tmp_path / "road.xodr"))
    for model in ("per_dash", "editor"):
        r = OpenDriveRoad.from_file(tmp_path / "road.xodr", marking_model=model)
        sensor = LineSensor()
        inner = sensor.measure(r, r.lane_pose("0", -1, 400.0))
        got = paint_types(inner, detect_lanes(inner), names=LINE_NAMES)
        assert (got["ego_left"], got["ego_right"]) == (left, 2), model
        outer = sensor.measure(r, r.lane_pose("0", -2, 400.0))
        det = detect_lanes(outer)
        assert paint_types(outer, det) == {"ego_left": 2, "ego_right": 1}, model
        # a line 1.5 m off the paint, or none: no paint under it
        moved = LaneDetection(ego_left=det.ego_left + np.array([0.0, 1.5]))
        assert paint_types(outer, moved) == {"ego_left": 0, "ego_right": 0}


def test_paint_types_of_a_double_line_from_either_side() -> None:
    """The shipped ``features`` map's yellow centre line is solid beside a broken stripe
    0.24 m nearer the car's lane: broken from the car's side, continuous from the
    oncoming lane's (``far_side``)."""
    from aldm_gym.roads import shipped_map

    road = OpenDriveRoad.from_file(shipped_map("features"), marking_model="per_dash")
    frame = LineSensor().measure(road, road.lane_pose("1", -1, 100.0))
    det = detect_lanes(frame)
    assert paint_types(frame, det)["ego_left"] == 2
    assert paint_types(frame, det, far_side=True)["ego_left"] == 1
