"""The private actions: what each does to its actor, step by step.

An action element makes one instance per actor when its event starts
(:class:`~aldm_gym.scenario.storyboard.ActionElement`); the instance ``start``\\ s,
then drives a *motion* of its entity (longitudinal: the speed; lateral: the offset from
the lane centre; a trajectory: both) until it is ``done``. A newer action of the same
domain on the same entity overrides a running one, which ends with a stop transition.

Dynamics (``SpeedActionDynamics``, ``LaneChangeActionDynamics``): the value changes
from its start to its target along a shape over a duration: ``step`` (at once),
``linear``, ``cubic`` (``3x² − 2x³``) or ``sinusoidal`` (``(1 − cos πx) / 2``). The
duration is the ``time`` given, or follows from a ``distance`` (travelled at the mean
of the start and target speeds, or at the current speed for lateral actions) or a
``rate``, read as the largest rate of change along the shape (linear: constant;
cubic: 1.5 × the mean; sinusoidal: π/2 × the mean). ``LaneOffsetAction``'s
``maxLateralAcc`` gives the duration of a sinusoidal (``π·√(|Δ|/2a)``) or cubic
(``√(6|Δ|/a)``) shape; a linear shape would need an unbounded acceleration and is an
error. A linear speed change by ``rate`` reaches its target at ``|rate|`` (a rate of
0 never does: the action keeps running).

``LongitudinalDistanceAction`` without ``DynamicConstraints`` places the actor at the
distance at once (as the OSC-ALKS files expect: "will position the Lead vehicle
precisely"), along its lane, and gives it the referenced entity's speed; with them, a
proportional controller within the limits closes the gap. ``continuous`` keeps either
going; otherwise the action ends when the distance is reached (within 0.1 m).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.errors import MapError, ScenarioError
from aldm_gym.scenario.positions import Position, Where
from aldm_gym.scenario.world import Entity, World

__all__ = [
    "SHAPES",
    "ActivateController",
    "AssignRoute",
    "Dynamics",
    "FollowTrajectory",
    "LaneChange",
    "LaneOffset",
    "LongitudinalDistance",
    "SpeedChange",
    "Teleport",
    "shape_value",
]

SHAPES = ("step", "linear", "cubic", "sinusoidal")
"""The dynamics shapes."""

_PEAK = {"linear": 1.0, "cubic": 1.5, "sinusoidal": math.pi / 2.0}
"""Largest rate of change along each shape, as a multiple of the mean rate."""


def shape_value(shape: str, x: float) -> float:
    """The shape's progress in [0, 1] at ``x`` in [0, 1]."""
    x = min(max(x, 0.0), 1.0)
    if shape == "step":
        return 1.0
    if shape == "linear":
        return x
    if shape == "cubic":
        return x * x * (3.0 - 2.0 * x)
    return 0.5 * (1.0 - math.cos(math.pi * x))


@dataclass(frozen=True)
class Dynamics:
    """Transition dynamics: ``shape``, ``dimension`` (``time``, ``distance``, ``rate``)
    and ``value`` [s, m, or unit/s]."""

    shape: str
    dimension: str
    value: float
    where: str = ""

    def duration(self, change: float, speed: float) -> float:
        """Duration [s] of a change of ``change`` (units of the value) at ``speed``
        [m/s] (for ``distance``)."""
        if self.shape == "step" or change == 0.0:
            return 0.0
        if self.dimension == "time":
            return max(self.value, 0.0)
        if self.dimension == "distance":
            return math.inf if speed <= 0.0 else max(self.value, 0.0) / speed
        rate = abs(self.value)
        return math.inf if rate == 0.0 else _PEAK[self.shape] * abs(change) / rate


class Instance:
    """An action's runtime on one actor: ``start``, ``done``, ``stop``."""

    def __init__(self, entity: Entity | None, where: str) -> None:
        """An instance not yet started."""
        self.entity = entity
        self.where = where
        self.done = False
        self.stopped = False

    def start(self, runner: Any) -> None:
        """Begin (may finish at once)."""
        raise NotImplementedError

    def stop(self) -> None:
        """End now (stopped by the storyboard or overridden)."""
        if not self.done:
            self.done = True
            self.stopped = True
            self._release()

    slot: str | None = None
    """The entity's motion this action drives (``longitudinal``, ``lateral``,
    ``trajectory``), if any."""

    def _release(self) -> None:
        """Take the instance's motion off its entity."""
        if self.slot is not None and self.entity is not None:
            if getattr(self.entity, self.slot) is self:
                setattr(self.entity, self.slot, None)

    def _scripted(self, runner: Any) -> Entity:
        """The actor, which must be scripted (not the active ego)."""
        entity = self.entity
        if entity is None:
            raise ScenarioError(f"{self.where}: a private action needs an actor")
        if not entity.scripted:
            raise ScenarioError(
                f"{self.where}: acts on {entity.name!r} while its controller drives it "
                "(the function under test): not supported"
            )
        return entity


def _override(entity: Entity, slot: str, motion: Any) -> None:
    """Give ``entity`` a new motion in ``slot`` (``None``: an action that completes at
    once), stopping the one it replaces."""
    old = getattr(entity, slot)
    if old is not None and old is not motion:
        old.stop()
        setattr(entity, slot, None)
    if slot in ("longitudinal", "lateral") and entity.trajectory is not None:
        entity.trajectory.stop()
    if slot == "trajectory":
        for other in ("longitudinal", "lateral"):
            if getattr(entity, other) is not None:
                getattr(entity, other).stop()
    setattr(entity, slot, motion)


# ---------------------------------------------------------------------- teleport
class Teleport(Instance):
    """``TeleportAction``: the actor is at the position at once."""

    def __init__(self, entity: Entity | None, where: str, position: Position) -> None:
        """See the class docstring."""
        super().__init__(entity, where)
        self.position = position

    def start(self, runner: Any) -> None:
        """Place the actor."""
        entity = self._scripted(runner)
        place(runner.world, entity, self.position.resolve(runner.world))
        self.done = True


def place(world: World, entity: Entity, where: Where) -> None:
    """Put ``entity`` at a resolved position."""
    if where.lane is not None:
        world.place(entity, where.lane, where.u, where.t, where.heading_offset)
    else:
        assert where.point is not None
        world.place_world(entity, where.point, where.heading)


# ---------------------------------------------------------------------- speed
class SpeedChange(Instance):
    """``SpeedAction``: towards an absolute or relative target speed."""

    slot = "longitudinal"

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        dynamics: Dynamics,
        target: Callable[[World], float],
        continuous: bool,
    ) -> None:
        """``target(world)`` is the target speed [m/s] now (relative targets follow
        their entity when ``continuous``)."""
        super().__init__(entity, where)
        self.dynamics = dynamics
        self.target = target
        self.continuous = continuous

    def start(self, runner: Any) -> None:
        """Fix the start, target and duration; a step is done at once."""
        entity = self._scripted(runner)
        world = runner.world
        self.v0 = entity.speed
        self.v1 = float(self.target(world))
        self.elapsed = 0.0
        self.T = self.dynamics.duration(self.v1 - self.v0, 0.5 * (self.v0 + self.v1))
        if self.T <= 0.0:
            entity.speed = self.v1
            if not self.continuous:
                _override(entity, "longitudinal", None)
                self.done = True
                return
        _override(entity, "longitudinal", self)

    def speed_after(self, world: World, entity: Entity, dt: float) -> float:
        """The speed [m/s] after ``dt`` [s]."""
        if self.continuous:
            self.v1 = float(self.target(world))
        self.elapsed += dt
        if self.dynamics.dimension == "rate" and self.dynamics.shape == "linear":
            step = abs(self.dynamics.value) * dt
            v = entity.speed
            v = min(v + step, self.v1) if v < self.v1 else max(v - step, self.v1)
            if v == self.v1 and not self.continuous:
                self._finish(entity)
            return v
        if self.T <= 0.0 or not math.isfinite(self.T):
            if self.T <= 0.0:
                return self.v1
            return entity.speed
        x = self.elapsed / self.T
        v = self.v0 + (self.v1 - self.v0) * shape_value(self.dynamics.shape, x)
        if x >= 1.0:
            v = self.v1
            if not self.continuous:
                self._finish(entity)
        return v

    def _finish(self, entity: Entity) -> None:
        self.done = True
        if entity.longitudinal is self:
            entity.longitudinal = None


# ---------------------------------------------------------------------- distance
class LongitudinalDistance(Instance):
    """``LongitudinalDistanceAction`` (module docstring)."""

    slot = "longitudinal"

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        ref: str,
        distance: float | None,
        time_gap: float | None,
        freespace: bool,
        leading: bool | None,
        continuous: bool,
        limits: tuple[float, float, float] | None,
        system: str = "entity",
    ) -> None:
        """``leading``: the actor leads the referenced entity (``displacement``
        ``leadingReferencedEntity``), trails it (``trailingReferencedEntity``, the
        default), or None (``any``: the side it is on when the action starts).
        ``system``: the distance is measured along the referenced entity's heading
        (``entity``), the reference line's ``s`` (``road``) or its lane (``lane``)."""
        super().__init__(entity, where)
        self.ref = ref
        self.distance = distance
        self.time_gap = time_gap
        self.freespace = freespace
        self.leading = leading
        self.continuous = continuous
        self.limits = limits
        self.system = system

    def _wanted(self, world: World) -> float:
        """Wanted distance between reference points [m], signed: > 0 when the actor is
        ahead of the referenced entity."""
        ref = world.entities[self.ref]
        entity = self.entity
        assert entity is not None
        v_ref = ref.speed if ref.scripted else ref.velocity
        d = self.distance if self.distance is not None else (self.time_gap or 0.0) * v_ref
        if self.freespace:
            if self.leading:  # ref's front to the actor's rear
                d += (ref.box.cx + 0.5 * ref.box.length) - (entity.box.cx - 0.5 * entity.box.length)
            else:  # the actor's front to ref's rear
                d += (entity.box.cx + 0.5 * entity.box.length) - (ref.box.cx - 0.5 * ref.box.length)
        return d if self.leading else -d

    def _now(self, world: World) -> float:
        """Current signed distance between the reference points [m] in the system."""
        entity = self.entity
        assert entity is not None
        ref = world.entities[self.ref]
        if self.system == "road":
            a, b = world.coordinates(entity), world.coordinates(ref)
            return (a.s - b.s) * b.direction
        if self.system == "lane":
            lane = world._lane(world.coordinates(ref).lane)
            u_a, _ = lane.local_coordinates(entity.reference_point())
            u_b, _ = lane.local_coordinates(ref.reference_point())
            return float(u_a) - float(u_b)
        return float((entity.reference_point() - ref.reference_point()) @ ref.forward())

    def start(self, runner: Any) -> None:
        """Place (no limits) or start closing the gap."""
        entity = self._scripted(runner)
        if self.leading is None:
            self.leading = self._now(runner.world) >= 0.0
        if self.limits is None:
            self._snap(runner.world, entity)
            if not self.continuous:
                _override(entity, "longitudinal", None)
                self.done = True
                return
        _override(entity, "longitudinal", self)

    def _snap(self, world: World, entity: Entity) -> None:
        """Put the actor at the distance along its lane (a rigid connection), at the
        referenced entity's speed."""
        ref = world.entities[self.ref]
        entity.speed = ref.speed if ref.scripted else ref.velocity
        c = world.coordinates(ref)
        mine = world.coordinates(entity)
        try:
            key, u, t = world.locate(
                mine.road_id, mine.lane_id, c.s + self._wanted(world) * c.direction, mine.offset
            )
            world.place(entity, key, u, t, entity.heading_offset)
            for _ in range(4):  # the road's s is a first guess where the system differs
                error = self._now(world) - self._wanted(world)
                if abs(error) < 1e-6:
                    break
                world.place(entity, entity.lane, entity.u - error, entity.t, entity.heading_offset)
        except MapError as exc:
            raise ScenarioError(
                f"{self.where}: the distance puts the actor off the map: {exc}"
            ) from None

    def speed_after(self, world: World, entity: Entity, dt: float) -> float:
        """The speed [m/s] after ``dt`` [s]."""
        ref = world.entities[self.ref]
        v_ref = ref.speed if ref.scripted else ref.velocity
        if self.limits is None:
            self._snap(world, entity)
            return entity.speed
        max_acc, max_dec, max_speed = self.limits
        error = self._now(world) - self._wanted(world)  # > 0: too far ahead
        accel = -0.5 * error + 1.0 * (v_ref - entity.speed)
        accel = min(max(accel, -max_dec), max_acc)
        v = min(max(entity.speed + accel * dt, 0.0), max_speed)
        if not self.continuous and abs(error) < 0.1 and abs(v_ref - v) < 0.1:
            self.done = True
            entity.longitudinal = None
        return v


# ---------------------------------------------------------------------- lateral
class LaneChange(Instance):
    """``LaneChangeAction``: onto a target lane, ending ``targetLaneOffset`` [m] from
    its centre (along the road's ``t``)."""

    slot = "lateral"

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        dynamics: Dynamics,
        target: Callable[[World, Entity], int],
        target_offset: float,
    ) -> None:
        """``target(world, actor) -> lane id`` of the target lane."""
        super().__init__(entity, where)
        self.dynamics = dynamics
        self.target = target
        self.target_offset = target_offset

    def start(self, runner: Any) -> None:
        """Measure the offset from the target lane; set the duration."""
        entity = self._scripted(runner)
        world = runner.world
        c = world.coordinates(entity)
        lane_id = int(self.target(world, entity))
        try:
            key, _, _ = world.locate(c.road_id, lane_id, c.s, 0.0)
        except Exception as exc:
            raise ScenarioError(f"{self.where}: no target lane {lane_id} here: {exc}") from None
        world.change_lane(entity, key)
        rec = world.road.lane_record(key)
        self.t0 = entity.t
        self.t1 = self.target_offset * rec.direction
        self.elapsed = 0.0
        self.T = self.dynamics.duration(self.t1 - self.t0, entity.speed)
        if not math.isfinite(self.T):
            raise ScenarioError(f"{self.where}: the lane change never ends (rate 0 or speed 0)")
        if self.T <= 0.0:
            _override(entity, "lateral", None)
            entity.t = self.t1
            world.place(entity, entity.lane, entity.u, entity.t, entity.heading_offset)
            self.done = True
            return
        _override(entity, "lateral", self)

    def offset_after(self, world: World, entity: Entity, dt: float) -> float:
        """The offset [m] (driver's left) after ``dt`` [s]."""
        self.elapsed += dt
        x = self.elapsed / self.T
        if x >= 1.0:
            self.done = True
            entity.lateral = None
            return self.t1
        return self.t0 + (self.t1 - self.t0) * shape_value(self.dynamics.shape, x)


class LaneOffset(Instance):
    """``LaneOffsetAction``: towards an offset from the lane centre (module docstring)."""

    slot = "lateral"

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        shape: str,
        max_lateral_acc: float | None,
        target: Callable[[World, Entity], float],
        continuous: bool,
    ) -> None:
        """``target(world, actor)`` is the target offset [m] along the road's ``t``."""
        super().__init__(entity, where)
        self.shape = shape
        self.max_acc = max_lateral_acc
        self.target = target
        self.continuous = continuous

    def start(self, runner: Any) -> None:
        """Set the duration from the largest lateral acceleration."""
        entity = self._scripted(runner)
        world = runner.world
        rec = world.road.lane_record(entity.lane)
        self.direction = rec.direction
        self.t0 = entity.t
        self.t1 = float(self.target(world, entity)) * rec.direction
        change = abs(self.t1 - self.t0)
        self.elapsed = 0.0
        if self.max_acc is None or self.shape == "step" or change == 0.0:
            self.T = 0.0
        elif self.max_acc <= 0.0:
            raise ScenarioError(f"{self.where}: maxLateralAcc must be > 0, got {self.max_acc:g}")
        elif self.shape == "sinusoidal":
            self.T = math.pi * math.sqrt(change / (2.0 * self.max_acc))
        elif self.shape == "cubic":
            self.T = math.sqrt(6.0 * change / self.max_acc)
        else:
            raise ScenarioError(
                f"{self.where}: dynamicsShape 'linear' with maxLateralAcc would need an "
                "unbounded lateral acceleration: use 'sinusoidal' or 'cubic'"
            )
        if self.T <= 0.0:
            entity.t = self.t1
            world.place(entity, entity.lane, entity.u, entity.t, entity.heading_offset)
            if not self.continuous:
                _override(entity, "lateral", None)
                self.done = True
                return
        _override(entity, "lateral", self)

    def offset_after(self, world: World, entity: Entity, dt: float) -> float:
        """The offset [m] (driver's left) after ``dt`` [s]."""
        self.elapsed += dt
        if self.continuous and self.elapsed >= self.T:
            self.t1 = float(self.target(world, entity)) * self.direction
            return self.t1
        x = 1.0 if self.T <= 0.0 else self.elapsed / self.T
        if x >= 1.0:
            if not self.continuous:
                self.done = True
                entity.lateral = None
            return self.t1
        return self.t0 + (self.t1 - self.t0) * shape_value(self.shape, x)


# ---------------------------------------------------------------------- trajectory
class FollowTrajectory(Instance):
    """``FollowTrajectoryAction`` on a ``Polyline`` with vertex times: the actor's
    reference point moves linearly between the vertices in time (``followingMode``
    ``position``; ``follow`` is played the same way), heading along the segment
    unless the vertex gives an orientation. Without times, the polyline is driven at
    the actor's current speed."""

    slot = "trajectory"

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        vertices: list[tuple[float | None, Position]],
        absolute: bool,
        scale: float,
        offset: float,
    ) -> None:
        """``vertices``: (time [s] or None, position) in order."""
        super().__init__(entity, where)
        self.vertices = vertices
        self.absolute = absolute
        self.scale = scale
        self.time_offset = offset

    def start(self, runner: Any) -> None:
        """Resolve the vertices now; timing from the action's start (relative)."""
        entity = self._scripted(runner)
        world = runner.world
        points, headings = [], []
        for _, pos in self.vertices:
            w = pos.resolve(world)
            if w.lane is not None:
                p, h = world.pose(w.lane, w.u, w.t)
                points.append(p)
                headings.append(h + w.heading_offset if w.heading_offset else None)
            else:
                assert w.point is not None
                points.append(w.point)
                headings.append(w.heading)
        self.points = np.array(points)
        self.headings = headings
        times = [t for t, _ in self.vertices]
        if all(t is not None for t in times):
            ts = np.array([float(t or 0.0) for t in times]) * self.scale + self.time_offset
            if not self.absolute:
                ts = ts + world.time
        else:
            seg = np.hypot(*np.diff(self.points, axis=0).T)
            v = max(entity.speed, 0.1)
            ts = world.time + np.concatenate(([0.0], np.cumsum(seg) / v))
        if np.any(np.diff(ts) < 0):
            raise ScenarioError(f"{self.where}: the vertices' times decrease")
        self.times = ts
        _override(entity, "trajectory", self)
        self.advance(world, entity, 0.0)

    def advance(self, world: World, entity: Entity, dt: float) -> None:
        """Move along the polyline to the world's time + ``dt``."""
        t = world.time + dt
        ts, pts = self.times, self.points
        if t <= ts[0]:
            i, x = 0, 0.0
        elif t >= ts[-1]:
            i, x = len(ts) - 2, 1.0
        else:
            i = int(np.searchsorted(ts, t, side="right")) - 1
            span = ts[i + 1] - ts[i]
            x = 1.0 if span <= 0 else (t - ts[i]) / span
        a, b = pts[i], pts[i + 1]
        point = a + x * (b - a)
        seg = b - a
        length = float(np.hypot(*seg))
        span = ts[i + 1] - ts[i]
        entity.speed = 0.0 if t >= ts[-1] or span <= 0 else length / span
        given = self.headings[i]
        heading = given if given is not None else float(math.atan2(seg[1], seg[0]))
        entity.traveled += entity.speed * dt
        world.place_world(entity, point, heading)
        if t >= ts[-1]:
            self.done = True
            entity.trajectory = None


# ---------------------------------------------------------------------- route
class AssignRoute(Instance):
    """``AssignRouteAction``: the actor's route. A scripted object follows its lane's
    chain of successors (the first successor where a lane splits), so a route is
    played when every waypoint lies on a road of that chain, and completes at once;
    a route that would need another choice at a split is an error, not ignored."""

    def __init__(self, entity: Entity | None, where: str, waypoints: list[Position]) -> None:
        """``waypoints`` in order."""
        super().__init__(entity, where)
        self.waypoints = waypoints

    def start(self, runner: Any) -> None:
        """Check the route against the actor's lane chain."""
        entity = self._scripted(runner)
        world = runner.world
        road = world.road
        roads, key, seen = set(), entity.lane, set()
        while key is not None and key not in seen:
            seen.add(key)
            roads.add(road.lane_record(key).road_id)
            key = road.successor(key)
        for pos in self.waypoints:
            w = pos.resolve(world)
            lane = w.lane if w.lane is not None else road.lane_position(w.point).lane
            if road.lane_record(lane).road_id not in roads:
                raise ScenarioError(
                    f"{pos.where}: the route leaves the roads {entity.name!r} follows along "
                    "its lane's successors; routes that choose another branch are not "
                    "supported"
                )
        self.done = True


# ---------------------------------------------------------------------- controller
class ActivateController(Instance):
    """``ActivateControllerAction``: the ego's function takes over (both domains)."""

    def __init__(
        self, entity: Entity | None, where: str, lateral: bool | None, longitudinal: bool | None
    ) -> None:
        """``None``: no change in that domain (the attribute was not given)."""
        super().__init__(entity, where)
        self.lateral = lateral
        self.longitudinal = longitudinal

    def start(self, runner: Any) -> None:
        """Hand the ego to the function under test."""
        entity = self.entity
        if entity is None or not entity.is_ego:
            raise ScenarioError(
                f"{self.where}: only the ego ({runner.ego.name!r}) has a controller here"
            )
        lateral = runner.active if self.lateral is None else self.lateral
        longitudinal = runner.active if self.longitudinal is None else self.longitudinal
        if lateral != longitudinal:
            raise ScenarioError(
                f"{self.where}: the function would drive one domain alone (lateral="
                f"{lateral}, longitudinal={longitudinal}): not supported, it drives both"
            )
        if lateral:
            runner.activate()
        else:
            runner.deactivate()
        self.done = True
