"""``ALDMHighway-v0``: highway driving whose ego sees lanes only through a line sensor.

See :class:`ALDMHighwayEnv`'s docstring (spaces, reward, episode end) and ``docs/env.md``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from highway_env import utils
from highway_env.envs.common.abstract import AbstractEnv
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.envs.actions import ALDMAction
from aldm_gym.envs.config import EnvConfig, default_config, map_road, merge_config, road_config
from aldm_gym.envs.control import LKAController
from aldm_gym.envs.longitudinal import (
    ACCConfig,
    LongitudinalCommand,
    LongitudinalController,
)
from aldm_gym.envs.observation import ALDMObservation
from aldm_gym.envs.targets import (
    NO_TARGET,
    Objects,
    TargetSelector,
    lane_overlap,
    objects_from_world,
)
from aldm_gym.envs.traffic import FastRoad
from aldm_gym.envs.traffic import kernels as K
from aldm_gym.envs.traffic.compiled import CompiledTraffic
from aldm_gym.envs.traffic.mix import Spawner, TrafficConfig, make_truck
from aldm_gym.envs.traffic.scalar import cos_scalar, sin_scalar
from aldm_gym.envs.traffic.vehicles import _uses_base_kinematics
from aldm_gym.envs.vehicle import MapIDMVehicle, SensorVehicle
from aldm_gym.errors import ConfigError
from aldm_gym.roads.cache import cached_road
from aldm_gym.roads.highway import HighwayRoad
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.roads.position import LanePosition
from aldm_gym.sensor.detection import LaneDetection
from aldm_gym.sensor.detectors import Detector, make_detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import score_detection
from aldm_gym.sensor.line_sensor import LineSensor, LineSensorConfig
from aldm_gym.sensor.tracking import EgoMotion

ROAD_END_MARGIN = 250.0
"""The episode is truncated when the ego is this close to the end of the road [m]."""

MAP_MIN_AHEAD = 500.0
"""On a map the ego starts with at least ``max(this, initial_speed · duration)`` of its
lane chain ahead, plus :data:`ROAD_END_MARGIN` [m]."""

MAP_TRAFFIC_ROOM = 200.0
"""Traffic is not placed on a lane whose chain ends within this distance [m]."""


def _velocity(vehicle: Any) -> Any:
    """``vehicle.velocity`` [m/s] (world frame): for highway-env's own kinematics the
    same floats computed without building two arrays."""
    if _uses_base_kinematics(type(vehicle)):
        speed, heading = vehicle.speed, vehicle.heading
        return (speed * cos_scalar(heading), speed * sin_scalar(heading))
    return vehicle.velocity


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
    ``normalize_reward``, mapped linearly from ``[collision + departure, positive sum]``
    to ``[0, 1]``:

    | term                  | default | value                                          |
    |-----------------------|---------|------------------------------------------------|
    | `collision_reward`    | -1.0    | 1 if crashed                                   |
    | `departure_reward`    | -0.5    | 1 if a wheel crossed a marking (no lane change)|
    | `high_speed_reward`   | 0.3     | speed mapped from `reward_speed_range` to [0,1]|
    | `progress_reward`     | 0.2     | road distance / (max speed · step), in [0, 1]  |
    | `lane_keeping_reward` | 0.3     | max(0, 1 - abs(offset) / (lane width / 2))     |
    | `right_lane_reward`   | 0.0     | lane id / (lanes - 1), 1 on the rightmost lane |
    | `lane_change_reward`  | 0.0     | 1 if the action was LANE_LEFT/RIGHT            |

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
    "correct" (1/0)}}``, NaN error and preview when the line is missing),
    ``departures`` (count this episode), ``target`` (the ACC's target against ground
    truth: ``target``, ``leader``, ``correct``, ``missed``, ``false``, ``aeb``,
    ``aeb_activations``, ``phantom_braking``, ``gap``, ``time_gap``), ``collision``
    (``""``, ``"front"``, ``"rear"``, ``"side"``); on a map also ``lane_ends_in`` (distance to
    the end of the ego's lane chain when it ends before the road [m], else inf). See
    ``docs/env.md``.

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
        self.highway: HighwayRoad | OpenDriveRoad | None = None
        """The road the ego drives on: a generated highway, or a map (``road.xodr``)."""
        self._off_map = False
        self.sensor: LineSensor | None = None
        self.frame: SensorFrame | None = None
        self.detection: LaneDetection | None = None
        self.lka = LKAController()
        self._detector: Detector | None = None
        self._departed_step = False
        self._departures = 0
        self.lane_position: LanePosition = LanePosition(0.0, 0.0, 0, 0, 1, 3.75, 0.0, 0.0)
        """The ego's ground-truth position on the road, updated every simulation step."""
        self._s_before = 0.0
        self._space_seed: int | None = None
        self.longitudinal: LongitudinalController | None = None
        """Target selection, ACC and AEB (``acc.enabled``): :mod:`aldm_gym.envs.longitudinal`."""
        self.acc_command: LongitudinalCommand | None = None
        """The longitudinal controller's output at the last simulation step."""
        self._truth = TargetSelector()
        self._objects = Objects()
        self._objects_xy = np.zeros((0, 2))
        self._acc_step: dict[str, Any] = {}
        self._lc_target_index: int | None = None
        self._collision = ""
        self._odometry: tuple[float, float, float] | None = None
        super().__init__(dict(config) if config else None, render_mode)

    # ------------------------------------------------------------------ config
    @classmethod
    def default_config(cls) -> dict:
        """See :func:`aldm_gym.envs.config.default_config`."""
        return default_config()

    def configure(self, config: Mapping[str, Any] | None) -> None:
        """Merge ``config`` into the current configuration after validating it.

        :raises ValueError: naming unknown keys and the allowed ones, or a bad value.
        """
        self.config = merge_config(self.config, config)
        if self.config["offscreen_rendering"] is None:
            self.config["offscreen_rendering"] = self.render_mode != "human"
        lka = dict(self.config["lka"])
        lka.pop("path_range")
        mount_x = LineSensorConfig(**self.config["sensor"]).mount_x
        self.lka = LKAController(**lka, sensor_x=float(mount_x))

    @property
    def path_range(self) -> float | None:
        """The trajectory is fitted on the detected lines up to this x [m] (``lka.path_range``)."""
        return self.config["lka"]["path_range"]

    def define_spaces(self) -> None:
        """Observation and action types and spaces from the config."""
        self.observation_type = ALDMObservation(self)
        self.action_type = ALDMAction(self)
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

    # ------------------------------------------------------------------ scene
    def _reset(self) -> None:
        cfg = self.config
        on_map = map_road(cfg)
        if on_map is None:
            seed = (
                int(self.np_random.integers(0, 2**31 - 1))
                if cfg["road"].get("seed", 0) is None
                else 0
            )
            self.highway = cached_road(road_config(cfg, seed))
        else:
            self.highway = on_map
        self.sensor = LineSensor(cfg["sensor"])
        self._detector = make_detector(
            cfg["detector"], cfg["detector_params"], path_range=self.path_range
        )
        if self.road is not None:
            # The old road and its vehicles reference each other; releasing them frees
            # them at once instead of at Python's next full garbage collection
            # (docs/reliability.md, "Memory over a long run").
            self.road.release()
        self.road = FastRoad(
            network=self.highway.network,
            np_random=self.np_random,
            record_history=cfg["show_trajectories"],
            # A map's lanes end at every lane section: look across to see the leader.
            neighbour_vehicles_connected_lanes=(
                cfg["neighbour_vehicles_connected_lanes"] or on_map is not None
            ),
        )
        if on_map is None and cfg["traffic"]["engine"] == "compiled":
            self.road.engine = CompiledTraffic(self.highway)
        self._off_map = False
        if on_map is None:
            self._create_vehicles()
        else:
            self._create_map_vehicles(on_map)
        self._departures = 0
        self._departed_step = False
        self._collision = ""
        self._odometry = None  # a new episode: the tracking ALDM starts without a prior
        self._reset_longitudinal()
        self._perceive()
        self._s_before = self.lane_position.s

    def _reset_longitudinal(self) -> None:
        """A fresh ACC/AEB (``acc.enabled``) and its ground-truth twin for ``info["target"]``."""
        acc = ACCConfig(**self.config["acc"])
        assert self.sensor is not None and self.highway is not None
        ego_x = -float(self.sensor.config.mount_x)
        lane_width = float(self.highway.lane_width)
        self.acc_command = None
        self._objects = Objects()
        self._acc_step = {"aeb": False, "phantom_braking": False}
        self._lc_target_index = None
        self.vehicle.acc_braking_limit = acc.aeb_deceleration
        if not acc.enabled:
            self.longitudinal = None
            return
        self.longitudinal = LongitudinalController(acc, ego_x=ego_x, lane_width=lane_width)
        self._truth = TargetSelector(
            max_range=acc.range,
            enter_overlap=acc.enter_overlap,
            exit_overlap=acc.exit_overlap,
            lane_width=lane_width,
            ego_x=ego_x,
        )

    def _create_vehicles(self) -> None:
        """Ego then ``vehicles_count`` IDM vehicles ahead of it, as in ``highway-v0``."""
        cfg = self.config
        other_type = utils.class_from_path(cfg["other_vehicles_type"])
        seed_vehicle = Vehicle.create_random(
            self.road,
            speed=float(cfg["initial_speed"]),
            lane_id=cfg["initial_lane_id"],
            spacing=float(cfg["ego_spacing"]),
        )
        ego = self._make_ego(seed_vehicle.position, seed_vehicle.heading, seed_vehicle.speed)
        self.controlled_vehicles = [ego]
        self.road.vehicles.append(ego)
        spawner = Spawner(TrafficConfig(**cfg["traffic"]), self.np_random)
        for _ in range(int(cfg["vehicles_count"])):
            v = other_type.create_random(self.road, spacing=1.0 / float(cfg["vehicles_density"]))
            v.randomize_behavior()
            spawner.place(v, spawner.draw())
            self.road.vehicles.append(v)

    def _make_ego(self, position: Any, heading: float, speed: float) -> SensorVehicle:
        cfg = self.config
        act = cfg["action"]
        assert self.highway is not None
        ego = SensorVehicle(
            self.road,
            position,
            heading,
            speed,
            lka=self.lka,
            target_speeds=tuple(act["target_speeds"]),
            continuous=act["type"] == "ContinuousAction",
            lane_change_timeout=float(act["lane_change_timeout"]),
            max_acceleration=float(act["max_acceleration"]),
            lane_width=self.highway.lane_width,
            path_range=self.path_range,
        )
        ego.sim_frequency = float(cfg["simulation_frequency"])
        return ego

    def _create_map_vehicles(self, road: OpenDriveRoad) -> None:
        """Ego on a seeded lane and position of the map, then IDM/MOBIL traffic ahead.

        The ego starts on a driving lane (of index ``initial_lane_id`` from the left, if
        set) at a position drawn uniformly among those with at least
        ``max(MAP_MIN_AHEAD, initial_speed · duration) + ROAD_END_MARGIN`` of lane chain
        ahead (the longest available, with a warning, on a short map). Traffic is placed
        ahead of it along its lane chain, highway-env's way (gaps shrinking with the
        lane count and ``vehicles_density``), each vehicle on a random lane of the
        ego's direction there, never on a lane that ends within ``MAP_TRAFFIC_ROOM``.
        """
        cfg = self.config
        rng = self.np_random
        net = road.network
        speed = float(cfg["initial_speed"])
        need = max(MAP_MIN_AHEAD, speed * float(cfg["duration"])) + ROAD_END_MARGIN
        lanes = list(road.lanes)
        if cfg["initial_lane_id"] is not None:
            lanes = [k for k in lanes if road.siblings(k).index(k) == cfg["initial_lane_id"]]
            if not lanes:
                raise ConfigError(
                    f"config.initial_lane_id {cfg['initial_lane_id']} : the map "
                    f"{road.map.path!r} has no driving lane with that index from the left"
                )
        # Start u along lane k such that chain_end - (chain_start + u) >= need.
        room = np.array(
            [
                min(road.lane_length(k), road.chain_end(k) - road.chain_start(k) - need)
                for k in lanes
            ]
        )
        weights = np.maximum(room, 0.0)
        if weights.sum() > 0.0:
            cum = np.cumsum(weights)
            i = min(
                int(np.searchsorted(cum, rng.uniform(0.0, cum[-1]), side="right")), len(lanes) - 1
            )
            u = float(rng.uniform(0.0, weights[i]))
        else:
            ahead = [road.chain_end(k) - road.chain_start(k) for k in lanes]
            i = int(np.argmax(ahead))
            u = 0.0
            warnings.warn(
                f"{road.map.path}: no driving lane has {need:.0f} m ahead; the ego starts "
                f"with the longest ({ahead[i]:.0f} m) and the episode may end early",
                stacklevel=2,
            )
        key = lanes[i]
        lane = net.get_lane(net.index_of[key])
        ego = self._make_ego(lane.position(u, 0.0), lane.heading_at(u), speed)
        self.controlled_vehicles = [ego]
        self.road.vehicles.append(ego)
        other_type = utils.class_from_path(cfg["other_vehicles_type"])
        if other_type.__name__ == "FastIDMVehicle" and cfg["other_vehicles_type"] == (
            EnvConfig.other_vehicles_type
        ):
            other_type = MapIDMVehicle  # the default traffic, with the mandatory merge
        spacing = 1.0 / float(cfg["vehicles_density"])
        spawner = Spawner(TrafficConfig(**cfg["traffic"]), rng)
        cur, cur_u = key, u
        for _ in range(int(cfg["vehicles_count"])):
            siblings = road.siblings(cur)
            v_speed = float(rng.uniform(0.7 * lane.speed_limit, 0.8 * lane.speed_limit))
            offset = spacing * (12.0 + v_speed) * math.exp(-5.0 / 40.0 * len(siblings))
            cur_u += offset * float(rng.uniform(0.9, 1.1))
            truck = spawner.draw()
            cur_u += spawner.extra_shift(truck)
            while cur is not None and cur_u > road.lane_length(cur):
                cur_u -= road.lane_length(cur)
                cur = road.successor(cur)
            if cur is None:
                break  # the ego's lane chain ends: no more room ahead
            siblings = road.siblings(cur)
            target = siblings[int(rng.integers(len(siblings)))]
            point = net.get_lane(net.index_of[cur]).position(cur_u, 0.0)
            other = net.get_lane(net.index_of[target])
            s, _ = other.local_coordinates(point)
            left = road.chain_end(target) - road.chain_start(target) - s
            if not (0.0 <= s <= other.length) or left < MAP_TRAFFIC_ROOM:
                continue
            v = other_type(self.road, other.position(s, 0.0), other.heading_at(s), v_speed)
            v.randomize_behavior()
            if truck is not None:
                make_truck(v, truck, spawner.config)
            self.road.vehicles.append(v)

    # ------------------------------------------------------------------ simulation
    def _perceive(self) -> None:
        """Ground truth bookkeeping, then one sensor frame and one detection."""
        ego = self.vehicle
        hw = self.highway
        assert hw is not None and self.sensor is not None and self._detector is not None
        try:
            self.lane_position = pos = hw.lane_position(ego.position)
        except ValueError:
            if not isinstance(hw, OpenDriveRoad):
                raise
            # Off the map (no driving lane within reach): keep the last lane, an
            # infinite offset counts a departure, and the episode terminates.
            self._off_map = True
            last = self.lane_position
            self.lane_position = pos = dataclasses.replace(
                last, offset=math.copysign(math.inf, last.offset)
            )
        mount_x = self.sensor.config.mount_x
        rng = self.np_random if self.sensor.config.noisy else None
        t = self.steps / self.config["simulation_frequency"]
        self.frame = self.sensor.measure(
            hw,
            (ego.position[0], ego.position[1], ego.heading),
            t,
            rng=rng,
            s_hint=pos.s + mount_x,
            occluders=self.road.vehicles if self.sensor.config.occlusion else None,
        )
        detector = self._detector
        motion = self._ego_motion() if getattr(detector, "uses_motion", True) else None
        self.detection = det = detector(self.frame, hw, pos.lane, motion=motion)
        ego.detection = det
        ego.trajectory = det.trajectory  # fitted up to lka.path_range by the detector
        if self.longitudinal is not None:
            self._longitudinal_step(pos)
        if ego.crashed and not self._collision:
            # Classified at the step of the impact: the crashed ego slides on.
            self._collision = self._collision_kind()
        # A wheel over a marking: |offset| + half the vehicle width beyond half the lane.
        over = abs(pos.offset) + 0.5 * ego.WIDTH > 0.5 * pos.width
        if over and ego.lane_change == 0:
            if not self._departed_step:
                self._departures += 1
            self._departed_step = True

    def _ego_motion(self) -> EgoMotion | None:
        """The sensor's motion since the previous frame, as odometry would give it: the
        distance its mount point travelled and its heading change over the simulation
        step (the tracking ALDM's input); ``None`` at the first frame of an episode or
        after an implausible jump."""
        ego = self.vehicle
        assert self.sensor is not None
        heading = float(ego.heading)
        origin, _ = self.sensor.world_pose((ego.position[0], ego.position[1], heading))
        pose = (float(origin[0]), float(origin[1]), heading)
        last, self._odometry = self._odometry, pose
        if last is None:
            return None
        dt = 1.0 / self.config["simulation_frequency"]
        speed = math.hypot(pose[0] - last[0], pose[1] - last[1]) / dt
        # highway-env's heading grows clockwise (its y axis points right of x): the
        # sensor frame's yaw (ISO 8855, left positive) turns the other way
        turn = -((pose[2] - last[2] + math.pi) % (2.0 * math.pi) - math.pi)
        if speed > 200.0 or abs(turn / dt) > 10.0:
            return None
        return EgoMotion(speed, turn / dt, dt)

    def _sense_objects(self) -> Objects:
        """The other vehicles in the sensor frame (ids: their index in ``road.vehicles``).

        Positions and velocities are exact (an ideal object sensor): the comparison is
        about the lanes, not about object detection.
        """
        ego = self.vehicle
        frame = self.frame
        assert frame is not None
        vehicles = self.road.vehicles
        n = len(vehicles)
        ego_row = next((i for i, v in enumerate(vehicles) if v is ego), n)
        rows = [*range(ego_row), *range(ego_row + 1, n)]
        if not rows:
            return Objects()
        engine = self.road.engine
        state = engine.moved_state(self.road) if engine is not None else None
        if state is not None:
            # The compiled traffic's arrays hold these very values: no second gather.
            table = state[1:].copy() if ego_row == 0 else state[rows]
            xy = self._objects_xy = table[:, K.F_X : K.F_Y + 1]
            speed, heading = table[:, K.F_SPEED], table[:, K.F_HEADING]
            width, length = table[:, K.F_WIDTH], table[:, K.F_LENGTH]
        else:
            others = [vehicles[i] for i in rows]
            xy = self._objects_xy = np.array([v.position for v in others], dtype=np.float64)
            speed = np.array([v.speed for v in others], dtype=np.float64)
            heading = np.array([v.heading for v in others], dtype=np.float64)
            width = np.array([v.WIDTH for v in others], dtype=np.float64)
            length = np.array([v.LENGTH for v in others], dtype=np.float64)
        return objects_from_world(
            np.array(rows, dtype=np.int64),
            xy,
            speed,
            heading,
            width,
            length,
            frame.origin,
            frame.yaw,
            _velocity(ego),
        )

    def _longitudinal_step(self, pos: LanePosition) -> None:
        """Target selection, ACC and AEB on this step's detection; its ground truth."""
        ego = self.vehicle
        ctrl = self.longitudinal
        assert ctrl is not None
        objects = self._objects = self._sense_objects()
        speed = float(ego.speed)
        curvature = ego.yaw_rate / speed if abs(speed) > 0.1 else 0.0
        path = ego.planned_path if len(ego.planned_path) >= 2 else ego.trajectory
        cmd = self.acc_command = ctrl.update(
            self.detection,
            objects,
            speed,
            float(ego.target_speed),
            path=path,
            side=int(ego.lane_change_side),
            curvature=curvature,
        )
        # The continuous action stays raw: the selection runs (info), nothing acts on it.
        ego.acc_command = None if ego.continuous else cmd.acceleration
        if ego.continuous:
            return
        self._acc_step["aeb"] |= cmd.aeb
        braking = (cmd.following or cmd.aeb) and (
            cmd.acceleration < -ctrl.config.phantom_deceleration
        )
        if braking and cmd.target != NO_TARGET and not self._acc_step["phantom_braking"]:
            # Braking hard for the target: is it truly in the ego's corridor?
            row = np.array([objects.index_of(cmd.target)])
            overlap = self._true_overlap(objects, row, pos)[0]
            self._acc_step["phantom_braking"] = bool(overlap < ctrl.config.exit_overlap)

    def _true_overlap(self, objects: Objects, rows: np.ndarray, pos: LanePosition) -> np.ndarray:
        """Ground truth: overlap [m] of ``objects`` ``rows`` with the ego's true corridor.

        Each vehicle is placed by the road's ground truth relative to the ego's true
        lane centre (:meth:`_true_lateral`); the true corridor is the ego's lane, plus
        the lane it changes into while a lane change is under way.
        """
        ego = self.vehicle
        if ego.lane_change == 0:
            self._lc_target_index = None
        elif self._lc_target_index is None:
            self._lc_target_index = pos.index - int(ego.lane_change)  # ids grow rightwards
        target = pos.index if self._lc_target_index is None else self._lc_target_index
        lo, hi = min(pos.index, target), max(pos.index, target)
        w = pos.width
        left, right = (pos.index - lo) * w + 0.5 * w, (pos.index - hi) * w - 0.5 * w
        y = self._true_lateral(self._objects_xy[rows], pos)
        overlap = lane_overlap(y, objects.width[rows], left, right)
        overlap[~np.isfinite(y)] = -math.inf
        return overlap

    def _true_leader(self) -> int:
        """The in-lane leader by ground truth: the target selector's rule and
        hysteresis (:class:`~aldm_gym.envs.targets.TargetSelector`) on the true
        corridor (:meth:`_true_overlap`). Evaluated once per policy step, for ``info``.
        """
        truth = self._truth
        objects = self._objects
        x = objects.x - truth.ego_x
        near = np.flatnonzero((x > 0.0) & (x <= truth.max_range))
        overlap = self._true_overlap(objects, near, self.lane_position)
        return truth.select_overlaps(objects.ids[near], objects.x[near], overlap)

    def _true_lateral(self, xy: np.ndarray, pos: LanePosition) -> np.ndarray:
        """Ground truth: lateral position [m] (> 0 left) of world points ``xy`` (N, 2)
        relative to the centre of the ego's lane; ``inf`` off a map's lanes.

        A generated road measures it along its one reference line (one compiled batch
        projection); a map as ``(ego lane index - its index) · width + its offset``.
        """
        hw = self.highway
        if len(xy) == 0:
            return np.zeros(0)
        if isinstance(hw, HighwayRoad):
            _, d = hw.reference.project_many(xy)
            return d - hw.lane_offset(pos.lane)
        assert hw is not None
        y = np.full(len(xy), math.inf)
        for k in range(len(xy)):
            try:
                p = hw.lane_position(xy[k])
            except ValueError:
                continue  # off a map's lanes: in no lane
            y[k] = (pos.index - p.index) * pos.width + p.offset
        return y

    def _simulate(self, action: Any = None) -> None:
        """``simulation_frequency / policy_frequency`` steps; sensor + detector at each."""
        frames = int(self.config["simulation_frequency"] // self.config["policy_frequency"])
        dt = 1.0 / self.config["simulation_frequency"]
        self._s_before = self.lane_position.s
        self._departed_step = False
        self._acc_step = {"aeb": False, "phantom_braking": False}
        if not self.config["manual_control"]:
            self.action_type.act(action)  # raises ValueError on a bad action (None too)
        engine = self.road.engine
        # Nothing but the simulation touches the traffic until the env step ends.
        with engine.holding() if engine is not None else contextlib.nullcontext():
            for frame in range(frames):
                self.road.act()
                self.road.step(dt)
                self.steps += 1
                self._perceive()
                if frame < frames - 1:
                    self._automatic_rendering()
        self.enable_auto_render = False

    # ------------------------------------------------------------------ reward / end
    def _rewards(self, action: Any) -> dict[str, float]:
        cfg = self.config
        ego = self.vehicle
        pos = self.lane_position
        lo, hi = cfg["reward_speed_range"]
        forward_speed = ego.speed * math.cos(ego.heading - pos.heading)
        step_time = 1.0 / cfg["policy_frequency"]
        is_lc = self.action_type.is_lane_change(action)
        return {
            "collision_reward": float(ego.crashed),
            "departure_reward": float(self._departed_step),
            "high_speed_reward": float(np.clip(utils.lmap(forward_speed, [lo, hi], [0, 1]), 0, 1)),
            "progress_reward": float(
                np.clip((pos.s - self._s_before) / (hi * step_time), 0.0, 1.0)
            ),
            "lane_keeping_reward": float(max(0.0, 1.0 - abs(pos.offset) / (0.5 * pos.width))),
            "right_lane_reward": pos.index / max(pos.lanes - 1, 1),
            "lane_change_reward": float(is_lc),
        }

    def _reward(self, action: Any) -> float:
        rewards = self._rewards(action)
        cfg = self.config
        reward = sum(cfg[name] * value for name, value in rewards.items())
        if cfg["normalize_reward"]:
            neg = sum(min(cfg[n], 0.0) for n in rewards)
            pos = sum(max(cfg[n], 0.0) for n in rewards)
            if pos > neg:
                reward = utils.lmap(reward, [neg, pos], [0.0, 1.0])
        return float(reward)

    def _is_terminated(self) -> bool:
        cfg = self.config
        pos = self.lane_position
        offroad = pos.edge_lane and abs(pos.offset) > 0.5 * pos.width
        return bool(
            self.vehicle.crashed
            or self._off_map
            or (cfg["offroad_terminal"] and offroad)
            or (cfg["departure_terminal"] and self._departed_step)
        )

    def _is_truncated(self) -> bool:
        pos = self.lane_position
        if isinstance(self.highway, OpenDriveRoad):
            # On a map the road ends where the farthest-reaching lane beside the ego
            # ends (its own lane may end sooner: it can merge out).
            road_end = self.highway.road_left(pos) < ROAD_END_MARGIN
        else:
            road_end = pos.s > pos.end - ROAD_END_MARGIN
        return bool(self.time >= self.config["duration"] or road_end)

    def _info(self, obs: Any, action: Any = None) -> dict:
        info = super()._info(obs, action)
        ego = self.vehicle
        pos = self.lane_position
        info.update(
            {
                "lateral_offset": pos.offset,
                "lane_departure": bool(self._departed_step),
                "lane_index": pos.index,
                "lane_change": int(ego.lane_change),
                "lane_change_refused": bool(ego.lane_change_refused),
                "lane_changes_completed": int(ego.lane_changes_completed),
                "lane_changes_aborted": int(ego.lane_changes_aborted),
                "arc_length": pos.s,
                "departures": self._departures,
                "detection": self._score(),
                "target": self._target_info(),
                "collision": self._collision,
            }
        )
        if isinstance(self.highway, OpenDriveRoad):
            # Map only (a generated road's lanes never end; its info stays as it was).
            info["lane_ends_in"] = self.highway.lane_ends_in(pos)
        return info

    def _target_info(self) -> dict[str, Any]:
        """``info["target"]``: the ACC's target against ground truth (``docs/acc.md``)."""
        cmd = self.acc_command
        ctrl = self.longitudinal
        if cmd is None or ctrl is None:
            return {
                "target": NO_TARGET,
                "leader": NO_TARGET,
                "correct": True,
                "missed": False,
                "false": False,
                "aeb": False,
                "aeb_activations": 0,
                "phantom_braking": False,
                "gap": math.inf,
                "time_gap": math.inf,
            }
        leader = self._true_leader()
        target = cmd.target
        time_gap = math.inf
        if leader != NO_TARGET:
            row = self._objects.index_of(leader)
            gap = float(ctrl.gaps(self._objects)[row])
            time_gap = max(gap, 0.0) / max(float(self.vehicle.speed), 0.1)
        return {
            "target": int(target),
            "leader": int(leader),
            "correct": target == leader,
            "missed": leader != NO_TARGET and target != leader,
            "false": target != NO_TARGET and target not in self._truth.inside,
            "aeb": bool(self._acc_step["aeb"]),
            "aeb_activations": int(ctrl.aeb.activations),
            "phantom_braking": bool(self._acc_step["phantom_braking"]),
            "gap": float(cmd.gap),
            "time_gap": time_gap,
        }

    def _collision_kind(self) -> str:
        """Where the other vehicle of the ego's collision was at the impact: ``"front"``
        (the ego ran into it: its centre more than half a car length ahead along the
        ego's axis), ``"rear"`` (it ran into the ego), else ``"side"``."""
        ego = self.vehicle
        others = [v for v in self.road.vehicles if v is not ego and v.crashed]
        if not others:
            return "side"
        other = min(others, key=lambda v: float(np.hypot(*(v.position - ego.position))))
        d = other.position - ego.position
        ahead = float(d[0] * math.cos(ego.heading) + d[1] * math.sin(ego.heading))
        if ahead > 0.5 * ego.LENGTH:
            return "front"
        if ahead < -0.5 * ego.LENGTH:
            return "rear"
        return "side"

    def _score(self) -> dict[str, dict[str, float]]:
        """Per ego line: mean |error| vs truth up to 60 m [m], preview [m], correct (1/0).

        ``correct`` is :class:`~aldm_gym.sensor.ground_truth.LineScore`'s: every point
        within 0.3 m of the true marking, starting <= 25 m, reaching >= 60 m.
        """
        assert self.highway is not None and self.frame is not None
        out: dict[str, dict[str, float]] = {}
        if self.detection is None:
            nan = float("nan")
            return {
                n: {"mean_abs_error": nan, "preview": nan, "correct": 0.0}
                for n in ("ego_left", "ego_right")
            }
        scores = score_detection(self.detection, self.highway, self.frame, self.lane_position.lane)
        for name in ("ego_left", "ego_right"):
            sc = scores[name]
            if sc.found:
                out[name] = {
                    "mean_abs_error": float(sc.mean_abs_error),
                    "preview": sc.preview,
                    "correct": float(sc.correct),
                }
            else:
                out[name] = {
                    "mean_abs_error": float("nan"),
                    "preview": float("nan"),
                    "correct": 0.0,
                }
        return out

    # ------------------------------------------------------------------ rendering
    def render(self) -> np.ndarray | None:
        """Render with highway-env's viewer plus the sensor / detection overlay."""
        if self.render_mode is None:
            return super().render()
        if self.viewer is None:
            from aldm_gym.envs.rendering import ALDMViewer

            self.viewer = ALDMViewer(self)
        return super().render()
