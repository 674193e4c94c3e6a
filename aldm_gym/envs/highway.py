"""``ALDMHighway-v0``: highway driving whose ego sees lanes only through a line sensor.

See :class:`ALDMHighwayEnv`'s docstring (spaces, reward, episode end) and ``docs/env.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from highway_env import utils
from highway_env.envs.common.abstract import AbstractEnv
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.envs.actions import ALDMAction
from aldm_gym.envs.config import default_config, merge_config, road_config
from aldm_gym.envs.control import LKAController
from aldm_gym.envs.observation import ALDMObservation
from aldm_gym.envs.traffic import FastRoad
from aldm_gym.envs.vehicle import SensorVehicle
from aldm_gym.roads.cache import cached_road
from aldm_gym.roads.highway import HighwayRoad
from aldm_gym.roads.position import LanePosition
from aldm_gym.sensor.detection import LaneDetection
from aldm_gym.sensor.detectors import Detector, make_detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import score_detection
from aldm_gym.sensor.line_sensor import LineSensor, LineSensorConfig

ROAD_END_MARGIN = 250.0
"""The episode is truncated when the ego is this close to the end of the road [m]."""


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
    | `lanes`            | (3,4)    | left/ego/right detected lane: gap, rel. vx of the   |
    |                    |          | nearest vehicle ahead, then of the nearest behind   |

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
        self._detector: Detector | None = None
        self._departed_step = False
        self._departures = 0
        self.lane_position: LanePosition = LanePosition(0.0, 0.0, 0, 0, 1, 3.75, 0.0, 0.0)
        """The ego's ground-truth position on the road, updated every simulation step."""
        self._s_before = 0.0
        self._space_seed: int | None = None
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
        seed = (
            int(self.np_random.integers(0, 2**31 - 1)) if cfg["road"].get("seed", 0) is None else 0
        )
        self.highway = cached_road(road_config(cfg, seed))
        self.sensor = LineSensor(cfg["sensor"])
        self._detector = make_detector(
            cfg["detector"], cfg["detector_params"], path_range=self.path_range
        )
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
        self._s_before = self.lane_position.s

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
            lane_width=self.highway.lane_width,
            path_range=self.path_range,
        )
        ego.sim_frequency = float(cfg["simulation_frequency"])
        self.controlled_vehicles = [ego]
        self.road.vehicles.append(ego)
        for _ in range(int(cfg["vehicles_count"])):
            v = other_type.create_random(self.road, spacing=1.0 / float(cfg["vehicles_density"]))
            v.randomize_behavior()
            self.road.vehicles.append(v)

    # ------------------------------------------------------------------ simulation
    def _perceive(self) -> None:
        """Ground truth bookkeeping, then one sensor frame and one detection."""
        ego = self.vehicle
        hw = self.highway
        assert hw is not None and self.sensor is not None and self._detector is not None
        self.lane_position = pos = hw.lane_position(ego.position)
        mount_x = self.sensor.config.mount_x
        rng = self.np_random if self.sensor.config.noisy else None
        t = self.steps / self.config["simulation_frequency"]
        self.frame = self.sensor.measure(
            hw,
            (ego.position[0], ego.position[1], ego.heading),
            t,
            rng=rng,
            s_hint=pos.s + mount_x,
        )
        self.detection = det = self._detector(self.frame, hw, pos.lane)
        ego.detection = det
        ego.trajectory = det.trajectory  # fitted up to lka.path_range by the detector
        # A wheel over a marking: |offset| + half the vehicle width beyond half the lane.
        over = abs(pos.offset) + 0.5 * ego.WIDTH > 0.5 * pos.width
        if over and ego.lane_change == 0:
            if not self._departed_step:
                self._departures += 1
            self._departed_step = True

    def _simulate(self, action: Any = None) -> None:
        """``simulation_frequency / policy_frequency`` steps; sensor + detector at each."""
        frames = int(self.config["simulation_frequency"] // self.config["policy_frequency"])
        dt = 1.0 / self.config["simulation_frequency"]
        self._s_before = self.lane_position.s
        self._departed_step = False
        if not self.config["manual_control"]:
            self.action_type.act(action)  # raises ValueError on a bad action (None too)
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
            or (cfg["offroad_terminal"] and offroad)
            or (cfg["departure_terminal"] and self._departed_step)
        )

    def _is_truncated(self) -> bool:
        return bool(
            self.time >= self.config["duration"]
            or self.lane_position.s > self.lane_position.end - ROAD_END_MARGIN
        )

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
