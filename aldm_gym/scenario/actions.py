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
(``√(6|Δ|/a)``) shape; a linear shape takes the cubic's duration (as esmini: a linear
shape's acceleration is unbounded at its ends); the offset follows the shape one step
late (the first step keeps it, as esmini). A linear speed change by ``rate`` reaches
its target at ``|rate|`` (a rate of 0 never does: the action keeps running); a speed
within 1e-6 m/s of its target has reached it.

``LongitudinalDistanceAction`` without ``DynamicConstraints`` (or without any
acceleration limit in them) places the actor at the distance (as the OSC-ALKS files
expect: "will position the Lead vehicle precisely"), along its lane, with the
referenced entity's speed: at every step once every entity has moved, so the order of
the entities does not matter. With them, a critically damped spring on the gap (as
esmini: stiffness 0.4 × the limit it pulls with) within the acceleration, deceleration
and speed limits and the rates ``maxAccelerationRate``/``maxDecelerationRate``, which
bound how fast the acceleration grows away from 0; a time gap is at the referenced
entity's speed. ``continuous`` keeps either going; otherwise the action ends when the
distance is reached (within 0.1 m).
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.errors import (
    InputError,
    MapError,
    NotDrivenError,
    OffRoadError,
    ScenarioError,
    ScenarioWarning,
)
from aldm_gym.scenario.positions import Position, Where
from aldm_gym.scenario.routes import RandomRoute as RandomRouteChooser
from aldm_gym.scenario.routes import RoutePlan, reachable_lanes, reachable_roads
from aldm_gym.scenario.shapes import Polyline, Shape
from aldm_gym.scenario.world import Entity, World, wrap_angle

__all__ = [
    "SHAPES",
    "ActivateController",
    "AssignRoute",
    "Dynamics",
    "FollowTrajectory",
    "GenerateTraffic",
    "Ignored",
    "LaneChange",
    "LaneOffset",
    "LateralDistance",
    "LongitudinalDistance",
    "RandomRoute",
    "SpeedChange",
    "SpeedProfile",
    "StopTraffic",
    "StoreChange",
    "Synchronize",
    "Teleport",
    "shape_value",
]

SHAPES = ("step", "linear", "cubic", "sinusoidal")
"""The dynamics shapes."""

SPRING = 0.4
"""The gap spring of a ``LongitudinalDistanceAction`` with ``DynamicConstraints``:
its stiffness is this times the acceleration limit it pulls with [1/s² per m/s²]
(esmini's choice), critically damped."""

_TIME_EPS = 1e-6
"""A transition whose elapsed time is this close to its duration [s] has ended."""

_LENGTH_EPS = 1e-6
"""A path travelled to this close to its end [m] has ended (esmini's tolerance)."""

SPEED_EPS = 1e-6
"""A speed this close to its target [m/s] has reached it (esmini's tolerance): a
target that differs from the speed in the last bits completes the action."""

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


def shape_slope(shape: str, x: float) -> float:
    """The derivative of :func:`shape_value` at ``x`` (0 outside [0, 1) and for a
    step)."""
    if shape == "step" or not 0.0 <= x < 1.0:
        return 0.0
    if shape == "linear":
        return 1.0
    if shape == "cubic":
        return 6.0 * x * (1.0 - x)
    return 0.5 * math.pi * math.sin(math.pi * x)


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

    rank: tuple[int, ...] = (2,)
    """Where the action moves its actor within a step, as esmini steps actions: those
    of ``Init`` first, then the storyboard's in document order (the runner and the
    storyboard set it)."""

    def _release(self) -> None:
        """Take the instance's motion off its entity."""
        if self.slot is not None and self.entity is not None:
            if getattr(self.entity, self.slot) is self:
                setattr(self.entity, self.slot, None)

    def _complete(self) -> None:
        """End now, having done what it does (its motion leaves the entity)."""
        self.done = True
        self._release()

    domains: tuple[str, ...] = ("lateral", "longitudinal")
    """The domains the action drives; none of them may be the function's."""

    def _scripted(self, runner: Any) -> Entity:
        """The actor, which the storyboard must drive in the action's domains (not
        the function under test)."""
        entity = self.entity
        if entity is None:
            raise ScenarioError(f"{self.where}: a private action needs an actor")
        taken = [d for d in self.domains if d in entity.controlled]
        if taken:
            raise ScenarioError(
                f"{self.where}: acts on {entity.name!r} in the {' and '.join(taken)} "
                "domain its controller drives (the function under test): not supported"
            )
        return entity


def _override(entity: Entity, slot: str, motion: Any) -> None:
    """Give ``entity`` a new motion in ``slot`` (``None``: an action that completes at
    once), stopping the one it replaces."""
    old = getattr(entity, slot)
    if old is not None and old is not motion:
        old.stop()
        setattr(entity, slot, None)
    trajectory = entity.trajectory
    if slot in ("longitudinal", "lateral") and trajectory is not None and trajectory is not motion:
        # a trajectory without timing holds the lateral domain only
        if slot == "lateral" or trajectory.timed:
            trajectory.stop()
            entity.trajectory = None
    if slot == "trajectory":
        others = ("longitudinal", "lateral") if motion is None or motion.timed else ("lateral",)
        for other in others:
            if getattr(entity, other) is not None:
                getattr(entity, other).stop()
                setattr(entity, other, None)
        if entity.trajectory is not None and entity.trajectory is not motion:
            entity.trajectory.stop()
    setattr(entity, slot, motion)


class Ignored(Instance):
    """An action with no meaning on the env (``EnvironmentAction``, light states, ...):
    it completes at once and changes nothing."""

    def start(self, runner: Any) -> None:
        """Complete."""
        self.done = True


class StoreChange(Instance):
    """``ParameterAction`` / ``VariableAction``: set a parameter or variable, or add to
    it or multiply it, at run time (conditions on it see the new value; attributes
    were resolved when the file was read, as in esmini)."""

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        store: str,
        name: str,
        op: str,
        value: Any,
        initial: Any = None,
    ) -> None:
        """``store``: ``parameters`` or ``variables``; ``op``: ``set`` (``value`` the
        attribute's text), ``add`` or ``multiply`` (``value`` a number); ``initial``:
        the value where the run's store does not hold the name yet (a parameter a
        story or a maneuver declares)."""
        super().__init__(entity, where)
        self.store, self.name, self.op, self.value = store, name, op, value
        self.initial = initial

    def start(self, runner: Any) -> None:
        """Change the value in the runner's store."""
        values = getattr(runner, self.store)
        current = values.get(self.name, self.initial)
        if self.op == "set":
            values[self.name] = _like(current, str(self.value), self.where)
        else:
            if isinstance(current, bool) or not isinstance(current, int | float):
                raise ScenarioError(f"{self.where}: {self.name} is not a number ({current!r})")
            new = current + self.value if self.op == "add" else current * self.value
            if not math.isfinite(new):
                raise ScenarioError(f"{self.where}: {self.name} becomes {new}")
            values[self.name] = (
                int(new) if isinstance(current, int) and float(new).is_integer() else new
            )
        self.done = True


def _like(current: Any, text: str, where: str) -> Any:
    """``text`` as a value of ``current``'s type."""
    try:
        if isinstance(current, bool):
            if text.strip().lower() not in ("true", "false", "1", "0"):
                raise ValueError(text)
            return text.strip().lower() in ("true", "1")
        if isinstance(current, int):
            return int(text)
        if isinstance(current, float):
            value = float(text)
            if not math.isfinite(value):
                raise ValueError(text)
            return value
    except ValueError:
        raise ScenarioError(
            f"{where}: {text!r} is not a {type(current).__name__} like the value it sets"
        ) from None
    return text


# ---------------------------------------------------------------------- teleport
class Teleport(Instance):
    """``TeleportAction``: the actor is at the position at once."""

    def __init__(self, entity: Entity | None, where: str, position: Position) -> None:
        """See the class docstring."""
        super().__init__(entity, where)
        self.position = position

    def start(self, runner: Any) -> None:
        """Place the actor: in ``Init`` at once; from the storyboard at the next step
        (the position resolved now, as esmini, which places it in the frame's action
        step after the triggers), which it does not move on in."""
        entity = self._scripted(runner)
        where = self.position.resolve(runner.world)
        if runner.world.running:
            entity.teleport = where
        else:
            place(runner.world, entity, where)
        self.done = True


class EntityChange(Instance):
    """``EntityAction``: ``DeleteEntityAction`` takes an entity out of the scenario,
    ``AddEntityAction`` puts it back at a position.

    From the storyboard the entity is out (or in) at once for every condition, and
    its vehicle leaves (or enters) the road at the next step, as a teleport moves it
    then (esmini plays both so): a deleted entity's vehicle is there at the step its
    action starts and gone from the next; an added one is placed at the position and
    moves on from it in the next step, at the speed it had. In ``Init`` they take
    effect at once; an entity that ``Init`` does not place and that an
    ``AddEntityAction`` adds starts absent (as in esmini). Adding an entity that is
    there, or deleting one that is gone, changes nothing (esmini skips both), except
    that an ``AddEntityAction`` in ``Init`` places an entity not yet placed. The
    function under test cannot be deleted.
    """

    def __init__(
        self, entity: Entity | None, where: str, name: str, position: Position | None
    ) -> None:
        """``name``: the entity's; ``position``: where to add it (None: delete it)."""
        super().__init__(entity, where)
        self.name, self.position = name, position

    def start(self, runner: Any) -> None:
        """Delete or add the entity (see the class docstring)."""
        world = runner.world
        entity = world.entities[self.name]
        self.done = True
        if self.position is None:
            if entity.is_ego:
                raise ScenarioError(f"{self.where}: deletes {self.name!r}, the function under test")
            if entity.present:
                entity.present, entity.arrival = False, None
                entity.leaving = world.running and runner.on_road(entity)
            return
        where = self.position.resolve(world)
        if entity.present:
            if not world.running and not entity.placed:
                place(world, entity, where)
            return
        entity.present = True
        if not world.running:
            place(world, entity, where)
        elif entity.leaving:  # deleted and added back before it left: it moves there
            entity.leaving = False
            entity.teleport = where
        else:
            entity.arrival = where


class GenerateTraffic(Instance):
    """``TrafficSwarmAction``, ``TrafficSourceAction``, ``TrafficSinkAction``
    (:mod:`aldm_gym.scenario.traffic`): its generator acts at every step from its start
    until the storyboard stops it (or a ``TrafficStopAction`` naming it)."""

    def __init__(self, entity: Entity | None, where: str, make: Callable[[Any], Any]) -> None:
        """``make(runner)``: the generator, its positions resolved at the start."""
        super().__init__(entity, where)
        self.make = make
        self.runner: Any = None
        self.generator: Any = None

    def start(self, runner: Any) -> None:
        """Make the generator and hand it to the runner (replacing one of its name)."""
        self.runner, self.generator = runner, self.make(runner)
        for other in list(runner.generators):
            if other.generator.name == self.generator.name:
                other.stop()
        runner.generators.append(self)

    def _release(self) -> None:
        if self.runner is not None and self in self.runner.generators:
            self.runner.generators.remove(self)


class StopTraffic(Instance):
    """``TrafficStopAction``: end the traffic action of a ``trafficName`` (its vehicles
    drive on); one of no such name running changes nothing."""

    def __init__(self, entity: Entity | None, where: str, name: str) -> None:
        """``name``: the ``trafficName`` to stop."""
        super().__init__(entity, where)
        self.name = name

    def start(self, runner: Any) -> None:
        """Stop the named traffic action."""
        for other in list(runner.generators):
            if other.generator.name == self.name:
                other.stop()
        self.done = True


class TrailerLink(Instance):
    """``ConnectTrailerAction`` / ``DisconnectTrailerAction`` on the tractor: the
    trailer is towed from the next step on (its coupler at the tractor's hitch, its
    own motions ended), or goes on by itself along its lane at the speed it has (both
    as esmini). Connecting a tractor that tows one already, or a trailer towed by
    another, is an error; disconnecting a tractor that tows nothing changes nothing
    (esmini skips it). A vehicle the function under test drives does not tow."""

    def __init__(self, entity: Entity | None, where: str, trailer: str | None) -> None:
        """``trailer``: the one to connect (None: disconnect)."""
        super().__init__(entity, where)
        self.trailer = trailer

    def start(self, runner: Any) -> None:
        """Connect or disconnect."""
        tractor = self.entity
        if tractor is None:
            raise ScenarioError(f"{self.where}: a trailer action needs an actor")
        self.done = True
        if self.trailer is None:
            if tractor.trailer is not None:
                tractor.trailer.tractor = None
                tractor.trailer = None
            return
        trailer = runner.world.entities[self.trailer]
        if tractor.trailer is trailer:
            return
        problem = ""
        if tractor.controlled or trailer.controlled:
            problem = "the function under test drives it: its vehicle does not tow"
        elif tractor.hitch is None:
            problem = f"{tractor.name!r} has no <TrailerHitch>"
        elif trailer.coupler is None:
            problem = f"{trailer.name!r} has no <TrailerCoupler>"
        elif tractor.trailer is not None:
            problem = f"{tractor.name!r} tows {tractor.trailer.name!r} already"
        elif trailer.tractor is not None:
            problem = f"{trailer.name!r} is towed by {trailer.tractor.name!r} already"
        elif trailer is tractor or tractor in trailer.chain():
            problem = f"{tractor.name!r} would tow itself through its trailers"
        if problem:
            raise ScenarioError(f"{self.where}: {problem}")
        for slot in ("longitudinal", "lateral", "trajectory"):
            motion = getattr(trailer, slot)
            if motion is not None:
                motion.stop()
                setattr(trailer, slot, None)
        tractor.trailer, trailer.tractor = trailer, tractor


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
    domains = ("longitudinal",)

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
        change = self.v1 - self.v0
        self.T = (
            0.0
            if abs(change) < SPEED_EPS
            else self.dynamics.duration(change, 0.5 * (self.v0 + self.v1))
        )
        # the entity's Performance limits stretch a change that would need more (esmini)
        limit = entity.acceleration_limit(change > 0)
        if self.T > 0.0 and math.isfinite(self.T) and self.dynamics.shape != "step":
            peak = _PEAK[self.dynamics.shape] * abs(change) / self.T
            if peak > limit:
                self.T = _PEAK[self.dynamics.shape] * abs(change) / limit
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
            limit = entity.acceleration_limit(self.v1 > entity.speed)
            step = min(abs(self.dynamics.value), limit) * dt
            v = entity.speed
            v = min(v + step, self.v1) if v < self.v1 else max(v - step, self.v1)
            if abs(v - self.v1) < SPEED_EPS:
                v = self.v1
            if v == self.v1 and not self.continuous:
                self._complete()
            return v
        if self.T <= 0.0 or not math.isfinite(self.T):
            if self.T > 0.0:
                return entity.speed
            if not self.continuous:
                return self.v1
            # following a speed: within the entity's Performance at every step (esmini)
            rise, fall = entity.max_acceleration * dt, entity.max_deceleration * dt
            return min(max(self.v1, entity.speed - fall), entity.speed + rise)
        x = self.elapsed / self.T
        v = self.v0 + (self.v1 - self.v0) * shape_value(self.dynamics.shape, x)
        if x >= 1.0:
            v = self.v1
            if not self.continuous:
                self._complete()
        return v


class SpeedProfile(Instance):
    """``SpeedProfileAction``: the entries' speeds one after another, each linearly in
    its ``time`` [s] from the speed the previous one reached (longer where that would
    need more than the limits), or without a time as fast as the limits allow (the
    ``DynamicConstraints``, capped by the entity's ``Performance``; none: at once).
    With ``entityRef`` each speed is relative to that entity's speed when the entry
    begins.

    ``followingMode="follow"`` with both jerk limits (``maxAccelerationRate``,
    ``maxDecelerationRate``) is esmini's jerk-limited profile (:class:`JerkProfile`,
    planned when the action starts); without them it is the linear one, as in esmini
    (whose jerk is then 1e10)."""

    slot = "longitudinal"
    domains = ("longitudinal",)

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        entries: list[tuple[float, float | None]],
        ref: str | None,
        limits: tuple[float, float],
        jerks: tuple[float, float] | None = None,
    ) -> None:
        """``entries``: (speed [m/s], time [s] or None); ``limits``: (acceleration,
        deceleration) [m/s²]; ``jerks``: (rising, falling) [m/s³] for ``follow`` (None:
        linear)."""
        super().__init__(entity, where)
        self.entries = entries
        self.ref = ref
        self.limits = limits
        self.jerks = jerks
        self.plan: JerkProfile | None = None

    def start(self, runner: Any) -> None:
        """Begin the first entry (``follow``: plan the whole profile)."""
        entity = self._scripted(runner)
        self.index = -1
        self.plan = None
        if self.jerks is not None:
            self.plan = self._jerk_plan(runner.world, entity)
        if self.plan is None:
            self._next(runner.world, entity)
        self.elapsed = 0.0
        _override(entity, "longitudinal", self)

    def _jerk_plan(self, world: World, entity: Entity) -> JerkProfile | None:
        """The jerk-limited plan from where the entity is (None where esmini's planner
        finds no solution: the linear profile plays)."""
        assert self.jerks is not None
        offset = world.entities[self.ref].current_speed if self.ref is not None else 0.0
        acc, dec = (
            min(self.limits[0], entity.acceleration_limit(True)),
            min(self.limits[1], entity.acceleration_limit(False)),
        )
        vertices = [(0.0, entity.speed)]
        t = 0.0
        for k, (speed, time) in enumerate(self.entries):
            target = speed + offset
            if k == 0 and time is not None and time <= _TIME_EPS:
                continue  # esmini's follow mode starts from the entity's own speed
            if time is None:
                change = target - vertices[-1][1]
                if abs(change) < 1e-6:
                    continue
                limit = acc if change > 0 else dec
                time = abs(change) / limit if math.isfinite(limit) else 0.0
            if time <= _TIME_EPS:
                return None
            t += time
            vertices.append((t, target))
        if len(vertices) < 2:
            return None
        return JerkProfile.plan(vertices, entity.acceleration, self.jerks, (acc, dec))

    def _next(self, world: World, entity: Entity) -> None:
        """Begin the next entry from the speed the entity has."""
        self.index += 1
        if self.index >= len(self.entries):
            return
        speed, time = self.entries[self.index]
        if self.ref is not None:
            other = world.entities[self.ref]
            speed += other.current_speed
        self.v0, self.v1, self.elapsed = entity.speed, speed, 0.0
        rising = self.v1 > self.v0
        limit = min(self.limits[0 if rising else 1], entity.acceleration_limit(rising))
        fastest = abs(self.v1 - self.v0) / limit if math.isfinite(limit) else 0.0
        # an entry's time is stretched where it would need more than the limits (esmini)
        self.T = fastest if time is None else max(time, fastest)

    def speed_after(self, world: World, entity: Entity, dt: float) -> float:
        """The speed [m/s] after ``dt`` [s]."""
        self.elapsed += dt
        if self.plan is not None:
            if self.elapsed >= self.plan.end - _TIME_EPS:
                self._complete()
                return self.plan.final
            return self.plan.speed(self.elapsed)
        while self.index < len(self.entries) and self.elapsed >= self.T - _TIME_EPS:
            left = self.elapsed - self.T
            entity.speed = self.v1
            self._next(world, entity)
            if self.index < len(self.entries):
                self.elapsed = left
        if self.index >= len(self.entries):
            self._complete()
            return entity.speed
        return self.v0 + (self.v1 - self.v0) * self.elapsed / self.T


@dataclass(frozen=True)
class JerkProfile:
    """A jerk-limited speed profile: segments ``(t0 [s], v0 [m/s], a0 [m/s²], j
    [m/s³])``, each ``v(t) = v0 + a0·(t − t0) + j·(t − t0)²/2`` from its ``t0`` to the
    next one's, and after the last its speed (esmini's ``follow`` mode of
    ``SpeedProfileAction``).

    :meth:`plan` builds it through the vertices ``(t, v)`` of the entries (time from
    the action's start): between two vertices, jerk up (or down) to a peak
    acceleration, hold it, and jerk back so as to arrive on time (stretched where the
    peak would pass the acceleration limits, or where the time is too short for the
    jerks); through more, a jerk first onto the first line's slope, then at every
    corner a jerk centred on it, from one line's slope to the next (the corner is cut
    by ``Δk²/(8 j)``), the last line flat.
    """

    segments: tuple[tuple[float, float, float, float], ...]

    @property
    def end(self) -> float:
        """When the last segment begins: the profile's final speed holds from then [s]."""
        return self.segments[-1][0]

    @property
    def final(self) -> float:
        """The final speed [m/s]."""
        return self.segments[-1][1]

    def speed(self, t: float) -> float:
        """The speed [m/s] at ``t`` [s] from the action's start."""
        seg = self.segments[0]
        for candidate in self.segments[1:]:
            if t > candidate[0] - 1e-6:
                seg = candidate
            else:
                break
        t0, v0, a0, j = seg
        dt = t - t0
        return v0 + a0 * dt + 0.5 * j * dt * dt

    @classmethod
    def plan(
        cls,
        vertices: list[tuple[float, float]],
        acceleration: float,
        jerks: tuple[float, float],
        limits: tuple[float, float],
    ) -> JerkProfile | None:
        """The profile through ``vertices`` from the current ``acceleration`` [m/s²]
        with ``jerks`` (rising, falling) [m/s³] > 0 within ``limits`` (acceleration,
        deceleration) [m/s²]; None where it cannot be planned (the linear profile
        plays)."""
        if len(vertices) == 2:
            return cls._two(vertices[0], vertices[1], acceleration, jerks, limits)
        return cls._through(vertices, acceleration, jerks)

    @classmethod
    def _two(
        cls,
        start: tuple[float, float],
        end: tuple[float, float],
        a_c: float,
        jerks: tuple[float, float],
        limits: tuple[float, float],
    ) -> JerkProfile | None:
        (t0, v0), (t3, v3) = start, end
        rise, fall = jerks
        span = t3 - t0
        if span <= 1e-9:
            return None
        slope = (v3 - v0) / span
        j0 = -fall if slope < a_c else rise
        j1 = rise if slope < 0 else -fall
        if j0 == j1:
            return None  # the acceleration already passes the mean slope: linear
        phi = (
            j0
            * j1
            * (
                2 * v0 * (j1 - j0)
                + a_c * a_c
                + 2 * a_c * j1 * span
                + j0 * j1 * span * span
                + 2 * v3 * (j0 - j1)
            )
        )
        if phi >= 0.0:  # a held acceleration between the jerks: on time
            t1 = (-math.sqrt(phi) - j0 * (a_c + j1 * t3) + j0 * j0 * t0) / (j0 * (j0 - j1))
        else:  # no time to hold it: the two jerks meet, later than the entry's time
            root = j1 * (j1 - j0) * (2 * j0 * (v3 - v0) + a_c * a_c)
            if root < 0.0:
                return None
            t1 = (math.sqrt(root) + (j0 - j1) * (j0 * t0 - a_c)) / (j0 * (j0 - j1))
        if t1 < t0 - 1e-9:
            return None
        peak = a_c + j0 * (t1 - t0)
        v1 = v0 + a_c * (t1 - t0) + 0.5 * j0 * (t1 - t0) ** 2
        acc, dec = limits
        if -dec <= peak <= acc:
            if phi >= 0.0:
                t2 = t3 + peak / j1
                v2 = v1 + peak * (t2 - t1)
            else:
                t2, v2 = t1, v1
                t3 = t2 - peak / j1
            segs = [(t0, v0, a_c, j0)]
            if t2 > t1:
                segs.append((t1, v1, peak, 0.0))
            segs += [(t2, v2, peak, j1), (t3, v3, 0.0, 0.0)]
            return cls(tuple(segs))
        peak = acc if peak > acc else -dec  # held at the limit: longer
        t1 = t0 + (peak - a_c) / j0
        v1 = v0 + a_c * (t1 - t0) + 0.5 * j0 * (t1 - t0) ** 2
        t3 = t1 + (v3 - v1) / peak - peak / (2 * j1)
        t2 = t3 + peak / j1
        v2 = v3 + peak * peak / (2 * j1)
        if not t0 <= t1 <= t2 <= t3:
            return None
        return cls(((t0, v0, a_c, j0), (t1, v1, peak, 0.0), (t2, v2, peak, j1), (t3, v3, 0.0, 0.0)))

    @classmethod
    def _through(
        cls, vertices: list[tuple[float, float]], a_c: float, jerks: tuple[float, float]
    ) -> JerkProfile | None:
        rise, fall = jerks
        # the nominal lines v = k·t + m through consecutive vertices; the last is flat
        lines = []
        for (ta, va), (tb, vb) in itertools.pairwise(vertices):
            k = (vb - va) / (tb - ta)
            lines.append((k, va - k * ta))
        lines.append((0.0, vertices[-1][1]))
        t0, v0 = vertices[0]
        k0 = lines[0][0]
        segs: list[tuple[float, float, float, float]] = []
        if abs(k0) > 1e-6:  # onto the first line's slope
            j = -fall if k0 < a_c else rise
            tau = (k0 - a_c) / j
            segs.append((t0, v0, a_c, j))
            t_on = t0 + tau
            v_on = v0 + a_c * tau + 0.5 * j * tau * tau
            segs.append((t_on, v_on, k0, 0.0))
            k_a, m_a = k0, v_on - k0 * t_on  # parallel to the first line, lagging it
        else:
            segs.append((t0, v0, k0, 0.0))
            k_a, m_a = k0, v0 - k0 * t0
        for k_b, m_b in lines[1:]:
            if abs(k_b - k_a) < 1e-6:
                continue
            j = -fall if k_b < k_a else rise
            tau = (k_b - k_a) / j
            cross = (m_b - m_a) / (k_a - k_b)
            t1, t3 = cross - 0.5 * tau, cross + 0.5 * tau
            if t1 < segs[-1][0] - 1e-9:
                return None  # the corner does not fit before the last one ends
            v1 = k_a * t1 + m_a
            v3 = v1 + k_a * tau + 0.5 * j * tau * tau
            segs += [(t1, v1, k_a, j), (t3, v3, k_b, 0.0)]
            k_a, m_a = k_b, v3 - k_b * t3
        return cls(tuple(segs))


class _Measured(Instance):
    """A longitudinal action that measures where every entity begins a step: the
    world calls :meth:`prepare` then (as esmini measures at the start of the frame,
    whatever order the entities move in), and the step takes the speed found."""

    next_speed: float | None = None

    def _measure(self, world: World, entity: Entity, dt: float) -> float:
        """The speed [m/s] the actor will have after ``dt`` [s], measured now."""
        raise NotImplementedError

    def prepare(self, world: World, dt: float) -> None:
        """Before a step of ``dt`` [s], with every entity where the step begins: the
        speed the actor will have."""
        entity = self.entity
        assert entity is not None
        speed = self._measure(world, entity, dt)
        if self.done:  # it ended: the speed it ends with is the entity's from now on
            entity.speed = float(speed)
        else:
            self.next_speed = speed

    def speed_after(self, world: World, entity: Entity, dt: float) -> float:
        """The speed [m/s] after ``dt`` [s]: the one :meth:`prepare` found (measured
        now if the action started within this step)."""
        speed, self.next_speed = self.next_speed, None
        return self._measure(world, entity, dt) if speed is None else speed


_LARGE = 1e10
"""esmini's "large number": a master that stands still never arrives."""

_MAX_DECELERATION = 8.0
"""The braking of a synchronisation that must stop at once [m/s²] (esmini's)."""


class Synchronize(_Measured):
    """``SynchronizeAction``: the actor reaches its target position when the master
    entity reaches its own, optionally at a final speed (absolute, or relative to the
    master's as a delta or a factor) held over a steady state (a distance or a time
    before the target). esmini's algorithm: every step both distances to go are
    measured along the road (in a straight line where the two are on different
    roads), the master's time to its target is its distance over its speed, and the
    actor's acceleration follows a linear speed profile to the final speed where one
    fits, else a two-phase one (accelerate then decelerate, or the reverse), or a stop
    and wait; without a final speed it takes the constant acceleration that arrives in
    time. It ends when either is within its tolerance of its target, when a distance
    grows again (a target passed), or when the master arrives within the step."""

    slot = "longitudinal"
    domains = ("longitudinal",)

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        master: str,
        target_master: Position,
        target: Position,
        tolerances: tuple[float, float],
        final: tuple[str, float] | None,
        steady: tuple[str, float] | None,
    ) -> None:
        """``tolerances``: (master's, actor's) [m]; ``final``: (``absolute``,
        ``delta`` or ``factor``, value); ``steady``: (``distance`` [m] or ``time`` [s],
        value)."""
        super().__init__(entity, where)
        self.master = master
        self.target_master, self.target = target_master, target
        self.tol_master, self.tol = tolerances
        self.final, self.steady = final, steady

    def start(self, runner: Any) -> None:
        """Resolve both targets now."""
        entity = self._scripted(runner)
        world = runner.world
        self.where_master = self.target_master.resolve(world)
        self.where_target = self.target.resolve(world)
        self.mode = "none"
        self.submode = "none"
        self.last = (math.inf, math.inf)
        self.steady_dist: float | None = None
        _override(entity, "longitudinal", self)

    def _final_speed(self, world: World) -> float | None:
        if self.final is None:
            return None
        kind, value = self.final
        if kind == "absolute":
            return value
        master = world.entities[self.master]
        v = master.current_speed
        return v + value if kind == "delta" else v * value

    def _to_go(self, world: World, entity: Entity, where: Where) -> float:
        """Distance [m] from the entity's reference point to a resolved position:
        along the road on one road, else in a straight line."""
        if where.lane is not None:
            point, _ = world.pose(where.lane, where.u, where.t)
            road_id = world.road.lane_record(where.lane).road_id
            s = world.road.reference_s(where.lane, where.u)
        else:
            assert where.point is not None
            point, road_id, s = where.point, None, 0.0
            try:
                pos = world.road.lane_position(where.point)
                road_id = world.road.lane_record(pos.lane).road_id
                s = world.road.reference_s(pos.lane, pos.s - world.road.chain_start(pos.lane))
            except InputError:  # off the road (or no finite point): a straight line
                road_id = None
        try:
            c = world.coordinates(entity)
        except OffRoadError:
            c = None
        if c is not None and road_id is not None and c.road_id == road_id:
            return abs(s - c.s)
        return float(np.hypot(*(np.asarray(point) - entity.reference_point())))

    def _finish(self, speed: float) -> float:
        self._complete()
        return speed

    def _measure(self, world: World, entity: Entity, dt: float) -> float:
        master = world.entities[self.master]
        dist = self._to_go(world, entity, self.where_target)
        master_dist = self._to_go(world, master, self.where_master)
        done = (
            dist < self.tol + 1e-6
            or master_dist < self.tol_master + 1e-6
            or dist > self.last[0]
            or master_dist > self.last[1]
        )
        self.last = (dist, master_dist)
        dist = max(dist - self.tol, 1e-6)
        master_dist = max(master_dist - self.tol_master, 1e-6)
        v_master = master.current_speed
        time_to_go = master_dist / v_master if v_master > 1e-6 else _LARGE
        if v_master > 1e-6 and time_to_go < dt:
            done = True
        final = self._final_speed(world)
        v = entity.speed
        if done:
            return self._finish(v if final is None else final)
        if final is None:
            average = dist / time_to_go
            return v + (2.0 * average - v - v) / time_to_go * dt
        if self.steady is not None and self.mode != "steady":
            if self.steady_dist is None:
                kind, value = self.steady
                self.steady_dist = value * final if kind == "time" else value
            steady_time = self.steady_dist / final if final > 0 else _LARGE
            if dist - self.steady_dist < 1e-6 or time_to_go - steady_time < 1e-6:
                self.mode, self.submode = "steady", "none"
            else:
                dist -= self.steady_dist
                time_to_go -= steady_time
        if self.mode == "steady":
            return final
        if self.mode == "waiting":
            if time_to_go >= _LARGE:
                return v
            self.mode = "none"
        if self.mode == "stop_now":
            v -= _MAX_DECELERATION * dt
            if v < 0.0:
                self.mode = "waiting"
                return 0.0
            return v
        if self.mode == "stopped":
            if final <= 0.0 or time_to_go < 2.0 * dist / final:
                self.mode = "linear"
            else:
                return 0.0
        if self.mode == "linear":
            if time_to_go > _LARGE - 1:
                return 0.0
            return max(
                0.0,
                2.0 * dist / time_to_go - max(0.0, final)
                if time_to_go > 1e-3 and dist > 1e-3
                else 0.0,
            )
        if self.mode == "nonlinear" and time_to_go < _LARGE:
            if abs(v - (2.0 * dist / time_to_go - final)) < 0.1:
                self.mode = "linear"  # on the straight profile: reach it with a constant rate
                return v
        if self.mode == "none":
            self.mode = "nonlinear"
            self.submode = "convex" if (final + v) / 2.0 < dist / time_to_go else "concave"
        s_, t_, v0, v1 = dist, time_to_go, v, final
        root = math.sqrt(2.0) * math.sqrt(
            max(2.0 * s_ * s_ - 2.0 * (v1 + v0) * t_ * s_ + (v1 * v1 + v0 * v0) * t_ * t_, 0.0)
        )
        if abs(v1 - v0) < 1e-6:
            vx = (s_ - t_ / 2.0 * v0) / (t_ / 2.0)
            acc = (vx - v0) / (t_ / 2.0)
        else:
            x1 = -(root + 2.0 * s_ - 2.0 * v1 * t_) / (2.0 * (v1 - v0))
            x2 = -(-root + 2.0 * s_ - 2.0 * v1 * t_) / (2.0 * (v1 - v0))
            vx1, vx2 = (2.0 * s_ - root) / (2.0 * t_), (2.0 * s_ + root) / (2.0 * t_)
            if 0.0 < x1 < t_:
                vx, acc = vx1, (vx1 - v0) / x1
            elif 0.0 < x2 < t_:
                vx, acc = vx2, (vx2 - v0) / x2
            else:
                vx, acc = 0.0, 0.0
        if (self.submode == "concave" and acc > 0) or (self.submode == "convex" and acc < 0):
            self.mode = "linear"  # the apex of the profile: keep the speed for this step
            acc = 0.0
        if self.mode == "nonlinear" and vx < 0.0:
            # stop on the way, wait, then go on: decelerate in proportion
            t1 = 2.0 * v0 * s_ / (v0 * v0 + v1 * v1) if v0 * v0 + v1 * v1 > 0 else 0.0
            acc = -v0 / t1 if abs(t1) > 1e-6 else 0.0
            if t1 * v0 / 2.0 > s_ / 2.0:
                acc = -_MAX_DECELERATION
                self.mode = "stop_now"
            if v0 + acc * dt < 0.0:
                self.mode = "stopped"
                return 0.0
        return v + acc * dt


# ---------------------------------------------------------------------- distance
class LongitudinalDistance(_Measured):
    """``LongitudinalDistanceAction`` (module docstring)."""

    slot = "longitudinal"
    domains = ("longitudinal",)

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
        limits: tuple[float, float, float, float, float] | None,
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
        v_ref = ref.current_speed
        # a time gap is at the referenced entity's speed (esmini's choice)
        v_follower = v_ref
        d = self.distance if self.distance is not None else (self.time_gap or 0.0) * v_follower
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

    @property
    def rigid(self) -> bool:
        """Without ``DynamicConstraints``: the actor is placed at the distance."""
        return self.limits is None

    def start(self, runner: Any) -> None:
        """Take the longitudinal domain; the first step places the actor (rigid) or
        starts closing the gap."""
        entity = self._scripted(runner)
        if self.leading is None:
            self.leading = self._now(runner.world) >= 0.0
        self.acceleration = 0.0
        _override(entity, "longitudinal", self)
        if self.rigid and not runner.world.running and runner.world.entities[self.ref].placed:
            self.settle(runner.world)  # in Init: the actor starts there (else: first step)

    def settle(self, world: World, ahead: float = 0.0) -> None:
        """After every entity moved in a step: put the actor at the distance from where
        the referenced entity is now (rigid), ``ahead`` [m] further on along the
        reference's direction (:meth:`World.settle`); a non-continuous action ends
        there."""
        entity = self.entity
        assert entity is not None
        self._snap(world, entity, ahead)
        if not self.continuous:
            self._complete()

    def _snap(self, world: World, entity: Entity, ahead: float = 0.0) -> None:
        """Put the actor at the distance along its lane (a rigid connection), ``ahead``
        [m] further on along the reference's direction, at the referenced entity's
        speed."""
        ref = world.entities[self.ref]
        entity.speed = ref.current_speed
        c = world.coordinates(ref)
        mine = world.coordinates(entity)
        try:
            key, u, t = world.locate(
                mine.road_id,
                mine.lane_id,
                c.s + self._wanted(world) * c.direction + ahead * c.direction,
                mine.offset,
            )
            world.place(entity, key, u, t, entity.heading_offset)
            for _ in range(4):  # the road's s is a first guess where the system differs
                error = self._now(world) - self._wanted(world) - ahead
                if abs(error) < 1e-6:
                    break
                world.place(entity, entity.lane, entity.u - error, entity.t, entity.heading_offset)
        except (MapError, OffRoadError) as exc:
            raise ScenarioError(
                f"{self.where}: the distance puts the actor off the map: {exc}"
            ) from None

    def speed_after(self, world: World, entity: Entity, dt: float) -> float:
        """The speed [m/s] after ``dt`` [s]: a rigid action keeps it (:meth:`settle`
        places the actor); else the spring's (:meth:`prepare`)."""
        if self.limits is None:
            return entity.speed
        return super().speed_after(world, entity, dt)

    def _measure(self, world: World, entity: Entity, dt: float) -> float:
        """A critically damped spring on the gap, within the limits and their rates."""
        assert self.limits is not None
        ref = world.entities[self.ref]
        v_ref = ref.current_speed
        max_acc, max_dec, max_speed, acc_rate, dec_rate = self.limits
        max_acc = min(max_acc, entity.max_acceleration)
        max_dec = min(max_dec, entity.max_deceleration)
        max_speed = min(max_speed, entity.max_speed)
        error = self._now(world) - self._wanted(world)  # > 0: too far ahead
        # the spring's stiffness scales with the acceleration limit when the actor is
        # too far ahead, with the deceleration limit when it lags (esmini's choice)
        pull = max_acc if error > 0.0 else max_dec
        k = SPRING * (pull if math.isfinite(pull) else min(max_acc, max_dec))
        accel = -k * error - 2.0 * math.sqrt(k) * (entity.speed - v_ref)
        accel = min(max(accel, -max_dec), max_acc)
        # the rates limit how fast the acceleration grows away from 0 [m/s³]
        if accel < 0.0 and accel < self.acceleration:
            accel = max(self.acceleration - dec_rate * dt, accel)
        elif accel > 0.0 and accel > self.acceleration:
            accel = min(self.acceleration + acc_rate * dt, accel)
        self.acceleration = accel
        v = min(max(entity.speed + accel * dt, -max_speed), max_speed)  # it may reverse
        if not self.continuous and abs(error) < 0.1:  # the distance is reached (esmini)
            self._complete()
        return v


# ---------------------------------------------------------------------- lateral
class LaneChange(Instance):
    """``LaneChangeAction``: onto a target lane, ending ``targetLaneOffset`` [m] from
    its centre (along the road's ``t``)."""

    slot = "lateral"
    domains = ("lateral",)
    speed_along_heading = True
    """The entity's speed is along its heading: the lateral motion takes its share."""

    @property
    def jumps(self) -> bool:
        """Whether the change is a jump (a step shape: no duration)."""
        return getattr(self, "T", 1.0) <= 0.0

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
        key = None
        try:
            key, _, _ = world.locate(c.road_id, lane_id, c.s, 0.0)
            rec = world.road.lane_record(key)
            same = rec.direction == c.direction
        except NotDrivenError:  # a shoulder, a border: its centre, beside the road
            try:
                x, y, _ = world.road.lane_pose(c.road_id, lane_id, c.s)
            except MapError as exc:
                raise ScenarioError(f"{self.where}: no target lane {lane_id} here: {exc}") from None
            point, same = np.array([x, y]), False
        except Exception as exc:
            raise ScenarioError(f"{self.where}: no target lane {lane_id} here: {exc}") from None
        if same and key is not None:
            world.change_lane(entity, key)
            self.t1 = self.target_offset * rec.direction
        else:
            # A lane of the other driving direction, or one not driven: a lane change
            # is a lateral transition, the entity keeps its direction of travel. It
            # goes on moving by its own lane, towards the target lane's centre (+ the
            # offset) measured across it.
            if key is not None:
                point, _ = world.pose(key, world.road.lane_u(key, c.s), 0.0)
            _, right = world._lane(entity.lane).local_coordinates(point)
            own = world.road.lane_record(entity.lane).direction
            self.t1 = -float(right) + self.target_offset * own
        self.t0 = entity.t
        self.elapsed = 0.0
        self.T = self.dynamics.duration(self.t1 - self.t0, entity.speed)
        if not math.isfinite(self.T):
            raise ScenarioError(f"{self.where}: the lane change never ends (rate 0 or speed 0)")
        # a step shape too moves the entity at the next step (esmini: in the frame's
        # action step, seen in the next frame)
        _override(entity, "lateral", self)

    def offset_after(self, world: World, entity: Entity, dt: float) -> float:
        """The offset [m] (driver's left) after ``dt`` [s]."""
        # the shape's rate where the step begins: in time (and rate) dimensions it
        # turns the heading and splits the speed between the two motions (esmini)
        self.rate = 0.0
        if self.T > 0.0 and self.dynamics.dimension != "distance":
            x0 = self.elapsed / self.T
            self.rate = (self.t1 - self.t0) / self.T * shape_slope(self.dynamics.shape, x0)
        self.elapsed += dt
        x = self.elapsed / self.T if self.T > 0.0 else 1.0
        if x >= 1.0:
            self._complete()
            return self.t1
        return self.t0 + (self.t1 - self.t0) * shape_value(self.dynamics.shape, x)

    rate: float | None = None
    """The lateral speed [m/s] (driver's left) where the last step began (None: the
    step's own move, in the distance dimension)."""

    def heading_rate(self) -> float | None:
        """The lateral speed that turns the heading: 0 in the step the change arrives
        (esmini straightens the entity along its lane then, whatever the shape), else
        the shape's rate where the step began (None in the distance dimension: the
        step's move)."""
        if self.done:
            return 0.0
        if self.dynamics.dimension == "distance":
            return None
        return self.rate

    def step_lateral(self, dt: float) -> float | None:
        """The lateral motion [m] that takes its share of a step's travel: the shape's
        rate where the step began times ``dt`` (esmini), None in the distance
        dimension (the step's own move)."""
        if self.rate is None or self.dynamics.dimension == "distance":
            return None
        return abs(self.rate) * dt


LATERAL_DONE = 0.01
"""A ``LateralDistanceAction`` that is not continuous ends within this of its
distance [m] (as esmini)."""


class LateralDistance(Instance):
    """``LateralDistanceAction``: the actor keeps ``distance`` [m] across the road from
    the referenced entity (between the boxes with ``freespace``, taken as along the
    road, else the reference points), on its left or right (``any``: the side it is
    on when the action starts), measured along the road's ``t``.

    As esmini plays it: the first step after the start only measures. Then, without
    ``DynamicConstraints`` (or with none of ``maxAcceleration``, ``maxDeceleration``,
    ``maxSpeed``) the actor is put at the distance at every step, on top of its travel,
    and turned towards where it moved; with
    ``maxAcceleration`` a critically damped spring (stiffness 0.4 × it) drives a
    lateral speed, its acceleration within ``maxAcceleration`` and changing at most
    ``maxAccelerationRate`` per second, the speed within ``maxSpeed`` and the
    actor's speed; with only ``maxSpeed`` (or ``maxDeceleration``) the actor moves
    towards the distance at that lateral speed (at most its own speed) and arrives in
    the step it would pass it. A moving actor keeps its speed along its heading: the
    lateral speed takes its share. Not ``continuous``: it ends once the distance is
    within :data:`LATERAL_DONE` at the start of a step (the step still moves it), or
    when the lateral speed alone arrives."""

    slot = "lateral"
    domains = ("lateral",)

    @property
    def speed_along_heading(self) -> bool:
        """A moving actor's lateral speed takes its share of its speed (as esmini)."""
        return self.limits is not None

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        ref: str,
        distance: float,
        freespace: bool,
        left: bool | None,
        continuous: bool,
        limits: tuple[float, float, float, float] | None,
    ) -> None:
        """``left``: the actor is on the referenced entity's left (None: any);
        ``limits``: ``(maxAcceleration, maxDeceleration, maxSpeed,
        maxAccelerationRate)``, inf where not given (None: put there at once)."""
        super().__init__(entity, where)
        self.ref, self.distance, self.freespace = ref, distance, freespace
        self.left, self.continuous, self.limits = left, continuous, limits

    def start(self, runner: Any) -> None:
        """Take the lateral domain; the side if ``any``."""
        entity = self._scripted(runner)
        world = runner.world
        if self.left is None:
            self.left = world.road_t(entity) >= world.road_t(world.entities[self.ref])
        self.lateral_speed = 0.0
        self.acceleration = 0.0
        self.begun = False
        self.ref_before: np.ndarray | None = None
        _override(entity, "lateral", self)

    def _target(self, world: World, entity: Entity) -> float:
        """The actor's wanted offset [m] to the driver's left of its lane's centre."""
        ref = world.entities[self.ref]
        side = 1.0 if self.left else -1.0
        gap = self.distance
        if self.freespace:  # the boxes' half widths (boxes along the road)
            gap += 0.5 * (ref.box.width + entity.box.width)
        wanted_t = world.road_t(ref) + side * gap
        c = world.coordinates(entity)
        return entity.t + (wanted_t - world.road_t(entity)) * c.direction

    def offset_after(self, world: World, entity: Entity, dt: float) -> float:
        """The offset [m] (driver's left) after ``dt`` [s]."""
        if not self.begun:  # the first step measures only (as esmini)
            self.begun = True
            return entity.t
        target = self._target(world, entity)
        error = target - entity.t
        if not self.continuous and abs(error) < LATERAL_DONE:
            self._complete()  # the step still moves it
        if self.limits is None or dt <= 0:
            return target
        max_acc, _, max_speed, max_rate = self.limits
        top = max(min(max_speed, abs(entity.speed)) - 1e-6, 0.0)
        if math.isfinite(max_acc):
            k = SPRING * max_acc
            # damped relative to the reference's lateral speed: its last step's move
            # across its own heading (esmini's)
            ref = world.entities[self.ref]
            point = ref.reference_point()
            ref_lateral = 0.0
            if self.ref_before is not None and dt > 0:
                ref_lateral = float((point - self.ref_before) @ ref.left()) / dt
            self.ref_before = point.copy()
            damping = 2.0 * math.sqrt(k) * (self.lateral_speed - ref_lateral)
            wanted = k * error - damping
            change = max_rate * dt
            acc = self.acceleration + min(max(wanted - self.acceleration, -change), change)
            self.acceleration = min(max(acc, -max_acc), max_acc)
            speed = self.lateral_speed + self.acceleration * dt
            self.lateral_speed = min(max(speed, -top), top)
        else:  # a speed limit alone: at that speed, arriving in the step it would pass
            speed = math.copysign(top, error) if error != 0.0 else top
            if (error - speed * dt >= 0.0) != (error >= 0.0):
                speed = error / dt
                if not self.continuous:
                    self._complete()
            self.lateral_speed = speed
        return entity.t + self.lateral_speed * dt


class LaneOffset(Instance):
    """``LaneOffsetAction``: towards an offset from the lane centre (module docstring)."""

    slot = "lateral"
    domains = ("lateral",)
    moves_along = False
    """It sets the offset only: the entity travels after every action, at the speed
    they left (esmini's lane offset does not move the entity on, a lane change does)."""

    @property
    def jumps(self) -> bool:
        """Whether the change is a jump (a step shape: no duration)."""
        return getattr(self, "T", 1.0) <= 0.0

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
        self.elapsed, self.x = 0.0, 0.0
        if self.max_acc is None or self.shape == "step" or change == 0.0:
            self.T = 0.0
        elif self.max_acc <= 0.0:
            raise ScenarioError(f"{self.where}: maxLateralAcc must be > 0, got {self.max_acc:g}")
        elif self.shape == "sinusoidal":
            self.T = math.pi * math.sqrt(change / (2.0 * self.max_acc))
        else:  # cubic; linear (its acceleration is unbounded) takes cubic's duration
            self.T = math.sqrt(6.0 * change / self.max_acc)
        # a step shape too moves the entity at the next step (esmini: in the frame's
        # action step, seen in the next frame)
        _override(entity, "lateral", self)

    def offset_after(self, world: World, entity: Entity, dt: float) -> float:
        """The offset [m] (driver's left) after ``dt`` [s]: the shape at the time the
        step began (a step late, as esmini plays it: the first step keeps the offset),
        the target at the first step that begins after the duration."""
        if self.elapsed >= self.T - _TIME_EPS:
            self.x = 1.0
            if self.continuous:
                self.t1 = float(self.target(world, entity)) * self.direction
            else:
                self._complete()
            return self.t1
        x = self.elapsed / self.T
        self.elapsed += dt
        self.x = x
        return self.t0 + (self.t1 - self.t0) * shape_value(self.shape, x)

    x: float = 1.0
    """The shape's parameter of the last step (where the offset it set lies)."""

    def heading_rate(self) -> float:
        """The lateral speed [m/s] (driver's left) that turns the entity's heading: the
        shape's rate where the last step's offset lies on it, which is the offset's
        motion in the next step (esmini turns the heading with the shape while the
        offset follows it a step late; 0 once the offset is reached)."""
        if self.T <= 0.0:
            return 0.0
        return (self.t1 - self.t0) / self.T * shape_slope(self.shape, self.x)


# ---------------------------------------------------------------------- trajectory
class FollowTrajectory(Instance):
    """``FollowTrajectoryAction`` on a shape (``Polyline``, ``Clothoid``,
    ``ClothoidSpline``, ``Nurbs``: :mod:`~aldm_gym.scenario.shapes`).

    With vertex times (``TimeReference/Timing``) the trajectory drives both domains:
    with ``followingMode`` ``position`` the actor's reference point moves linearly
    between the vertices in time, at the speed that takes; with ``follow`` a polyline's
    speed changes at a constant acceleration along each segment from the actor's
    speed on (esmini's plan: every vertex at its time, the speed continuous). After
    the last time it goes on at the speed of its last step. Without
    them (``TimeReference/None``) it drives the lateral domain only: the actor moves
    along the polyline at its own speed, which the longitudinal domain keeps setting
    (a ``SpeedAction`` during the trajectory changes the speed and leaves the path,
    OpenSCENARIO 1.3 §6.9). The heading is a vertex's ``h`` where the vertex gives an
    orientation, else the direction of the segment. At the path's end the actor keeps
    its speed and drives on along its lane.
    """

    slot = "trajectory"

    def __init__(
        self,
        entity: Entity | None,
        where: str,
        shape: Shape,
        timing: tuple[bool, float, float] | None,
        initial: float = 0.0,
        follow: bool = False,
    ) -> None:
        """``shape``: the path (:mod:`~aldm_gym.scenario.shapes`); ``timing``:
        ``(absolute, scale, offset [s])`` of ``TimeReference/Timing``, None without
        timing (the shape's times, if any, are then not used); ``initial``: where
        along the path an untimed one begins [m] (``initialDistanceOffset``);
        ``follow``: ``followingMode="follow"`` (a timed polyline's speed changes
        smoothly, :meth:`_vertex_speeds`)."""
        super().__init__(entity, where)
        self.shape = shape
        self.timing = timing
        self.initial = initial
        self.follow = follow
        self.timed = False

    def start(self, runner: Any) -> None:
        """Resolve the shape now; timing from the action's start (relative)."""
        entity = self._scripted(runner)
        world = runner.world
        path = self.shape.resolve(world, entity)
        self.points = path.points
        self.headings = path.headings
        self.smooth = path.smooth
        seg = np.hypot(*np.diff(self.points, axis=0).T)
        self.arc = np.concatenate(([0.0], np.cumsum(seg)))
        """Arc length [m] at each point."""
        self.timed = self.timing is not None and path.times is not None
        self.along = 0.0 if self.timed else min(self.initial, float(self.arc[-1]))
        if self.timed:
            assert self.timing is not None and path.times is not None
            absolute, scale, offset = self.timing
            ts = np.asarray(path.times, dtype=float) * scale + offset
            if not absolute:
                ts = ts + world.time
            if np.any(np.diff(ts) < 0) or not np.all(np.isfinite(ts)):
                raise ScenarioError(f"{self.where}: the trajectory's times decrease")
            self.times = ts
            polyline = self.follow and isinstance(self.shape, Polyline)
            self.vertex_speeds = self._vertex_speeds(entity.speed) if polyline else None
            self.timed_along = self._along_at_time(world.time)
        _override(entity, "trajectory", self)
        # The actor is put on the path by the first step (as esmini, which steps a new
        # action in the frame it starts in: its first logged pose is a step along).
        if not world.running and not entity.placed:
            # in Init, an actor nothing placed starts where the path does (as esmini)
            along = self._along_at_time(world.time) if self.timed else self.along
            self._place(world, entity, *self._at_length(along))

    def _vertex_speeds(self, speed: float) -> np.ndarray:
        """A timed polyline's speed [m/s] at each vertex with ``followingMode="follow"``,
        as esmini plans it: the actor's ``speed`` at the first, then each segment at a
        constant acceleration that covers its length in its time (``v[i+1] = 2 L / T -
        v[i]``). With ``position``, and on a sampled curve (clothoids, NURBS), there are
        none: each segment moves at its mean speed, every vertex at its time."""
        lengths = np.diff(self.arc)
        spans = np.diff(self.times)
        v = np.empty(len(self.arc))
        v[0] = speed
        for k in range(len(lengths)):
            v[k + 1] = 2.0 * lengths[k] / spans[k] - v[k] if spans[k] > 0.0 else v[k]
        return v

    def _along_at_time(self, t: float) -> float:
        """Arc length [m] along the path at time ``t`` [s] (timed): each segment at the
        constant acceleration between its vertices' speeds (a polyline), else at its
        mean speed; the start before the first time, the end after the last."""
        ts, arc = self.times, self.arc
        if t <= ts[0]:
            return float(arc[0])
        if t >= ts[-1]:
            return float(arc[-1])
        i = int(np.searchsorted(ts, t, side="right")) - 1
        span = ts[i + 1] - ts[i]
        length = arc[i + 1] - arc[i]
        tau = t - ts[i]
        v = self.vertex_speeds
        if span <= 0.0:
            return float(arc[i + 1])
        if v is None:
            return float(arc[i] + length * tau / span)
        return float(arc[i] + v[i] * tau + (v[i + 1] - v[i]) * tau * tau / (2.0 * span))

    vertex_speeds: np.ndarray | None = None
    """A timed polyline's speed [m/s] at each vertex (:meth:`_vertex_speeds`)."""

    def _at_length(self, s: float) -> tuple[int, float]:
        """Segment and fraction along it at arc length ``s`` [m]."""
        arc = self.arc
        if s >= arc[-1]:
            return len(arc) - 2, 1.0
        i = min(int(np.searchsorted(arc, s, side="right")) - 1, len(arc) - 2)
        span = arc[i + 1] - arc[i]
        return i, 1.0 if span <= 0 else (s - arc[i]) / span

    def _place(self, world: World, entity: Entity, i: int, x: float) -> None:
        a, b = self.points[i], self.points[i + 1]
        seg = b - a
        given, after = self.headings[i], self.headings[i + 1]
        heading = given if given is not None else float(math.atan2(seg[1], seg[0]))
        if self.smooth and given is not None and after is not None:
            heading = given + x * wrap_angle(after - given)  # along a sampled curve
        world.place_world(entity, a + x * seg, heading)

    def advance(self, world: World, entity: Entity, dt: float) -> None:
        """Move along the polyline by ``dt`` [s]: to the world's time + ``dt``
        (timed), or by the actor's speed (untimed, after its longitudinal motion)."""
        if self.timed:
            # the place at the step's end time; the speed is the step's travel over
            # its time while the trajectory runs (esmini), and is kept after its end
            t = world.time + dt
            along = self._along_at_time(t)
            if dt > 0.0 and t < self.times[-1] + _TIME_EPS:
                entity.speed = abs(along - self.timed_along) / dt
            self.timed_along = along
            i, x = self._at_length(along)
            finished = t >= self.times[-1]
        else:
            # The speed that moves the actor: the one before this step's longitudinal
            # update if the trajectory comes before that action in the document (esmini
            # steps the running actions in document order), else the updated one.
            speed = entity.speed
            motion = entity.longitudinal
            if motion is not None:
                entity.speed = float(motion.speed_after(world, entity, dt))
                if motion.rank < self.rank:
                    speed = entity.speed
            else:
                speed = entity.speed
            entity.speed = min(max(entity.speed, -entity.max_speed), entity.max_speed)
            speed = min(max(speed, 0.0), entity.max_speed)
            self.along += speed * dt
            i, x = self._at_length(self.along)
            finished = self.along >= self.arc[-1] - _LENGTH_EPS
        entity.traveled += entity.speed * dt
        self._place(world, entity, i, x)
        if finished:
            self._complete()
            rest = 0.0
            if not self.timed and self.along > self.arc[-1]:
                rest = self.along - float(self.arc[-1])
            elif self.timed:  # the part of this step after the last time
                rest = min(world.time + dt - float(self.times[-1]), dt) * entity.speed
            if rest > 0.0:
                # the rest of the step's travel goes on along the end heading (as esmini)
                h = entity.heading
                end = entity.reference_point() + rest * np.array([math.cos(h), math.sin(h)])
                world.place_world(entity, end, h)


# ---------------------------------------------------------------------- route
class AssignRoute(Instance):
    """``AssignRouteAction`` (and ``AcquirePositionAction``, a route to one position):
    the actor's route, which chooses its branch where its lane splits
    (:class:`~aldm_gym.scenario.routes.RoutePlan`); the action completes at once.
    A waypoint the actor can reach only from a lane beside its own (an exit ramp from
    a through lane: a lane change would be needed, which a route does not make) is
    passed by, as esmini plays it: the actor follows its lane, with a
    :class:`~aldm_gym.errors.ScenarioWarning`. One on a road it cannot reach either
    way (behind it, the other carriageway) is an error."""

    def __init__(self, entity: Entity | None, where: str, waypoints: list[Position]) -> None:
        """``waypoints`` in order."""
        super().__init__(entity, where)
        self.waypoints = waypoints

    def start(self, runner: Any) -> None:
        """Check the route against the lanes the actor can reach, and assign it."""
        entity = self._scripted(runner)
        if entity.lane is None:
            raise ScenarioError(f"{self.where}: {entity.name!r} is on no lane to route from")
        road = runner.world.road
        roads, here = [], [entity.lane]
        for pos in self.waypoints:
            road_id = road.lane_record(runner.world.lane_of(pos.resolve(runner.world))).road_id
            ahead = reachable_lanes(road, here)
            on_road = [k for k in ahead if road.lane_record(k).road_id == road_id]
            if on_road:
                roads.append(road_id)
                here = on_road  # the lanes of the waypoint's road it can be on
                continue
            # the lanes beside those it can reach, driven the same way
            beside = [m for k in ahead for m in road.siblings(k)]
            if road_id not in reachable_roads(road, beside):
                raise ScenarioError(
                    f"{pos.where}: the route leaves the roads {entity.name!r} can reach "
                    f"(road {road_id!r} is on none of them, nor on a lane beside its own)"
                )
            warnings.warn(
                f"{pos.where}: {entity.name!r} cannot reach road {road_id!r} along its "
                "lanes without a lane change, which a route does not make: it follows its "
                "lane (as esmini plays it)",
                ScenarioWarning,
                stacklevel=2,
            )
        entity.route = RoutePlan(roads)
        self.done = True


class RandomRoute(Instance):
    """``RandomRouteAction``: at every split of its lanes from now on, the actor takes
    a branch drawn with equal chances (:class:`~aldm_gym.scenario.routes.RandomRoute`),
    from a generator seeded by the episode's (the same seed, the same branches). The
    action completes at once."""

    def start(self, runner: Any) -> None:
        """Assign the random route."""
        entity = self._scripted(runner)
        seed = int(runner.rng.integers(2**63))
        entity.route = RandomRouteChooser(np.random.default_rng(seed))
        self.done = True


# ---------------------------------------------------------------------- controller
class ActivateController(Instance):
    """``ActivateControllerAction``: the ego's function takes over the domains given
    (lateral: LKA; longitudinal: ACC/AEB; both), the storyboard keeps the others."""

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
        domains = runner.domains
        lateral = "lateral" in domains if self.lateral is None else self.lateral
        longitudinal = "longitudinal" in domains if self.longitudinal is None else self.longitudinal
        runner.control(lateral, longitudinal)
        self.done = True
