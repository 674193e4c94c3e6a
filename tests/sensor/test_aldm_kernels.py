"""The ALDM's numba kernels (aldm_gym.sensor.aldm_kernels): twins, sorts, fit sums,
the fit window, a fully plain-Python run."""

from __future__ import annotations

from pathlib import Path

import _synthetic as S
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aldm_gym.sensor.aldm import _packed, detect_lanes, make_params
from aldm_gym.sensor.aldm_kernels import fit, grid, layout, output, robust, sort

from ._aldm_cases import frame, run_without_jit


# ----------------------------------------------------------------- kernels
def _kernel_inputs(seed: int, mode: str):  # type: ignore[no-untyped-def]
    _road, pts = frame(seed, radius=-200, noise=0.05, dropout=0.1)
    fp, ip = _packed(make_params(mode=mode))
    return pts, fp, ip


@pytest.mark.parametrize("mode", ["robust", "paper"])
@pytest.mark.parametrize("reach", [np.inf, 80.0])
def test_python_and_numba_pipeline_agree_exactly(mode: str, reach: float) -> None:
    """The top-level kernel as Python (its helpers compiled) vs fully compiled."""
    pts, fp, ip = _kernel_inputs(13, mode)
    got_py = output.detect_frame_py(pts, fp, ip, reach)
    got_nb = output.detect_frame(pts, fp, ip, reach)
    for a, b in zip(got_py, got_nb, strict=True):
        np.testing.assert_array_equal(a, b)


def test_leaf_kernels_python_and_numba_agree_exactly() -> None:
    pts, _fp, _ip = _kernel_inputs(14, "robust")
    xs, ys = sort.gather_py(pts, True, 0.5, 500.0)
    xs2, ys2 = sort.gather(pts, True, 0.5, 500.0)
    np.testing.assert_array_equal(xs, xs2)
    np.testing.assert_array_equal(ys, ys2)
    m = int(np.searchsorted(xs, 23.52, side="right"))
    np.testing.assert_array_equal(
        robust._seed_chains_py(xs, ys, m, 4.5, 1.5), robust._seed_chains(xs, ys, m, 4.5, 1.5)
    )
    label = np.arange(m) % (layout.N_LINES + 1) - 1  # -1: unlabelled
    mask_py, mask_nb = np.zeros(len(xs), np.uint8), np.zeros(len(xs), np.uint8)
    for a, b in zip(
        robust.claim_seeds_py(label, mask_py), robust.claim_seeds(label, mask_nb), strict=True
    ):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(mask_py, mask_nb)
    assert mask_nb[1] == 1 and mask_nb[0] == 0
    g_py, g_nb = grid.build_grid_py(xs, ys, 1.2), grid.build_grid(xs, ys, 1.2)
    for a, b in zip(g_py, g_nb, strict=True):
        np.testing.assert_array_equal(a, b)
    # the neighbouring-marking check of the trace's second look: a guide along the
    # parabola y = 0.001 x^2 and points on the parallel curve 0.75 m to its right
    gx = 5.0 + grid.GUIDE_STEP * np.arange(40)
    guide = np.column_stack([gx, 0.002 * gx, np.full(40, 0.001), 0.001 * gx * gx])
    px = np.arange(6.0, 90.0, 2.0)
    slope = 0.002 * px
    py = 0.001 * px * px - 0.75 * np.sqrt(1.0 + slope * slope)
    seen = set()
    for k in range(0, len(px), 5):
        d_py = grid._guide_normal_py(guide, px[k], py[k], 18.0)
        assert d_py == grid._guide_normal(guide, px[k], py[k], 18.0)
        assert abs(d_py + 0.75) < 0.01  # along the normal, however steep
        for off in (d_py, d_py + 0.3):
            got = grid._beside_py(px, py, guide, px[k], off, 18.0)
            assert got == grid._beside(px, py, guide, px[k], off, 18.0)
            seen.add(got)
    assert seen == {True, False}
    assert np.isnan(grid._guide_normal(guide, gx[-1] + 19.0, 0.0, 18.0))
    us, vs = xs[:20] - xs[19], ys[:20]
    w1, w2 = np.empty((2, 3, 3)), np.empty((2, 3, 3))
    r_py = fit._ridge_quadratic_py(us, vs, 20, 0.001, 0.0, 2.0, 1.0, 0.005, w1)
    r_nb = fit._ridge_quadratic(us, vs, 20, 0.001, 0.0, 2.0, 1.0, 0.005, w2)
    assert r_py[:3] == r_nb[:3]
    np.testing.assert_array_equal(r_py[3], r_nb[3])


@pytest.mark.parametrize("kind", ["uniform", "ties", "crowded", "constant", "empty"])
def test_start_region_y_order_is_a_sort(kind: str) -> None:
    """The start region's y order (the one bucket sort on ``ys[:m]``) is the stable
    ascending order."""
    rng = np.random.default_rng(7)
    ys = rng.uniform(-180.0, 180.0, 1200)
    if kind == "ties":
        ys = np.round(ys / 10.0) * 10.0
    elif kind == "crowded":  # most values in a few buckets (further passes), one far outlier
        ys[:1000] = np.round(rng.uniform(0.0, 1.0, 1000), 2)
        ys[1000] = -1e4
    elif kind == "constant":
        ys[:] = -0.0
    m = 0 if kind == "empty" else 1000  # only ys[:m] counts
    for order in (sort.bucket_order, sort.bucket_order_py):
        yo = order(ys[:m], ys[:m])
        np.testing.assert_array_equal(yo, np.argsort(ys[:m], kind="stable"))


def _sort_keys(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """``(k1, k2)`` of a named case of :func:`test_bucket_order_is_the_stable_lexsort`."""
    rng = np.random.default_rng(11)
    k1 = rng.uniform(0.0, 200.0, 2000)
    k2 = rng.uniform(-50.0, 50.0, 2000)
    if kind == "ties":
        k1, k2 = np.round(k1), np.round(k2)
    elif kind == "crowded":  # a few crowded buckets of mixed x, one far outlier
        k1[:1900] = np.round(rng.uniform(0.0, 1.0, 1900), 1)
        k1[0] = 1e4
    elif kind in ("grid", "grid_curve", "grid_duplicates"):  # columns of exact x ties
        pts = S.grid_frame(100, radius=500.0 if kind == "grid_curve" else np.inf)
        if kind == "grid_duplicates":  # also exact (x, y) ties
            pts = np.concatenate([pts, pts[:3000]])
        k1, k2 = pts[:, 0], pts[:, 1]
    elif kind == "one_column":  # one x: a pass over y only
        k1 = np.full(2000, 5.52)
    elif kind == "constant":  # all (x, y) tie: index order
        k1, k2 = np.zeros(2000), np.full(2000, -0.0)
    elif kind == "subnormal_range":  # too narrow to bucket: comparison sort
        k1 = np.where(rng.random(2000) < 0.5, 0.0, 5e-324)
    elif kind == "tiny_range":  # two adjacent doubles: still bucketed
        k1 = np.where(rng.random(2000) < 0.5, 1.0, np.nextafter(1.0, 2.0))
    elif kind == "huge":  # hi - lo would overflow
        k1 = rng.choice([-1.7e308, -1e300, 0.0, 3.0, 1e307, 1.7e308], 2000)
        k2 = rng.choice([-np.finfo(float).max, 0.0, np.finfo(float).max], 2000)
    elif kind == "geometric":  # each pass splits off a few: still crowded after the last
        k1 = 2.0 ** -rng.permutation(2000).astype(float)
    return k1, k2


@pytest.mark.parametrize(
    "kind",
    [
        "uniform",
        "ties",
        "crowded",
        "grid",
        "grid_curve",
        "grid_duplicates",
        "one_column",
        "constant",
        "subnormal_range",
        "tiny_range",
        "huge",
        "geometric",
    ],
)
def test_bucket_order_is_the_stable_lexsort(kind: str) -> None:
    """``bucket_order(k1, k2)`` is ``np.lexsort((k2, k1))`` exactly: lexicographic, ties
    in (k1, k2) in index order; the plain-Python twin never overflows."""
    k1, k2 = _sort_keys(kind)
    want = np.lexsort((k2, k1))
    for order in (sort.bucket_order, sort.bucket_order_py):
        with np.errstate(over="raise", divide="raise", invalid="raise"):
            got = order(k1, k2)
        np.testing.assert_array_equal(got, want)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 600),
    distinct=st.tuples(st.integers(1, 60), st.integers(1, 60)),
    scale=st.sampled_from([1.0, 200.0, 1e-310, 1e-200, 1e300, 1.7e308]),
)
def test_bucket_order_is_the_stable_lexsort_on_tied_keys(
    seed: int, n: int, distinct: tuple[int, int], scale: float
) -> None:
    """Keys drawn from a few values (columns of ties, as on the sensor's x grid), at
    any magnitude: the order of ``np.lexsort((k2, k1))``, compiled and plain Python."""
    rng = np.random.default_rng(seed)
    k1 = rng.choice(rng.uniform(-1.0, 1.0, distinct[0]) * scale, n)
    k2 = rng.choice(rng.uniform(-1.0, 1.0, distinct[1]) * scale, n)
    want = np.lexsort((k2, k1))
    np.testing.assert_array_equal(sort.bucket_order(k1, k2), want)
    with np.errstate(over="raise", divide="raise", invalid="raise"):
        np.testing.assert_array_equal(sort.bucket_order_py(k1, k2), want)


def test_fit_sums_update_adds_and_drops_exactly() -> None:
    """``update_sums`` with w = ±1 is the former add/drop pair bit for bit (frozen copy),
    and the sums it builds are the normal equations of the true quadratic."""

    def add_drop(sums: tuple, u: float, y: float, sign: float) -> tuple:
        s0, s1, s2, s3, s4, t0, t1, t2 = sums
        uu = u * u
        if sign > 0:
            return (
                s0 + 1.0,
                s1 + u,
                s2 + uu,
                s3 + uu * u,
                s4 + uu * uu,
                t0 + y,
                t1 + u * y,
                t2 + uu * y,
            )
        return (
            s0 - 1.0,
            s1 - u,
            s2 - uu,
            s3 - uu * u,
            s4 - uu * uu,
            t0 - y,
            t1 - u * y,
            t2 - uu * y,
        )

    rng = np.random.default_rng(5)
    us = -rng.uniform(0.0, 40.0, 60)
    ys = 1.8 + 0.02 * us + 1e-3 * us * us  # an exact quadratic
    sums_py = sums_nb = frozen = (0.0,) * 8
    for k in range(60):
        for w in (1.0, -1.0) if k % 7 == 3 else (1.0,):  # some points added and dropped
            sums_py = fit.update_sums_py(*sums_py, us[k], ys[k], w)
            sums_nb = fit.update_sums(*sums_nb, us[k], ys[k], w)
            frozen = add_drop(frozen, us[k], ys[k], w)
            assert sums_py == frozen and sums_nb == frozen
    for w in (1.0,):  # the dropped points back, then the fit of the true quadratic
        for k in range(3, 60, 7):
            sums_nb = fit.update_sums(*sums_nb, us[k], ys[k], w)
    want = [np.sum(us**j) for j in range(5)] + [np.sum(ys * us**j) for j in range(3)]
    np.testing.assert_allclose(sums_nb, want, rtol=1e-12)
    a, b, c, _ = fit.ridge_solve(*sums_nb, 0.0, 0.0, 0.0, 0.0, 1.0, np.empty((2, 3, 3)))
    np.testing.assert_allclose([a, b, c], [1e-3, 0.02, 1.8], rtol=1e-8)


@pytest.mark.parametrize("fit_length", [40.0, 20.0])
def test_trace_fit_window_dense_line_and_gap(fit_length: float) -> None:
    """The trace's running fit sums: > HIST points in the window, and a gap that leaves
    only the new point in it (fit_length 20 m < the 25 m gap < gap_search_length)."""
    x = np.concatenate([np.arange(5.0, 60.0, 0.25), np.arange(85.0, 180.0, 0.25)])
    pts = np.concatenate([np.column_stack([x, np.full_like(x, y)]) for y in (1.8, -1.9)])
    params = make_params(fit_length=fit_length, gap_search_length=30.0)
    det = detect_lanes(pts, params)
    for name, y in (("ego_left", 1.8), ("ego_right", -1.9)):
        line = getattr(det, name)
        assert line[0, 0] == 5.0 and line[-1, 0] == 179.75
        np.testing.assert_allclose(line[:, 1], y, atol=1e-9)
    # The trace kernel alone, plain Python vs compiled, on a noisy copy.
    noisy = pts + np.random.default_rng(3).normal(0.0, 0.05, pts.shape)
    fp, _ip = _packed(params)
    xs, ys = sort.gather(noisy, False, 0.5, 500.0)
    cells = grid.build_grid(xs, ys, fp[layout.P.gate_max])
    seed = (xs <= 23.52) & (ys > 0.0)
    first, last = np.flatnonzero(seed)[[0, -1]]
    masks, bit = [], np.uint8(2)
    for trace in (robust._robust_trace_py, robust._robust_trace):
        mask = np.where(seed, 2, 0).astype(np.uint8)
        trace(xs, ys, first, last, 0.0, 0.0, fp, 2.5, 1.0, np.zeros((0, 3)), cells, mask, bit)
        masks.append(mask)
    np.testing.assert_array_equal(masks[0], masks[1])
    assert xs[masks[1] == 2].max() > 170.0


@pytest.mark.slow
def test_fully_plain_python_run_agrees_with_numba(tmp_path: Path) -> None:
    """NUMBA_DISABLE_JIT=1: every kernel runs as plain Python in a subprocess."""
    _road, pts = frame(15, radius=300, noise=0.05, dropout=0.1)
    pts = pts[pts[:, 0] < 90.0]  # keep the pure-Python run short
    np.save(tmp_path / "pts.npy", pts)
    code = (
        "import json, sys, numpy as np\n"
        "from aldm_gym.sensor.aldm import detect_lanes\n"
        f"p = np.load({str(tmp_path / 'pts.npy')!r})\n"
        "out = {}\n"
        "for mode in ('robust', 'paper'):\n"
        "    d = detect_lanes(p, mode=mode)\n"
        "    out[mode] = {n: getattr(d, n).tolist() for n in "
        "('left_adjacent', 'ego_left', 'ego_right', 'right_adjacent', 'trajectory')}\n"
        "print(json.dumps(out))\n"
    )
    plain = run_without_jit(code)
    for mode in ("robust", "paper"):
        det = detect_lanes(pts, mode=mode)
        for name, value in plain[mode].items():
            np.testing.assert_array_equal(np.array(value).reshape(-1, 2), getattr(det, name))


@pytest.mark.slow
def test_the_neighbouring_marking_check_agrees_with_a_plain_python_run(tmp_path: Path) -> None:
    """A broken right edge line whose paint ends at 60 m beside a solid shoulder line
    0.75 m outside, in an R 400 m bend: the trace's neighbouring-marking check ends
    the right line at the paint, as plain Python (NUMBA_DISABLE_JIT=1) and compiled."""
    marks = [
        S.SynthMarking(5.25),
        S.SynthMarking(1.75),
        S.SynthMarking(-1.75, dashed=True, end_s=60.0),
        S.SynthMarking(-2.5),
    ]
    road = S.SynthRoad(marks, 1.0 / 400.0)
    pts, _ = S.sample(road, seed=1, x_range=100.0)
    np.save(tmp_path / "pts.npy", pts)
    code = (
        "import json, numpy as np\n"
        "from aldm_gym.sensor.aldm import detect_lanes\n"
        f"d = detect_lanes(np.load({str(tmp_path / 'pts.npy')!r}))\n"
        "print(json.dumps({n: getattr(d, n).tolist() for n in "
        "('left_adjacent', 'ego_left', 'ego_right', 'right_adjacent', 'trajectory')}))\n"
    )
    plain = run_without_jit(code)
    det = detect_lanes(pts)
    assert det.ego_right[-1, 0] < 60.0 and road.lateral_error(2, det.ego_right).max() < 0.3
    for name, value in plain.items():
        np.testing.assert_array_equal(np.array(value).reshape(-1, 2), getattr(det, name))


@pytest.mark.slow
def test_grid_frames_match_a_plain_python_run_with_np_lexsort(tmp_path: Path) -> None:
    """CarMaker-grid frames (columns of exact x ties): the compiled pipeline gives bit
    for bit what every kernel as plain Python gives with the bucket sort replaced by
    ``np.lexsort`` (NUMBA_DISABLE_JIT=1, a subprocess)."""
    frames = {
        "4 straight": S.grid_frame(4),
        "4 curve": S.grid_frame(4, radius=-500.0),
        "100 straight": S.grid_frame(100),
    }
    frames["100 straight"] = frames["100 straight"][frames["100 straight"][:, 0] < 60.0]
    np.savez(tmp_path / "frames.npz", **frames)
    code = (
        "import json, numpy as np\n"
        "from aldm_gym.sensor.aldm import detect_lanes\n"
        "from aldm_gym.sensor.aldm_kernels import robust, sort\n"
        "def lexsort_order(k1, k2):\n"
        "    return np.lexsort((k2, k1))\n"
        "sort.bucket_order = robust.bucket_order = lexsort_order\n"
        f"frames = np.load({str(tmp_path / 'frames.npz')!r})\n"
        "out = {}\n"
        "for key in frames.files:\n"
        "    d = detect_lanes(frames[key])\n"
        "    out[key] = {n: getattr(d, n).tolist() for n in "
        "('left_adjacent', 'ego_left', 'ego_right', 'right_adjacent', 'trajectory')}\n"
        "print(json.dumps(out))\n"
    )
    # The package this process imported, also where an installed copy is another one.
    plain = run_without_jit(code)
    for key, pts in frames.items():
        det = detect_lanes(pts)
        assert len(det.ego_left) == len(det.ego_right) == 13
        for name, value in plain[key].items():
            np.testing.assert_array_equal(np.array(value).reshape(-1, 2), getattr(det, name))


# ----------------------------------------------------------------- canonical order
@pytest.mark.parametrize("kind", ["uniform", "ties", "crowded", "signed_zero", "grid"])
def test_gather_is_the_lexicographic_sort_of_the_valid_points(kind: str) -> None:
    """The bucket sort equals np.lexsort by (x, y) of the kept rows, also for crowded
    buckets and columns of tied x."""
    rng = np.random.default_rng(5)
    pts = rng.uniform(-10.0, 300.0, (3000, 3))
    pts[:, 2] *= 0.003
    if kind == "ties":
        pts[:, :2] = np.round(pts[:, :2])
    elif kind == "crowded":  # most points in a few buckets (argsort path), one far outlier
        pts[:, 0] = np.round(rng.uniform(0.0, 1.0, 3000), 2)
        pts[0, 0] = 450.0
    elif kind == "signed_zero":
        pts[:300, 0] = -0.0
        pts[300:600, 1] = -0.0
    elif kind == "grid":  # CarMaker's x grid: columns of exact x ties, straight lines
        pts[:, :2] = S.grid_frame(40)[:3000, :2]
    pts[rng.integers(0, 3000, 20)] = np.nan
    keep = (pts[:, 0] >= 0) & (pts[:, 0] <= 500) & (np.abs(pts[:, 1]) <= 500)
    keep &= np.abs(pts[:, 2]) <= 0.5
    q = pts[keep] + 0.0
    o = np.lexsort((q[:, 1], q[:, 0]))
    for gather in (sort.gather, sort.gather_py):
        xs, ys = gather(pts[rng.permutation(len(pts))], True, 0.5, 500.0)
        np.testing.assert_array_equal(xs, q[o, 0])
        np.testing.assert_array_equal(ys, q[o, 1])
        assert not np.signbit(xs).any() and not np.signbit(ys[ys == 0.0]).any()
