"""Reference-line geometry: straights, arcs and clothoid transitions, tabulated.

A road's reference line is described by its curvature profile: a sequence of
:class:`Segment` with curvature varying linearly along each (0 → straight,
constant → arc, linear → clothoid transition). The line is tabulated every
``step`` metres of arc length; every lateral offset of it (lane centres,
markings) is derived from the table.

Frames and signs. World coordinates are highway-env's ``(x, y)`` plane with its
heading convention (direction ``(cos h, sin h)``). highway-env numbers lanes
towards ``+y`` and its ``LANE_LEFT`` action decreases the lane id, so the
driver's *left* is the direction ``(sin h, -cos h)``; this module calls a
lateral offset ``d`` positive to the driver's left, and a curvature ``kappa``
positive for a left-hand curve, as in ISO 8855. With that, the world heading
changes as ``dh/ds = -kappa``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.types import BoolArray, FloatArray, IntArray

_F64 = np.dtype(np.float64)

_POINT_MEMO_SIZE = 4096
"""Positions remembered by :meth:`ReferenceLine.project` (the memo is emptied when full)."""

COORD_LIMIT = 1e12
"""Largest |coordinate| [m] the compiled projection takes (its cell keys fit in int64)."""

LineLookup = tuple[
    FloatArray, FloatArray, float, float, IntArray, IntArray, IntArray, IntArray, int
]
"""A reference line's projection tables, one argument of the kernels (built once as
:attr:`ReferenceLine.lookup`): ``(xy, heading, step, cell, keys, ptr, idx, coarse,
window)``.

- ``xy`` ``(n, 2)`` [m], ``heading`` ``(n,)`` [rad]: the tabulated samples, ``step``
  [m] apart in arc length;
- ``cell`` [m]: the spatial hash's cell size; ``keys`` (sorted) are the cell keys that
  list candidates, cell ``keys[i]``'s candidate coarse samples are
  ``idx[ptr[i]:ptr[i + 1]]``; ``coarse`` lists every coarse sample;
- ``window``: how many samples either side of the nearest candidate are searched.

A plain tuple rather than a ``NamedTuple``: numba types a plain tuple argument in C when
Python calls a kernel, a ``NamedTuple`` in Python (about 2 µs a call). Kernels unpack
it in this order.
"""


@dataclass(frozen=True)
class Segment:
    """One piece of a curvature profile.

    :ivar length: arc length of the piece [m] (> 0).
    :ivar kappa_start: curvature at its start [1/m], positive = left curve.
    :ivar kappa_end: curvature at its end [1/m]; equal to ``kappa_start`` for a
        straight or an arc, different for a clothoid transition.
    """

    length: float
    kappa_start: float = 0.0
    kappa_end: float | None = None

    @property
    def kappa_stop(self) -> float:
        """Curvature at the end [1/m]."""
        return self.kappa_start if self.kappa_end is None else self.kappa_end


def left_normal(heading: FloatArray | float) -> FloatArray:
    """Unit vector(s) to the driver's left for world heading(s) [rad], shape ``(..., 2)``."""
    h = np.asarray(heading, dtype=np.float64)
    return np.stack([np.sin(h), -np.cos(h)], axis=-1)


class ReferenceLine:
    """A tabulated planar curve with arc-length parametrisation and fast projection.

    :param segments: the curvature profile, in driving order.
    :param start: world position of the start [m].
    :param heading: world heading at the start [rad].
    :param step: tabulation step in arc length [m].
    :param max_offset: largest lateral distance at which :meth:`project` is
        expected to be called quickly [m]; farther points fall back to a full search.
    """

    _CELL = 20.0  # spatial-hash cell size [m]

    def __init__(
        self,
        segments: list[Segment] | tuple[Segment, ...],
        start: tuple[float, float] = (0.0, 0.0),
        heading: float = 0.0,
        step: float = 0.5,
        max_offset: float = 40.0,
    ) -> None:
        if not segments:
            raise InputError("a reference line needs at least one segment")
        for seg in segments:
            if not (np.isfinite(seg.length) and seg.length > 0):
                raise InputError(f"segment length must be > 0, got {seg.length}")
        self.segments = tuple(segments)
        self.step = float(step)
        bounds = np.concatenate([[0.0], np.cumsum([seg.length for seg in segments])])
        self.length = float(bounds[-1])
        n = int(np.ceil(self.length / step)) + 1
        s = np.linspace(0.0, self.length, n)
        self.step = float(s[1] - s[0])  # actual spacing (<= the requested step)
        # Curvature is piecewise linear in s; sample it per segment.
        lengths = np.array([seg.length for seg in segments])
        idx = np.clip(np.searchsorted(bounds, s, side="right") - 1, 0, len(segments) - 1)
        k0 = np.array([seg.kappa_start for seg in segments])
        k1 = np.array([seg.kappa_stop for seg in segments])
        t = s - bounds[idx]
        kappa = k0[idx] + (k1[idx] - k0[idx]) * t / lengths[idx]
        # Heading, exact at every sample: dh/ds = -kappa, integrated analytically per segment.
        turn = np.concatenate([[0.0], np.cumsum(0.5 * (k0 + k1) * lengths)])
        integral = turn[idx] + k0[idx] * t + 0.5 * (k1[idx] - k0[idx]) * t**2 / lengths[idx]
        h = heading - integral
        dh = np.diff(h)
        # Position: chord of each small arc, exact for constant curvature.
        chord = np.diff(s) * np.sinc(dh / (2.0 * np.pi))
        hm = 0.5 * (h[1:] + h[:-1])
        xy = np.zeros((n, 2))
        xy[0] = start
        xy[1:, 0] = start[0] + np.cumsum(chord * np.cos(hm))
        xy[1:, 1] = start[1] + np.cumsum(chord * np.sin(hm))
        self.s: FloatArray = s
        self.xy: FloatArray = xy
        self.heading: FloatArray = h
        self.kappa: FloatArray = kappa
        self.normal: FloatArray = left_normal(h)
        self.max_offset = float(max_offset)
        self._memo: tuple[bytes, FloatArray, FloatArray] | None = None
        self._point_memo: dict[bytes, tuple[float, float]] = {}
        # Plain-float copies of the tables for the scalar paths (list indexing is ~5x
        # cheaper than numpy scalar indexing; the values are the same doubles).
        self._s_list: list[float] = s.tolist()
        self._x_list: list[float] = xy[:, 0].tolist()
        self._y_list: list[float] = xy[:, 1].tolist()
        self._h_list: list[float] = h.tolist()
        self._build_lookup()

    @classmethod
    def from_points(
        cls, xy: FloatArray, step: float = 0.5, max_offset: float = 40.0
    ) -> ReferenceLine:
        """A line tabulated from a polyline instead of a curvature profile.

        The polyline is resampled at a constant arc-length step (the table layout the
        evaluation and projection rely on); headings come from the resampled chords
        (unwrapped, so they interpolate; a vertex gets the mean of its two chords, an
        end its chord), curvature from their differences. ``segments`` is empty.

        :param xy: ``(N >= 2, 2)`` world vertices [m] in the driving direction.
        :param step: tabulation step [m] (the actual one is ``<= step``).
        :param max_offset: lateral reach of the fast projection [m].
        """
        line = cls.__new__(cls)
        line._tabulate_points(xy, step, max_offset)
        return line

    def _tabulate_points(self, xy: FloatArray, step: float, max_offset: float) -> None:
        """Fill the tables from a polyline (see :meth:`from_points`)."""
        pts = np.asarray(xy, dtype=np.float64)
        u = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
        length = float(u[-1])
        if not length > 0.0:
            raise InputError("a line from points needs a positive length")
        n = max(int(np.ceil(length / step)) + 1, 2)
        s = np.linspace(0.0, length, n)
        table = np.column_stack([np.interp(s, u, pts[:, 0]), np.interp(s, u, pts[:, 1])])
        chord = np.diff(table, axis=0)
        seg_heading = np.unwrap(np.arctan2(chord[:, 1], chord[:, 0]))
        heading = np.empty(n)
        heading[0], heading[-1] = seg_heading[0], seg_heading[-1]
        heading[1:-1] = 0.5 * (seg_heading[1:] + seg_heading[:-1])
        self.segments = ()
        self.step = float(s[1] - s[0])
        self.length = length
        self.s = s
        self.xy = table
        self.heading = heading
        self.kappa = -np.gradient(heading, s)  # dh/ds = -kappa in highway-env's world
        self.normal = left_normal(heading)
        self.max_offset = float(max_offset)
        self._memo = None
        self._point_memo = {}
        self._s_list = s.tolist()
        self._x_list = table[:, 0].tolist()
        self._y_list = table[:, 1].tolist()
        self._h_list = heading.tolist()
        self._build_lookup()

    # ------------------------------------------------------------------ tables
    _STRIDE = 10  # coarse samples: every 10th tabulated point

    def _build_lookup(self) -> None:
        """Build :attr:`lookup`: map each spatial cell to the coarse samples that may be
        nearest to a point in it.

        A point within ``max_offset`` of the line has its nearest coarse sample
        within ``max_offset + coarse spacing`` of itself, hence within
        ``max_offset + coarse spacing + cell diagonal`` of its cell's corner.
        """
        c = self._CELL
        coarse = np.arange(0, len(self.s), self._STRIDE)
        r = self.max_offset + self._STRIDE * self.step + 1.5 * c
        span = int(np.ceil(r / c))
        base = np.floor(self.xy[coarse] / c).astype(np.int64)
        d = np.arange(-span, span + 1)
        dx, dy = np.meshgrid(d, d, indexing="ij")
        cx = (base[:, 0, None] + dx.ravel()[None]).ravel()
        cy = (base[:, 1, None] + dy.ravel()[None]).ravel()
        idx = np.repeat(coarse, dx.size)
        keys = cx * 1_000_003 + cy
        order = np.argsort(keys, kind="stable")
        keys, idx = keys[order], idx[order]
        uniq, first = np.unique(keys, return_index=True)
        self.lookup: LineLookup = (
            np.ascontiguousarray(self.xy, dtype=np.float64),
            np.ascontiguousarray(self.heading, dtype=np.float64),
            self.step,
            c,
            uniq.astype(np.int64),
            np.concatenate([first, [len(idx)]]).astype(np.int64),
            idx.astype(np.int64),
            coarse.astype(np.int64),
            2 * self._STRIDE,
        )
        """The projection tables the kernels take (:data:`LineLookup`)."""

    def _interp(self, s: FloatArray | float) -> tuple[FloatArray, FloatArray]:
        """Position ``(..., 2)`` and heading at arc length(s) ``s``, extrapolated straight."""
        s = np.asarray(s, dtype=np.float64)
        i = np.clip((s / self.step).astype(np.int64), 0, len(self.s) - 2)
        t = (s - self.s[i]) / (self.s[i + 1] - self.s[i])
        tt = np.clip(t, 0.0, 1.0)
        h = self.heading[i] + (self.heading[i + 1] - self.heading[i]) * tt
        p = self.xy[i] + (self.xy[i + 1] - self.xy[i]) * tt[..., None]
        # Beyond either end, continue straight along the end heading.
        extra = (s - np.clip(s, 0.0, self.length))[..., None]
        p = p + extra * np.stack([np.cos(h), np.sin(h)], axis=-1)
        return p, h

    def pose_at(self, s: float) -> tuple[float, float, float]:
        """Scalar :meth:`_interp`: world ``(x [m], y [m], heading [rad])`` at arc length ``s``.

        highway-env's vehicles ask for one lane position or heading at a time, thousands
        of times per step; this avoids numpy's per-call overhead (~2 µs instead of ~40 µs)
        with the same table and arithmetic. The table interval and the heading come from
        :func:`heading_on_table_py`, which the compiled traffic calls too.
        """
        i, tt, h = heading_on_table_py(self._s_list, self._h_list, self.step, s)
        x_tab, y_tab = self._x_list, self._y_list
        x0, y0 = x_tab[i], y_tab[i]
        x = x0 + (x_tab[i + 1] - x0) * tt
        y = y0 + (y_tab[i + 1] - y0) * tt
        if s < 0.0:
            extra = s - 0.0
        elif s > self.length:
            extra = s - self.length
        else:
            extra = 0.0
        if extra != 0.0:  # beyond either end: continue straight along the end heading
            x += extra * math.cos(h)
            y += extra * math.sin(h)
        return x, y, h

    def position(self, s: FloatArray | float, d: FloatArray | float = 0.0) -> FloatArray:
        """World position at arc length ``s`` [m] and left offset ``d`` [m], shape ``(..., 2)``."""
        if isinstance(s, float | int) and isinstance(d, float | int) and math.isfinite(s):
            x, y, hs = self.pose_at(float(s))
            return np.array([x + d * math.sin(hs), y - d * math.cos(hs)])
        p, h = self._interp(s)
        return p + np.asarray(d, dtype=np.float64)[..., None] * left_normal(h)

    def heading_at(self, s: FloatArray | float) -> FloatArray:
        """World heading at arc length ``s`` [rad]."""
        if isinstance(s, float | int) and math.isfinite(s):
            return np.float64(self.pose_at(float(s))[2])  # type: ignore[return-value]
        return self._interp(s)[1]

    def curvature_at(self, s: FloatArray | float) -> FloatArray:
        """Curvature at arc length ``s`` [1/m], positive = left curve."""
        return np.asarray(np.interp(s, self.s, self.kappa), dtype=np.float64)

    # -------------------------------------------------------------- projection
    def project(self, point: FloatArray) -> tuple[float, float]:
        """Arc length ``s`` [m] and left offset ``d`` [m] of a world ``point`` (2,).

        Inverse of :meth:`position`. Points before the start or past the end get
        ``s < 0`` or ``s > length``.

        Results for float64 ``(2,)`` arrays are memoised by their bytes: within a
        simulation step highway-env's vehicles ask for the same positions on every lane
        (all lanes share this line) many times. The memo holds the last
        :data:`_POINT_MEMO_SIZE` positions or so; a hit returns the very same floats.

        :raises InputError: if a coordinate is not finite.
        """
        key = None
        if type(point) is np.ndarray and point.dtype == _F64 and point.shape == (2,):
            key = point.tobytes()
            hit = self._point_memo.get(key)
            if hit is not None:
                return hit
        px, py = float(point[0]), float(point[1])
        result: tuple[float, float]
        if abs(px) < COORD_LIMIT and abs(py) < COORD_LIMIT:  # False for NaN
            result = project_on(self.lookup, px, py)
        else:
            if not (math.isfinite(px) and math.isfinite(py)):
                raise InputError(f"cannot project the point ({px}, {py}): not finite")
            # Farther out than any cell of the spatial hash: search every coarse sample.
            xy, heading, step, _, _, _, _, coarse, window = self.lookup
            result = project_point(xy, heading, step, coarse, window, px, py)
        if key is not None:
            memo = self._point_memo
            if len(memo) >= _POINT_MEMO_SIZE:
                memo.clear()
            memo[key] = result
        return result

    def remember_projections(self, points: FloatArray) -> dict[bytes, tuple[float, float]]:
        """Project ``(N, 2)`` points in one batch and memoise each for :meth:`project`.

        :meth:`project_many` gives :meth:`project`'s results bit for bit, so a later
        ``project`` of one of these positions returns the very floats it would compute.

        :return: ``{point.tobytes(): (s, d)}`` of this batch (empty if a coordinate is
            not finite: nothing is memoised then).
        """
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        # One reduction checks project_many's batch condition (NaN fails the comparison).
        if len(pts) == 0 or not float(np.abs(pts).max()) < COORD_LIMIT:
            return {}  # a NaN position fails in project itself, at its own look-up
        s, d = self._batch_project(pts)
        raw = pts.tobytes()  # row k is raw[16 k : 16 (k + 1)], as point.tobytes() in project
        self._memo = (raw, s, d)  # project_many's memo (it hands out copies)
        batch = {
            raw[16 * k : 16 * k + 16]: sd
            for k, sd in enumerate(zip(s.tolist(), d.tolist(), strict=True))
        }
        memo = self._point_memo
        if len(memo) + len(batch) > _POINT_MEMO_SIZE:
            memo.clear()
        memo.update(batch)
        return batch

    def _batch_project(self, pts: FloatArray) -> tuple[FloatArray, FloatArray]:
        """One compiled call projecting finite ``(N, 2)`` points (see :meth:`project`)."""
        return _project_many(self.lookup, pts)

    def project_many(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Vectorised :meth:`project` for ``(N, 2)`` points: ``(s (N,), d (N,))``.

        One compiled call (``_project_many``: :func:`project_on`'s steps for each point,
        as :meth:`project`, so the same results bit for bit). The last
        result is memoised: traffic code projects the same vehicle positions once per
        lane, and all lanes of a road share this reference line.
        """
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        key = pts.tobytes()
        if self._memo is not None and self._memo[0] == key:
            return self._memo[1].copy(), self._memo[2].copy()
        if np.isfinite(pts).all() and (np.abs(pts) < COORD_LIMIT).all():
            s, d = self._batch_project(pts)
        else:  # NaN / huge coordinates: the scalar path (and its errors)
            out = np.array([self.project(p) for p in pts], dtype=np.float64).reshape(-1, 2)
            s, d = out[:, 0].copy(), out[:, 1].copy()
        self._memo = (key, s, d)
        return s.copy(), d.copy()

    def project_near(self, points: FloatArray) -> tuple[FloatArray, FloatArray, BoolArray]:
        """:meth:`project_many` for the points within the line's fast reach only.

        A point whose spatial-hash cell holds no candidate (farther than about
        ``max_offset`` from the line) or with a non-finite coordinate is not projected:
        its ``s`` and ``d`` are NaN and its ``near`` flag False. The others get
        :meth:`project`'s results bit for bit. For traffic on a long map, where most
        vehicles are far from any one lane, this skips their full search.

        :param points: ``(N, 2)`` world points [m].
        :return: ``(s (N,) [m], d (N,) [m], near (N,))``.
        """
        pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
        return project_point_near(self.lookup, pts)


def project_point_py(
    xy: FloatArray,
    heading: FloatArray,
    step: float,
    cand: np.ndarray,
    window: int,
    px: float,
    py: float,
) -> tuple[float, float]:
    """Project ``(px, py)`` on a tabulated line: ``(s, d)`` (plain-Python reference).

    1. nearest of the candidate coarse samples, 2. nearest tabulated sample within
    ``window`` of it, 3. Newton iterations on ``(p - P(s)) . T(s) = 0`` where ``P``
    interpolates positions and ``T`` the heading linearly (the same interpolation as
    :meth:`ReferenceLine.position`, so that projection inverts it).
    """
    n = xy.shape[0]
    best = 0
    best_d2 = math.inf
    for k in range(cand.shape[0]):
        i = cand[k]
        dx = xy[i, 0] - px
        dy = xy[i, 1] - py
        d2 = dx * dx + dy * dy
        if d2 < best_d2:
            best_d2 = d2
            best = i
    lo = max(best - window, 0)
    hi = min(best + window + 1, n)
    for i in range(lo, hi):
        dx = xy[i, 0] - px
        dy = xy[i, 1] - py
        d2 = dx * dx + dy * dy
        if d2 < best_d2:
            best_d2 = d2
            best = i
    s = best * step
    length = (n - 1) * step
    d = 0.0
    for _ in range(8):
        j = int(s / step) if s > 0.0 else 0
        if j > n - 2:
            j = n - 2
        t = (s - j * step) / step
        tc = min(max(t, 0.0), 1.0)
        h = heading[j] + tc * (heading[j + 1] - heading[j])
        ch, sh = math.cos(h), math.sin(h)
        # Beyond either end the line continues straight (see ReferenceLine._interp).
        extra = s - min(max(s, 0.0), length)
        pxs = xy[j, 0] + tc * (xy[j + 1, 0] - xy[j, 0]) + extra * ch
        pys = xy[j, 1] + tc * (xy[j + 1, 1] - xy[j, 1]) + extra * sh
        rx, ry = px - pxs, py - pys
        f = rx * ch + ry * sh
        d = rx * sh - ry * ch
        dh = (heading[j + 1] - heading[j]) / step if 0.0 <= s <= length else 0.0
        # f'(s) = -P'.T + (p - P).T' with T' = dh (-sin h, cos h): -1 - d dh
        delta = f / (1.0 + d * dh)
        s += delta
        if abs(delta) < 1e-10:
            break
    return s, d


project_point = numba.njit(cache=True)(project_point_py)


def cell_slice_py(line: LineLookup, px: float, py: float) -> tuple[int, int]:
    """The candidates of the spatial-hash cell of ``(px, py)`` [m]: ``(lo, hi)``, the
    slice ``idx[lo:hi]`` of ``line``'s ``idx``, empty (``lo == hi``) when the cell lists
    none (the point is beyond the line's fast reach: search every coarse sample).
    Coordinates must be finite and below :data:`COORD_LIMIT` (int64 cell keys)."""
    _, _, _, cell, keys, ptr, _, _, _ = line
    key = np.int64(math.floor(px / cell)) * 1_000_003 + np.int64(math.floor(py / cell))
    i = np.searchsorted(keys, key)
    if i < keys.shape[0] and keys[i] == key:
        return ptr[i], ptr[i + 1]
    return 0, 0


# Inlined where it is called (numba IR): a call of it from project_on costs about a
# fifth of a projection.
cell_slice = numba.njit(cache=True, inline="always")(cell_slice_py)


def project_on_py(line: LineLookup, px: float, py: float) -> tuple[float, float]:
    """:meth:`ReferenceLine.project` of ``(px, py)`` [m]: ``(s [m], d [m])``, the same
    floats (:func:`project_point` from the samples :func:`cell_slice` lists, else from
    every coarse sample). Coordinates must be finite and below :data:`COORD_LIMIT`."""
    xy, heading, step, _, _, _, idx, coarse, window = line
    lo, hi = cell_slice(line, px, py)
    cand = idx[lo:hi] if lo < hi else coarse
    return project_point(xy, heading, step, cand, window, px, py)


project_on = numba.njit(cache=True)(project_on_py)


def _project_many_py(line: LineLookup, points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """:func:`project_on_py` for every row of ``points`` ``(N, 2)``: ``(s (N,), d (N,))``.

    Its steps are written out in the loop: a call of the compiled ``project_on`` per
    point costs about 40 % more here. Coordinates must be finite and below
    :data:`COORD_LIMIT` (int64 cell keys).
    """
    xy, heading, step, _, _, _, idx, coarse, window = line
    n = points.shape[0]
    s_out = np.empty(n)
    d_out = np.empty(n)
    for k in range(n):
        px = points[k, 0]
        py = points[k, 1]
        lo, hi = cell_slice(line, px, py)
        cand = idx[lo:hi] if lo < hi else coarse
        s, d = project_point(xy, heading, step, cand, window, px, py)
        s_out[k] = s
        d_out[k] = d
    return s_out, d_out


_project_many = numba.njit(cache=True)(_project_many_py)


def project_point_near_py(
    line: LineLookup, points: FloatArray
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """:func:`_project_many_py` restricted to points whose hash cell has candidates.

    Other points (and points with a coordinate not finite or beyond
    :data:`COORD_LIMIT`) get ``s = d = NaN`` and ``near = False``.
    """
    xy, heading, step, _, _, _, idx, _, window = line
    n = points.shape[0]
    s_out = np.full(n, np.nan)
    d_out = np.full(n, np.nan)
    near = np.zeros(n, dtype=np.bool_)
    for k in range(n):
        px = points[k, 0]
        py = points[k, 1]
        # The comparisons fail for NaN.
        if not (abs(px) < COORD_LIMIT and abs(py) < COORD_LIMIT):
            continue
        lo, hi = cell_slice(line, px, py)
        if lo < hi:
            s, d = project_point(xy, heading, step, idx[lo:hi], window, px, py)
            s_out[k] = s
            d_out[k] = d
            near[k] = True
    return s_out, d_out, near


project_point_near = numba.njit(cache=True)(project_point_near_py)


def heading_on_table_py(
    s_tab: FloatArray | list[float], h_tab: FloatArray | list[float], step: float, s: float
) -> tuple[int, float, float]:
    """Where arc length ``s`` [m] falls in a line's table, and the heading [rad] there.

    :param s_tab: the tabulated arc lengths [m], ``step`` [m] apart.
    :param h_tab: the headings [rad] at them.
    :return: ``(i, tt, h)``: the interval ``[s_tab[i], s_tab[i + 1]]`` (the first or
        the last one beyond the ends), the fraction ``tt`` of it at ``s`` (clamped to
        ``[0, 1]``) and the interpolated heading ``h``. :meth:`ReferenceLine.pose_at`
        interpolates the positions with the same ``i`` and ``tt``. The clamps are
        comparisons (builtin min/max cost ~0.15 µs each in Python) with min/max's
        results, NaN and signed zeros included.
    """
    i = int(s / step)
    last = len(s_tab) - 2
    if i < 0:
        i = 0
    elif i > last:
        i = last
    s0 = s_tab[i]
    tt = (s - s0) / (s_tab[i + 1] - s0)
    if tt < 0.0:
        tt = 0.0
    elif tt > 1.0:
        tt = 1.0
    h0 = h_tab[i]
    return i, tt, h0 + (h_tab[i + 1] - h0) * tt


heading_on_table = numba.njit(cache=True)(heading_on_table_py)
