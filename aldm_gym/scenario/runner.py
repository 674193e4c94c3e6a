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

from aldm_gym.errors import ScenarioError
from aldm_gym.scenario.reader import Scenario
from aldm_gym.scenario.world import Entity, ScenarioVehicle, World

__all__ = ["ScenarioRunner", "choose_ego"]


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
        self.init_actions, self.storyboard = scenario.build(self.world.entities)
        self.steps = 0
        self.active = False
        """Whether the function under test drives the ego."""
        self.activated_at: float | None = None
        """Simulation time of the ``ActivateControllerAction`` [s]."""
        self.on_activate: Callable[[Entity], None] | None = None

    @property
    def finished(self) -> bool:
        """Whether the storyboard's stop trigger has fired."""
        return self.storyboard.finished

    def populate(self, traffic: Any, make_ego: Callable[[Any, Any, float, float], Any]) -> Any:
        """Make every entity's vehicle on ``traffic`` (the ego with ``make_ego``), play
        ``Init`` at time 0, and start the storyboard; return the ego's vehicle.

        :raises ScenarioError: an entity that ``Init`` does not place.
        """
        import numpy as np

        for entity in self.world.entities.values():
            if entity.is_ego:
                v = make_ego(traffic, np.zeros(2), 0.0, 0.0)
            else:
                v = ScenarioVehicle(traffic, np.zeros(2), 0.0, 0.0)
                v.entity = entity
            v.LENGTH, v.WIDTH = entity.box.length, entity.box.width
            v.diagonal = float(np.hypot(v.LENGTH, v.WIDTH))
            entity.vehicle = v
        for action in self.init_actions:
            action.start(self)
        missing = [e.name for e in self.world.entities.values() if not e.placed]
        if missing:
            raise ScenarioError(
                f"{self.scenario.path.name}: Init places no position for {missing} "
                "(a TeleportAction is needed)"
            )
        ego = self.ego.vehicle
        traffic.vehicles.append(ego)  # the ego first, as the env expects
        for entity in self.world.entities.values():
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
        self.world.ego_due()
        return ego

    def step(self, dt: float) -> None:
        """After the road moved everyone by ``dt`` [s]: move the ego where the scenario
        still drives it, then update the storyboard at the new time."""
        world = self.world
        if not self.active:
            world.advance_ego(dt)  # unless a scripted entity's step already moved it
        else:
            world.sync(self.ego)
            self.ego.traveled += self.ego.velocity * dt
        # the clock counts steps at the simulation frequency: 12 / 10 is 1.2 exactly,
        # where 12 * 0.1 (or a sum of 0.1 s) is 1.2000000000000002
        self.steps += 1
        frequency = round(1.0 / dt)
        world.time = self.steps / frequency if abs(frequency * dt - 1.0) < 1e-9 else self.steps * dt
        world.track(dt)
        self.storyboard.update(self, world.time)
        world.ego_due()

    def activate(self) -> None:
        """The function under test takes the ego over (``ActivateControllerAction``)."""
        if self.active:
            return
        self.active = True
        self.activated_at = self.world.time
        self.ego.scripted = False
        self.ego.longitudinal = self.ego.lateral = self.ego.trajectory = None
        if self.on_activate is not None:
            self.on_activate(self.ego)

    def deactivate(self) -> None:
        """``ActivateControllerAction`` with both domains false: the scenario drives the
        ego again from where it is."""
        if not self.active:
            return
        self.active = False
        self.world.sync(self.ego)
        self.ego.scripted = True
