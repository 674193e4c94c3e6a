"""OpenSCENARIO positions, resolved against the world when an action starts.

Supported: ``LanePosition``, ``RelativeLanePosition`` (``ds`` along the reference line,
or ``dsLane`` along the referenced entity's lane in the direction it faces),
``RoadPosition``, ``WorldPosition`` (OpenDRIVE's inertial frame, mirrored into
highway-env's as the map is), ``GeoPosition`` (through the map's ``<geoReference>``) and
``RelativeObjectPosition`` (``dx``/``dy`` in the referenced entity's frame). An
``Orientation`` is relative to the lane's driving direction for lane and road
positions and to the referenced entity for relative ones unless its ``type`` says
``absolute`` (then OpenDRIVE's heading); ``WorldPosition``'s ``h`` is absolute. The
world is planar: an orientation's pitch ``p`` and roll ``r`` are not used.

Lane ids follow OpenDRIVE: ``RelativeLanePosition.dLane`` counts lanes along the road's
``t`` axis (+1 is the next lane to the left of the reference line's direction), skipping
the centre lane 0; ``offset`` is along ``t``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from aldm_gym.errors import MapError, NotDrivenError, OffRoadError, ScenarioError
from aldm_gym.scenario.routes import RoutePlan, next_lane
from aldm_gym.scenario.world import Entity, World, wrap_angle

__all__ = [
    "GeoPos",
    "LanePos",
    "NotPlacedYet",
    "Orientation",
    "Position",
    "RelativeLanePos",
    "RelativeObjectPos",
    "RelativeRoadPos",
    "RelativeWorldPos",
    "RoadPos",
    "RoutePos",
    "TrajectoryPos",
    "Where",
    "WorldPos",
    "lane_step",
]


@dataclass(frozen=True)
class Orientation:
    """An ``Orientation``: heading ``h`` [rad] (OpenDRIVE's sense: counter-clockwise),
    ``relative`` or absolute."""

    h: float = 0.0
    relative: bool = True


@dataclass(frozen=True)
class Where:
    """A resolved position: on a lane (``lane`` set: ``u``, ``t`` to the driver's left,
    ``heading_offset`` from the lane's direction, highway-env's sense), or a world
    ``point`` with a world ``heading`` (highway-env's frame)."""

    lane: Any = None
    u: float = 0.0
    t: float = 0.0
    heading_offset: float = 0.0
    point: np.ndarray | None = None
    heading: float = 0.0
    heading_given: bool = True
    """Whether the position gave an orientation (a trajectory vertex without one
    takes its segment's direction)."""


class Position:
    """A position element; :meth:`resolve` turns it into a :class:`Where` now."""

    where: str = ""

    def resolve(self, world: World) -> Where:
        """Where the position is in the world's current state.

        :raises ScenarioError: naming the element, when the position is off the map.
        """
        raise NotImplementedError

    def _error(self, exc: Exception) -> ScenarioError:
        return ScenarioError(f"{self.where}: the position is not on the map: {exc}")

    def _reference(self, world: World) -> Entity:
        """The entity this position is relative to (its ``entity`` field).

        :raises NotPlacedYet: nothing has placed it yet (in ``Init``, whose actions may
            name an entity that a later one places).
        """
        ref: Entity = world.entities[self.entity]  # type: ignore[attr-defined]
        if not ref.placed:
            raise NotPlacedYet(
                f"{self.where}: {ref.name!r}, which the position is relative to, has no "
                "position yet",
                ref.name,
            )
        return ref


class NotPlacedYet(ScenarioError):
    """A position relative to an entity that nothing has placed yet."""

    def __init__(self, message: str, entity: str) -> None:
        """``entity``: the one not placed."""
        super().__init__(message)
        self.entity = entity


def lane_step(lane_id: int, steps: int) -> int:
    """The OpenDRIVE lane id ``steps`` lanes from ``lane_id`` along the road's ``t``
    axis, skipping the centre lane 0 (-1 + 1 is lane 1)."""
    new = lane_id + steps
    if lane_id > 0 >= new or lane_id < 0 <= new:
        new += 1 if steps > 0 else -1
    return new


def _lane_where(
    world: World, road_id: str, lane_id: int, s: float, offset: float, o: Orientation | None
) -> Where:
    key, u, t = world.locate(road_id, lane_id, s, offset)
    heading = 0.0
    if o is not None:
        if o.relative:
            heading = -o.h  # OpenDRIVE's counter-clockwise is negative in highway-env's world
        else:
            _, lane_heading = world.pose(key, u, 0.0)
            heading = -o.h - lane_heading
    return Where(lane=key, u=u, t=t, heading_offset=heading, heading_given=o is not None)


@dataclass(frozen=True)
class LanePos(Position):
    """``LanePosition``: road, lane id, ``s`` and ``offset`` [m]."""

    road_id: str
    lane_id: int
    s: float
    offset: float = 0.0
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`. On a lane that is not driven (a shoulder, a border),
        the world point on its centre at ``s``, ``offset`` along the road's ``t``,
        heading along it (an entity placed there moves beside the nearest driving
        lane)."""
        try:
            return _lane_where(
                world, self.road_id, self.lane_id, self.s, self.offset, self.orientation
            )
        except NotDrivenError:
            return self._beside(world)
        except MapError as exc:
            raise self._error(exc) from None

    def _beside(self, world: World) -> Where:
        road = world.road
        try:
            x, y, h = road.map.lane_pose(self.road_id, self.lane_id, self.s)
            _, _, ref_h = road.map.plan_views[self.road_id].position(np.array([self.s]))
        except (MapError, KeyError) as exc:
            raise self._error(exc) from None
        n = float(ref_h[0]) + 0.5 * math.pi  # the road's t axis (OpenDRIVE's frame)
        point = np.array([x + self.offset * math.cos(n), -(y + self.offset * math.sin(n))])
        heading = -float(h)  # highway-env's frame
        o = self.orientation
        if o is not None:
            heading = heading - o.h if o.relative else -o.h
        return Where(point=point, heading=heading, heading_given=o is not None)


@dataclass(frozen=True)
class RoadPos(Position):
    """``RoadPosition``: road, ``s`` and ``t`` [m] from the reference line; the lane is
    the driving lane containing the point."""

    road_id: str
    s: float
    t: float
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        odr = world.road.map
        plan = odr.plan_views.get(str(self.road_id))
        length = odr.lengths.get(str(self.road_id), -1.0)
        if plan is None or not -1e-9 <= self.s <= length + 1e-9:
            raise self._error(MapError(f"no road {self.road_id!r} with s = {self.s:g} m"))
        xs, ys, hs = plan.position(np.array([self.s]))
        x, y, h = float(xs[0]), float(ys[0]), float(hs[0])
        point = np.array([x - self.t * math.sin(h), y + self.t * math.cos(h)])
        world_point = np.array([point[0], -point[1]])
        try:
            pos = world.road.lane_position(world_point)
        except OffRoadError as exc:
            raise self._error(exc) from None
        o = self.orientation
        heading = 0.0
        if o is not None:
            # relative to the lane's direction, or absolute (OpenDRIVE's heading)
            heading = -o.h if o.relative else wrap_angle(-o.h - pos.heading)
        return Where(
            lane=pos.lane,
            u=pos.s - world.road.chain_start(pos.lane),
            t=pos.offset,
            heading_offset=heading,
            heading_given=o is not None,
        )


@dataclass(frozen=True)
class WorldPos(Position):
    """``WorldPosition``: OpenDRIVE inertial ``x``, ``y`` [m] and heading ``h`` [rad]."""

    x: float
    y: float
    h: float | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position` (without ``h`` the heading is 0, the standard's default
        for a placement, and a trajectory takes its segment's direction)."""
        h = 0.0 if self.h is None else self.h
        return Where(
            point=np.array([self.x, -self.y]), heading=-h, heading_given=self.h is not None
        )


@dataclass(frozen=True)
class GeoPos(Position):
    """``GeoPosition``: ``latitude`` and ``longitude`` [deg] on WGS 84, put into the
    map's inertial frame through its ``<geoReference>`` (a PROJ string, by pyproj) and
    its header's ``<offset>``; the altitude is not used (the world is planar). An
    ``Orientation`` is absolute (OpenDRIVE's heading) or relative to the lane's
    driving direction there; without one the heading is 0, as a ``WorldPosition``'s."""

    latitude: float
    longitude: float
    orientation: Orientation | None = None
    where: str = ""

    def inertial(self, world: World) -> tuple[float, float]:
        """``(x, y)`` [m] in OpenDRIVE's inertial frame of the map."""
        header = world.road.map.header
        if not header.geo_reference:
            raise ScenarioError(
                f"{self.where}: a GeoPosition needs the map's <geoReference> (a PROJ "
                f"string), and {world.road.map.path} has none"
            )
        east, north = _projection(header.geo_reference, self.where)(self.longitude, self.latitude)
        if not (math.isfinite(east) and math.isfinite(north)):
            raise ScenarioError(
                f"{self.where}: latitude {self.latitude:g}, longitude {self.longitude:g} "
                f"[deg] lie outside the map's projection ({header.geo_reference})"
            )
        ox, oy, _oz, hdg = header.offset
        dx, dy = east - ox, north - oy  # the projection's frame: R(hdg) p + offset
        c, s = math.cos(hdg), math.sin(hdg)
        return c * dx + s * dy, -s * dx + c * dy

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        x, y = self.inertial(world)
        o = self.orientation
        if o is None or not o.relative:
            return WorldPos(x, y, None if o is None else o.h, self.where).resolve(world)
        point = np.array([x, -y])
        try:
            pos = world.road.lane_position(point)
        except OffRoadError as exc:
            raise self._error(exc) from None
        return Where(point=point, heading=float(pos.heading) - o.h, heading_given=True)


def _projection(proj: str, where: str) -> Any:
    """The transform from WGS 84 (longitude, latitude [deg]) to the projection ``proj``
    (easting, northing [m]), cached per string."""
    transform = _PROJECTIONS.get(proj)
    if transform is None:
        try:
            import pyproj
        except ImportError:  # a dependency of the package; a broken install
            raise ScenarioError(
                f"{where}: a GeoPosition needs pyproj (pip install pyproj)"
            ) from None
        try:
            crs = pyproj.CRS.from_user_input(proj)
        except pyproj.exceptions.CRSError as exc:
            raise ScenarioError(
                f"{where}: the map's <geoReference> {proj!r} is not a projection pyproj "
                f"knows: {exc}"
            ) from None
        units = [a.unit_conversion_factor for a in crs.axis_info[:2]]
        if not crs.is_projected or any(abs(u - 1.0) > 1e-12 for u in units):
            raise ScenarioError(
                f"{where}: the map's <geoReference> {proj!r} is not a projected coordinate "
                "system in metres, which an OpenDRIVE inertial frame must be"
            )
        transform = pyproj.Transformer.from_crs("EPSG:4326", crs, always_xy=True)
        _PROJECTIONS[proj] = transform
    return transform.transform


_PROJECTIONS: dict[str, Any] = {}


@dataclass(frozen=True)
class RelativeLanePos(Position):
    """``RelativeLanePosition``: ``dLane`` lanes and ``ds`` [m] along the reference
    line (or ``dsLane`` along the lane) from an entity, ``offset`` [m] along ``t``."""

    entity: str
    d_lane: int
    ds: float | None
    ds_lane: float | None
    offset: float = 0.0
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        ref = self._reference(world)
        c = world.coordinates(ref)
        lane_id = lane_step(c.lane_id, self.d_lane)
        try:
            if self.ds is not None:
                return _lane_where(
                    world, c.road_id, lane_id, c.s + self.ds, self.offset, self.orientation
                )
            # dsLane: along the referenced entity's lane, in the direction it faces
            facing = 1.0 if math.cos(ref.heading - world.pose(c.lane, c.u, 0.0)[1]) >= 0 else -1.0
            s_new = world.road.reference_s(c.lane, c.u + facing * float(self.ds_lane or 0.0))
            return _lane_where(world, c.road_id, lane_id, s_new, self.offset, self.orientation)
        except MapError as exc:
            raise self._error(exc) from None


@dataclass(frozen=True)
class RelativeObjectPos(Position):
    """``RelativeObjectPosition``: ``dx``, ``dy`` [m] in an entity's frame (ISO: y left)."""

    entity: str
    dx: float
    dy: float
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        ref: Entity = self._reference(world)
        point = ref.reference_point() + self.dx * ref.forward() + self.dy * ref.left()
        return _relative_to(ref, point, self.orientation)


@dataclass(frozen=True)
class RelativeRoadPos(Position):
    """``RelativeRoadPosition``: ``ds`` along and ``dt`` across the reference line [m]
    from an entity's reference point, on the entity's road."""

    entity: str
    ds: float
    dt: float
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        ref = self._reference(world)
        c = world.coordinates(ref)
        road = RoadPos(c.road_id, c.s + self.ds, world.road_t(ref) + self.dt, self.orientation)
        return replace(road, where=self.where).resolve(world)


@dataclass(frozen=True)
class RelativeWorldPos(Position):
    """``RelativeWorldPosition``: ``dx``, ``dy`` [m] in OpenDRIVE's inertial frame from
    an entity's reference point."""

    entity: str
    dx: float
    dy: float
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position` (an orientation relative to the entity's heading)."""
        ref: Entity = self._reference(world)
        point = ref.reference_point() + np.array([self.dx, -self.dy])
        return _relative_to(ref, point, self.orientation)


def _relative_to(ref: Entity, point: np.ndarray, orientation: Orientation | None) -> Where:
    """A world point with the heading of ``ref`` turned by a relative orientation, or an
    absolute one (OpenDRIVE's counter-clockwise is negative in highway-env's world)."""
    heading = ref.heading
    if orientation is not None:
        heading = heading - orientation.h if orientation.relative else -orientation.h
    return Where(point=point, heading=heading, heading_given=orientation is not None)


@dataclass(frozen=True)
class TrajectoryPos(Position):
    """``TrajectoryPosition``: ``s`` [m] along a trajectory's shape and ``t`` [m] to
    its left; the heading is the trajectory's there, turned by an orientation."""

    shape: Any
    s: float
    t: float = 0.0
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        path = self.shape.resolve(world)
        pts = path.points
        arc = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))
        if not -1e-9 <= self.s <= arc[-1] + 1e-9:
            raise self._error(MapError(f"s = {self.s:g} m is off the {arc[-1]:.1f} m trajectory"))
        i = min(max(int(np.searchsorted(arc, self.s, side="right")) - 1, 0), len(arc) - 2)
        span = arc[i + 1] - arc[i]
        x = 0.0 if span <= 0 else (self.s - arc[i]) / span
        seg = pts[i + 1] - pts[i]
        h = path.headings[i]
        heading = float(math.atan2(seg[1], seg[0])) if h is None else float(h)
        after = path.headings[i + 1]
        if path.smooth and h is not None and after is not None:
            heading = h + x * wrap_angle(after - h)
        left = np.array([math.sin(heading), -math.cos(heading)])  # highway-env's world
        point = pts[i] + x * seg + self.t * left
        o = self.orientation
        if o is not None:
            heading = heading - o.h if o.relative else -o.h
        return Where(point=point, heading=heading)


@dataclass(frozen=True)
class RoutePos(Position):
    """``RoutePosition``: on a route (the lanes from its first waypoint on, taking
    the branch towards its next waypoint where a lane splits), from an entity's
    current position (``FromCurrentEntity``), or ``path_s`` [m] along the route from its
    first waypoint (in the roads' ``s``, their reference lines' length), then ``t`` [m]
    from the reference line (``FromRoadCoordinates``) or ``lane_offset`` [m] from the
    centre of lane ``lane_id`` (``FromLaneCoordinates``)."""

    waypoints: tuple[Position, ...]
    mode: str
    entity: str = ""
    path_s: float = 0.0
    t: float = 0.0
    lane_id: int = 0
    lane_offset: float = 0.0
    orientation: Orientation | None = None
    where: str = ""

    def resolve(self, world: World) -> Where:
        """See :class:`Position`."""
        if self.mode == "entity":
            ref: Entity = self._reference(world)
            return _relative_to(ref, ref.reference_point(), self.orientation)
        start = self.waypoints[0].resolve(world)
        road = world.road
        try:
            if start.lane is not None:
                key, u = start.lane, start.u
            else:
                assert start.point is not None
                pos = road.lane_position(start.point)
                key, u = pos.lane, pos.s - road.chain_start(pos.lane)
            # pathS counts the roads' s (their reference lines, as esmini does), lane
            # after lane along the route
            plan = RoutePlan(
                [
                    road.lane_record(world.lane_of(w.resolve(world))).road_id
                    for w in self.waypoints[1:]
                ]
            )
            left = self.path_s
            s = road.reference_s(key, u)
            while True:
                end = road.reference_s(key, road.lane_length(key))
                if left <= abs(end - s):
                    s += math.copysign(left, end - s)
                    break
                left -= abs(end - s)
                nxt = next_lane(road, plan, key)
                if nxt is None:
                    raise MapError(f"pathS = {self.path_s:g} m runs past the route's end")
                key = nxt
                s = road.reference_s(key, 0.0)
            rec = road.lane_record(key)
            if self.mode == "road":
                return RoadPos(rec.road_id, s, self.t, self.orientation, self.where).resolve(world)
            return _lane_where(
                world, rec.road_id, self.lane_id, s, self.lane_offset, self.orientation
            )
        except (MapError, OffRoadError) as exc:
            raise self._error(exc) from None
