"""The vehicles of ``ALDMHighway-v0``: the ego, steered only from the detected lanes,
and the traffic of a map (:class:`MapIDMVehicle`, IDM/MOBIL with a mandatory merge).

:class:`SensorVehicle` is highway-env's kinematic bicycle whose lateral control (the
:class:`~aldm_gym.envs.control.LKAController`) sees nothing but the detection the
environment hands it after every simulation step, plus the lane-change state machine
of the meta actions (:class:`~aldm_gym.envs.actions.MetaAction`): a change steers onto
the *detected* adjacent lane, is refused when that lane is not detected, tracks its
target lane by continuity while the lines are relabelled under the car, and ends when
the ego is centred in the new lane or the timeout elapses.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from highway_env import utils
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.envs.actions import ActionConfig, MetaAction
from aldm_gym.envs.control import LKAConfig, LKAController
from aldm_gym.envs.lane_end import opening_path
from aldm_gym.envs.observation import sensor_to_world, to_sensor_frame
from aldm_gym.envs.traffic import BatchedLaneUpdate, FastBicycleStep, FastIDMVehicle, clip_scalar
from aldm_gym.roads.highway import RoadConfig
from aldm_gym.roads.markings import MarkingType
from aldm_gym.sensor.lane_detection import LaneDetection, driving_trajectory, paint_types
from aldm_gym.types import FloatArray

BROKEN = (int(MarkingType.DASHED), int(MarkingType.DOTTED))
"""The line types a lane change may cross."""

_ACTION = ActionConfig()


MIN_TARGET_PATH = 2
"""A lane change needs a target path of at least this many points (the detected
adjacent lane's centre)."""

MRM_DECELERATION = 3.0
"""Deceleration [m/s²] of the minimal-risk manoeuvre of the built-in lane keeping: once
the detection has had no path for longer than the last path reached, the car holds
its steering and brakes at this rate to a stop (UN R157 asks an MRM to decelerate in
the lane at no more than 4 m/s²)."""


class SensorVehicle(FastBicycleStep, BatchedLaneUpdate, Vehicle):
    """The ego vehicle: laterally controlled only from the detected lanes.

    highway-env's kinematic bicycle (``Vehicle``) with its ``lane_index``
    bookkeeping (traffic needs it), but :meth:`act` steers with the
    :class:`~aldm_gym.envs.control.LKAController` on ``self.detection`` (set by the
    environment after every simulation step), never on the true lane.

    The speed: ``acc_command`` (the ACC/AEB of :mod:`aldm_gym.envs.longitudinal`, set by
    the environment after every simulation step on the same detection) under meta
    actions, or v0's proportional control towards ``target_speed`` when it is ``None``.

    Meta actions: IDLE follows the detected trajectory; LANE_LEFT/RIGHT steer onto
    the centre of the detected adjacent lane (midway between the ego line and the
    adjacent line, cubic fits as for the trajectory) and are refused when that
    adjacent line is not detected, the lane closes ahead, or the ego line is not seen
    on broken paint (:meth:`lane_change_available`); FASTER/SLOWER step through
    ``target_speeds``.
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
        target_speeds: tuple[float, ...] = tuple(_ACTION.target_speeds),
        continuous: bool = False,
        lane_change_timeout: float = _ACTION.lane_change_timeout,
        cross_solid_lines: bool = _ACTION.cross_solid_lines,
        max_acceleration: float = _ACTION.max_acceleration,
        lane_width: float = RoadConfig.lane_width,
        path_range: float | None = LKAConfig.path_range,
    ) -> None:
        super().__init__(road, position, heading, speed)
        self.lka = lka or LKAController()
        self.target_speeds = np.asarray(target_speeds, dtype=np.float64)
        self.speed_index = int(np.argmin(np.abs(self.target_speeds - speed)))
        self.target_speed = float(self.target_speeds[self.speed_index])
        self.continuous = continuous
        self.lane_change_timeout = lane_change_timeout
        self.cross_solid_lines = cross_solid_lines
        self.frame: Any = None
        """The sensor frame of :attr:`detection` (set by the env with it)."""
        # paint_types of (detection, frame), per side of the lines (far_side)
        self._paint: dict[bool, tuple[Any, Any, dict[str, int]]] = {}
        self.return_permit = 0
        """The direction (+1 left, -1 right, 0 none) of a change back across the double
        line the last lane change crossed from its broken side; set when a change
        starts."""
        self.max_acceleration = max_acceleration
        self.lane_width = lane_width
        self.detection: LaneDetection | None = None
        self.trajectory: FloatArray = np.zeros((0, 2))  # the detection's (set by the env)
        self.path_range = path_range
        self.command = np.zeros(2)  # continuous mode: (steering ISO [rad], acceleration)
        self.steering_iso = 0.0
        self.lane_change = 0  # +1 left, -1 right, 0 none
        self.lane_change_elapsed = 0.0
        self.lane_change_target_y = 0.0
        self.lane_change_refused = False
        self.lane_changes_completed = 0
        self.lane_changes_aborted = 0  # lost the target lane or timed out
        self.planned_path: FloatArray = np.zeros((0, 2))
        self.lane_change_side = 0  # +1/-1: the target is still the adjacent lane on that side
        self.acc_command: float | None = None  # ACC/AEB [m/s²] (set by the env), None: v0's
        self.acc_braking_limit = max_acceleration  # braking the ACC/AEB command may reach
        self.requested_steering: float | None = None
        """A function under test's steering [rad] (ISO), None: the built-in LKA's."""
        self.requested_acceleration: float | None = None
        """A function under test's acceleration [m/s²], None: the built-in ACC/AEB's."""
        self.opening_factor = 0.0
        """A detected lane wider than this many lane widths is opening: the LKA keeps a
        lane's width from the staying line (``lane_end.opening_factor``, set by the env;
        0: the middle)."""
        self.sensor_pose: tuple[FloatArray, float] | None = None
        """The world pose of the sensor frame of ``detection`` and ``trajectory``:
        origin [m] and yaw [rad] (set by the environment with them)."""
        self.carried: tuple[FloatArray, FloatArray, float] | None = None
        """The last path the LKA followed and the sensor pose it was seen from (path
        [m], origin [m], yaw [rad]): without a path in the detection it is followed on
        (dead reckoning), see :meth:`act`."""
        self.blind = False
        """Whether the last step had no path of the detection to follow."""
        self.minimal_risk = False
        """Whether the car brakes in a minimal-risk manoeuvre: no path, and the carried
        one run out (:data:`MRM_DECELERATION`)."""

    # ------------------------------------------------------------------ actions
    def set_meta_action(self, action: int) -> None:
        """Apply a ``DiscreteMetaAction`` index (see the env docstring)."""
        self.lane_change_refused = False
        if action == MetaAction.FASTER:
            self.speed_index = min(self.speed_index + 1, len(self.target_speeds) - 1)
        elif action == MetaAction.SLOWER:
            self.speed_index = max(self.speed_index - 1, 0)
        elif action in (MetaAction.LANE_LEFT, MetaAction.LANE_RIGHT) and self.lane_change == 0:
            direction = 1 if action == MetaAction.LANE_LEFT else -1
            self.lane_change_refused = not self.start_lane_change(direction)
        self.target_speed = float(self.target_speeds[self.speed_index])

    def start_lane_change(self, direction: int, forced: bool = False) -> bool:
        """Start a lane change to the left (+1) or right (-1) if the adjacent lane on that
        side is detected and its ego line may be crossed (:meth:`lane_change_available`'s
        rule, ``forced`` as there); whether it started. The meta actions' and the
        chauffeur's own (a lane that ends, ``forced``) way in."""
        path = self._target_path(direction, forced)
        if path is None:
            return False
        name = "ego_left" if direction > 0 else "ego_right"
        # crossing a double line from its broken side: the way back is open (until the
        # next change starts)
        double = self.paint.get(name, 0) in BROKEN and (
            self.far_paint.get(name, 0) == MarkingType.CONTINUOUS
        )
        self.return_permit = -direction if double else 0
        self.lane_change = direction
        self.lane_change_side = direction
        self.lane_change_elapsed = 0.0
        self.lane_change_target_y = float(path[0, 1])
        return True

    def lane_change_available(self, direction: int, forced: bool = False) -> bool:
        """Whether a lane change to the left (+1) or right (-1) would start now: none is
        under way (the action is ignored then), the adjacent lane on that side is
        detected and no narrower than the car (:meth:`_target_wide`), and the ego line on
        that side may be crossed (:meth:`_may_cross`; ``forced``: the chauffeur leaving a
        lane that ends, refused only by paint seen continuous): else it is refused, the
        rule :meth:`set_meta_action` applies."""
        return self._target_path(direction, forced) is not None

    def _target_path(self, direction: int, forced: bool) -> FloatArray | None:
        """The path of the lane change :meth:`lane_change_available` allows (its
        target lane's centre), None when it is refused."""
        if self.lane_change != 0 or not self._may_cross(direction, forced):
            return None
        path = self._adjacent_path(direction)
        if len(path) < MIN_TARGET_PATH or not self._target_wide(direction):
            return None
        return path

    def _target_wide(self, direction: int) -> bool:
        """Whether the detected adjacent lane on that side is at least as wide as the car
        (``WIDTH`` [m]) wherever both its lines are detected, up to the path range (its
        lines' y apart at equal x): not a lane that closes ahead (a taper), where the car
        would arrive as it ends."""
        det = self.detection
        if det is None:
            return False
        if direction > 0:
            outer, inner = det.left_adjacent, det.ego_left
        else:
            outer, inner = det.right_adjacent, det.ego_right
        if len(outer) < 2 or len(inner) < 2:
            return False
        reach = math.inf if self.path_range is None else float(self.path_range)
        lo = max(float(outer[0, 0]), float(inner[0, 0]))
        hi = min(float(outer[-1, 0]), float(inner[-1, 0]), reach)
        if hi < lo:
            return True  # no x where both are seen within reach: nothing says it closes
        xs = np.linspace(lo, hi, 17)
        width = np.abs(
            np.interp(xs, outer[:, 0], outer[:, 1]) - np.interp(xs, inner[:, 0], inner[:, 1])
        )
        return bool(width.min() >= self.WIDTH)

    def _paint_of(self, far_side: bool) -> dict[str, int]:
        """:func:`~aldm_gym.sensor.lane_detection.paint_types` of :attr:`frame` for the
        ego lines, once per detection and frame."""
        det, frame = self.detection, self.frame
        if det is None or frame is None:
            return {}
        cached = self._paint.get(far_side)
        if cached is None or cached[0] is not det or cached[1] is not frame:
            cached = self._paint[far_side] = (
                det,
                frame,
                paint_types(frame, det, far_side=far_side),
            )
        return cached[2]

    @property
    def paint(self) -> dict[str, int]:
        """The type of paint under each detected ego line
        (:func:`~aldm_gym.sensor.lane_detection.paint_types` of :attr:`frame`; read
        when a lane change asks). Without a frame (a detection set by hand) it is empty,
        and every lane change but a forced one is refused."""
        return self._paint_of(False)

    @property
    def far_paint(self) -> dict[str, int]:
        """:attr:`paint` as read from the far side of each ego line (the stripe of a
        double line on the lane beside)."""
        return self._paint_of(True)

    def _may_cross(self, direction: int, forced: bool = False) -> bool:
        """Whether the ego line on that side may be crossed: the sensor reports it
        broken (:attr:`paint`: dashed or dotted; a double line by its stripe on the
        car's side), not continuous nor unseen (a line the detector only carries
        gives no leave to cross it); or the car changes back across a double line it
        crossed from its broken side (:attr:`return_permit`: a driver who overtook
        resumes their lane); or, ``forced`` (leaving a lane that ends), it is not
        seen continuous; or ``cross_solid_lines``."""
        name = "ego_left" if direction > 0 else "ego_right"
        paint = self.paint.get(name, 0)
        if self.cross_solid_lines or paint in BROKEN or (forced and paint == 0):
            return True
        return direction == self.return_permit and self.far_paint.get(name, 0) in BROKEN

    def _adjacent_path(self, direction: int) -> FloatArray:
        """Centre path of the detected adjacent lane (+1 left, -1 right), or empty."""
        det = self.detection
        if det is None:
            return np.zeros((0, 2))
        if direction > 0:
            if not (det.found("left_adjacent") and det.found("ego_left")):
                return np.zeros((0, 2))
            return driving_trajectory(
                det.left_adjacent, det.ego_left, self.lane_width, path_range=self.path_range
            )
        if not (det.found("right_adjacent") and det.found("ego_right")):
            return np.zeros((0, 2))
        return driving_trajectory(
            det.ego_right, det.right_adjacent, self.lane_width, path_range=self.path_range
        )

    def _lateral_path(self) -> FloatArray:
        """The path to follow now: the ego trajectory, or the lane-change target's centre."""
        det = self.detection
        if det is None:
            return np.zeros((0, 2))
        if self.lane_change == 0:
            if self.opening_factor > 0.0:
                return opening_path(self.trajectory, det, self.lane_width, self.opening_factor)
            return self.trajectory
        self.lane_change_elapsed += 1.0 / self.sim_frequency
        # The detected lines are relabelled while the ego crosses the marking, so the
        # target lane is tracked by continuity: the candidate centre whose offset at
        # the sensor is nearest to where the target was at the previous step.
        cands = [(0, self.trajectory), (1, self._adjacent_path(1)), (-1, self._adjacent_path(-1))]
        cands = [(k, p) for k, p in cands if len(p) >= 2]
        if not cands:
            self.lane_change = self.lane_change_side = 0
            self.lane_changes_aborted += 1
            return np.zeros((0, 2))
        k, path = min(cands, key=lambda kp: abs(float(kp[1][0, 1]) - self.lane_change_target_y))
        jump = abs(float(path[0, 1]) - self.lane_change_target_y)
        timed_out = self.lane_change_elapsed > self.lane_change_timeout
        if jump > 0.5 * self.lane_width or timed_out:
            # Lost the target lane or took too long: keep the lane.
            self.lane_change = self.lane_change_side = 0
            self.lane_changes_aborted += 1
            return self.trajectory
        self.lane_change_target_y = float(path[0, 1])
        self.lane_change_side = k
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
            self.blind = len(path) < 2
            if not self.blind:
                if self.sensor_pose is not None:
                    self.carried = (path, *self.sensor_pose)
                self.minimal_risk = False
            if self.requested_steering is not None:  # a function under test's lateral domain
                steer_iso = self.requested_steering
                self.minimal_risk = False  # the function steers: not the LKA's manoeuvre
            else:
                steer = self.lka.steering(path, self.speed)
                if steer is None:
                    # No path: follow the last one on, carried by the car's own motion,
                    # until it runs out; then hold the steering (a curve continues) and
                    # the minimal-risk manoeuvre brakes to a stop.
                    ahead = self._carried_ahead()
                    # run out once it ends nearer than the look-ahead distance (from the
                    # sensor: a few metres before pure pursuit's, from the rear axle,
                    # would; there it would aim at the path's end, off its curve)
                    if len(ahead) and math.hypot(*ahead[-1]) >= self.lka.lookahead(self.speed):
                        steer = self.lka.steering(ahead, self.speed)
                    if steer is None and self.carried is not None:
                        self.minimal_risk = True  # until a path comes back
                steer_iso = self.steering_iso if steer is None else steer
            if self.requested_acceleration is not None:
                # a function under test's longitudinal domain; it never reverses the car
                accel = max(self.requested_acceleration, -max(self.speed, 0.0) * self.sim_frequency)
            elif self.acc_command is None:
                accel = self.lka.speed_gain * (self.target_speed - self.speed)
            else:
                # ACC/AEB (aldm_gym.envs.longitudinal), computed by the env on the same
                # detection; braking never reverses the car.
                accel = max(self.acc_command, -max(self.speed, 0.0) * self.sim_frequency)
            if self.minimal_risk and self.requested_acceleration is None:
                stop = -max(self.speed, 0.0) * self.sim_frequency
                accel = min(accel, max(-MRM_DECELERATION, stop))
        # np.clip's result for scalars with non-NaN bounds, without its ~4 µs dispatch.
        max_steering = float(self.lka.max_steering)
        max_acceleration = float(self.max_acceleration)
        max_braking = max_acceleration
        if not self.continuous and (
            self.acc_command is not None or self.requested_acceleration is not None
        ):
            max_braking = max(max_acceleration, float(self.acc_braking_limit))
        steer_iso = float(clip_scalar(float(steer_iso), -max_steering, max_steering))
        accel = float(clip_scalar(float(accel), -max_braking, max_acceleration))
        self.steering_iso = steer_iso
        # highway-env's world: a positive steering angle turns towards the driver's right.
        self.action = {"steering": -steer_iso, "acceleration": accel}

    def _carried_ahead(self) -> FloatArray:
        """The carried path (:attr:`carried`) in the current sensor frame, its points
        ahead of the sensor only [m] (empty without one)."""
        if self.carried is None or self.sensor_pose is None:
            return np.zeros((0, 2))
        path, origin, yaw = self.carried
        world = sensor_to_world(path, origin, yaw)
        now = to_sensor_frame(world, np.zeros_like(world), *self.sensor_pose)[:, :2]
        return now[now[:, 0] > 0.0]

    @property
    def yaw_rate(self) -> float:
        """Yaw rate [rad/s], ISO sign (> 0 turning left)."""
        beta = math.atan(0.5 * math.tan(float(self.action["steering"])))
        return -self.speed * math.sin(beta) / (0.5 * self.LENGTH)

    @property
    def path_curvature(self) -> float:
        """Curvature of the path driven now [1/m] (> 0 left): yaw rate / speed, 0 below
        0.1 m/s."""
        speed = float(self.speed)
        return self.yaw_rate / speed if abs(speed) > 0.1 else 0.0


MERGE_ZONE = 300.0
"""A map vehicle whose lane ends within this distance merges out (mandatory merge) [m]."""

MERGE_MAX_BRAKING = 4.0
"""Braking [m/s²] a mandatory merge may impose on the new follower (and on itself);
MOBIL's discretionary limit is ``LANE_CHANGE_MAX_BRAKING_IMPOSED`` (2 m/s²)."""


class MapIDMVehicle(FastIDMVehicle):
    """Traffic on an OpenDRIVE map: IDM/MOBIL plus a mandatory merge out of ending lanes.

    On a :class:`~aldm_gym.roads.map_network.MapNetwork` (elsewhere it is
    :class:`~aldm_gym.envs.traffic.FastIDMVehicle` unchanged):

    * a vehicle whose lane chain ends within :data:`MERGE_ZONE` merges into a side lane
      that reaches farther: every step (not every ``LANE_CHANGE_DELAY``), at any speed,
      without MOBIL's incentive test (politeness 0), as soon as neither it nor the new
      follower must brake harder than :data:`MERGE_MAX_BRAKING`;
    * until then it brakes for the lane's end as for a standing car (IDM), so that it
      stops at the end rather than driving off it (and never reverses);
    * discretionary MOBIL changes never enter a lane that ends within :data:`MERGE_ZONE`.
    """

    def _lane_left(self, lane_index: Any, at_least: float = math.inf) -> float:
        left = getattr(self.road.network, "lane_left", None)
        return math.inf if left is None else float(left(lane_index, self.position, at_least))

    def change_lane_policy(self) -> None:
        """MOBIL, or the mandatory merge near the end of the lane (class docstring)."""
        network = self.road.network
        if self.lane_index != self.target_lane_index or not hasattr(network, "lane_left"):
            super().change_lane_policy()
            return
        own = self._lane_left(self.lane_index, MERGE_ZONE)
        if own < MERGE_ZONE:
            for lane_index in network.side_lanes(self.lane_index):
                if self._lane_left(lane_index) <= own + 1.0:
                    continue  # ends as soon: no better
                if not network.get_lane(lane_index).is_reachable_from(self.position):
                    continue
                if self._merge_is_safe(lane_index):
                    self.target_lane_index = lane_index
                    return
            return
        if not utils.do_every(self.LANE_CHANGE_DELAY, self.timer):
            return
        self.timer = 0
        for lane_index in network.side_lanes(self.lane_index):
            if not network.get_lane(lane_index).is_reachable_from(self.position):
                continue
            if abs(self.speed) < 1 or self._lane_left(lane_index, MERGE_ZONE) < MERGE_ZONE:
                continue
            if self.mobil(lane_index):
                self.target_lane_index = lane_index

    def _merge_is_safe(self, lane_index: Any) -> bool:
        """Neither the new follower nor this vehicle brakes harder than the merge limit."""
        front, rear = self.road.neighbour_vehicles(self, lane_index)
        if rear is not None and self.acceleration(rear, self) < -MERGE_MAX_BRAKING:
            return False
        return not (front is not None and self.acceleration(self, front) < -MERGE_MAX_BRAKING)

    def act(self, action: dict[str, float] | str | None = None) -> None:
        """IDM/MOBIL, then brake for the end of the followed lane if it ends ahead."""
        super().act(action)
        if self.crashed:
            return
        gap = self._lane_left(self.target_lane_index, 2 * MERGE_ZONE) - 0.5 * self.LENGTH
        if gap >= MERGE_ZONE:
            return
        # IDM towards a standing obstacle at the lane's end (dv = own speed).
        v = max(self.speed, 0.0)
        ab = -self.COMFORT_ACC_MAX * self.COMFORT_ACC_MIN
        wanted = self.DISTANCE_WANTED - Vehicle.LENGTH + v * self.TIME_WANTED  # a car's d0
        wanted += v * v / (2 * math.sqrt(ab))
        ratio = wanted / max(gap, 1e-3)
        stop = self.COMFORT_ACC_MAX * (1 - ratio * ratio)
        if stop < self.action["acceleration"]:
            self.action["acceleration"] = float(clip_scalar(stop, -self.ACC_MAX, self.ACC_MAX))

    def on_state_update(self) -> None:
        """The end of a step: a vehicle stopped for a lane's end stays stopped (no
        reversing), then the lane update (deferred inside ``FastRoad.step``).

        Clamping here rather than after ``step`` keeps ``step`` the base one, whose
        closest-lane look-up :class:`~aldm_gym.envs.traffic.FastRoad` batches; the
        look-up reads only the position and heading, so the order does not matter.
        """
        if self.speed < 0.0:
            self.speed = 0.0
        super().on_state_update()
