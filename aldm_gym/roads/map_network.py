"""highway-env's lane network of an OpenDRIVE map, for traffic, the ego's lane and rendering.

highway-env's vehicles (IDM/MOBIL), its neighbour queries and its renderer work on a
:class:`~highway_env.road.road.RoadNetwork`: a graph of nodes and edges, each edge a
list of lanes ordered from the driver's left (``LANE_LEFT`` lowers the lane id, MOBIL
looks at ids ``± 1``). :class:`MapNetwork` builds one from the driving lanes of an
:class:`~aldm_gym.roads.map_road.OpenDriveRoad`:

* one edge per (road, lane section, driving direction), its lanes ordered from the
  driver's left, as :meth:`OpenDriveRoad.lane_position
  <aldm_gym.roads.map_road.OpenDriveRoad.lane_position>` numbers them;
* edges linked along the map's lane links (:meth:`OpenDriveRoad.successor`): the end
  node of an edge is the start node of the edges its lanes continue into (nodes are
  merged with a union-find, so splits and merges give nodes with several edges);
* every lane a :class:`MapLane`: highway-env's lane interface on the lane's centre
  line, resampled at a constant step into a :class:`CentreLine` (a
  :class:`~aldm_gym.roads.reference_line.ReferenceLine` built from points), so lane
  coordinates come from its compiled, spatially hashed projection (highway-env's
  ``PolyLane`` searches the whole polyline in Python at every call).

Lane coordinates follow highway-env's: ``s`` is the arc length along the lane's own
centre line from the start of its section [m] (in the driving direction), ``r`` the
lateral offset, positive to the driver's right [m]. ``next_lane`` follows the map's
lane links (not highway-env's "same id or closest lane" guess); a lane without
successor keeps its vehicles (they must merge out before its end, see
:class:`~aldm_gym.envs.vehicle.MapIDMVehicle`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numba
import numpy as np
from highway_env.road.lane import LineType
from highway_env.road.road import LaneIndex, RoadNetwork

from aldm_gym.roads.lane import ReferenceLane
from aldm_gym.roads.reference_line import LineLookup, ReferenceLine, project_point_near
from aldm_gym.types import BoolArray, FloatArray

if TYPE_CHECKING:
    from aldm_gym.roads.map_road import OpenDriveRoad
    from aldm_gym.roads.opendrive.map import LaneKey

CENTRE_STEP = 0.5
"""Tabulation step of a map lane's centre line [m]."""

CENTRE_REACH = 15.0
"""Largest lateral distance [m] at which a lane projection uses the spatial hash."""

HEADING_WEIGHT = 1.0
"""Cost of a heading mismatch in the closest-lane look-up [m/rad] (highway-env's)."""


class CentreLine(ReferenceLine):
    """A lane's centre: a :class:`ReferenceLine` tabulated from a polyline.

    :meth:`ReferenceLine.from_points <aldm_gym.roads.reference_line.ReferenceLine.from_points>`
    with the map lanes' step and reach; everything else (``pose_at``, ``position``,
    ``project``, ``project_many``, ``project_near``) is the reference line's.

    :param xy: ``(N >= 2, 2)`` world vertices [m] in the driving direction.
    :param step: tabulation step [m] (the actual one is ``<= step``).
    :param max_offset: lateral reach of the fast projection [m].
    """

    def __init__(
        self, xy: FloatArray, step: float = CENTRE_STEP, max_offset: float = CENTRE_REACH
    ) -> None:
        self._tabulate_points(xy, step, max_offset)


class MapLane(ReferenceLane):
    """A driving lane of a map: highway-env's lane interface on its :class:`CentreLine`.

    :param centre: the lane's centre line (driving direction).
    :param u: ``(N,)`` arc length of the width samples along the centre [m].
    :param width: ``(N,)`` lane width there [m].
    :param key: the map's lane key ``(road id, section, lane id)``.
    :param line_types: highway-env line types (left, right), for rendering.
    :param speed_limit: [m/s].
    """

    def __init__(
        self,
        centre: CentreLine,
        u: FloatArray,
        width: FloatArray,
        key: LaneKey,
        line_types: tuple[int, int] | None = None,
        speed_limit: float = 36.0,
    ) -> None:
        w = np.asarray(width, dtype=np.float64)
        super().__init__(centre, 0.0, float(np.median(w)), line_types, speed_limit)
        self.key = key
        # Most lanes keep one width: then width_at is a constant, not an interpolation.
        self._u = np.asarray(u, dtype=np.float64)
        self._w = w
        self._constant = bool(np.ptp(w) < 1e-9)
        self._w_max = float(w.max())
        self.width = float(w[0]) if self._constant else self.width

    def width_at(self, longitudinal: float) -> float:
        """Lane width at ``s`` [m] (the map's, interpolated along the centre)."""
        if self._constant:
            return self.width
        return float(np.interp(longitudinal, self._u, self._w))

    def to_config(self) -> dict:
        """A description of the lane (the centre line itself is not serialised)."""
        return {
            "class_path": f"{type(self).__module__}.{type(self).__name__}",
            "config": {"key": list(self.key), "length": self.length},
        }

    def neighbour_table(
        self, positions: FloatArray, margin: float
    ) -> tuple[FloatArray, BoolArray, np.ndarray] | None:
        """Which positions are on this lane, and in which order along it, in one compiled pass.

        For the traffic's neighbour queries: ``s`` is every position's
        ``local_coordinates`` ``s`` [m], except NaN for a position beyond the centre
        line's fast reach (see :meth:`ReferenceLine.project_near
        <aldm_gym.roads.reference_line.ReferenceLine.project_near>`; such a position is not
        on the lane); ``on`` the ``on_lane(margin=margin)`` mask; ``order`` the indices
        of the on-lane positions sorted by ``s`` (stable: ties in index order). The
        answers are those of ``local_coordinates`` and ``AbstractLane.on_lane``.

        :param positions: ``(N, 2)`` world positions [m].
        :param margin: the on-lane test's lateral margin [m].
        :return: ``(s (N,), on (N,), order (M,))``, or None when a position on the
            lane could lie beyond the fast reach (a lane wider than the reach).
        """
        c = self.reference
        if not self._w_max / 2 + margin + self.VEHICLE_LENGTH < c.max_offset:
            return None
        pts = np.ascontiguousarray(positions, dtype=np.float64).reshape(-1, 2)
        s, _, on, order = _neighbour_table(
            c.lookup,
            self._u,
            self._w,
            self._constant,
            margin,
            -self.VEHICLE_LENGTH,
            self.length + self.VEHICLE_LENGTH,
            pts,
        )
        return s, on, order


class MapNetwork(RoadNetwork):
    """highway-env's network of an :class:`OpenDriveRoad`'s driving lanes (module docstring).

    :ivar road: the map road.
    :ivar index_of: lane key -> highway-env lane index ``(from, to, id)``.
    :ivar key_of: highway-env lane index -> lane key.
    """

    def __init__(self, road: OpenDriveRoad, speed_limit: float = 36.0) -> None:
        super().__init__()
        self.road = road
        odr = road.map
        centres = road._centres
        groups: dict[tuple[str, int, int], list[LaneKey]] = {}
        for key in road.lanes:
            rec = odr.lanes[key]
            groups.setdefault((rec.road_id, rec.section, rec.direction), []).append(key)
        # Union-find over the (group, "in"/"out") nodes, merged along lane links.
        parent: dict[tuple, tuple] = {}

        def find(a: tuple) -> tuple:
            parent.setdefault(a, a)
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        group_of = {k: g for g, keys in groups.items() for k in keys}
        for g in groups:
            find((g, "in"))
            find((g, "out"))
        for key in road.lanes:
            nxt = road.successor(key)
            if nxt is not None:
                a, b = find((group_of[key], "out")), find((group_of[nxt], "in"))
                if a != b:
                    parent[b] = a
        names: dict[tuple, str] = {}

        def node(a: tuple) -> str:
            root = find(a)
            if root not in names:
                names[root] = f"n{len(names)}"
            return names[root]

        self.index_of: dict[LaneKey, LaneIndex] = {}
        self.key_of: dict[LaneIndex, LaneKey] = {}
        self.lane_row: dict[LaneIndex, int] = {}
        rows = road._key_index
        for g, keys in groups.items():
            ordered = road._siblings[keys[0]]
            _from, _to = node((g, "in")), node((g, "out"))
            if _from == _to:  # a lane linked to itself (a ring): keep the edge apart
                _to = f"{_to}'"
            last = len(ordered) - 1
            for i, key in enumerate(ordered):
                row = rows[key]
                a, b = int(centres.start[row]), int(centres.start[row + 1])
                left = LineType.CONTINUOUS_LINE if i == 0 else LineType.NONE
                right = LineType.CONTINUOUS_LINE if i == last else LineType.STRIPED
                lane = MapLane(
                    CentreLine(centres.xy[a:b]),
                    centres.u[a:b],
                    road.lane_widths(key),
                    key,
                    (left, right),
                    speed_limit,
                )
                index = (_from, _to, len(self.graph.get(_from, {}).get(_to, [])))
                self.add_lane(_from, _to, lane)
                self.index_of[key] = index
                self.key_of[index] = key
                self.lane_row[index] = row
        self._row_index = [self.index_of[k] for k in road.lanes]
        xy = centres.xy
        seg = np.diff(xy, axis=0)
        self._seg_heading = np.append(np.arctan2(seg[:, 1], seg[:, 0]), 0.0)
        # lane_left's constants per lane: the chain's length and its reach beyond the lane.
        self._chain: dict[LaneIndex, tuple[float, float]] = {}
        for index, key in self.key_of.items():
            chain = road.chain_end(key) - road.chain_start(key)
            self._chain[index] = (chain, chain - self.get_lane(index).length)
        self._prepared: dict[tuple[bytes, float], LaneIndex] = {}

    # ------------------------------------------------------------------ look-ups
    def get_closest_lane_index(
        self, position: np.ndarray, heading: float | None = None
    ) -> LaneIndex:
        """The lane whose centre is nearest to ``position`` [m] (plus a heading cost).

        The cost is highway-env's ``distance_with_heading``: distance to the lane [m]
        plus :data:`HEADING_WEIGHT` times the heading difference [rad] when
        ``heading`` is given; only lanes within reach of the position are examined
        (all lanes when none is near).
        """
        if (
            type(position) is np.ndarray
            and position.dtype == np.float64
            and position.shape == (2,)
            and isinstance(heading, float)
            and self._prepared
        ):
            prepared = self._prepared.get((position.tobytes(), heading))
            if prepared is not None:
                return prepared
        c = self.road._centres
        px, py = float(position[0]), float(position[1])
        use_heading = heading is not None and math.isfinite(float(heading))
        args = (
            c.chunk_mark,
            c.chunk_i0,
            c.chunk_i1,
            c.chunk_centre,
            c.chunk_radius,
            len(c.start) - 1,
            c.xy,
            self._seg_heading,
            px,
            py,
            float(heading) if use_heading else 0.0,
            HEADING_WEIGHT if use_heading else 0.0,
        )
        row = _closest_lane(*args, CENTRE_REACH)
        if row < 0:  # nothing within reach: every lane
            row = _closest_lane(*args, math.inf)
        return self._row_index[row if row >= 0 else 0]

    def prepare_closest_lane_poses(self, positions: FloatArray, headings: FloatArray) -> None:
        """Look up the closest lanes of ``(N, 2)`` positions [m], ``(N,)`` headings [rad].

        One compiled call for the poses :meth:`get_closest_lane_index` is about to be
        asked for (every vehicle's, after a simulation step): the same search with
        the same arguments per pose, so the remembered lanes are the ones it would
        return. Only the latest batch is kept; poses with a coordinate or heading not
        finite are not remembered.
        """
        pts = np.ascontiguousarray(positions, dtype=np.float64).reshape(-1, 2)
        hs = np.asarray(headings, dtype=np.float64).reshape(-1)
        self._prepared = {}
        finite = np.isfinite(hs) & np.isfinite(pts).all(axis=1)
        keep = np.flatnonzero(finite)
        if len(keep) == 0:
            return
        c = self.road._centres
        rows = _closest_lanes(
            c.chunk_mark,
            c.chunk_i0,
            c.chunk_i1,
            c.chunk_centre,
            c.chunk_radius,
            len(c.start) - 1,
            c.xy,
            self._seg_heading,
            np.ascontiguousarray(pts[keep]),
            hs[keep],
            HEADING_WEIGHT,
            CENTRE_REACH,
        )
        raw = pts.tobytes()  # row k is raw[16 k : 16 (k + 1)], as position.tobytes()
        row_index = self._row_index
        heading_list = hs.tolist()
        for k, row in zip(keep.tolist(), rows.tolist(), strict=True):
            key = (raw[16 * k : 16 * k + 16], heading_list[k])
            self._prepared[key] = row_index[row if row >= 0 else 0]

    def next_lane(
        self,
        current_index: LaneIndex,
        route: list | None = None,
        position: np.ndarray | None = None,
        np_random: np.random.RandomState | np.random.Generator = np.random,  # type: ignore[assignment]
    ) -> LaneIndex:
        """The lane that continues ``current_index`` along the map's lane links.

        Several successors (a split): one is drawn with ``np_random``. No successor
        (the lane ends): ``current_index`` itself (its vehicles merge out before).
        A ``route`` is not supported on maps and is ignored.
        """
        key = self.key_of.get(current_index)
        if key is None:
            return current_index
        nxt = [n for n in self.road.successors(key) if n in self.index_of]
        if not nxt:
            return current_index
        pick = nxt[0] if len(nxt) == 1 else nxt[int(np_random.integers(len(nxt)))]
        return self.index_of[pick]

    def lane_left(
        self, lane_index: LaneIndex, position: FloatArray, at_least: float = math.inf
    ) -> float:
        """Distance from ``position`` to the end of the lane's chain of successors [m].

        Measured along the lane (its section) and then along the chain (the road's
        arc lengths); ``inf`` for an unknown lane. When the chain reaches
        ``at_least`` beyond the lane's own end, that reach is returned without
        projecting ``position`` (a lower bound, enough to know the end is far).
        """
        constants = self._chain.get(lane_index)
        if constants is None:
            return math.inf
        chain, beyond = constants
        if beyond >= at_least:
            return beyond
        s, _ = self.get_lane(lane_index).local_coordinates(position)
        return chain - float(s)


def _closest_lane_among_py(
    chunks: np.ndarray,
    chunk_mark: np.ndarray,
    chunk_i0: np.ndarray,
    chunk_i1: np.ndarray,
    centre: FloatArray,
    radius: FloatArray,
    n_rows: int,
    xy: FloatArray,
    seg_heading: FloatArray,
    px: float,
    py: float,
    heading: float,
    weight: float,
    reach: float,
) -> int:
    """:func:`_closest_lane_py` over the chunks listed in ``chunks`` (ascending).

    Only chunks of centre vertices (:class:`~aldm_gym.roads.polyline.PolylineMarkings`'
    spatial index) within ``reach`` of ``(px, py)`` are searched. A lane's distance is
    to its nearest segment among those (clamped at the ends); its heading error is to
    that segment's heading, wrapped to ``[0, pi]``. Ties keep the lower row; ``-1``
    when no chunk is within reach.
    """
    best_d2 = np.full(n_rows, np.inf)
    best_i = np.full(n_rows, -1, dtype=np.int64)
    for c in chunks:
        dx = centre[c, 0] - px
        dy = centre[c, 1] - py
        r = reach + radius[c]
        dc2 = dx * dx + dy * dy
        if dc2 > r * r:
            continue
        row = chunk_mark[c]
        # Every segment of the chunk lies in its bounding circle: none is nearer than
        # this bound (less a margin far above rounding), so a chunk that cannot get
        # strictly nearer than the row's best so far changes nothing.
        bound = math.sqrt(dc2) - radius[c] - 1e-3
        if bound > 0.0 and bound * bound > best_d2[row]:
            continue
        for i in range(chunk_i0[c], chunk_i1[c] - 1):
            ax = xy[i, 0]
            ay = xy[i, 1]
            sx = xy[i + 1, 0] - ax
            sy = xy[i + 1, 1] - ay
            ll = sx * sx + sy * sy
            t = ((px - ax) * sx + (py - ay) * sy) / ll if ll > 0.0 else 0.0
            t = min(max(t, 0.0), 1.0)
            qx = ax + t * sx - px
            qy = ay + t * sy - py
            d2 = qx * qx + qy * qy
            if d2 < best_d2[row]:
                best_d2[row] = d2
                best_i[row] = i
    best_row = -1
    best_cost = math.inf
    for row in range(n_rows):
        i = best_i[row]
        if i < 0:
            continue
        cost = math.sqrt(best_d2[row])
        if weight != 0.0:
            err = (heading - seg_heading[i] + math.pi) % (2.0 * math.pi) - math.pi
            cost += weight * abs(err)
        if cost < best_cost:
            best_cost = cost
            best_row = row
    return best_row


_closest_lane_among = numba.njit(cache=True)(_closest_lane_among_py)


def _closest_lane_py(
    chunk_mark: np.ndarray,
    chunk_i0: np.ndarray,
    chunk_i1: np.ndarray,
    centre: FloatArray,
    radius: FloatArray,
    n_rows: int,
    xy: FloatArray,
    seg_heading: FloatArray,
    px: float,
    py: float,
    heading: float,
    weight: float,
    reach: float,
) -> int:
    """Row of the lane centre with the least distance + ``weight`` · heading error.

    Only chunks of centre vertices (:class:`~aldm_gym.roads.polyline.PolylineMarkings`'
    spatial index) within ``reach`` of ``(px, py)`` are searched. A lane's distance is
    to its nearest segment among those (clamped at the ends); its heading error is to
    that segment's heading, wrapped to ``[0, pi]``. Ties keep the lower row; ``-1``
    when no chunk is within reach.
    """
    return _closest_lane_among(
        np.arange(chunk_mark.shape[0]),
        chunk_mark,
        chunk_i0,
        chunk_i1,
        centre,
        radius,
        n_rows,
        xy,
        seg_heading,
        px,
        py,
        heading,
        weight,
        reach,
    )


_closest_lane = numba.njit(cache=True)(_closest_lane_py)


def _closest_lanes_py(
    chunk_mark: np.ndarray,
    chunk_i0: np.ndarray,
    chunk_i1: np.ndarray,
    centre: FloatArray,
    radius: FloatArray,
    n_rows: int,
    xy: FloatArray,
    seg_heading: FloatArray,
    points: FloatArray,
    headings: FloatArray,
    weight: float,
    reach: float,
) -> np.ndarray:
    """:func:`_closest_lane_py` for every pose: ``(N,)`` rows (``-1``: no lane at all).

    Per pose as :meth:`MapNetwork.get_closest_lane_index`: the lanes within ``reach``,
    else every lane. Positions must be finite.
    """
    n = points.shape[0]
    rows = np.empty(n, dtype=np.int64)
    if n == 0:
        return rows
    # A chunk beyond reach of the poses' bounding box is beyond reach of every pose:
    # searching only the others (in the same order) gives the same rows.
    x0 = points[:, 0].min()
    x1 = points[:, 0].max()
    y0 = points[:, 1].min()
    y1 = points[:, 1].max()
    near = np.empty(chunk_mark.shape[0], dtype=np.int64)
    count = 0
    for c in range(chunk_mark.shape[0]):
        r = reach + radius[c]
        cx = centre[c, 0]
        cy = centre[c, 1]
        if x0 - r <= cx and cx <= x1 + r and y0 - r <= cy and cy <= y1 + r:
            near[count] = c
            count += 1
    near = near[:count]
    every = np.arange(chunk_mark.shape[0])
    for k in range(n):
        px = points[k, 0]
        py = points[k, 1]
        h = headings[k]
        row = _closest_lane_among(
            near,
            chunk_mark,
            chunk_i0,
            chunk_i1,
            centre,
            radius,
            n_rows,
            xy,
            seg_heading,
            px,
            py,
            h,
            weight,
            reach,
        )
        if row < 0:
            row = _closest_lane_among(
                every,
                chunk_mark,
                chunk_i0,
                chunk_i1,
                centre,
                radius,
                n_rows,
                xy,
                seg_heading,
                px,
                py,
                h,
                weight,
                math.inf,
            )
        rows[k] = row
    return rows


_closest_lanes = numba.njit(cache=True)(_closest_lanes_py)


def _neighbour_table_py(
    line: LineLookup,
    u: FloatArray,
    w: FloatArray,
    constant: bool,
    margin: float,
    low: float,
    high: float,
    points: FloatArray,
) -> tuple[FloatArray, FloatArray, BoolArray, np.ndarray]:
    """``(s, d, on, order)`` for :meth:`MapLane.neighbour_table` (plain-Python reference).

    ``s`` from :func:`~aldm_gym.roads.reference_line.project_point_near_py` (NaN off reach), the
    lateral coordinate ``r = 0 - d`` (``ReferenceLane.local_coordinates`` at offset
    0), the width ``w[0]`` or interpolated at ``s`` (``MapLane.width_at``), then
    ``AbstractLane.on_lane``'s comparisons; ``order`` sorts the on-lane indices by
    ``s`` with a stable sort. ``s``, ``d`` (left offset [m]), ``on`` have shape
    ``(N,)``, ``order`` ``(M,)``.
    """
    s, d, near = project_point_near(line, points)
    n = points.shape[0]
    on = np.zeros(n, dtype=np.bool_)
    count = 0
    for k in range(n):
        if not near[k]:
            continue
        sk = s[k]
        r = 0.0 - d[k]
        width = w[0] if constant else np.interp(sk, u, w)
        if abs(r) <= width / 2 + margin and low <= sk and sk < high:
            on[k] = True
            count += 1
    idx = np.empty(count, dtype=np.int64)
    j = 0
    for k in range(n):
        if on[k]:
            idx[j] = k
            j += 1
    order = idx[np.argsort(s[idx], kind="mergesort")]
    return s, d, on, order


_neighbour_table = numba.njit(cache=True)(_neighbour_table_py)
