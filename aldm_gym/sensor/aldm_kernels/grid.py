"""Robust mode's search grid: the points bucketed by x and y, and the gated search.

Each trace step visits only the grid cells its prediction ± the largest gate
crosses, so a step costs the points near the line, not all N.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aldm_gym.sensor.aldm_kernels.layout import P

GUIDE_STEP = 2.0
"""x step of a guide line's table [m] (:func:`guide_dev`)."""


def build_grid_py(xs, ys, cell_y):
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


build_grid = numba.njit(cache=True)(build_grid_py)


def _gated_py(xs, ys, k, x_last, A, B, C, inv, fp, sig2):
    """|residual| of point k against the prediction, or -1 if it fails the gate.

    The gate is ``gate_sigmas`` predicted standard deviations (noise plus the fit's
    covariance at look-ahead u), clipped to [gate_min, gate_max]; the model must
    also stay flatter than ``max_slope`` up to the point.
    """
    u = xs[k] - x_last
    if abs(2.0 * A * u + B) > fp[P.max_slope]:
        return -1.0
    r = abs(ys[k] - ((A * u + B) * u + C))
    if r > fp[P.gate_max]:
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
    gate = fp[P.gate_sigmas] * math.sqrt(sig2 * (1.0 + max(v, 0.0)))
    gate = min(max(gate, fp[P.gate_min]), fp[P.gate_max])
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


def guide_dev_py(guide, x, y):
    """``y`` minus the guide line at ``x`` [m] (NaN outside the guide's x range).

    ``guide`` is a ``(G, 4)`` table (x, slope, a, y) every :data:`GUIDE_STEP`
    (G = 0: none); the line near ``x`` is the local quadratic of the nearest row.
    """
    ng = guide.shape[0]
    if ng == 0 or x < guide[0, 0] or x > guide[ng - 1, 0]:
        return np.nan
    g = min(int((x - guide[0, 0]) / GUIDE_STEP + 0.5), ng - 1)
    u = x - guide[g, 0]
    return y - (guide[g, 3] + (guide[g, 1] + guide[g, 2] * u) * u)


guide_dev = numba.njit(cache=True)(guide_dev_py)


NEIGHBOUR_GATES = 1.5
"""A trace's poor winner farther than this many ``parallel_gate`` from the traced line
(along the guide's normal) may be a neighbouring marking (:func:`_neighbour`): 0.45 m
by default: inside the 0.75 m between a broken edge line and a solid shoulder line,
and well outside the scatter of a line's own points about its fit under 10 cm of
sensor noise."""

BESIDE_LENGTH = 20.0
"""A trace's poor winner is a neighbouring marking (:func:`_beside`) when points at
its offset from the guide line lie up to this far behind the trace's last point [m] ..."""

BESIDE_DY = 0.15
"""... within this of that offset [m] ..."""

BESIDE_MIN = 3
"""... at least this many of them."""


def _guide_normal_py(guide, x, y, reach):
    """The distance of ``(x, y)`` [m] from the guide line along the guide's normal
    (:func:`guide_dev`, the y difference, times the cosine of the guide's heading; a
    line parallel to the guide keeps it in a bend, where its y difference grows),
    with the guide's end rows extended up to ``reach`` [m] beyond its x range (a
    guide ends where its line turned steeper than ``max_slope``, a few metres before a
    line beside it may); NaN farther out."""
    ng = guide.shape[0]
    if ng == 0 or x < guide[0, 0] - reach or x > guide[ng - 1, 0] + reach:
        return np.nan
    g = min(max(int((x - guide[0, 0]) / GUIDE_STEP + 0.5), 0), ng - 1)
    u = x - guide[g, 0]
    slope = guide[g, 1] + 2.0 * guide[g, 2] * u
    dy = y - (guide[g, 3] + (guide[g, 1] + guide[g, 2] * u) * u)
    return dy / math.sqrt(1.0 + slope * slope)


_guide_normal = numba.njit(cache=True)(_guide_normal_py)


def _beside_py(xs, ys, guide, x_last, off, reach):
    """Whether at least :data:`BESIDE_MIN` points with ``x_last - BESIDE_LENGTH <= x <=
    x_last`` lie within :data:`BESIDE_DY` of distance ``off`` [m] from the guide line
    (along its normal, :func:`_guide_normal`): a marking that has run beside the
    traced line, parallel to it. ``xs`` is sorted."""
    lo = np.searchsorted(xs, x_last - BESIDE_LENGTH)
    count = 0
    for k in range(lo, xs.shape[0]):
        if xs[k] > x_last:
            break
        if abs(_guide_normal(guide, xs[k], ys[k], reach) - off) <= BESIDE_DY:
            count += 1
            if count >= BESIDE_MIN:
                return True
    return False


_beside = numba.njit(cache=True)(_beside_py)


def _neighbour_py(ctx, best):
    """Whether a trace's winner ``best`` — after a poor fit to its prediction — lies
    on a neighbouring marking: more than :data:`NEIGHBOUR_GATES` times
    ``parallel_gate`` from the traced line, both measured along the guide line's
    normal (the line at the trace's last x, where its fit passes; the guide extended
    by ``search_length`` beyond its ends), on a marking that has run beside the
    traced line (:func:`_beside`), e.g. a solid shoulder line beside a broken edge line
    whose next dash is not in view. The line then ends rather than stepping over to
    it. A line's own next dash after a gap in a tight bend can be as far off its
    prediction and the guide's y, but not off its distance along the normal, and no
    marking runs beside it there."""
    xs, ys, _mask, _geo, _start, _pts, x_last, _a, _b, c_last, _inv, fp, _sig2, guide, _ = ctx
    reach = fp[P.search_length]
    off = _guide_normal(guide, xs[best], ys[best], reach)
    own = _guide_normal(guide, x_last, c_last, reach)
    if not abs(off - own) > NEIGHBOUR_GATES * fp[P.parallel_gate]:
        return False
    return _beside(xs, ys, guide, x_last, off, reach)


_neighbour = numba.njit(cache=True)(_neighbour_py)


def _scan_py(ctx, x_lo, x_hi, r_max, nearest, par_max):
    """The best unclaimed point with ``x_lo < x <= x_hi`` that passes the gate
    (:func:`_gated`) with |residual| <= ``r_max`` (and, for a finite ``par_max``, lies
    within ``par_max`` of the guide line shifted by ``g_off``): the nearest in x (``nearest``;
    ties: smaller residual, then smaller index) or the smallest residual (ties:
    smaller index). Only grid cells the prediction ± gate_max crosses are visited,
    bins in x order (``nearest`` stops at the first bin with a hit).

    ``ctx`` is the search's context, ``(xs, ys, mask, geo, start, pts, x_last, A, B,
    C, inv, fp, sig2, guide, g_off)`` (see :func:`grid_search`).

    Used by the rare second look only: :func:`grid_search`'s own two passes do the
    same visit inline, because calling this for them made a typical frame's
    ``detect_lanes`` ~30 % slower (92 vs 121 µs, ``benchmarks/bench_aldm.py`` frame).

    :return: ``(index or -1, its |residual|)``.
    """
    xs, ys, mask, geo, start, pts, x_last, A, B, C, inv, fp, sig2, guide, g_off = ctx
    x0 = geo[0]
    igx = geo[1]
    gx = 1.0 / igx
    nx = int(geo[4])
    ny = int(geo[5])
    gm = fp[P.gate_max]
    bx_lo = min(int((x_lo - x0) * igx), nx - 1) if x_lo >= x0 else 0
    bx_hi = min(int((x_hi - x0) * igx), nx - 1)
    best = -1
    best_x = np.inf
    best_r = np.inf
    for bx in range(bx_lo, bx_hi + 1):
        xa = max(x0 + bx * gx, x_last)
        xb = min(x0 + (bx + 1) * gx, x_hi)
        by0, by1 = _cell_rows(geo, x_last, xa, xb, A, B, C, gm)
        for by in range(by0, by1 + 1):
            c = bx * ny + by
            for q in range(start[c], start[c + 1]):
                k = pts[q]
                x = xs[k]
                if x <= x_lo or x > x_hi or mask[k] != 0 or (nearest and x > best_x):
                    continue
                r = _gated(xs, ys, k, x_last, A, B, C, inv, fp, sig2)
                if r < 0.0 or r > r_max:
                    continue
                if par_max < np.inf and not abs(guide_dev(guide, x, ys[k]) - g_off) <= par_max:
                    continue
                if (nearest and x < best_x) or r < best_r or (r == best_r and k < best):
                    best = k
                    best_x = x
                    best_r = r
        if nearest and best >= 0:
            break
    return best, best_r


_scan = numba.njit(cache=True)(_scan_py)


def grid_search_py(
    xs, ys, mask, geo, start, pts, x_last, A, B, C, inv, fp, sig2, search, guide, g_off
):
    """Next point of a robust trace (§ALDM step 2 with a gate), via the grid.

    Among unclaimed points with ``x_last < x <= x_last + search`` that pass the
    gate (:func:`_gated`), the nearest in x wins; gated points within ``tie_dx`` of
    it compete by |residual| (ties: smaller (x, y)). If the winner's residual exceeds
    ``skip_residual``, the nearest gated point farther in the window with at most half
    that residual wins instead (clutter beside a dashed line fills its gaps).

    Markings are parallel: with a guide line (``guide``, see :func:`guide_dev`) and
    the traced line's mean offset from it (``g_off``; NaN: not known), a winner more
    than ``parallel_gate`` off the guide shifted by that offset yields to the nearest
    gated point in the window at most half as far off (an old marking diverging from
    the paint at a small angle, while the paint goes on). After a poor fit, a point on
    a neighbouring marking that has run beside the line ends the line
    (:func:`_neighbour`: a solid shoulder line beside a broken edge line); like the
    guide check, only where ``g_off`` is known.

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
    tie_dx = fp[P.tie_dx]
    gm = fp[P.gate_max]
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
    best = np.int64(-1)  # int64, not a literal: one compiled callee (numba)
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
    if best_r <= fp[P.skip_residual] and not (
        abs(guide_dev(guide, xs[best], ys[best]) - g_off) > fp[P.parallel_gate]
    ):
        return best  # the common case: no second look (NaN offsets compare false)
    ctx = (xs, ys, mask, geo, start, pts, x_last, A, B, C, inv, fp, sig2, guide, g_off)
    return _second_look(ctx, x_hi, x_tie, best, best_r)


def _second_look_py(ctx, x_hi, x_tie, best, best_r):
    """The rare second look of :func:`grid_search` at its winner ``best``: a poor fit
    (residual above ``skip_residual``: a tar seam beside a dashed line, in the gap)
    yields to the nearest gated point farther in the window that fits at least twice
    as well; a point off the guide shifted by ``g_off`` by more than ``parallel_gate``
    (an old marking diverging from the paint) to the nearest gated point at most half
    as far off. After a poor fit, a point on a neighbouring marking that has run beside
    the line (:func:`_neighbour`) ends the line instead (-1). Kept out of the search's
    common path, which stays as small as it was.
    ``ctx`` is the search's context (:func:`_scan`).
    """
    xs = ctx[0]
    ys = ctx[1]
    x_last = ctx[6]
    fp = ctx[11]
    guide = ctx[13]
    g_off = ctx[14]
    poor = best_r > fp[P.skip_residual]
    if poor:
        skip, _ = _scan(ctx, x_tie, x_hi, 0.5 * best_r, True, np.inf)
        if skip >= 0:
            best = skip
    if g_off == g_off:
        dev = abs(guide_dev(guide, xs[best], ys[best]) - g_off)
        if dev > fp[P.parallel_gate]:
            alt, _ = _scan(ctx, x_last, x_hi, np.inf, True, 0.5 * dev)
            if alt >= 0:
                best = alt
        if poor and _neighbour(ctx, best):
            return -1
    return best


_second_look = numba.njit(cache=True)(_second_look_py)


grid_search = numba.njit(cache=True)(grid_search_py)
