"""The observation of ``ALDMHighway-v0``: detected lines, ego state, traffic by detected lane.

Everything is in the ego's line-sensor frame (ISO 8855: x forward, y left) [m], so an
agent sees the road only as the detector delivers it. Nearby vehicles are assigned to
the ego / left / right lane by evaluating the *detected* lines at the vehicle's x
(the paper's motivation: is the vehicle ahead in my lane?).

=====================  ===========  ==========================================================
key                    shape        content
=====================  ===========  ==========================================================
``lines``              (4, 13, 2)   x, y [m] of the 4 lines (left_adjacent, ego_left, ego_right,
                                    right_adjacent), 13 points equally spaced in x; 0 if missing
``line_valid``         (4,)         1.0 where the line was detected, else 0.0
``line_confidence``    (4,)         only with ``line_confidence=True``: the detector's
                                    confidence in each line, in [0, 1], 0 where the line
                                    is missing (:func:`detected_confidence`)
``trajectory``         (13, 2)      desired path (midway between the ego lines) x, y [m]
``trajectory_valid``   (1,)         1.0 if a trajectory exists
``ego``                (4,)         speed [m/s], yaw rate [rad/s] (> 0 left), steering [rad]
                                    (> 0 left), lane change under way (+1 left, -1 right, 0)
``vehicles``           (N, 6)       per nearby vehicle (nearest first): present (0/1), x, y [m],
                                    relative vx, vy [m/s] (sensor frame), lane code
                                    (1 ego, 2 left, 3 right, 0 other/unknown)
``lanes``              (3, 4)       per detected lane (left, ego, right): gap to the nearest
                                    vehicle ahead [m], its relative vx [m/s], gap to the
                                    nearest vehicle behind [m], its relative vx [m/s]
``target``             (3,)         the ACC's target (:mod:`aldm_gym.envs.targets`): present
                                    (0/1), bumper-to-bumper gap [m], relative speed [m/s]
=====================  ===========  ==========================================================

``lanes`` summarises every vehicle within ``perception_distance`` (not only the N
nearest) by the same lane codes: a gap is bumper to bumper along x, measured from the
ego's centre (the sensor sits ``mount_x`` ahead of it), ``|x - x_ego|`` less half of
both vehicles' lengths (``VEHICLE_LENGTH`` between two cars), clipped to
``[0, perception_distance]``; an empty lane (or a lane not detected) reads
``perception_distance`` with relative speed 0. It is what an object-to-lane assignment
of a highway chauffeur hands to its decision layer, and what a learning agent needs
most: "is my lane blocked, is the next one free".

``line_confidence`` is opt-in (``ObservationConfig.line_confidence``): without it the
space is the one models were trained on before it existed. The lane-model filter
(``detector_params={"tracking": "model"}``) gives each drawn line its existence
confidence (:class:`~aldm_gym.sensor.lane_filter.ModelLaneDetection`); every other
detector (single-frame ALDM, the point tracker, naive, ground truth) has none, and the
key equals ``line_valid`` there: 1 where a line was detected, 0 otherwise. So the space
depends on the setting alone, never on the detector.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from aldm_gym.config import setting, validate
from aldm_gym.envs.traffic.vehicles import velocity
from aldm_gym.errors import InputError
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection, resample_line
from aldm_gym.types import FloatArray

if TYPE_CHECKING:
    from aldm_gym.envs.highway import ALDMHighwayEnv

N_POINTS = 13
"""Points per line in the observation (paper: 13 equally distributed points)."""

LINE_BOUND = 250.0
"""Bound of line / trajectory coordinates [m] (the sensor sees 200 m)."""

SPEED_BOUND = 80.0
"""Bound of speeds and relative speeds [m/s]."""

TARGET_GAP_BOUND = 250.0
"""Bound of the ``target`` gap [m] (``acc.range`` is at most 250 m); no target reads
``acc.range`` (the ACC sees nothing nearer)."""


class LaneCode(IntEnum):
    """Lane of a vehicle per the *detected* lines (the ``vehicles`` observation's last column)."""

    OTHER = 0  # beyond the detected lanes, or the lines are not detected
    EGO = 1
    LEFT = 2
    RIGHT = 3


LANE_ROWS = (LaneCode.LEFT, LaneCode.EGO, LaneCode.RIGHT)
"""Lane code of each row of the ``lanes`` observation."""

_ROW_OF_CODE = {float(code): row for row, code in enumerate(LANE_ROWS)}
"""Row of the ``lanes`` observation of a lane code (as the float codes hold it)."""

VEHICLE_LENGTH = 5.0
"""highway-env's vehicle length [m], subtracted from centre distances to give gaps."""


@dataclass(frozen=True)
class ObservationConfig:
    """The env's ``observation`` section.

    :ivar type: ``"ALDMObservation"`` (the only one: the Dict of the module table).
    :ivar vehicles_count: rows N of the ``vehicles`` key (nearest vehicles first).
    :ivar perception_distance: vehicles farther than this along x or y are not
        observed; also the bound of gaps [m].
    :ivar line_confidence: add the ``line_confidence`` key (see the module docstring);
        off by default, which keeps the space of earlier versions and of the models
        trained on it.
    """

    type: str = setting("ALDMObservation", choices=("ALDMObservation",))
    vehicles_count: int = setting(8, lo=1, hi=64, integer=True)
    perception_distance: float = setting(100.0, lo=1.0, hi=250.0)
    line_confidence: bool = setting(False)

    def __post_init__(self) -> None:
        validate(self, "observation")


def observation_space(
    vehicles_count: int, perception_distance: float, line_confidence: bool = False
) -> spaces.Dict:
    """The observation space (a Dict of bounded float32 Boxes, see the module table).

    :param line_confidence: with the ``line_confidence`` key.
    """
    f32 = np.float32
    veh_low = np.tile(
        np.array(
            [0.0, -perception_distance, -perception_distance, -SPEED_BOUND, -SPEED_BOUND, 0.0],
            dtype=f32,
        ),
        (vehicles_count, 1),
    )
    veh_high = np.tile(
        np.array(
            [1.0, perception_distance, perception_distance, SPEED_BOUND, SPEED_BOUND, 3.0],
            dtype=f32,
        ),
        (vehicles_count, 1),
    )
    space = spaces.Dict(
        {
            "lines": spaces.Box(-LINE_BOUND, LINE_BOUND, (4, N_POINTS, 2), f32),
            "line_valid": spaces.Box(0.0, 1.0, (4,), f32),
            "trajectory": spaces.Box(-LINE_BOUND, LINE_BOUND, (N_POINTS, 2), f32),
            "trajectory_valid": spaces.Box(0.0, 1.0, (1,), f32),
            "ego": spaces.Box(
                np.array([-SPEED_BOUND, -math.pi, -math.pi / 2, -1.0], dtype=f32),
                np.array([SPEED_BOUND, math.pi, math.pi / 2, 1.0], dtype=f32),
                (4,),
                f32,
            ),
            "vehicles": spaces.Box(veh_low, veh_high, (vehicles_count, 6), f32),
            "lanes": spaces.Box(
                np.tile(np.array([0.0, -SPEED_BOUND] * 2, dtype=f32), (3, 1)),
                np.tile(np.array([perception_distance, SPEED_BOUND] * 2, dtype=f32), (3, 1)),
                (3, 4),
                f32,
            ),
            "target": spaces.Box(
                np.array([0.0, 0.0, -SPEED_BOUND], dtype=f32),
                np.array([1.0, TARGET_GAP_BOUND, SPEED_BOUND], dtype=f32),
                (3,),
                f32,
            ),
        }
    )
    if line_confidence:
        space = spaces.Dict({**space.spaces, "line_confidence": spaces.Box(0.0, 1.0, (4,), f32)})
    return space


def eval_line(line: FloatArray, x: FloatArray) -> FloatArray:
    """y [m] of a line at ``x`` [m]: linear interpolation, linear extrapolation beyond its ends.

    :param line: ``(K >= 2, 2)`` points sorted by x.
    :param x: ``(N,)`` positions.
    """
    xs, ys = line[:, 0], line[:, 1]
    y = np.interp(x, xs, ys)
    if xs[1] > xs[0]:
        s0 = (ys[1] - ys[0]) / (xs[1] - xs[0])
        y = np.where(x < xs[0], ys[0] + s0 * (x - xs[0]), y)
    if xs[-1] > xs[-2]:
        s1 = (ys[-1] - ys[-2]) / (xs[-1] - xs[-2])
        y = np.where(x > xs[-1], ys[-1] + s1 * (x - xs[-1]), y)
    return y


def assign_lanes(
    detection_lines: dict[str, FloatArray], x: FloatArray, y: FloatArray
) -> FloatArray:
    """Lane code of points ``(x, y)`` [m] from the detected lines (see the lane codes).

    A point between the ego lines is in the ego lane; between ``ego_left`` and
    ``left_adjacent`` in the left lane; likewise on the right. Without both ego lines
    every point is ``LaneCode.OTHER`` (unknown).

    :param detection_lines: line name -> ``(K, 2)`` points (empty when missing).
    :return: ``(N,)`` float codes.
    """
    codes = np.full(len(x), float(LaneCode.OTHER))
    el, er = detection_lines["ego_left"], detection_lines["ego_right"]
    if len(el) < 2 or len(er) < 2 or len(x) == 0:
        return codes
    yl, yr = eval_line(el, x), eval_line(er, x)
    codes[(y < yl) & (y > yr)] = LaneCode.EGO
    la, ra = detection_lines["left_adjacent"], detection_lines["right_adjacent"]
    if len(la) >= 2:
        codes[(y >= yl) & (y < eval_line(la, x))] = LaneCode.LEFT
    if len(ra) >= 2:
        codes[(y <= yr) & (y > eval_line(ra, x))] = LaneCode.RIGHT
    return codes


def lane_gaps(
    codes: FloatArray,
    x: FloatArray,
    vx: FloatArray,
    perception_distance: float,
    lengths: FloatArray | None = None,
) -> FloatArray:
    """The ``lanes`` observation: per lane of :data:`LANE_ROWS`, nearest vehicle ahead and behind.

    :param codes: ``(N,)`` lane codes of the vehicles (see :func:`assign_lanes`).
    :param x: ``(N,)`` longitudinal positions relative to the ego's centre, along the
        sensor's x axis [m].
    :param vx: ``(N,)`` longitudinal speeds relative to the ego [m/s].
    :param lengths: ``(N,)`` vehicle lengths [m] (``None``: all
        :data:`VEHICLE_LENGTH`, as is the ego).
    :return: ``(3, 4)``: front gap [m], front relative vx [m/s], rear gap [m], rear
        relative vx [m/s]; gaps ``perception_distance`` and speeds 0 where no vehicle.
    :raises InputError: arrays of different shapes, or non-finite x / vx.
    """
    codes, x, vx = (np.asarray(a, dtype=np.float64) for a in (codes, x, vx))
    if not (codes.ndim == 1 and codes.shape == x.shape == vx.shape):
        raise InputError(
            f"codes, x and vx must be 1-D of one length, got {codes.shape}, {x.shape}, {vx.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(vx))):
        raise InputError("x and vx must be finite")
    # Centre to bumper: half of each length (5.0 exactly between two cars).
    if lengths is None:
        reach = np.full(x.shape, VEHICLE_LENGTH)
    else:
        lengths = np.asarray(lengths, dtype=np.float64)
        if lengths.shape != x.shape or not np.all(np.isfinite(lengths)):
            raise InputError(f"lengths must be finite of shape {x.shape}, got {lengths.shape}")
        reach = 0.5 * (lengths + VEHICLE_LENGTH)
    pd = perception_distance
    out = np.tile(np.array([pd, 0.0, pd, 0.0]), (3, 1))
    # The nearest vehicle ahead (smallest x >= 0) and behind (largest x < 0) per lane,
    # the first one on ties; one pass over a handful of vehicles, in plain floats.
    xs = x.tolist()
    ahead = [-1, -1, -1]
    behind = [-1, -1, -1]
    for i, (code, xi) in enumerate(zip(codes.tolist(), xs, strict=True)):
        row = _ROW_OF_CODE.get(code)
        if row is None:
            continue
        if xi >= 0.0:
            j = ahead[row]
            if j < 0 or xi < xs[j]:
                ahead[row] = i
        else:
            j = behind[row]
            if j < 0 or xi > xs[j]:
                behind[row] = i
    gaps = reach.tolist()
    speeds = vx.tolist()
    for row in range(3):
        i = ahead[row]
        if i >= 0:
            out[row, 0] = min(max(xs[i] - gaps[i], 0.0), pd)
            out[row, 1] = speeds[i]
        i = behind[row]
        if i >= 0:
            out[row, 2] = min(max(-xs[i] - gaps[i], 0.0), pd)
            out[row, 3] = speeds[i]
    return out


def detected_confidence(detection: LaneDetection | None, valid: FloatArray) -> FloatArray:
    """The ``line_confidence`` key: the detection's confidence in each line, in [0, 1].

    A detection with a per-line ``confidence`` (the lane-model filter's
    :class:`~aldm_gym.sensor.lane_filter.ModelLaneDetection`) gives it where the line
    is valid and 0 elsewhere, so the key is never above ``line_valid``; a detection
    without one (every other detector) gives ``valid`` itself.

    :param valid: ``(4,)`` the ``line_valid`` key (1 where the line was detected).
    :return: ``(4,)`` in :data:`~aldm_gym.sensor.lane_detection.LINE_NAMES` order.
    """
    confidence = getattr(detection, "confidence", None)
    if confidence is None:
        return np.array(valid, dtype=np.float64)
    return np.where(np.asarray(valid) > 0.0, np.clip(confidence, 0.0, 1.0), 0.0)


def build_observation(
    detection: LaneDetection | None,
    trajectory: FloatArray,
    ego_state: FloatArray,
    others: FloatArray,
    vehicles_count: int,
    perception_distance: float,
    ego_x: float = 0.0,
    target: FloatArray | None = None,
    lengths: FloatArray | None = None,
    line_confidence: bool = False,
) -> dict[str, np.ndarray]:
    """Assemble the observation dict.

    :param detection: the latest detection (``None`` gives empty lines).
    :param trajectory: ``(M, 2)`` desired path the controller follows [m] (may be empty).
    :param ego_state: ``(4,)`` speed, yaw rate, steering, lane-change direction.
    :param others: ``(M, 4)`` x, y, vx, vy of other vehicles in the sensor frame
        (velocities relative to the ego) [m, m/s].
    :param ego_x: x of the ego's centre in the sensor frame [m] (``-mount_x``); the
        ``lanes`` gaps are measured from it.
    :param target: ``(3,)`` the ACC's target: present (0/1), gap [m], relative speed
        [m/s]; ``None``: none, gap :data:`TARGET_GAP_BOUND`.
    :param lengths: ``(M,)`` lengths of the other vehicles [m] (``None``: all cars).
    :param line_confidence: add the ``line_confidence`` key (:func:`detected_confidence`).
    """
    lines = np.zeros((4, N_POINTS, 2))
    valid = np.zeros(4)
    traj = np.zeros((N_POINTS, 2))
    traj_valid = np.zeros(1)
    full: dict[str, FloatArray] = {name: np.zeros((0, 2)) for name in LINE_NAMES}
    if detection is not None:
        for i, name in enumerate(LINE_NAMES):
            line = detection.line(name)
            full[name] = line
            r = resample_line(line, N_POINTS) if len(line) != N_POINTS else line
            if len(r):
                lines[i] = r
                valid[i] = 1.0
    t = resample_line(trajectory, N_POINTS) if len(trajectory) >= 2 else trajectory
    if len(t):
        traj = t
        traj_valid[0] = 1.0
    veh = np.zeros((vehicles_count, 6))
    if len(others) == 0:
        lanes = lane_gaps(np.zeros(0), np.zeros(0), np.zeros(0), perception_distance)
    else:
        dist = np.hypot(others[:, 0], others[:, 1])
        near = np.flatnonzero(dist <= perception_distance)
        near = near[np.argsort(dist[near], kind="stable")]
        seen = others[near]
        codes = assign_lanes(full, seen[:, 0], seen[:, 1])
        lanes = lane_gaps(
            codes,
            seen[:, 0] - ego_x,
            seen[:, 2],
            perception_distance,
            None if lengths is None else np.asarray(lengths, dtype=np.float64)[near],
        )
        k = min(len(seen), vehicles_count)
        veh[:k, 0] = 1.0
        veh[:k, 1:5] = seen[:k]
        veh[:k, 5] = codes[:k]
    pd = perception_distance
    veh[:, 1:3] = np.clip(veh[:, 1:3], -pd, pd)
    veh[:, 3:5] = np.clip(veh[:, 3:5], -SPEED_BOUND, SPEED_BOUND)
    ego = np.clip(
        ego_state,
        [-SPEED_BOUND, -math.pi, -math.pi / 2, -1.0],
        [SPEED_BOUND, math.pi, math.pi / 2, 1.0],
    )
    out: dict[str, Any] = {
        "lines": np.clip(lines, -LINE_BOUND, LINE_BOUND).astype(np.float32),
        "line_valid": valid.astype(np.float32),
        "trajectory": np.clip(traj, -LINE_BOUND, LINE_BOUND).astype(np.float32),
        "trajectory_valid": traj_valid.astype(np.float32),
        "ego": ego.astype(np.float32),
        "vehicles": veh.astype(np.float32),
        "lanes": np.clip(lanes, [0.0, -SPEED_BOUND] * 2, [pd, SPEED_BOUND] * 2).astype(np.float32),
        "target": np.clip(
            np.array([0.0, TARGET_GAP_BOUND, 0.0]) if target is None else target,
            [0.0, 0.0, -SPEED_BOUND],
            [1.0, TARGET_GAP_BOUND, SPEED_BOUND],
        ).astype(np.float32),
    }
    if line_confidence:
        out["line_confidence"] = detected_confidence(detection, valid).astype(np.float32)
    return out


def sensor_to_world(points: FloatArray, origin: FloatArray, yaw: float) -> FloatArray:
    """Sensor-frame points ``(N, 2)`` (x forward, y left) to world ``(N, 2)`` [m]: the
    inverse of :func:`to_sensor_frame`'s positions.

    The driver's left in highway-env's world is ``(sin h, -cos h)`` (see
    :mod:`aldm_gym.roads.reference_line`).
    """
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = points[:, 0], points[:, 1]
    return np.column_stack([origin[0] + x * c + y * s, origin[1] + x * s - y * c])


def to_sensor_frame(
    positions: FloatArray, velocities: FloatArray, origin: FloatArray, yaw: float
) -> FloatArray:
    """World positions and velocities as sensor-frame ``(x, y, vx, vy)`` rows.

    :param positions: ``(N, 2)`` world positions [m].
    :param velocities: ``(N, 2)`` world velocities relative to the ego [m/s].
    :param origin: the sensor's world position [m].
    :param yaw: the sensor's world heading [rad] (highway-env's convention: the
        driver's left is ``(sin yaw, -cos yaw)``, see :mod:`aldm_gym.roads.reference_line`).
    :return: ``(N, 4)``: x forward, y left [m], vx, vy [m/s] (ISO 8855).
    """
    cy, sy = math.cos(yaw), math.sin(yaw)
    pos = positions - origin
    vel = velocities
    return np.column_stack(
        [
            pos[:, 0] * cy + pos[:, 1] * sy,
            pos[:, 0] * sy - pos[:, 1] * cy,
            vel[:, 0] * cy + vel[:, 1] * sy,
            vel[:, 0] * sy - vel[:, 1] * cy,
        ]
    )


class ALDMObservation:
    """highway-env's ``ObservationType`` of the env: the space and the observation.

    It reads the env's current sensor frame, detection and ego vehicle, transforms
    the other vehicles into the sensor frame (:func:`to_sensor_frame`) and builds the
    Dict of the module table (:func:`build_observation`).
    """

    def __init__(self, env: ALDMHighwayEnv) -> None:
        self.env = env
        self.config: ObservationConfig = env.settings.observation
        self.observer_vehicle = env.vehicle

    def space(self) -> spaces.Space:
        """See :func:`observation_space`."""
        config = self.config
        return observation_space(
            config.vehicles_count, config.perception_distance, config.line_confidence
        )

    def observe(self) -> dict[str, np.ndarray]:
        """The observation of the env's current state."""
        env = self.env
        ego = env.vehicle
        frame = env.frame
        if frame is None:
            raise RuntimeError("observe() before the env measured a sensor frame (call reset)")
        others = [v for v in env.road.vehicles if v is not ego]
        if others:
            rel = to_sensor_frame(
                np.array([v.position for v in others], dtype=np.float64),
                np.array([velocity(v) for v in others], dtype=np.float64) - ego.velocity,
                frame.origin,
                frame.yaw,
            )
        else:
            rel = np.zeros((0, 4))
        ego_state = np.array([ego.speed, ego.yaw_rate, ego.steering_iso, float(ego.lane_change)])
        ego_x = float(
            to_sensor_frame(ego.position[None, :], np.zeros((1, 2)), frame.origin, frame.yaw)[0, 0]
        )
        return build_observation(
            env.detection,
            ego.trajectory,
            ego_state,
            rel,
            self.config.vehicles_count,
            float(self.config.perception_distance),
            ego_x,
            self._target(),
            np.array([v.LENGTH for v in others], dtype=np.float64) if others else None,
            self.config.line_confidence,
        )

    def _target(self) -> FloatArray | None:
        """``(present, gap, relative speed)`` of the ACC's target; ``None`` without ACC."""
        cmd, ctrl = self.env.acc_command, self.env.longitudinal
        if cmd is None or ctrl is None:
            return None
        if cmd.target < 0:
            return np.array([0.0, ctrl.config.range, 0.0])
        return np.array([1.0, max(cmd.gap, 0.0), cmd.relative_speed])
