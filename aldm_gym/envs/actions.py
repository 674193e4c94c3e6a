"""Actions of ``ALDMHighway-v0``: highway-env's meta actions through the LKA, or raw control.

:class:`MetaAction` is the one home of the meta-action indices (highway-env's
``DiscreteMetaAction.ACTIONS_ALL`` order); :class:`ALDMAction` is the env's
highway-env ``ActionType``: it declares the action space and hands an agent's action
to the ego vehicle (:class:`~aldm_gym.envs.vehicle.SensorVehicle`).
"""

from __future__ import annotations

from enum import IntEnum


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
