"""One run of a scenario on the env's road: entities, ``Init``, the storyboard's clock.

:class:`ScenarioRunner` is what the env's scenario scene holds for an episode: it
makes the entities' vehicles, plays ``Init`` at time 0, and after every simulation step
moves the ego while the scenario still drives it, then updates the storyboard. The
ego is the function under test: until an ``ActivateControllerAction`` hands it over it
holds the lane and speed its ``Init`` gave it (scripted like the other entities);
from then on the env's function (LKA on the detected lanes, ACC and AEB, or the
user's policy) drives it, with its set speed at the speed it had.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from aldm_gym.errors import InputError, ScenarioError
from aldm_gym.scenario.actions import place
from aldm_gym.scenario.reader import Scenario
from aldm_gym.scenario.world import Entity, ScenarioVehicle, World

__all__ = ["ScenarioRunner", "choose_ego"]


def _idm_vehicle(road: Any, position: Any, heading: float, speed: float) -> Any:
    """highway-env's IDM/MOBIL vehicle (a generated vehicle where the env gives none)."""
    from highway_env.vehicle.behavior import IDMVehicle

    return IDMVehicle(road, position, heading, speed)


def choose_ego(scenario: Scenario, name: str = "") -> str:
    """The name of the entity the env drives: ``name`` when given, else the one vehicle
    with an ``ObjectController``, else one called ``Ego``.

    :raises ScenarioError: ``name`` is not a vehicle of the scenario, or no choice is
        unambiguous.
    """
    vehicles = [e for e in scenario.entities if e.kind == "vehicle"]
    if name:
        spec = scenario.entity(name)
        if spec.kind != "vehicle":
            raise ScenarioError(
                f"{scenario.path.name}: the ego {name!r} is a {spec.kind}, not a vehicle"
            )
        return name
    controlled = [e.name for e in vehicles if e.controlled]
    if len(controlled) == 1:
        return controlled[0]
    if any(e.name == "Ego" for e in vehicles):
        return "Ego"
    raise ScenarioError(
        f"{scenario.path.name}: cannot tell which vehicle is the ego (with an ObjectController: "
        f"{controlled}); set scenario.ego to one of {[e.name for e in vehicles]}"
    )


class ScenarioRunner:
    """The scenario's runtime for one episode.

    :param scenario: the concrete scenario (:func:`~aldm_gym.scenario.read_scenario`).
    :param road: the map road the env built from its ``LogicFile``.
    :param ego: the name of the entity the env drives.
    """

    def __init__(self, scenario: Scenario, road: Any, ego: str) -> None:
        """Entities without vehicles yet; see :meth:`populate`."""
        self.scenario = scenario
        self.world = World(road)
        for spec in scenario.entities:
            self.world.add(spec.entity(is_ego=spec.name == ego))
        self.ego: Entity = self.world.entities[ego]
        self.parameters: dict[str, Any] = dict(scenario.parameters)
        """The parameters' values now (``ParameterAction`` changes them)."""
        self.variables: dict[str, Any] = dict(scenario.variables)
        """The variables' values now (``VariableAction`` changes them)."""
        self.init_actions, self.storyboard = scenario.build(self.world.entities)
        for k, action in enumerate(self.init_actions):
            action.rank = (0, k)
        self.steps = 0
        self.domains: frozenset[str] = frozenset()
        """The domains the function under test drives (``lateral``, ``longitudinal``);
        the storyboard drives the others."""
        self.activated_at: float | None = None
        """Simulation time of the ``ActivateControllerAction`` [s]."""
        self.on_activate: Callable[[Entity], None] | None = None
        self.traffic: Any = None
        """The road whose vehicles the entities' are (set by :meth:`populate`)."""
        self.generators: list[Any] = []
        """The running traffic actions (swarms, sources, sinks:
        :mod:`aldm_gym.scenario.traffic`), in the order they started."""
        self.rng: Any = None
        """The episode's generator, which the generated traffic draws from."""
        self.traffic_vehicle: Callable[..., Any] = _idm_vehicle
        """Makes a generated vehicle: ``(road, position, heading, speed)``."""

    @property
    def active(self) -> bool:
        """Whether the function under test drives the ego in any domain."""
        return bool(self.domains)

    @property
    def finished(self) -> bool:
        """Whether the storyboard's stop trigger has fired."""
        return self.storyboard.finished

    def _play_init(self) -> None:
        """Start ``Init``'s actions in document order, but an action placing its actor
        relative to an entity that a later action places waits, with the actor's later
        actions, until that entity has its place (as esmini plays the ASAM examples
        that put the ego relative to a vehicle placed after it).

        :raises ScenarioError: an action that fails, or positions relative to each
            other in a cycle (naming the first).
        """
        from aldm_gym.scenario.positions import NotPlacedYet

        pending = list(self.init_actions)
        while pending:
            waiting: list[Any] = []
            held: set[str] = set()  # actors whose earlier action waits
            failure: NotPlacedYet | None = None
            for action in pending:
                actor = getattr(action.entity, "name", None)
                if actor is not None and actor in held:
                    waiting.append(action)
                    continue
                try:
                    action.start(self)
                except NotPlacedYet as exc:
                    failure = failure or exc
                    waiting.append(action)
                    if actor is not None:
                        held.add(actor)
                except ScenarioError:
                    raise
                except InputError as exc:  # a value that puts an entity outside the world
                    raise ScenarioError(f"{action.where}: {exc}") from None
            if len(waiting) == len(pending):  # no progress: a cycle, or never placed
                assert failure is not None
                raise ScenarioError(
                    f"{failure} (in Init, positions relative to each other in a circle, or "
                    "to an entity no action places)"
                ) from None
            pending = waiting

    def populate(
        self,
        traffic: Any,
        make_ego: Callable[[Any, Any, float, float], Any],
        dt: float | None = None,
        rng: Any = None,
        traffic_vehicle: Callable[..., Any] | None = None,
    ) -> Any:
        """Make every entity's vehicle on ``traffic`` (the ego with ``make_ego``), play
        ``Init`` at time 0, and start the storyboard; return the ego's vehicle. ``dt``
        [s]: the simulation step, to prepare the first one (the actions that measure
        where every entity begins a step). ``rng``: the episode's generator, for
        generated traffic (a fixed seed when None); ``traffic_vehicle``: makes a
        generated vehicle, ``(road, position, heading, speed)`` (highway-env's IDM
        vehicle when None).

        :raises ScenarioError: an entity that ``Init`` does not place.
        """
        import numpy as np

        self.traffic = traffic
        self.rng = rng if rng is not None else np.random.default_rng(0)
        if traffic_vehicle is not None:
            self.traffic_vehicle = traffic_vehicle
        for entity in self.world.entities.values():
            if entity.is_ego:
                v = make_ego(traffic, np.zeros(2), 0.0, 0.0)
            else:
                v = ScenarioVehicle(traffic, np.zeros(2), 0.0, 0.0)
                v.entity = entity
            v.LENGTH, v.WIDTH = entity.box.length, entity.box.width
            v.diagonal = float(np.hypot(v.LENGTH, v.WIDTH))
            entity.vehicle = v
        self._play_init()
        self._couple()
        for entity in self.world.entities.values():
            if not entity.placed and entity.name in self.scenario.added:
                entity.present = False  # absent until its AddEntityAction (as esmini)
        missing = [e.name for e in self.world.entities.values() if e.present and not e.placed]
        if missing:
            raise ScenarioError(
                f"{self.scenario.path.name}: Init places no position for {missing} "
                "(a TeleportAction is needed)"
            )
        ego = self.ego.vehicle
        traffic.vehicles.append(ego)  # the ego first, as the env expects
        for entity in self.world.entities.values():
            if not entity.present:  # deleted in Init: not on the road until added
                entity.vehicle.collidable = False
                continue
            if entity.lane is not None and entity.trajectory is None:
                # the pose again with the speed Init gave after placing it
                self.world.place(entity, entity.lane, entity.u, entity.t, entity.heading_offset)
            if not entity.is_ego:
                traffic.vehicles.append(entity.vehicle)
        for entity in self.world.entities.values():
            entity.vehicle.on_state_update()
        self.world.track(0.0)
        self.world.running = True
        self.storyboard.update(self, 0.0)
        self._generate(dt or 0.0)
        if dt is not None:
            self.world.prepare(dt)
        self.world.ego_due()
        return ego

    def step(self, dt: float) -> None:
        """After the road moved everyone by ``dt`` [s]: move the ego where the scenario
        still drives it, then update the storyboard at the new time.

        :raises ScenarioError: naming the file and the time, where the scenario's values
            put an entity outside the world (an :class:`InputError` of the road's).
        """
        try:
            self._step(dt)
        except ScenarioError:
            raise
        except InputError as exc:
            raise ScenarioError(
                f"{self.scenario.path.name} at {self.world.time:g} s: {exc}"
            ) from None

    def _step(self, dt: float) -> None:
        world = self.world
        if not self.active:
            world.advance_all(dt)  # unless a scripted entity's step already moved them
        elif self.domains == {"longitudinal"}:
            world.follow_lateral(self.ego, dt)  # its speed the function's, its lane the script's
        else:
            speed = self.ego.speed
            world.sync(self.ego)
            self.ego.traveled += self.ego.velocity * dt
            if self.domains == {"lateral"}:
                self.ego.speed = speed  # the script's (the vehicle's has the env's push)
        self._come_and_go(dt)
        world.tow()
        world.settle(dt)
        # the clock counts steps at the simulation frequency: 12 / 10 is 1.2 exactly,
        # where 12 * 0.1 (or a sum of 0.1 s) is 1.2000000000000002
        self.steps += 1
        frequency = round(1.0 / dt)
        world.time = self.steps / frequency if abs(frequency * dt - 1.0) < 1e-9 else self.steps * dt
        world.track(dt)
        self.storyboard.update(self, world.time)
        self._generate(dt)
        if self.domains == {"lateral"}:
            world.script_speed(self.ego, dt)  # the next step's speed is the script's
        world.prepare(dt)
        world.ego_due()

    def generated(self) -> list[Any]:
        """The generated vehicles on the road (swarms', sources'), in road order."""
        if self.traffic is None:
            return []
        return [v for v in self.traffic.vehicles if getattr(v, "generated_by", None) is not None]

    def _generate(self, dt: float) -> None:
        """Let the running traffic actions add and remove their vehicles."""
        for action in list(self.generators):
            action.generator.step(self, self.rng, dt)

    def _couple(self) -> None:
        """The trailers the vehicles tow from the start (``Trailer``), in line behind
        their tractors once ``Init`` has placed these."""
        entities = self.world.entities
        for spec in self.scenario.entities:
            if spec.trailer is None:
                continue
            tractor, trailer = entities[spec.name], entities[spec.trailer]
            tractor.trailer, trailer.tractor = trailer, tractor
        if self.active:
            self._check_not_towing()
        heads = [e for e in entities.values() if e.trailer is not None and e.tractor is None]
        if any(not e.placed for e in heads):
            return  # the missing position is named next
        try:
            self.world.tow(straight=True)
        except InputError as exc:  # a trailer behind its tractor is off the map
            raise ScenarioError(
                f"{self.scenario.path.name}: a trailer in line behind "
                f"{[e.name for e in heads]}: {exc}"
            ) from None

    def _check_not_towing(self) -> None:
        """Raise where the function under test's vehicle tows or is towed (not played)."""
        ego = self.ego
        if ego.trailer is not None or ego.tractor is not None:
            raise ScenarioError(
                f"{self.scenario.path.name} at {self.world.time:g} s: the function under "
                f"test takes {ego.name!r}, which "
                + ("tows a trailer" if ego.trailer is not None else "is towed")
                + ": a function's vehicle with a trailer is not played"
            )

    def on_road(self, entity: Entity) -> bool:
        """Whether the entity's vehicle is on the road (not deleted, or added back)."""
        return self.traffic is not None and any(v is entity.vehicle for v in self.traffic.vehicles)

    def _come_and_go(self, dt: float) -> None:
        """The vehicles of entities a ``DeleteEntityAction`` took out leave the road;
        those an ``AddEntityAction`` put back are placed and move on by ``dt`` [s]."""
        vehicles = self.traffic.vehicles
        world = self.world
        for entity in world.entities.values():
            v = entity.vehicle
            if not entity.present and not entity.leaving:
                if any(x is v for x in vehicles):
                    vehicles.remove(v)
            elif entity.arrival is not None:
                where, entity.arrival = entity.arrival, None
                v.collidable = True
                place(world, entity, where)
                world.advance(entity, dt)
                v.on_state_update()
                vehicles.append(v)

    def control(self, lateral: bool, longitudinal: bool) -> None:
        """``ActivateControllerAction``: the function under test drives the ego in the
        domains given, the storyboard in the others. The motions of the domains handed
        to the function end; where it gives a domain back, the storyboard drives it on
        from where the ego is."""
        wanted = frozenset(
            d for d, on in (("lateral", lateral), ("longitudinal", longitudinal)) if on
        )
        if wanted == self.domains:
            return
        ego = self.ego
        if wanted:
            self._check_not_towing()
        before = self.domains
        if before:
            self.world.sync(ego)
        self.domains = wanted
        ego.controlled = wanted
        ego.scripted = not wanted
        for domain in wanted - before:
            motion = getattr(ego, domain)
            if motion is not None:
                motion.stop()
            # a trajectory moves the scripted ego only: it ends with either domain
            if ego.trajectory is not None:
                ego.trajectory.stop()
        if wanted and not before:
            self.activated_at = self.world.time
            if self.on_activate is not None:
                self.on_activate(ego)

    def activate(self) -> None:
        """The function under test takes the ego over in both domains."""
        self.control(True, True)

    def deactivate(self) -> None:
        """The scenario drives the ego again from where it is."""
        self.control(False, False)
