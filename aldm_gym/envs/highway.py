"""``ALDMHighway-v0``: highway driving whose ego sees lanes only through a line sensor.

See :class:`ALDMHighwayEnv`'s docstring (spaces, reward, episode end) and ``docs/env.md``.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from highway_env import utils
from highway_env.envs.common.abstract import AbstractEnv
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.envs.config import default_config, merge_config, road_config
from aldm_gym.envs.control import LKAController
from aldm_gym.envs.observation import build_observation, observation_space
from aldm_gym.envs.traffic import BatchedLaneUpdate, FastControlledVehicle, FastRoad, _clip
from aldm_gym.roads.highway import HighwayRoad, RoadConfig
from aldm_gym.sensor.detection import LaneDetection, driving_trajectory
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import ground_truth_detect, score_detection
from aldm_gym.sensor.line_sensor import LineSensor
from aldm_gym.sensor.naive import naive_detect
from aldm_gym.types import FloatArray

LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = 0, 1, 2, 3, 4
"""highway-env's ``DiscreteMetaAction`` indices."""

ROAD_END_MARGIN = 250.0
"""The episode is truncated when the ego is this close to the end of the road [m]."""

_ROAD_CACHE: OrderedDict[RoadConfig, HighwayRoad] = OrderedDict()
_ROAD_CACHE_SIZE = 8


def _cached_road(config: RoadConfig) -> HighwayRoad:
    """A :class:`HighwayRoad` per road config, shared across resets (roads are immutable)."""
    road = _ROAD_CACHE.get(config)
    if road is None:
        road = HighwayRoad(config)
        _ROAD_CACHE[config] = road
        while len(_ROAD_CACHE) > _ROAD_CACHE_SIZE:
            _ROAD_CACHE.popitem(last=False)
    else:
        _ROAD_CACHE.move_to_end(config)
    return road


def near_path(left: FloatArray, right: FloatArray, lane_width: float, max_x: float) -> FloatArray:
    """Driving path midway between two lines, fitted on their part up to ``max_x`` [m].

    :func:`~aldm_gym.sensor.detection.driving_trajectory` fits one cubic over the
    whole visible line (up to 200 m); in a tight curve (R = 100 m the marking turns
    sideways within the view) that cubic is off by metres near the car, where the
    controller looks. Fitting only the first ``max_x`` metres (default 80 m, beyond
    the paper's 60 m preview) keeps the path exact near the car on any radius the
    road generator allows. A line keeps at least its first 4 points.
    """

    def cut(line: FloatArray) -> FloatArray:
        if len(line) <= 4:
            return line
        k = max(int(np.searchsorted(line[:, 0], max_x, side="right")), 4)
        return line[:k]

    return driving_trajectory(cut(left), cut(right), lane_width)


class SensorVehicle(BatchedLaneUpdate, Vehicle):
    """The ego vehicle: laterally controlled only from the detected lanes.

    highway-env's kinematic bicycle (``Vehicle``) with its ``lane_index``
    bookkeeping (traffic needs it), but :meth:`act` steers with the
    :class:`~aldm_gym.envs.control.LKAController` on ``self.detection`` (set by the
    environment after every simulation step), never on the true lane.

    Meta actions: IDLE follows the detected trajectory; LANE_LEFT/RIGHT steer onto
    the centre of the detected adjacent lane (midway between the ego line and the
    adjacent line, cubic fits as for the trajectory) and are refused when that
    adjacent line is not detected; FASTER/SLOWER step through ``target_speeds``.
    The change is under way until the detection shows the ego centred in the new
    lane (|y(0)| < ``LC_DONE_OFFSET``) or ``lane_change_timeout`` elapses.
    """

    LC_DONE_OFFSET = 0.3
    """A lane change is complete when the new ego trajectory starts within this of 0 [m]."""

    def __init__(
        self,
        road: Any,
        position: Any,
        heading: float = 0.0,
        speed: float = 0.0,
        lka: LKAController | None = None,
        target_speeds: tuple[float, ...] = (20.0, 25.0, 30.0),
        continuous: bool = False,
        lane_change_timeout: float = 8.0,
        max_acceleration: float = 5.0,
        lane_width: float = 3.75,
    ) -> None:
        super().__init__(road, position, heading, speed)
        self.lka = lka or LKAController()
        self.target_speeds = np.asarray(target_speeds, dtype=np.float64)
        self.speed_index = int(np.argmin(np.abs(self.target_speeds - speed)))
        self.target_speed = float(self.target_speeds[self.speed_index])
        self.continuous = continuous
        self.lane_change_timeout = lane_change_timeout
        self.max_acceleration = max_acceleration
        self.lane_width = lane_width
        self.detection: LaneDetection | None = None
        self.trajectory: FloatArray = np.zeros((0, 2))
        self.path_range = 80.0
        self.command = np.zeros(2)  # continuous mode: (steering ISO [rad], acceleration)
        self.steering_iso = 0.0
        self.lane_change = 0  # +1 left, -1 right, 0 none
        self.lane_change_elapsed = 0.0
        self.lane_change_target_y = 0.0
        self.lane_change_refused = False
        self.lane_changes_completed = 0
        self.lane_changes_aborted = 0  # lost the target lane or timed out
        self.planned_path: FloatArray = np.zeros((0, 2))

    # ------------------------------------------------------------------ actions
    def set_meta_action(self, action: int) -> None:
        """Apply a ``DiscreteMetaAction`` index (see the env docstring)."""
        self.lane_change_refused = False
        if action == FASTER:
            self.speed_index = min(self.speed_index + 1, len(self.target_speeds) - 1)
        elif action == SLOWER:
            self.speed_index = max(self.speed_index - 1, 0)
        elif action in (LANE_LEFT, LANE_RIGHT) and self.lane_change == 0:
            direction = 1 if action == LANE_LEFT else -1
            path = self._adjacent_path(direction)
            if len(path) < 2:
                self.lane_change_refused = True
            else:
                self.lane_change = direction
                self.lane_change_elapsed = 0.0
                self.lane_change_target_y = float(path[0, 1])
        self.target_speed = float(self.target_speeds[self.speed_index])

    def _adjacent_path(self, direction: int) -> FloatArray:
        """Centre path of the detected adjacent lane (+1 left, -1 right), or empty."""
        det = self.detection
        if det is None:
            return np.zeros((0, 2))
        if direction > 0:
            if not (det.found("left_adjacent") and det.found("ego_left")):
                return np.zeros((0, 2))
            return near_path(det.left_adjacent, det.ego_left, self.lane_width, self.path_range)
        if not (det.found("right_adjacent") and det.found("ego_right")):
            return np.zeros((0, 2))
        return near_path(det.ego_right, det.right_adjacent, self.lane_width, self.path_range)

    def _lateral_path(self) -> FloatArray:
        """The path to follow now: the ego trajectory, or the lane-change target's centre."""
        det = self.detection
        if det is None:
            return np.zeros((0, 2))
        if self.lane_change == 0:
            return self.trajectory
        self.lane_change_elapsed += 1.0 / self.sim_frequency
        # The detected lines are relabelled while the ego crosses the marking, so the
        # target lane is tracked by continuity: the candidate centre whose offset at
        # the sensor is nearest to where the target was at the previous step.
        cands = [(0, self.trajectory), (1, self._adjacent_path(1)), (-1, self._adjacent_path(-1))]
        cands = [(k, p) for k, p in cands if len(p) >= 2]
        if not cands:
            self.lane_change = 0
            self.lane_changes_aborted += 1
            return np.zeros((0, 2))
        k, path = min(cands, key=lambda kp: abs(float(kp[1][0, 1]) - self.lane_change_target_y))
        jump = abs(float(path[0, 1]) - self.lane_change_target_y)
        timed_out = self.lane_change_elapsed > self.lane_change_timeout
        if jump > 0.5 * self.lane_width or timed_out:
            self.lane_change = 0  # lost the target lane or took too long: keep the lane
            self.lane_changes_aborted += 1
            return self.trajectory
        self.lane_change_target_y = float(path[0, 1])
        if k == 0 and abs(self.lane_change_target_y) < self.LC_DONE_OFFSET:
            self.lane_change = 0
            self.lane_changes_completed += 1
        return path

    sim_frequency = 10.0
    """Simulation frequency [Hz] (set by the environment), for the lane-change clock."""

    def act(self, action: dict | str | None = None) -> None:
        """Compute (steering, acceleration) for the next simulation step from the detection."""
        if isinstance(action, dict):  # a raw highway-env action (manual control, tests)
            super().act(action)
            return
        if self.continuous:
            steer_iso, accel = float(self.command[0]), float(self.command[1])
            self.planned_path = self.trajectory
        else:
            path = self._lateral_path()
            self.planned_path = path
            steer = self.lka.steering(path, self.speed)
            # No path: hold the last steering (a curve continues), like a driver briefly blind.
            steer_iso = self.steering_iso if steer is None else steer
            accel = self.lka.speed_gain * (self.target_speed - self.speed)
        # np.clip's result for scalars with non-NaN bounds, without its ~4 µs dispatch.
        max_steering = float(self.lka.max_steering)
        max_acceleration = float(self.max_acceleration)
        steer_iso = float(_clip(float(steer_iso), -max_steering, max_steering))
        accel = float(_clip(float(accel), -max_acceleration, max_acceleration))
        self.steering_iso = steer_iso
        # highway-env's world: a positive steering angle turns towards the driver's right.
        self.action = {"steering": -steer_iso, "acceleration": accel}

    step = FastControlledVehicle.step
    """``Vehicle.step``'s bicycle model with the same float operations, numpy-free
    (:class:`~aldm_gym.envs.traffic.FastControlledVehicle`)."""

    @property
    def yaw_rate(self) -> float:
        """Yaw rate [rad/s], ISO sign (> 0 turning left)."""
        beta = math.atan(0.5 * math.tan(float(self.action["steering"])))
        return -self.speed * math.sin(beta) / (0.5 * self.LENGTH)


class _ActionType:
    """highway-env ``ActionType`` protocol for the two action modes of the env."""

    def __init__(self, env: ALDMHighwayEnv) -> None:
        self.env = env
        cfg = env.config
        self.continuous = cfg["action"]["type"] == "ContinuousAction"
        self.max_steering = float(env.lka.max_steering)
        self.max_acceleration = float(cfg["action"]["max_acceleration"])
        self.last_action: Any = None

    def space(self) -> spaces.Space:
        """``Discrete(5)`` or ``Box([-max_steer, -max_acc], [max_steer, max_acc])``."""
        if self.continuous:
            hi = np.array([self.max_steering, self.max_acceleration], dtype=np.float32)
            return spaces.Box(-hi, hi, (2,), np.float32)
        return spaces.Discrete(5)

    @property
    def vehicle_class(self) -> type:
        """The ego vehicle class."""
        return SensorVehicle

    @property
    def controlled_vehicle(self) -> Vehicle:
        """The ego vehicle."""
        return self.env.vehicle

    def act(self, action: Any) -> None:
        """Pass an agent action to the ego (once per policy step)."""
        ego = self.env.vehicle
        self.last_action = action
        if self.continuous:
            a = np.asarray(action, dtype=np.float64).reshape(-1)
            if a.shape != (2,) or not np.all(np.isfinite(a)):
                raise ValueError(f"continuous action must be 2 finite numbers, got {action!r}")
            hi = np.array([self.max_steering, self.max_acceleration])
            ego.command = np.clip(a, -hi, hi)
        else:
            a = int(np.asarray(action).reshape(-1)[0])
            if not 0 <= a <= 4:
                raise ValueError(f"meta action must be in [0, 4], got {action!r}")
            ego.set_meta_action(a)

    def get_available_actions(self) -> list[int]:
        """All meta actions (refused ones are no-ops)."""
        return [0, 1, 2, 3, 4]


class _ObservationType:
    """highway-env ``ObservationType`` protocol around :mod:`aldm_gym.envs.observation`."""

    def __init__(self, env: ALDMHighwayEnv) -> None:
        self.env = env
        self.observer_vehicle = env.vehicle

    def space(self) -> spaces.Space:
        """See :func:`aldm_gym.envs.observation.observation_space`."""
        o = self.env.config["observation"]
        return observation_space(int(o["vehicles_count"]), float(o["perception_distance"]))

    def observe(self) -> dict[str, np.ndarray]:
        """The current observation."""
        return self.env._observe()


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
      | 1   | IDLE       | keep the lane: pure pursuit on the detected trajectory              |
      | 2   | LANE_RIGHT | steer onto the detected right lane (no-op if its line is not found) |
      | 3   | FASTER     | next higher target speed of ``action.target_speeds``                |
      | 4   | SLOWER     | next lower target speed                                             |

    * ``"ContinuousAction"``: ``Box((2,), float32)``: steering [rad] (ISO: > 0 turns
      left, within ±``lka.max_steering``) and acceleration [m/s²] (±``max_acceleration``).
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

    Lane codes of `vehicles`: 1 ego lane, 2 left, 3 right, 0 other / unknown.

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
    ``departures`` (count this episode). See ``docs/env.md``.

    ## Version History

    * v0: initial version.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 10}  # noqa: RUF012

    def __init__(self, config: Mapping[str, Any] | None = None, render_mode: str | None = None):
        # AbstractEnv.__init__ calls reset(): everything reset needs is set first.
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        self.highway: HighwayRoad | None = None
        self.sensor: LineSensor | None = None
        self.frame: SensorFrame | None = None
        self.detection: LaneDetection | None = None
        self.lka = LKAController()
        self._detector: Callable[[SensorFrame], LaneDetection] | None = None
        self._departed_step = False
        self._departures = 0
        self._truth = (0.0, 0.0, 0)  # s, lateral offset, lane id
        self._s_before = 0.0
        self._path_range: float | None = 80.0
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
        self._path_range = lka.pop("path_range", 80.0)
        self.lka = LKAController(**lka, sensor_x=self._sensor_x())

    def _sensor_x(self) -> float:
        return float(self.config["sensor"].get("mount_x", 1.0))

    def define_spaces(self) -> None:
        """Observation and action types and spaces from the config."""
        self.observation_type = _ObservationType(self)
        self.action_type = _ActionType(self)
        self.observation_space = self.observation_type.space()
        self.action_space = self.action_type.space()

    # ------------------------------------------------------------------ scene
    def _reset(self) -> None:
        cfg = self.config
        seed = (
            int(self.np_random.integers(0, 2**31 - 1)) if cfg["road"].get("seed", 0) is None else 0
        )
        self.highway = _cached_road(road_config(cfg, seed))
        self.sensor = LineSensor(cfg["sensor"])
        self._detector = self._make_detector()
        self.road = FastRoad(
            network=self.highway.network,
            np_random=self.np_random,
            record_history=cfg["show_trajectories"],
            neighbour_vehicles_connected_lanes=cfg["neighbour_vehicles_connected_lanes"],
        )
        self._create_vehicles()
        self._departures = 0
        self._departed_step = False
        self._perceive()
        self._s_before = self._truth[0]

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
        act = cfg["action"]
        ego = SensorVehicle(
            self.road,
            seed_vehicle.position,
            seed_vehicle.heading,
            seed_vehicle.speed,
            lka=self.lka,
            target_speeds=tuple(act["target_speeds"]),
            continuous=act["type"] == "ContinuousAction",
            lane_change_timeout=float(act["lane_change_timeout"]),
            max_acceleration=float(act["max_acceleration"]),
            lane_width=self.highway.lane_width if self.highway else 3.75,
        )
        ego.sim_frequency = float(cfg["simulation_frequency"])
        ego.path_range = 1e9 if self._path_range is None else float(self._path_range)
        self.controlled_vehicles = [ego]
        self.road.vehicles.append(ego)
        for _ in range(int(cfg["vehicles_count"])):
            v = other_type.create_random(self.road, spacing=1.0 / float(cfg["vehicles_density"]))
            v.randomize_behavior()
            self.road.vehicles.append(v)

    def _make_detector(self) -> Callable[[SensorFrame], LaneDetection]:
        cfg = self.config
        name = cfg["detector"]
        lane_width = self.highway.lane_width if self.highway else 3.75
        if name == "aldm":
            from aldm_gym.sensor.aldm import detect_lanes, make_params

            params = make_params(None, **cfg["detector_params"])
            return lambda frame: detect_lanes(frame, params)
        if name == "naive":
            return lambda frame: naive_detect(frame, lane_width)

        def truth(frame: SensorFrame) -> LaneDetection:
            assert self.highway is not None
            return ground_truth_detect(self.highway, frame, self._truth[2])

        return truth

    # ------------------------------------------------------------------ simulation
    def _perceive(self) -> None:
        """Ground truth bookkeeping, then one sensor frame and one detection."""
        ego = self.vehicle
        hw = self.highway
        assert hw is not None and self.sensor is not None and self._detector is not None
        s, d, lane_id = hw.locate(ego.position)
        offset = d - hw.lane_offset(lane_id)
        self._truth = (float(s), float(offset), lane_id)
        mount_x = self.sensor.config.mount_x
        rng = self.np_random if self.sensor.config.noisy else None
        t = self.steps / self.config["simulation_frequency"]
        self.frame = self.sensor.measure(
            hw, (ego.position[0], ego.position[1], ego.heading), t, rng=rng, s_hint=s + mount_x
        )
        self.detection = det = self._detector(self.frame)
        ego.detection = det
        if self._path_range is None:
            ego.trajectory = det.trajectory
        else:
            ego.trajectory = near_path(det.ego_left, det.ego_right, hw.lane_width, self._path_range)
        # A wheel over a marking: |offset| + half the vehicle width beyond half the lane.
        over = abs(offset) + 0.5 * ego.WIDTH > 0.5 * hw.lane_width
        if over and ego.lane_change == 0:
            if not self._departed_step:
                self._departures += 1
            self._departed_step = True

    def _simulate(self, action: Any = None) -> None:
        """``simulation_frequency / policy_frequency`` steps; sensor + detector at each."""
        frames = int(self.config["simulation_frequency"] // self.config["policy_frequency"])
        dt = 1.0 / self.config["simulation_frequency"]
        self._s_before = self._truth[0]
        self._departed_step = False
        if action is not None and not self.config["manual_control"]:
            self.action_type.act(action)
        for frame in range(frames):
            self.road.act()
            self.road.step(dt)
            self.steps += 1
            self._perceive()
            if frame < frames - 1:
                self._automatic_rendering()
        self.enable_auto_render = False

    # ------------------------------------------------------------------ observation
    def _observe(self) -> dict[str, np.ndarray]:
        ego = self.vehicle
        frame = self.frame
        assert frame is not None
        cy, sy = math.cos(frame.yaw), math.sin(frame.yaw)
        others = [v for v in self.road.vehicles if v is not ego]
        if others:
            pos = np.array([v.position for v in others], dtype=np.float64) - frame.origin
            vel = np.array([v.velocity for v in others], dtype=np.float64) - ego.velocity
            # World -> sensor frame (y to the driver's left, see roads.geometry).
            rel = np.column_stack(
                [
                    pos[:, 0] * cy + pos[:, 1] * sy,
                    pos[:, 0] * sy - pos[:, 1] * cy,
                    vel[:, 0] * cy + vel[:, 1] * sy,
                    vel[:, 0] * sy - vel[:, 1] * cy,
                ]
            )
        else:
            rel = np.zeros((0, 4))
        ego_state = np.array([ego.speed, ego.yaw_rate, ego.steering_iso, float(ego.lane_change)])
        o = self.config["observation"]
        back = ego.position - frame.origin
        ego_x = float(back[0] * cy + back[1] * sy)
        return build_observation(
            self.detection,
            ego.trajectory,
            ego_state,
            rel,
            int(o["vehicles_count"]),
            float(o["perception_distance"]),
            ego_x,
        )

    # ------------------------------------------------------------------ reward / end
    def _rewards(self, action: Any) -> dict[str, float]:
        cfg = self.config
        hw = self.highway
        assert hw is not None
        ego = self.vehicle
        s, offset, lane_id = self._truth
        lo, hi = cfg["reward_speed_range"]
        forward_speed = ego.speed * math.cos(ego.heading - float(hw.reference.heading_at(s)))
        step_time = 1.0 / cfg["policy_frequency"]
        is_lc = (
            not self.action_type.continuous
            and action is not None
            and int(np.asarray(action).reshape(-1)[0]) in (LANE_LEFT, LANE_RIGHT)
        )
        return {
            "collision_reward": float(ego.crashed),
            "departure_reward": float(self._departed_step),
            "high_speed_reward": float(np.clip(utils.lmap(forward_speed, [lo, hi], [0, 1]), 0, 1)),
            "progress_reward": float(np.clip((s - self._s_before) / (hi * step_time), 0.0, 1.0)),
            "lane_keeping_reward": float(max(0.0, 1.0 - abs(offset) / (0.5 * hw.lane_width))),
            "right_lane_reward": lane_id / max(hw.lanes_count - 1, 1),
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
        hw = self.highway
        assert hw is not None
        offroad = self._truth[2] in (0, hw.lanes_count - 1) and (
            abs(self._truth[1]) > 0.5 * hw.lane_width
        )
        return bool(
            self.vehicle.crashed
            or (cfg["offroad_terminal"] and offroad)
            or (cfg["departure_terminal"] and self._departed_step)
        )

    def _is_truncated(self) -> bool:
        assert self.highway is not None
        return bool(
            self.time >= self.config["duration"]
            or self._truth[0] > self.highway.length - ROAD_END_MARGIN
        )

    def _info(self, obs: Any, action: Any = None) -> dict:
        info = super()._info(obs, action)
        ego = self.vehicle
        _, offset, lane_id = self._truth
        info.update(
            {
                "lateral_offset": offset,
                "lane_departure": bool(self._departed_step),
                "lane_index": lane_id,
                "lane_change": int(ego.lane_change),
                "lane_change_refused": bool(ego.lane_change_refused),
                "lane_changes_completed": int(ego.lane_changes_completed),
                "lane_changes_aborted": int(ego.lane_changes_aborted),
                "arc_length": float(self._truth[0]),
                "departures": self._departures,
                "detection": self._score(),
            }
        )
        return info

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
        scores = score_detection(self.detection, self.highway, self.frame, self._truth[2])
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
