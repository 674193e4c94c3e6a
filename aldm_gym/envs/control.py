"""Pure-pursuit lane keeping on the detected trajectory: the env's lateral control and an agent.

The paper's LKA follows the desired path the lane detection delivers (midway between
cubic fits of the ego lines, §"Advanced Lane Detection Model"). This controller does
exactly that and nothing else: it never sees the road's ground truth.

Geometry. highway-env's vehicle is a kinematic bicycle with the centre of gravity in
the middle (``beta = atan(tan(delta) / 2)``, ``dpsi/dt = v sin(beta) / (L / 2)``), so
its *rear axle* moves along the heading and the wheelbase is the vehicle length
``L`` (5 m). Pure pursuit from the rear axle is therefore exact on circles: a look-ahead
point at ``(x, y)`` (rear-axle frame, y left) lies on the arc of curvature
``kappa = 2 y / (x² + y²)``, and the steering angle is ``atan(kappa L)``. The look-ahead
distance grows with speed (``lookahead_time * v``, at least ``min_lookahead``).

Signs: ISO 8855 throughout (y left, steering > 0 turns left). highway-env's world
steers the other way round (see :mod:`aldm_gym.roads.reference_line`); the environment
converts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.config import setting, validate
from aldm_gym.envs.traffic.scalar import clip_scalar
from aldm_gym.errors import ConfigError
from aldm_gym.sensor.line_sensor import LineSensorConfig
from aldm_gym.types import FloatArray

WHEELBASE = 5.0
"""highway-env's ``Vehicle.LENGTH``, the wheelbase of its bicycle model [m]."""


@dataclass(frozen=True)
class LKAConfig:
    """The env's ``lka`` section: the lane keeping on the detected trajectory.

    :ivar lookahead_time: look-ahead distance per unit speed [s].
    :ivar min_lookahead: smallest look-ahead distance [m].
    :ivar max_steering: steering saturation [rad].
    :ivar path_range: the trajectory is fitted on the detected lines up to this x [m]
        (``None``: the whole visible line). A cubic over 200 m of an R = 100 m curve
        is metres off near the car, where the controller looks; 80 m (beyond the
        paper's 60 m preview) keeps the path exact near the car on any radius the
        road generator allows.
    """

    lookahead_time: float = setting(0.9, lo=0.0, hi=10.0)
    min_lookahead: float = setting(10.0, lo=1.0, hi=200.0)
    max_steering: float = setting(math.pi / 4, lo=0.0, hi=math.pi / 2)
    path_range: float | None = setting(80.0, lo=10.0, hi=1000.0, optional=True)

    def __post_init__(self) -> None:
        validate(self, "lka")


class LKAController:
    """Pure-pursuit lane keeping on a detected trajectory (sensor frame, ISO 8855).

    :param lookahead_time: look-ahead distance per unit speed [s].
    :param min_lookahead: smallest look-ahead distance [m].
    :param max_steering: steering saturation [rad].
    :param wheelbase: wheelbase of the bicycle model [m].
    :param sensor_x: x of the sensor ahead of the vehicle centre [m]; trajectories are
        given in the sensor frame.
    :param speed_gain: proportional gain of :meth:`predict`'s speed control [1/s].
    :param target_speed: speed :meth:`predict` holds [m/s]; ``None`` keeps the current one.

    Example (continuous action mode)::

        env = gym.make("ALDMHighway-v0", config={"action": {"type": "ContinuousAction"}})
        lka = LKAController()
        obs, _ = env.reset(seed=0)
        action, _ = lka.predict(obs)
    """

    def __init__(
        self,
        lookahead_time: float = LKAConfig.lookahead_time,
        min_lookahead: float = LKAConfig.min_lookahead,
        max_steering: float = LKAConfig.max_steering,
        wheelbase: float = WHEELBASE,
        sensor_x: float = LineSensorConfig.mount_x,
        speed_gain: float = 1.0 / 0.6,
        target_speed: float | None = None,
    ) -> None:
        for name, value, lo in (
            ("lookahead_time", lookahead_time, 0.0),
            ("min_lookahead", min_lookahead, 1.0),
            ("max_steering", max_steering, 0.0),
            ("wheelbase", wheelbase, 0.1),
            ("speed_gain", speed_gain, 0.0),
        ):
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not ok or not math.isfinite(float(value)) or float(value) < lo:
                raise ConfigError(f"lka.{name} must be a finite number >= {lo}, got {value!r}")
        if max_steering > math.pi / 2:
            raise ConfigError(f"lka.max_steering must be <= pi/2, got {max_steering!r}")
        self.lookahead_time = float(lookahead_time)
        self.min_lookahead = float(min_lookahead)
        self.max_steering = float(max_steering)
        self.wheelbase = float(wheelbase)
        self.sensor_x = float(sensor_x)
        self.speed_gain = float(speed_gain)
        self.target_speed = target_speed

    def lookahead(self, speed: float) -> float:
        """Look-ahead distance from the rear axle [m] at ``speed`` [m/s]."""
        return max(self.min_lookahead, self.lookahead_time * abs(float(speed)))

    def steering(self, trajectory: FloatArray, speed: float) -> float | None:
        """Steering angle [rad] (ISO: > 0 turns left) to follow ``trajectory``.

        :param trajectory: ``(M, 2)`` path (x, y) in the sensor frame [m], x increasing.
        :param speed: vehicle speed [m/s].
        :return: the angle, or ``None`` when the trajectory has fewer than two points.
        """
        traj = np.asarray(trajectory, dtype=np.float64)
        if traj.ndim != 2 or traj.shape[0] < 2 or traj.shape[1] != 2:
            return None
        rear = self.sensor_x + 0.5 * self.wheelbase  # sensor x -> rear-axle x
        xr = traj[:, 0] + rear
        yr = traj[:, 1]
        ld = self.lookahead(speed)
        dist = np.hypot(xr, yr)
        ahead = np.flatnonzero(dist >= ld)
        if len(ahead) == 0:
            # Path shorter than the look-ahead: aim at its end.
            px, py = float(xr[-1]), float(yr[-1])
        elif ahead[0] == 0:
            px, py = float(xr[0]), float(yr[0])
        else:
            # Interpolate the point at distance ld between the bracketing samples.
            i = int(ahead[0])
            d0, d1 = float(dist[i - 1]), float(dist[i])
            t = (ld - d0) / (d1 - d0) if d1 > d0 else 1.0
            px = float(xr[i - 1] + t * (xr[i] - xr[i - 1]))
            py = float(yr[i - 1] + t * (yr[i] - yr[i - 1]))
        d2 = px * px + py * py
        if d2 <= 1e-9:
            return 0.0
        kappa = 2.0 * py / d2
        delta = math.atan(kappa * self.wheelbase)
        # np.clip's result for a scalar with non-NaN bounds, without its dispatch.
        return float(clip_scalar(delta, -self.max_steering, self.max_steering))

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Continuous action from an ``ALDMHighway-v0`` observation, SB3 style.

        Uses the observation's ``trajectory`` (13 × (x, y), sensor frame) and
        ``trajectory_valid``, and the ego speed (``ego[0]``). Works on a single
        observation or a batch (leading dimension) as SB3's ``predict`` does.

        :return: ``(action, state)``: ``action = [steering [rad], acceleration [m/s²]]``
            as float32 (batched if the observation was), ``state`` unchanged.
        """
        traj = np.asarray(observation["trajectory"], dtype=np.float64)
        valid = np.asarray(observation["trajectory_valid"], dtype=np.float64)
        ego = np.asarray(observation["ego"], dtype=np.float64)
        if traj.ndim == 3:
            acts = [
                self._act(traj[i], bool(valid[i].reshape(-1)[0] > 0.5), float(ego[i][0]))
                for i in range(traj.shape[0])
            ]
            return np.stack(acts).astype(np.float32), state
        return self._act(traj, bool(valid.reshape(-1)[0] > 0.5), float(ego[0])), state

    def _act(self, traj: FloatArray, valid: bool, speed: float) -> np.ndarray:
        steer = self.steering(traj, speed) if valid else None
        target = speed if self.target_speed is None else self.target_speed
        accel = self.speed_gain * (target - speed)
        return np.array([0.0 if steer is None else steer, accel], dtype=np.float32)
