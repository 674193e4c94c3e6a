"""Traffic that scales: a drop-in ``Road`` whose per-step cost is about linear in vehicles.

highway-env's :class:`~highway_env.road.road.Road` answers every neighbour query by
projecting *every* vehicle onto the queried lane (``neighbour_vehicles``), checks
collisions for every pair of vehicles (``step``), computes a norm per vehicle for
every perception query (``close_objects_to``), and
:meth:`~highway_env.road.road.RoadNetwork.get_closest_lane_index` evaluates every lane
through several numpy scalar calls. IDM/MOBIL vehicles call ``neighbour_vehicles``
several times per simulation step, so a step costs O(n²) Python-level lane
projections (highway-env issues #36, #121, #223).

:class:`FastRoad` keeps the exact answers and removes the quadratic work:

- **Neighbours** -- once per simulation step (lazily, per queried lane) every road
  object is projected onto the lane in one vectorised pass (``lane.local_coordinates_many``
  when the lane offers it), the on-lane objects are sorted by longitudinal coordinate,
  and each query is a bisection. Ties are broken as in the base loop (front: the
  *last* object in ``vehicles + objects`` order among equal ``s``; rear: the *first*).
- **Collisions** -- a sort-and-sweep broad phase on ``x`` (radius = the base
  spherical pre-check's radius) and a separating-axis test on the boxes' edge
  normals (with a margin far above rounding) select the only pairs whose
  :meth:`~highway_env.vehicle.objects.RoadObject.handle_collisions` can have an
  effect; they are handled in the base loop's order, so impacts are identical.
- **Perception** -- ``close_objects_to`` filters by distance with one vectorised norm.
- **Lane look-up** -- :class:`FastRoadNetwork` evaluates ``StraightLane`` distances with
  plain float arithmetic (the same IEEE operations as the base code).

The neighbour cache is invalidated at the two places positions can change in a
highway-env simulation step: at the start of :meth:`FastRoad.act` and after the
vehicles moved in :meth:`FastRoad.step`. It is also invalidated whenever a vehicle
steps on its own (``Vehicle.on_state_update`` reads ``road.record_history``, which is
a property here), and when ``vehicles``/``objects`` change membership. Code that
moves vehicles by assigning ``position`` directly must call :meth:`FastRoad.invalidate`.

Usage::

    road = FastRoad(network=..., np_random=self.np_random, ...)  # in _create_road
    use_fast_road(env)                                           # any highway-env env
"""

from __future__ import annotations

import math
import weakref
from bisect import bisect_left, bisect_right
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from highway_env import utils
from highway_env.road.lane import AbstractLane, StraightLane
from highway_env.road.road import LaneIndex, Road, RoadNetwork
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.controller import ControlledVehicle
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import Landmark, RoadObject

from aldm_gym.roads.lane import ReferenceLane
from aldm_gym.types import BoolArray, FloatArray

if TYPE_CHECKING:
    from highway_env.envs.common.abstract import AbstractEnv

__all__ = [
    "FAST_MATH_MATCHES_NUMPY",
    "BatchedLaneUpdate",
    "FastControlledVehicle",
    "FastIDMVehicle",
    "FastRoad",
    "FastRoadNetwork",
    "use_fast_road",
]

_NEIGHBOUR_MARGIN = 1.0
"""Lateral margin [m] of ``Road.neighbour_vehicles``'s ``on_lane(..., margin=1)``."""

_BROAD_PHASE_SLACK = 1e-6
"""Absolute slack [m] added to collision radii so that float rounding in the base
``np.linalg.norm`` pre-check can never make the broad phase drop a pair it keeps."""

_SEPARATION_MARGIN = 1e-4
"""Gap [m] a box pair must clear on a separating axis before its exact check is skipped.

highway-env's polygon test computes the same projections with rounding errors of
order ``1e-16 × |position|`` (well below 1e-8 m on any road); the margin dwarfs them,
so a pair skipped here is one where that test returns "not intersecting, will not
intersect"."""


def _is_plain_straight(lane: AbstractLane) -> bool:
    """Whether ``lane`` uses ``StraightLane``'s own geometry (no overridden methods)."""
    return type(lane) is StraightLane


def _uses_default_on_lane(lane: AbstractLane) -> bool:
    """Whether ``lane.on_lane`` is ``AbstractLane.on_lane`` (so it can be vectorised)."""
    return type(lane).on_lane is AbstractLane.on_lane


_CUSTOM_COLLISIONS: dict[type, bool] = {}


def _has_custom_collisions(cls: type) -> bool:
    """Whether ``cls`` overrides highway-env's collision check (cached per class)."""
    custom = _CUSTOM_COLLISIONS.get(cls)
    if custom is None:
        custom = (
            getattr(cls, "handle_collisions", None) is not RoadObject.handle_collisions
            or getattr(cls, "_is_colliding", None) is not RoadObject._is_colliding
        )
        _CUSTOM_COLLISIONS[cls] = custom
    return custom


_BoxShape = tuple[float, float, float, float, float, float, float, float]
"""``(x, y, cos h, sin h, length / 2, width / 2, vx dt, vy dt)`` of a box road object."""

_BASE_BOX: dict[type, bool] = {}


def _uses_base_box(cls: type) -> bool:
    """Whether ``cls`` collides as highway-env's box: base polygon, velocity and checks."""
    base = _BASE_BOX.get(cls)
    if base is None:
        base = (
            not _has_custom_collisions(cls)
            and getattr(cls, "polygon", None) is RoadObject.polygon
            and getattr(cls, "direction", None) is RoadObject.direction
            and getattr(cls, "velocity", None) in (Vehicle.velocity, RoadObject.velocity)
        )
        _BASE_BOX[cls] = base
    return base


def _boxes_separated(a: _BoxShape, b: _BoxShape) -> bool:
    """Whether the boxes ``a`` (swept by its displacement relative to ``b``) and ``b`` are
    apart by more than :data:`_SEPARATION_MARGIN` on one of their four edge normals.

    Those normals are among the axes of ``utils.are_polygons_intersecting``, so
    then it reports neither a current nor a future intersection, and
    ``handle_collisions`` has no effect. NaN never passes (the pair is then checked).
    """
    ax, ay, ac, as_, al, aw, adx, ady = a
    bx, by, bc, bs, bl, bw, bdx, bdy = b
    dx = bx - ax
    dy = by - ay
    wx = adx - bdx
    wy = ady - bdy
    for nx, ny in ((ac, as_), (-as_, ac), (bc, bs), (-bs, bc)):
        gap = (
            abs(dx * nx + dy * ny)
            - al * abs(ac * nx + as_ * ny)
            - aw * abs(ac * ny - as_ * nx)
            - bl * abs(bc * nx + bs * ny)
            - bw * abs(bc * ny - bs * nx)
            - abs(wx * nx + wy * ny)
        )
        if gap > _SEPARATION_MARGIN:
            return True
    return False


class FastRoadNetwork(RoadNetwork):
    """A :class:`RoadNetwork` with a faster, result-identical ``get_closest_lane_index``.

    ``Vehicle.on_state_update`` calls ``get_closest_lane_index`` for every vehicle at
    every simulation step; the base version loops over all lanes through numpy scalar
    calls (~6 µs per lane). Here ``StraightLane`` lanes are evaluated with plain float
    arithmetic performing the same IEEE operations in the same order (two-term dot
    products, ``wrap_to_pi``'s ``%``), and the argmin keeps ``np.argmin``'s rules (first
    minimum; the first NaN wins). Other lane classes fall back to their own
    ``distance_with_heading``.

    The flat lane list is cached; it is rebuilt when :meth:`add_lane` is called or the
    graph's shape (edges and lane counts) changes.
    """

    def __init__(self) -> None:
        """Create an empty network."""
        super().__init__()
        self._flat: list[tuple[LaneIndex, AbstractLane, tuple[float, ...] | None]] | None = None
        self._flat_shape: tuple[int, ...] = ()

    @classmethod
    def from_network(cls, network: RoadNetwork) -> FastRoadNetwork:
        """Wrap an existing network, sharing its graph (lanes are not copied).

        :param network: any ``RoadNetwork``.
        :return: a ``FastRoadNetwork`` whose ``graph`` is ``network.graph``.
        """
        fast = cls()
        fast.graph = network.graph
        return fast

    def add_lane(self, _from: str, _to: str, lane: AbstractLane) -> None:
        """Add a lane (see ``RoadNetwork.add_lane``) and drop the flat lane cache."""
        super().add_lane(_from, _to, lane)
        self._flat = None

    def _graph_shape(self) -> tuple[int, ...]:
        """Cheap fingerprint of the graph's structure: lane count of every edge."""
        return tuple(len(lanes) for to in self.graph.values() for lanes in to.values())

    def _flat_lanes(self) -> list[tuple[LaneIndex, AbstractLane, tuple[float, ...] | None]]:
        """All lanes in the base iteration order, with StraightLane constants unpacked."""
        shape = self._graph_shape()
        if self._flat is None or shape != self._flat_shape:
            flat: list[tuple[LaneIndex, AbstractLane, tuple[float, ...] | None]] = []
            for _from, to_dict in self.graph.items():
                for _to, lanes in to_dict.items():
                    for _id, lane in enumerate(lanes):
                        flat.append(((_from, _to, _id), lane, _straight_geometry(lane)))
            self._flat = flat
            self._flat_shape = shape
        return self._flat

    def get_closest_lane_index(
        self, position: np.ndarray, heading: float | None = None
    ) -> LaneIndex:
        """Index of the lane closest to a world position (same result as the base class).

        :param position: a world position ``(2,)`` [m].
        :param heading: a heading angle [rad], or None to ignore headings.
        :return: the index of the closest lane.
        """
        px, py = (float(c) for c in position[:2])
        two_pi = 2 * np.pi
        best_index: LaneIndex | None = None
        best = 0.0
        angle_of: dict[float, float] = {}
        for index, lane, consts in self._flat_lanes():
            if consts is None:
                d = float(lane.distance_with_heading(position, heading))
            else:
                sx, sy, d0, d1, l0, l1, length, lane_heading = consts
                # Same operations as StraightLane.local_coordinates: delta = p - start,
                # then two-term dot products (np.dot of length 2 is a*b + c*d).
                dx = px - sx
                dy = py - sy
                s = dx * d0 + dy * d1
                r = dx * l0 + dy * l1
                # max(x, 0) returns x unless 0 > x (NaN stays NaN).
                beyond = s - length
                before = 0 - s
                d = abs(r) + (0 if 0 > beyond else beyond) + (0 if 0 > before else before)
                if heading is not None:
                    # AbstractLane.local_angle -> utils.wrap_to_pi; Python's float % and
                    # numpy's remainder share the fmod-and-fix-sign definition. Parallel
                    # lanes share a heading, so the angle is computed once per heading.
                    angle = angle_of.get(lane_heading)
                    if angle is None:
                        angle = abs(((heading - lane_heading) + np.pi) % two_pi - np.pi)
                        angle_of[lane_heading] = angle
                    d = d + 1.0 * angle
            if d != d:  # np.argmin returns the first NaN
                return index
            if best_index is None or d < best:
                best_index = index
                best = d
        if best_index is None:
            raise ValueError("get_closest_lane_index called on a network without lanes")
        return best_index


class _LaneTable:
    """Longitudinal coordinates of every road object on one lane, for one epoch.

    ``s`` / ``r`` have shape ``(N,)`` and follow ``FastRoad``'s object order;
    ``on_lane`` is the ``on_lane(..., margin=1)`` mask.
    """

    __slots__ = ("on_lane", "r", "s")

    def __init__(self, s: FloatArray, r: FloatArray, on_lane: BoolArray) -> None:
        self.s = s
        self.r = r
        self.on_lane = on_lane


class _SortedNeighbours:
    """On-lane objects of one query lane sorted by effective longitudinal coordinate.

    ``keys`` ascending; ties keep object order (stable sort), which the bisection
    queries rely on for the base loop's tie-breaking.
    """

    __slots__ = ("keys", "objects", "query_s")

    def __init__(self, keys: list[float], objects: list[RoadObject], query_s: list[float]) -> None:
        self.keys = keys
        self.objects = objects
        self.query_s = query_s


class FastRoad(Road):
    """A :class:`highway_env.road.road.Road` with O(n log n) neighbours and collisions.

    Results are those of the base class: same neighbours (including tie-breaking), same
    collision outcomes (pairs handled in the base loop's order), same
    ``close_objects_to`` lists. See the module docstring for how the per-step cache is
    kept valid.

    :param network: the road network; a plain ``RoadNetwork`` is wrapped in a
        :class:`FastRoadNetwork` sharing its graph.
    :param vehicles: the vehicles driving on the road.
    :param road_objects: obstacles and landmarks.
    :param np_random: random generator for vehicle behaviour.
    :param record_history: whether vehicles record their trajectories (display only).
    :param neighbour_vehicles_connected_lanes: also search connected lane segments.
    """

    def __init__(
        self,
        network: RoadNetwork | None = None,
        vehicles: list[RoadObject] | None = None,
        road_objects: list[RoadObject] | None = None,
        np_random: np.random.RandomState | np.random.Generator | None = None,
        record_history: bool = False,
        neighbour_vehicles_connected_lanes: bool = False,
    ) -> None:
        """Create a road; see the class docstring for the parameters."""
        if network is not None and type(network) is RoadNetwork:
            network = FastRoadNetwork.from_network(network)
        self._record_history = bool(record_history)
        self._cache_valid = False
        self._deferred_updates: list[Vehicle] | None = None
        super().__init__(
            network=network,
            vehicles=vehicles,
            road_objects=road_objects,
            np_random=np_random,
            record_history=record_history,
            neighbour_vehicles_connected_lanes=neighbour_vehicles_connected_lanes,
        )
        self._reset_cache()

    @classmethod
    def from_road(cls, road: Road) -> FastRoad:
        """Rewrap an existing road, keeping its network, vehicles, objects and settings.

        The ``vehicles`` and ``objects`` lists are shared (not copied) and every object
        whose ``road`` is the old road is re-pointed to the new one, so vehicles created
        before the swap query the fast road.

        :param road: a ``Road`` (or ``FastRoad``, returned unchanged).
        :return: the fast road.
        """
        if isinstance(road, FastRoad):
            return road
        fast = cls(
            network=road.network,
            np_random=road.np_random,
            record_history=road.record_history,
            neighbour_vehicles_connected_lanes=road.neighbour_vehicles_connected_lanes,
        )
        fast.vehicles = road.vehicles
        fast.objects = road.objects
        for obj in [*road.vehicles, *road.objects]:
            if getattr(obj, "road", None) is road:
                obj.road = fast
        return fast

    # -- cache ----------------------------------------------------------------------

    @property
    def record_history(self) -> bool:
        """Whether vehicles record their trajectories (display only).

        ``Vehicle.on_state_update`` reads this flag right after a vehicle moved, so
        reading it also invalidates the neighbour cache: a vehicle stepped outside
        :meth:`step` (e.g. ``predict_trajectory`` on a deep copy) cannot leave it stale.
        """
        self._cache_valid = False
        return self._record_history

    @record_history.setter
    def record_history(self, value: bool) -> None:
        self._record_history = bool(value)

    def invalidate(self) -> None:
        """Drop the per-step neighbour cache (call after moving vehicles by hand)."""
        self._cache_valid = False

    def _reset_cache(self) -> None:
        """Start a new cache epoch (called lazily on the first query after invalidation)."""
        self._cache_valid = False
        self._cache_vehicles: list[RoadObject] = []
        self._cache_objects: list[RoadObject] = []
        self._items: list[RoadObject] = []
        self._index: dict[int, int] = {}
        self._positions: FloatArray = np.zeros((0, 2))
        self._lane_tables: dict[int, _LaneTable] = {}
        self._sorted: dict[tuple[LaneIndex, bool], _SortedNeighbours] = {}

    def _ensure_cache(self) -> None:
        """Rebuild the epoch's object list and positions if the cache is not valid."""
        if (
            self._cache_valid
            and self._cache_vehicles == self.vehicles
            and self._cache_objects == self.objects
        ):
            return
        self._reset_cache()
        self._cache_vehicles = list(self.vehicles)
        self._cache_objects = list(self.objects)
        # Same population and order as the base loop over `vehicles + objects`.
        items = [
            o for o in self._cache_vehicles + self._cache_objects if not isinstance(o, Landmark)
        ]
        self._items = items
        self._index = {id(o): i for i, o in enumerate(items)}
        if items:
            self._positions = np.array([o.position for o in items], dtype=np.float64).reshape(-1, 2)
        self._cache_valid = True

    def _lane_table(self, lane: AbstractLane) -> _LaneTable:
        """Coordinates and on-lane mask of every cached object on ``lane`` (O(N))."""
        table = self._lane_tables.get(id(lane))
        if table is not None:
            return table
        positions = self._positions
        n = len(self._items)
        if n == 0:
            empty = np.zeros(0)
            table = _LaneTable(empty, empty, np.zeros(0, dtype=bool))
        elif _is_plain_straight(lane):
            assert isinstance(lane, StraightLane)
            # StraightLane.local_coordinates, vectorised with the same operations.
            dx = positions[:, 0] - lane.start[0]
            dy = positions[:, 1] - lane.start[1]
            s = dx * lane.direction[0] + dy * lane.direction[1]
            r = dx * lane.direction_lateral[0] + dy * lane.direction_lateral[1]
            on = (
                (np.abs(r) <= lane.width / 2 + _NEIGHBOUR_MARGIN)
                & (-lane.VEHICLE_LENGTH <= s)
                & (s < lane.length + lane.VEHICLE_LENGTH)
            )
            table = _LaneTable(s, r, on)
        else:
            many: Callable[[FloatArray], tuple[Any, Any]] | None = getattr(
                lane, "local_coordinates_many", None
            )
            if many is not None:
                s_raw, r_raw = many(positions)
                s = np.asarray(s_raw, dtype=np.float64).reshape(n)
                r = np.asarray(r_raw, dtype=np.float64).reshape(n)
            else:
                coords = [lane.local_coordinates(o.position) for o in self._items]
                s = np.array([c[0] for c in coords], dtype=np.float64)
                r = np.array([c[1] for c in coords], dtype=np.float64)
            if _uses_default_on_lane(lane):
                widths = np.array([lane.width_at(si) for si in s.tolist()], dtype=np.float64)
                on = (
                    (np.abs(r) <= widths / 2 + _NEIGHBOUR_MARGIN)
                    & (-lane.VEHICLE_LENGTH <= s)
                    & (s < lane.length + lane.VEHICLE_LENGTH)
                )
            else:
                on = np.array(
                    [
                        bool(lane.on_lane(o.position, si, ri, margin=_NEIGHBOUR_MARGIN))
                        for o, si, ri in zip(self._items, s.tolist(), r.tolist(), strict=True)
                    ],
                    dtype=bool,
                )
            table = _LaneTable(s, r, on)
        self._lane_tables[id(lane)] = table
        return table

    def _search_lanes(self, lane_index: LaneIndex) -> list[tuple[AbstractLane, float]]:
        """Lanes searched for neighbours and their offsets, as in ``Road.neighbour_vehicles``."""
        lane = self.network.get_lane(lane_index)
        lanes_offsets: list[tuple[AbstractLane, float]] = [(lane, 0)]
        if self.neighbour_vehicles_connected_lanes:
            _from, _to, _id = lane_index
            for next_lanes in self.network.graph.get(_to, {}).values():
                if _id < len(next_lanes):
                    lanes_offsets.append((next_lanes[_id], lane.length))
                elif next_lanes:
                    lanes_offsets.append((next_lanes[0], lane.length))
            for to_dict in self.network.graph.values():
                if _from in to_dict:
                    prev_lanes = to_dict[_from]
                    if _id < len(prev_lanes):
                        prev_lane = prev_lanes[_id]
                    elif prev_lanes:
                        prev_lane = prev_lanes[0]
                    else:
                        continue
                    lanes_offsets.append((prev_lane, -prev_lane.length))
        return lanes_offsets

    def _sorted_neighbours(self, lane_index: LaneIndex) -> _SortedNeighbours:
        """Objects on ``lane_index`` (and connected lanes) sorted by longitudinal position."""
        connected = bool(self.neighbour_vehicles_connected_lanes)
        key = (lane_index, connected)
        entry = self._sorted.get(key)
        if entry is not None:
            return entry
        if not connected and (
            self._build_straight_edge(lane_index) or self._build_reference_edge(lane_index)
        ):
            return self._sorted[key]
        lanes_offsets = self._search_lanes(lane_index)
        primary = self._lane_table(lanes_offsets[0][0])
        n = len(self._items)
        if len(lanes_offsets) == 1:
            effective = primary.s
            matched = primary.on_lane
        else:
            # Each object is matched on the first searched lane it is on (the base
            # loop's `break`), its coordinate shifted into the primary lane's frame.
            effective = np.full(n, np.nan)
            matched = np.zeros(n, dtype=bool)
            for search_lane, offset in lanes_offsets:
                table = self._lane_table(search_lane)
                take = table.on_lane & ~matched
                effective[take] = table.s[take] + offset
                matched |= table.on_lane
        # NaN coordinates never satisfy the base loop's comparisons: drop them.
        candidates = np.flatnonzero(matched & ~np.isnan(effective))
        keys = effective[candidates]
        order = np.argsort(keys, kind="stable")
        items = self._items
        entry = _SortedNeighbours(
            keys=keys[order].tolist(),
            objects=[items[i] for i in candidates[order].tolist()],
            query_s=primary.s.tolist(),
        )
        self._sorted[key] = entry
        return entry

    def _edge_lanes(
        self, lane_index: LaneIndex, qualifies: Callable[[AbstractLane], bool]
    ) -> list[AbstractLane] | None:
        """The lanes of ``lane_index``'s edge if it exists and every lane qualifies, else None."""
        _from, _to, _ = lane_index
        try:
            lanes = self.network.graph[_from][_to]
        except (KeyError, TypeError):
            return None
        if not lanes or not all(qualifies(lane) for lane in lanes):
            return None
        return lanes

    def _build_straight_edge(self, lane_index: LaneIndex) -> bool:
        """Sorted neighbours of every lane of ``lane_index``'s edge in one numpy pass.

        Only for edges made of plain ``StraightLane`` lanes searched without connected
        lanes (the highway case): IDM/MOBIL query the own lane and both side lanes, so
        batching the edge's ``(lanes, N)`` projection saves most numpy call overhead.

        :return: False (nothing built) if the edge does not qualify.
        """
        _from, _to, _ = lane_index
        lanes = self._edge_lanes(lane_index, _is_plain_straight)
        if lanes is None:
            return False
        items = self._items
        n = len(items)
        n_lanes = len(lanes)
        if n == 0:
            for i in range(n_lanes):
                self._sorted[((_from, _to, i), False)] = _SortedNeighbours([], [], [])
            return True
        geometry = np.array(
            [
                (
                    lane.start[0],
                    lane.start[1],
                    lane.direction[0],
                    lane.direction[1],
                    lane.direction_lateral[0],
                    lane.direction_lateral[1],
                    lane.width / 2 + _NEIGHBOUR_MARGIN,
                    -lane.VEHICLE_LENGTH,
                    lane.length + lane.VEHICLE_LENGTH,
                )
                for lane in lanes
            ],
            dtype=np.float64,
        )
        # StraightLane.local_coordinates and on_lane(margin=1), broadcast to (lanes, N)
        # with the same elementwise operations.
        dx = self._positions[:, 0] - geometry[:, 0:1]
        dy = self._positions[:, 1] - geometry[:, 1:2]
        s = dx * geometry[:, 2:3] + dy * geometry[:, 3:4]
        r = dx * geometry[:, 4:5] + dy * geometry[:, 5:6]
        on = (np.abs(r) <= geometry[:, 6:7]) & (geometry[:, 7:8] <= s) & (s < geometry[:, 8:9])
        # The on-lane test already rejects NaN coordinates. Sort on-lane objects first,
        # then by s, ties in object order (lexsort is stable).
        order = np.lexsort((s, ~on), axis=-1)
        counts = on.sum(axis=1).tolist()
        sorted_s = s[np.arange(n_lanes)[:, None], order]
        for i, lane in enumerate(lanes):
            count = counts[i]
            self._lane_tables[id(lane)] = _LaneTable(s[i], r[i], on[i])
            self._sorted[((_from, _to, i), False)] = _SortedNeighbours(
                keys=sorted_s[i, :count].tolist(),
                objects=[items[k] for k in order[i, :count].tolist()],
                query_s=s[i].tolist(),
            )
        return True

    def _build_reference_edge(self, lane_index: LaneIndex) -> bool:
        """Sorted neighbours of every lane of an edge of :class:`ReferenceLane` lanes at once.

        The lanes of an aldm-gym highway share one reference line and its arc length
        ``s``: the objects are projected once (``project_many``), sorted once by ``s``
        (stable, so ties stay in object order), and each lane only applies its
        on-lane mask (``AbstractLane.on_lane(margin=1)``'s comparisons) to that order.
        The lane coordinates are those of ``local_coordinates_many`` (``s``,
        ``offset - d``), so the answers are those of the generic path.

        :return: False (nothing built) if the edge does not qualify.
        """
        _from, _to, _ = lane_index
        lanes = self._edge_lanes(lane_index, lambda lane: type(lane) is ReferenceLane)
        if lanes is None:
            return False
        reference = lanes[0].reference
        if any(lane.reference is not reference for lane in lanes):
            return False
        items = self._items
        n = len(items)
        if n == 0:
            for i in range(len(lanes)):
                self._sorted[((_from, _to, i), False)] = _SortedNeighbours([], [], [])
            return True
        s, d = reference.project_many(self._positions)
        # One stable sort by s (ties in object order), then each lane keeps the objects
        # passing on_lane(margin=1): r = offset - d and the comparisons on Python floats
        # (the same IEEE operations as local_coordinates_many and AbstractLane.on_lane;
        # a NaN coordinate fails every comparison, as there). For a few dozen objects
        # this is cheaper than the broadcast numpy version.
        order = np.argsort(s, kind="stable")
        rows = list(zip(s[order].tolist(), d[order].tolist(), order.tolist(), strict=True))
        query_s = s.tolist()
        for i, lane in enumerate(lanes):
            offset = lane.offset
            half_width = lane.width / 2 + _NEIGHBOUR_MARGIN
            low = -lane.VEHICLE_LENGTH
            high = lane.length + lane.VEHICLE_LENGTH
            keys: list[float] = []
            objects: list[RoadObject] = []
            for sk, dk, k in rows:
                if abs(offset - dk) <= half_width and low <= sk and sk < high:
                    keys.append(sk)
                    objects.append(items[k])
            self._sorted[((_from, _to, i), False)] = _SortedNeighbours(keys, objects, query_s)
        return True

    # -- Road API -------------------------------------------------------------------

    def neighbour_vehicles(
        self, vehicle: RoadObject, lane_index: LaneIndex | None = None
    ) -> tuple[RoadObject | None, RoadObject | None]:
        """Preceding and following objects of ``vehicle`` on a lane (base-class result).

        :param vehicle: the vehicle whose neighbours must be found.
        :param lane_index: the lane to search (default: the vehicle's lane); the vehicle
            is projected onto it.
        :return: ``(front, rear)``, either of which may be None.
        """
        lane_index = lane_index or vehicle.lane_index
        if not lane_index:
            return None, None
        # _ensure_cache's and _sorted_neighbours' fast checks inlined (tens of queries
        # per simulation step).
        if not (
            self._cache_valid
            and self._cache_vehicles == self.vehicles
            and self._cache_objects == self.objects
        ):
            self._ensure_cache()
        entry = self._sorted.get((lane_index, bool(self.neighbour_vehicles_connected_lanes)))
        if entry is None:
            entry = self._sorted_neighbours(lane_index)
        i = self._index.get(id(vehicle))
        if i is not None and self._items[i] is vehicle:
            s = entry.query_s[i]
        else:
            s = float(self.network.get_lane(lane_index).local_coordinates(vehicle.position)[0])
        if s != s:  # NaN: no comparison holds in the base loop
            return None, None
        keys = entry.keys
        objects = entry.objects
        size = len(keys)
        # Front: smallest key >= s; among equal keys the base loop keeps the last one.
        front = None
        first_at_or_after = j = bisect_left(keys, s)
        while j < size and front is None:
            end = bisect_right(keys, keys[j], j)
            for m in range(end - 1, j - 1, -1):
                if objects[m] is not vehicle:
                    front = objects[m]
                    break
            j = end
        # Rear: largest key < s; among equal keys the base loop keeps the first one.
        rear = None
        j = first_at_or_after - 1
        while j >= 0 and rear is None:
            start = bisect_left(keys, keys[j], 0, j)
            for m in range(start, j + 1):
                if objects[m] is not vehicle:
                    rear = objects[m]
                    break
            j = start - 1
        return front, rear

    def close_objects_to(
        self,
        vehicle: RoadObject,
        distance: float,
        count: int | None = None,
        see_behind: bool = True,
        sort: bool = True,
        vehicles_only: bool = False,
    ) -> list[RoadObject]:
        """Objects within ``distance`` [m] of ``vehicle`` (base-class result and order).

        The Euclidean pre-filter is one vectorised norm; the lane-distance conditions
        and sorting then run on the few remaining objects exactly as in the base class.

        :param vehicle: the reference vehicle.
        :param distance: the search radius [m].
        :param count: keep at most this many objects (after sorting).
        :param see_behind: include vehicles behind the reference vehicle.
        :param sort: sort by absolute lane distance.
        :param vehicles_only: skip road objects.
        :return: the selected objects.
        """
        origin = np.asarray(vehicle.position, dtype=np.float64)

        def near(population: list[RoadObject]) -> list[RoadObject]:
            if not population:
                return []
            positions = np.array([o.position for o in population], dtype=np.float64)
            delta = positions.reshape(-1, 2) - origin
            # np.linalg.norm of a length-2 vector is sqrt(x*x + y*y).
            dist = np.sqrt(delta[:, 0] * delta[:, 0] + delta[:, 1] * delta[:, 1])
            return [population[i] for i in np.flatnonzero(dist < distance).tolist()]

        vehicles = [
            v
            for v in near(self.vehicles)
            if v is not vehicle
            and (see_behind or -2 * vehicle.LENGTH < vehicle.lane_distance_to(v))
        ]
        obstacles = [
            o for o in near(self.objects) if -2 * vehicle.LENGTH < vehicle.lane_distance_to(o)
        ]
        objects_ = vehicles if vehicles_only else vehicles + obstacles
        if sort:
            objects_ = sorted(objects_, key=lambda o: abs(vehicle.lane_distance_to(o)))
        if count:
            objects_ = objects_[:count]
        return objects_

    def act(self) -> None:
        """Decide the actions of every vehicle (positions are fixed from here to ``step``)."""
        self.invalidate()
        for vehicle in self.vehicles:
            vehicle.act()

    def step(self, dt: float) -> None:
        """Move every vehicle by ``dt`` [s], then resolve collisions (base-class result).

        Vehicles whose ``step`` ends with ``on_state_update`` (see
        :class:`BatchedLaneUpdate`) have their closest-lane look-up deferred until all
        have moved: the look-up depends only on the vehicle's own pose, so the order
        does not matter, and the network may then prepare every position in one batch
        (``prepare_closest_lanes``, e.g. one compiled projection of all vehicles).

        :param dt: timestep [s].
        """
        deferred: list[Vehicle] = []
        try:
            for vehicle in self.vehicles:
                self._deferred_updates = (
                    deferred if type(vehicle).step in _STEPS_ENDING_WITH_UPDATE else None
                )
                vehicle.step(dt)
        finally:
            self._deferred_updates = None
        if deferred:
            prepare: Callable[[FloatArray], None] | None = getattr(
                self.network, "prepare_closest_lanes", None
            )
            if prepare is not None:
                # Built like _ensure_cache's array: when every object is a deferred
                # vehicle (a highway), the next act's batch projection is a memo hit.
                prepare(np.array([v.position for v in deferred], dtype=np.float64).reshape(-1, 2))
            for vehicle in deferred:
                Vehicle.on_state_update(vehicle)
        self.invalidate()
        self._handle_collisions(dt)

    def _handle_collisions(self, dt: float) -> None:
        """Call ``handle_collisions`` on exactly the pairs where it can have an effect.

        The base loop calls ``vehicles[i].handle_collisions(other)`` for every later
        vehicle, then every object. That call is a no-op unless one side checks
        collisions, both are collidable and the centres are within
        ``(diag_i + diag_j) / 2 + speed_i * dt`` (its spherical pre-check). A
        sort-and-sweep on ``x`` with radius ``diag / 2 + max(speed * dt, 0)`` keeps a
        superset of those pairs. Pairs of plain boxes that are apart on one of their
        edge normals (:func:`_boxes_separated`; vehicles side by side in adjacent
        lanes are the common case) are dropped too: the base polygon test would report
        no intersection for them. The rest are handled in the base loop's order, so the
        last write to each ``impact`` is the same. (Plain Python: for a few dozen
        objects it is several times cheaper than the same sweep in numpy calls.)
        """
        vehicles = self.vehicles
        n_vehicles = len(vehicles)
        if n_vehicles == 0:
            return
        population = [*vehicles, *self.objects]
        entries: list[tuple[float, float, float, float, int, bool]] = []
        boxes: dict[int, _BoxShape] = {}
        for index, obj in enumerate(population):
            if not obj.collidable:
                continue  # both sides must be collidable
            px, py = obj.position.tolist()
            cls = type(obj)
            if _has_custom_collisions(cls):
                radius = math.inf  # its own collision logic: pair it with everything
            else:
                radius = obj.diagonal / 2 + max(obj.speed * dt, 0.0)
                radius = radius * (1 + 1e-9) + _BROAD_PHASE_SLACK
            if not (math.isfinite(px) and math.isfinite(py)) or radius != radius:
                self._handle_all_collisions(dt)
                return
            if _uses_base_box(cls):
                c = math.cos(obj.heading)
                s = math.sin(obj.heading)
                step = obj.speed * dt
                boxes[index] = (px, py, c, s, obj.LENGTH / 2, obj.WIDTH / 2, step * c, step * s)
            entries.append(
                (px - radius, px + radius, py, radius, index, bool(obj.check_collisions))
            )
        entries.sort()
        pairs: list[tuple[int, int]] = []
        active: list[tuple[float, float, float, float, int, bool]] = []
        for entry in entries:
            low, _, y, radius, index, checks = entry
            if active:
                # Sorted by `low`, an earlier interval overlaps this one iff it ends after `low`.
                active = [a for a in active if a[1] >= low]
                for other in active:
                    if (checks or other[5]) and abs(y - other[2]) <= radius + other[3]:
                        i, j = (index, other[4]) if index < other[4] else (other[4], index)
                        if i >= n_vehicles:  # objects never call handle_collisions themselves
                            continue
                        # Narrow phase: boxes clearly apart (side by side in adjacent
                        # lanes, or following at a distance) cannot collide this step.
                        box_i = boxes.get(i)
                        box_j = boxes.get(j)
                        if box_i is not None and box_j is not None:
                            if _boxes_separated(box_i, box_j):
                                continue
                        pairs.append((i, j))
            active.append(entry)
        pairs.sort()
        for i, j in pairs:
            population[i].handle_collisions(population[j], dt)

    def _handle_all_collisions(self, dt: float) -> None:
        """The base O(n²) collision loop (used when positions are not finite)."""
        for i, vehicle in enumerate(self.vehicles):
            for other in self.vehicles[i + 1 :]:
                vehicle.handle_collisions(other, dt)
            for other in self.objects:
                vehicle.handle_collisions(other, dt)


# -- vehicles ---------------------------------------------------------------------------
#
# After FastRoad, the per-step cost is dominated by numpy *scalar* calls in the vehicle
# models (np.clip alone is ~4 µs through its Python dispatch; np.dot, np.array, properties
# building 2-vectors). The classes below redo the same IEEE operations on Python floats.
# Elementary functions come from `math` only when they agree with numpy's scalar ufuncs
# on this machine (checked once at import; numpy may use its own SIMD kernels elsewhere).

_StraightGeometry = tuple[float, float, float, float, float, float, float, float]
_STRAIGHT_GEOMETRY: dict[int, tuple[weakref.ref[AbstractLane], _StraightGeometry]] = {}
"""Geometry of plain StraightLanes by ``id``; entries leave when their lane is collected
(a WeakKeyDictionary lookup costs ~3x more, and this is on the per-vehicle hot path)."""


def _straight_geometry(lane: AbstractLane) -> _StraightGeometry | None:
    """``(start_x, start_y, dir_x, dir_y, lat_x, lat_y, length, heading)`` of a plain StraightLane.

    None for any other lane class (including StraightLane subclasses, which may
    override the geometry).
    """
    if type(lane) is not StraightLane:
        return None
    key = id(lane)
    entry = _STRAIGHT_GEOMETRY.get(key)
    if entry is not None and entry[0]() is lane:
        return entry[1]
    assert isinstance(lane, StraightLane)
    geometry = (
        float(lane.start[0]),
        float(lane.start[1]),
        float(lane.direction[0]),
        float(lane.direction[1]),
        float(lane.direction_lateral[0]),
        float(lane.direction_lateral[1]),
        float(lane.length),
        float(lane.heading),
    )

    def _forget(ref: weakref.ref[AbstractLane], key: int = key) -> None:
        current = _STRAIGHT_GEOMETRY.get(key)
        if current is not None and current[0] is ref:
            del _STRAIGHT_GEOMETRY[key]

    _STRAIGHT_GEOMETRY[key] = (weakref.ref(lane, _forget), geometry)
    return geometry


def _math_matches_numpy() -> bool:
    """Whether ``math``'s functions return numpy's scalar results bit for bit here."""
    angles = [*np.linspace(-3.5, 3.5, 301).tolist(), 1e-9, -1e-7, 1e-4, 0.3, -0.7]
    unit = np.linspace(-1.0, 1.0, 201).tolist()
    pairs: list[tuple[Callable[[Any], Any], Callable[[float], float], list[float]]] = [
        (np.sin, math.sin, angles),
        (np.cos, math.cos, angles),
        (np.tan, math.tan, angles),
        (np.arctan, math.atan, angles),
        (np.arcsin, math.asin, unit),
    ]
    for numpy_f, math_f, xs in pairs:
        if any(float(numpy_f(x)) != math_f(x) for x in xs):
            return False
    bases = np.linspace(0.0, 2.5, 101).tolist()
    return all(
        float(np.power(b, e)) == math.pow(b, e) for b in bases for e in (3.5, 3.9, 4.0, 4.37)
    )


FAST_MATH_MATCHES_NUMPY: bool = _math_matches_numpy()
"""True when the fast vehicles use ``math`` (else numpy scalar calls, same results)."""


def _numpy_scalar(ufunc: np.ufunc) -> Callable[[float], float]:
    """A scalar function evaluated by a numpy ufunc (fallback when ``math`` differs)."""

    def evaluate(x: float) -> float:
        return float(ufunc(x))

    return evaluate


_sin: Callable[[float], float] = math.sin if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.sin)
_cos: Callable[[float], float] = math.cos if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.cos)
_tan: Callable[[float], float] = math.tan if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.tan)
_atan: Callable[[float], float] = math.atan if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.arctan)
_asin: Callable[[float], float] = math.asin if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.arcsin)


# np.power special-cases some exponents (e.g. 2 -> square, 0.5 -> sqrt, -1 -> reciprocal):
# those, and anything math.pow rejects, go through numpy itself.
_NUMPY_POWER_SPECIAL = frozenset({-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0})


def _power(x: float, exponent: float) -> float:
    """``np.power(x, exponent)`` for scalars, bit for bit."""
    if FAST_MATH_MATCHES_NUMPY and exponent not in _NUMPY_POWER_SPECIAL:
        try:
            return math.pow(x, exponent)
        except (ValueError, OverflowError):
            pass
    return float(np.power(x, exponent))


def _clip(x: float, low: float, high: float) -> float:
    """``np.clip`` for scalars with non-NaN bounds (same NaN and signed-zero results).

    ``min(max(x, low), high)`` spelled as comparisons (the builtins are several times
    slower): ``max`` keeps ``x`` unless ``low > x``, ``min`` keeps it unless ``high < x``.
    """
    if low > x:
        x = low
    if high < x:
        return high
    return x


def _not_zero(x: float) -> float:
    """``highway_env.utils.not_zero(x)`` (eps = 0.01) with the same comparisons."""
    if abs(x) > 0.01:
        return x
    if x >= 0:
        return 0.01
    return -0.01


_BASE_KINEMATICS: dict[type, bool] = {}


def _uses_base_kinematics(obj: RoadObject) -> bool:
    """Whether ``obj.velocity`` / ``obj.direction`` are highway-env's own properties."""
    cls = type(obj)
    base = _BASE_KINEMATICS.get(cls)
    if base is None:
        base = getattr(cls, "direction", None) is RoadObject.direction and (
            getattr(cls, "velocity", None) in (Vehicle.velocity, RoadObject.velocity)
        )
        _BASE_KINEMATICS[cls] = base
    return base


class BatchedLaneUpdate(Vehicle):
    """Mixin: lets :meth:`FastRoad.step` defer this vehicle's closest-lane look-up.

    ``Vehicle.on_state_update`` (called at the end of ``step``) looks up the closest
    lane of the new position. Inside :meth:`FastRoad.step` the call is queued and run,
    unchanged, once every vehicle has moved, after the network has had the chance to
    project all positions in one batch. Anywhere else it runs at once.
    """

    def on_state_update(self) -> None:
        """Update the lane (now, or after all vehicles moved in ``FastRoad.step``)."""
        deferred: list[Vehicle] | None = getattr(self.road, "_deferred_updates", None)
        if deferred is not None:
            deferred.append(self)
            return
        Vehicle.on_state_update(self)


class FastControlledVehicle(BatchedLaneUpdate, ControlledVehicle):
    """A ``ControlledVehicle`` whose hot paths avoid numpy scalar overhead.

    ``step`` (the bicycle model of ``Vehicle.step``), ``steering_control``,
    ``follow_road`` and ``lane_distance_to`` perform the same floating-point operations
    as highway-env's versions, so trajectories are identical bit for bit (checked in
    ``tests/test_traffic.py``). Lanes other than plain ``StraightLane`` use the lane's
    own methods.
    """

    def step(self, dt: float) -> None:
        """Propagate the state by ``dt`` [s] exactly as ``Vehicle.step`` does.

        :param dt: integration timestep [s].
        """
        self.clip_actions()
        beta = _atan(1 / 2 * _tan(self.action["steering"]))
        speed = self.speed
        course = self.heading + beta
        position = self.position
        # Vehicle.step: position += (speed * [cos, sin]) * dt, element by element.
        position[0] = position[0] + speed * _cos(course) * dt
        position[1] = position[1] + speed * _sin(course) * dt
        impact: np.ndarray | None = getattr(self, "impact", None)
        if impact is not None:
            self.position += impact
            self.crashed = True
            self.impact = None
        self.heading += speed * _sin(beta) / (self.LENGTH / 2) * dt
        self.speed += self.action["acceleration"] * dt
        self.on_state_update()

    def lane_distance_to(self, other: RoadObject, lane: AbstractLane | None = None) -> float:
        """Signed distance [m] to ``other`` along ``lane`` (default: own lane).

        :param other: the other object (None gives NaN).
        :param lane: the lane to measure along.
        :return: ``s_other - s_self`` [m].
        """
        if not other:
            return np.nan
        if not lane:
            lane = self.lane
        geometry = _straight_geometry(lane)
        if geometry is None:
            return super().lane_distance_to(other, lane)
        sx, sy, d0, d1 = geometry[0], geometry[1], geometry[2], geometry[3]
        ox, oy = other.position.tolist()
        px, py = self.position.tolist()
        return ((ox - sx) * d0 + (oy - sy) * d1) - ((px - sx) * d0 + (py - sy) * d1)

    def follow_road(self) -> None:
        """At the end of the target lane, switch to the next one (as the base class)."""
        target_lane_index: LaneIndex = getattr(self, "target_lane_index")  # noqa: B009 (typed)
        lane = self.road.network.get_lane(target_lane_index)
        geometry = _straight_geometry(lane)
        if geometry is None:
            after_end = lane.after_end(self.position)
        else:
            px, py = self.position.tolist()
            s = (px - geometry[0]) * geometry[2] + (py - geometry[1]) * geometry[3]
            after_end = s > geometry[6] - lane.VEHICLE_LENGTH / 2
        if after_end:
            self.target_lane_index = self.road.network.next_lane(
                target_lane_index,
                route=self.route,
                position=self.position,
                np_random=self.road.np_random,
            )

    def steering_control(self, target_lane_index: LaneIndex) -> float:
        """Steering angle [rad] to follow the centre of a lane (base-class result).

        :param target_lane_index: index of the lane to follow.
        :return: the steering wheel angle command [rad].
        """
        target_lane = self.road.network.get_lane(target_lane_index)
        geometry = _straight_geometry(target_lane)
        if geometry is None:
            s, r = target_lane.local_coordinates(self.position)
        else:
            px, py = self.position.tolist()
            dx = px - geometry[0]
            dy = py - geometry[1]
            s = dx * geometry[2] + dy * geometry[3]
            r = dx * geometry[4] + dy * geometry[5]
        speed = self.speed
        lane_future_heading = target_lane.heading_at(s + speed * self.TAU_PURSUIT)
        lateral_speed_command = -self.KP_LATERAL * r
        heading_command = _asin(_clip(lateral_speed_command / _not_zero(speed), -1, 1))
        heading_ref = lane_future_heading + _clip(heading_command, -np.pi / 4, np.pi / 4)
        heading_rate_command = self.KP_HEADING * utils.wrap_to_pi(heading_ref - self.heading)
        slip_angle = _asin(_clip(self.LENGTH / 2 / _not_zero(speed) * heading_rate_command, -1, 1))
        steering_angle = _atan(2 * _tan(slip_angle))
        return float(_clip(steering_angle, -self.MAX_STEERING_ANGLE, self.MAX_STEERING_ANGLE))


class FastIDMVehicle(FastControlledVehicle, IDMVehicle):
    """highway-env's ``IDMVehicle`` (IDM + MOBIL) with identical results, computed faster.

    Use it as ``other_vehicles_type = "aldm_gym.envs.traffic.FastIDMVehicle"``.
    ``act``, ``acceleration`` and ``desired_gap`` are the base code with numpy scalar
    calls replaced by the same float operations; MOBIL (``change_lane_policy``,
    ``mobil``) is inherited unchanged and benefits through these methods.
    """

    def step(self, dt: float) -> None:
        """Advance the lane-change timer, then the dynamics (``IDMVehicle.step``).

        :param dt: integration timestep [s].
        """
        self.timer += dt
        FastControlledVehicle.step(self, dt)

    def act(self, action: dict[str, float] | str | None = None) -> None:
        """Decide steering (MOBIL + lane following) and acceleration (IDM).

        :param action: ignored, as in ``IDMVehicle.act``.
        """
        if self.crashed:
            return
        command: dict[str, float] = {}
        self.follow_road()
        if self.enable_lane_change:
            self.change_lane_policy()
        steering = self.steering_control(self.target_lane_index)
        command["steering"] = _clip(steering, -self.MAX_STEERING_ANGLE, self.MAX_STEERING_ANGLE)
        front_vehicle, rear_vehicle = self.road.neighbour_vehicles(self, self.lane_index)
        acceleration = self.acceleration(
            ego_vehicle=self, front_vehicle=front_vehicle, rear_vehicle=rear_vehicle
        )
        # When changing lane, check both current and target lanes.
        if self.lane_index != self.target_lane_index:
            front_vehicle, rear_vehicle = self.road.neighbour_vehicles(self, self.target_lane_index)
            target_acceleration = self.acceleration(
                ego_vehicle=self, front_vehicle=front_vehicle, rear_vehicle=rear_vehicle
            )
            acceleration = min(acceleration, target_acceleration)
        command["acceleration"] = _clip(acceleration, -self.ACC_MAX, self.ACC_MAX)
        Vehicle.act(self, command)

    def acceleration(
        self,
        ego_vehicle: ControlledVehicle | None,
        front_vehicle: RoadObject | None = None,
        rear_vehicle: RoadObject | None = None,
    ) -> float:
        """IDM acceleration [m/s²] of ``ego_vehicle`` behind ``front_vehicle`` (base result).

        :param ego_vehicle: the vehicle whose acceleration is computed (any vehicle).
        :param front_vehicle: its leader, if any.
        :param rear_vehicle: unused, as in the base class.
        :return: the acceleration command [m/s²].
        """
        if not ego_vehicle or not isinstance(ego_vehicle, Vehicle):
            return 0
        ego_target_speed = getattr(ego_vehicle, "target_speed", 0)
        if ego_vehicle.lane and ego_vehicle.lane.speed_limit is not None:
            ego_target_speed = _clip(ego_target_speed, 0, ego_vehicle.lane.speed_limit)
        acceleration = self.COMFORT_ACC_MAX * (
            1 - _power(max(ego_vehicle.speed, 0) / abs(_not_zero(ego_target_speed)), self.DELTA)
        )
        if front_vehicle:
            d = ego_vehicle.lane_distance_to(front_vehicle)
            ratio = self.desired_gap(ego_vehicle, front_vehicle) / _not_zero(d)
            # np.power(x, 2) is computed as x * x.
            acceleration -= self.COMFORT_ACC_MAX * (ratio * ratio)
        return acceleration

    def desired_gap(
        self,
        ego_vehicle: Vehicle,
        front_vehicle: RoadObject | None = None,
        projected: bool = True,
    ) -> float:
        """Desired distance [m] to the leader (IDM ``s*``, base-class result).

        :param ego_vehicle: the following vehicle.
        :param front_vehicle: its leader.
        :param projected: project the velocity difference on the ego heading.
        :return: the desired gap [m].
        """
        assert front_vehicle is not None
        if projected and not (
            _uses_base_kinematics(ego_vehicle) and _uses_base_kinematics(front_vehicle)
        ):
            return float(super().desired_gap(ego_vehicle, front_vehicle, projected))
        d0 = self.DISTANCE_WANTED
        tau = self.TIME_WANTED
        ab = -self.COMFORT_ACC_MAX * self.COMFORT_ACC_MIN
        ego_speed = ego_vehicle.speed
        if projected:
            # np.dot(ego.velocity - front.velocity, ego.direction), term by term.
            cos_e = _cos(ego_vehicle.heading)
            sin_e = _sin(ego_vehicle.heading)
            front_speed = front_vehicle.speed
            dvx = ego_speed * cos_e - front_speed * _cos(front_vehicle.heading)
            dvy = ego_speed * sin_e - front_speed * _sin(front_vehicle.heading)
            dv = dvx * cos_e + dvy * sin_e
        else:
            dv = ego_speed - front_vehicle.speed
        return d0 + ego_speed * tau + ego_speed * dv / (2 * math.sqrt(ab))


_STEPS_ENDING_WITH_UPDATE = frozenset(
    {Vehicle.step, FastControlledVehicle.step, FastIDMVehicle.step}
)
"""``step`` methods whose last action is ``self.on_state_update()`` (nothing after it
reads the lane), so :meth:`FastRoad.step` may defer that call."""


def use_fast_road(env: Any) -> AbstractEnv:
    """Make a highway-env environment simulate on a :class:`FastRoad`.

    The env's ``_create_road`` is wrapped (on the instance) so that every road it
    creates on ``reset`` is rewrapped with :meth:`FastRoad.from_road` before vehicles
    are added; the current road, if any, is converted too. Works through Gymnasium
    wrappers.

    :param env: a highway-env environment (``AbstractEnv``), possibly wrapped.
    :return: the unwrapped environment.
    """
    base = env.unwrapped
    if getattr(base, "_fast_road_installed", False):
        return base
    create_road = base._create_road

    def _create_fast_road() -> None:
        create_road()
        base.road = FastRoad.from_road(base.road)

    base._create_road = _create_fast_road
    base._fast_road_installed = True
    if base.road is not None:
        base.road = FastRoad.from_road(base.road)
    return base
