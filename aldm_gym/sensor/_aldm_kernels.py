"""Numba kernels of the Advanced Lane Detection Model (ALDM).

Written the umap way: every kernel is a plain Python function ``_name_py`` (the
readable reference, runnable under ``NUMBA_DISABLE_JIT=1``) and its compiled twin
``_name = numba.njit(cache=True)(_name_py)``. Kernels call each other through the
compiled names, so with JIT disabled the whole pipeline is plain Python.

The public wrapper is :func:`aldm_gym.sensor.aldm.detect_lanes`; the algorithm and
every decision where the paper is silent are described in ``docs/aldm.md``.
Paper references are to the section "Advanced Lane Detection Model" (§ALDM).

All kernels work on points already sorted lexicographically by ``(x, y)`` (see
:func:`_gather`), so every decision below depends on point *values* only: input
order can never change a result. No ``fastmath`` (NaN/inf must keep IEEE semantics
and results must be bit-identical with the plain-Python reference).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aldm_gym.sensor.trajectory import PATH_STEP, _path

# --------------------------------------------------------------------------- types
# Array types of the kernels' arguments (pynndescent habit). Signatures are inferred
# lazily on the first call and cached on disk (``cache=True``), so importing the
# package never compiles anything.
F8_1D = numba.types.Array(numba.types.float64, 1, "C")
"""``(N,)`` float64: sorted x or y coordinates [m], parameter vectors."""
F8_2D = numba.types.Array(numba.types.float64, 2, "C")
"""``(N, 2|3)`` float64: raw points (x, y[, z]) [m]; ``(K, 2)`` output lines."""
I8_1D = numba.types.Array(numba.types.int64, 1, "C")
"""``(N,)`` int64: sort order, point indices, component labels."""
U1_1D = numba.types.Array(numba.types.uint8, 1, "C")
"""``(N,)`` uint8: per point bit mask of the lines (bit ``l``) that own it."""

# ------------------------------------------------------------- parameter layout
# Float parameters are passed as one float64 vector, integer ones as one int64 vector
# (module-level ints are compile-time constants inside numba).
P_START_X_MAX = 0  # start points only at x <= this [m] (paper: 18 + 5.52)
P_START_SPACING = 1  # paper mode: start points at least this far apart in x [m]
P_SEARCH = 2  # next-point search window ahead of the last point [m] (paper: 18)
P_ADJ_OFFSET = 3  # adjacent line starts this far outside the ego line [m] (paper: 2)
P_NOISE = 4  # robust: design lateral noise sigma [m]
P_GATE_SIGMAS = 5  # robust: residual gate in predicted standard deviations
P_GATE_MIN = 6  # robust: smallest residual gate [m]
P_GATE_MAX = 7  # robust: largest residual gate [m]
P_FIT_LENGTH = 8  # robust: fit uses accepted points within this x distance [m]
P_A_MAX = 9  # robust: |a| bound of y = a x^2 + ..., 1 / (2 R_min) [1/m]
P_A_STD = 10  # robust: prior std of a [1/m]
P_B_STD = 11  # robust: prior std of the slope dy/dx [-]
P_LINK_DX = 12  # robust seeds: link points at most this far apart in x [m]
P_LINK_DY = 13  # robust seeds: ... and this far apart in y [m]
P_MERGE_DY = 14  # robust seeds: chains whose offsets differ less are one line [m]
P_MAX_EGO = 15  # robust: an ego line passes within this |y| of the sensor [m]
P_MAX_LANE = 16  # robust: adjacent line at most this far outside the ego line [m]
P_SMOOTH_H = 17  # smoothed output: half width of the local quadratic fit [m]
P_TIE_DX = 18  # robust: gated points within this x of the first one compete [m]
P_LANE_WIDTH = 19  # default lane width for a one-line trajectory [m]
P_MIN_LANE = 20  # smallest plausible lane width [m] (lane-width estimate)
P_Z_BAND = 21  # points with |z| above this are not road paint (overpass, barrier) [m]
P_MAX_RANGE = 22  # points farther ahead or sideways are ignored [m]
P_VIEW_RANGE = 23  # paper mode: the sensor's range of view [m] (trace end)
P_GAP_SEARCH = 24  # robust: next-point window, bridging a missing dash [m]
P_MAX_SLOPE = 25  # robust: a trace stops where its slope |dy/dx| exceeds this [-]
P_GUIDE_A_STD = 26  # robust: prior std of a about the guide line's [1/m]
P_GUIDE_B_STD = 27  # robust: prior std of the slope about the guide line's [-]
N_FLOAT_PARAMS = 28
GUIDE_MIN_POINTS = 6  # a guide line needs this many points ...
GUIDE_MIN_EXTENT = 30.0  # ... over at least this x extent [m]
GUIDE_STEP = 2.0  # x step of the guide's shape table [m]

I_PAPER = 0  # 1: the paper's literal algorithm, 0: the robust variant
I_START_POINTS = 1  # paper mode: number of start points per line (3)
I_MIN_SEED = 2  # robust: fewest start-region points of a line
I_N_OUT = 3  # points per output line (0: all traced points)
I_SMOOTH = 4  # 1: output the smoothed line, 0: the measured points
N_INT_PARAMS = 5

N_LINES = 4
# Line slots, in the order of LINE_NAMES: left_adjacent, ego_left, ego_right,
# right_adjacent.
L_LEFT_ADJ = 0
L_EGO_LEFT = 1
L_EGO_RIGHT = 2
L_RIGHT_ADJ = 3
HIST = 64  # ring buffer of the most recent accepted points of a traced line


# ===================================================================== gather
SMALL_RUN = 16  # buckets up to this size are sorted by insertion, larger ones by argsort


def _sort_run_py(xs, ys, a, b):
    """Sort ``xs[a:b], ys[a:b]`` in place lexicographically by ``(x, y)`` (a crowded bucket)."""
    o = np.argsort(xs[a:b])
    sx = xs[a:b][o]
    sy = ys[a:b][o]
    xs[a:b] = sx
    ys[a:b] = sy
    # Runs of equal x by y (the argsort need not be stable or lexicographic).
    i = a
    while i < b:
        j = i + 1
        while j < b and xs[j] == xs[i]:
            j += 1
        if j - i > 1:
            ys[i:j] = np.sort(ys[i:j])
        i = j


_sort_run = numba.njit(cache=True)(_sort_run_py)


def _gather_py(pts, has_z, z_band, max_range):
    """Valid points in canonical order: sorted lexicographically by ``(x, y)``.

    Rows with a non-finite coordinate, with x < 0 (behind the sensor), with x or |y|
    beyond ``max_range`` or, when ``has_z``, with ``|z| > z_band`` (an overpass's
    lines, barriers) are dropped; ``-0.0`` becomes ``0.0``. The result is a function
    of the point set only, never of the input order.

    Sorting is a bucket sort by x (as many buckets as points over the x range, then
    each bucket by ``(x, y)``): O(N) for the sensor's roughly uniform x, and
    O(N log N) at worst (a crowded bucket is sorted by ``np.argsort``). The bucket
    index is monotone in x, so the buckets concatenate in order.

    :return: ``(xs, ys)``, each ``(M,)`` [m].
    """
    n = pts.shape[0]
    # key[i]: 0 for a usable row, -1 for a dropped one; then the row's bucket
    key = np.empty(n, dtype=np.int64)
    m = 0
    lo = np.inf
    hi = -np.inf
    for i in range(n):
        key[i] = -1
        x = pts[i, 0]
        y = pts[i, 1]
        if not (0.0 <= x <= max_range and abs(y) <= max_range):
            continue  # also drops NaN (comparisons are False) and inf
        if has_z:
            z = pts[i, 2]
            if not math.isfinite(z) or abs(z) > z_band:
                continue
        key[i] = 0
        lo = min(lo, x)
        hi = max(hi, x)
        m += 1
    xs = np.empty(m)
    ys = np.empty(m)
    if m == 0:
        return xs, ys
    scale = m / (hi - lo) if hi > lo else 0.0
    if not math.isfinite(scale):
        scale = 0.0  # a sub-normal x range: one bucket
    # cnt[b + 1]: size of bucket b, then (prefix sum) its start, then (scatter) its end
    cnt = np.zeros(m + 1, dtype=np.int64)
    for i in range(n):
        if key[i] == 0:
            b = min(int((pts[i, 0] - lo) * scale), m - 1)
            key[i] = b
            cnt[b + 1] += 1
    run = 0
    for b in range(m):
        c = cnt[b + 1]
        cnt[b + 1] = run
        run += c
    for i in range(n):
        b = key[i]
        if b >= 0:
            q = cnt[b + 1]
            cnt[b + 1] = q + 1
            xs[q] = pts[i, 0] + 0.0  # -0.0 -> 0.0
            ys[q] = pts[i, 1] + 0.0
    # now bucket b is [cnt[b], cnt[b + 1])
    for b in range(m):
        s = cnt[b]
        e = cnt[b + 1]
        if e - s > SMALL_RUN:
            _sort_run(xs, ys, s, e)
            continue
        # insertion sort by (x, y), inline: most buckets hold 0-3 points
        for i in range(s + 1, e):
            x = xs[i]
            y = ys[i]
            j = i - 1
            while j >= s and (xs[j] > x or (xs[j] == x and ys[j] > y)):
                xs[j + 1] = xs[j]
                ys[j + 1] = ys[j]
                j -= 1
            xs[j + 1] = x
            ys[j + 1] = y
    return xs, ys


_gather = numba.njit(cache=True)(_gather_py)


# ============================================================ small linear algebra
def _inv3_py(m, inv):
    """Inverse of a 3×3 matrix by the adjugate (as the paper's C code, §ALDM).

    Writes the inverse into ``inv`` (zeros when ``det == 0``).

    :return: ``det``.
    """
    c00 = m[1, 1] * m[2, 2] - m[1, 2] * m[2, 1]
    c01 = m[1, 2] * m[2, 0] - m[1, 0] * m[2, 2]
    c02 = m[1, 0] * m[2, 1] - m[1, 1] * m[2, 0]
    det = m[0, 0] * c00 + m[0, 1] * c01 + m[0, 2] * c02
    if det == 0.0 or not math.isfinite(det):
        inv[:, :] = 0.0
        return 0.0
    inv[0, 0] = c00 / det
    inv[1, 0] = c01 / det
    inv[2, 0] = c02 / det
    inv[0, 1] = (m[0, 2] * m[2, 1] - m[0, 1] * m[2, 2]) / det
    inv[1, 1] = (m[0, 0] * m[2, 2] - m[0, 2] * m[2, 0]) / det
    inv[2, 1] = (m[0, 1] * m[2, 0] - m[0, 0] * m[2, 1]) / det
    inv[0, 2] = (m[0, 1] * m[1, 2] - m[0, 2] * m[1, 1]) / det
    inv[1, 2] = (m[0, 2] * m[1, 0] - m[0, 0] * m[1, 2]) / det
    inv[2, 2] = (m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]) / det
    return det


_inv3 = numba.njit(cache=True)(_inv3_py)


def _add_sums_py(s0, s1, s2, s3, s4, t0, t1, t2, u, y):
    """The running fit sums with the point ``(u, y)`` added (u = x - x_last) [m].

    ``s_k = Σ u^k`` (k = 0..4) and ``t_k = Σ u^k y`` (k = 0..2): the normal equations
    of the quadratic fit ``y = A u² + B u + C``.
    """
    uu = u * u
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


_add_sums = numba.njit(cache=True, inline="always")(_add_sums_py)


def _drop_sums_py(s0, s1, s2, s3, s4, t0, t1, t2, u, y):
    """The running fit sums without the point ``(u, y)`` (u = x - x_last) [m].

    ``s_k = Σ u^k`` (k = 0..4) and ``t_k = Σ u^k y`` (k = 0..2) of the points in the
    fit window; the inverse of :func:`_add_sums_py`.
    """
    uu = u * u
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


_drop_sums = numba.njit(cache=True, inline="always")(_drop_sums_py)


def _ridge_quadratic_py(us, ys, n, a0, b0, lam_a, lam_b, a_max, work):
    """Ridge least-squares quadratic ``y = A u^2 + B u + C`` through ``n`` points.

    Gaussian priors ``A ~ a0`` and ``B ~ b0`` enter as ``lam_a = sigma^2/sigma_A^2``
    and ``lam_b = sigma^2/sigma_B^2`` (MAP estimate); ``|A|`` is then bounded by
    ``a_max`` (minimum curve radius) and B, C refitted with A fixed.

    ``work`` is a ``(2, 3, 3)`` scratch array (no allocation per call): ``work[0]``
    receives the regularised normal matrix, ``work[1]`` its inverse.

    :return: ``(A, B, C, inv)``; ``inv = work[1]``, ``sigma^2 * inv`` is the
        coefficient covariance.
    """
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    s4 = 0.0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for k in range(n):
        s0, s1, s2, s3, s4, t0, t1, t2 = _add_sums(s0, s1, s2, s3, s4, t0, t1, t2, us[k], ys[k])
    return _ridge_solve(s0, s1, s2, s3, s4, t0, t1, t2, a0, b0, lam_a, lam_b, a_max, work)


_ridge_quadratic = numba.njit(cache=True)(_ridge_quadratic_py)


def _ridge_solve_py(s0, s1, s2, s3, s4, t0, t1, t2, a0, b0, lam_a, lam_b, a_max, work):
    """:func:`_ridge_quadratic` from the point sums ``s_k = sum u^k``, ``t_k = sum y u^k``.

    Lets a trace keep running sums over its sliding fit window (:func:`_robust_trace`).
    """
    m = work[0]
    inv = work[1]
    m[0, 0] = s4 + lam_a
    m[0, 1] = s3
    m[0, 2] = s2
    m[1, 0] = s3
    m[1, 1] = s2 + lam_b
    m[1, 2] = s1
    m[2, 0] = s2
    m[2, 1] = s1
    m[2, 2] = s0
    r0 = t2 + lam_a * a0
    r1 = t1 + lam_b * b0
    r2 = t0
    det = _inv3(m, inv)
    if det == 0.0:
        # Degenerate (no points and no prior): the prior alone, through the mean.
        c = t0 / s0 if s0 > 0.0 else 0.0
        return a0, b0, c, inv
    a = inv[0, 0] * r0 + inv[0, 1] * r1 + inv[0, 2] * r2
    b = inv[1, 0] * r0 + inv[1, 1] * r1 + inv[1, 2] * r2
    c = inv[2, 0] * r0 + inv[2, 1] * r1 + inv[2, 2] * r2
    # y'' = kappa (1 + y'^2)^(3/2): the bound on A grows with the slope at u = 0.
    bound = a_max * (1.0 + b * b) ** 1.5
    if abs(a) > bound:
        a = bound if a > 0.0 else -bound
        # [[s2 + lam_b, s1], [s1, s0]] [b, c] = [r1 - a s3, t0 - a s2]
        q00 = s2 + lam_b
        d2 = q00 * s0 - s1 * s1
        v0 = r1 - a * s3
        v1 = t0 - a * s2
        if d2 != 0.0:
            b = (s0 * v0 - s1 * v1) / d2
            c = (q00 * v1 - s1 * v0) / d2
    return a, b, c, inv


_ridge_solve = numba.njit(cache=True)(_ridge_solve_py)


# =============================================================== paper mode
def _paper_start_py(xs, ys, m, side, ref, min_off, k, spacing, out):
    """The paper's start condition (§ALDM) on one side.

    Among points ``0..m-1`` (those with x <= 23.52 m) on the side (``side = +1``:
    y > 0, ``-1``: y <= 0), pick greedily the ``k`` points of lowest |y| that are
    pairwise at least ``spacing`` apart *in x* (so the 3×3 system is regular).
    For an adjacent line, ``ref`` holds the parabola (a, b, c) of the ego line's
    start points and a point must lie ``min_off`` or more outside it at its own x.
    Ties in |y| go to the smaller (x, y).

    :return: number of points chosen, written to ``out`` sorted by x.
    """
    got = 0
    for _ in range(k):
        best = -1
        best_key = np.inf
        for i in range(m):
            y = ys[i]
            if side > 0:
                if not y > 0.0:
                    continue
            elif not y <= 0.0:
                continue
            if min_off > 0.0:
                x = xs[i]
                yr = (ref[0] * x + ref[1]) * x + ref[2]
                if side * (y - yr) < min_off:
                    continue
            ok = True
            for j in range(got):
                if abs(xs[i] - xs[out[j]]) < spacing:
                    ok = False
                    break
            if not ok:
                continue
            key = abs(y)
            if key < best_key:
                best_key = key
                best = i
        if best < 0:
            break
        out[got] = best
        got += 1
    # Sort the chosen indices (index order is (x, y) order).
    for i in range(1, got):
        v = out[i]
        j = i - 1
        while j >= 0 and out[j] > v:
            out[j + 1] = out[j]
            j -= 1
        out[j + 1] = v
    return got


_paper_start = numba.njit(cache=True)(_paper_start_py)


def _parabola_py(x0, y0, x1, y1, x2, y2, x):
    """The exact parabola through three points (paper eq. for a, b, c), at ``x``.

    Evaluated in Lagrange form: the same function as the paper's 3×3 inverse,
    without its loss of precision at x ~ 200 m.
    """
    l0 = (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2))
    l1 = (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2))
    l2 = (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1))
    return y0 * l0 + y1 * l1 + y2 * l2


_parabola = numba.njit(cache=True)(_parabola_py)


def _paper_coeffs_py(xs, ys, idx):
    """Coefficients (a, b, c) of the parabola through points ``idx[0:3]``."""
    x0 = xs[idx[0]]
    x1 = xs[idx[1]]
    x2 = xs[idx[2]]
    y0 = ys[idx[0]]
    y1 = ys[idx[1]]
    y2 = ys[idx[2]]
    d01 = (y1 - y0) / (x1 - x0)
    d12 = (y2 - y1) / (x2 - x1)
    a = (d12 - d01) / (x2 - x0)
    b = d01 - a * (x0 + x1)
    c = y0 - (a * x0 + b) * x0
    out = np.empty(3)
    out[0] = a
    out[1] = b
    out[2] = c
    return out


_paper_coeffs = numba.njit(cache=True)(_paper_coeffs_py)


def _paper_trace_py(xs, ys, start, search, view, mask, bit):
    """The paper's trace (§ALDM steps 1–3) from three start points.

    Repeatedly fit the exact parabola through the last three points and take, among
    all points with ``x_last < x <= x_last + search``, the one with the smallest
    ``|y - f(x)|`` (ties: smaller (x, y)). No gate, no exclusivity (the paper traces
    every line on all points). "Repeating this until the sensor's range of view is
    reached": the trace stops when the window holds no point or would reach past
    the range of view ``view`` (without a gate, a window past the end of the line's
    visible part could only hold other lines' points).
    Sets bit ``bit`` of ``mask`` on every point of the line.
    """
    n = xs.shape[0]
    i0 = start[0]
    i1 = start[1]
    i2 = start[2]
    for t in range(3):
        mask[start[t]] |= bit
    while True:
        x_last = xs[i2]
        if x_last + search > view:
            break
        k = i2 + 1
        while k < n and xs[k] <= x_last:
            k += 1
        best = -1
        best_r = np.inf
        while k < n and xs[k] <= x_last + search:
            f = _parabola(xs[i0], ys[i0], xs[i1], ys[i1], xs[i2], ys[i2], xs[k])
            r = abs(ys[k] - f)
            if r < best_r:
                best_r = r
                best = k
            k += 1
        if best < 0:
            break
        mask[best] |= bit
        i0 = i1
        i1 = i2
        i2 = best


_paper_trace = numba.njit(cache=True)(_paper_trace_py)


def _paper_detect_py(xs, ys, fp, ip, mask, offsets):
    """The paper's ALDM: start conditions and traces of the four lines.

    ``offsets[l]`` receives each found line's start-parabola value at x = 0 [m]
    (used for the lane-width estimate), NaN when not found.
    """
    n = xs.shape[0]
    m = 0
    while m < n and xs[m] <= fp[P_START_X_MAX]:
        m += 1
    k = ip[I_START_POINTS]
    spacing = fp[P_START_SPACING]
    start = np.zeros(max(k, 3), dtype=np.int64)
    ref = np.zeros(3)
    refs = np.zeros((N_LINES, 3))
    found = np.zeros(N_LINES, dtype=np.bool_)
    for slot in range(N_LINES):
        offsets[slot] = np.nan
    # Ego lines first, then each adjacent line relative to its ego line.
    slots = np.array([L_EGO_LEFT, L_EGO_RIGHT, L_LEFT_ADJ, L_RIGHT_ADJ])
    for step in range(N_LINES):
        slot = slots[step]
        side = 1 if slot <= L_EGO_LEFT else -1
        min_off = 0.0
        if slot == L_LEFT_ADJ or slot == L_RIGHT_ADJ:
            ego = L_EGO_LEFT if slot == L_LEFT_ADJ else L_EGO_RIGHT
            if not found[ego]:
                continue
            ref[:] = refs[ego]
            min_off = fp[P_ADJ_OFFSET]
        got = _paper_start(xs, ys, m, side, ref, min_off, k, spacing, start)
        if got < k or got < 3:
            continue  # fewer start points than required: the line is not found
        # The trace continues from the last three start points.
        coeffs = _paper_coeffs(xs, ys, start[got - 3 : got])
        refs[slot] = coeffs
        offsets[slot] = coeffs[2]
        found[slot] = True
        for t in range(got - 3):
            mask[start[t]] |= np.uint8(1 << slot)
        _paper_trace(
            xs, ys, start[got - 3 : got], fp[P_SEARCH], fp[P_VIEW_RANGE], mask, np.uint8(1 << slot)
        )


_paper_detect = numba.njit(cache=True)(_paper_detect_py)


# ============================================================== search grid
def _build_grid_py(xs, ys, cell_y):
    """Bucket the sorted points into an x-by-y grid (counting sort, O(N + cells)).

    Cells are 2 m in x (one sensor sample) by ``2 cell_y`` in y, coarsened until
    there are at most ``N + 1024`` cells. Within a cell points keep their
    canonical (x, y) order. A point's cell is ``floor((x - x0) * (1 / gx))`` by
    ``floor((y - y0) * (1 / gy))`` (clipped), the same monotone maps the search uses
    (:func:`_cell_rows`), so a search range in x and y covers every cell that can
    hold a point in it.

    :return: ``(geo, start, pts)``: ``geo = (x0, 1/gx, y0, 1/gy, nx, ny)``; the
        points of cell ``c = bx * ny + by`` are ``pts[start[c]:start[c + 1]]``.
    """
    n = xs.shape[0]
    geo = np.zeros(6)
    if n == 0:
        geo[1] = 1.0
        geo[3] = 1.0
        geo[4] = 1.0
        geo[5] = 1.0
        return geo, np.zeros(2, dtype=np.int64), np.zeros(0, dtype=np.int64)
    x0 = xs[0]
    y0 = ys[0]
    y1 = ys[0]
    for i in range(n):
        y0 = min(y0, ys[i])
        y1 = max(y1, ys[i])
    gx = 2.0
    gy = max(2.0 * cell_y, 0.5)
    nx = int((xs[n - 1] - x0) / gx) + 1
    ny = int((y1 - y0) / gy) + 1
    while nx * ny > n + 1024:
        if nx >= ny:
            gx *= 2.0
        else:
            gy *= 2.0
        nx = int((xs[n - 1] - x0) / gx) + 1
        ny = int((y1 - y0) / gy) + 1
    igx = 1.0 / gx
    igy = 1.0 / gy
    nc = nx * ny
    # start[c]: count of cell c, then (prefix sum) its end, then (scatter) its start;
    # each point's cell is computed once (cell[i]).
    start = np.zeros(nc + 1, dtype=np.int64)
    cell = np.empty(n, dtype=np.int64)
    for i in range(n):
        bx = min(int((xs[i] - x0) * igx), nx - 1)
        by = min(int((ys[i] - y0) * igy), ny - 1)
        c = bx * ny + by
        cell[i] = c
        start[c] += 1
    for c in range(1, nc):
        start[c] += start[c - 1]
    pts = np.empty(n, dtype=np.int64)
    for i in range(n - 1, -1, -1):
        c = cell[i]
        start[c] -= 1
        pts[start[c]] = i
    start[nc] = n
    geo[0] = x0
    geo[1] = igx
    geo[2] = y0
    geo[3] = igy
    geo[4] = nx
    geo[5] = ny
    return geo, start, pts


_build_grid = numba.njit(cache=True)(_build_grid_py)


def _gated_py(xs, ys, k, x_last, A, B, C, inv, fp, sig2):
    """|residual| of point k against the prediction, or -1 if it fails the gate.

    The gate is ``gate_sigmas`` predicted standard deviations (noise plus the fit's
    covariance at look-ahead u), clipped to [gate_min, gate_max]; the model must
    also stay flatter than ``max_slope`` up to the point.
    """
    u = xs[k] - x_last
    if abs(2.0 * A * u + B) > fp[P_MAX_SLOPE]:
        return -1.0
    r = abs(ys[k] - ((A * u + B) * u + C))
    if r > fp[P_GATE_MAX]:
        return -1.0
    p0 = u * u
    # predicted variance / sig2: 1 + phi' inv phi, phi = (u^2, u, 1)
    v = (
        inv[0, 0] * p0 * p0
        + 2.0 * inv[0, 1] * p0 * u
        + 2.0 * inv[0, 2] * p0
        + inv[1, 1] * u * u
        + 2.0 * inv[1, 2] * u
        + inv[2, 2]
    )
    gate = fp[P_GATE_SIGMAS] * math.sqrt(sig2 * (1.0 + max(v, 0.0)))
    gate = min(max(gate, fp[P_GATE_MIN]), fp[P_GATE_MAX])
    if r <= gate:
        return r
    return -1.0


_gated = numba.njit(cache=True)(_gated_py)


def _cell_rows_py(geo, x_last, xa, xb, A, B, C, margin):
    """Range ``(by0, by1)`` of y cells the prediction ± margin crosses on [xa, xb]."""
    ua = xa - x_last
    ub = xb - x_last
    fa = (A * ua + B) * ua + C
    fb = (A * ub + B) * ub + C
    lo = min(fa, fb)
    hi = max(fa, fb)
    if A != 0.0:
        uv = -B / (2.0 * A)
        if ua < uv < ub:
            fv = (A * uv + B) * uv + C
            lo = min(lo, fv)
            hi = max(hi, fv)
    eps = 1e-9 * (1.0 + abs(lo) + abs(hi))
    ny = int(geo[5])
    fy0 = (lo - margin - eps - geo[2]) * geo[3]
    fy1 = (hi + margin + eps - geo[2]) * geo[3]
    if fy1 < 0.0 or fy0 >= ny:
        return 0, -1
    by0 = max(math.floor(fy0), 0)
    by1 = min(math.floor(fy1), ny - 1)
    return by0, by1


_cell_rows = numba.njit(cache=True)(_cell_rows_py)


def _grid_search_py(xs, ys, mask, geo, start, pts, x_last, A, B, C, inv, fp, sig2, search):
    """Next point of a robust trace (§ALDM step 2 with a gate), via the grid.

    Among unclaimed points with ``x_last < x <= x_last + search`` that pass the
    gate (:func:`_gated`), the nearest in x wins; gated points within ``tie_dx`` of
    it compete by |residual| (ties: smaller (x, y)). Only grid cells the
    prediction ± gate_max crosses are visited.

    :return: index of the chosen point, or -1.
    """
    n = xs.shape[0]
    if n == 0:
        return -1
    x0 = geo[0]
    igx = geo[1]
    gx = 1.0 / igx
    nx = int(geo[4])
    ny = int(geo[5])
    x_hi = x_last + search
    tie_dx = fp[P_TIE_DX]
    gm = fp[P_GATE_MAX]
    bx0 = min(int((x_last - x0) * igx), nx - 1) if x_last >= x0 else 0
    bx1 = min(int((x_hi - x0) * igx), nx - 1)
    # pass 1: the nearest gated x (bins are visited in x order)
    x_first = np.inf
    bx_first = -1
    for bx in range(bx0, bx1 + 1):
        xa = max(x0 + bx * gx, x_last)
        xb = min(x0 + (bx + 1) * gx, x_hi)
        by0, by1 = _cell_rows(geo, x_last, xa, xb, A, B, C, gm)
        for by in range(by0, by1 + 1):
            c = bx * ny + by
            for q in range(start[c], start[c + 1]):
                k = pts[q]
                x = xs[k]
                if x <= x_last or x > x_hi or mask[k] != 0 or x >= x_first:
                    continue
                if _gated(xs, ys, k, x_last, A, B, C, inv, fp, sig2) >= 0.0:
                    x_first = x
        if x_first < np.inf:
            bx_first = bx
            break
    if bx_first < 0:
        return -1
    # pass 2: smallest residual among gated points within tie_dx of x_first
    x_tie = min(x_first + tie_dx, x_hi)
    bx2 = min(int((x_tie - x0) * igx), nx - 1)
    best = -1
    best_r = np.inf
    for bx in range(bx_first, bx2 + 1):
        xa = max(x0 + bx * gx, x_last)
        xb = min(x0 + (bx + 1) * gx, x_hi)
        by0, by1 = _cell_rows(geo, x_last, xa, xb, A, B, C, gm)
        for by in range(by0, by1 + 1):
            c = bx * ny + by
            for q in range(start[c], start[c + 1]):
                k = pts[q]
                x = xs[k]
                if x < x_first or x > x_tie or mask[k] != 0:
                    continue
                r = _gated(xs, ys, k, x_last, A, B, C, inv, fp, sig2)
                if r >= 0.0 and (r < best_r or (r == best_r and k < best)):
                    best_r = r
                    best = k
    return best


_grid_search = numba.njit(cache=True)(_grid_search_py)


# ============================================================== robust mode
def _find_py(parent, i):
    """Union-find root with path halving."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


_find = numba.njit(cache=True)(_find_py)


def _argsort_y_py(ys, m):
    """Indices of ``ys[:m]`` in ascending order (ties in any order), by a bucket sort.

    As :func:`_gather`: one bucket per value over the range, insertion sort inside
    a bucket, ``np.argsort`` for a crowded one, so O(m) for spread values and
    O(m log m) at worst. Cheaper than ``np.argsort`` for the ~1,000 start-region
    points of a crowded frame.
    """
    yo = np.empty(m, dtype=np.int64)
    if m == 0:
        return yo
    lo = ys[0]
    hi = ys[0]
    for i in range(m):
        lo = min(lo, ys[i])
        hi = max(hi, ys[i])
    scale = m / (hi - lo) if hi > lo else 0.0
    if not math.isfinite(scale):
        scale = 0.0
    key = np.empty(m, dtype=np.int64)
    cnt = np.zeros(m + 1, dtype=np.int64)
    for i in range(m):
        b = min(int((ys[i] - lo) * scale), m - 1)
        key[i] = b
        cnt[b + 1] += 1
    for b in range(m):
        cnt[b + 1] += cnt[b]
    fill = cnt[:m].copy()
    for i in range(m):
        b = key[i]
        yo[fill[b]] = i
        fill[b] += 1
    for b in range(m):
        s = cnt[b]
        e = cnt[b + 1]
        if e - s > SMALL_RUN:
            yo[s:e] = yo[s:e][np.argsort(ys[yo[s:e]])]
            continue
        for i in range(s + 1, e):
            v = yo[i]
            y = ys[v]
            j = i - 1
            while j >= s and ys[yo[j]] > y:
                yo[j + 1] = yo[j]
                j -= 1
            yo[j + 1] = v
    return yo


_argsort_y = numba.njit(cache=True)(_argsort_y_py)


def _seed_chains_py(xs, ys, m, link_dx, link_dy):
    """Chain start-region points into pieces of marking (robust start condition).

    Each point ``i < m`` links to its best predecessor: the point j with
    ``x_i - link_dx <= x_j < x_i`` of smallest ``|y_i - y_j| <= link_dy`` (ties:
    the larger index, i.e. the larger (x, y)). Linked points form a component
    (union-find, the smaller index is the root), so a dash or a continuous line
    becomes one chain. Candidates are found through the points' y order, so the
    cost grows with the points of one marking, not with the number of markings.

    :return: ``(M,)`` component root of every start-region point.
    """
    parent = np.arange(m)
    # Any sort will do: the candidates of a point are all those within link_dy in y
    # whatever the order among equal y, and the choice among them is by value.
    yo = _argsort_y(ys, m)
    pos = np.empty(m, dtype=np.int64)
    for q in range(m):
        pos[yo[q]] = q
    for i in range(m):
        best = -1
        best_d = np.inf
        for direction in (-1, 1):
            q = pos[i] + direction
            while 0 <= q < m:
                j = yo[q]
                d = abs(ys[i] - ys[j])
                if d > link_dy:
                    break
                if xs[i] - link_dx <= xs[j] < xs[i]:
                    if d < best_d or (d == best_d and j > best):
                        best_d = d
                        best = j
                q += direction
        if best >= 0:
            ri = _find(parent, i)
            rj = _find(parent, best)
            if ri != rj:
                if ri < rj:
                    parent[rj] = ri
                else:
                    parent[ri] = rj
    for i in range(m):
        parent[i] = _find(parent, i)
    return parent


_seed_chains = numba.njit(cache=True)(_seed_chains_py)


def _joint_shape_py(xs, ys, comp, m, lam_a, lam_b, a_max):
    """Common shape of all start-region chains: ``y_k = c_k + b x + a x^2``.

    Lane markings are parallel, so every chain shares curvature and heading while
    each has its own offset ``c_k`` (the chain's lateral position at the sensor,
    x = 0). Offsets are eliminated by centring each chain; the 2×2 ridge system
    (priors a ~ 0, b ~ 0) gives (a, b); then ``c_k = mean(y - b x - a x^2)``.

    :return: ``(a, b, c, cnt)``; ``c`` and ``cnt`` (points per chain) are indexed
        by the chain root.
    """
    cnt = np.zeros(m)
    sx = np.zeros(m)
    sx2 = np.zeros(m)
    sx3 = np.zeros(m)
    sx4 = np.zeros(m)
    sy = np.zeros(m)
    sxy = np.zeros(m)
    sx2y = np.zeros(m)
    for i in range(m):
        r = comp[i]
        x = xs[i]
        y = ys[i]
        x2 = x * x
        cnt[r] += 1.0
        sx[r] += x
        sx2[r] += x2
        sx3[r] += x2 * x
        sx4[r] += x2 * x2
        sy[r] += y
        sxy[r] += x * y
        sx2y[r] += x2 * y
    g11 = lam_a
    g12 = 0.0
    g22 = lam_b
    r1 = 0.0
    r2 = 0.0
    for r in range(m):
        nk = cnt[r]
        if nk < 2.0:
            continue
        g11 += sx4[r] - sx2[r] * sx2[r] / nk
        g12 += sx3[r] - sx2[r] * sx[r] / nk
        g22 += sx2[r] - sx[r] * sx[r] / nk
        r1 += sx2y[r] - sx2[r] * sy[r] / nk
        r2 += sxy[r] - sx[r] * sy[r] / nk
    det = g11 * g22 - g12 * g12
    a = 0.0
    b = 0.0
    if det > 0.0:
        a = (g22 * r1 - g12 * r2) / det
        b = (g11 * r2 - g12 * r1) / det
        if abs(a) > a_max:
            a = a_max if a > 0.0 else -a_max
            b = (r2 - a * g12) / g22
    c = np.zeros(m)
    for r in range(m):
        if cnt[r] > 0.0:
            c[r] = (sy[r] - b * sx[r] - a * sx2[r]) / cnt[r]
    return a, b, c, cnt


_joint_shape = numba.njit(cache=True)(_joint_shape_py)


def _robust_seeds_py(xs, ys, m, fp, ip, lam_a, lam_b, label, offsets):
    """Robust start condition: seed points of the four lines (``label`` per point).

    Chains of start-region points are placed by their offset at x = 0 under the
    common shape (:func:`_joint_shape`); chains whose offsets differ by less than
    ``merge_dy`` are pieces of one marking (e.g. two dashes). The left ego line is
    the nearest marking with offset in (0, max_ego], the right one the nearest in
    [-max_ego, 0]; adjacent lines are the nearest markings at least ``adj_offset``
    and at most ``max_lane`` outside them. A marking needs ``min_seed`` points.
    Judging by the offset at x = 0 rather than by |y| of single points is what keeps
    a marking that crosses the car's axis within 23.5 m (R ~ 100 m) on its own side.

    :return: ``(a, b)``, the common shape; ``label[i]`` is the line slot of
        start-region point i (or -1); ``offsets`` the markings' offsets [m].
    """
    for s in range(N_LINES):
        offsets[s] = np.nan
    if m == 0:
        return 0.0, 0.0
    comp = _seed_chains(xs, ys, m, fp[P_LINK_DX], fp[P_LINK_DY])
    a, b, c, cnt = _joint_shape(xs, ys, comp, m, lam_a, lam_b, fp[P_A_MAX])
    # Chains sorted by offset (ties: root index), then merged into markings.
    nroot = 0
    roots = np.empty(m, dtype=np.int64)
    for r in range(m):
        if cnt[r] > 0.0:
            roots[nroot] = r
            nroot += 1
    roots = roots[:nroot]
    keys = np.empty(nroot)
    for q in range(nroot):
        keys[q] = c[roots[q]]
    srt = roots[np.argsort(keys, kind="mergesort")]
    group = np.full(m, -1, dtype=np.int64)  # chain root -> marking index
    g_off = np.zeros(nroot)
    g_cnt = np.zeros(nroot)
    ng = 0
    prev = -np.inf
    for q in range(nroot):
        r = srt[q]
        if ng == 0 or c[r] - prev > fp[P_MERGE_DY]:
            ng += 1
        group[r] = ng - 1
        g_off[ng - 1] += c[r] * cnt[r]
        g_cnt[ng - 1] += cnt[r]
        prev = c[r]
    for g in range(ng):
        g_off[g] /= g_cnt[g]
    min_seed = ip[I_MIN_SEED]
    chosen = np.full(N_LINES, -1, dtype=np.int64)
    # Ego lines: the nearest marking on each side within max_ego.
    for g in range(ng):
        if g_cnt[g] < min_seed:
            continue
        off = g_off[g]
        if 0.0 < off <= fp[P_MAX_EGO] and chosen[L_EGO_LEFT] < 0:
            chosen[L_EGO_LEFT] = g
    for g in range(ng - 1, -1, -1):
        if g_cnt[g] < min_seed:
            continue
        off = g_off[g]
        if -fp[P_MAX_EGO] <= off <= 0.0 and chosen[L_EGO_RIGHT] < 0:
            chosen[L_EGO_RIGHT] = g
    # Adjacent lines: nearest marking outside the ego line on its side.
    if chosen[L_EGO_LEFT] >= 0:
        base = g_off[chosen[L_EGO_LEFT]]
        for g in range(ng):
            d = g_off[g] - base
            if g_cnt[g] >= min_seed and fp[P_ADJ_OFFSET] <= d <= fp[P_MAX_LANE]:
                chosen[L_LEFT_ADJ] = g
                break
    if chosen[L_EGO_RIGHT] >= 0:
        base = g_off[chosen[L_EGO_RIGHT]]
        for g in range(ng - 1, -1, -1):
            d = base - g_off[g]
            if g_cnt[g] >= min_seed and fp[P_ADJ_OFFSET] <= d <= fp[P_MAX_LANE]:
                chosen[L_RIGHT_ADJ] = g
                break
    for s in range(N_LINES):
        if chosen[s] >= 0:
            offsets[s] = g_off[chosen[s]]
    for i in range(m):
        g = group[comp[i]]
        label[i] = -1
        for s in range(N_LINES):
            if chosen[s] == g:
                label[i] = s
    return a, b


_robust_seeds = numba.njit(cache=True)(_robust_seeds_py)


def _robust_trace_py(xs, ys, first, last, a0, b0, fp, lam_a, lam_b, guide, grid, mask, bit):
    """Trace one line forward from its seed with a gated ridge quadratic (robust).

    The seed is every point ``i`` in ``[first, last]`` with ``mask[i] & bit``. Each
    step fits ``y = A u^2 + B u + C`` (u = x - x_last) by ridge least squares to the
    accepted points within ``fit_length`` behind the last one (priors: the common
    shape ``a0``, ``b0`` of the start region; ``|A| <= 1/(2 R_min)``). The gate at
    look-ahead u is ``gate_sigmas`` predicted standard deviations (noise plus fit
    covariance), clipped to [gate_min, gate_max]. Among unclaimed points in
    ``(x_last, x_last + search]`` whose residual passes the gate, the nearest in x
    wins; gated points within ``tie_dx`` of it compete by |residual| (ties: smaller
    (x, y)). No gated point: the line ends here (exit, lane drop, end of paint).
    Nor is a line followed where it is steeper than ``max_slope``.

    ``guide`` is a ``(G, 3)`` table (x, slope, a) of the shape of an already traced
    line every 2 m (``G = 0``: none). Markings are parallel, so where the guide
    exists its local slope and curvature are the (tighter) priors of the fit: a
    dashed line then needs only its offset from its own points, and crosses gaps
    along the guide's shape.
    """
    hist = np.empty(HIST, dtype=np.int64)
    head = 0  # number of accepted points so far (hist is a ring)
    for i in range(first, last + 1):
        if mask[i] & bit:
            hist[head % HIST] = i
            head += 1
    if head == 0:
        return
    work = np.empty((2, 3, 3))
    sig2 = fp[P_NOISE] * fp[P_NOISE]
    lam_ga = sig2 / (fp[P_GUIDE_A_STD] * fp[P_GUIDE_A_STD])
    lam_gb = sig2 / (fp[P_GUIDE_B_STD] * fp[P_GUIDE_B_STD])
    ng = guide.shape[0]
    fit_length = fp[P_FIT_LENGTH]
    # The nearest gated point wins, so a window longer than the paper's 18 m only
    # matters when a whole dash (or both ends of a gap) was not measured.
    search = max(fp[P_SEARCH], fp[P_GAP_SEARCH])
    # Fit window: accepted points lo..head-1 (x is nondecreasing along hist), the
    # newest HIST of them with u = x - x_last >= -fit_length. Its sums s_k = sum u^k,
    # t_k = sum y u^k are kept running: shifted to the new x_last, the new point
    # added and the points that fall out subtracted, rather than summed afresh each
    # step (the same window; the sums differ from fresh ones at rounding level).
    x_last = xs[hist[(head - 1) % HIST]]
    lo = head - 1
    while lo > 0 and lo > head - HIST and xs[hist[(lo - 1) % HIST]] - x_last >= -fit_length:
        lo -= 1
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    s4 = 0.0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for q in range(head - 1, lo - 1, -1):
        j = hist[q % HIST]
        s0, s1, s2, s3, s4, t0, t1, t2 = _add_sums(
            s0, s1, s2, s3, s4, t0, t1, t2, xs[j] - x_last, ys[j]
        )
    while True:
        # Priors: the guide's shape at x_last, else the start region's common shape.
        pa = a0
        pb = b0 + 2.0 * a0 * x_last
        la = lam_a
        lb = lam_b
        if ng > 0 and guide[0, 0] <= x_last <= guide[ng - 1, 0]:
            g = min(int((x_last - guide[0, 0]) / GUIDE_STEP + 0.5), ng - 1)
            pb = guide[g, 1]
            pa = guide[g, 2]
            la = lam_ga
            lb = lam_gb
        A, B, C, inv = _ridge_solve(
            s0, s1, s2, s3, s4, t0, t1, t2, pa, pb, la, lb, fp[P_A_MAX], work
        )
        if abs(B) > fp[P_MAX_SLOPE]:
            break
        geo, start, pts = grid
        best = _grid_search(xs, ys, mask, geo, start, pts, x_last, A, B, C, inv, fp, sig2, search)
        if best < 0:
            break
        x_new = xs[best]
        # Drop the oldest points (the window holds at most HIST, and the ring slot
        # of the new point is about to be overwritten) ...
        while head + 1 - lo > HIST:
            j = hist[lo % HIST]
            s0, s1, s2, s3, s4, t0, t1, t2 = _drop_sums(
                s0, s1, s2, s3, s4, t0, t1, t2, xs[j] - x_last, ys[j]
            )
            lo += 1
        mask[best] |= bit
        hist[head % HIST] = best
        head += 1
        # ... shift the sums to u' = u + e (e = x_last - x_new <= 0) ...
        e = x_last - x_new
        e2 = e * e
        s4 = s4 + 4.0 * e * s3 + 6.0 * e2 * s2 + 4.0 * e2 * e * s1 + e2 * e2 * s0
        s3 = s3 + 3.0 * e * s2 + 3.0 * e2 * s1 + e2 * e * s0
        s2 = s2 + 2.0 * e * s1 + e2 * s0
        s1 = s1 + e * s0
        t2 = t2 + 2.0 * e * t1 + e2 * t0
        t1 = t1 + e * t0
        x_last = x_new
        # ... add the new point (u = 0) and drop those now more than fit_length behind.
        s0 += 1.0
        t0 += ys[best]
        while xs[hist[lo % HIST]] - x_last < -fit_length:
            j = hist[lo % HIST]
            s0, s1, s2, s3, s4, t0, t1, t2 = _drop_sums(
                s0, s1, s2, s3, s4, t0, t1, t2, xs[j] - x_last, ys[j]
            )
            lo += 1
        if lo == head - 1:  # the new point alone: the sums are exact, drop the residue
            s0 = 1.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            s4 = 0.0
            t0 = ys[best]
            t1 = 0.0
            t2 = 0.0


_robust_trace = numba.njit(cache=True)(_robust_trace_py)


def _guide_table_py(xs, ys, mask, bit, fp, a0, b0, lam_a, lam_b):
    """Shape table ``(G, 3)`` = (x, slope, a) of a traced line every 2 m, or (0, 3).

    Empty when the line has fewer than ``GUIDE_MIN_POINTS`` points or spans less
    than ``GUIDE_MIN_EXTENT`` in x.
    """
    n = xs.shape[0]
    idx = np.empty(n, dtype=np.int64)  # the line's points, one pass over the mask
    cnt = 0
    for i in range(n):
        if mask[i] & bit:
            idx[cnt] = i
            cnt += 1
    if cnt < GUIDE_MIN_POINTS:
        return np.zeros((0, 3))
    lx = np.empty(cnt)
    ly = np.empty(cnt)
    for k in range(cnt):
        lx[k] = xs[idx[k]]
        ly[k] = ys[idx[k]]
    if lx[cnt - 1] - lx[0] < GUIDE_MIN_EXTENT:
        return np.zeros((0, 3))
    g = int((lx[cnt - 1] - lx[0]) / GUIDE_STEP) + 1
    gx = np.empty(g)
    for j in range(g):
        gx[j] = lx[0] + GUIDE_STEP * j
    _, gb, ga = _smooth_at(lx, ly, gx, fp[P_SMOOTH_H], a0, b0, lam_a, lam_b, fp[P_A_MAX])
    out = np.empty((g, 3))
    for j in range(g):
        out[j, 0] = gx[j]
        out[j, 1] = gb[j]
        out[j, 2] = ga[j]
    return out


_guide_table = numba.njit(cache=True)(_guide_table_py)


def _robust_detect_py(xs, ys, fp, ip, mask, offsets):
    """Robust ALDM: seeds of the four lines, then traces with point exclusivity.

    Seeds are claimed first; then lines are traced ego lines before adjacent ones,
    each pair in order of seed size (ties: left first). A point belongs to at most
    one line: when two lines compete for a point, the one traced first keeps it.

    :return: ``(a, b)``, the common shape of the start region.
    """
    n = xs.shape[0]
    m = 0
    while m < n and xs[m] <= fp[P_START_X_MAX]:
        m += 1
    sig2 = fp[P_NOISE] * fp[P_NOISE]
    lam_a = sig2 / (fp[P_A_STD] * fp[P_A_STD])
    lam_b = sig2 / (fp[P_B_STD] * fp[P_B_STD])
    label = np.full(m, -1, dtype=np.int64)
    a, b = _robust_seeds(xs, ys, m, fp, ip, lam_a, lam_b, label, offsets)
    if math.isnan(offsets[L_EGO_LEFT]) or math.isnan(offsets[L_EGO_RIGHT]):
        # A missing ego line (its dash gap fills the start region, points dropped):
        # look one search window further (x <= 23.52 + 18 m) for that line only. Its
        # offset must be clear of the lines already found.
        m2 = m
        while m2 < n and xs[m2] <= fp[P_START_X_MAX] + fp[P_SEARCH]:
            m2 += 1
        label2 = np.full(m2, -1, dtype=np.int64)
        off2 = np.full(N_LINES, np.nan)
        _robust_seeds(xs, ys, m2, fp, ip, lam_a, lam_b, label2, off2)
        for s in (L_EGO_LEFT, L_EGO_RIGHT):
            if not math.isnan(offsets[s]) or math.isnan(off2[s]):
                continue
            clear = True
            for t in range(N_LINES):
                if not math.isnan(offsets[t]) and abs(offsets[t] - off2[s]) <= fp[P_MERGE_DY]:
                    clear = False
            if (s == L_EGO_LEFT and off2[s] <= offsets[L_EGO_RIGHT]) or (
                s == L_EGO_RIGHT and off2[s] >= offsets[L_EGO_LEFT]
            ):
                clear = False
            if not clear:
                continue
            offsets[s] = off2[s]
            grown = np.full(m2, -1, dtype=np.int64)
            grown[: label.shape[0]] = label  # label may already be grown (both ego lines)
            for i in range(m2):
                if label2[i] == s and grown[i] < 0:
                    grown[i] = s
            label = grown
        m = label.shape[0]
    size = np.zeros(N_LINES)
    last = np.full(N_LINES, -1, dtype=np.int64)
    first = np.full(N_LINES, -1, dtype=np.int64)
    for i in range(m):
        s = label[i]
        if s >= 0:
            mask[i] |= np.uint8(1 << s)
            size[s] += 1.0
            last[s] = i
            if first[s] < 0:
                first[s] = i
    # Trace order: larger seed first (ties: slot order); the first line traced with
    # enough support becomes the guide (shape prior) of the others.
    order = np.argsort(-size, kind="mergesort")
    guide = np.zeros((0, 3))
    grid = _build_grid(xs, ys, fp[P_GATE_MAX])
    for q in range(N_LINES):
        s = order[q]
        if size[s] == 0.0:
            continue
        _robust_trace(
            xs, ys, first[s], last[s], a, b, fp, lam_a, lam_b, guide, grid, mask, np.uint8(1 << s)
        )
        if guide.shape[0] == 0:
            guide = _guide_table(xs, ys, mask, np.uint8(1 << s), fp, a, b, lam_a, lam_b)
    return a, b


_robust_detect = numba.njit(cache=True)(_robust_detect_py)


# ================================================================== output
def _smooth_at_py(lx, ly, xq, h, a0, b0, lam_a, lam_b, a_max):
    """Local quadratic (ridge) fit of a line's points at each ``xq`` [m].

    Uses the points within ``h`` of ``xq`` (at least the three nearest), so a value
    inside a dash gap interpolates along the curve rather than along a chord.

    :return: ``(y, slope, a)`` at each ``xq``: value [m], dy/dx [-], half the second
        derivative [1/m].
    """
    k = lx.shape[0]
    nq = xq.shape[0]
    out_y = np.empty(nq)
    out_b = np.empty(nq)
    out_a = np.empty(nq)
    us = np.empty(k)
    vs = np.empty(k)
    work = np.empty((2, 3, 3))
    lo = 0
    for q in range(nq):
        x0 = xq[q]
        while lo < k and lx[lo] < x0 - h:
            lo += 1
        hi = lo
        while hi < k and lx[hi] <= x0 + h:
            hi += 1
        a = lo
        bnd = hi
        # at least three points: widen towards the nearer neighbour
        while bnd - a < 3 and (a > 0 or bnd < k):
            if a == 0:
                bnd += 1
            elif bnd == k:
                a -= 1
            elif x0 - lx[a - 1] <= lx[bnd] - x0:
                a -= 1
            else:
                bnd += 1
        nf = 0
        for j in range(a, bnd):
            us[nf] = lx[j] - x0
            vs[nf] = ly[j]
            nf += 1
        A, B, C, _ = _ridge_quadratic(us, vs, nf, a0, b0 + 2.0 * a0 * x0, lam_a, lam_b, a_max, work)
        out_y[q] = C
        out_b[q] = B
        out_a[q] = A
    return out_y, out_b, out_a


_smooth_at = numba.njit(cache=True)(_smooth_at_py)


def _assemble_py(xs, ys, mask, fp, ip, a0, b0):
    """Output lines: measured or smoothed, all points or ``n_out`` equally spaced.

    Lines with fewer than two points, or no extent in x, are empty. Output never
    extends beyond the first and last traced point (no extrapolation).

    :return: ``(lines, starts)``: ``lines[starts[l]:starts[l+1]]`` is line l ``(K, 2)``.
    """
    n = xs.shape[0]
    n_out = ip[I_N_OUT]
    smooth = ip[I_SMOOTH] == 1
    sig2 = fp[P_NOISE] * fp[P_NOISE]
    lam_a = sig2 / (fp[P_A_STD] * fp[P_A_STD])
    lam_b = sig2 / (fp[P_B_STD] * fp[P_B_STD])
    cnt = np.zeros(N_LINES, dtype=np.int64)
    x_lo = np.full(N_LINES, np.inf)
    x_hi = np.full(N_LINES, -np.inf)
    # owned[:n_owned]: the points of any line, so each line's pass below visits
    # only those (a few hundred) rather than all N points.
    owned = np.empty(n, dtype=np.int64)
    n_owned = 0
    for i in range(n):
        mk = mask[i]
        if mk != 0:
            owned[n_owned] = i
            n_owned += 1
            for s in range(N_LINES):
                if mk & (1 << s):
                    cnt[s] += 1
                    x_lo[s] = min(x_lo[s], xs[i])
                    x_hi[s] = max(x_hi[s], xs[i])
    starts = np.zeros(N_LINES + 1, dtype=np.int64)
    for s in range(N_LINES):
        size = 0
        if cnt[s] >= 2 and x_hi[s] > x_lo[s]:
            size = n_out if n_out >= 2 else cnt[s]
        starts[s + 1] = starts[s] + size
    lines = np.empty((starts[N_LINES], 2))
    for s in range(N_LINES):
        size = starts[s + 1] - starts[s]
        if size == 0:
            continue
        lx = np.empty(cnt[s])
        ly = np.empty(cnt[s])
        k = 0
        for t in range(n_owned):
            i = owned[t]
            if mask[i] & (1 << s):
                lx[k] = xs[i]
                ly[k] = ys[i]
                k += 1
        if n_out >= 2:
            xq = np.linspace(lx[0], lx[k - 1], n_out)
        else:
            xq = lx
        if smooth:
            yq, _, _ = _smooth_at(lx, ly, xq, fp[P_SMOOTH_H], a0, b0, lam_a, lam_b, fp[P_A_MAX])
        elif n_out >= 2:
            yq = np.interp(xq, lx, ly)
        else:
            yq = ly
        o = starts[s]
        for j in range(size):
            lines[o + j, 0] = xq[j]
            lines[o + j, 1] = yq[j]
    return lines, starts


_assemble = numba.njit(cache=True)(_assemble_py)


def _one_line_width_py(starts, offsets, fp):
    """Lane width [m] for a trajectory from one ego line (§ALDM is silent).

    With only one ego line found, the distance between its offset at x = 0 and that
    of the adjacent line on the same side, when found and within
    [min_lane_width, max_lane_width]; otherwise (and with two or no ego lines, where
    it is unused) the ``lane_width`` parameter.
    """
    width = fp[P_LANE_WIDTH]
    nl = starts[L_EGO_LEFT + 1] - starts[L_EGO_LEFT]
    nr = starts[L_EGO_RIGHT + 1] - starts[L_EGO_RIGHT]
    if nl > 0 and nr == 0 and starts[L_LEFT_ADJ + 1] > starts[L_LEFT_ADJ]:
        w = offsets[L_LEFT_ADJ] - offsets[L_EGO_LEFT]
        if fp[P_MIN_LANE] <= w <= fp[P_MAX_LANE]:
            width = w
    elif nr > 0 and nl == 0 and starts[L_RIGHT_ADJ + 1] > starts[L_RIGHT_ADJ]:
        w = offsets[L_EGO_RIGHT] - offsets[L_RIGHT_ADJ]
        if fp[P_MIN_LANE] <= w <= fp[P_MAX_LANE]:
            width = w
    return width


_one_line_width = numba.njit(cache=True)(_one_line_width_py)


def _detect_py(pts, fp, ip, path_range):
    """The whole ALDM on one frame; the single entry point called from Python.

    :param pts: ``(N, 2|3)`` float64 raw points (x, y[, z]) [m].
    :param fp: float parameters (layout ``P_*``).
    :param ip: integer parameters (layout ``I_*``).
    :param path_range: the trajectory fits the ego lines up to this x [m] (``inf``:
        whole lines), see :func:`aldm_gym.sensor.trajectory._path`.
    :return: ``(lines, starts, offsets, ok, trajectory, width)``: packed output lines
        (see :func:`_assemble`), the lines' offsets at x = 0 ``(4,)`` [m] (NaN if not
        found), whether the compiled path fit applied (else the caller falls back to
        ``driving_trajectory`` with the same lines and ``width``), the ``(M, 2)``
        driving trajectory [m] and the lane width used for a one-line path [m].
    """
    has_z = pts.shape[1] >= 3
    xs, ys = _gather(pts, has_z, fp[P_Z_BAND], fp[P_MAX_RANGE])
    mask = np.zeros(xs.shape[0], dtype=np.uint8)
    offsets = np.full(N_LINES, np.nan)
    a0 = 0.0
    b0 = 0.0
    if ip[I_PAPER] == 1:
        _paper_detect(xs, ys, fp, ip, mask, offsets)
    else:
        a0, b0 = _robust_detect(xs, ys, fp, ip, mask, offsets)
    lines, starts = _assemble(xs, ys, mask, fp, ip, a0, b0)
    width = _one_line_width(starts, offsets, fp)
    left = lines[starts[L_EGO_LEFT] : starts[L_EGO_LEFT + 1]]
    right = lines[starts[L_EGO_RIGHT] : starts[L_EGO_RIGHT + 1]]
    ok, traj = _path(left, right, width, PATH_STEP, path_range)
    return lines, starts, offsets, ok, traj, width


_detect = numba.njit(cache=True)(_detect_py)
