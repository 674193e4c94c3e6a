"""The scenario's entities on the map: where they are in the road's coordinates, and how
a scripted entity moves.

Every entity is a highway-env vehicle on the env's road (so the observation, the line
sensor's occlusion, rendering and collisions see it) plus an :class:`Entity` that holds
what OpenSCENARIO asks of it. A *scripted* entity (every scenario object but the ego
once its controller is active) moves along its lane as the storyboard's actions say:
its state is the lane, the arc length ``u`` along the lane's centre [m], the lateral
offset ``t`` from the centre [m] (> 0 to the driver's left) and the speed [m/s]; the
vehicle's pose follows from them at every simulation step.

Positions. OpenSCENARIO places an entity by its reference point, the centre of the rear
axle for vehicles; its ``BoundingBox`` centre lies ``center.x`` ahead of it. highway-env
places a vehicle by the centre of its box. :meth:`Entity.reference_point` and
:meth:`World.place` convert. Road coordinates (:class:`RoadCoordinates`) are
OpenDRIVE's: the road, the lane id, the reference line's ``s`` [m] and the offset from
the lane centre along the road's ``t`` axis [m] (left of the reference line's
direction), whatever the lane's driving direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.errors import OffRoadError
from aldm_gym.scenario.routes import Chooser, next_lane

if TYPE_CHECKING:
    from aldm_gym.roads.map_road import OpenDriveRoad
    from aldm_gym.roads.opendrive.map import LaneKey

__all__ = ["BoundingBox", "Entity", "RoadCoordinates", "ScenarioVehicle", "World", "wrap_angle"]


@dataclass(frozen=True)
class BoundingBox:
    """An entity's box (OpenSCENARIO ``BoundingBox``): centre relative to the reference
    point, ISO 8855 (x forward, y left) [m], and dimensions [m]."""

    cx: float
    cy: float
    length: float
    width: float
    height: float


@dataclass(frozen=True)
class RoadCoordinates:
    """Where an entity's reference point is on the map, in OpenDRIVE's terms.

    :ivar road_id: the OpenDRIVE road.
    :ivar lane_id: the OpenDRIVE lane id (> 0 left of the reference line).
    :ivar s: the reference line's arc length there [m].
    :ivar offset: offset from the lane centre along the road's ``t`` axis [m].
    :ivar lane: the map road's key of the lane.
    :ivar u: arc length along the lane's centre [m].
    :ivar direction: +1 when the lane is driven along increasing ``s``, -1 against.
    """

    road_id: str
    lane_id: int
    s: float
    offset: float
    lane: Any
    u: float
    direction: int


class ScenarioVehicle(Vehicle):
    """A highway-env vehicle that the scenario moves (it does not act on its own).

    ``road.step`` calls :meth:`step`, which advances the :class:`Entity`'s script by
    ``dt`` and sets the pose; collisions are then handled by highway-env as for every
    vehicle. A crashed scripted vehicle keeps to its script (OpenSCENARIO's actors do
    not react); the episode's outcome is judged on the ego.
    """

    entity: Entity | None = None

    def act(self, action: Any = None) -> None:
        """No action of its own: the scenario moves it."""
        self.action = {"steering": 0.0, "acceleration": 0.0}

    def handle_collisions(self, other: Any, dt: float = 0) -> None:
        """highway-env's collision check, but for a tractor and the trailer it tows
        (their boxes meet at the hitch)."""
        mine, theirs = self.entity, getattr(other, "entity", None)
        if mine is not None and theirs is not None:
            if mine.trailer is theirs or mine.tractor is theirs:
                return
        super().handle_collisions(other, dt)

    def step(self, dt: float) -> None:
        """Advance the script by ``dt`` [s]; then highway-env's lane bookkeeping."""
        if self.entity is not None and self.entity.world is not None:
            world = self.entity.world
            world.advance_all(dt)  # every scripted entity, in esmini's order, once a step
        self.impact = None
        self.on_state_update()


@dataclass(eq=False)
class Entity:
    """One ``ScenarioObject``: its description, its vehicle and its scripted state.

    :ivar name: the scenario's name for it.
    :ivar kind: ``"vehicle"``, ``"pedestrian"`` or ``"miscObject"``.
    :ivar category: the catalog's category (``car``, ``truck``, ``pedestrian``, ...).
    :ivar box: the bounding box.
    :ivar max_speed: [m/s] (``Performance``; inf when not given).
    :ivar max_acceleration: [m/s²].
    :ivar max_deceleration: [m/s²] (> 0).
    :ivar is_ego: the function under test (the env's ego vehicle).
    """

    name: str
    kind: str
    category: str
    box: BoundingBox
    max_speed: float = math.inf
    max_acceleration: float = math.inf
    max_deceleration: float = math.inf
    is_ego: bool = False
    vehicle: Any = None
    world: World | None = None
    # scripted state
    scripted: bool = True
    lane: Any = None
    u: float = 0.0
    t: float = 0.0
    heading_offset: float = 0.0
    speed: float = 0.0
    traveled: float = 0.0
    longitudinal: Any = None
    lateral: Any = None
    trajectory: Any = None
    still_since: float | None = None
    """Simulation time [s] since which the entity stands still (None: it moves)."""
    acceleration: float = 0.0
    """Longitudinal acceleration over the last step [m/s²]."""
    road_end_since: float | None = None
    """Simulation time [s] since which it is at the end of its lane chain."""
    off_road_since: float | None = None
    """Simulation time [s] since which it is on no driving lane."""
    last_speed: float | None = None
    controlled: frozenset[str] = frozenset()
    """The domains the function under test drives (the ego only)."""
    teleport: Any = None
    """A position to put the entity at before its next step (a storyboard teleport)."""
    ended: bool = False
    """It drove to the end of its road: it stays there until placed elsewhere."""
    ended_steps: int = 0
    """Steps since it drove to the end of its road: its speed reads 0 from the second
    on (esmini keeps reporting the speed it arrived with for two steps)."""
    last_lateral: Any = None
    """The lateral motion that moved the entity in its last step (it may have ended
    there and left ``lateral``)."""
    placed: bool = False
    present: bool = True
    """It is in the scenario: not deleted by a ``DeleteEntityAction`` (or added
    back). No condition on an absent entity holds; its vehicle is not on the road
    (from the step after the deletion), so it does not move, collide or show."""
    leaving: bool = False
    """A ``DeleteEntityAction`` took it out: its vehicle leaves at its next step."""
    arrival: Any = None
    """Where an ``AddEntityAction`` puts its vehicle at the next step (a resolved
    position)."""
    hitch: float | None = None
    """Its trailer hitch [m] ahead of its reference point (None: it tows nothing)."""
    coupler: float | None = None
    """Its trailer coupler [m] ahead of its reference point (None: it is no trailer)."""
    trailer: Entity | None = None
    """The trailer it tows now."""
    tractor: Entity | None = None
    """The vehicle that tows it now."""
    speed_before: float | None = None
    """Its speed at the start of the step, where its longitudinal action already set
    this step's speed (esmini steps every action before the default moves); None
    otherwise."""
    route: Chooser | None = None
    """What chooses its branch where its lane splits
    (:class:`~aldm_gym.scenario.routes.Chooser`); None: the straightest."""

    def chain(self) -> list[Entity]:
        """The trailers it tows, nearest first."""
        out, t = [], self.trailer
        while t is not None and t not in out:
            out.append(t)
            t = t.trailer
        return out

    @property
    def current_speed(self) -> float:
        """Its speed now [m/s]: the script's while scripted, else its vehicle's."""
        return self.speed if self.scripted else self.velocity

    def acceleration_limit(self, rising: bool) -> float:
        """The ``Performance`` limit [m/s²] of a speed change up (``rising``) or down."""
        return self.max_acceleration if rising else self.max_deceleration

    @property
    def position(self) -> np.ndarray:
        """The vehicle's box centre, highway-env's world [m]."""
        return np.asarray(self.vehicle.position, dtype=np.float64)

    @property
    def heading(self) -> float:
        """The vehicle's heading, highway-env's world [rad]."""
        return float(self.vehicle.heading)

    @property
    def velocity(self) -> float:
        """The vehicle's speed [m/s]."""
        return float(self.vehicle.speed)

    def forward(self) -> np.ndarray:
        """Unit vector of the heading (highway-env's world)."""
        h = self.heading
        return np.array([math.cos(h), math.sin(h)])

    def left(self) -> np.ndarray:
        """Unit vector to the driver's left (highway-env's world has y down the screen)."""
        h = self.heading
        return np.array([math.sin(h), -math.cos(h)])

    def reference_point(self) -> np.ndarray:
        """OpenSCENARIO's reference point (rear axle centre), highway-env's world [m]."""
        return self.position - self.box.cx * self.forward() - self.box.cy * self.left()

    def corners(self) -> np.ndarray:
        """``(4, 2)`` corners of the box, highway-env's world [m]."""
        c = self.position
        f, left = self.forward(), self.left()
        hl, hw = 0.5 * self.box.length, 0.5 * self.box.width
        return np.array(
            [c + sx * hl * f + sy * hw * left for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
        )


class World:
    """The entities of one scenario run on the map, and the run's clock.

    :param road: the map (the scenario's ``RoadNetwork/LogicFile``).
    """

    def __init__(self, road: OpenDriveRoad) -> None:
        """An empty world on ``road``."""
        self.road = road
        self.network = road.network
        self.entities: dict[str, Entity] = {}
        self.time = 0.0
        """Simulation time [s]."""
        self.ego: Entity | None = None
        self._ego_due = False
        self._all_due = False
        self.moved_at: dict[str, tuple[int, ...]] = {}
        """The entities an action moved in this step, by the action's rank."""
        self.running = False
        """Whether the storyboard runs (``Init`` has been played)."""

    def add(self, entity: Entity) -> None:
        """Add an entity (its vehicle is set by the scene builder)."""
        entity.world = self
        self.entities[entity.name] = entity
        if entity.is_ego:
            self.ego = entity

    def ego_due(self) -> None:
        """A simulation step begins: the scripted ego and entities are yet to move."""
        self._ego_due = True
        self._all_due = True
        self.moved_at = {}

    def advance_all(self, dt: float) -> None:
        """Move every scripted entity by ``dt`` [s], once a step, in esmini's order.

        esmini steps the running actions (``Init``'s, then the storyboard's, in
        document order), then moves the entities no action moved along their lanes
        (its default controller). So here: in the actions' order, an entity with a
        lateral motion or a trajectory moves, and a speed action sets its entity's
        speed for the step; then the other entities move, in the file's order. Each
        sees the others where they are at that point: an action written after its
        reference's sees the reference's new state, one written before sees the old."""
        if not self._all_due:
            return
        self._all_due = False
        self.moved_at = {}
        steps: list[tuple[tuple[int, ...], int, bool, Entity]] = []
        others = []
        for index, entity in enumerate(self.entities.values()):
            ranks = [
                motion.rank
                for motion in (entity.lateral, entity.trajectory)
                if motion is not None and hasattr(motion, "rank")
            ]
            if ranks:
                steps.append((min(ranks), index, True, entity))
            else:
                others.append(entity)
            speed = entity.longitudinal
            if (
                speed is not None
                and self._moves_normally(entity)
                and (not ranks or speed.rank < min(ranks))
            ):
                steps.append((speed.rank, index, False, entity))
        try:
            for rank, _, moves, entity in sorted(steps, key=lambda item: item[:2]):
                if moves:
                    if self._moves(entity):
                        self.moved_at[entity.name] = rank
                    self._advance_one(entity, dt)
                else:  # a speed action: the speed now, the move later
                    entity.speed_before = entity.speed
                    entity.speed = float(entity.longitudinal.speed_after(self, entity, dt))
            for entity in others:
                self._advance_one(entity, dt)
        finally:
            for entity in self.entities.values():
                entity.speed_before = None  # one that did not move keeps its speed

    def _moves(self, entity: Entity) -> bool:
        """Whether :meth:`advance` will move the entity in this step (not a vehicle the
        function drives, nor an absent, towed or stopped one)."""
        return (
            entity.scripted
            and entity.placed
            and entity.present
            and not entity.leaving
            and entity.tractor is None
            and not entity.ended
            and (not entity.is_ego or self._ego_due)
        )

    def _moves_normally(self, entity: Entity) -> bool:
        """Whether :meth:`advance` will move the entity along its lane by its speed
        (:meth:`_moves`, and neither teleported nor on a trajectory)."""
        return self._moves(entity) and entity.teleport is None and entity.trajectory is None

    def _advance_one(self, entity: Entity, dt: float) -> None:
        if entity.is_ego:
            self.advance_ego(dt)
        else:
            self.advance(entity, dt)

    def advance_ego(self, dt: float) -> None:
        """Move the ego by ``dt`` [s] if the scenario drives it and it has not moved in
        this step (a scripted ego moves where :meth:`advance_all` puts it in the order;
        the env's ego, which its function drives, moves by itself before them all)."""
        ego = self.ego
        if not self._ego_due or ego is None:
            return
        self._ego_due = False
        if ego.scripted:
            self.advance(ego, dt)
            ego.vehicle.on_state_update()

    # ------------------------------------------------------------ road coordinates
    def _lane(self, key: LaneKey) -> Any:
        return self.network.get_lane(self.network.index_of[key])

    def lane(self, key: LaneKey) -> Any:
        """The highway-env lane of a driving lane's key (``position(u, lateral)``,
        ``heading_at(u)``, ``length``, ``speed_limit``)."""
        return self._lane(key)

    def lane_of(self, where: Any) -> LaneKey:
        """The driving lane of a resolved position (its own, else the one holding its
        point).

        :raises OffRoadError: the point is on no driving lane."""
        if where.lane is not None:
            return where.lane
        return self.road.lane_position(where.point).lane

    def point_of(self, where: Any) -> np.ndarray:
        """The world point [m] (highway-env's frame) of a resolved position."""
        if where.lane is not None:
            return self.pose(where.lane, where.u, where.t)[0]
        return np.asarray(where.point, dtype=np.float64)

    def coordinates(self, entity: Entity) -> RoadCoordinates:
        """Where the entity's reference point is, in the road's coordinates.

        The lane is the one that holds the reference point: a scripted entity's own
        lane while it is inside it, else (the active ego, a scripted entity changing
        lanes) the driving lane whose centre is nearest.

        :raises OffRoadError: the entity is on no driving lane.
        """
        return self._locate(entity)[0]

    def _locate(self, entity: Entity) -> tuple[RoadCoordinates, Any]:
        """:meth:`coordinates`, and the map's nearest-lane look-up of the reference
        point where it was made (None where the entity is inside its own lane)."""
        road = self.road
        pos = None
        inside = (
            entity.scripted
            and entity.lane is not None
            and abs(entity.t) <= 0.5 * float(self._lane(entity.lane).width_at(entity.u))
        )
        if inside:
            key, u, t_left = entity.lane, entity.u, entity.t
        else:  # the active ego, or a scripted entity outside the lane it moves by
            pos = road.lane_position(entity.reference_point())
            key, t_left = pos.lane, pos.offset
            u = pos.s - road.chain_start(key)
        rec = road.lane_record(key)
        s = road.reference_s(key, u)
        coordinates = RoadCoordinates(
            road_id=rec.road_id,
            lane_id=int(rec.lane_id),
            s=s,
            offset=t_left * rec.direction,
            lane=key,
            u=u,
            direction=int(rec.direction),
        )
        return coordinates, pos

    def offset_in_lane(self, entity: Entity, value: float) -> float:
        """The offset [m] from the centre of the lane ``entity`` moves by, along the
        road's ``t``, of the place ``value`` [m] (along ``t``) from the centre of the
        lane that holds its reference point: the two differ after a lane change onto a
        lane of the other driving direction (the entity moves by its own lane)."""
        c = self.coordinates(entity)
        direction = self.road.lane_record(entity.lane).direction
        if c.lane == entity.lane or c.direction == direction:
            return value  # its own lane, or one beside it driven the same way
        return entity.t * direction - c.offset + value

    def offset_beside(self, entity: Entity, ref: Entity, value: float) -> float:
        """The offset [m] from the centre of ``entity``'s lane, along the road's ``t`` (a
        ``LanePosition``'s sense), that puts ``entity`` ``value`` [m] beside ``ref``:
        where ``ref``'s reference point lies across that lane (on the lane's chain, at
        ``ref``'s place along it) plus ``value`` to ``ref``'s left along the road's
        ``t`` (esmini's reading of ``RelativeTargetLaneOffset``)."""
        road = self.road
        point = ref.reference_point()
        key = entity.lane
        for _ in range(64):  # along the chain to the piece of lane beside ref
            lane = self._lane(key)
            u, r = (float(x) for x in lane.local_coordinates(point))
            nxt = road.successor(key) if u > road.lane_length(key) else None
            nxt = road.predecessor(key) if u < 0.0 else nxt
            if nxt is None:
                break
            key = nxt
        direction = road.lane_record(entity.lane).direction
        facing = 1.0 if math.cos(ref.heading - float(lane.heading_at(u))) >= 0.0 else -1.0
        # r is to the driver's right of the lane; ref's left along t is the lane's
        # driver's left when ref faces the lane's way
        return direction * (-r + value * facing)

    def road_t(self, entity: Entity) -> float:
        """The road's ``t`` [m] of the entity's reference point: its distance left of
        the reference line (OpenDRIVE's sense) at its ``s``."""
        c = self.coordinates(entity)
        plan = self.road.map.plan_views[c.road_id]
        xs, ys, hs = plan.position(np.array([c.s]))
        ref = entity.reference_point()
        px, py = float(ref[0]), -float(ref[1])  # highway-env's world back to OpenDRIVE's
        h = float(hs[0])
        return (px - float(xs[0])) * -math.sin(h) + (py - float(ys[0])) * math.cos(h)

    def road_box(self, entity: Entity) -> tuple[float, float, float, float]:
        """``(s_min, s_max, t_min, t_max)`` [m] of the entity's bounding box in its
        road's coordinates: every corner projected on the lane that holds the
        reference point, along the reference line (``s``) and across it (``t``)."""
        c = self.coordinates(entity)
        lane = self._lane(c.lane)
        _, r_ref = lane.local_coordinates(entity.reference_point())
        t_ref = self.road_t(entity)
        ss, ts = [], []
        for corner in entity.corners():
            u, r = lane.local_coordinates(corner)
            ss.append(self.road.reference_s(c.lane, float(u)))
            # r is to the driver's right; the road's t is left of its reference line
            ts.append(t_ref - (float(r) - float(r_ref)) * c.direction)
        return min(ss), max(ss), min(ts), max(ts)

    def lane_box(self, entity: Entity, key: LaneKey) -> tuple[float, float, float, float]:
        """``(u_min, u_max, left_min, left_max)`` [m] of the entity's bounding box along
        and across lane ``key`` (every corner projected on its centre; left positive)."""
        lane = self._lane(key)
        us, ls = [], []
        for corner in entity.corners():
            u, r = lane.local_coordinates(corner)
            us.append(float(u))
            ls.append(-float(r))
        return min(us), max(us), min(ls), max(ls)

    def lane_offsets(self, source: Entity, target: Entity) -> tuple[float, float]:
        """``(|du|, |dt|)`` [m] of the target from the source along and across the
        source's lane (reference points projected on the lane's centre)."""
        c = self.coordinates(source)
        lane = self._lane(c.lane)
        u_s, lat_s = lane.local_coordinates(source.reference_point())
        u_t, lat_t = lane.local_coordinates(target.reference_point())
        return abs(float(u_t) - float(u_s)), abs(float(lat_t) - float(lat_s))

    def locate(
        self, road_id: str, lane_id: int, s: float, offset: float
    ) -> tuple[Any, float, float]:
        """``(lane key, u [m], t [m] > 0 left of the driver)`` of a lane position.

        :raises MapError: no such driving lane at ``s``.
        """
        key = self.road.lane_key(road_id, lane_id, s)
        rec = self.road.lane_record(key)
        return key, self.road.lane_u(key, s), float(offset) * rec.direction

    # ------------------------------------------------------------ placing and moving
    def pose(self, key: LaneKey, u: float, t: float) -> tuple[np.ndarray, float]:
        """World point [m] and the lane's heading [rad] at ``u`` along lane ``key``,
        ``t`` to the driver's left of its centre (highway-env's lateral is to the right)."""
        lane = self._lane(key)
        return np.asarray(lane.position(u, -t), dtype=np.float64), float(lane.heading_at(u))

    def place(
        self,
        entity: Entity,
        key: LaneKey,
        u: float,
        t: float,
        heading_offset: float = 0.0,
        lateral_speed: float = 0.0,
    ) -> None:
        """Put a scripted entity's reference point at ``(key, u, t)``, heading along
        the lane plus ``heading_offset`` and the direction of its lateral motion."""
        entity.lane, entity.u, entity.t = key, float(u), float(t)
        entity.heading_offset = float(heading_offset)
        entity.placed = True
        entity.ended = False
        self._update_pose(entity, lateral_speed)

    def place_world(self, entity: Entity, point: np.ndarray, heading: float) -> None:
        """Put a scripted entity's reference point at a world point [m] with a world
        heading [rad]; its lane is the nearest driving lane's (for road coordinates).

        :raises OffRoadError: no driving lane near the point.
        """
        pos = self.road.lane_position(point)
        entity.lane = pos.lane
        entity.u = pos.s - self.road.chain_start(pos.lane)
        entity.t = pos.offset
        entity.heading_offset = wrap_angle(heading - pos.heading)
        entity.placed = True
        entity.ended = False
        self._set_vehicle(entity, point, heading)

    def _update_pose(
        self, entity: Entity, lateral_speed: float, along_heading: bool = False
    ) -> None:
        point, lane_heading = self.pose(entity.lane, entity.u, entity.t)
        # Moving to the driver's left turns the heading towards it (heading decreases
        # to the left in highway-env's world): the lateral speed is the sine's share of
        # the speed where the speed is along the heading, else on top of it.
        slip = 0.0
        if lateral_speed:
            speed = max(abs(entity.speed), 0.1)
            if along_heading:
                slip = math.asin(min(max(lateral_speed / speed, -1.0), 1.0))
            else:
                slip = math.atan2(lateral_speed, speed)
            if math.cos(entity.heading_offset) < 0.0:
                slip = -slip  # turned round on its lane: the lane's left is its right
        self._set_vehicle(entity, point, lane_heading + entity.heading_offset - slip)

    def centre_step(self, key: LaneKey, u: float, t: float, along: float) -> float:
        """The arc length [m] along lane ``key``'s centre that moves a point ``t`` [m]
        to the driver's left of it by ``along`` [m] along its own path: longer on the
        outside of a curve, shorter on the inside (the path's curvature radius is the
        centre's minus ``t``)."""
        lane = self._lane(key)
        mid = min(max(u + 0.5 * along, 0.5), max(float(lane.length) - 0.5, 0.5))
        h0 = float(lane.heading_at(mid - 0.5))
        h1 = float(lane.heading_at(mid + 0.5))
        kappa = wrap_angle(h1 - h0)  # per metre: highway-env's world, < 0 turning left
        scale = 1.0 + kappa * t
        return along / scale if scale > 0.05 else along / 0.05

    def _set_vehicle(self, entity: Entity, ref_point: np.ndarray, heading: float) -> None:
        v = entity.vehicle
        if v is None:
            return
        f = np.array([math.cos(heading), math.sin(heading)])
        left = np.array([math.sin(heading), -math.cos(heading)])
        v.position = np.asarray(ref_point + entity.box.cx * f + entity.box.cy * left, dtype=float)
        v.heading = float(heading)
        v.speed = float(entity.speed)

    def advance(self, entity: Entity, dt: float) -> None:
        """Move a scripted entity by ``dt`` [s]: its longitudinal and lateral motions
        (or its trajectory) set speed and offset, then it drives ``speed · dt`` along
        its lane, on into the lane's successor at the lane's end."""
        if entity.leaving:  # deleted in the last step: gone from this one on
            entity.leaving, entity.present = False, False
            if entity.vehicle is not None:
                entity.vehicle.collidable = False
            return
        if not entity.scripted or not entity.placed or not entity.present:
            return
        if entity.tractor is not None:
            return  # towed: moved by its tractor (tow)
        if entity.teleport is not None:
            where, entity.teleport = entity.teleport, None
            if where.lane is not None:
                self.place(entity, where.lane, where.u, where.t, where.heading_offset)
            else:
                self.place_world(entity, where.point, where.heading)
            return  # the step that teleports does not move it on (as esmini)
        if entity.ended:  # at the end of its road it stays until placed elsewhere
            entity.ended_steps += 1
            if entity.ended_steps >= 2:
                entity.speed = 0.0
            return
        if entity.trajectory is not None:
            entity.trajectory.advance(self, entity, dt)
            return
        longitudinal = entity.longitudinal
        if entity.speed_before is not None:  # its action set this step's speed already
            speed_before, entity.speed_before = entity.speed_before, None
        else:
            speed_before = entity.speed
            if longitudinal is not None:
                entity.speed = float(longitudinal.speed_after(self, entity, dt))
        entity.speed = min(max(entity.speed, -entity.max_speed), entity.max_speed)
        # a rigid distance places the actor once everyone has moved (settle)
        settles = getattr(longitudinal, "rigid", False)
        # A lane change moves the entity itself, before a speed action written after it
        # has changed the speed (esmini steps actions in document order); a lane
        # offset only sets the offset, and the entity travels at the new speed
        travel_speed = entity.speed
        if (
            entity.lateral is not None
            and getattr(entity.lateral, "moves_along", True)
            and longitudinal is not None
            and longitudinal.rank > entity.lateral.rank
        ):
            travel_speed = speed_before
        lateral_speed = 0.0
        t_before = entity.t
        entity.last_lateral = entity.lateral
        jumped = False
        if entity.lateral is not None:
            entity.t = float(entity.lateral.offset_after(self, entity, dt))
            lateral_speed = _heading_speed(entity.last_lateral, entity.t - t_before, dt)
            # a step-shaped (or rigid) lateral change is a jump, not a motion: it takes
            # no travel and turns no heading (as esmini)
            jumped = bool(getattr(entity.last_lateral, "jumps", False))
            if jumped:
                lateral_speed = 0.0
        # A lane change keeps the speed along the heading: its lateral motion takes
        # its share; a lane offset moves sideways on top of the speed (as esmini plays
        # both). The rest moves the entity along its own path (parallel to the lane's
        # centre at its offset), which in a curve is longer or shorter than the centre's.
        step = abs(travel_speed) * dt
        lateral = 0.0 if jumped else entity.t - t_before
        along = step
        if getattr(entity.last_lateral, "speed_along_heading", False):
            share = getattr(entity.last_lateral, "step_lateral", None)
            split = share(dt) if share is not None else None
            split = abs(lateral) if split is None else split
            along = math.sqrt(step * step - split * split) if split < step else 0.0
        entity.traveled += math.hypot(along, lateral)
        mean_t = 0.5 * (entity.t + t_before)
        if settles:
            along = 0.0
        # an entity turned round on its lane (|heading offset| > 90°) drives against it,
        # and a negative speed (reversing) against its heading
        sign = -1.0 if math.cos(entity.heading_offset) < 0.0 else 1.0
        sign = -sign if travel_speed < 0.0 else sign
        du = self.centre_step(entity.lane, entity.u, mean_t, along) if along else 0.0
        entity.lane, entity.u = self._along_chain(entity, entity.lane, entity.u + sign * du)
        along_heading = bool(getattr(entity.last_lateral, "speed_along_heading", False))
        self._update_pose(entity, lateral_speed, along_heading)

    def track(self, dt: float) -> None:
        """After a step of ``dt`` [s], at the new time: what the state conditions need
        (standing still, acceleration, at the road's end, off road) for every entity."""
        for e in self.entities.values():
            if e.vehicle is None or not e.present:
                continue
            speed = e.current_speed
            if e.last_speed is not None and dt > 0:
                e.acceleration = (speed - e.last_speed) / dt
            e.last_speed = speed
            if abs(speed) < 1e-3:
                e.still_since = self.time if e.still_since is None else e.still_since
            else:
                e.still_since = None
            try:
                c, pos = self._locate(e)
                # off road: the reference point lies outside its nearest driving lane
                # (beyond the road's outer edge; between lanes it is always inside one)
                if pos is None:
                    pos = self.road.lane_position(e.reference_point())
                off = abs(pos.offset) > 0.5 * pos.width
            except OffRoadError:
                c, off = None, True
            if off:
                e.off_road_since = self.time if e.off_road_since is None else e.off_road_since
            else:
                e.off_road_since = None
            if c is None:
                continue
            # the lane it moves by (scripted: its own, which it may drive beside)
            lane, u = (e.lane, e.u) if e.scripted and e.lane is not None else (c.lane, c.u)
            at_end = self.road.successor(lane) is None and (
                u >= self.road.lane_length(lane) - 0.5 * e.box.length
            )
            if at_end:
                e.road_end_since = self.time if e.road_end_since is None else e.road_end_since
            else:
                e.road_end_since = None

    def prepare(self, dt: float) -> None:
        """Before a step of ``dt`` [s]: the distance actions with dynamics measure their
        gaps where every entity is now."""
        for entity in self.entities.values():
            if not entity.present:
                continue
            motion = entity.longitudinal
            own = "longitudinal" not in entity.controlled  # the storyboard's speed
            if own and hasattr(motion, "prepare") and not getattr(motion, "rigid", False):
                motion.prepare(self, dt)

    def _along_chain(
        self, entity: Entity, key: LaneKey, u: float, halt: bool = True
    ) -> tuple[LaneKey, float]:
        """``(lane, u)`` of arc length ``u`` [m] from the start of lane ``key``, on along
        its successors (or back along its predecessors where ``u`` < 0); at the end of
        the chain it is there, and a scripted entity (``halt``) stops there."""
        road = self.road
        length = road.lane_length(key)
        while u > length:
            nxt = self.next_lane(entity, key)
            if nxt is None:
                if halt:  # the lane chain ends: the entity stops at its end
                    entity.ended, entity.ended_steps = True, 0
                return key, length
            u -= length
            key, length = nxt, road.lane_length(nxt)
        while u < 0.0:
            prev = road.predecessor(key)
            if prev is None:
                if halt:
                    entity.ended, entity.ended_steps = True, 0
                return key, 0.0
            key = prev
            u += road.lane_length(key)
        return key, u

    def next_lane(self, entity: Entity, key: LaneKey) -> LaneKey | None:
        """The lane ``entity`` drives onto after lane ``key`` (None: the chain ends):
        where the lane splits, its route's choice (:mod:`~aldm_gym.scenario.routes`),
        else the road's straightest successor."""
        return next_lane(self.road, entity.route, key)

    def tow(self, straight: bool = False) -> None:
        """Move every towed trailer after its tractor (tractors first along a chain):
        its coupler to the tractor's hitch, its reference point along the line from
        where it was to the hitch (a trailer follows its hitch as a tractrix, as
        esmini moves it); ``straight``: in line behind the tractor (a connection in
        ``Init``). It moves at its tractor's speed."""
        for head in self.entities.values():
            if head.trailer is None or head.tractor is not None:
                continue
            tractor = head
            for trailer in head.chain():
                assert tractor.hitch is not None and trailer.coupler is not None
                hitch = tractor.reference_point() + tractor.hitch * tractor.forward()
                direction = tractor.forward()
                if not straight and trailer.placed:
                    pull = hitch - trailer.reference_point()
                    norm = float(np.hypot(*pull))
                    if norm > 1e-9:
                        direction = pull / norm
                heading = math.atan2(float(direction[1]), float(direction[0]))
                trailer.speed = tractor.current_speed
                self.place_world(trailer, hitch - trailer.coupler * direction, heading)
                if trailer.vehicle is not None:
                    trailer.vehicle.speed = trailer.speed
                    trailer.vehicle.on_state_update()
                tractor = trailer

    def settle(self, dt: float = 0.0) -> None:
        """After every entity moved in a step of ``dt`` [s]: the rigid distance actions
        place their actors from where their referenced entities are now.

        esmini places such an actor when it steps the action, at the distance from
        where the reference will be after its default move (``speed · dt`` on along its
        lane): the same place, unless an action that esmini stepped before moved the
        reference already. Then the actor is placed that much further on, as there."""
        moved_at = self.moved_at
        for entity in self.entities.values():
            motion = entity.longitudinal
            own = "longitudinal" not in entity.controlled  # the storyboard's speed
            if own and entity.placed and entity.present and getattr(motion, "rigid", False):
                ref = self.entities.get(getattr(motion, "ref", ""))
                ahead = 0.0
                if ref is not None:
                    ref_rank = moved_at.get(ref.name)
                    if ref_rank is not None and ref_rank < motion.rank:
                        ahead = ref.current_speed * dt
                motion.settle(self, ahead)

    def follow_lateral(self, entity: Entity, dt: float) -> None:
        """The ego after a step of ``dt`` [s] whose speed the function drives and whose
        lane the storyboard does: its progress along its lane and its speed are the
        vehicle's, its offset from the lane's centre (and its heading) the script's."""
        vehicle = entity.vehicle
        lane = self._lane(entity.lane)
        u, _ = lane.local_coordinates(entity.reference_point())
        u = float(u)
        entity.speed = float(vehicle.speed)
        entity.traveled += entity.speed * dt
        t_before = entity.t
        entity.last_lateral = entity.lateral
        if entity.lateral is not None:
            entity.t = float(entity.lateral.offset_after(self, entity, dt))
        key, u = self._along_chain(entity, entity.lane, max(u, 0.0), halt=False)
        entity.lane, entity.u = key, u
        lateral_speed = _heading_speed(entity.last_lateral, entity.t - t_before, dt)
        along = bool(getattr(entity.last_lateral, "speed_along_heading", False))
        self._update_pose(entity, lateral_speed, along)
        vehicle.speed = entity.speed

    def script_speed(self, entity: Entity, dt: float) -> None:
        """The ego whose lane the function drives and whose speed the storyboard does:
        its speed for the next step of ``dt`` [s] is the script's (its longitudinal
        motion's, else the speed it has)."""
        if entity.longitudinal is not None:
            entity.speed = float(entity.longitudinal.speed_after(self, entity, dt))
        entity.speed = min(max(entity.speed, -entity.max_speed), entity.max_speed)
        entity.vehicle.speed = entity.speed

    def sync(self, entity: Entity) -> None:
        """Read an entity that moved on its own (the active ego) into its state."""
        try:
            c = self.coordinates(entity)
        except OffRoadError:
            return
        entity.lane, entity.u = c.lane, c.u
        entity.t = c.offset * c.direction
        entity.speed = entity.velocity

    def change_lane(self, entity: Entity, key: LaneKey) -> None:
        """Make ``key`` the lane a scripted entity's offset is measured from, keeping
        its world position (``t`` becomes its offset from the new lane's centre)."""
        lane = self._lane(key)
        u, lateral = lane.local_coordinates(entity.reference_point())
        entity.lane, entity.u, entity.t = key, float(u), -float(lateral)


def _heading_speed(motion: Any, moved: float, dt: float) -> float:
    """The lateral speed [m/s] that turns the heading in a step of ``dt`` [s] in which
    the lateral ``motion`` moved the entity by ``moved`` [m]: the motion's own
    ``heading_rate`` where it gives one (a lane offset; a lane change in the step it
    arrives), else the speed of the move."""
    rate = getattr(motion, "heading_rate", None)
    if rate is not None:
        got = rate()
        if got is not None:
            return float(got)
    return moved / dt if dt > 0 else 0.0


def wrap_angle(angle: float) -> float:
    """An angle in [-pi, pi) [rad]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
