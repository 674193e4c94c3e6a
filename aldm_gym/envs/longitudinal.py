"""The highway chauffeur's longitudinal half: ACC (constant time gap) and AEB.

:class:`LongitudinalController` runs once per simulation step on what the ego
perceives: the detected lanes (:class:`~aldm_gym.sensor.lane_detection.LaneDetection`) and
the other road users in the sensor frame (:class:`~aldm_gym.envs.targets.Objects`).

* **Target selection** (:mod:`aldm_gym.envs.targets`): the nearest vehicle ahead that
  the *perceived* lanes place in the ego lane (with the target lane during a lane
  change), by its overlap at its own x along the detected lines, with hysteresis.
* **ACC** (:func:`acc_acceleration`): cruise at the set speed, or follow the target
  with a constant time gap ``d* = standstill_gap + time_gap · v``::

      a_follow = gap_gain · (d - d*) + speed_gain · (v_t - v)
      a_follow = min(a_follow, -(v - v_t)² / (2 (d - standstill_gap)))   if closing in
      a        = clip(min(cruise_gain · (v_set - v), a_follow), -max_deceleration, max_acceleration)

  The second line is the deceleration that matches the target's speed exactly at the
  standstill gap: the linear law alone brakes too late for a slow or stopped vehicle
  far ahead. Comfort limits 2 m/s² up, 3.5 m/s² down (the issue's; ISO 15622 allows
  3.5 m/s² average braking for ACC).
* **AEB** (:class:`AEB`): time to collision ``TTC = gap / closing speed`` on every
  object in the perceived *driving corridor* (the ego's width along its planned path,
  so it also catches what target selection missed); below ``aeb_ttc`` it brakes with
  ``aeb_deceleration`` (9 m/s²), beyond the ACC's comfort limit, until the minimum
  TTC rises above twice ``aeb_ttc`` (release hysteresis, no chattering).

All quantities in SI units; gaps are bumper to bumper along the sensor's x axis.
Decisions where the issue is silent: ``docs/acc.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from aldm_gym.config import setting, validate
from aldm_gym.envs.targets import (
    NO_TARGET,
    Objects,
    TargetSelector,
    arc_line,
    corridor_overlaps,
    line_slope,
    line_y,
)
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.types import FloatArray

EGO_LENGTH = 5.0
"""highway-env's vehicle length [m] (the ego's, for bumper-to-bumper gaps)."""

EGO_WIDTH = 2.0
"""highway-env's vehicle width [m] (the ego's, for the AEB corridor)."""

AEB_RELEASE_FACTOR = 2.0
"""The AEB releases when the minimum TTC exceeds this times ``aeb_ttc``."""


@dataclass(frozen=True)
class ACCConfig:
    """The env's ``acc`` section: target selection, ACC law and AEB.

    :ivar enabled: ACC and AEB drive the ego's speed under meta actions (False: the
        speed controller of v0, ``lka``'s proportional gain towards the target speed,
        and no target selection).
    :ivar time_gap: desired time gap to the target [s].
    :ivar standstill_gap: desired bumper-to-bumper gap at standstill [m].
    :ivar range: farthest target, from the ego's centre [m].
    :ivar max_acceleration: comfort acceleration limit of the ACC [m/s²].
    :ivar max_deceleration: comfort braking limit of the ACC [m/s²] (> 0).
    :ivar cruise_gain: speed-control gain towards the set speed [1/s].
    :ivar gap_gain: gain on the gap error [1/s²].
    :ivar speed_gain: gain on the target's relative speed [1/s].
    :ivar enter_overlap: an object enters the perceived corridor (cut-in) when this
        much of its width lies inside it [m].
    :ivar exit_overlap: the target leaves it (cut-out) when its overlap falls below
        this [m] (<= ``enter_overlap``: hysteresis).
    :ivar enter_fraction: a narrow object (a motorbike, a pedestrian) enters when this
        share of its width is inside, if that is less than ``enter_overlap``.
    :ivar prediction_horizon: objects are predicted this far ahead at constant lateral
        speed relative to the lanes [s] (0: no prediction); an object whose predicted
        overlap reaches the threshold before the ego reaches it is a target, and the
        AEB counts an object predicted in the ego's path when the ego gets there.
    :ivar min_lateral_speed: lateral speeds below this are not predicted [m/s] (the
        lanes' and the object sensor's errors).
    :ivar aeb_ttc: the AEB brakes when an object in the driving corridor is closer
        than this time to collision [s] (0: no AEB).
    :ivar aeb_deceleration: the AEB's braking [m/s²] (> 0).
    :ivar phantom_deceleration: braking harder than this [m/s²] for a target that is
        not in the true ego lane counts as phantom braking (``info["target"]``).
    """

    enabled: bool = setting(True)
    time_gap: float = setting(1.8, lo=0.5, hi=5.0)
    standstill_gap: float = setting(4.0, lo=0.5, hi=50.0)
    range: float = setting(150.0, lo=20.0, hi=250.0)
    max_acceleration: float = setting(2.0, lo=0.0, lo_open=True, hi=10.0)
    max_deceleration: float = setting(3.5, lo=0.0, lo_open=True, hi=10.0)
    cruise_gain: float = setting(0.5, lo=0.0, lo_open=True, hi=10.0)
    gap_gain: float = setting(0.2, lo=0.0, hi=10.0)
    speed_gain: float = setting(0.8, lo=0.0, hi=10.0)
    enter_overlap: float = setting(0.5, lo=0.0, hi=3.0)
    exit_overlap: float = setting(0.1, lo=-3.0, hi="enter_overlap")
    enter_fraction: float = setting(0.4, lo=0.0, lo_open=True, hi=1.0)
    prediction_horizon: float = setting(3.0, lo=0.0, hi=10.0)
    min_lateral_speed: float = setting(0.25, lo=0.0, hi=10.0)
    aeb_ttc: float = setting(1.5, lo=0.0, hi=10.0)
    aeb_deceleration: float = setting(9.0, lo=0.0, lo_open=True, hi=15.0)
    phantom_deceleration: float = setting(1.0, lo=0.0, hi=15.0)

    def __post_init__(self) -> None:
        validate(self, "acc")


def acc_acceleration(
    speed: float,
    set_speed: float,
    gap: float | None = None,
    relative_speed: float = 0.0,
    config: ACCConfig | None = None,
) -> float:
    """The ACC's acceleration command [m/s²] (the law in the module docstring).

    :param speed: ego speed [m/s].
    :param set_speed: the driver's set speed [m/s].
    :param gap: bumper-to-bumper gap to the target [m]; ``None``: no target (cruise).
    :param relative_speed: target speed minus ego speed [m/s] (< 0: closing in).
    :param config: the ACC's parameters (default :class:`ACCConfig`).
    """
    c = config or _DEFAULT
    a = c.cruise_gain * (set_speed - speed)
    if gap is not None:
        desired = c.standstill_gap + c.time_gap * max(speed, 0.0)
        follow = c.gap_gain * (gap - desired) + c.speed_gain * relative_speed
        if relative_speed < 0.0:
            room = max(gap - c.standstill_gap, 0.1)
            follow = min(follow, -relative_speed * relative_speed / (2.0 * room))
        a = min(a, follow)
    return min(max(a, -c.max_deceleration), c.max_acceleration)


_DEFAULT = ACCConfig()


def time_to_collision(gap: FloatArray, relative_speed: FloatArray) -> FloatArray:
    """Time to collision [s]: ``gap / -relative_speed`` when closing in, else ``inf``.

    :param gap: ``(N,)`` bumper-to-bumper gaps [m] (clipped at 0).
    :param relative_speed: ``(N,)`` object speed minus ego speed [m/s].
    """
    gap = np.maximum(np.asarray(gap, dtype=np.float64), 0.0)
    rel = np.asarray(relative_speed, dtype=np.float64)
    closing = rel < 0.0
    out = np.full(gap.shape, math.inf)
    out[closing] = gap[closing] / -rel[closing]
    return out


def _path_line(path: FloatArray, curvature: float, reach: float) -> FloatArray:
    """The planned path, or the arc of ``curvature`` when it has fewer than 2 points."""
    return path if len(path) >= 2 else arc_line(curvature, reach)


def driving_corridor_overlap(
    objects: Objects, path: FloatArray, curvature: float = 0.0, ego_width: float = EGO_WIDTH
) -> FloatArray:
    """Each object's lateral overlap [m] with the ego's swept width along its path.

    :param path: ``(M, 2)`` the planned path in the sensor frame [m] (linear
        extrapolation beyond its ends); fewer than 2 points: the arc of ``curvature``.
    :param curvature: the ego's path curvature [1/m] (> 0 left), without a path.
    """
    line = _path_line(path, curvature, 250.0)
    half = 0.5 * ego_width
    return corridor_overlaps(objects.x, objects.y, objects.width, line, half, line, -half)


def _min_ttc_py(
    x: FloatArray,
    y: FloatArray,
    vx: FloatArray,
    vy: FloatArray,
    width: FloatArray,
    length: FloatArray,
    path: FloatArray,
    ego_x: float,
    ego_length: float,
    ego_width: float,
    ego_speed: float,
    min_lateral_speed: float,
) -> float:
    """Smallest time to collision [s] of the objects ahead in the driving corridor
    (their width overlapping the ego's along ``path``) now, or, moving sideways
    relative to the path at ``min_lateral_speed`` or more, when the ego gets there
    (their lateral position then, at constant lateral speed: a crossing pedestrian on
    a collision course); ``inf`` if none closes in."""
    best = np.inf
    half = 0.5 * ego_width
    for i in range(x.shape[0]):
        if x[i] <= ego_x or vx[i] >= 0.0:
            continue
        gap = max(x[i] - ego_x - 0.5 * (length[i] + ego_length), 0.0)
        ttc = gap / -vx[i]
        if ttc >= best:
            continue
        centre = line_y(path, 0.0, x[i])
        w = 0.5 * width[i]
        hit = min(y[i] + w, centre + half) - max(y[i] - w, centre - half) > 0.0
        if not hit:
            lateral = vy[i] - line_slope(path, x[i]) * (vx[i] + ego_speed)
            if abs(lateral) >= min_lateral_speed:
                there = y[i] + lateral * ttc
                hit = min(there + w, centre + half) - max(there - w, centre - half) > 0.0
        if hit:
            best = ttc
    return best


_min_ttc = numba.njit(cache=True)(_min_ttc_py)


def selector_for(config: ACCConfig, *, ego_x: float, lane_width: float) -> TargetSelector:
    """A :class:`~aldm_gym.envs.targets.TargetSelector` with the ``acc`` section's
    selection settings (the perceived and the ground-truth selection share them)."""
    return TargetSelector(
        max_range=config.range,
        enter_overlap=config.enter_overlap,
        exit_overlap=config.exit_overlap,
        enter_fraction=config.enter_fraction,
        horizon=config.prediction_horizon,
        min_lateral_speed=config.min_lateral_speed,
        lane_width=lane_width,
        ego_x=ego_x,
        ego_length=EGO_LENGTH,
    )


@dataclass
class AEB:
    """Time-to-collision emergency braking with release hysteresis (module docstring).

    :ivar ttc: activation threshold [s] (0: never active).
    :ivar deceleration: braking while active [m/s²].
    :ivar active: braking now.
    :ivar activations: activations since :meth:`reset`.
    """

    ttc: float = ACCConfig.aeb_ttc
    deceleration: float = ACCConfig.aeb_deceleration
    active: bool = False
    activations: int = 0

    def reset(self) -> None:
        """Not active, no activations."""
        self.active = False
        self.activations = 0

    def update(self, min_ttc: float) -> bool:
        """Activate below ``ttc``, release above ``AEB_RELEASE_FACTOR · ttc``; ``active``."""
        if self.ttc <= 0.0:
            self.active = False
        elif not self.active and min_ttc < self.ttc:
            self.active = True
            self.activations += 1
        elif self.active and min_ttc > AEB_RELEASE_FACTOR * self.ttc:
            self.active = False
        return self.active


@dataclass(frozen=True)
class LongitudinalCommand:
    """The output of one :meth:`LongitudinalController.update`.

    :ivar acceleration: the command [m/s²].
    :ivar target: the selected target's id, or ``NO_TARGET``.
    :ivar gap: bumper-to-bumper gap to the target [m] (``inf`` without one).
    :ivar relative_speed: target speed minus ego speed [m/s] (0 without one).
    :ivar following: the target limits the command (not the set speed).
    :ivar aeb: the AEB brakes.
    :ivar min_ttc: smallest time to collision in the driving corridor [s].
    :ivar stopping: the end of the lane limits the command (``stop_at``).
    """

    acceleration: float
    target: int = NO_TARGET
    gap: float = math.inf
    relative_speed: float = 0.0
    following: bool = False
    aeb: bool = False
    min_ttc: float = math.inf
    stopping: bool = False


class LongitudinalController:
    """Target selection, ACC and AEB on perceived lanes and objects (module docstring).

    :param config: the ``acc`` section.
    :param ego_x: x of the ego's centre in the sensor frame [m] (``-mount_x``).
    :param lane_width: width assumed for a missing line [m].
    """

    def __init__(
        self, config: ACCConfig | None = None, ego_x: float = -1.0, lane_width: float = 3.75
    ) -> None:
        self.config = config or ACCConfig()
        self.ego_x = float(ego_x)
        self.selector = selector_for(self.config, ego_x=self.ego_x, lane_width=lane_width)
        self.aeb = AEB(self.config.aeb_ttc, self.config.aeb_deceleration)
        # Without prediction the AEB too takes only what is in the path now.
        self._aeb_lateral_speed = (
            self.config.min_lateral_speed if self.config.prediction_horizon > 0.0 else math.inf
        )

    def reset(self) -> None:
        """A new episode: no target, AEB inactive, counters zero."""
        self.selector.reset()
        self.aeb.reset()

    def gaps(self, objects: Objects) -> FloatArray:
        """Bumper-to-bumper gaps from the ego to ``objects`` along x [m] (``(N,)``)."""
        return self.selector.gaps(objects.x, objects.length)

    def update(
        self,
        detection: LaneDetection | None,
        objects: Objects,
        speed: float,
        set_speed: float,
        *,
        path: FloatArray | None = None,
        side: int = 0,
        curvature: float = 0.0,
        stop_at: float | None = None,
    ) -> LongitudinalCommand:
        """One simulation step: select the target, then the ACC and AEB command.

        :param detection: the detected lanes.
        :param objects: other road users in the sensor frame.
        :param speed: ego speed [m/s].
        :param set_speed: the set speed [m/s].
        :param path: the ego's planned path (sensor frame) for the AEB corridor;
            ``None``: the arc of ``curvature``.
        :param side: +1/-1 while a lane change into the adjacent lane on that side is
            under way (the corridor includes that lane), 0 otherwise.
        :param curvature: the ego's path curvature [1/m] (> 0 left).
        :param stop_at: stop before a point this far ahead of the ego's centre [m] (the
            end of its lane, :mod:`aldm_gym.envs.lane_end`): the ACC law brakes for it
            as for a standing vehicle there, and where that cannot stop in time at its
            comfort limit, the constant deceleration that stops at the point does (at
            most ``aeb_deceleration``); ``None``: nothing to stop for.
        """
        target = self.selector.select(
            detection, objects, side=side, curvature=curvature, ego_speed=speed
        )
        gap: float | None = None
        rel = 0.0
        min_ttc = math.inf
        if len(objects):
            if target != NO_TARGET:
                row = objects.index_of(target)
                gap = float(objects.x[row]) - self.ego_x
                gap -= 0.5 * (float(objects.length[row]) + EGO_LENGTH)
                rel = float(objects.vx[row])
            if self.aeb.ttc > 0.0:
                line = _path_line(
                    np.zeros((0, 2)) if path is None else path, curvature, self.config.range
                )
                min_ttc = float(
                    _min_ttc(
                        objects.x,
                        objects.y,
                        objects.vx,
                        objects.vy,
                        objects.width,
                        objects.length,
                        line,
                        self.ego_x,
                        EGO_LENGTH,
                        EGO_WIDTH,
                        float(speed),
                        self._aeb_lateral_speed,
                    )
                )
        cruise = acc_acceleration(speed, set_speed, None, 0.0, self.config)
        accel = acc_acceleration(speed, set_speed, gap, rel, self.config)
        stopping = False
        if stop_at is not None:
            end_gap = float(stop_at) - 0.5 * EGO_LENGTH
            v = max(speed, 0.0)
            stop = acc_acceleration(speed, set_speed, end_gap, -v, self.config)
            # Seen too late for comfort (a detector that shows the taper only near its
            # end): the deceleration that stops at the point, up to the AEB's.
            needed = -v * v / (2.0 * max(end_gap, 0.1))
            if needed < -self.config.max_deceleration:
                stop = min(stop, max(needed, -self.config.aeb_deceleration))
            stopping = stop < accel
            accel = min(accel, stop)
        aeb = self.aeb.update(min_ttc)
        if aeb:
            accel = -self.aeb.deceleration
        return LongitudinalCommand(
            acceleration=accel,
            target=target,
            gap=math.inf if gap is None else gap,
            relative_speed=rel,
            following=gap is not None and accel < cruise and not stopping,
            stopping=stopping,
            aeb=aeb,
            min_ttc=min_ttc,
        )
