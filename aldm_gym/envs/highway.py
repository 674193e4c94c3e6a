"""``ALDMHighway-v0``: highway driving whose ego sees lanes only through a line sensor.

The env composes parts of one job each, in the order of the data flow:

- settings: :class:`~aldm_gym.envs.config.EnvConfig` (``env.settings``), validated once
  per ``configure``; highway-env reads the dict view ``env.config``;
- scene: :mod:`aldm_gym.envs.scene` builds the road and its vehicles (a generated
  highway or an OpenDRIVE map);
- perception: :mod:`aldm_gym.envs.perception`: line sensor, detector, object list;
- functions: the ego's LKA and lane changes (:mod:`aldm_gym.envs.vehicle`), ACC and AEB
  (:mod:`aldm_gym.envs.longitudinal`);
- referee: :mod:`aldm_gym.envs.referee`: ground truth the agent never sees;
- outcome: :mod:`aldm_gym.envs.outcome`: reward, episode end, ``info``.

See :class:`ALDMHighwayEnv`'s docstring (spaces, reward, episode end) and ``docs/env.md``.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from highway_env.envs.common.abstract import AbstractEnv

from aldm_gym.envs import outcome
from aldm_gym.envs.actions import ALDMAction
from aldm_gym.envs.config import (
    ConfigView,
    EnvConfig,
    EnvOverrides,
    default_config,
    load_map,
    map_lanes_count,
    merged_config,
    parse_config,
    read_config_scenario,
)
from aldm_gym.envs.control import LKAController
from aldm_gym.envs.lane_end import LaneEnd, LaneEndMonitor, target_lane_free
from aldm_gym.envs.longitudinal import LongitudinalCommand, LongitudinalController
from aldm_gym.envs.observation import ALDMObservation
from aldm_gym.envs.osi_trace import OsiRecorder
from aldm_gym.envs.perception import Perception
from aldm_gym.envs.referee import Referee
from aldm_gym.envs.scene import (
    MAP_MIN_AHEAD,
    MAP_START_WIDTH,
    MAP_TRAFFIC_ROOM,
    ROAD_END_MARGIN,
    GeneratedScene,
    Scene,
    make_scene,
)
from aldm_gym.envs.targets import Objects
from aldm_gym.envs.vehicle import SensorVehicle
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.roads.position import LanePosition
from aldm_gym.roads.protocol import Road
from aldm_gym.scenario.runner import ScenarioRunner
from aldm_gym.sensor.detectors import Detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.sensor.line_sensor import LineSensor

__all__ = [
    "MAP_MIN_AHEAD",
    "MAP_START_WIDTH",
    "MAP_TRAFFIC_ROOM",
    "ROAD_END_MARGIN",
    "ALDMHighwayEnv",
]

SCENARIO_END_MARGIN = 5.0
"""A scenario run is truncated when the ego is this close to the end of its lanes [m]."""

HINT_REACH = 20.0
"""Lateral offset from the nearest lane's centre [m] up to which the sensor is handed the
ego's arc length; farther off, the projection of the ego (exact only within 40 m of a
generated road's reference line) may belong to another stretch of a winding road."""


class ALDMHighwayEnv(AbstractEnv):
    """Highway driving on a curved multi-lane road, lanes perceived through a line sensor.

    The ego vehicle's lateral control uses only what an emulated CarMaker line sensor
    measures and the chosen detector (``"aldm"``, ``"naive"`` or ``"ground_truth"``)
    rebuilds, at every simulation step. Traffic is highway-env's IDM/MOBIL on a
    :class:`~aldm_gym.envs.traffic.FastRoad` (cost about linear in vehicles).

    ## Action Space

    ``config["action"]["type"]``:

    * ``"DiscreteMetaAction"`` (default): ``Discrete(5)``, highway-env's meaning.

      | Num | Action     | Effect                                                              |
      |-----|------------|---------------------------------------------------------------------|
      | 0   | LANE_LEFT  | steer onto the detected left lane (no-op if its line is not found)  |
      | 1   | IDLE       | keep the lane (pure pursuit on the detected trajectory), ACC + AEB  |
      | 2   | LANE_RIGHT | steer onto the detected right lane (no-op if its line is not found) |
      | 3   | FASTER     | next higher set speed of ``action.target_speeds``                   |
      | 4   | SLOWER     | next lower target speed                                             |

    * ``"ContinuousAction"``: ``Box((2,), float32)``: steering [rad] (ISO: > 0 turns
      left, within ±``lka.max_steering``) and acceleration [m/s²] (±``max_acceleration``),
      raw: no ACC or AEB acts on it.

    The speed under meta actions: ACC (constant time gap behind the target selected on
    the *detected* lanes, else the set speed) and AEB, ``acc`` section
    (:mod:`aldm_gym.envs.longitudinal`, ``docs/acc.md``).
      :class:`~aldm_gym.envs.control.LKAController` ``.predict(obs)`` produces such actions.

    ## Observation Space

    ``Dict`` of bounded float32 Boxes, all in the sensor frame (x forward, y left) [m]:

    | key                | shape    | content                                             |
    |--------------------|----------|-----------------------------------------------------|
    | `lines`            | (4,13,2) | 4 lines (left_adj., ego_left, ego_right, right_adj.)|
    | `line_valid`       | (4,)     | 1 where the detector found the line                 |
    | `line_confidence`  | (4,)     | opt-in (`observation.line_confidence`): the lane-   |
    |                    |          | model filter's confidence per line, else line_valid |
    | `trajectory`       | (13,2)   | desired path (midway between the ego lines)         |
    | `trajectory_valid` | (1,)     | 1 if there is a trajectory                          |
    | `ego`              | (4,)     | speed, yaw rate, steering, lane change (+1/-1/0)    |
    | `vehicles`         | (N,6)    | present, x, y, rel. vx, vy, lane by detected lines  |
    | `lanes`            | (3,4)    | left/ego/right detected lane: gap, rel. vx of the   |
    |                    |          | nearest vehicle ahead, then of the nearest behind   |
    | `target`           | (3,)     | ACC target: present, gap [m], relative speed [m/s]  |

    Lane codes of `vehicles` (:class:`~aldm_gym.envs.observation.LaneCode`): 1 ego
    lane, 2 left, 3 right, 0 other / unknown. Built by
    :class:`~aldm_gym.envs.observation.ALDMObservation`; details in ``docs/env.md``.

    ## Rewards

    ``r = Σ_k w_k · r_k`` with weights from the config (``*_reward`` keys), then, if
    ``normalize_reward``, mapped linearly from the least possible sum (collision +
    departure - overtaking) to the greatest (the positive weights) onto ``[0, 1]``:

    | term                  | default | value                                          |
    |-----------------------|---------|------------------------------------------------|
    | `collision_reward`    | -1.0    | 1 if crashed                                   |
    | `departure_reward`    | -0.5    | 1 if a wheel crossed a marking (no lane change)|
    | `high_speed_reward`   | 0.3     | speed mapped from `reward_speed_range` to [0,1]|
    | `progress_reward`     | 0.2     | road distance / (max speed · step), in [0, 1]  |
    | `lane_keeping_reward` | 0.3     | max(0, 1 - abs(offset) / (lane width / 2))     |
    | `right_lane_reward`   | 0.0     | lane id / (lanes - 1), 1 on the rightmost lane |
    | `lane_change_reward`  | 0.0     | 1 if the action was LANE_LEFT/RIGHT            |
    | `overtaking_reward`   | 0.0     | vehicles passed - passed by, clipped to [-1, 1]|

    ## Episode End

    Terminated: the ego crashed; or left the road with ``offroad_terminal``; or departed
    its lane with ``departure_terminal``. Truncated: ``duration`` [s] elapsed, or the
    ego is within 250 m of the road's end.

    ## Info

    ``speed``, ``crashed``, ``action``, ``rewards`` (highway-env's), plus
    ``lateral_offset`` (true offset from the current lane centre [m], > 0 left),
    ``lane_departure`` (during this step), ``lane_index`` (true lane id, 0 leftmost),
    ``lane_change`` (+1/-1 under way, 0), ``lane_change_refused``,
    ``lane_changes_completed`` / ``lane_changes_aborted`` (counts this episode),
    ``arc_length`` (true position along the road [m]), ``detection``
    (``{"ego_left"|"ego_right": {"mean_abs_error" [m] up to 60 m, "preview" [m],
    "correct" (1/0)}}``, NaN error and preview when the line is missing; with the
    lane-model filter also its "confidence" in [0, 1] and "measured_from" /
    "measured_to", the x range [m] this frame measured it in, NaN when carried),
    ``departures`` (count this episode), ``target`` (the ACC's target against ground
    truth: ``target``, ``leader``, ``correct``, ``missed``, ``false``, ``aeb``,
    ``aeb_activations``, ``phantom_braking``, ``gap``, ``time_gap``), ``collision``
    (``""``, ``"front"``, ``"rear"``, ``"side"``), ``lane_end`` (the end of the ego's
    lane the chauffeur acts on: ``distance`` [m], ``side``, ``source``,
    ``lane_changes``; docs/acc.md, "Lanes that end"); on a map also ``lane_ends_in``
    (distance to the end of the ego's lane chain when it ends before the road [m], else
    inf). See ``docs/env.md``.

    ## Maps

    ``config={"road": {"xodr": path}}`` drives on an OpenDRIVE map (seeded start with
    enough lane chain ahead, IDM/MOBIL traffic with a mandatory merge out of ending
    lanes, truncation where the road ahead ends); see ``docs/env.md``.

    ## Version History

    * v0: initial version; ACC + AEB under meta actions (``acc``), observation key
      ``target``, ``info["target"]`` and ``info["collision"]``.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}  # noqa: RUF012

    def __init__(self, config: Mapping[str, Any] | None = None, render_mode: str | None = None):
        # AbstractEnv.__init__ calls reset(): everything reset needs is set first.
        if config is not None and not isinstance(config, Mapping):
            raise ConfigError(
                f"config must be a mapping of settings (a dict), got {type(config).__name__}"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        self.settings = EnvConfig()
        """The validated settings (:class:`~aldm_gym.envs.config.EnvConfig`), read by
        attribute; ``self.config`` is their dict view for highway-env."""
        self._scene: Scene = GeneratedScene(self.settings)
        self.highway: Road | None = None
        """The road the ego drives on: a generated highway, or a map (``road.xodr``)."""
        self.lka = LKAController()
        self.perception: Perception | None = None
        """The ego's sensing this episode (:mod:`aldm_gym.envs.perception`)."""
        self.referee: Referee | None = None
        """Ground truth of this episode (:mod:`aldm_gym.envs.referee`)."""
        self.longitudinal: LongitudinalController | None = None
        """Target selection, ACC and AEB (``acc.enabled``): :mod:`aldm_gym.envs.longitudinal`."""
        self.acc_command: LongitudinalCommand | None = None
        """The longitudinal controller's output at the last simulation step."""
        self.lane_end = LaneEndMonitor(self.settings.lane_end)
        """Where the ego's lane ends, this episode (:mod:`aldm_gym.envs.lane_end`)."""
        self.lane_end_changes = 0
        """Lane changes the chauffeur started out of an ending lane this episode."""
        self._s_before = 0.0
        self._passing_before: dict[Any, float] = {}
        self._space_seed: int | None = None
        self.scenario: ScenarioRunner | None = None
        """This episode's scenario run (``scenario.xosc`` set), else None."""
        self.osi: OsiRecorder | None = None
        """The OSI trace writer (``osi.trace`` set), else None."""
        self._configured = False
        if config is not None and not isinstance(config, EnvOverrides):
            config = dict(config)
        super().__init__(config or None, render_mode)

    # ------------------------------------------------------------------ config
    @classmethod
    def default_config(cls) -> dict:
        """See :func:`aldm_gym.envs.config.default_config`."""
        return default_config()

    def configure(self, config: Mapping[str, Any] | None) -> None:
        """Merge ``config`` into the current configuration, validate it into
        :attr:`settings` (once), and read a map it names. The first configuration
        given as :class:`~aldm_gym.envs.config.EnvOverrides` was validated where it
        was made and is taken as it is.

        :raises ConfigError: naming unknown keys and the allowed ones, or a bad value.
        :raises MapNotFoundError, MapError: ``road.xodr`` names a missing or bad file.
        :raises ScenarioError: ``scenario.xosc`` names a file the player cannot play.
        """
        if isinstance(config, EnvOverrides) and not self._configured:
            settings, view = config.parsed()  # validated where it was made
        else:
            settings, view = parse_config(merged_config(self.config, config))
        if settings.offscreen_rendering is None:
            object.__setattr__(settings, "offscreen_rendering", self.render_mode != "human")
            dict.__setitem__(view, "offscreen_rendering", settings.offscreen_rendering)
        scenario = None
        if settings.scenario.enabled:
            scenario = read_config_scenario(settings)
        on_map = load_map(settings, scenario)
        if on_map is not None:
            # The map sets these (settings and view are this call's own): its lane count,
            # and neighbours searched across connected lanes, which highway-env's reset
            # copies from the config onto the road.
            for key, value in (
                ("lanes_count", map_lanes_count(on_map)),
                ("neighbour_vehicles_connected_lanes", True),
            ):
                object.__setattr__(settings, key, value)
                dict.__setitem__(view, key, value)
        self.settings = settings
        self.config: ConfigView = view
        self._configured = True
        self._scene = make_scene(settings, on_map, scenario)
        self.lka = LKAController(
            **{k: v for k, v in vars(settings.lka).items() if k != "path_range"},
            sensor_x=float(settings.sensor.mount_x),
        )

    @property
    def path_range(self) -> float | None:
        """The trajectory is fitted on the detected lines up to this x [m] (``lka.path_range``)."""
        return self.settings.lka.path_range

    def define_spaces(self) -> None:
        """Observation and action types and spaces from the settings."""
        self.observation_type = ALDMObservation(self)
        self.action_type = ALDMAction(self, SensorVehicle)
        # highway-env rebuilds the spaces at every reset; an equal space is kept so
        # that a user's ``action_space.seed(...)`` survives.
        obs_space = self.observation_type.space()
        if getattr(self, "observation_space", None) != obs_space:
            self.observation_space = obs_space
        action_space = self.action_type.space()
        if getattr(self, "action_space", None) != action_space:
            self.action_space = action_space
        if self._space_seed is not None:
            # reset(seed=...) seeds the spaces too: reset's info["action"] (highway-env
            # draws it with action_space.sample()) repeats with the seed.
            self.action_space.seed(self._space_seed)
            self.observation_space.seed(self._space_seed)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[Any, dict]:
        """highway-env's reset; ``seed`` also seeds the action and observation spaces."""
        self._space_seed = seed
        try:
            return super().reset(seed=seed, options=options)
        finally:
            self._space_seed = None

    # ------------------------------------------------------------------ parts
    @property
    def sensor(self) -> LineSensor | None:
        """This episode's line sensor."""
        return None if self.perception is None else self.perception.sensor

    @property
    def frame(self) -> SensorFrame | None:
        """The sensor frame of the last simulation step."""
        return None if self.perception is None else self.perception.frame

    @property
    def detection(self) -> LaneDetection | None:
        """The detection of the last simulation step."""
        return None if self.perception is None else self.perception.detection

    @property
    def _detector(self) -> Detector | None:
        """This episode's detector (tests swap it for a recording one)."""
        return None if self.perception is None else self.perception.detector

    @_detector.setter
    def _detector(self, detector: Detector) -> None:
        assert self.perception is not None
        self.perception.detector = detector

    @property
    def lane_position(self) -> LanePosition:
        """The ego's ground-truth position on the road, updated every simulation step."""
        assert self.referee is not None
        return self.referee.lane_position

    # ------------------------------------------------------------------ scene
    def _reset(self) -> None:
        scene = self._scene
        self.highway = road = scene.road(self.np_random)
        self.perception = Perception(self.settings, self.path_range)
        self._passing_before = {}  # holds the last step's vehicles
        if self.road is not None:
            # The old road and its vehicles reference each other; releasing them frees
            # them at once instead of at Python's next full garbage collection
            # (docs/reliability.md, "Memory over a long run").
            self.road.release()
        self.road = scene.traffic_road(road, self.np_random)
        ego = scene.place_vehicles(road, self.road, self.np_random, self._make_ego)
        self.controlled_vehicles = [ego]
        self.scenario = getattr(scene, "runner", None)
        if self.scenario is not None:
            self.scenario.on_activate = self._hand_over
            if self.scenario.active:  # handed over by Init or at time 0
                self._hand_over(self.scenario.ego)
        self._reset_longitudinal(road)
        self._perceive()
        self._s_before = self.lane_position.s
        if self.settings.osi.enabled:
            if self.osi is None or self.osi.settings != self.settings.osi:
                if self.osi is not None:
                    self.osi.close()
                self.osi = OsiRecorder(self.settings.osi)
            self.osi.start()
            self.osi.record(self)
        elif self.osi is not None:
            self.osi.close()
            self.osi = None

    def _hand_over(self, entity: Any) -> None:
        """The scenario hands the ego to the function: its set speed is the speed it
        has (the only target speed while the scenario runs)."""
        ego = self.vehicle
        ego.target_speeds = np.array([float(entity.speed)])
        ego.speed_index = 0
        ego.target_speed = float(entity.speed)

    def _make_ego(self, traffic: Any, position: Any, heading: float, speed: float) -> SensorVehicle:
        """The ego at a pose, with the action and LKA settings."""
        s = self.settings
        act = s.action
        assert self.highway is not None
        ego = SensorVehicle(
            traffic,
            position,
            heading,
            speed,
            lka=self.lka,
            target_speeds=tuple(act.target_speeds),
            continuous=act.type == "ContinuousAction",
            lane_change_timeout=float(act.lane_change_timeout),
            cross_solid_lines=bool(act.cross_solid_lines),
            max_acceleration=float(act.max_acceleration),
            lane_width=self.highway.lane_width,
            path_range=self.path_range,
        )
        ego.sim_frequency = float(s.simulation_frequency)
        ego.opening_factor = float(s.lane_end.opening_factor)
        return ego

    def _reset_longitudinal(self, road: Road) -> None:
        """A fresh referee, ACC/AEB (``acc.enabled``) and command."""
        acc = self.settings.acc
        assert self.sensor is not None
        ego_x = -float(self.sensor.config.mount_x)
        self.referee = Referee(road, acc, ego_x)
        self.lane_end = LaneEndMonitor(self.settings.lane_end, ego_x)
        self.lane_end_changes = 0
        self.acc_command = None
        self.vehicle.acc_braking_limit = acc.aeb_deceleration
        if not acc.enabled:
            self.longitudinal = None
            return
        self.longitudinal = LongitudinalController(
            acc, ego_x=ego_x, lane_width=float(road.lane_width)
        )

    # ------------------------------------------------------------------ simulation
    def _perceive(self) -> None:
        """Ground truth, then one sensor frame, one detection, the ACC; then the referee."""
        ego = self.vehicle
        road = self.highway
        perception, referee = self.perception, self.referee
        assert road is not None and perception is not None and referee is not None
        pos = referee.locate(ego)
        t = self.steps / self.settings.simulation_frequency
        # Far off the road (a departure the episode survives) the ego's projection may
        # belong to another stretch of a winding road: the sensor then finds its own.
        s_hint = pos.s if abs(pos.offset) <= HINT_REACH else None
        perception.measure(road, ego, t, s_hint, self.np_random, self.road.vehicles)
        perception.detect(road, pos.lane, ego)
        ahead = self.lane_end.update(
            road,
            None if referee.off_map else pos,
            perception.detection,
            travelled=max(float(ego.speed), 0.0) / self.settings.simulation_frequency,
            lane_changes=int(ego.lane_changes_completed),
        )
        objects = None  # sensed once per step, by the first that needs them
        if ahead is not None and self._may_leave(ahead):
            objects = perception.sense_objects(self.road, ego)
            self._leave_ending_lane(ahead, objects)
        if self.longitudinal is not None:
            self._longitudinal_step(objects)
        referee.judge(ego, self.road.vehicles)

    def _may_leave(self, ahead: LaneEnd) -> bool:
        """Whether a lane change out of a lane that ends may start now (``docs/acc.md``,
        "Lanes that end"): under the built-in lateral control, none under way, the end
        within the zone, its side known and that side's lane detected."""
        ego = self.vehicle
        if ego.continuous or ego.requested_steering is not None or ego.lane_change != 0:
            return False
        if self.scenario is not None and "lateral" not in self.scenario.domains:
            return False  # the storyboard drives the ego
        if ahead.side == 0 or ahead.distance > self.lane_end.zone(float(ego.speed)):
            return False
        return bool(ego.lane_change_available(ahead.side, forced=True))

    def _leave_ending_lane(self, ahead: LaneEnd, objects: Objects) -> None:
        """Start the lane change :meth:`_may_leave` allows if the target lane has a free
        gap among this step's ``objects``."""
        ego = self.vehicle
        assert self.perception is not None and self.highway is not None
        if not target_lane_free(
            self.perception.detection,
            objects,
            ahead.side,
            lane_width=float(self.highway.lane_width),
            ego_x=self.lane_end.ego_x,
            ego_speed=float(ego.speed),
            curvature=ego.path_curvature,
        ):
            return
        if ego.start_lane_change(ahead.side, forced=True):
            self.lane_end_changes += 1

    def _longitudinal_step(self, objects: Objects | None = None) -> None:
        """Target selection, ACC and AEB on this step's detection; its ground truth.

        :param objects: this step's objects if already sensed (else sensed here).
        """
        ego = self.vehicle
        ctrl, perception, referee = self.longitudinal, self.perception, self.referee
        assert ctrl is not None and perception is not None and referee is not None
        if objects is None:
            objects = perception.sense_objects(self.road, ego)
        speed = float(ego.speed)
        curvature = ego.path_curvature
        path = ego.planned_path if len(ego.planned_path) >= 2 else ego.trajectory
        ahead = self.lane_end.lane_end
        stop = None
        zone = self.lane_end.zone(speed)
        if ahead is not None and ego.lane_change == 0 and ahead.distance <= zone:
            # No way out yet: brake for the end as for a standing vehicle before it.
            stop = ahead.distance - self.settings.lane_end.stop_margin
        cmd = self.acc_command = ctrl.update(
            perception.detection,
            objects,
            speed,
            float(ego.target_speed),
            path=path,
            side=int(ego.lane_change_side),
            curvature=curvature,
            stop_at=stop,
        )
        # The continuous action stays raw: the selection runs (info), nothing acts on it.
        ego.acc_command = None if ego.continuous else cmd.acceleration
        if ego.continuous:
            return
        referee.check_braking(
            cmd, ctrl, objects, perception.objects_xy, ego, lambda: perception.objects_velocity
        )

    def _simulate(self, action: Any = None) -> None:
        """``simulation_frequency / policy_frequency`` steps; sensor + detector at each."""
        s = self.settings
        frames = int(s.simulation_frequency // s.policy_frequency)
        dt = 1.0 / s.simulation_frequency
        assert self.referee is not None
        self._s_before = self.lane_position.s
        self._passing_before = outcome.passing_positions(self.vehicle, self.road.vehicles)
        self.referee.begin_step()
        if not s.manual_control:
            self.action_type.act(action)  # raises InputError on a bad action (None too)
        engine = self.road.engine
        every_frame = self.osi is not None and self.settings.osi.every == "frame"
        # Nothing but the simulation touches the traffic until the env step ends.
        with engine.holding() if engine is not None else contextlib.nullcontext():
            for frame in range(frames):
                self.road.act()
                self.road.step(dt)
                self.steps += 1
                if self.scenario is not None:
                    self.scenario.step(dt)
                self._perceive()
                if every_frame:
                    self.osi.record(self)  # type: ignore[union-attr]
                if self.scenario is not None and self.scenario.finished:
                    break  # the stop trigger ends the episode at this simulation step
                if frame < frames - 1:
                    self._automatic_rendering()
        if self.osi is not None and not every_frame:
            self.osi.record(self)
        self.enable_auto_render = False

    # ------------------------------------------------------------------ outcome
    def _rewards(self, action: Any) -> dict[str, float]:
        assert self.referee is not None
        return outcome.reward_terms(
            self.settings,
            self.vehicle,
            self.lane_position,
            self._s_before,
            self.referee.departed_step,
            self.action_type.is_lane_change(action),
            outcome.net_overtakes(
                self._passing_before,
                outcome.passing_positions(self.vehicle, self.road.vehicles),
            ),
        )

    def _reward(self, action: Any) -> float:
        return outcome.reward(self.settings, self._rewards(action))

    def _is_terminated(self) -> bool:
        assert self.referee is not None
        return outcome.terminated(self.settings, self.vehicle, self.referee)

    def _is_truncated(self) -> bool:
        assert self.referee is not None
        if self.scenario is not None:
            # a scenario ends at its stop trigger (max_time: a cap), or where the ego's
            # lanes end (the scenario's map decides how far it can drive)
            road_end = self.referee.road.ends_within(self.lane_position, SCENARIO_END_MARGIN)
            late = self.scenario.world.time >= self.settings.scenario.max_time
            return bool(self.scenario.finished or late or road_end)
        return outcome.truncated(self.settings, self.time, self.referee)

    def _info(self, obs: Any, action: Any = None) -> dict:
        info = super()._info(obs, action)
        perception, referee = self.perception, self.referee
        assert perception is not None and referee is not None and perception.frame is not None
        detection = referee.score(perception.detection, perception.frame)
        target = referee.target_info(
            self.acc_command,
            self.longitudinal,
            perception.objects,
            perception.objects_xy,
            self.vehicle,
            perception.objects_velocity,
        )
        info.update(outcome.step_info(self.vehicle, referee, detection, target))
        ahead = self.lane_end.lane_end
        info["lane_end"] = {
            "distance": math.inf if ahead is None else ahead.distance,
            "side": 0 if ahead is None else ahead.side,
            "source": "" if ahead is None else ahead.source,
            "lane_changes": self.lane_end_changes,
        }
        if not self.action_type.continuous:
            info["action_mask"] = self.action_type.action_mask()
        if self.scenario is not None:
            info["scenario"] = {
                "time": self.scenario.world.time,
                "ego_active": self.scenario.active,
                "finished": self.scenario.finished,
            }
        if self.settings.info_metrics:
            info["lane_metrics"] = referee.lane_metrics(
                perception.detection, perception.frame, perception.sensor.config.visibility
            )
        return info

    def action_masks(self) -> np.ndarray:
        """Which meta actions act now (``(5,)`` bool, :class:`MetaAction` order): lane
        changes only towards a detected adjacent lane and when none is under way, the
        rest always. The method sb3-contrib's ``MaskablePPO`` calls (through wrappers:
        ``env.get_wrapper_attr("action_masks")()``); also ``info["action_mask"]``.

        :raises InputError: with ``ContinuousAction``.
        """
        return self.action_type.action_mask()

    def request(
        self,
        steering: float | None = None,
        curvature: float | None = None,
        acceleration: float | None = None,
    ) -> None:
        """A function under test's requests, held from the next :meth:`step` until the
        next call (:mod:`aldm_gym.function`). What is not requested stays with the
        built-in function: the LKA steers without a steering or curvature, the ACC/AEB
        sets the speed without an acceleration. Under meta actions only.

        :param steering: steering angle [rad], ISO (> 0 turns left); clipped to
            ``lka.max_steering``.
        :param curvature: or the path curvature [1/m] (> 0 left), steered as the LKA
            steers an arc: ``atan(curvature · wheelbase)``.
        :param acceleration: longitudinal acceleration [m/s²]; clipped to
            ``action.max_acceleration`` and ``acc.aeb_deceleration``; it never reverses
            the car.
        :raises InputError: a value that is not a finite number, both steering and
            curvature, or ``ContinuousAction`` (its action is the request already).
        """
        if self.action_type.continuous:
            raise InputError("request() is for meta actions; ContinuousAction's action is one")
        values = {"steering": steering, "curvature": curvature, "acceleration": acceleration}
        for name, value in values.items():
            ok = value is None or (
                isinstance(value, int | float | np.floating | np.integer)
                and not isinstance(value, bool)
                and math.isfinite(float(value))
            )
            if not ok:
                raise InputError(f"request: {name} must be a finite number or None, got {value!r}")
        if steering is not None and curvature is not None:
            raise InputError("request: give steering or curvature, not both")
        if curvature is not None:
            steering = math.atan(float(curvature) * self.lka.wheelbase)
        ego = self.vehicle
        ego.requested_steering = None if steering is None else float(steering)
        ego.requested_acceleration = None if acceleration is None else float(acceleration)

    def close(self) -> None:
        """Close the viewer and finish the OSI trace (``osi.trace``)."""
        if self.osi is not None:
            self.osi.close()
        super().close()

    # ------------------------------------------------------------------ rendering
    def render(self) -> np.ndarray | None:
        """Render with highway-env's viewer plus the sensor / detection overlay."""
        if self.render_mode is None:
            return super().render()
        if self.viewer is None:
            from aldm_gym.envs.rendering import ALDMViewer

            self.viewer = ALDMViewer(self)
        return super().render()
