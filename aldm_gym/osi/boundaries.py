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


def _merged(intervals: FloatArray) -> FloatArray:
    """Sorted intervals with those that touch or overlap joined, empty ones dropped."""
    iv = intervals[intervals[:, 1] - intervals[:, 0] > _TIE]
    if len(iv) < 2:
        return iv
    iv = iv[np.argsort(iv[:, 0], kind="stable")]
    out = [iv[0].copy()]
    for lo, hi in iv[1:]:
        if lo <= out[-1][1] + _TIE:
            out[-1][1] = max(out[-1][1], hi)
        else:
            out.append(np.array([lo, hi]))
    return np.array(out)


def _run_points(
    x: FloatArray, y: FloatArray, u: FloatArray, intervals: FloatArray
) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """Points and dash states of one contiguous run of samples (x increasing).

    Samples inside paint are ``CONTINUE``; a point is added where the paint starts
    (``START``) and ends (``END``), interpolated linearly in ``u`` between samples;
    samples in gaps are left out (OSI needs only the dash ends). A run that begins or
    ends inside paint begins or ends with a ``CONTINUE`` sample (the view cuts it).
    """
    k = len(x)
    none = (np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64))
    if k < 2:
        return none
    iv = _merged(np.asarray(intervals, dtype=np.float64).reshape(-1, 2))
    if len(iv) == 0:
        return none
    rising = u[-1] >= u[0]
    idx = np.arange(k, dtype=np.float64)
    us, ts = (u, idx) if rising else (u[::-1], idx[::-1])
    umin, umax = float(us[0]), float(us[-1])
    # samples on paint ([u0, u1) along u; a stretch beginning within _TIE after the
    # first sample counts as begun there)
    probe = u.copy()
    probe[0] += 2.0 * _TIE if rising else -2.0 * _TIE
    q = np.searchsorted(iv[:, 0], probe, side="right") - 1
    on = (q >= 0) & (probe < iv[np.maximum(q, 0), 1])
    # paint edges strictly inside the run: where x grows, an interval's start enters
    # paint when u grows with x and leaves it when u falls
    e_u = iv.reshape(-1)
    e_enter = np.tile([rising, not rising], len(iv))
    inner = (e_u > umin + _TIE) & (e_u < umax - _TIE)
    e_t = np.interp(e_u[inner], us, ts)
    e_state = np.where(e_enter[inner], DASH_START, DASH_END)
    # a sample on an edge gives way to it
    keep = on.copy()
    if len(e_t):
        near = np.abs(np.arange(k)[:, None] - e_t[None, :]).min(axis=1) <= _TIE
        keep &= ~near
    t = np.concatenate([np.flatnonzero(keep).astype(np.float64), e_t])
    state = np.concatenate([np.full(int(keep.sum()), DASH_CONTINUE), e_state])
    order = np.argsort(t, kind="stable")
    t, state = t[order], state[order]
    if len(state) and state[-1] == DASH_START:  # a dash that begins at the run's end
        t, state = t[:-1], state[:-1]
    return np.interp(t, idx, x), np.interp(t, idx, y), state.astype(np.int64)


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
    for r, j in enumerate(rows):
        ok = np.isfinite(ys[r]) & np.isfinite(us[r])
        if ok.sum() < 2:
            continue
        idx = np.flatnonzero(ok)
        breaks = np.flatnonzero(np.diff(idx) > 1)
        for run in np.split(idx, breaks + 1):
            u = us[r, run]
            lo, hi = float(u.min()), float(u.max())
            iv = marking_intervals(table, int(j), lo, hi)
            if len(iv) == 0:
                continue
            px, py, dash = _run_points(xs[run], ys[r, run], u, iv)
            if len(dash) < 2:
                continue
            # sensor frame -> highway-env world: forward (c, s), left (s, -c)
            xy = np.stack([origin[0] + px * c + py * s, origin[1] + px * s - py * c], axis=1)
            out.append(BoundarySample(int(j), xy, px, dash))
    return out


def painted_intervals(
    u: FloatArray, dash: np.ndarray, botts: bool = False, width: float = 0.1
) -> FloatArray:
    """Painted stretches of one OSI boundary, as intervals ``[u0, u1]`` of its arc length.

    Points in order: ``DASH_START`` opens a stretch, ``DASH_END`` closes it,
    ``DASH_CONTINUE`` lies on one and ``DASH_GAP`` between two. A boundary that starts
    on a ``CONTINUE`` or ``END`` point starts inside paint (a view cut inside a dash);
    a stretch still open at the last point ends :data:`OPEN_END` beyond it. Without any ``START``,
    ``END`` or ``GAP`` (``DASH_UNKNOWN``/``OTHER`` everywhere, a solid line) the whole
    boundary is painted; for Botts' dots (``botts``) without dash states every point
    is a dot ``width`` [m] long (OSI: "one BoundaryPoint position has to define each
    Botts' dot").

    :param u: ``(N,)`` arc length of the points along the boundary [m], increasing.
    :param dash: ``(N,)`` dash states.
    :raises InputError: ``u`` and ``dash`` of different lengths.
    """
    u = np.asarray(u, dtype=np.float64)
    dash = np.asarray(dash)
    if u.shape != dash.shape:
        raise InputError(f"u and dash must have the same length, got {u.shape} and {dash.shape}")
    if len(u) == 0:
        return np.zeros((0, 2))
    marked = (dash == DASH_START) | (dash == DASH_END) | (dash == DASH_GAP)
    if botts and not marked.any():
        half = 0.5 * width
        return np.stack([u - half, u + half], axis=1)
    if not marked.any():
        return np.array([[u[0], u[-1] + OPEN_END]]) if len(u) >= 2 else np.zeros((0, 2))
    out = []
    start: float | None = None
    first = int(dash[0])
    if first in (DASH_CONTINUE, DASH_END):
        start = float(u[0])
    for i in range(len(u)):
        d = int(dash[i])
        if d == DASH_START:
            if start is None:
                start = float(u[i])
        elif d == DASH_END:
            if start is not None and u[i] > start:
                out.append((start, float(u[i])))
            start = None
        elif d == DASH_GAP:
            if start is not None and i > 0 and u[i - 1] > start:
                out.append((start, float(u[i - 1])))
            start = None
    if start is not None and u[-1] > start:
        out.append((start, float(u[-1]) + OPEN_END))
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)
