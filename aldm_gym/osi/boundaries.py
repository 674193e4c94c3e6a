"""Painted markings <-> OSI lane boundaries: points with dash states.

OSI's ``LaneBoundary`` is a polyline of ``BoundaryPoint``s; a dashed line has a point
at the start (``DASH_START``) and one at the end (``DASH_END``) of every dash, points
inside a dash are ``DASH_CONTINUE`` and points in a gap ``DASH_GAP`` (osi_lane.proto).
That is the paper's problem in OSI's words: the dashes of a converted road survive a
cut-down view.

Writing (:func:`sample_boundaries`): every marking of a road near a sensor, sampled at
the sensor's x grid (so a reader measuring with the same sensor meets the same
vertices), with a point added at each end of each painted stretch. Reading
(:func:`painted_intervals`): the painted stretches of a boundary from its dash states,
as arc-length intervals along the boundary's own polyline.

Frames: OSI's world is right-handed (x east, y north, the inertial frame of an
OpenDRIVE map); highway-env's world is mirrored in y (``docs/architecture.md``). A
world point ``(x, y)`` here is ``(x, -y)`` in OSI, a heading ``h`` is ``-h``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numba
import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.roads.protocol import MarkedRoad
from aldm_gym.types import FloatArray

DASH_UNKNOWN, DASH_OTHER, DASH_START, DASH_CONTINUE, DASH_END, DASH_GAP = range(6)
"""``osi3.LaneBoundary.BoundaryPoint.Dash`` values (OSI 3.8)."""

_TIE = 1e-9
"""Two arc lengths closer than this are one place [m]."""

OPEN_END = 1e-6
"""A painted stretch still open at a boundary's last point ends this far beyond it
[m], so that the point itself is painted (intervals are half-open)."""


@dataclass(frozen=True)
class BoundarySample:
    """One marking near a sensor as OSI boundary points.

    :ivar marking: the marking's index on the road (its row of ``marking_table``).
    :ivar xy: ``(N, 2)`` world points (highway-env frame) [m], in increasing sensor x.
    :ivar x: ``(N,)`` their x in the sensor frame [m].
    :ivar dash: ``(N,)`` dash state of each point (:data:`DASH_START` ...).
    """

    marking: int
    xy: FloatArray
    x: FloatArray
    dash: np.ndarray


def marking_intervals(table: Mapping[str, np.ndarray], j: int, lo: float, hi: float) -> FloatArray:
    """Painted intervals ``[u0, u1)`` of marking ``j`` meeting ``[lo, hi]`` [m]: its
    explicit paint, its periodic dash pattern, or one run for a continuous line."""
    a, b = int(table["paint_start"][j]), int(table["paint_start"][j + 1])
    if b > a:
        rows = np.asarray(table["paint"][a:b], dtype=np.float64)
        return rows[(rows[:, 1] > lo) & (rows[:, 0] < hi)]
    if not bool(table["broken"][j]):
        return np.array([[lo - 1.0, hi + 1.0]])
    phase, period, dash = (float(table[k][j]) for k in ("phase", "period", "dash"))
    n0 = int(np.floor((lo - phase) / period)) - 1
    n1 = int(np.ceil((hi - phase) / period)) + 1
    starts = phase + period * np.arange(n0, n1 + 1)
    rows = np.stack([starts, starts + dash], axis=1)
    return rows[(rows[:, 1] > lo) & (rows[:, 0] < hi)]


def _run_points_py(
    x: FloatArray,
    y: FloatArray,
    u: FloatArray,
    intervals: FloatArray,
    px: FloatArray,
    py: FloatArray,
    state: np.ndarray,
) -> int:
    """Points and dash states of one contiguous run of samples (x increasing), into
    ``px``, ``py``, ``state`` (room for ``len(x) + 2 len(intervals)``); their number.

    Samples inside paint (``[u0, u1)`` along the marking's arc length ``u``) are
    ``CONTINUE``, samples in gaps ``GAP`` (they keep the gap on the marking: a chord
    across a 12 m gap would leave it by L²/8R); a point is added where the paint starts
    (``START``) and ends (``END``), interpolated linearly in ``u`` between samples, and
    a sample on such an edge gives way to it.
    A run that begins or ends inside paint begins or ends with a ``CONTINUE`` sample
    (the view cuts it); a stretch beginning within ``_TIE`` after the first sample
    counts as begun there. ``intervals``: sorted by start; touching or overlapping ones
    are joined, empty ones dropped.

    Plain-Python reference of ``_run_points`` (same code, compiled once)."""
    k = len(x)
    if k < 2:
        return 0
    # join touching and overlapping intervals
    iv = np.empty((len(intervals), 2))
    m = 0
    for r in range(len(intervals)):
        lo = intervals[r, 0]
        hi = intervals[r, 1]
        if hi - lo <= _TIE:
            continue
        if m > 0 and lo <= iv[m - 1, 1] + _TIE:
            iv[m - 1, 1] = max(iv[m - 1, 1], hi)
        else:
            iv[m, 0] = lo
            iv[m, 1] = hi
            m += 1
    if m == 0:
        return 0
    rising = u[k - 1] >= u[0]
    umin = min(u[0], u[k - 1])
    umax = max(u[0], u[k - 1])
    # the paint edges strictly inside the run, in x order: (t, entering paint)
    ne = 0
    e_t = np.empty(2 * m)
    e_in = np.empty(2 * m, dtype=np.bool_)
    for q in range(2 * m):
        r = q if rising else 2 * m - 1 - q  # u grows with x, or falls
        ue = iv[r // 2, r % 2]
        if not (umin + _TIE < ue < umax - _TIE):
            continue
        # the sample segment that crosses ue (u monotonic along the run)
        lo_i = 0
        hi_i = k - 1
        while hi_i - lo_i > 1:
            mid = (lo_i + hi_i) // 2
            if (u[mid] <= ue) == rising:
                lo_i = mid
            else:
                hi_i = mid
        e_t[ne] = lo_i + (ue - u[lo_i]) / (u[hi_i] - u[lo_i])
        # a start enters paint where u grows with x, an end where it falls
        e_in[ne] = (r % 2 == 0) == rising
        ne += 1
    n = 0
    e = 0
    for i in range(k):
        while e < ne and e_t[e] < i - _TIE:
            t = e_t[e]
            j = int(t)
            f = t - j
            px[n] = x[j] + f * (x[j + 1] - x[j])
            py[n] = y[j] + f * (y[j + 1] - y[j])
            state[n] = DASH_START if e_in[e] else DASH_END
            n += 1
            e += 1
        if e < ne and abs(e_t[e] - i) <= _TIE:  # an edge on this sample
            px[n] = x[i]
            py[n] = y[i]
            state[n] = DASH_START if e_in[e] else DASH_END
            n += 1
            e += 1
            continue
        uq = u[i]
        if i == 0:
            uq = uq + (2.0 * _TIE if rising else -2.0 * _TIE)
        on = False
        for r in range(m):  # few intervals per run
            if iv[r, 0] <= uq < iv[r, 1]:
                on = True
                break
        px[n] = x[i]
        py[n] = y[i]
        state[n] = DASH_CONTINUE if on else DASH_GAP
        n += 1
    if n > 0 and state[n - 1] == DASH_START:  # a dash that begins at the run's end
        n -= 1
    return n


_run_points_kernel = numba.njit(cache=True)(_run_points_py)


def _run_points(
    x: FloatArray, y: FloatArray, u: FloatArray, intervals: FloatArray
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """:func:`_run_points_py` as arrays ``(px, py, state)``."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    iv = np.asarray(intervals, dtype=np.float64).reshape(-1, 2)
    iv = iv[np.argsort(iv[:, 0], kind="stable")]
    size = len(x) + 2 * len(iv)
    px, py = np.empty(size), np.empty(size)
    state = np.empty(size, dtype=np.int64)
    n = _run_points_kernel(
        x,
        np.ascontiguousarray(y, dtype=np.float64),
        np.ascontiguousarray(u, dtype=np.float64),
        iv,
        px,
        py,
        state,
    )
    return px[:n], py[:n], state[:n]


def sample_boundaries(
    road: MarkedRoad, origin: FloatArray, yaw: float, xs: FloatArray
) -> list[BoundarySample]:
    """Every marking of ``road`` near a sensor frame as OSI boundary points.

    :param origin: the frame's world origin ``(2,)`` [m] (highway-env frame).
    :param yaw: world heading of its x axis [rad].
    :param xs: ``(K,)`` increasing x [m]: the samples (the sensor's own grid).
    :return: one :class:`BoundarySample` per painted run of a marking in view
        (``dash`` never empty; a run shorter than two samples is dropped).
    """
    rows, ys, us = road.sample_visible(origin, yaw, xs)
    table = road.marking_table
    c, s = float(np.cos(yaw)), float(np.sin(yaw))
    out = []
    seen = np.isfinite(ys) & np.isfinite(us)
    counts = seen.sum(axis=1)
    for r, j in enumerate(rows):
        if counts[r] < 2:
            continue
        idx = np.flatnonzero(seen[r])
        if idx[-1] - idx[0] + 1 == len(idx):  # one run (the usual case)
            runs: list = [slice(int(idx[0]), int(idx[-1]) + 1)]
        else:
            runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
        for run in runs:
            u = us[r, run]
            lo, hi = (float(u[0]), float(u[-1])) if u[-1] >= u[0] else (float(u[-1]), float(u[0]))
            iv = marking_intervals(table, int(j), lo, hi)
            if len(iv) == 0:
                continue
            px, py, dash = _run_points(xs[run], ys[r, run], u, iv)
            if len(dash) < 2 or (dash == DASH_GAP).all():
                continue
            # sensor frame -> highway-env world: forward (c, s), left (s, -c)
            xy = np.stack([origin[0] + px * c + py * s, origin[1] + px * s - py * c], axis=1)
            out.append(BoundarySample(int(j), xy, px, dash))
    return out


def painted_intervals(
    u: FloatArray,
    dash: np.ndarray,
    botts: bool = False,
    width: float = 0.1,
    dashed: bool = False,
) -> FloatArray:
    """Painted stretches of one OSI boundary, as intervals ``[u0, u1]`` of its arc length.

    Points in order: ``DASH_START`` opens a stretch, ``DASH_END`` closes it,
    ``DASH_CONTINUE`` lies on one (and opens one where none is open: a view cut inside
    a dash) and ``DASH_GAP`` lies between two (it closes an open stretch at the point
    before it). A stretch still open at the last point ends :data:`OPEN_END` beyond it.
    Without any ``START``, ``END``, ``GAP`` or ``CONTINUE`` (``DASH_UNKNOWN``/``OTHER``
    everywhere): a dashed line (``dashed``) has its dashes between points 0 and 1, 2
    and 3, ... (OSI: "one BoundaryPoint has to be at the start and another at the end
    of each dashed line segment"; esmini writes its dashes so), Botts' dots (``botts``)
    a dot ``width`` [m] long at every point (OSI: "one BoundaryPoint position has to
    define each Botts' dot"), anything else is painted all along.

    :param u: ``(N,)`` arc length of the points along the boundary [m], increasing.
    :param dash: ``(N,)`` dash states.
    :raises InputError: ``u`` and ``dash`` of different lengths.
    """
    u = np.asarray(u, dtype=np.float64)
    dash = np.asarray(dash, dtype=np.int64)
    if u.shape != dash.shape:
        raise InputError(f"u and dash must have the same length, got {u.shape} and {dash.shape}")
    out = np.empty((len(u) + 1, 2))
    k = _painted(u, dash, bool(botts), float(width), bool(dashed), out)
    return out[:k].copy()


def _painted_py(
    u: FloatArray, dash: np.ndarray, botts: bool, width: float, dashed: bool, out: FloatArray
) -> int:
    """:func:`painted_intervals` into ``out`` (``(N + 1, 2)``); the number of rows.

    Plain-Python reference of ``_painted`` (same code, compiled once)."""
    n = len(u)
    if n == 0:
        return 0
    marked = False
    for i in range(n):
        d = dash[i]
        if d == DASH_START or d == DASH_END or d == DASH_GAP or d == DASH_CONTINUE:
            marked = True
            break
    if not marked:
        if botts:
            for i in range(n):
                out[i, 0] = u[i] - 0.5 * width
                out[i, 1] = u[i] + 0.5 * width
            return n
        if dashed:
            k = 0
            for i in range(0, n - 1, 2):
                if u[i + 1] > u[i]:
                    out[k, 0] = u[i]
                    out[k, 1] = u[i + 1]
                    k += 1
            return k
        if n < 2:
            return 0
        out[0, 0] = u[0]
        out[0, 1] = u[n - 1] + OPEN_END
        return 1
    # START (or CONTINUE, or the first point when it ends a stretch) opens paint, END
    # closes it at its point, GAP at the point before it
    k = 0
    open_ = dash[0] == DASH_END
    start = u[0]
    for i in range(n):
        d = dash[i]
        if d == DASH_START or d == DASH_CONTINUE:
            if not open_:
                open_ = True
                start = u[i]
        elif d == DASH_END or d == DASH_GAP:
            if open_:
                stop = u[i] if d == DASH_END else u[i - 1] if i > 0 else start
                if stop > start:
                    out[k, 0] = start
                    out[k, 1] = stop
                    k += 1
            open_ = False
    if open_ and u[n - 1] > start:
        out[k, 0] = start
        out[k, 1] = u[n - 1] + OPEN_END
        k += 1
    return k


_painted = numba.njit(cache=True)(_painted_py)


def _curve_py(
    rows: FloatArray,
    botts: bool,
    dashed: bool,
    width: float,
    stub: float,
    xy: FloatArray,
    u: FloatArray,
    iv: FloatArray,
) -> tuple[int, int]:
    """One OSI boundary's points (``rows``: x, y, dash, as :func:`~aldm_gym.osi.wire.
    decode_points` gives them) as a marking curve in highway-env's world: repeated
    points dropped (the later dash state wins if it is START, END or GAP), a straight
    ``stub`` [m] added at each end, arc lengths, and the painted intervals
    (:func:`painted_intervals`, merged where dots overlap, the stubs painted as their
    ends). Fills ``xy`` ``(N + 2, 2)``, ``u`` ``(N + 2,)``, ``iv`` ``(N + 1, 2)``;
    returns ``(vertices, intervals)``, vertices 0 when fewer than two points differ.

    Plain-Python reference of ``_curve`` (same code, compiled once)."""
    n = rows.shape[1]
    dash = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        x = rows[0, i]
        y = -rows[1, i]  # OSI -> highway-env world
        d = np.int64(rows[2, i])
        if m > 0 and abs(x - xy[m, 0]) + abs(y - xy[m, 1]) <= 1e-9:
            if d == DASH_START or d == DASH_END or d == DASH_GAP:
                dash[m - 1] = d
            continue
        m += 1
        xy[m, 0] = x
        xy[m, 1] = y
        dash[m - 1] = d
    if m < 2:
        return 0, 0
    # arc length of the points, from 0 at the first
    pu = np.empty(m)
    pu[0] = 0.0
    for i in range(1, m):
        pu[i] = pu[i - 1] + np.hypot(xy[i + 1, 0] - xy[i, 0], xy[i + 1, 1] - xy[i, 1])
    raw = np.empty((m + 1, 2))
    k = _painted(pu, dash[:m], botts, width, dashed, raw)
    length = pu[m - 1]
    # clip to the boundary, drop empty ones, merge overlapping (dots)
    q = 0
    for r in range(k):
        lo = max(raw[r, 0], 0.0)
        hi = min(raw[r, 1], length + OPEN_END)
        if hi - lo <= 1e-9:
            continue
        if q > 0 and lo < iv[q - 1, 1]:
            iv[q - 1, 1] = max(iv[q - 1, 1], hi)
            continue
        iv[q, 0] = lo
        iv[q, 1] = hi
        q += 1
    if q == 0:
        return m + 2, 0
    for r in range(q):  # along the curve with its first stub
        iv[r, 0] += stub
        iv[r, 1] += stub
    # the stubs: straight on, painted as their ends are
    d0x = xy[2, 0] - xy[1, 0]
    d0y = xy[2, 1] - xy[1, 1]
    s0 = np.hypot(d0x, d0y)
    d1x = xy[m, 0] - xy[m - 1, 0]
    d1y = xy[m, 1] - xy[m - 1, 1]
    s1 = np.hypot(d1x, d1y)
    xy[0, 0] = xy[1, 0] - stub * d0x / s0
    xy[0, 1] = xy[1, 1] - stub * d0y / s0
    xy[m + 1, 0] = xy[m, 0] + stub * d1x / s1
    xy[m + 1, 1] = xy[m, 1] + stub * d1y / s1
    u[0] = 0.0
    for i in range(m):
        u[i + 1] = pu[i] + stub
    u[m + 1] = u[m] + stub
    if iv[0, 0] <= stub + 1e-9:
        iv[0, 0] = 0.0
    if iv[q - 1, 1] >= length + stub:
        iv[q - 1, 1] = u[m + 1] + OPEN_END
    return m + 2, q


_curve = numba.njit(cache=True)(_curve_py)
