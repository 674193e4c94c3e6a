"""The function under test: what it receives each step and what it returns.

A driving function (LKA, ACC, a lane-change policy, a whole chauffeur) is anything
with the :class:`Function` protocol: ``reset()``, ``step(FunctionInput) ->
FunctionOutput`` and the ``domains`` it takes. It sees only what the ego perceives:

* the perceived lines (:class:`PerceivedLine`: points, a cubic, the detector's
  confidence where it gives one, and the line's role);
* the ego's own motion (:class:`EgoState`: speed, yaw rate, acceleration, steering);
* the objects the ACC's object sensor reports (:class:`PerceivedObject`: relative
  position, relative speed, size).

It returns requests (:class:`FunctionOutput`): an acceleration, a steering angle or a
path curvature, a lane change, a step of the set speed. A request left ``None`` (or a
domain the function does not take) stays with the env's built-in function: the LKA
steers, the ACC/AEB sets the speed, the rule-based lane change is not asked for. In a
scenario the storyboard drives the domains the scenario has not handed over
(``ActivateControllerAction``), whatever the function requests.

Everything is in the sensor frame of ISO 8855 (x forward, y left), SI units. The
function is stepped once per env step (``policy_frequency``) with that step's inputs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.sensor.lane_detection import LINE_NAMES
from aldm_gym.types import FloatArray

__all__ = [
    "DOMAINS",
    "LINE_ROLES",
    "EgoState",
    "Function",
    "FunctionInput",
    "FunctionOutput",
    "PerceivedLine",
    "PerceivedObject",
    "check_output",
]

DOMAINS = frozenset({"lateral", "longitudinal"})
"""The control domains a function may take (OpenSCENARIO's names)."""

LINE_ROLES: tuple[str, ...] = tuple(LINE_NAMES)
"""The perceived lines' roles, in :attr:`FunctionInput.lines` order: ``left_adjacent``,
``ego_left``, ``ego_right``, ``right_adjacent``."""


def _finite(name: str, value: Any) -> float:
    ok = isinstance(value, int | float | np.floating | np.integer) and not isinstance(value, bool)
    if not ok or not math.isfinite(float(value)):
        raise InputError(f"{name} must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class PerceivedLine:
    """One lane marking as the detector reports it (sensor frame).

    :ivar role: one of :data:`LINE_ROLES`.
    :ivar points: ``(K, 2)`` points (x forward, y left) [m], x increasing; ``K = 0``
        when the detector did not find the line.
    :ivar confidence: the detector's confidence in [0, 1] (the lane-model filter's),
        ``None`` where the detector gives none.
    """

    role: str
    points: FloatArray
    confidence: float | None = None

    @property
    def found(self) -> bool:
        """Whether the detector reports the line (at least two points)."""
        return len(self.points) >= 2

    @property
    def range(self) -> float:
        """The farthest x of the line [m] (0 when not found)."""
        return float(self.points[-1, 0]) if self.found else 0.0

    def cubic(self) -> np.ndarray:
        """``(c0, c1, c2, c3)`` of ``y(x) = c0 + c1 x + c2 x² + c3 x³`` [m, 1, 1/m, 1/m²],
        least squares over the points (lower degree for fewer points); zeros when not
        found. The usual lane-marking interface of a camera (a clothoid's polynomial:
        offset, heading, curvature / 2, curvature rate / 6)."""
        out = np.zeros(4)
        if not self.found:
            return out
        x, y = self.points[:, 0], self.points[:, 1]
        degree = min(3, len(x) - 1)
        out[: degree + 1] = np.polynomial.polynomial.polyfit(x, y, degree)
        return out


@dataclass(frozen=True)
class EgoState:
    """The ego's own motion, as its odometry gives it.

    :ivar speed: [m/s].
    :ivar yaw_rate: [rad/s], > 0 turning left.
    :ivar acceleration: the longitudinal acceleration of the last step [m/s²].
    :ivar steering: the steering angle of the last step [rad], > 0 left.
    """

    speed: float
    yaw_rate: float
    acceleration: float
    steering: float


@dataclass(frozen=True)
class PerceivedObject:
    """One object the ACC's object sensor reports (sensor frame).

    :ivar id: the object's row in the traffic at this step (the same from step to step
        while no vehicle enters or leaves the road).
    :ivar x: longitudinal position of its centre [m].
    :ivar y: lateral position of its centre [m], > 0 left.
    :ivar vx: longitudinal speed relative to the ego [m/s] (< 0: closing in).
    :ivar length: [m].
    :ivar width: [m].
    :ivar vy: lateral speed relative to the ego [m/s] (> 0: moving left).
    """

    id: int
    x: float
    y: float
    vx: float
    length: float
    width: float
    vy: float = 0.0


@dataclass(frozen=True)
class FunctionInput:
    """What a function receives at one step.

    :ivar time: simulation time [s].
    :ivar step: the time until the next step [s] (``1 / policy_frequency``).
    :ivar lines: the four perceived lines, in :data:`LINE_ROLES` order.
    :ivar ego: the ego's motion.
    :ivar objects: the objects the object sensor reports.
    :ivar lane_change: the built-in lane change under way: +1 left, -1 right, 0 none.
    :ivar observation: the env's Gymnasium observation of the same step (for a trained
        policy; a function written against this interface does not need it).
    :ivar action_mask: which of the env's meta actions act now (``(5,)`` bool), for a
        policy trained with masks.
    :ivar lane_end_distance: the map horizon (as ADASIS gives a production car): the
        distance [m] from the ego's centre to where its lane gets too narrow before it
        ends (``lane_end.end_width``), ``inf`` when its lane does not end before the road
        or the road has no map (docs/acc.md, "Lanes that end").
    :ivar lane_end_side: the side to leave that lane by: +1 left, -1 right, 0 none.
    """

    time: float
    step: float
    lines: tuple[PerceivedLine, ...]
    ego: EgoState
    objects: tuple[PerceivedObject, ...] = ()
    lane_change: int = 0
    observation: Mapping[str, Any] | None = field(default=None, repr=False)
    action_mask: np.ndarray | None = field(default=None, repr=False)
    lane_end_distance: float = math.inf
    lane_end_side: int = 0

    def line(self, role: str) -> PerceivedLine:
        """The line of ``role`` (one of :data:`LINE_ROLES`).

        :raises InputError: an unknown role.
        """
        for line in self.lines:
            if line.role == role:
                return line
        raise InputError(f"no line role {role!r}; roles: {', '.join(LINE_ROLES)}")


@dataclass(frozen=True)
class FunctionOutput:
    """What a function requests for the next step; ``None`` leaves a domain to the
    built-in function.

    :ivar acceleration: longitudinal acceleration [m/s²] (longitudinal domain).
    :ivar steering: steering angle [rad], > 0 left (lateral domain) ...
    :ivar curvature: ... or the path curvature [1/m], > 0 left; not both.
    :ivar lane_change: +1 / -1: ask the built-in lane change for the lane to the left /
        right (when the function leaves steering to it); 0: none.
    :ivar speed_step: +1 / -1: the built-in ACC's next higher / lower set speed
        (``action.target_speeds``); 0: keep it.
    """

    acceleration: float | None = None
    steering: float | None = None
    curvature: float | None = None
    lane_change: int = 0
    speed_step: int = 0


def check_output(output: Any, domains: frozenset[str], source: str = "the function") -> None:
    """Check a function's output before it reaches the env.

    :param domains: the domains the function takes; a request in another one is an
        error, not silently dropped.
    :raises InputError: not a :class:`FunctionOutput`, a value that is not finite, both
        steering and curvature, a lane change or speed step outside -1..1, a lane change
        asked of the built-in beside the function's own steering, or a request outside
        ``domains``.
    """
    if not isinstance(output, FunctionOutput):
        raise InputError(
            f"{source} must return a FunctionOutput, got {type(output).__name__}: {output!r}"
        )
    for name in ("acceleration", "steering", "curvature"):
        value = getattr(output, name)
        if value is not None:
            _finite(f"{source}'s {name}", value)
    if output.steering is not None and output.curvature is not None:
        raise InputError(f"{source} requests steering and curvature; give one")
    for name in ("lane_change", "speed_step"):
        value = getattr(output, name)
        integer = isinstance(value, int | np.integer) and not isinstance(value, bool)
        if not integer or value not in (-1, 0, 1):
            raise InputError(f"{source}'s {name} must be -1, 0 or 1, got {value!r}")
    if output.lane_change and (output.steering is not None or output.curvature is not None):
        raise InputError(
            f"{source} steers and asks the built-in lane change for a lane: a function "
            "that steers changes lanes itself"
        )
    taken = sorted(domains) or "none"
    if (output.steering is not None or output.curvature is not None) and "lateral" not in domains:
        raise InputError(f"{source} steers but does not take the lateral domain (takes {taken})")
    if output.acceleration is not None and "longitudinal" not in domains:
        raise InputError(
            f"{source} requests an acceleration but does not take the longitudinal "
            f"domain (takes {taken})"
        )


@runtime_checkable
class Function(Protocol):
    """A function under test.

    :ivar domains: the domains it takes (a subset of :data:`DOMAINS`); the built-in
        function keeps the others.

    It may also have ``env_config`` (a mapping of env settings it needs, e.g. the
    observation a policy was trained on) and ``close()`` (called when the run ends).
    """

    domains: frozenset[str]

    def reset(self) -> None:
        """Forget the last episode (called before its first step)."""
        ...

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        """The requests for the next step, from this step's inputs."""
        ...
