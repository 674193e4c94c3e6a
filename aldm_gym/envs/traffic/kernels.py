"""Compiled IDM/MOBIL traffic on one reference line: the kernels of the compiled engine.

One call decides the actions of every compiled vehicle (:func:`traffic_act`), one
moves them and finds their lanes (:func:`traffic_step`). Each repeats, operation for
operation, what highway-env's ``IDMVehicle`` (through
:class:`~aldm_gym.envs.traffic.vehicles.FastIDMVehicle`) computes on a road whose lanes
are :class:`~aldm_gym.roads.lane.ReferenceLane` offsets of one
:class:`~aldm_gym.roads.reference_line.ReferenceLine`, in the same order and with the same
IEEE operations (``math`` and numba call the same C library here), so the results are
the same floats (``tests/envs/traffic/test_compiled.py`` checks whole episodes bit for bit).
On such a road every lane shares the line's arc length ``s`` and the lateral coordinate
of lane ``k`` is ``offset[k] - d``, so one projection per vehicle and step serves every
lane query.

State layout (rows follow ``road.vehicles``; :mod:`~aldm_gym.envs.traffic.compiled`
fills and reads them):

- ``f`` float64 ``(N, F_COLUMNS)``: columns ``F_X, F_Y`` [m], ``F_HEADING`` [rad],
  ``F_SPEED`` [m/s], ``F_LENGTH`` [m], ``F_TARGET_SPEED`` [m/s], ``F_SPEED_LIMIT`` [m/s]
  (of the vehicle's lane; NaN: none), ``F_TIMER`` [s], ``F_STEERING`` [rad],
  ``F_ACCELERATION`` [m/s²] (the action), ``F_IMPACT_X, F_IMPACT_Y`` [m], ``F_WIDTH``
  and ``F_DIAGONAL`` [m];
- ``k`` int64 ``(N, K_COLUMNS)``: ``K_LANE``, ``K_TARGET`` (lane ids; -1: no target,
  i.e. not a highway-env ``ControlledVehicle``), ``K_COMPILED`` (1: this kernel
  decides and moves it; 0: it only takes part as a neighbour), ``K_CRASHED``,
  ``K_IMPACT`` (an impact is pending), ``K_LANE_CHANGE`` (MOBIL enabled),
  ``K_COLLIDABLE`` and ``K_CHECKS`` (``collidable``, ``check_collisions``);
- ``p`` float64 ``(N, P_COLUMNS)``: the IDM/MOBIL and controller constants of each
  compiled vehicle (highway-env's class or instance attributes).

Lanes: ``lane_offset``, ``lane_width``, ``lane_length`` [m] and ``lane_forbidden`` per
lane id; ``lane_vehicle_length`` is highway-env's ``AbstractLane.VEHICLE_LENGTH`` [m].
"""

from __future__ import annotations

import math

import numba
import numpy as np

from aldm_gym.envs.traffic.collisions import BROAD_PHASE_SLACK, boxes_separated
from aldm_gym.roads.reference_line import LineLookup, heading_on_table, project_on
from aldm_gym.types import FloatArray

F_X, F_Y, F_HEADING, F_SPEED, F_LENGTH, F_TARGET_SPEED, F_SPEED_LIMIT = 0, 1, 2, 3, 4, 5, 6
F_TIMER, F_STEERING, F_ACCELERATION, F_IMPACT_X, F_IMPACT_Y = 7, 8, 9, 10, 11
F_WIDTH, F_DIAGONAL = 12, 13
F_COLUMNS = 14

K_LANE, K_TARGET, K_COMPILED, K_CRASHED, K_IMPACT, K_LANE_CHANGE = range(6)
K_COLLIDABLE, K_CHECKS = 6, 7
K_COLUMNS = 8

(
    P_COMFORT_ACC_MAX,
    P_COMFORT_ACC_MIN,
    P_DISTANCE_WANTED,
    P_TIME_WANTED,
    P_DELTA,
    P_POLITENESS,
    P_MIN_ACC_GAIN,
    P_MAX_BRAKING_IMPOSED,
    P_LANE_CHANGE_DELAY,
    P_ACC_MAX,
    P_MAX_STEERING,
    P_KP_LATERAL,
    P_KP_HEADING,
    P_TAU_PURSUIT,
    P_MAX_SPEED,
    P_MIN_SPEED,
) = range(16)
P_COLUMNS = 16

CAR_LENGTH = 5.0
"""highway-env's ``Vehicle.LENGTH`` [m]: gaps to longer vehicles are bumper to bumper."""
NEIGHBOUR_MARGIN = 1.0
"""Lateral margin [m] of ``Road.neighbour_vehicles``'s ``on_lane(..., margin=1)``."""


def _clip_py(x: float, low: float, high: float) -> float:
    """``clip_scalar``: ``np.clip`` of a scalar (same NaN and signed-zero results)."""
    if low > x:
        x = low
    if high < x:
        return high
    return x


_clip = numba.njit(cache=True)(_clip_py)


def _not_zero_py(x: float) -> float:
    """``highway_env.utils.not_zero(x)`` (eps = 0.01)."""
    if abs(x) > 0.01:
        return x
    if x >= 0:
        return 0.01
    return -0.01


_not_zero = numba.njit(cache=True)(_not_zero_py)


def _extra_length_py(length: float) -> float:
    """Half of what a vehicle of ``length`` [m] is longer than a car [m] (0 if not)."""
    return 0.5 * (length - CAR_LENGTH) if length > CAR_LENGTH else 0.0


_extra_length = numba.njit(cache=True)(_extra_length_py)


def _desired_gap_py(f: FloatArray, p: FloatArray, c: int, e: int, front: int) -> float:
    """IDM ``s*`` [m] of vehicle ``e`` behind ``front`` with caller ``c``'s constants."""
    d0 = p[c, P_DISTANCE_WANTED]
    tau = p[c, P_TIME_WANTED]
    ab = -p[c, P_COMFORT_ACC_MAX] * p[c, P_COMFORT_ACC_MIN]
    ego_speed = f[e, F_SPEED]
    cos_e = math.cos(f[e, F_HEADING])
    sin_e = math.sin(f[e, F_HEADING])
    front_speed = f[front, F_SPEED]
    dvx = ego_speed * cos_e - front_speed * math.cos(f[front, F_HEADING])
    dvy = ego_speed * sin_e - front_speed * math.sin(f[front, F_HEADING])
    dv = dvx * cos_e + dvy * sin_e
    return d0 + ego_speed * tau + ego_speed * dv / (2 * math.sqrt(ab))


_desired_gap = numba.njit(cache=True)(_desired_gap_py)


def _acceleration_py(
    f: FloatArray, p: FloatArray, s: FloatArray, c: int, e: int, front: int
) -> float:
    """IDM acceleration [m/s²] of vehicle ``e`` (-1: none, 0) behind ``front`` (-1: none),
    with caller ``c``'s constants (``FastIDMVehicle.acceleration``)."""
    if e < 0:
        return 0.0
    target = f[e, F_TARGET_SPEED]
    limit = f[e, F_SPEED_LIMIT]
    if not math.isnan(limit):
        target = _clip(target, 0.0, limit)
    speed = f[e, F_SPEED]
    if 0 > speed:  # max(speed, 0)
        speed = 0.0
    acceleration = p[c, P_COMFORT_ACC_MAX] * (1 - (speed / abs(_not_zero(target))) ** p[c, P_DELTA])
    if front >= 0:
        d = s[front] - s[e]
        extra = _extra_length(f[e, F_LENGTH]) + _extra_length(f[front, F_LENGTH])
        if extra != 0.0:
            d -= extra
        ratio = _desired_gap(f, p, c, e, front) / _not_zero(d)
        acceleration -= p[c, P_COMFORT_ACC_MAX] * (ratio * ratio)
    return acceleration


_acceleration = numba.njit(cache=True)(_acceleration_py)


def _neighbours_py(
    s: FloatArray,
    d: FloatArray,
    lane_offset: FloatArray,
    lane_width: FloatArray,
    lane_length: FloatArray,
    lane_vehicle_length: float,
    i: int,
    lane: int,
) -> tuple[int, int]:
    """``Road.neighbour_vehicles(vehicle i, lane)``: rows ``(front, rear)`` (-1: none),
    highway-env's loop and tie rules (front: last of equal ``s``; rear: first)."""
    front = -1
    rear = -1
    s_front = 0.0
    s_rear = 0.0
    s_i = s[i]
    half = lane_width[lane] / 2 + NEIGHBOUR_MARGIN
    offset = lane_offset[lane]
    end = lane_length[lane] + lane_vehicle_length
    for j in range(s.shape[0]):
        if j == i:
            continue
        s_j = s[j]
        if not (abs(offset - d[j]) <= half and -lane_vehicle_length <= s_j < end):
            continue
        if s_i <= s_j and (front < 0 or s_j <= s_front):
            front = j
            s_front = s_j
        if s_j < s_i and (rear < 0 or s_j > s_rear):
            rear = j
            s_rear = s_j
    return front, rear


_neighbours = numba.njit(cache=True)(_neighbours_py)


def _same_point_py(x0: float, y0: float, x1: float, y1: float) -> bool:
    """Whether ``(x0, y0)`` and ``(x1, y1)`` are the same doubles (zeros by sign too)."""
    return (
        x0 == x1
        and y0 == y1
        and math.copysign(1.0, x0) == math.copysign(1.0, x1)
        and math.copysign(1.0, y0) == math.copysign(1.0, y1)
    )


_same_point = numba.njit(cache=True)(_same_point_py)


def _mobil_py(
    f: FloatArray,
    k: np.ndarray,
    p: FloatArray,
    s: FloatArray,
    d: FloatArray,
    lane_offset: FloatArray,
    lane_width: FloatArray,
    lane_length: FloatArray,
    lane_vehicle_length: float,
    i: int,
    lane: int,
) -> bool:
    """``IDMVehicle.mobil(lane)`` of vehicle ``i`` (no planned route)."""
    new_preceding, new_following = _neighbours(
        s, d, lane_offset, lane_width, lane_length, lane_vehicle_length, i, lane
    )
    new_following_a = _acceleration(f, p, s, i, new_following, new_preceding)
    new_following_pred_a = _acceleration(f, p, s, i, new_following, i)
    if new_following_pred_a < -p[i, P_MAX_BRAKING_IMPOSED]:
        return False
    old_preceding, old_following = _neighbours(
        s, d, lane_offset, lane_width, lane_length, lane_vehicle_length, i, k[i, K_LANE]
    )
    self_pred_a = _acceleration(f, p, s, i, i, new_preceding)
    self_a = _acceleration(f, p, s, i, i, old_preceding)
    old_following_a = _acceleration(f, p, s, i, old_following, i)
    old_following_pred_a = _acceleration(f, p, s, i, old_following, old_preceding)
    jerk = (
        self_pred_a
        - self_a
        + p[i, P_POLITENESS]
        * (new_following_pred_a - new_following_a + old_following_pred_a - old_following_a)
    )
    return not jerk < p[i, P_MIN_ACC_GAIN]


_mobil = numba.njit(cache=True)(_mobil_py)


def _steering_py(
    f: FloatArray,
    p: FloatArray,
    s: FloatArray,
    d: FloatArray,
    lane_offset: FloatArray,
    s_tab: FloatArray,
    h_tab: FloatArray,
    step: float,
    i: int,
    lane: int,
) -> float:
    """``ControlledVehicle.steering_control(lane)`` of vehicle ``i`` [rad] (``s_tab``,
    ``h_tab``: the reference line's arc lengths [m], ``step`` [m] apart, and headings)."""
    r = lane_offset[lane] - d[i]
    speed = f[i, F_SPEED]
    future = s[i] + speed * p[i, P_TAU_PURSUIT]
    lane_future_heading = heading_on_table(s_tab, h_tab, step, future)[2]
    lateral_speed_command = -p[i, P_KP_LATERAL] * r
    heading_command = math.asin(_clip(lateral_speed_command / _not_zero(speed), -1.0, 1.0))
    heading_ref = lane_future_heading + _clip(heading_command, -np.pi / 4, np.pi / 4)
    wrapped = ((heading_ref - f[i, F_HEADING] + np.pi) % (2 * np.pi)) - np.pi
    heading_rate_command = p[i, P_KP_HEADING] * wrapped
    slip_angle = math.asin(
        _clip(f[i, F_LENGTH] / 2 / _not_zero(speed) * heading_rate_command, -1.0, 1.0)
    )
    steering_angle = math.atan(2 * math.tan(slip_angle))
    return _clip(steering_angle, -p[i, P_MAX_STEERING], p[i, P_MAX_STEERING])


_steering = numba.njit(cache=True)(_steering_py)


def _traffic_act_py(
    f: FloatArray,
    k: np.ndarray,
    p: FloatArray,
    memo: FloatArray,
    lane_offset: FloatArray,
    lane_width: FloatArray,
    lane_length: FloatArray,
    lane_forbidden: np.ndarray,
    lane_vehicle_length: float,
    s_tab: FloatArray,
    line: LineLookup,
    coord_limit: float,
) -> bool:
    """``IDMVehicle.act`` of every compiled, uncrashed vehicle, in row order, in place.

    Writes ``F_STEERING``, ``F_ACCELERATION``, ``F_TIMER`` and ``K_TARGET``. Positions
    are fixed while vehicles act, so each is projected once; ``memo`` ``(M, 4)`` rows
    ``(x, y, s, d)`` [m] hold :func:`traffic_step`'s projections, reused for a row
    whose position is the very same (a projection depends on the point alone).
    ``follow_road`` is left out: on a one-edge network its ``next_lane`` returns the
    lane it is given. ``s_tab`` [m] are the reference line's tabulated arc lengths,
    ``line`` its :attr:`~aldm_gym.roads.reference_line.ReferenceLine.lookup`.

    :return: False, with nothing written, if a coordinate is not below
        ``coord_limit`` [m] in magnitude (NaN included): the caller's Python path.
    """
    n = f.shape[0]
    for j in range(n):
        if not (abs(f[j, F_X]) < coord_limit and abs(f[j, F_Y]) < coord_limit):
            return False
    _, h_tab, step, _, _, _, _, _, _ = line
    s = np.empty(n)
    d = np.empty(n)
    for j in range(n):
        if j < memo.shape[0] and _same_point(memo[j, 0], memo[j, 1], f[j, F_X], f[j, F_Y]):
            s[j] = memo[j, 2]  # projected by the last traffic_step: the same floats
            d[j] = memo[j, 3]
            continue
        s[j], d[j] = project_on(line, f[j, F_X], f[j, F_Y])
    n_lanes = lane_offset.shape[0]
    for i in range(n):
        if k[i, K_COMPILED] == 0 or k[i, K_CRASHED] != 0:
            continue
        lane = k[i, K_LANE]
        if k[i, K_LANE_CHANGE] != 0:
            # change_lane_policy
            target = k[i, K_TARGET]
            if lane != target:
                # A lane change is under way: abort it if a vehicle ahead changes into it.
                for j in range(n):
                    if j != i and k[j, K_LANE] != target and k[j, K_TARGET] == target:
                        gap = s[j] - s[i]
                        gap_star = _desired_gap(f, p, i, i, j)
                        if 0 < gap < gap_star:
                            k[i, K_TARGET] = lane
                            break
            elif p[i, P_LANE_CHANGE_DELAY] < f[i, F_TIMER]:
                f[i, F_TIMER] = 0.0
                for side in (lane - 1, lane + 1):  # network.side_lanes: left, then right
                    if side < 0 or side >= n_lanes or lane_forbidden[side] != 0:
                        continue
                    lateral = lane_offset[side] - d[i]
                    if not (
                        abs(lateral) <= 2 * lane_width[side]
                        and 0 <= s[i] < lane_length[side] + lane_vehicle_length
                    ):
                        continue
                    if abs(f[i, F_SPEED]) < 1:
                        continue
                    if _mobil(
                        f,
                        k,
                        p,
                        s,
                        d,
                        lane_offset,
                        lane_width,
                        lane_length,
                        lane_vehicle_length,
                        i,
                        side,
                    ):
                        k[i, K_TARGET] = side
        target = k[i, K_TARGET]
        steering = _steering(f, p, s, d, lane_offset, s_tab, h_tab, step, i, target)
        f[i, F_STEERING] = _clip(steering, -p[i, P_MAX_STEERING], p[i, P_MAX_STEERING])
        front, _ = _neighbours(
            s, d, lane_offset, lane_width, lane_length, lane_vehicle_length, i, lane
        )
        acceleration = _acceleration(f, p, s, i, i, front)
        if lane != target:
            front, _ = _neighbours(
                s, d, lane_offset, lane_width, lane_length, lane_vehicle_length, i, target
            )
            target_acceleration = _acceleration(f, p, s, i, i, front)
            if target_acceleration < acceleration:  # min(acceleration, target_acceleration)
                acceleration = target_acceleration
        f[i, F_ACCELERATION] = _clip(acceleration, -p[i, P_ACC_MAX], p[i, P_ACC_MAX])
    return True


traffic_act = numba.njit(cache=True)(_traffic_act_py)


def _traffic_step_py(
    f: FloatArray,
    k: np.ndarray,
    p: FloatArray,
    memo: FloatArray,
    dt: float,
    lanes_count: int,
    lane_width: float,
    line: LineLookup,
    coord_limit: float,
) -> bool:
    """``IDMVehicle.step(dt)`` [s] of every compiled vehicle, then its closest lane.

    ``Vehicle.clip_actions`` (crashed vehicles brake to a stop, speeds stay within
    ``MIN_SPEED``/``MAX_SPEED``), the kinematic bicycle model, a pending impact, then
    ``HighwayRoad.lane_of_offset`` of the new position's projection on ``line`` (the
    reference line's :attr:`~aldm_gym.roads.reference_line.ReferenceLine.lookup`). Writes the
    position, heading, speed, timer, clipped action, lane and crash columns, and, if
    ``memo`` has ``N`` rows, the compiled rows' ``(x, y, s, d)`` (NaN for the others)
    for the next :func:`traffic_act`.

    :return: False, with nothing written, if a compiled vehicle's coordinate is not
        below ``coord_limit`` [m] in magnitude before or after its move (NaN included).
    """
    n = f.shape[0]
    moved = f.copy()
    for i in range(n):
        if k[i, K_COMPILED] == 0:
            continue
        if not (abs(f[i, F_X]) < coord_limit and abs(f[i, F_Y]) < coord_limit):
            return False
    lanes = np.empty(n, dtype=np.int64)
    projected = np.full((n, 4), np.nan)
    crashed = k[:, K_CRASHED].copy()
    impact = k[:, K_IMPACT].copy()
    f_in = f
    f = moved
    for i in range(n):
        if k[i, K_COMPILED] == 0:
            continue
        f[i, F_TIMER] += dt
        speed = f[i, F_SPEED]
        steering = f[i, F_STEERING]
        acceleration = f[i, F_ACCELERATION]
        if crashed[i] != 0:
            steering = 0.0
            acceleration = -1.0 * speed
        if speed > p[i, P_MAX_SPEED]:
            bound = 1.0 * (p[i, P_MAX_SPEED] - speed)
            if bound < acceleration:
                acceleration = bound
        elif speed < p[i, P_MIN_SPEED]:
            bound = 1.0 * (p[i, P_MIN_SPEED] - speed)
            if bound > acceleration:
                acceleration = bound
        f[i, F_STEERING] = steering
        f[i, F_ACCELERATION] = acceleration
        beta = math.atan(1 / 2 * math.tan(steering))
        course = f[i, F_HEADING] + beta
        f[i, F_X] = f[i, F_X] + speed * math.cos(course) * dt
        f[i, F_Y] = f[i, F_Y] + speed * math.sin(course) * dt
        if impact[i] != 0:
            f[i, F_X] += f[i, F_IMPACT_X]
            f[i, F_Y] += f[i, F_IMPACT_Y]
            crashed[i] = 1
            impact[i] = 0
        f[i, F_HEADING] += speed * math.sin(beta) / (f[i, F_LENGTH] / 2) * dt
        f[i, F_SPEED] += acceleration * dt
        if not (abs(f[i, F_X]) < coord_limit and abs(f[i, F_Y]) < coord_limit):
            return False
        s_new, d = project_on(line, f[i, F_X], f[i, F_Y])
        lane = math.ceil(0.5 * lanes_count - d / lane_width) - 1
        lanes[i] = min(max(lane, 0), lanes_count - 1)
        projected[i, 0] = f[i, F_X]
        projected[i, 1] = f[i, F_Y]
        projected[i, 2] = s_new
        projected[i, 3] = d
    # Every move was valid: commit.
    f_in[:] = f
    if memo.shape[0] == n:
        memo[:] = projected
    for i in range(n):
        if k[i, K_COMPILED] != 0:
            k[i, K_LANE] = lanes[i]
            k[i, K_CRASHED] = crashed[i]
            k[i, K_IMPACT] = impact[i]
    return True


traffic_step = numba.njit(cache=True)(_traffic_step_py)


def _box_py(f: FloatArray, i: int, dt: float) -> tuple[float, ...]:
    """Vehicle ``i``'s box for :func:`~aldm_gym.envs.traffic.collisions.boxes_separated_py`:
    ``(x, y, cos h, sin h, length / 2, width / 2, vx dt, vy dt)`` [m]."""
    c = math.cos(f[i, F_HEADING])
    s = math.sin(f[i, F_HEADING])
    step = f[i, F_SPEED] * dt
    return (f[i, F_X], f[i, F_Y], c, s, f[i, F_LENGTH] / 2, f[i, F_WIDTH] / 2, step * c, step * s)


_box = numba.njit(cache=True)(_box_py)


def _collision_pairs_py(f: FloatArray, k: np.ndarray, dt: float) -> tuple[bool, np.ndarray]:
    """Vehicle pairs ``(i, j)``, ``i < j`` in row order, whose ``handle_collisions`` may
    have an effect: :func:`~aldm_gym.envs.traffic.collisions.resolve_collisions`'s
    broad phase (centres within the sum of the radii ``diagonal / 2 + speed dt`` on
    both axes) and narrow phase (boxes apart on an edge normal), for plain boxes.

    :return: ``(ok, pairs)``: ``pairs`` ``(M, 2)`` int64 rows, sorted; ``ok`` False
        (and no pairs) if a collidable vehicle's pose, speed or size is not finite
        (the caller then checks every pair, as ``resolve_collisions`` does).
    """
    n = f.shape[0]
    radius = np.empty(n)
    for i in range(n):
        r = f[i, F_DIAGONAL] / 2 + max(f[i, F_SPEED] * dt, 0.0)
        radius[i] = r * (1 + 1e-9) + BROAD_PHASE_SLACK
        if k[i, K_COLLIDABLE] != 0 and not (
            math.isfinite(f[i, F_X])
            and math.isfinite(f[i, F_Y])
            and math.isfinite(f[i, F_HEADING])
            and math.isfinite(radius[i])
        ):
            return False, np.empty((0, 2), dtype=np.int64)
    pairs = np.empty((n * (n - 1) // 2, 2), dtype=np.int64)
    m = 0
    for i in range(n):
        if k[i, K_COLLIDABLE] == 0:
            continue
        xi = f[i, F_X]
        for j in range(i + 1, n):
            if k[j, K_COLLIDABLE] == 0 or (k[i, K_CHECKS] == 0 and k[j, K_CHECKS] == 0):
                continue
            xj = f[j, F_X]
            if not (xi + radius[i] >= xj - radius[j] and xj + radius[j] >= xi - radius[i]):
                continue
            if abs(f[i, F_Y] - f[j, F_Y]) > radius[i] + radius[j]:
                continue
            if boxes_separated(*_box(f, i, dt), *_box(f, j, dt)):
                continue
            pairs[m, 0] = i
            pairs[m, 1] = j
            m += 1
    return True, pairs[:m]


collision_pairs = numba.njit(cache=True)(_collision_pairs_py)
