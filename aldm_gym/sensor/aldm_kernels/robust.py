"""Robust mode: seeds of the four lines from the start region, then gated traces.

The paper's structure with its fragile parts replaced (``docs/aldm.md``): chains of
start-region points placed by their offset at the sensor under a common lane shape,
a ridge-regularised quadratic prediction over a sliding window with a curvature
bound, a covariance-based residual gate, and one owner per point.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aldm_gym.sensor.aldm_kernels.fit import ridge_solve, smooth_at, update_sums
from aldm_gym.sensor.aldm_kernels.grid import GUIDE_STEP, build_grid, grid_search, guide_dev
from aldm_gym.sensor.aldm_kernels.layout import (
    L_EGO_LEFT,
    L_EGO_RIGHT,
    L_LEFT_ADJ,
    L_RIGHT_ADJ,
    N_LINES,
    I,
    P,
)
from aldm_gym.sensor.aldm_kernels.sort import bucket_order

HIST = 64
"""Ring buffer of the most recent accepted points of a traced line (fit window cap)."""
GUIDE_MIN_POINTS = 6
"""A guide line needs this many points ..."""
GUIDE_MIN_EXTENT = 30.0
"""... over at least this x extent [m]."""
PARALLEL_MIN_POINTS = 3
"""A traced line's offset from the guide counts once this many of its window's
points lie along the guide."""
MAX_SHAPE_OUTLIERS = 3
"""Start-region chains that may be left out of the common shape as not parallel."""
SHAPE_MAX_RMS = 0.5
"""A start-region chain whose RMS residual under the common shape exceeds this [m] is
left out of the shape as not parallel (:func:`_joint_shape`)."""
CLEAR_DY = 1.0
"""An ego line found only in the extended start region must lie farther than this
from every line already found [m]."""
AMBIGUITY_MARGIN = 0.1
"""A farther candidate of an ego line replaces the nearest one only when its lane
widths agree better by more than this [m] (:func:`_pick_ego`)."""


def _find_py(parent, i):
    """Union-find root with path halving."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


_find = numba.njit(cache=True)(_find_py)


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
    # Points in y order (the bucket sort of gather, here on y). Any order among equal
    # y will do: the candidates of a point are all those within link_dy in y, and the
    # choice among them is by value.
    yo = bucket_order(ys[:m], ys[:m])
    pos = np.empty(m, dtype=np.int64)
    for q in range(m):
        pos[yo[q]] = q
    for i in range(m):
        best = np.int64(-1)  # int64, not a literal: one compiled callee (numba)
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


def _joint_shape_py(xs, ys, comp, m, lam_a, lam_b, a_max, max_rms):
    """Common shape of the start-region chains: ``y_k = c_k + b x + a x^2``.

    Lane markings are parallel, so every chain shares curvature and heading while
    each has its own offset ``c_k`` (the chain's lateral position at the sensor,
    x = 0). Offsets are eliminated by centring each chain; the 2×2 ridge system
    (priors a ~ 0, b ~ 0) gives (a, b); then ``c_k = mean(y - b x - a x^2)``.

    A chain that is not parallel to the others (an exit's edge diverging at a gore, a
    marking at an angle) would tilt the common shape and shift every offset: while
    the worst chain's RMS residual under the shape exceeds ``max_rms`` [m], it is left
    out of the shape (at most :data:`MAX_SHAPE_OUTLIERS` chains) and the shape refitted.
    A chain left out gets the offset at x = 0 of its own straight-line fit.

    :return: ``(a, b, c, cnt, worst)``; ``c`` and ``cnt`` (points per chain) are
        indexed by the chain root; ``worst`` is the largest mean square residual of a
        chain of two or more points under the common shape, left out of it or not [m²].
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
    out = np.zeros(m, dtype=np.bool_)
    c = np.zeros(m)
    rss = np.zeros(m)
    a = 0.0
    b = 0.0
    for _round in range(MAX_SHAPE_OUTLIERS + 1):
        g11 = lam_a
        g12 = 0.0
        g22 = lam_b
        r1 = 0.0
        r2 = 0.0
        for r in range(m):
            nk = cnt[r]
            if nk < 2.0 or out[r]:
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
        for r in range(m):
            if cnt[r] > 0.0:
                c[r] = (sy[r] - b * sx[r] - a * sx2[r]) / cnt[r]
            rss[r] = 0.0
        for i in range(m):
            r = comp[i]
            e = ys[i] - c[r] - b * xs[i] - a * xs[i] * xs[i]
            rss[r] += e * e
        worst = -1
        worst_ms = max_rms * max_rms
        for r in range(m):
            if cnt[r] >= 2.0 and not out[r] and rss[r] / cnt[r] > worst_ms:
                worst_ms = rss[r] / cnt[r]
                worst = r
        if worst < 0 or _round == MAX_SHAPE_OUTLIERS:
            break
        out[worst] = True
    worst_ms = 0.0
    for r in range(m):
        if cnt[r] >= 2.0:
            worst_ms = max(worst_ms, rss[r] / cnt[r])
        if out[r]:
            vx = sx2[r] - sx[r] * sx[r] / cnt[r]
            slope = (sxy[r] - sx[r] * sy[r] / cnt[r]) / vx if vx > 0.0 else b
            c[r] = (sy[r] - slope * sx[r]) / cnt[r]
    return a, b, c, cnt, worst_ms


_joint_shape = numba.njit(cache=True)(_joint_shape_py)


def _next_group_py(g_off, g_cnt, ng, k, side, min_dist, min_seed):
    """The nearest marking group at least ``min_dist`` from group ``k`` on ``side``
    (+1: larger offsets, -1: smaller), or -1."""
    g = k + (1 if side > 0.0 else -1)
    while 0 <= g < ng:
        if g_cnt[g] >= min_seed and side * (g_off[g] - g_off[k]) >= min_dist:
            return g
        g += 1 if side > 0.0 else -1
    return -1


_next_group = numba.njit(cache=True)(_next_group_py)


def _lane_fit_py(g_off, g_cnt, ng, k, side, min_seed, fp):
    """How badly group ``k`` fits as an ego line on ``side``: the difference of the
    lane widths on its two sides [m] (inf: not judged).

    The inner width runs from ``k`` to the nearest group at least min_lane_width
    inwards (the other ego line); the outer one from ``k`` to the nearest group at
    least min_lane_width outwards, or, without one, the lane beyond the other ego
    line. Widths above max_lane_width do not count.
    """
    lo = fp[P.min_lane_width]
    hi = fp[P.max_lane_width]
    inner = _next_group(g_off, g_cnt, ng, k, -side, lo, min_seed)
    if inner < 0 or abs(g_off[k] - g_off[inner]) > hi:
        return np.inf
    w_in = abs(g_off[k] - g_off[inner])
    outer = _next_group(g_off, g_cnt, ng, k, side, lo, min_seed)
    if outer >= 0 and abs(g_off[outer] - g_off[k]) <= hi:
        return abs(abs(g_off[outer] - g_off[k]) - w_in)
    beyond = _next_group(g_off, g_cnt, ng, inner, -side, lo, min_seed)
    if beyond >= 0 and abs(g_off[inner] - g_off[beyond]) <= hi:
        return abs(abs(g_off[inner] - g_off[beyond]) - w_in)
    return np.inf


_lane_fit = numba.njit(cache=True)(_lane_fit_py)


def _pick_ego_py(g_off, g_cnt, ng, side, min_seed, fp):
    """The ego line's marking group on ``side`` (+1 left, -1 right), or -1.

    The nearest group with offset in (0, max_ego] (left) or [-max_ego, 0] (right).
    Two groups less than min_lane_width apart cannot both bound lanes: where farther
    groups within max_ego lie that close beyond the nearest (a tar seam or an old
    marking beside the marking, either side of it), the one whose lane widths agree
    best (:func:`_lane_fit`) is taken, if it beats the nearest by ``AMBIGUITY_MARGIN``;
    where the nearest's widths cannot be judged, only a candidate whose widths agree
    within ``AMBIGUITY_MARGIN`` replaces it.
    """
    max_ego = fp[P.max_ego_offset]
    near = -1
    g = 0 if side > 0.0 else ng - 1
    while 0 <= g < ng:
        off = g_off[g]
        if g_cnt[g] >= min_seed and (
            (side > 0.0 and 0.0 < off <= max_ego) or (side < 0.0 and -max_ego <= off <= 0.0)
        ):
            near = g
            break
        g += 1 if side > 0.0 else -1
    if near < 0:
        return -1
    best = near
    best_fit = -1.0  # the nearest's fit, computed when a competitor shows up
    g = near + (1 if side > 0.0 else -1)
    while 0 <= g < ng and side * (g_off[g] - g_off[near]) < fp[P.min_lane_width]:
        if g_cnt[g] >= min_seed and abs(g_off[g]) <= max_ego:
            if best_fit < 0.0:
                best_fit = _lane_fit(g_off, g_cnt, ng, near, side, min_seed, fp)
                if best_fit == np.inf:
                    # The nearest cannot be judged: only a candidate whose widths
                    # agree within the margin replaces it.
                    best_fit = 2.0 * AMBIGUITY_MARGIN
            fit = _lane_fit(g_off, g_cnt, ng, g, side, min_seed, fp)
            if fit + AMBIGUITY_MARGIN < best_fit:
                best = g
                best_fit = fit
        g += 1 if side > 0.0 else -1
    return best


_pick_ego = numba.njit(cache=True)(_pick_ego_py)


def _pick_adjacent_py(g_off, g_cnt, ng, ego, side, w_ego, min_seed, fp):
    """The adjacent line's group beyond ego line group ``ego`` on ``side``, or -1:
    of the groups adjacent_offset..max_lane_width beyond it, the one whose lane width
    is nearest ``w_ego`` (ties: the nearest)."""
    best = -1
    best_d = np.inf
    g = ego + (1 if side > 0.0 else -1)
    while 0 <= g < ng:
        d = side * (g_off[g] - g_off[ego])
        if d > fp[P.max_lane_width]:
            break
        if g_cnt[g] >= min_seed and d >= fp[P.adjacent_offset] and abs(d - w_ego) < best_d:
            best_d = abs(d - w_ego)
            best = g
        g += 1 if side > 0.0 else -1
    return best


_pick_adjacent = numba.njit(cache=True)(_pick_adjacent_py)


def _robust_seeds_py(xs, ys, m, fp, ip, lam_a, lam_b, label, offsets):
    """Robust start condition: seed points of the four lines (``label`` per point).

    Chains of start-region points are placed by their offset at x = 0 under the
    common shape (:func:`_joint_shape`); where a chain strays from it, they are
    chained again with that shape taken out (``chain_dy``), which keeps a seam
    beside a dashed marking out of its chain;
    chains whose offsets differ by less than ``merge_dy`` are pieces of one marking
    (e.g. two dashes). The left ego line is the nearest marking with offset in
    (0, max_ego], the right one the nearest in [-max_ego, 0], unless a marking close
    beyond it fits the lane widths better (:func:`_pick_ego`); adjacent lines lie
    ``adj_offset``..``max_lane`` outside them (:func:`_pick_adjacent`). A marking
    needs ``min_seed`` points.
    Judging by the offset at x = 0 rather than by |y| of single points is what keeps
    a marking that crosses the car's axis within 23.5 m (R ~ 100 m) on its own side.

    :return: ``(a, b)``, the common shape; ``label[i]`` is the line slot of
        start-region point i (or -1); ``offsets`` the markings' offsets [m].
    """
    for s in range(N_LINES):
        offsets[s] = np.nan
    if m == 0:
        return 0.0, 0.0
    comp = _seed_chains(xs, ys, m, fp[P.link_dx], fp[P.link_dy])
    a, b, c, cnt, worst = _joint_shape(xs, ys, comp, m, lam_a, lam_b, fp[P.a_max], SHAPE_MAX_RMS)
    # Second pass, where a chain strays from the common shape by more than a quarter
    # of chain_dy (RMS; also one left out of the shape, which may be a seam joined to
    # a marking's dashes), with that shape taken out: every marking is then a level row,
    # and points chain only within chain_dy of each other. A tar seam or an old
    # marking beside a dashed marking, which the first pass linked into the dashes
    # (nothing else lies within link_dx of a dash's first point), becomes a chain of
    # its own.
    if worst > 0.0625 * fp[P.chain_dy] * fp[P.chain_dy]:
        flat = np.empty(m)
        for i in range(m):
            flat[i] = ys[i] - (b + a * xs[i]) * xs[i]
        comp = _seed_chains(xs, flat, m, fp[P.link_dx], fp[P.chain_dy])
        a, b, c, cnt, _ = _joint_shape(xs, ys, comp, m, lam_a, lam_b, fp[P.a_max], SHAPE_MAX_RMS)
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
    ng = np.int64(0)  # int64, not a literal: one compiled callee (numba)
    prev = -np.inf
    for q in range(nroot):
        r = srt[q]
        if ng == 0 or c[r] - prev > fp[P.merge_dy]:
            ng += 1
        group[r] = ng - 1
        g_off[ng - 1] += c[r] * cnt[r]
        g_cnt[ng - 1] += cnt[r]
        prev = c[r]
    for g in range(ng):
        g_off[g] /= g_cnt[g]
    min_seed = ip[I.min_seed_points]
    chosen = np.full(N_LINES, -1, dtype=np.int64)
    # Ego lines: the nearest marking on each side within max_ego, unless a farther
    # one less than min_lane_width beyond it fits the lanes better (_pick_ego).
    chosen[L_EGO_LEFT] = _pick_ego(g_off, g_cnt, ng, 1.0, min_seed, fp)
    chosen[L_EGO_RIGHT] = _pick_ego(g_off, g_cnt, ng, -1.0, min_seed, fp)
    # Adjacent lines: outside the ego line on its side, between adjacent_offset and
    # max_lane_width beyond it; of several, the one whose lane is nearest the ego
    # lane's width (ties: the nearest).
    if chosen[L_EGO_LEFT] >= 0 and chosen[L_EGO_RIGHT] >= 0:
        w_ego = g_off[chosen[L_EGO_LEFT]] - g_off[chosen[L_EGO_RIGHT]]
    else:
        w_ego = fp[P.lane_width]
    if chosen[L_EGO_LEFT] >= 0:
        chosen[L_LEFT_ADJ] = _pick_adjacent(
            g_off, g_cnt, ng, chosen[L_EGO_LEFT], 1.0, w_ego, min_seed, fp
        )
    if chosen[L_EGO_RIGHT] >= 0:
        chosen[L_RIGHT_ADJ] = _pick_adjacent(
            g_off, g_cnt, ng, chosen[L_EGO_RIGHT], -1.0, w_ego, min_seed, fp
        )
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
    (x, y)); a winner that fits poorly, or lies off the guide (below), may yield to a
    better point farther on (:func:`grid_search`). No gated point: the line ends here
    (exit, lane drop, end of paint). Nor is a line followed where it is steeper than
    ``max_slope``.

    ``guide`` is a ``(G, 4)`` table (x, slope, a, y) of an already traced line every
    2 m (``G = 0``: none). Markings are parallel, so where the guide exists its local
    slope and curvature are the (tighter) priors of the fit: a dashed line then needs
    only its offset from its own points, and crosses gaps along the guide's shape;
    and the mean offset from the guide of the window's points (at least
    ``PARALLEL_MIN_POINTS``) tells the next point from clutter diverging from the
    line (:func:`grid_search`).
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
    sig2 = fp[P.noise_std] * fp[P.noise_std]
    lam_ga = sig2 / (fp[P.guide_a_std] * fp[P.guide_a_std])
    lam_gb = sig2 / (fp[P.guide_b_std] * fp[P.guide_b_std])
    ng = guide.shape[0]
    fit_length = fp[P.fit_length]
    # The nearest gated point wins, so a window longer than the paper's 18 m only
    # matters when a whole dash (or both ends of a gap) was not measured.
    search = max(fp[P.search_length], fp[P.gap_search_length])
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
    # Running sum and count of the window points' offsets from the guide (those
    # within its x range), updated with the window like the fit's sums.
    dsum = 0.0
    dcnt = 0
    for q in range(head - 1, lo - 1, -1):
        j = hist[q % HIST]
        s0, s1, s2, s3, s4, t0, t1, t2 = update_sums(
            s0, s1, s2, s3, s4, t0, t1, t2, xs[j] - x_last, ys[j], 1.0
        )
        d = guide_dev(guide, xs[j], ys[j])
        if d == d:
            dsum += d
            dcnt += 1
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
        A, B, C, inv = ridge_solve(
            s0, s1, s2, s3, s4, t0, t1, t2, pa, pb, la, lb, fp[P.a_max], work
        )
        if abs(B) > fp[P.max_slope]:
            break
        # Mean offset from the guide of the window's points within its range.
        g_off = dsum / dcnt if dcnt >= PARALLEL_MIN_POINTS else np.nan
        geo, start, pts = grid
        best = grid_search(
            xs, ys, mask, geo, start, pts, x_last, A, B, C, inv, fp, sig2, search, guide, g_off
        )
        if best < 0:
            break
        x_new = xs[best]
        # Drop the oldest points (the window holds at most HIST, and the ring slot
        # of the new point is about to be overwritten) ...
        while head + 1 - lo > HIST:
            j = hist[lo % HIST]
            s0, s1, s2, s3, s4, t0, t1, t2 = update_sums(
                s0, s1, s2, s3, s4, t0, t1, t2, xs[j] - x_last, ys[j], -1.0
            )
            d = guide_dev(guide, xs[j], ys[j])
            if d == d:
                dsum -= d
                dcnt -= 1
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
        d = guide_dev(guide, x_new, ys[best])
        if d == d:
            dsum += d
            dcnt += 1
        while xs[hist[lo % HIST]] - x_last < -fit_length:
            j = hist[lo % HIST]
            s0, s1, s2, s3, s4, t0, t1, t2 = update_sums(
                s0, s1, s2, s3, s4, t0, t1, t2, xs[j] - x_last, ys[j], -1.0
            )
            d = guide_dev(guide, xs[j], ys[j])
            if d == d:
                dsum -= d
                dcnt -= 1
            lo += 1
        if lo == head - 1:  # the new point alone: the sums are exact, drop the residue
            d = guide_dev(guide, x_new, ys[best])
            dsum = d if d == d else 0.0
            dcnt = 1 if d == d else 0
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
    """Table ``(G, 4)`` = (x, slope, a, y) of a traced line every 2 m, or (0, 4).

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
        return np.zeros((0, 4))
    lx = np.empty(cnt)
    ly = np.empty(cnt)
    for k in range(cnt):
        lx[k] = xs[idx[k]]
        ly[k] = ys[idx[k]]
    if lx[cnt - 1] - lx[0] < GUIDE_MIN_EXTENT:
        return np.zeros((0, 4))
    g = int((lx[cnt - 1] - lx[0]) / GUIDE_STEP) + 1
    gx = np.empty(g)
    for j in range(g):
        gx[j] = lx[0] + GUIDE_STEP * j
    gy, gb, ga = smooth_at(lx, ly, gx, fp[P.smooth_half_width], a0, b0, lam_a, lam_b, fp[P.a_max])
    out = np.empty((g, 4))
    for j in range(g):
        out[j, 0] = gx[j]
        out[j, 1] = gb[j]
        out[j, 2] = ga[j]
        out[j, 3] = gy[j]
    return out


_guide_table = numba.njit(cache=True)(_guide_table_py)


def claim_seeds_py(label, mask):
    """Claim each line's seed points: ``mask[i]`` gets bit ``1 << label[i]`` for every
    labelled start-region point (``label[i] >= 0``).

    :return: ``(size, first, last)``, each ``(N_LINES,)``: the seed's point count (as a
        float), and its first and last point's index (-1: no seed).
    """
    size = np.zeros(N_LINES)
    last = np.full(N_LINES, -1, dtype=np.int64)
    first = np.full(N_LINES, -1, dtype=np.int64)
    for i in range(label.shape[0]):
        s = label[i]
        if s >= 0:
            mask[i] |= np.uint8(1 << s)
            size[s] += 1.0
            last[s] = i
            if first[s] < 0:
                first[s] = i
    return size, first, last


claim_seeds = numba.njit(cache=True)(claim_seeds_py)


def robust_detect_py(xs, ys, fp, ip, mask, offsets):
    """Robust ALDM: seeds of the four lines, then traces with point exclusivity.

    Seeds are claimed first; then lines are traced ego lines before adjacent ones,
    each pair in order of seed size (ties: left first). A point belongs to at most
    one line: when two lines compete for a point, the one traced first keeps it.

    :return: ``(a, b)``, the common shape of the start region.
    """
    n = xs.shape[0]
    m = 0
    while m < n and xs[m] <= fp[P.start_x_max]:
        m += 1
    sig2 = fp[P.noise_std] * fp[P.noise_std]
    lam_a = sig2 / (fp[P.a_std] * fp[P.a_std])
    lam_b = sig2 / (fp[P.b_std] * fp[P.b_std])
    label = np.full(m, -1, dtype=np.int64)
    a, b = _robust_seeds(xs, ys, m, fp, ip, lam_a, lam_b, label, offsets)
    if math.isnan(offsets[L_EGO_LEFT]) or math.isnan(offsets[L_EGO_RIGHT]):
        # A missing ego line (its dash gap fills the start region, points dropped):
        # look one search window further (x <= 23.52 + 18 m) for that line only. Its
        # offset must be clear of the lines already found.
        m2 = m
        while m2 < n and xs[m2] <= fp[P.start_x_max] + fp[P.search_length]:
            m2 += 1
        label2 = np.full(m2, -1, dtype=np.int64)
        off2 = np.full(N_LINES, np.nan)
        _robust_seeds(xs, ys, m2, fp, ip, lam_a, lam_b, label2, off2)
        for s in (L_EGO_LEFT, L_EGO_RIGHT):
            if not math.isnan(offsets[s]) or math.isnan(off2[s]):
                continue
            clear = True
            for t in range(N_LINES):
                if not math.isnan(offsets[t]) and abs(offsets[t] - off2[s]) <= CLEAR_DY:
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
    size, first, last = claim_seeds(label, mask)
    # Trace order: larger seed first (ties: slot order); the first line traced with
    # enough support becomes the guide (shape prior) of the others.
    order = np.argsort(-size, kind="mergesort")
    guide = np.zeros((0, 4))
    grid = build_grid(xs, ys, fp[P.gate_max])
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


robust_detect = numba.njit(cache=True)(robust_detect_py)
