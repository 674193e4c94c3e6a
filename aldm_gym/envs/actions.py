"""Actions of ``ALDMHighway-v0``: highway-env's meta actions through the LKA, or raw control.

:class:`MetaAction` is the one home of the meta-action indices (highway-env's
``DiscreteMetaAction.ACTIONS_ALL`` order); :class:`ALDMAction` is the env's
highway-env ``ActionType``: it declares the action space and hands an agent's action
to the ego vehicle (:class:`~aldm_gym.envs.vehicle.SensorVehicle`).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from aldm_gym.config import setting, validate
from aldm_gym.errors import InputError

if TYPE_CHECKING:
    from highway_env.vehicle.kinematics import Vehicle

    from aldm_gym.envs.highway import ALDMHighwayEnv

ACTION_TYPES = ("DiscreteMetaAction", "ContinuousAction")
"""Action types: highway-env's meta actions (via the LKA), or (steering, acceleration)."""


class MetaAction(IntEnum):
    """highway-env's ``DiscreteMetaAction`` indices (``ACTIONS_ALL``)."""

    LANE_LEFT = 0
    IDLE = 1
    LANE_RIGHT = 2
    FASTER = 3
    SLOWER = 4


ACTIONS_ALL: dict[int, str] = {int(a): a.name for a in MetaAction}
"""Index -> name, as highway-env's ``DiscreteMetaAction.ACTIONS_ALL``."""

LANE_CHANGES = frozenset({MetaAction.LANE_LEFT, MetaAction.LANE_RIGHT})
"""The meta actions that request a lane change."""


def meta_action_index(action: Any) -> int:
    """``action`` as a :class:`MetaAction` index, accepting only integers.

    Python and numpy integers (a :class:`MetaAction` too) and one-element integer
    arrays are accepted; floats (1.5, but also 1.0), strings, bools, ``None`` and
    longer arrays are not, so a wrong action is never silently rounded.

    :raises InputError: saying what was given.
    """
    a = action
    if isinstance(a, np.ndarray) and a.size == 1 and np.issubdtype(a.dtype, np.integer):
        a = a.reshape(-1)[0]
    if isinstance(a, bool | np.bool_) or not isinstance(a, int | np.integer):
        raise InputError(
            f"meta action must be an integer in [0, {len(MetaAction) - 1}] "
            f"({', '.join(f'{m.value} {m.name}' for m in MetaAction)}), got {action!r}"
        )
    if not 0 <= int(a) < len(MetaAction):
        raise InputError(f"meta action must be in [0, {len(MetaAction) - 1}], got {action!r}")
    return int(a)


@dataclass(frozen=True)
class ActionConfig:
    """The env's ``action`` section.

    :ivar type: ``"DiscreteMetaAction"`` (:class:`MetaAction` through the LKA) or
        ``"ContinuousAction"`` (steering [rad], acceleration [m/s²]).
    :ivar target_speeds: the speeds FASTER/SLOWER step through [m/s], increasing.
    :ivar lane_change_timeout: a lane change not completed after this is aborted [s].
    :ivar max_acceleration: acceleration saturation, both signs [m/s²].
    :ivar cross_solid_lines: a lane change may cross an ego line the sensor reports as
        continuous (False: it is refused, as traffic rules forbid; a double line only
        from its broken stripe's side: :func:`~aldm_gym.sensor.lane_detection.paint_types`).
    """

    type: str = setting("DiscreteMetaAction", choices=ACTION_TYPES)
    target_speeds: list[float] = setting([20.0, 25.0, 30.0], lo=0.0, hi=40.0, increasing=True)
    lane_change_timeout: float = setting(8.0, lo=0.5, hi=60.0)
    max_acceleration: float = setting(5.0, lo=0.0, lo_open=True, hi=20.0)
    cross_solid_lines: bool = setting(False)

    def __post_init__(self) -> None:
        validate(self, "action")


class ALDMAction:
    """highway-env's ``ActionType`` for the env: the space, and acting on the ego.

    Meta actions go to :meth:`SensorVehicle.set_meta_action
    <aldm_gym.envs.vehicle.SensorVehicle.set_meta_action>` once per policy step;
    continuous actions (clipped to the space) are held by the ego until the next one.
    """

    def __init__(self, env: ALDMHighwayEnv, vehicle_class: type[Vehicle]) -> None:
        """The action type of ``env``, whose ego is a ``vehicle_class``."""
        self.env = env
        self._vehicle_class = vehicle_class
        action = env.settings.action
        self.continuous = action.type == "ContinuousAction"
        self.max_steering = float(env.lka.max_steering)
        self.max_acceleration = float(action.max_acceleration)
        self.last_action: Any = None

    def space(self) -> spaces.Space:
        """``Discrete(5)`` or ``Box([-max_steer, -max_acc], [max_steer, max_acc])``."""
        if self.continuous:
            hi = np.array([self.max_steering, self.max_acceleration], dtype=np.float32)
            return spaces.Box(-hi, hi, (2,), np.float32)
        return spaces.Discrete(len(MetaAction))

    @property
    def vehicle_class(self) -> type:
        """The ego vehicle class."""
        return self._vehicle_class

    @property
    def controlled_vehicle(self) -> Vehicle:
        """The ego vehicle."""
        return self.env.vehicle

    def act(self, action: Any) -> None:
        """Pass an agent action to the ego (once per policy step).

        :raises InputError: a meta action that is not an integer in ``[0, 4]`` (Python
            or numpy integers, or a one-element integer array), or a continuous action
            that is not exactly 2 finite numbers (shape ``(2,)``).
        """
        ego = self.env.vehicle
        if self.continuous:
            ego.command = self._continuous(action)
        else:
            ego.set_meta_action(meta_action_index(action))
        self.last_action = action

    def _continuous(self, action: Any) -> np.ndarray:
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            a = np.zeros(0)
        if a.shape != (2,) or not np.all(np.isfinite(a)):
            raise InputError(
                "continuous action must be 2 finite numbers of shape (2,) "
                f"(steering [rad], acceleration [m/s²]), got {action!r}"
            )
        hi = np.array([self.max_steering, self.max_acceleration])
        return np.clip(a, -hi, hi)

    def is_lane_change(self, action: Any) -> bool:
        """Whether ``action`` (as given to :meth:`act`) requests a lane change."""
        return (
            not self.continuous and action is not None and meta_action_index(action) in LANE_CHANGES
        )

    def get_available_actions(self) -> list[int]:
        """All meta actions (refused ones are no-ops)."""
        return [int(a) for a in MetaAction]

    def action_mask(self) -> np.ndarray:
        """Which meta actions act now, ``(5,)`` bool in :class:`MetaAction` order: IDLE,
        FASTER and SLOWER always; LANE_LEFT / LANE_RIGHT where a lane change would
        start (:meth:`SensorVehicle.lane_change_available
        <aldm_gym.envs.vehicle.SensorVehicle.lane_change_available>`: the detected
        adjacent lane exists and does not close ahead, the ego line on that side is
        seen on broken paint, and no change is under way).

        :raises InputError: with ``ContinuousAction`` (masks are for meta actions).
        """
        if self.continuous:
            raise InputError("action masks are for the meta actions (DiscreteMetaAction)")
        ego = self.env.vehicle
        mask = np.ones(len(MetaAction), dtype=bool)
        mask[MetaAction.LANE_LEFT] = ego.lane_change_available(+1)
        mask[MetaAction.LANE_RIGHT] = ego.lane_change_available(-1)
        return mask
