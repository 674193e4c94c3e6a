"""Rule-based policies for ``ALDMHighway-v0``'s meta actions, SB3-style ``predict``.

They decide lane changes and the set speed; the env's ACC and AEB
(:mod:`aldm_gym.envs.longitudinal`) keep the distance to the vehicle ahead under every
meta action, so a policy never has to brake for it.

Both act only on the observation, i.e. on what the line sensor and the detector
deliver: with the naive detector the lane assignment of other vehicles is as wrong as
the detected lanes, which is the point of the comparison.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.envs.actions import MetaAction
from aldm_gym.envs.lane_end import CLOSING_TIME, GAP_AHEAD, GAP_BEHIND, gap_is_free
from aldm_gym.envs.observation import VEHICLE_LENGTH, LaneCode


def _batched(observation: dict[str, Any]) -> bool:
    return np.asarray(observation["ego"]).ndim == 2


def _unbatch(observation: dict[str, Any], i: int) -> dict[str, Any]:
    return {k: np.asarray(v)[i] for k, v in observation.items()}


class IdlePolicy:
    """Always MetaAction.IDLE: lane keeping and ACC on the detected lanes, current set speed."""

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray | np.int64, Any]:
        """``(MetaAction.IDLE, state)``; a batch of IDLEs for a batched observation."""
        if _batched(observation):
            return np.full(np.asarray(observation["ego"]).shape[0], MetaAction.IDLE), state
        return np.int64(MetaAction.IDLE), state


@dataclass
class RuleBasedLCA:
    """A MOBIL-like lane-change policy on perceived lanes and vehicles.

    Overtake on the left when a slower or close vehicle is ahead in the ego lane and the
    detected left lane is free; return to the right (the keep-right rule of Austrian
    and German motorways) when the detected right lane is free for longer; adapt the
    target speed to the vehicle ahead. A lane change needs the adjacent line to be
    detected (``line_valid``); the env refuses it otherwise.

    :ivar front_gap: a vehicle ahead in the ego lane closer than this (bumper to
        bumper) is a reason to overtake or slow down [m].
    :ivar slower_by: ... or one slower than the ego by more than this [m/s].
    :ivar left_clear: free window ``(behind, ahead)`` needed in the target lane to
        overtake [m]; vehicles behind also need ``closing_time`` × closing speed.
    :ivar right_clear: free window needed to return to the right [m].
    :ivar closing_time: time margin for faster vehicles approaching from behind [s].
    :ivar cooldown: policy steps between two lane-change commands.
    """

    front_gap: float = 40.0
    slower_by: float = 1.0
    left_clear: tuple[float, float] = (GAP_BEHIND, GAP_AHEAD)
    right_clear: tuple[float, float] = (25.0, 70.0)
    closing_time: float = CLOSING_TIME
    cooldown: int = 4

    def __post_init__(self) -> None:
        self._since = self.cooldown

    def reset(self) -> None:
        """Forget the cooldown (call at episode start)."""
        self._since = self.cooldown

    def _free(self, vehicles: np.ndarray, code: int, window: tuple[float, float]) -> bool:
        """Whether lane ``code`` has ``window`` free (:func:`~aldm_gym.envs.lane_end.gap_is_free`,
        the check the env's lane change out of an ending lane makes too)."""
        rows = [
            (x, vx)
            for present, x, _y, vx, _vy, lane in vehicles
            if present >= 0.5 and round(float(lane)) == code
        ]
        xs = np.array([r[0] for r in rows], dtype=np.float64)
        vxs = np.array([r[1] for r in rows], dtype=np.float64)
        return gap_is_free(xs, vxs, window[0], window[1], self.closing_time)

    @staticmethod
    def _lead(vehicles: np.ndarray, code: int) -> tuple[float, float] | None:
        best = None
        for present, x, _y, vx, _vy, lane in vehicles:
            if present > 0.5 and round(float(lane)) == code and x > 0:
                if best is None or x < best[0]:
                    best = (float(x), float(vx))
        return best

    def act(self, observation: dict[str, Any]) -> int:
        """One meta action for one observation."""
        self._since += 1
        ego = np.asarray(observation["ego"], dtype=np.float64)
        valid = np.asarray(observation["line_valid"]) > 0.5
        veh = np.asarray(observation["vehicles"], dtype=np.float64)
        if ego[3] != 0:  # a lane change is under way
            return MetaAction.IDLE
        lead = self._lead(veh, LaneCode.EGO)
        blocked = lead is not None and (
            lead[0] - VEHICLE_LENGTH < self.front_gap or lead[1] < -self.slower_by
        )
        ready = self._since >= self.cooldown
        if (
            blocked
            and ready
            and valid[0]
            and valid[1]
            and self._free(veh, LaneCode.LEFT, self.left_clear)
        ):
            left_lead = self._lead(veh, LaneCode.LEFT)
            if left_lead is None or left_lead[0] > lead[0] + 10.0:  # type: ignore[index]
                self._since = 0
                return MetaAction.LANE_LEFT
        if (
            not blocked
            and ready
            and valid[2]
            and valid[3]
            and self._free(veh, LaneCode.RIGHT, self.right_clear)
        ):
            self._since = 0
            return MetaAction.LANE_RIGHT
        if lead is not None and lead[0] - VEHICLE_LENGTH < 0.5 * self.front_gap and lead[1] < 0:
            return MetaAction.SLOWER
        if lead is None or lead[0] - VEHICLE_LENGTH > 2 * self.front_gap:
            return MetaAction.FASTER
        return MetaAction.IDLE

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray | np.int64, Any]:
        """``(action, state)`` as SB3's ``predict``; batched observations give a batch.

        A batch shares one cooldown counter; use one instance per environment for
        vectorised evaluation.
        """
        if episode_start is not None and np.any(episode_start):
            self.reset()
        if _batched(observation):
            n = np.asarray(observation["ego"]).shape[0]
            return np.array([self.act(_unbatch(observation, i)) for i in range(n)]), state
        return np.int64(self.act(observation)), state
