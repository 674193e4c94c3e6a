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
"""Buckets up to this size are sorted by insertion; larger (crowded) ones get another
bucket pass."""
MAX_PASSES = 3
"""Bucket passes over a stretch of points; a bucket still crowded after the last one is
sorted by a stable comparison sort (``np.argsort``, merge sort)."""
HUGE = 2.0**1022
"""Keys of at least this magnitude are halved before their range is taken, so the range
of finite keys cannot overflow (``DBL_MAX - (-DBL_MAX)`` is inf)."""
TINY_SPAN = 1e-300
"""A key range narrower than this per point cannot be bucketed (the scale ``n / range``
would overflow): such a stretch is sorted by comparison."""


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


def _insert_run_py(k1, k2, order, a, b):
    """Sort ``order[a:b]`` lexicographically by ``(k1, k2)`` by insertion (stable)."""
    for i in range(a + 1, b):
        v = order[i]
        x = k1[v]
        y = k2[v]
        j = i - 1
        while j >= a and (k1[order[j]] > x or (k1[order[j]] == x and k2[order[j]] > y)):
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = v


_insert_run = numba.njit(cache=True)(_insert_run_py)


def _sort_run_py(k1, k2, order, a, b):
    """Sort ``order[a:b]`` lexicographically by ``(k1, k2)`` with a stable comparison
    sort (a bucket still crowded after :data:`MAX_PASSES` bucket passes)."""
    run = order[a:b]
    run = run[np.argsort(k1[run], kind="mergesort")]
    # Runs of equal k1 by k2; both sorts are stable, so ties in (k1, k2) keep their order.
    i = 0
    n = run.shape[0]
    while i < n:
        j = i + 1
        while j < n and k1[run[j]] == k1[run[i]]:
            j += 1
        if j - i > 1:
            run[i:j] = run[i:j][np.argsort(k2[run[i:j]], kind="mergesort")]
        i = j
    order[a:b] = run


_sort_run = numba.njit(cache=True)(_sort_run_py)


def _key_scale_py(lo, hi, n):
    """How a key in ``[lo, hi]`` (``lo < hi``) maps to ``n`` buckets:
    ``min(int((v * half - lo_h) * scale), n - 1)``.

    Keys of magnitude >= :data:`HUGE` are halved (exact at that magnitude, monotone
    below it), so the range of finite keys cannot overflow; otherwise ``half = 1.0``
    and the arithmetic is that of the plain key. The map is monotone in the key.

    :return: ``(half, lo_h, scale)``; ``scale = 0.0`` when the range is too narrow to
        bucket (under :data:`TINY_SPAN` per bucket: ``n / range`` would overflow).
    """
    half = 0.5 if max(abs(lo), abs(hi)) >= HUGE else 1.0
    lo_h = lo * half
    span = hi * half - lo_h
    if not span >= n * TINY_SPAN:
        return half, lo_h, 0.0
    return half, lo_h, n / span


_key_scale = numba.njit(cache=True)(_key_scale_py)


def _bucket_pass_py(k1, k2, order, a, b, tmp, cell, end):
    """One stable bucket pass over ``order[a:b]`` (``n = b - a >= 2`` points).

    The key is ``k1``, or ``k2`` when every ``k1`` of the stretch ties (a column of
    the sensor's x grid, split by y): ``n`` buckets over the key's range
    (:func:`_key_scale`), so the buckets concatenate in key order; points are
    scattered in their order in the stretch, so ties keep that order.

    :param tmp: int64 scratch, at least ``n`` long (the scattered stretch).
    :param cell: int64 scratch, at least ``n`` long (each point's bucket).
    :param end: int64, at least ``n`` long; on return bucket ``c`` is
        ``order[a + end[c - 1]:a + end[c]]`` (``end[-1]`` read as 0).
    :return: the number of buckets; 0 when both keys tie over the stretch (it is in
        order as it is); -1 when the key's range is too narrow to bucket.
    """
    n = b - a
    v = order[a]
    lo1 = k1[v]
    hi1 = lo1
    lo2 = k2[v]
    hi2 = lo2
    for q in range(a + 1, b):
        v = order[q]
        lo1 = min(lo1, k1[v])
        hi1 = max(hi1, k1[v])
        lo2 = min(lo2, k2[v])
        hi2 = max(hi2, k2[v])
    key = k1
    lo = lo1
    hi = hi1
    if lo1 == hi1:
        if lo2 == hi2:
            return 0
        key = k2
        lo = lo2
        hi = hi2
    half, lo_h, scale = _key_scale(lo, hi, n)
    if scale == 0.0:
        return -1
    for c in range(n):
        end[c] = 0
    for q in range(n):
        c = min(int((key[order[a + q]] * half - lo_h) * scale), n - 1)
        cell[q] = c
        end[c] += 1
    # end[c]: size of bucket c; exclusive prefix sums make it the bucket's start, and
    # the scatter advances it to the bucket's end.
    s = 0
    for c in range(n):
        k = end[c]
        end[c] = s
        s += k
    for q in range(n):
        c = cell[q]
        tmp[end[c]] = order[a + q]
        end[c] += 1
    for q in range(n):
        order[a + q] = tmp[q]
    return n


_bucket_pass = numba.njit(cache=True)(_bucket_pass_py)


def _sort_crowded_py(k1, k2, order, a, b, work):
    """Sort the crowded bucket ``order[a:b]`` lexicographically by ``(k1, k2)``, stably.

    Further bucket passes (:func:`_bucket_pass`) up to :data:`MAX_PASSES` in all (the
    caller's pass was the first), then a stable comparison sort (:func:`_sort_run`) of
    what is still crowded. The stretches waiting for a pass are disjoint and each has
    more than :data:`SMALL_RUN` points.

    :param work: ``(6, L)`` int64 scratch, ``L >= b - a``.
    """
    tmp = work[0]
    cell = work[1]
    end = work[2]
    st_a = work[3]
    st_b = work[4]
    st_pass = work[5]
    st_a[0] = a
    st_b[0] = b
    st_pass[0] = 1
    top = 1
    while top > 0:
        top -= 1
        a0 = st_a[top]
        nb = _bucket_pass(k1, k2, order, a0, st_b[top], tmp, cell, end)
        if nb < 0:
            _sort_run(k1, k2, order, a0, st_b[top])
            continue
        p = st_pass[top] + 1  # passes done on the buckets below
        s = a0
        for c in range(nb):
            e = a0 + end[c]
            if e - s > SMALL_RUN:
                if p < MAX_PASSES:
                    st_a[top] = s
                    st_b[top] = e
                    st_pass[top] = p
                    top += 1
                else:
                    _sort_run(k1, k2, order, s, e)
            elif e - s > 1:
                _insert_run(k1, k2, order, s, e)
            s = e


_sort_crowded = numba.njit(cache=True)(_sort_crowded_py)


def bucket_order_py(k1, k2):
    """The indices that sort ``(k1, k2)`` lexicographically, ties in index order.

    The order of ``np.lexsort((k2, k1))``, by a most-significant-digit bucket sort: a
    pass puts the points, in index order, into as many buckets as points over the
    range of ``k1`` (:func:`_key_scale`); a bucket of at most :data:`SMALL_RUN` points
    is sorted by insertion (most hold 0-3), a crowded one by further passes
    (:func:`_sort_crowded`): over its own, narrower range of ``k1``, or over ``k2``
    when its ``k1`` all tie. The sensor samples every line at the same x, so a frame's
    x come in columns of exact ties (and a straight road's y too): one pass on x and
    one on y per column. A bucket still crowded after :data:`MAX_PASSES` passes is
    sorted by a stable ``np.argsort``. Every step is stable, so the order is unique.
    O(N) for roughly uniform keys or columns of ties (the sensor's x, the start
    region's y), O(N log N) at worst. Pass ``k2 = k1`` to sort by one key. Values must
    be finite, of any magnitude.

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
    half, lo_h, scale = 1.0, lo, 0.0  # all ties (or too narrow): one bucket
    if hi > lo:
        half, lo_h, scale = _key_scale(lo, hi, m)
    # cnt[b + 1]: size of bucket b, then (prefix sum) its end; fill[b]: next free slot.
    key = np.empty(m, dtype=np.int64)
    cnt = np.zeros(m + 1, dtype=np.int64)
    for i in range(m):
        b = min(int((k1[i] * half - lo_h) * scale), m - 1)
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
    # Scratch of the crowded buckets, sized for the largest one and bound once: an
    # array rebound inside the loop below made the whole sort about 2x slower (numba).
    big = 0
    for b in range(m):
        big = max(big, cnt[b + 1] - cnt[b])
    work = np.empty((6, big if big > SMALL_RUN else 0), dtype=np.int64)
    for b in range(m):
        s = cnt[b]
        e = cnt[b + 1]
        if e - s > SMALL_RUN:
            _sort_crowded(k1, k2, order, s, e, work)
        elif e - s > 1:
            _insert_run(k1, k2, order, s, e)
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
