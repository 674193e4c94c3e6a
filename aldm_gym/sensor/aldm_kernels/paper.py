"""Paper mode: the ALDM of §ALDM as published (start condition, exact parabola, trace).

The paper's algorithm, kept as the reference the robust mode is measured against:
three lowest-|y| start points per side, the exact parabola through the last three
points, the nearest residual within the next 18 m, no gate. Where the text leaves a
choice (stop rule, adjacent-line start, Lagrange evaluation) the choice is marked
in the docstrings below and listed in ``docs/aldm.md``.
"""

from __future__ import annotations

import numba
import numpy as np

from aldm_gym.sensor.aldm_kernels.layout import (
    L_EGO_LEFT,
    L_EGO_RIGHT,
    L_LEFT_ADJ,
    L_RIGHT_ADJ,
    N_LINES,
    I,
    P,
)
from aldm_gym.sensor.aldm_kernels.sort import insertion_sort


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
    insertion_sort(out, got)  # index order is (x, y) order
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


def paper_detect_py(xs, ys, fp, ip, mask, offsets):
    """The paper's ALDM: start conditions and traces of the four lines.

    ``offsets[l]`` receives each found line's start-parabola value at x = 0 [m]
    (used for the lane-width estimate), NaN when not found.
    """
    n = xs.shape[0]
    m = 0
    while m < n and xs[m] <= fp[P.start_x_max]:
        m += 1
    k = ip[I.start_points]
    spacing = fp[P.start_spacing]
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
            min_off = fp[P.adjacent_offset]
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
            xs,
            ys,
            start[got - 3 : got],
            fp[P.search_length],
            fp[P.view_range],
            mask,
            np.uint8(1 << slot),
        )


paper_detect = numba.njit(cache=True)(paper_detect_py)
