"""Markings as world polylines with their own arc length and painted intervals.

The generated highway (:mod:`aldm_gym.roads.highway`) places every marking at a
constant offset from one reference line and paints it with one periodic dash
pattern. Real maps do neither: lane widths vary, lanes open and close, a marking
changes from broken to solid at an exit, double lines run side by side. Here a
marking is what a converted road gives CarMaker: a curve (a polyline of world
vertices, finely sampled) with its own arc length ``u`` [m], and the list of
intervals of ``u`` that carry paint (one per dash of a broken line, one per painted
run of a solid line).

:class:`PolylineMarkings` holds all markings of a road in flat CSR arrays (the
layout numba kernels want) and answers the sensor's one geometric question: where
does each marking cross the lines ``x = xs`` of a sensor frame
(:meth:`PolylineMarkings.sample`)? Markings near the sensor are found through
chunks of vertices with a bounding circle, so the cost does not grow with the map.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from aldm_gym.config import check_range
from aldm_gym.errors import InputError
from aldm_gym.roads.markings import MARKING_MODELS
from aldm_gym.roads.overpass import overpass_lines
from aldm_gym.roads.position import world_point
from aldm_gym.types import FloatArray

CHUNK = 64
"""Vertices per chunk of the spatial index (consecutive chunks share one vertex)."""


@dataclass(frozen=True)
class MarkingCurve:
    """One marking line of a map, as the sensor sees it.

    :ivar xy: ``(N >= 2, 2)`` world vertices [m] in painting order.
    :ivar painted: ``(P, 2)`` painted intervals ``[u0, u1)`` of the arc length along
        ``xy`` [m], sorted, not overlapping; one row per dash of a broken line.
    :ivar type: CarMaker line type (1 continuous, 2 dashed, 3 dotted).
    :ivar colour: colour index (0 white, 1 yellow, ...).
    :ivar width: painted width [m].
    :ivar height: height above the road [m] (> 0 for curbs and barriers).
    :ivar u: ``(N,)`` arc length along ``xy`` [m] when the caller has it (saves
        :class:`PolylineMarkings` computing it); ``None``: computed.
    """

    xy: FloatArray
    painted: FloatArray
    type: int = 1
    colour: int = 0
    width: float = 0.15
    height: float = 0.0
    u: FloatArray | None = None


def arc_length(xy: FloatArray) -> FloatArray:
    """Cumulative arc length [m] along a polyline ``(N, 2)``, starting at 0."""
    seg = np.hypot(np.diff(xy[:, 0]), np.diff(xy[:, 1]))
    return np.concatenate([[0.0], np.cumsum(seg)])


class PolylineMarkings:
    """All markings of a road as flat arrays, and their sampling in a sensor frame.

    :ivar xy: ``(N, 2)`` vertices of every marking, marking after marking [m].
    :ivar u: ``(N,)`` arc length of each vertex along its marking [m].
    :ivar start: ``(M + 1,)`` marking ``j`` owns vertices ``start[j]:start[j + 1]``.
    :ivar paint: ``(P, 2)`` painted intervals in ``u`` of every marking [m].
    :ivar paint_start: ``(M + 1,)`` marking ``j`` owns ``paint[paint_start[j]:paint_start[j + 1]]``.
    """

    def __init__(self, curves: Sequence[MarkingCurve]) -> None:
        """``curves``: the markings (none for a road without paint: the sensor then
        sees nothing)."""
        xys: list[FloatArray] = [np.zeros((0, 2))]
        us: list[FloatArray] = [np.zeros(0)]
        paints: list[FloatArray] = [np.zeros((0, 2))]
        for j, c in enumerate(curves):
            xy = np.asarray(c.xy, dtype=np.float64)
            if xy.ndim != 2 or xy.shape[0] < 2 or xy.shape[1] != 2:
                raise InputError(f"marking {j}: xy must be (N >= 2, 2), got {xy.shape}")
            if not np.all(np.isfinite(xy)):
                raise InputError(f"marking {j}: xy holds NaN or inf")
            u = arc_length(xy) if c.u is None else np.asarray(c.u, dtype=np.float64)
            if u.shape != (len(xy),) or u[0] != 0.0:
                raise InputError(f"marking {j}: u must be (N,) arc lengths from 0")
            if not np.all(np.diff(u) > 0.0):
                raise InputError(f"marking {j}: repeated vertices")
            p = np.asarray(c.painted, dtype=np.float64).reshape(-1, 2)
            if len(p) and (np.any(p[:, 1] <= p[:, 0]) or np.any(p[1:, 0] < p[:-1, 1])):
                raise InputError(f"marking {j}: painted intervals must be sorted and disjoint")
            xys.append(xy)
            us.append(u)
            paints.append(p)
        self.curves = tuple(curves)
        self.xy = np.ascontiguousarray(np.concatenate(xys))
        self.u = np.concatenate(us)
        self.start = np.concatenate([[0], np.cumsum([len(x) for x in xys[1:]])]).astype(np.int64)
        self.paint = np.ascontiguousarray(np.concatenate(paints).reshape(-1, 2))
        self.paint_start = np.concatenate([[0], np.cumsum([len(p) for p in paints[1:]])]).astype(
            np.int64
        )
        self._build_chunks()

    def __len__(self) -> int:
        return len(self.curves)

    def _build_chunks(self) -> None:
        # Chunks of CHUNK segments per marking (consecutive chunks share a vertex): their
        # bounding box's centre and the farthest vertex from it, all markings at once.
        i0_parts = [np.zeros(0, dtype=np.int64)]
        i1_parts = [np.zeros(0, dtype=np.int64)]
        mark_parts = [np.zeros(0, dtype=np.int64)]
        for j in range(len(self.curves)):
            a, b = int(self.start[j]), int(self.start[j + 1])
            c0 = np.arange(a, b - 1, CHUNK, dtype=np.int64)
            i0_parts.append(c0)
            i1_parts.append(np.minimum(c0 + CHUNK + 1, b))
            mark_parts.append(np.full(len(c0), j, dtype=np.int64))
        i0 = np.concatenate(i0_parts)
        i1 = np.concatenate(i1_parts)
        # vertex ranges [i0, i1) overlap by one vertex: gather them explicitly
        lengths = i1 - i0
        owner = np.repeat(np.arange(len(i0)), lengths)
        index = np.arange(int(lengths.sum())) - np.repeat(np.cumsum(lengths) - lengths, lengths)
        pts = self.xy[np.repeat(i0, lengths) + index]
        starts = np.cumsum(lengths) - lengths
        if len(starts) == 0:  # no marking
            self.chunk_mark, self.chunk_i0, self.chunk_i1 = i0, i0, i1
            self.chunk_centre = np.zeros((0, 2))
            self.chunk_radius = np.zeros(0)
            return
        lo = np.minimum.reduceat(pts, starts, axis=0)
        hi = np.maximum.reduceat(pts, starts, axis=0)
        centre = 0.5 * (lo + hi)
        rel = pts - centre[owner]
        dist = np.hypot(rel[:, 0], rel[:, 1])
        self.chunk_mark = np.concatenate(mark_parts)
        self.chunk_i0 = i0
        self.chunk_i1 = i1
        self.chunk_centre = np.ascontiguousarray(centre, dtype=np.float64)
        self.chunk_radius = np.maximum.reduceat(dist, starts)

    def near(self, origin: FloatArray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Polylines with a chunk within ``reach`` [m] of ``origin``: ``(rows, lo, hi)``,
        the polyline indices (ascending) and their vertex ranges ``[lo, hi)`` there."""
        return _near_markings(
            self.chunk_mark,
            self.chunk_i0,
            self.chunk_i1,
            self.chunk_centre,
            self.chunk_radius,
            len(self.curves),
            float(origin[0]),
            float(origin[1]),
            float(reach),
        )

    def sample(
        self, origin: FloatArray, yaw: float, xs: FloatArray, reach: float
    ) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """Where the markings near ``origin`` cross the lines ``x = xs`` of a sensor frame.

        The frame has its origin at world ``origin`` and its x axis along world heading
        ``yaw``; y to the left (ISO 8855; in highway-env's world the left of heading h
        is ``(sin h, -cos h)``). Each marking is followed from its vertex nearest to
        the origin in the direction in which x grows, until x stops growing (a marking
        is never reported twice at one x).

        :param xs: ``(K,)`` increasing x [m].
        :param reach: markings with no vertex within this distance of the origin are
            skipped [m] (the sensor's range plus a margin).
        :return: ``(rows, y, u)``: the indices of the markings considered ``(R,)``, and
            ``(R, K)`` lateral position [m] and arc length along the marking [m] at
            each ``xs``; NaN where the marking does not reach that x.
        """
        rows, lo, hi = self.near(origin, reach)
        y = np.full((len(rows), len(xs)), np.nan)
        u = np.full((len(rows), len(xs)), np.nan)
        _sample_polylines(
            self.xy,
            self.u,
            rows,
            lo,
            hi,
            float(origin[0]),
            float(origin[1]),
            float(yaw),
            np.asarray(xs, dtype=np.float64),
            y,
            u,
        )
        return rows, y, u


def _near_markings_py(
    chunk_mark: np.ndarray,
    chunk_i0: np.ndarray,
    chunk_i1: np.ndarray,
    centre: FloatArray,
    radius: FloatArray,
    n_markings: int,
    ox: float,
    oy: float,
    reach: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Markings with a chunk within ``reach`` of ``(ox, oy)``, and their vertex ranges.

    :return: ``(rows, lo, hi)``: marking indices (ascending) and, per row, the range
        ``[lo, hi)`` of vertices covered by its near chunks.
    """
    lo = np.full(n_markings, -1, dtype=np.int64)
    hi = np.full(n_markings, -1, dtype=np.int64)
    n = 0
    for c in range(len(chunk_mark)):
        dx = centre[c, 0] - ox
        dy = centre[c, 1] - oy
        r = reach + radius[c]
        if dx * dx + dy * dy <= r * r:
            j = chunk_mark[c]
            if lo[j] < 0:
                lo[j] = chunk_i0[c]
                hi[j] = chunk_i1[c]
                n += 1
            else:
                lo[j] = min(lo[j], chunk_i0[c])
                hi[j] = max(hi[j], chunk_i1[c])
    rows = np.empty(n, dtype=np.int64)
    rlo = np.empty(n, dtype=np.int64)
    rhi = np.empty(n, dtype=np.int64)
    q = 0
    for j in range(n_markings):
        if lo[j] >= 0:
            rows[q] = j
            rlo[q] = lo[j]
            rhi[q] = hi[j]
            q += 1
    return rows, rlo, rhi


_near_markings = numba.njit(cache=True)(_near_markings_py)


def _sample_polylines_py(
    xy: FloatArray,
    u: FloatArray,
    rows: np.ndarray,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    ox: float,
    oy: float,
    yaw: float,
    xs: FloatArray,
    y_out: FloatArray,
    u_out: FloatArray,
) -> None:
    """Fill ``y_out``/``u_out`` (rows of :meth:`PolylineMarkings.sample`); plain twin."""
    ch = math.cos(yaw)
    sh = math.sin(yaw)
    k = len(xs)
    for r in range(len(rows)):
        lo = row_lo[r]
        hi = row_hi[r]
        if hi - lo < 2:
            continue
        # The vertex nearest to the origin.
        best = lo
        best_d = np.inf
        for i in range(lo, hi):
            dx = xy[i, 0] - ox
            dy = xy[i, 1] - oy
            d = dx * dx + dy * dy
            if d < best_d:
                best_d = d
                best = i
        # Sensor-frame x of a vertex: forward (cos h, sin h); y: left (sin h, -cos h).
        xb = (xy[best, 0] - ox) * ch + (xy[best, 1] - oy) * sh
        step = 1
        if best + 1 < hi:
            xn = (xy[best + 1, 0] - ox) * ch + (xy[best + 1, 1] - oy) * sh
            if xn <= xb:
                step = -1
        else:
            step = -1
        i = best
        p = 0
        x0 = xb
        y0 = (xy[i, 0] - ox) * sh - (xy[i, 1] - oy) * ch
        while p < k:
            nxt = i + step
            if nxt < lo or nxt >= hi:
                break
            x1 = (xy[nxt, 0] - ox) * ch + (xy[nxt, 1] - oy) * sh
            if not x1 > x0:
                break  # the marking stops advancing in x
            y1 = (xy[nxt, 0] - ox) * sh - (xy[nxt, 1] - oy) * ch
            while p < k and xs[p] < x0:
                p += 1
            while p < k and xs[p] < x1:
                t = (xs[p] - x0) / (x1 - x0)
                y_out[r, p] = y0 + t * (y1 - y0)
                u_out[r, p] = u[i] + t * (u[nxt] - u[i])
                p += 1
            i = nxt
            x0 = x1
            y0 = y1


_sample_polylines = numba.njit(cache=True)(_sample_polylines_py)


class PolylineRoad:
    """A road given by its marking curves: what the line sensor needs of a map.

    The sensor side of a map road (:class:`aldm_gym.roads.OpenDriveRoad` adds lanes,
    ground truth and traffic): :meth:`sample_visible`, :meth:`sample_markings`,
    :attr:`marking_table` and :attr:`marking_model`, the same protocol as
    :class:`~aldm_gym.roads.HighwayRoad`.

    :param curves: the markings.
    :param marking_model: ``"per_dash"`` (every painted piece its own line object, as
        on converted roads) or ``"editor"`` (one object per marking).
    :param lane_width: nominal lane width [m] (for one-line trajectories).
    :param reach: markings farther than this from the sensor are not sampled [m].
    """

    def __init__(
        self,
        curves: Sequence[MarkingCurve] | PolylineMarkings,
        marking_model: str = "per_dash",
        lane_width: float = 3.75,
        reach: float = 260.0,
    ) -> None:
        if marking_model not in MARKING_MODELS:
            raise InputError(
                f"marking_model must be one of {list(MARKING_MODELS)}, got {marking_model!r}"
            )
        self.markings = curves if isinstance(curves, PolylineMarkings) else PolylineMarkings(curves)
        self._marking_model = marking_model
        self.lane_width = float(lane_width)
        self.reach = float(reach)
        cs = self.markings.curves
        self.marking_table: dict[str, np.ndarray] = {
            "type": np.array([int(c.type) for c in cs], dtype=np.int64),
            "colour": np.array([int(c.colour) for c in cs], dtype=np.int64),
            "height": np.array([float(c.height) for c in cs], dtype=np.float64),
            "width": np.array([float(c.width) for c in cs], dtype=np.float64),
            # No periodic pattern: every marking's paint is its explicit intervals.
            "dash": np.zeros(len(cs)),
            "period": np.ones(len(cs)),
            "phase": np.zeros(len(cs)),
            "broken": np.array([int(c.type) != 1 for c in cs], dtype=bool),
            "paint": self.markings.paint,
            "paint_start": self.markings.paint_start,
        }
        """Marking attributes by marking index (the line sensor's table)."""

    @property
    def marking_model(self) -> str:
        """``"per_dash"`` or ``"editor"``."""
        return self._marking_model

    overpass_lines: FloatArray = np.zeros((0, 5))
    """``(B, 5)`` world segments ``(x0, y0, x1, y1, z)`` [m] of bridge markings above the
    road (:mod:`aldm_gym.roads.overpass`): a map's own bridges
    (:mod:`aldm_gym.roads.opendrive.bridges`) and those added by :meth:`with_overpasses`."""

    def with_overpasses(
        self,
        places: Sequence[tuple[float, float, float]],
        angle: float = math.radians(45.0),
        height: float = 6.0,
        half_width: float = 10.0,
    ) -> PolylineRoad:
        """The same road with more bridges crossing above it (shares the geometry).

        A map's own bridges (roads passing over it in the file) are already there; this
        adds a straight, level bridge at each place given, e.g. on a map without
        elevation data.

        :param places: world ``(x [m], y [m], heading [rad])`` of each crossing: the
            point on the lower road and that road's heading there.
        :param angle: angle between a bridge's road and the lower road [rad], in
            [10°, 90°].
        :param height: height of the bridge's markings [m], in [0.5, 50].
        :param half_width: half the lower road's width there [m] (its markings run 30 m
            beyond it).
        :raises InputError: naming the argument out of its range.
        """
        check_range("overpass", "angle", angle, math.radians(10.0), math.pi / 2)
        check_range("overpass", "height", height, 0.5, 50.0)
        check_range("overpass", "half_width", half_width, 0.0, 1000.0)
        rows = []
        for place in places:
            x, y, h = (float(v) for v in place)
            if not all(math.isfinite(v) for v in (x, y, h)):
                raise InputError(f"overpass places must be finite (x, y, heading), got {place!r}")
            rows.append(overpass_lines(np.array([x, y]), h, half_width, angle, height))
        twin = copy.copy(self)
        twin.overpass_lines = np.concatenate([self.overpass_lines, *rows])
        return twin

    def with_marking_model(self, marking_model: str) -> PolylineRoad:
        """The same road with another marking model (shares the geometry)."""
        if marking_model not in MARKING_MODELS:
            raise InputError(
                f"marking_model must be one of {list(MARKING_MODELS)}, got {marking_model!r}"
            )
        twin = copy.copy(self)
        twin._marking_model = marking_model
        return twin

    def sample_visible(
        self, origin: FloatArray, yaw: float, xs: FloatArray, s_origin: float | None = None
    ) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """``(rows, y, u)``: the markings near ``origin`` crossing ``x = xs`` (see
        :meth:`PolylineMarkings.sample`). ``s_origin`` is accepted for the sensor's
        protocol and not needed here."""
        origin = world_point("origin", origin)
        if not math.isfinite(yaw):
            raise InputError(f"yaw must be finite, got {yaw!r}")
        return self.markings.sample(origin, yaw, xs, self.reach)

    def sample_markings(
        self, origin: FloatArray, yaw: float, xs: FloatArray, s_origin: float | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """``(y, u)``, each ``(n_markings, K)``: every marking at ``x = xs`` (NaN where
        it does not reach), as :meth:`HighwayRoad.sample_markings
        <aldm_gym.roads.HighwayRoad.sample_markings>`."""
        rows, y, u = self.sample_visible(origin, yaw, xs, s_origin)
        m = len(self.markings)
        y_all = np.full((m, len(xs)), np.nan)
        u_all = np.full((m, len(xs)), np.nan)
        y_all[rows] = y
        u_all[rows] = u
        return y_all, u_all
