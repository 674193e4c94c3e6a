"""Which way an entity goes where its lane splits.

A lane that continues into more than one lane (a junction whose connections leave
from one lane towards two roads: an exit that branches off a through lane) is a
*split*. Without a route, an entity takes the road's
:meth:`~aldm_gym.roads.map_road.OpenDriveRoad.successor` there: the straightest
branch (esmini's first choice too). A route decides otherwise:

- :class:`RoutePlan` (``AssignRouteAction``, ``AcquirePositionAction`` and
  ``RoutePosition``) takes, at each split, the branch with the shortest drive along
  lane successors to the road of its next waypoint not reached yet (a waypoint is
  reached once the entity is on its road, and so is every waypoint before it; of two
  branches as near, the straightest). A waypoint no branch leads to (it needs a lane
  change, which a route does not make) is passed over for the next one; with none
  left, it takes the straightest branch.
- :class:`RandomRoute` (``RandomRouteAction``) takes a branch drawn with equal
  chances at each split, from its own generator (seeded from the episode's, so the
  same seed takes the same branches).
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = [
    "SEARCH_LIMIT",
    "Chooser",
    "RandomRoute",
    "RoutePlan",
    "drive_to",
    "next_lane",
    "reachable_lanes",
    "reachable_roads",
]

LaneKey = Any
"""A driving lane of the map: ``(road id, section index, lane id)``."""

SEARCH_LIMIT = 100_000
"""Lanes a route search visits at most (a bound on a map's size, not on a route)."""


class Chooser:
    """Chooses the branch at a split; the base takes the road's straightest."""

    def choose(self, road: Any, lane: LaneKey, options: Sequence[LaneKey]) -> LaneKey:
        """The lane to take after ``lane`` among ``options`` (its successors, more than
        one)."""
        return road.successor(lane)

    def reached(self, road_id: str) -> None:
        """The entity is on a lane of road ``road_id`` now."""


class RoutePlan(Chooser):
    """A route through its waypoints' roads (see the module docstring).

    :param roads: the roads of the waypoints, in order.
    """

    def __init__(self, roads: Sequence[str]) -> None:
        """See the class docstring."""
        self.pending = list(roads)
        self._distances: dict[tuple[LaneKey, str], float] = {}

    def reached(self, road_id: str) -> None:
        """The entity is on road ``road_id``: the waypoints up to the first on it are
        behind it."""
        if road_id in self.pending:
            del self.pending[: self.pending.index(road_id) + 1]

    def choose(self, road: Any, lane: LaneKey, options: Sequence[LaneKey]) -> LaneKey:
        """The branch nearest the next waypoint's road; the straightest if none leads
        there or every waypoint is reached."""
        straight = road.successor(lane)
        for goal in self.pending:  # the first waypoint a branch leads to
            # the straightest branch unless another is nearer
            best, best_d = straight, self.distance(road, straight, goal)
            for option in options:
                d = self.distance(road, option, goal)
                if d < best_d:
                    best, best_d = option, d
            if best_d < np.inf:
                return best
        return straight

    def distance(self, road: Any, lane: LaneKey, goal: str) -> float:
        """The drive [m] from the start of ``lane`` along lane successors to the start
        of a lane on road ``goal`` (0 when ``lane`` is on it; inf: none leads there)."""
        key = (lane, goal)
        if key not in self._distances:
            self._distances[key] = drive_to(road, lane, goal)
        return self._distances[key]


class RandomRoute(Chooser):
    """A branch drawn with equal chances at each split.

    :param rng: the generator it draws from.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        """See the class docstring."""
        self.rng = rng

    def choose(self, road: Any, lane: LaneKey, options: Sequence[LaneKey]) -> LaneKey:
        """One of ``options``, each as likely."""
        return options[int(self.rng.integers(len(options)))]


def next_lane(road: Any, route: Chooser | None, lane: LaneKey) -> LaneKey | None:
    """The lane after ``lane`` (None: the chain ends): where it splits, ``route``'s
    choice, else (or without a route) the road's straightest successor."""
    if route is None:
        return road.successor(lane)
    route.reached(road.lane_record(lane).road_id)
    options = road.successors(lane)
    if len(options) > 1:
        nxt = route.choose(road, lane, options)
    else:
        nxt = options[0] if options else None
    if nxt is not None:
        route.reached(road.lane_record(nxt).road_id)
    return nxt


def drive_to(road: Any, lane: LaneKey, goal: str) -> float:
    """The shortest drive [m] from the start of ``lane`` along lane successors to the
    start of a lane on road ``goal`` (Dijkstra on the lanes' lengths; inf: none)."""
    todo: list[tuple[float, int, LaneKey]] = [(0.0, 0, lane)]
    seen: set[LaneKey] = set()
    tie = 0
    while todo and len(seen) < SEARCH_LIMIT:
        d, _, key = heapq.heappop(todo)
        if key in seen:
            continue
        seen.add(key)
        if road.lane_record(key).road_id == goal:
            return d
        length = road.lane_length(key)
        for nxt in road.successors(key):
            if nxt not in seen:
                tie += 1
                heapq.heappush(todo, (d + length, tie, nxt))
    return float("inf")


def reachable_lanes(road: Any, lanes: Sequence[LaneKey]) -> list[LaneKey]:
    """The lanes reachable from ``lanes`` (themselves included) along every branch of
    their successors."""
    out, todo, seen = [], list(lanes), set(lanes)
    while todo and len(seen) < SEARCH_LIMIT:
        key = todo.pop()
        out.append(key)
        for nxt in road.successors(key):
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return out


def reachable_roads(road: Any, lanes: Sequence[LaneKey]) -> set[str]:
    """The roads of :func:`reachable_lanes`."""
    return {road.lane_record(k).road_id for k in reachable_lanes(road, lanes)}
