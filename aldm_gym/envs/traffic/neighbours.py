"""The neighbour cache: ``Road.neighbour_vehicles``'s answers by bisection.

highway-env answers every neighbour query by projecting *every* road object onto the
queried lane, and IDM/MOBIL vehicles query several times per simulation step: O(n²)
Python-level lane projections (highway-env issues #36, #121, #223). Here, once per
cache epoch (lazily, per queried lane), every road object is projected onto the lane
in one vectorised pass (``lane.local_coordinates_many`` when the lane offers it; one
pass for a whole edge of plain ``StraightLane`` lanes or of
:class:`~aldm_gym.roads.lane.ReferenceLane` lanes sharing a reference line; one
compiled pass of ``lane.neighbour_table`` for a lane that sorts its objects itself, as
a map's lanes do), the on-lane objects are sorted by longitudinal coordinate, and each
query is a bisection.
Ties are broken as in the base loop (front: the *last* object in
``vehicles + objects`` order among equal ``s``; rear: the *first*).

The owner (:class:`~aldm_gym.envs.traffic.road.FastRoad`) ends an epoch with
:meth:`NeighbourCache.invalidate` whenever positions may have changed; a change of the
``vehicles``/``objects`` membership is noticed by the cache itself.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from collections.abc import Callable
from typing import Any

import numpy as np
from highway_env.road.lane import AbstractLane, StraightLane
from highway_env.road.road import LaneIndex, Road
from highway_env.vehicle.objects import Landmark, RoadObject

from aldm_gym.envs.traffic.straight_lanes import is_plain_straight
from aldm_gym.roads.lane import ReferenceLane
from aldm_gym.types import BoolArray, FloatArray

__all__ = ["NeighbourCache"]

_NEIGHBOUR_MARGIN = 1.0
"""Lateral margin [m] of ``Road.neighbour_vehicles``'s ``on_lane(..., margin=1)``."""


def _uses_default_on_lane(lane: AbstractLane) -> bool:
    """Whether ``lane.on_lane`` is ``AbstractLane.on_lane`` (so it can be vectorised)."""
    return type(lane).on_lane is AbstractLane.on_lane


class _LaneTable:
    """Longitudinal coordinates of every road object on one lane, for one epoch.

    ``s`` has shape ``(N,)`` [m] and follows the cache's object order; ``on_lane`` is
    the ``on_lane(..., margin=1)`` mask. With ``lazy``, a NaN in ``s`` means "not
    computed" (the object is off the lane, too far to be projected). A compiled table
    (:meth:`NeighbourCache._compiled_table`) also keeps ``on_rows``, the on-lane
    object indices, and ``s_list``, ``s`` as Python floats.
    """

    __slots__ = ("lazy", "on_lane", "on_rows", "s", "s_list")

    def __init__(
        self,
        s: FloatArray,
        on_lane: BoolArray,
        lazy: bool = False,
        on_rows: list[int] | None = None,
        s_list: list[float] | None = None,
    ) -> None:
        self.s = s
        self.on_lane = on_lane
        self.lazy = lazy
        self.on_rows = on_rows
        self.s_list = s_list


class _SortedNeighbours:
    """On-lane objects of one query lane sorted by effective longitudinal coordinate.

    ``keys`` [m] ascending; ties keep object order (stable sort), which the bisection
    queries rely on for the base loop's tie-breaking. ``query_s`` [m] is every cached
    object's coordinate on the query lane; with ``lazy``, a NaN there means "not
    computed" (the object is far from the lane) and the query projects it itself.
    """

    __slots__ = ("keys", "lazy", "objects", "query_s")

    def __init__(
        self,
        keys: list[float],
        objects: list[RoadObject],
        query_s: list[float],
        lazy: bool = False,
    ) -> None:
        self.keys = keys
        self.objects = objects
        self.query_s = query_s
        self.lazy = lazy


class NeighbourCache:
    """Per-epoch sorted neighbour tables of a road; answers ``neighbour_vehicles``.

    An epoch lasts until :meth:`invalidate` is called or the road's ``vehicles`` /
    ``objects`` lists change membership; its tables are built lazily, per queried lane.

    :param road: the road whose ``vehicles``, ``objects``, ``network`` and
        ``neighbour_vehicles_connected_lanes`` are read (on every query, so the road
        may replace its lists).
    """

    def __init__(self, road: Road) -> None:
        """Create an empty cache for ``road``; see the class docstring."""
        self.road = road
        self.valid = False
        self._reset()

    def invalidate(self) -> None:
        """End the epoch: the next query rebuilds the tables."""
        self.valid = False

    def _reset(self) -> None:
        """Start a new epoch (called lazily on the first query after invalidation)."""
        self.valid = False
        self._vehicles: list[RoadObject] = []
        self._objects: list[RoadObject] = []
        self._items: list[RoadObject] = []
        self._index: dict[int, int] = {}
        self._positions: FloatArray = np.zeros((0, 2))
        self._lane_tables: dict[int, _LaneTable] = {}
        self._sorted: dict[tuple[LaneIndex, bool], _SortedNeighbours] = {}

    def _ensure(self) -> None:
        """Rebuild the epoch's object list and positions if the cache is not valid."""
        road = self.road
        if self.valid and self._vehicles == road.vehicles and self._objects == road.objects:
            return
        self._reset()
        self._vehicles = list(road.vehicles)
        self._objects = list(road.objects)
        # Same population and order as the base loop over `vehicles + objects`.
        items = [o for o in self._vehicles + self._objects if not isinstance(o, Landmark)]
        self._items = items
        self._index = {id(o): i for i, o in enumerate(items)}
        if items:
            self._positions = np.array([o.position for o in items], dtype=np.float64).reshape(-1, 2)
        self.valid = True

    def neighbours(
        self, vehicle: RoadObject, lane_index: LaneIndex
    ) -> tuple[RoadObject | None, RoadObject | None]:
        """Preceding and following objects of ``vehicle`` on a lane (``Road``'s result).

        :param vehicle: the vehicle whose neighbours must be found.
        :param lane_index: the lane to search (not empty); the vehicle is projected
            onto it.
        :return: ``(front, rear)``, either of which may be None.
        """
        road = self.road
        # _ensure's and _sorted_neighbours' fast checks inlined (tens of queries per
        # simulation step).
        if not (self.valid and self._vehicles == road.vehicles and self._objects == road.objects):
            self._ensure()
        entry = self._sorted.get((lane_index, bool(road.neighbour_vehicles_connected_lanes)))
        if entry is None:
            entry = self._sorted_neighbours(lane_index)
        i = self._index.get(id(vehicle))
        if i is not None and self._items[i] is vehicle:
            s = entry.query_s[i]
            if s != s and entry.lazy:
                s = float(road.network.get_lane(lane_index).local_coordinates(vehicle.position)[0])
        else:
            s = float(road.network.get_lane(lane_index).local_coordinates(vehicle.position)[0])
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

    def _lane_table(self, lane: AbstractLane) -> _LaneTable:
        """Coordinates and on-lane mask of every cached object on ``lane`` (O(N))."""
        table = self._lane_tables.get(id(lane))
        if table is not None:
            return table
        positions = self._positions
        n = len(self._items)
        if n == 0:
            empty = np.zeros(0)
            table = _LaneTable(empty, np.zeros(0, dtype=bool))
        elif is_plain_straight(lane):
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
            table = _LaneTable(s, on)
        elif (fast := self._compiled_table(lane)) is not None:
            table = _LaneTable(fast[0], fast[1], True, fast[2].tolist(), fast[0].tolist())
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
            table = _LaneTable(s, on)
        self._lane_tables[id(lane)] = table
        return table

    def _search_lanes(self, lane_index: LaneIndex) -> list[tuple[AbstractLane, float]]:
        """Lanes searched for neighbours and their offsets, as in ``Road.neighbour_vehicles``."""
        network = self.road.network
        lane = network.get_lane(lane_index)
        lanes_offsets: list[tuple[AbstractLane, float]] = [(lane, 0)]
        if self.road.neighbour_vehicles_connected_lanes:
            _from, _to, _id = lane_index
            for next_lanes in network.graph.get(_to, {}).values():
                if _id < len(next_lanes):
                    lanes_offsets.append((next_lanes[_id], lane.length))
                elif next_lanes:
                    lanes_offsets.append((next_lanes[0], lane.length))
            for to_dict in network.graph.values():
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
        connected = bool(self.road.neighbour_vehicles_connected_lanes)
        key = (lane_index, connected)
        entry = self._sorted.get(key)
        if entry is not None:
            return entry
        if not connected and (
            self._build_ordered_lane(lane_index)
            or self._build_straight_edge(lane_index)
            or self._build_reference_edge(lane_index)
        ):
            return self._sorted[key]
        lanes_offsets = self._search_lanes(lane_index)
        primary = self._lane_table(lanes_offsets[0][0])
        if primary.on_rows is not None:
            tables = [self._lane_table(lane) for lane, _ in lanes_offsets]
            if all(table.on_rows is not None for table in tables):
                entry = self._merge_compiled(tables, [offset for _, offset in lanes_offsets])
                self._sorted[key] = entry
                return entry
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
            lazy=primary.lazy,
        )
        self._sorted[key] = entry
        return entry

    def _merge_compiled(self, tables: list[_LaneTable], offsets: list[float]) -> _SortedNeighbours:
        """The generic merge of :meth:`_sorted_neighbours` on compiled tables, in Python.

        Each object is matched on the first searched lane it is on, its coordinate
        shifted by that lane's offset (not shifted with a single lane, as there); the
        objects are sorted by coordinate, ties in object order (a stable argsort over
        ascending object indices). A few objects per lane: cheaper than the numpy
        version over every object.
        """
        matched: dict[int, float] = {}
        if len(tables) == 1:
            s_list = tables[0].s_list
            assert s_list is not None and tables[0].on_rows is not None
            for k in tables[0].on_rows:
                matched[k] = s_list[k]
        else:
            for table, offset in zip(tables, offsets, strict=True):
                s_list = table.s_list
                assert s_list is not None and table.on_rows is not None
                for k in table.on_rows:
                    if k not in matched:
                        matched[k] = s_list[k] + offset
        # (coordinate, index) tuples: ties in object order; coordinates are never NaN
        # (on-lane objects pass comparisons).
        pairs = sorted([(key, k) for k, key in matched.items()])
        items = self._items
        primary_s = tables[0].s_list
        assert primary_s is not None
        return _SortedNeighbours(
            keys=[key for key, _ in pairs],
            objects=[items[k] for _, k in pairs],
            query_s=primary_s,
            lazy=True,
        )

    def _edge_lanes(
        self, lane_index: LaneIndex, qualifies: Callable[[AbstractLane], bool]
    ) -> list[AbstractLane] | None:
        """The lanes of ``lane_index``'s edge if it exists and every lane qualifies, else None."""
        _from, _to, _ = lane_index
        try:
            lanes = self.road.network.graph[_from][_to]
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
        lanes = self._edge_lanes(lane_index, is_plain_straight)
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
            self._lane_tables[id(lane)] = _LaneTable(s[i], on[i])
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

    def _compiled_table(self, lane: AbstractLane) -> tuple[Any, ...] | None:
        """``lane.neighbour_table(positions, margin)`` if the lane offers and accepts it.

        Lanes with their own centre line (a map's
        :class:`~aldm_gym.roads.map_network.MapLane`) share nothing with their
        siblings, but on a long map most objects are far from any one lane: the lane
        projects only the objects within reach, applies ``on_lane(margin=1)`` and
        sorts, in one compiled pass: ``(s, on, order)``, NaN ``s`` for objects not
        projected (off the lane; a query projects itself if it needs its own ``s``).
        """
        table_of: Callable[[FloatArray, float], Any] | None = getattr(lane, "neighbour_table", None)
        if table_of is None or not self._items:
            return None
        result: tuple[Any, ...] | None = table_of(self._positions, _NEIGHBOUR_MARGIN)
        return result

    def _build_ordered_lane(self, lane_index: LaneIndex) -> bool:
        """Sorted neighbours of a lane with a compiled table (:meth:`_compiled_table`).

        Only when searched without connected lanes; the order comes with the table.
        The answers are those of the generic path (``lazy``: a query projects itself
        when its ``s`` was not computed).

        :return: False (nothing built) if the lane has no compiled table.
        """
        lane = self.road.network.get_lane(lane_index)
        table = self._compiled_table(lane)
        if table is None:
            return False
        s, on, order = table
        order_list = order.tolist()
        s_list = s.tolist()
        self._lane_tables[id(lane)] = _LaneTable(s, on, True, order_list, s_list)
        items = self._items
        self._sorted[(lane_index, False)] = _SortedNeighbours(
            keys=[s_list[k] for k in order_list],
            objects=[items[k] for k in order_list],
            query_s=s_list,
            lazy=True,
        )
        return True
