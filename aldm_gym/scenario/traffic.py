"""Generated traffic: ``TrafficSwarmAction``, ``TrafficSourceAction``,
``TrafficSinkAction``, ``TrafficAreaAction`` and ``TrafficStopAction``.

OpenSCENARIO leaves the generated vehicles' behaviour to the tool ("controlled by the
simulator's default traffic"): here they are the env's own map traffic (the runner's
``traffic_vehicle``: in the env :class:`~aldm_gym.envs.vehicle.MapIDMVehicle`,
highway-env's IDM and MOBIL with the mandatory merge), placed on a driving lane's
centre, heading along it. Their draws
(where, which category, how fast) come from the episode's generator, so a seed gives
the same traffic. They are not scenario objects: no condition or action names them;
they are vehicles of the road, which the function under test senses and can hit.

* A **swarm** keeps ``numberOfVehicles`` vehicles in the ring between the circle of
  ``innerRadius`` around its central object and the ellipse of semi-axes
  ``semiMajorAxis`` (along the central object's heading) and ``semiMinorAxis``, centred
  ``offset`` ahead of it: each step it removes its vehicles outside the ellipse and
  places new ones in the ring (a few tries per step) where they keep a gap to every
  vehicle. ``DirectionOfTravelDistribution`` weighs lanes driven the central object's
  way against the others (default: its way only).
* A **source** places a vehicle within ``radius`` of its position every ``1 / rate``
  seconds (a blocked place is tried again the next step), :data:`MAX_GENERATED` in all.
* A **sink** removes the generated vehicles within ``radius`` of its position, at most
  ``rate`` per second (all, without ``rate``). Scenario objects are never removed.
* An **area** (1.3) keeps ``numberOfEntities`` vehicles on its road ranges (the roads
  between consecutive road cursors, :func:`road_ranges`) or in its polygon:
  ``continuous``, those that leave are removed and replaced; else that many are
  placed once.
* **TrafficStopAction** ends the traffic action of its ``trafficName``; the vehicles it
  generated drive on.

A generating action runs until the storyboard stops it (as esmini plays swarms).
The speed of a new vehicle: uniform in ``InitialSpeedRange``, else the action's
``velocity`` (``speed`` of a source), else 70-80 % of the lane's speed limit (as the
env's map traffic). Its size: its category's (``VehicleCategoryDistribution``, drawn
by weight; :data:`CATEGORY_SIZES`), or its entity template's (a 1.3
``TrafficDistribution``: the template's ``vehicleCategory`` and bounding box, drawn
by the entry's weight times the template's share of its ``EntityDistribution``).
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.errors import InputError, ScenarioError

__all__ = [
    "CATEGORY_SIZES",
    "MAX_GENERATED",
    "MAX_SPEED",
    "Area",
    "Cursor",
    "Sink",
    "Source",
    "Swarm",
    "TrafficDefinition",
    "road_ranges",
]

CATEGORY_SIZES: dict[str, tuple[float, float]] = {
    "car": (5.0, 2.0),
    "van": (5.5, 2.1),
    "truck": (12.0, 2.55),
    "semitrailer": (16.5, 2.55),
    "trailer": (12.0, 2.55),
    "bus": (12.0, 2.55),
    "motorbike": (2.2, 0.8),
    "bicycle": (1.8, 0.6),
    "train": (20.0, 2.8),
    "tram": (20.0, 2.65),
}
"""Length and width [m] of a generated vehicle by OpenSCENARIO ``vehicleCategory``."""

MAX_GENERATED = 200
"""The most vehicles one action keeps or places (``numberOfVehicles`` above is an
error): each is a highway-env vehicle stepped at the simulation rate."""

MAX_SPEED = 100.0
"""The fastest a generated vehicle starts [m/s] (a faster one is an error)."""

TRIES_PER_STEP = 5
"""Places a swarm tries per step to fill its ring (a blocked one is left for later)."""

GAP_TIME = 0.5
"""Time gap [s] a new vehicle keeps to every vehicle at its speed, at least
:data:`MIN_GAP` [m] between the boxes."""

MIN_GAP = 2.0
"""Least distance [m] between a new vehicle's box and another's (bumper to bumper)."""


def _in_unit_disc(rng: np.random.Generator) -> tuple[float, float]:
    """A point uniform in the unit disc, in polar coordinates ``(r, phi [rad])``."""
    r = math.sqrt(float(rng.uniform()))
    return r, float(rng.uniform(0.0, 2.0 * math.pi))


@dataclass(frozen=True)
class TrafficDefinition:
    """The vehicles to draw, with their weights: a ``TrafficDefinition``'s categories,
    or a ``TrafficDistribution``'s entity templates (1.3) with their own sizes.

    :ivar categories: ``(vehicleCategory, weight)`` pairs, weights > 0.
    :ivar sizes: per category entry its ``(length, width)`` [m]; empty: the
        category's (:data:`CATEGORY_SIZES`).
    """

    categories: tuple[tuple[str, float], ...] = (("car", 1.0),)
    sizes: tuple[tuple[float, float], ...] = ()

    def draw(self, rng: np.random.Generator) -> tuple[str, float, float]:
        """One vehicle, drawn by weight: ``(category, length [m], width [m])``."""
        weights = np.array([w for _, w in self.categories], dtype=float)
        i = int(rng.choice(len(weights), p=weights / weights.sum()))
        category = self.categories[i][0]
        length, width = self.sizes[i] if self.sizes else CATEGORY_SIZES[category]
        return category, length, width


@dataclass
class _Generator:
    """What every generating action shares: its definition, speeds, and vehicles."""

    name: str
    definition: TrafficDefinition
    speed_range: tuple[float, float] | None = None
    speed: float | None = None

    def __post_init__(self) -> None:
        self.vehicles: list[Any] = []
        # the next vehicle (category, length, width), kept until placed
        self.pending: tuple[str, float, float] | None = None

    def _speed(self, rng: np.random.Generator, lane: Any) -> float:
        if self.speed_range is not None:
            lo, hi = self.speed_range
            return float(rng.uniform(lo, hi))
        if self.speed is not None:
            return float(self.speed)
        limit = float(getattr(lane, "speed_limit", None) or 30.0)
        return float(rng.uniform(0.7 * limit, 0.8 * limit))

    def _place(
        self,
        runner: Any,
        rng: np.random.Generator,
        point: np.ndarray,
        heading_to_match: float | None = None,
        same_share: float = 1.0,
    ) -> bool:
        """Put a new vehicle on the driving lane nearest ``point`` (on its centre), if
        it keeps its gap to every vehicle; whether it did. With ``heading_to_match``,
        a lane driven that way is taken with probability ``same_share`` and one driven
        the other way otherwise."""
        world = runner.world
        try:
            pos = world.road.lane_position(point)
        except InputError:
            return False  # off the map
        if not math.isfinite(pos.s):
            return False
        key = pos.lane
        u = pos.s - world.road.chain_start(key)
        lane = world.lane(key)
        if not 0.0 <= u <= lane.length:
            return False
        if heading_to_match is not None:
            same = math.cos(float(lane.heading_at(u)) - heading_to_match) > 0.0
            want_same = rng.uniform() < same_share
            if same != want_same:
                return False
        if self.pending is None:
            self.pending = self.definition.draw(rng)
        category, length, width = self.pending
        speed = self._speed(rng, lane)
        where = np.asarray(lane.position(u, 0.0), dtype=float)
        road = runner.traffic
        for other in road.vehicles:
            gap = float(np.hypot(*(np.asarray(other.position) - where)))
            room = (length + float(getattr(other, "LENGTH", 5.0))) / 2
            if gap < room + max(MIN_GAP, GAP_TIME * max(speed, float(other.speed))):
                return False
        v = runner.traffic_vehicle(road, where, float(lane.heading_at(u)), speed)
        randomize = getattr(v, "randomize_behavior", None)
        if callable(randomize):
            randomize()  # as the env's map traffic (drawn from the road's generator)
        v.LENGTH, v.WIDTH = length, width
        v.diagonal = float(np.hypot(length, width))
        v.target_speed = speed
        v.generated_by = self.name
        v.category = category
        road.vehicles.append(v)
        self.vehicles.append(v)
        self.pending = None
        return True

    def _forget_gone(self, runner: Any) -> None:
        """Drop the vehicles no longer on the road (removed by a sink)."""
        on_road = {id(v) for v in runner.traffic.vehicles}
        self.vehicles = [v for v in self.vehicles if id(v) in on_road]


@dataclass
class Swarm(_Generator):
    """``TrafficSwarmAction`` (see the module docstring).

    :ivar central: the central object's name.
    :ivar inner_radius: [m].
    :ivar semi_major, semi_minor: the ellipse's semi-axes [m].
    :ivar offset: the ellipse's centre ahead of the central object [m].
    :ivar count: the vehicles kept.
    :ivar same_share: the share of lanes driven the central object's way.
    """

    central: str = ""
    inner_radius: float = 0.0
    semi_major: float = 0.0
    semi_minor: float = 0.0
    offset: float = 0.0
    count: int = 0
    same_share: float = 1.0

    def _frame(self, runner: Any) -> tuple[np.ndarray, float] | None:
        entity = runner.world.entities[self.central]
        if not entity.present or entity.vehicle is None:
            return None
        return np.asarray(entity.vehicle.position, dtype=float), float(entity.vehicle.heading)

    def _inside(self, centre: np.ndarray, heading: float, point: np.ndarray) -> bool:
        d = point - centre
        c, s = math.cos(heading), math.sin(heading)
        along = d[0] * c + d[1] * s - self.offset
        across = -d[0] * s + d[1] * c
        return (along / self.semi_major) ** 2 + (across / self.semi_minor) ** 2 <= 1.0

    def step(self, runner: Any, rng: np.random.Generator, dt: float) -> None:
        """Remove this swarm's vehicles outside the ellipse; fill the ring."""
        self._forget_gone(runner)
        frame = self._frame(runner)
        if frame is None:
            return
        centre, heading = frame
        road = runner.traffic
        for v in list(self.vehicles):
            if not self._inside(centre, heading, np.asarray(v.position, dtype=float)):
                road.vehicles.remove(v)
                self.vehicles.remove(v)
        c, s = math.cos(heading), math.sin(heading)
        for _ in range(TRIES_PER_STEP):
            if len(self.vehicles) >= self.count:
                break
            # a point uniform in the ellipse, kept where it is outside the inner circle
            r, phi = _in_unit_disc(rng)
            along = self.offset + self.semi_major * r * math.cos(phi)
            across = self.semi_minor * r * math.sin(phi)
            point = centre + np.array([along * c - across * s, along * s + across * c])
            if float(np.hypot(*(point - centre))) < self.inner_radius:
                continue
            self._place(runner, rng, point, heading, self.same_share)


@dataclass
class Source(_Generator):
    """``TrafficSourceAction`` (see the module docstring).

    :ivar point: the source's position (highway-env's frame) [m].
    :ivar radius: [m].
    :ivar rate: vehicles per second.
    :ivar started: the time it started [s].
    """

    point: Any = None
    radius: float = 0.0
    rate: float = 0.0
    started: float = 0.0
    placed: int = 0

    def step(self, runner: Any, rng: np.random.Generator, dt: float) -> None:
        """Place the next vehicle once it is due (and the place is free)."""
        self._forget_gone(runner)
        if self.placed >= MAX_GENERATED:
            return
        if runner.world.time + 1e-9 < self.started + self.placed / self.rate:
            return
        r, phi = _in_unit_disc(rng)
        r = self.radius * r
        point = np.asarray(self.point, dtype=float) + r * np.array([math.cos(phi), math.sin(phi)])
        if self._place(runner, rng, point):
            self.placed += 1


@dataclass
class Sink(_Generator):
    """``TrafficSinkAction`` (see the module docstring).

    :ivar point: the sink's position (highway-env's frame) [m].
    :ivar radius: [m].
    :ivar rate: vehicles removed per second at most (inf: all).
    """

    point: Any = None
    radius: float = 0.0
    rate: float = math.inf
    budget: float = 0.0

    def step(self, runner: Any, rng: np.random.Generator, dt: float) -> None:
        """Remove the generated vehicles inside the radius (at most ``rate`` a second)."""
        # what it may remove now: its rate over this step, and at least one vehicle
        # (an idle sink saves nothing up)
        self.budget = min(self.budget + self.rate * dt, max(1.0, self.rate * dt))
        road = runner.traffic
        centre = np.asarray(self.point, dtype=float)
        for v in list(road.vehicles):
            if self.budget < 1.0:
                break
            if getattr(v, "generated_by", None) is None:
                continue  # a scenario object or the function under test
            if float(np.hypot(*(np.asarray(v.position, dtype=float) - centre))) <= self.radius:
                road.vehicles.remove(v)
                self.budget -= 1.0


@dataclass
class Area(_Generator):
    """``TrafficAreaAction`` (1.3): ``count`` vehicles in an area, placed where they
    keep their gaps; ``continuous``: the vehicles that leave the area are removed and
    replaced for as long as the action runs, else ``count`` are placed once and drive
    on.

    :ivar ranges: the area as road ranges: ``(road id, s from, s to [m], lane ids or
        () for every driving lane)``.
    :ivar polygon: or as a polygon's corners ``(K, 2)`` (highway-env's frame) [m].
    """

    count: int = 0
    continuous: bool = False
    ranges: tuple[tuple[str, float, float, tuple[int, ...]], ...] = ()
    polygon: Any = None
    placed: int = 0

    def _inside(self, runner: Any, point: np.ndarray) -> bool:
        if self.polygon is not None:
            return _in_polygon(np.asarray(self.polygon, dtype=float), point)
        road = runner.world.road
        try:
            pos = road.lane_position(point)
        except InputError:
            return False
        rec = road.lane_record(pos.lane)
        s = road.reference_s(pos.lane, pos.s - road.chain_start(pos.lane))
        return any(
            rec.road_id == rid and lo - 1e-6 <= s <= hi + 1e-6 and (not ids or rec.lane_id in ids)
            for rid, lo, hi, ids in self.ranges
        )

    def _sample(self, runner: Any, rng: np.random.Generator) -> np.ndarray | None:
        world = runner.world
        if self.polygon is not None:
            corners = np.asarray(self.polygon, dtype=float)
            lo, hi = corners.min(axis=0), corners.max(axis=0)
            point = lo + rng.uniform(size=2) * (hi - lo)
            try:  # where the vehicle would stand: on the nearest lane's centre
                pos = world.road.lane_position(point)
            except InputError:
                return None
            u = pos.s - world.road.chain_start(pos.lane)
            centre, _ = world.pose(pos.lane, u, 0.0)
            return point if _in_polygon(corners, np.asarray(centre, dtype=float)) else None
        spans = np.array([hi - lo for _, lo, hi, _ in self.ranges], dtype=float)
        k = int(rng.choice(len(spans), p=spans / spans.sum())) if spans.sum() > 0 else 0
        road_id, lo, hi, ids = self.ranges[k]
        s = float(rng.uniform(lo, hi))
        road = world.road
        keys = []
        for key in road.lanes:  # the driving lanes there (of the ids given)
            rec = road.lane_record(key)
            if rec.road_id == road_id and rec.s0 - 1e-9 <= s <= rec.s1 + 1e-9:
                if not ids or rec.lane_id in ids:
                    keys.append(key)
        if not keys:
            return None
        key = keys[int(rng.integers(len(keys)))]
        point, _ = world.pose(key, road.lane_u(key, s), 0.0)
        return np.asarray(point, dtype=float)

    def step(self, runner: Any, rng: np.random.Generator, dt: float) -> None:
        """Continuous: remove the vehicles outside the area; place up to ``count``."""
        self._forget_gone(runner)
        road = runner.traffic
        if self.continuous:
            for v in list(self.vehicles):
                if not self._inside(runner, np.asarray(v.position, dtype=float)):
                    road.vehicles.remove(v)
                    self.vehicles.remove(v)
        for _ in range(TRIES_PER_STEP):
            if len(self.vehicles) >= self.count or (
                not self.continuous and self.placed >= self.count
            ):
                break
            point = self._sample(runner, rng)
            if point is not None and self._place(runner, rng, point):
                self.placed += 1


Cursor = tuple[str, "float | None", tuple[int, ...]]
"""A ``RoadCursor``: road id, ``s`` [m] (None: not given), lane ids (() for all)."""


def road_ranges(
    road: Any, specs: list[tuple[float, list[Cursor]]], where: str
) -> tuple[tuple[str, float, float, tuple[int, ...]], ...]:
    """The ``RoadRange``s of a traffic area as ``(road id, s from, s to [m], lane ids)``
    pieces on ``road``'s map, each range ``(length [m], cursors)`` cut after ``length``
    of road (counted from its first cursor, in its direction of travel).

    Between two cursors on one road the range is the road between their ``s``, on the
    first cursor's lanes. Between cursors on two roads it runs from the first along
    the roads that join them (through lane links, with the traffic or against it,
    never turning back at a fork) to the second: the first cursor's road from its
    ``s`` to where the range leaves it, on that cursor's lanes; every road between,
    and the second's up to its ``s``, whole across (a lane id of one road names
    another lane on the next). A cursor without ``s`` takes in its whole road. A piece
    two pairs share is counted once.

    :raises ScenarioError: an unknown road, an ``s`` off its road, two roads no lanes
        join, or ranges that cover no road.
    """
    odr = road.map
    out: list[tuple[str, float, float, tuple[int, ...]]] = []
    for limit, cursors in specs:
        # (road id, s from, s to, lanes, along s): the range's travel on each piece
        pieces: list[tuple[str, float, float, tuple[int, ...], bool]] = []
        for (r0, s0, ids), (r1, s1, _) in itertools.pairwise(cursors):
            r0, r1 = str(r0), str(r1)
            for rid, s in ((r0, s0), (r1, s1)):
                length = odr.lengths.get(rid)
                if length is None:
                    raise ScenarioError(f"{where}: a road cursor names no road {rid!r} of the map")
                if s is not None and not -1e-9 <= s <= length + 1e-9:
                    raise ScenarioError(
                        f"{where}: a road cursor's s = {s:g} m is off road {rid!r} "
                        f"(0 to {length:g} m)"
                    )
            if r0 == r1:
                lo = 0.0 if s0 is None else s0
                hi = odr.lengths[r0] if s1 is None else s1
                pieces.append((r0, min(lo, hi), max(lo, hi), ids, hi >= lo))
                continue
            path = _road_path(road, r0, r1)
            if path is None:
                raise ScenarioError(
                    f"{where}: no lanes join road {r0!r} and road {r1!r}: a road range "
                    "between them covers nothing"
                )
            for j, (rid, forward) in enumerate(path):
                length = odr.lengths[rid]
                lo, hi, lanes = 0.0, length, ()
                if j == 0:  # from the first cursor to where the range leaves its road
                    lanes = ids
                    if s0 is not None:
                        lo, hi = (s0, length) if forward else (0.0, s0)
                elif j == len(path) - 1 and s1 is not None:  # to the second cursor
                    lo, hi = (0.0, s1) if forward else (s1, length)
                pieces.append((rid, lo, hi, lanes, forward))
        covered = 0.0
        seen: set[tuple[str, float, float, tuple[int, ...]]] = set()
        for rid, lo, hi, ids, forward in pieces:
            if (rid, lo, hi, ids) in seen:
                continue
            seen.add((rid, lo, hi, ids))
            room = max(limit - covered, 0.0)
            if forward:
                hi = min(hi, lo + room)
            else:  # travelled against s: the range enters at hi
                lo = max(lo, hi - room)
            covered += hi - lo
            if hi > lo:
                out.append((rid, lo, hi, ids))
    if not out:
        raise ScenarioError(f"{where}: the road ranges cover no road")
    return tuple(out)


def _road_path(road: Any, start: str, goal: str) -> list[tuple[str, bool]] | None:
    """The roads from ``start`` to ``goal`` along lane links, each with whether the
    path runs along its ``s``: breadth first over the driving lanes, from lane to
    successor (with the traffic) or else from lane to predecessor (against it), never
    both (a range does not turn back at a fork); None when no lanes link them."""
    for ahead in (True, False):
        lanes = [k for k in road.lanes if k[0] == start]
        parent: dict[Any, Any] = {k: None for k in lanes}
        todo = deque(lanes)
        found = None
        while todo and found is None:
            key = todo.popleft()
            steps = road.successors(key) if ahead else road.predecessors(key)
            for nxt in steps:
                if nxt not in parent:
                    parent[nxt] = key
                    todo.append(nxt)
                    if nxt[0] == goal:
                        found = nxt
                        break
        if found is None:
            continue
        chain = [found]
        while parent[chain[-1]] is not None:
            chain.append(parent[chain[-1]])
        roads: list[tuple[str, bool]] = []
        for key in reversed(chain):  # with (against) a lane's traffic: along s?
            if not roads or roads[-1][0] != key[0]:
                roads.append((key[0], (road.lane_record(key).direction > 0) == ahead))
        return roads
    return None


def _in_polygon(corners: np.ndarray, point: np.ndarray) -> bool:
    """Whether ``point`` lies inside the polygon of ``corners`` ``(K, 2)`` (even-odd)."""
    x, y = float(point[0]), float(point[1])
    inside = False
    k = len(corners)
    for i in range(k):
        x0, y0 = corners[i]
        x1, y1 = corners[(i + 1) % k]
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside
