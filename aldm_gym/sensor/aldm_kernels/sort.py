"""Sort stage: the points in canonical (x, y) order, and the one bucket sort behind it.

Every later stage sees the points sorted lexicographically by ``(x, y)``
(:func:`gather`), so each decision depends on point *values* only: input order can
never change a result. The start condition walks its points in y order with the same
sort (:func:`bucket_order`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

SMALL_RUN = 16
"""Buckets up to this size are sorted by insertion, larger (crowded) ones by argsort."""


def insertion_sort_py(a, m):
    """Sort ``a[:m]`` in place, ascending, by insertion (a handful of values, no
    allocation)."""
    for i in range(1, m):
        v = a[i]
        j = i - 1
        while j >= 0 and a[j] > v:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = v


insertion_sort = numba.njit(cache=True)(insertion_sort_py)


def _sort_run_py(k1, k2, order, a, b):
    """Sort ``order[a:b]`` lexicographically by ``(k1, k2)`` (a crowded bucket)."""
    run = order[a:b]
    run = run[np.argsort(k1[run])]
    # Runs of equal k1 by k2 (the argsort need not be stable or lexicographic).
    i = 0
    n = run.shape[0]
    while i < n:
        j = i + 1
        while j < n and k1[run[j]] == k1[run[i]]:
            j += 1
        if j - i > 1:
            run[i:j] = run[i:j][np.argsort(k2[run[i:j]])]
        i = j
    order[a:b] = run


_sort_run = numba.njit(cache=True)(_sort_run_py)


def bucket_order_py(k1, k2):
    """The indices that sort ``(k1, k2)`` lexicographically (ties in index order or any).

    A bucket sort on ``k1``: as many buckets as values over its range, each bucket by
    insertion (most hold 0-3 values) or, when crowded, by ``np.argsort``. O(N) for
    roughly uniform ``k1`` (the sensor's x, the start region's y), O(N log N) at worst.
    The bucket index is monotone in ``k1``, so the buckets concatenate in order.
    Pass ``k2 = k1`` to sort by one key. Values must be finite.

    :param k1: ``(M,)`` primary key.
    :param k2: ``(M,)`` secondary key, for ties in ``k1``.
    :return: ``(M,)`` int64 permutation.
    """
    m = k1.shape[0]
    order = np.empty(m, dtype=np.int64)
    if m == 0:
        return order
    lo = k1[0]
    hi = k1[0]
    for i in range(m):
        lo = min(lo, k1[i])
        hi = max(hi, k1[i])
    scale = m / (hi - lo) if hi > lo else 0.0
    if not math.isfinite(scale):
        scale = 0.0  # a sub-normal range: one bucket
    # cnt[b + 1]: size of bucket b, then (prefix sum) its end; fill[b]: next free slot.
    key = np.empty(m, dtype=np.int64)
    cnt = np.zeros(m + 1, dtype=np.int64)
    for i in range(m):
        b = min(int((k1[i] - lo) * scale), m - 1)
        key[i] = b
        cnt[b + 1] += 1
    for b in range(m):
        cnt[b + 1] += cnt[b]
    fill = cnt[:m].copy()
    for i in range(m):
        b = key[i]
        order[fill[b]] = i
        fill[b] += 1
    # now bucket b is order[cnt[b]:cnt[b + 1]]
    for b in range(m):
        s = cnt[b]
        e = cnt[b + 1]
        if e - s > SMALL_RUN:
            _sort_run(k1, k2, order, s, e)
            continue
        for i in range(s + 1, e):
            v = order[i]
            x = k1[v]
            y = k2[v]
            j = i - 1
            while j >= s and (k1[order[j]] > x or (k1[order[j]] == x and k2[order[j]] > y)):
                order[j + 1] = order[j]
                j -= 1
            order[j + 1] = v
    return order


bucket_order = numba.njit(cache=True)(bucket_order_py)


def gather_py(pts, has_z, z_band, max_range):
    """Valid points in canonical order: sorted lexicographically by ``(x, y)``.

    Rows with a non-finite coordinate, with x < 0 (behind the sensor), with x or |y|
    beyond ``max_range`` or, when ``has_z``, with ``|z| > z_band`` (an overpass's
    lines, barriers) are dropped; ``-0.0`` becomes ``0.0``. The result is a function
    of the point set only, never of the input order (:func:`bucket_order`).

    :return: ``(xs, ys)``, each ``(M,)`` [m].
    """
    n = pts.shape[0]
    vx = np.empty(n)
    vy = np.empty(n)
    m = 0
    for i in range(n):
        x = pts[i, 0]
        y = pts[i, 1]
        if not (0.0 <= x <= max_range and abs(y) <= max_range):
            continue  # also drops NaN (comparisons are False) and inf
        if has_z:
            z = pts[i, 2]
            if not math.isfinite(z) or abs(z) > z_band:
                continue
        vx[m] = x + 0.0  # -0.0 -> 0.0
        vy[m] = y + 0.0
        m += 1
    vx = vx[:m]
    vy = vy[:m]
    order = bucket_order(vx, vy)
    xs = np.empty(m)
    ys = np.empty(m)
    for q in range(m):
        xs[q] = vx[order[q]]
        ys[q] = vy[order[q]]
    return xs, ys


gather = numba.njit(cache=True)(gather_py)
