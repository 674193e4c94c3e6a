"""Kernels of the tracking ALDM (:class:`aldm_gym.sensor.tracking.LaneTracker`).

The tracker carries the last frame's lines forward by odometry and tabulates them
(:func:`track_table`), holds them to the lanes' common shape (:func:`consensus`; the
detected lines too, :func:`hold_to_consensus`), turns them into a prior for the stateless ALDM
(:func:`track_prior`: which points support a track, which contradict it, and prior points
along the stretches a track has no support in) and gives every detected line the
identity of the track it continues (:func:`match_tracks`). Decisions and their reasons:
``docs/aldm.md``, section "Tracking".

A track is a polyline sorted by x (a line of the last detection); the tracks of a
frame are concatenated into one ``(M, 2)`` array with offsets ``ls`` (track ``t`` is
``lines[ls[t]:ls[t + 1]]``).
Plain-Python twins ``_name_py`` as in the other kernel modules.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aldm_gym.sensor.aldm_kernels.sort import insertion_sort


def _interp_line_py(lx, ly, lo, hi, x):
    """y of the polyline ``lx[lo:hi], ly[lo:hi]`` at ``x`` [m]; NaN beyond its last
    vertex, before ``min(first vertex, 0)``, or for fewer than two vertices.

    Before the first vertex the first parabola is extrapolated down to the sensor
    (x = 0): a line whose first dash began 17 m ahead still claims, and guards, the
    start region of the next frame.

    A parabola through the segment's two vertices and the next one (the previous one
    at the end): the ALDM returns 13 points over up to 200 m, and a chord between
    vertices 16 m apart lies 4 cm inside a 800 m curve, a bias a tracker would add
    up frame after frame.
    """
    if hi - lo < 2 or x > lx[hi - 1] or x < min(lx[lo], 0.0):
        return math.nan
    a = lo
    b = hi - 1
    if x < lx[lo]:
        b = lo + 1
    while b - a > 1:
        m = (a + b) // 2
        if lx[m] <= x:
            a = m
        else:
            b = m
    span = lx[b] - lx[a]
    if span <= 0.0:
        return ly[a]
    if hi - lo == 2:
        return ly[a] + (x - lx[a]) / span * (ly[b] - ly[a])
    c = b + 1 if b + 1 < hi else a - 1
    x0 = lx[a]
    x1 = lx[b]
    x2 = lx[c]
    return (
        ly[a] * (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2))
        + ly[b] * (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2))
        + ly[c] * (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1))
    )


TABLE_STEP = 2.0
"""Spacing in x of the tracks' look-up tables [m]: linear interpolation between
samples of the parabolas 2 m apart is off by 0.6 mm in a 800 m curve, 5 mm in a
100 m one."""


def track_table_py(lines, ls, dx, dy, dpsi):
    """The tracks ``lines[ls[t]:ls[t + 1]]`` (``(K, 2)`` each, sorted by x) moved into
    the new sensor frame, tabulated.

    The sensor moved by ``(dx, dy)`` [m] and turned by ``dpsi`` [rad], both in the
    old frame. Each moved track is sampled at x = 0, 2, 4, ... m on
    :func:`_interp_line_py`'s parabolas (in Newton's form, computed once per segment
    while walking the vertices once); NaN where the track does not reach. Before its
    first vertex a track is extrapolated down to x = 0. A track is cut at its first
    vertex that would not be strictly ahead of the previous one.

    :return: ``(table, first)``: ``(T, G)`` y [m], and ``(T,)`` the x of each moved
        track's first vertex [m] (inf for a track of fewer than two vertices; samples
        before it are extrapolated).
    """
    c = math.cos(dpsi)
    s = math.sin(dpsi)
    n_tracks = len(ls) - 1
    px = np.empty(lines.shape[0])
    py = np.empty(lines.shape[0])
    ps = np.zeros(n_tracks + 1, dtype=np.int64)
    k = 0
    x_max = 0.0
    for t in range(n_tracks):
        ps[t] = k
        last = -math.inf
        for i in range(ls[t], ls[t + 1]):
            u = lines[i, 0] - dx
            v = lines[i, 1] - dy
            x = c * u + s * v
            if x <= last:
                break
            px[k] = x
            py[k] = -s * u + c * v
            last = x
            k += 1
        if k - ps[t] >= 2 and px[k - 1] > x_max:
            x_max = px[k - 1]
    ps[n_tracks] = k
    n_grid = int(x_max / TABLE_STEP) + 2
    table = np.full((n_tracks, n_grid), math.nan)
    first = np.full(n_tracks, math.inf)
    for t in range(n_tracks):
        lo = ps[t]
        hi = ps[t + 1]
        if hi - lo < 2:
            continue
        first[t] = px[lo]
        a = lo  # the segment (a, a + 1) holding x, walked forward once (x grows)
        seg = -1  # the segment whose parabola is in (x0, x1, y0, d01, d012)
        x0 = x1 = y0 = d01 = d012 = 0.0
        for g in range(n_grid):
            x = g * TABLE_STEP
            if x > px[hi - 1]:
                break
            if x < min(px[lo], 0.0):
                continue
            while a + 2 < hi and px[a + 1] <= x:
                a += 1
            if a != seg:
                # _interp_line_py's parabola: through a, a + 1 and the next vertex (the
                # previous one on the last segment), in Newton's form, once per segment
                seg = a
                if hi - lo == 2:
                    i0, i1, i2 = a, a + 1, -1
                elif a + 3 <= hi:
                    i0, i1, i2 = a, a + 1, a + 2
                else:
                    i0, i1, i2 = a - 1, a, a + 1
                x0 = px[i0]
                x1 = px[i1]
                y0 = py[i0]
                d01 = (py[i1] - y0) / (x1 - x0)
                d012 = 0.0
                if i2 >= 0:
                    d012 = ((py[i2] - py[i1]) / (px[i2] - x1) - d01) / (px[i2] - x0)
            table[t, g] = y0 + (x - x0) * (d01 + (x - x1) * d012)
    return table, first


track_table = numba.njit(cache=True)(track_table_py)


CONSENSUS_NEAR = 50.0
"""Two tracks parting are ended only beyond this x [m] (nearer, a part that strays
is more likely the start region's than the lane's)."""


def _median_py(buf, m):
    """Median of ``buf[:m]`` (``m >= 1``); a handful of values are sorted in place
    (no allocation), more by numpy's selection (insertion sort is quadratic)."""
    if m > 16:
        return np.median(buf[:m])
    insertion_sort(buf, m)
    h = m // 2
    return buf[h] if m % 2 == 1 else 0.5 * (buf[h - 1] + buf[h])


_median = numba.njit(cache=True)(_median_py)


def consensus_py(table, first, tol0, tol_slope):
    """Pull every track back to the lanes' common shape where it strays (in place).

    Lanes are parallel: a track following an old marking or a seam far ahead
    diverges from the others. The reference is the track tabulated at the most x.
    Distances between tracks are taken along the lanes' normal (the lateral
    difference at one x times the cosine of the tracks' median heading: parallel
    curves are farther apart in y where they turn away from the x axis). Each
    track's distance to the reference is its median over all x where both have
    their own samples (from the later of their first vertices ``first`` [m] on, not
    the extrapolation before them): a stray part shorter than half the overlap
    does not move it.
    At every x where at least three tracks are tabulated, the common shift is the
    median over them of (their distance there minus that median distance); a track
    more than ``tol0 + tol_slope * x`` [m] from it is set onto it. Where only two
    tracks are seen beyond :data:`CONSENSUS_NEAR` and their distance changes by more
    than that, nothing says which one strays: both end there (NaN from there on).
    One track alone is left as it is.

    :return: the number of samples moved.
    """
    n_tracks, n_grid = table.shape
    if n_tracks < 2:
        return 0
    count = np.zeros(n_tracks, dtype=np.int64)
    for t in range(n_tracks):
        for g in range(n_grid):
            if not math.isnan(table[t, g]):
                count[t] += 1
    ref = 0
    for t in range(n_tracks):
        if count[t] > count[ref]:
            ref = t
    if count[ref] == 0:
        return 0
    cos = np.full(n_grid, math.nan)  # cosine of the lanes' heading (median slope)
    slopes = np.empty(n_tracks)
    for g in range(n_grid):
        if math.isnan(table[ref, g]):
            continue
        m = 0
        for t in range(n_tracks):
            if math.isnan(table[t, g]):
                continue
            lo = g - 1 if g > 0 and not math.isnan(table[t, g - 1]) else g
            hi = g + 1 if g + 1 < n_grid and not math.isnan(table[t, g + 1]) else g
            if hi > lo:
                slopes[m] = (table[t, hi] - table[t, lo]) / ((hi - lo) * TABLE_STEP)
                m += 1
        if m > 0:
            k = _median(slopes, m)
            cos[g] = 1.0 / math.sqrt(1.0 + k * k)
    near = np.full(n_tracks, math.nan)
    buf = np.empty(max(n_grid, n_tracks))
    for t in range(n_tracks):
        x0 = max(first[t], first[ref], 0.0)
        if not x0 < math.inf:
            continue
        g0 = int(math.ceil(x0 / TABLE_STEP))  # noqa: RUF046  (numba: float ceil)
        m = 0
        for g in range(g0, n_grid):
            if not (math.isnan(table[t, g]) or math.isnan(cos[g])):
                buf[m] = (table[t, g] - table[ref, g]) * cos[g]
                m += 1
        if m > 0:
            near[t] = _median(buf, m)
    moved = 0
    pair = np.empty(2, dtype=np.int64)
    for g in range(n_grid):
        c = cos[g]
        yr = table[ref, g]
        if math.isnan(c) or math.isnan(yr):
            continue
        m = 0
        for t in range(n_tracks):
            if not (math.isnan(table[t, g]) or math.isnan(near[t])):
                buf[m] = (table[t, g] - yr) * c - near[t]
                if m < 2:
                    pair[m] = t
                m += 1
        tol = tol0 + tol_slope * g * TABLE_STEP
        if m == 2 and g * TABLE_STEP >= CONSENSUS_NEAR and abs(buf[0] - buf[1]) > tol:
            # two lines part and nothing says which one strays: both end here
            for t in pair:
                for g2 in range(g, n_grid):
                    if not math.isnan(table[t, g2]):
                        table[t, g2] = math.nan
                        moved += 1
            continue
        if m < 3:
            continue
        shift = _median(buf, m)
        for t in range(n_tracks):
            if math.isnan(table[t, g]) or math.isnan(near[t]):
                continue
            if abs((table[t, g] - yr) * c - near[t] - shift) > tol:
                table[t, g] = yr + (near[t] + shift) / c
                moved += 1
    return moved


consensus = numba.njit(cache=True)(consensus_py)


def hold_to_consensus_py(lines, ls, tol0, tol_slope):
    """A detection's lines (concatenated as the tracks) held to their common shape.

    The lines are tabulated as they are (:func:`track_table` without motion) and
    :func:`consensus` decides where one strays; each vertex moves by the
    consensus's correction there (interpolated between the samples; past the last
    sample, the last one's), and the vertices from a sample before a line was ended
    (two lines parting) on are dropped; a line left with fewer than two is dropped.

    :return: ``(out, out_ls, moved)``: the lines and their offsets (new arrays when
        any vertex moved or was dropped, else the inputs) and whether one did.
    """
    table, first = track_table(lines, ls, 0.0, 0.0, 0.0)
    before = table.copy()
    if consensus(table, first, tol0, tol_slope) == 0:
        return lines, ls, False
    out = np.empty_like(lines)
    out_ls = np.zeros_like(ls)
    n = 0
    n_grid = table.shape[1]
    changed = False
    for t in range(len(ls) - 1):
        out_ls[t] = n
        end = n_grid  # the first sample the consensus ended the line at
        last = -1  # the last sample left
        for g in range(n_grid):
            if math.isnan(before[t, g]):
                continue
            if math.isnan(table[t, g]):
                end = min(end, g)
            else:
                last = g
        for i in range(ls[t], ls[t + 1]):
            x = lines[i, 0]
            if x >= (end - 1) * TABLE_STEP:
                changed = True
                continue
            yt = _lookup(table, t, x)
            yb = _lookup(before, t, x)
            dy = 0.0
            if not (math.isnan(yt) or math.isnan(yb)):
                dy = yt - yb
            elif last >= 0 and x >= last * TABLE_STEP:
                dy = table[t, last] - before[t, last]
            if dy != 0.0:
                changed = True
            out[n, 0] = x
            out[n, 1] = lines[i, 1] + dy
            n += 1
        if n - out_ls[t] < 2:  # a line needs two points
            changed = changed or n > out_ls[t]
            n = out_ls[t]
    out_ls[len(ls) - 1] = n
    if not changed:
        return lines, ls, False
    return out[:n], out_ls, True


hold_to_consensus = numba.njit(cache=True)(hold_to_consensus_py)


def _lookup_py(table, t, x):
    """Track ``t``'s y at ``x`` from its table [m]; NaN where it does not reach."""
    g = int(x / TABLE_STEP)
    if x < 0.0 or g + 1 >= table.shape[1]:
        return math.nan
    f = x / TABLE_STEP - g
    return table[t, g] + f * (table[t, g + 1] - table[t, g])


_lookup = numba.njit(cache=True)(_lookup_py)


def _fill_py(table, t, a, b, ra, rb, d, step, with_a, with_b, vx, vy, n):
    """Prior points on track ``t`` (or, with ``d`` != 0, on its parallel ``d`` [m] to
    the left, :func:`_beside`) whose feet lie between x = a and x = b at most
    ``step`` apart, shifted laterally by ``ra`` at a to ``rb`` at b (linearly) [m],
    written to ``vx, vy`` from index ``n``; the ends only when asked. Returns the
    new count."""
    m = int(math.ceil((b - a) / step))  # noqa: RUF046  (numba: float ceil)
    if m < 1:
        m = 1
    first = 0 if with_a else 1
    last = m if with_b else m - 1
    for k in range(first, last + 1):
        x = a + (b - a) * k / m
        if d == 0.0:
            y = _lookup(table, t, x)
        else:
            x, y = _beside(table, t, x, d)
        if not math.isnan(y):
            vx[n] = x
            vy[n] = y + ra + (rb - ra) * k / m
            n += 1
    return n


_fill = numba.njit(cache=True)(_fill_py)


def _slope_py(table, t, x):
    """dy/dx of track ``t`` at ``x`` from its table (central difference, one-sided at
    its ends); NaN where it does not reach."""
    y0 = _lookup(table, t, x - TABLE_STEP)
    y1 = _lookup(table, t, x + TABLE_STEP)
    if not math.isnan(y0) and not math.isnan(y1):
        return (y1 - y0) / (2.0 * TABLE_STEP)
    y = _lookup(table, t, x)
    if not math.isnan(y1):
        return (y1 - y) / TABLE_STEP
    if not math.isnan(y0):
        return (y - y0) / TABLE_STEP
    return math.nan


_slope = numba.njit(cache=True)(_slope_py)


def _beside_py(table, t, x, d):
    """The point ``d`` [m] to the left of track ``t`` (along its normal) whose foot is
    at ``x`` [m]: ``(x, y)``, NaN where the track does not reach."""
    y = _lookup(table, t, x)
    k = _slope(table, t, x)
    if math.isnan(y) or math.isnan(k):
        return math.nan, math.nan
    c = 1.0 / math.sqrt(1.0 + k * k)
    return x - d * k * c, y + d * c


_beside = numba.njit(cache=True)(_beside_py)


def _parallel_py(table, t, d, x):
    """y at ``x`` [m] of the parallel ``d`` [m] left of track ``t`` (a concentric
    curve: in a bend a constant lateral shift in the sensor frame is not parallel)."""
    k = _slope(table, t, x)
    if math.isnan(k):
        return math.nan
    c = 1.0 / math.sqrt(1.0 + k * k)
    _, y = _beside(table, t, x + d * k * c, d)  # the foot whose normal passes near x
    return y


_parallel = numba.njit(cache=True)(_parallel_py)


def track_prior_py(
    pts, table, coast_ok, gate0, gate_slope, bridge_gap, step, max_pair, z_band, tail_length
):
    """The tracks (tabulated by :func:`track_table`) as a prior for one frame's points.

    A point *supports* the nearest track when its lateral residual to it is within
    ``gate0 + gate_slope * x`` [m]. A point that supports no track and lies between
    two tracks at most ``max_pair`` [m] apart (inside a tracked lane) contradicts the
    track: it is dropped. Points outside the tracked lanes are kept (new lines, the
    lines a lane change brings into view). Along each track, prior points (at most
    ``step`` apart) fill every stretch without support longer than ``bridge_gap``
    between supported points, and the stretch from the nearest measured x to the
    first supported point, shifted by the residuals of the supported points at
    the stretch's ends (the odometry's error, measured); a track with no support
    at all is filled along its whole length when ``coast_ok``.

    Beyond a track's last supported point its *continuation* runs parallel to the
    laterally nearest track (within ``2 * max_pair``) whose support reaches more than
    ``bridge_gap`` farther, at their offset there (lanes are parallel: the car ahead
    hides the ego lane's lines while a line beside is still seen). Points within the
    gate of the continuation that support no track support it; prior points fill its
    stretches without support longer than ``bridge_gap`` and its tail, up to the
    neighbour's last support but never more than ``tail_length`` [m] beyond a point
    supporting the track or its continuation (a stray point far ahead does not
    carry it on; ``tail_length = 0``: no continuation at all).
    The continuation follows the neighbour, seen there in this frame, never the
    track's own carried end (which no point has confirmed for a while and which
    would drift frame after frame). Without such a neighbour nothing is added beyond a track's
    last supported point. Points with NaN/inf, x < 0 or (with z)
    ``|z| > z_band`` are kept untouched (the ALDM drops them) and ignored here.

    :param pts: ``(N, 2|3)`` points in the sensor frame [m].
    :param coast_ok: ``(T,)`` whether a track without support may still be filled.
    :return: ``(keep, vx, vy, support)``: ``(N,)`` bool, the prior points' x and y
        [m], and the number of supporting points per track.
    """
    n_pts = pts.shape[0]
    has_z = pts.shape[1] > 2
    n_tracks = table.shape[0]
    keep = np.ones(n_pts, dtype=np.bool_)
    free = np.zeros(n_pts, dtype=np.bool_)  # valid, kept, supporting no track
    support = np.zeros(n_tracks, dtype=np.int64)
    sup_x = np.empty((n_tracks, max(n_pts, 1)))
    sup_r = np.empty((n_tracks, max(n_pts, 1)))
    x_near = math.inf
    for i in range(n_pts):
        x = pts[i, 0]
        y = pts[i, 1]
        if not (math.isfinite(x) and math.isfinite(y)) or x < 0.0:
            continue
        if has_z:
            z = pts[i, 2]
            if not math.isfinite(z) or abs(z) > z_band:
                continue
        if x < x_near:
            x_near = x
        best = math.inf
        best_r = 0.0
        best_t = -1
        left = math.inf  # lateral distance to the nearest track left of the point
        right = math.inf
        for t in range(n_tracks):
            yt = _lookup(table, t, x)
            if math.isnan(yt):
                continue
            r = y - yt
            if abs(r) < best:
                best = abs(r)
                best_r = r
                best_t = t
            if r < 0.0 and -r < left:
                left = -r
            elif r >= 0.0 and r < right:
                right = r
        if best_t < 0:
            free[i] = True
            continue
        if best <= gate0 + gate_slope * x:
            sup_x[best_t, support[best_t]] = x
            sup_r[best_t, support[best_t]] = best_r
            support[best_t] += 1
        elif left + right <= max_pair:
            keep[i] = False
        else:
            free[i] = True
    last_x = np.full(n_tracks, -math.inf)  # each track's farthest support
    for t in range(n_tracks):
        for j in range(support[t]):
            last_x[t] = max(last_x[t], sup_x[t, j])
    cont_x = np.empty(max(n_pts, 1))
    cap = n_tracks * (int(table.shape[1] * TABLE_STEP / step) + 3 + n_pts)
    vx = np.empty(cap)
    vy = np.empty(cap)
    n = 0
    for t in range(n_tracks):
        # the track's reach: the table's last sample that is not NaN
        b = -1.0
        for g in range(table.shape[1] - 1, -1, -1):
            if not math.isnan(table[t, g]):
                b = g * TABLE_STEP
                break
        a = x_near if math.isfinite(x_near) else 0.0
        if b <= a:
            continue
        ns = support[t]
        if ns == 0:
            if coast_ok[t]:
                n = _fill(table, t, a, b, 0.0, 0.0, 0.0, step, True, True, vx, vy, n)
            continue
        order = np.argsort(sup_x[t, :ns])
        xs = sup_x[t, :ns][order]
        rs = sup_r[t, :ns][order]
        prev = a
        r_prev = 0.0
        for j in range(ns):
            if xs[j] - prev > bridge_gap:
                # the odometry's error is measured at both ends of the gap: the
                # mean residual of up to 3 supported points on each side
                r_next = np.mean(rs[j : min(j + 3, ns)])
                if j == 0:
                    r_prev = r_next
                n = _fill(
                    table, t, prev, xs[j], r_prev, r_next, 0.0, step, j == 0, False, vx, vy, n
                )
            prev = xs[j]
            r_prev = np.mean(rs[max(j - 2, 0) : j + 1])
        # the continuation beyond the last support, along the nearest neighbour
        # whose support reaches farther
        y_end = _lookup(table, t, prev)
        if math.isnan(y_end) or tail_length <= 0.0:
            continue
        y_end += r_prev
        ref = -1
        d = 0.0  # the continuation's distance left of the neighbour, along its normal
        closest = 2.0 * max_pair
        for u in range(n_tracks):
            if u == t or last_x[u] - prev <= bridge_gap:
                continue
            yu = _lookup(table, u, prev)
            ku = _slope(table, u, prev)
            if math.isnan(yu) or math.isnan(ku):
                continue
            # the neighbour where measured: its table plus the residuals of its
            # supports within 10 m of x = prev (the nearest one if none)
            total = 0.0
            count = 0
            near_r = 0.0
            near_dx = math.inf
            for j in range(support[u]):
                dxj = abs(sup_x[u, j] - prev)
                if dxj <= 10.0:
                    total += sup_r[u, j]
                    count += 1
                if dxj < near_dx:
                    near_dx = dxj
                    near_r = sup_r[u, j]
            yu += total / count if count > 0 else near_r
            if abs(y_end - yu) < closest:
                closest = abs(y_end - yu)
                ref = u
                d = (y_end - yu) / math.sqrt(1.0 + ku * ku)
        if ref < 0:
            continue
        m = 0
        for i in range(n_pts):
            x = pts[i, 0]
            if free[i] and prev < x <= last_x[ref]:
                yc = _parallel(table, ref, d, x)
                if abs(pts[i, 1] - yc) <= gate0 + gate_slope * x:
                    cont_x[m] = x
                    m += 1
        cx = np.sort(cont_x[:m])
        # prior points every `step` on the neighbour's track moved d along its
        # normal, in the continuation's stretches without support longer than
        # bridge_gap and its tail; never more than tail_length beyond a point of
        # the track or its continuation (a stray point far ahead does not carry it)
        end = prev
        for j in range(m + 1):
            a = end
            b = min(cx[j] if j < m else last_x[ref], a + tail_length)
            if b - a > bridge_gap:
                on_point = j < m and b == cx[j]  # no prior point on a measured one
                n = _fill(table, ref, a, b, 0.0, 0.0, d, step, False, not on_point, vx, vy, n)
            if j == m or cx[j] - a > tail_length:
                break
            end = cx[j]
    return keep, vx[:n], vy[:n], support


track_prior = numba.njit(cache=True)(track_prior_py)


def match_tracks_py(
    lines, ls, table, match_gate, ids, coast, support, travel, min_support, next_id
):
    """The track each detected line continues, and the lines' ids and coasting.

    The cost of line ``i`` against track ``t`` is the mean lateral distance of the
    line's points where the track reaches (at least two of them); pairs are taken
    greedily by lowest cost below ``match_gate`` [m], each line and track once. A
    matched line takes the track's id; its coasted distance [m] is 0 when at least
    ``min_support`` points supported the track, else the track's plus ``travel``. A
    found line without a track gets the id ``next_id``, ``next_id + 1``, ...

    :param lines: ``(K, 2)`` the detected lines concatenated; line i is
        ``lines[ls[i]:ls[i + 1]]``.
    :return: ``(new_ids, new_coast, next_id)``; id -1 for a line not found.
    """
    n_det = len(ls) - 1
    n_tracks = table.shape[0]
    cost = np.full((n_det, n_tracks), math.inf)
    for i in range(n_det):
        for t in range(n_tracks):
            total = 0.0
            count = 0
            for k in range(ls[i], ls[i + 1]):
                yt = _lookup(table, t, lines[k, 0])
                if not math.isnan(yt):
                    total += abs(lines[k, 1] - yt)
                    count += 1
            if count >= 2:
                cost[i, t] = total / count
    assign = np.full(n_det, -1, dtype=np.int64)
    used = np.zeros(n_tracks, dtype=np.bool_)
    for _ in range(min(n_det, n_tracks)):
        best = match_gate
        bi = -1
        bt = -1
        for i in range(n_det):
            if assign[i] >= 0:
                continue
            for t in range(n_tracks):
                if not used[t] and cost[i, t] < best:
                    best = cost[i, t]
                    bi = i
                    bt = t
        if bi < 0:
            break
        assign[bi] = bt
        used[bt] = True
    new_ids = np.full(n_det, -1, dtype=np.int64)
    new_coast = np.zeros(n_det)
    for i in range(n_det):
        if ls[i + 1] - ls[i] < 2:
            continue
        t = assign[i]
        if t < 0:
            new_ids[i] = next_id
            next_id += 1
        else:
            new_ids[i] = ids[t]
            new_coast[i] = 0.0 if support[t] >= min_support else coast[t] + travel
    return new_ids, new_coast, next_id


match_tracks = numba.njit(cache=True)(match_tracks_py)
