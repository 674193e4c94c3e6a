"""The episode runner and its metrics, on scripted episodes with known outcomes."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from aldm_gym.agents.episodes import EpisodeStats, run_episode, summarize
from aldm_gym.envs.actions import MetaAction


class _Unwrapped:
    def __init__(self) -> None:
        self.config = {"policy_frequency": 1}


class ScriptedEnv:
    """A stand-in env replaying scripted ``info`` dicts (one per step)."""

    def __init__(self, infos: list[dict[str, Any]]) -> None:
        self.unwrapped = _Unwrapped()
        self.infos = infos
        self.i = 0

    @staticmethod
    def _info(**kw: Any) -> dict[str, Any]:
        det = {"mean_abs_error": 0.01, "preview": 190.0, "correct": 1.0}
        base = {
            "distance": 0.0,
            "lane_index": 1,
            "lane_changes_completed": 0,
            "lane_changes_aborted": 0,
            "lane_change": 0,
            "lane_change_refused": False,
            "speed": 25.0,
            "lane_departure": False,
            "crashed": False,
            "lateral_offset": 0.0,
            "detection": {"ego_left": dict(det), "ego_right": dict(det)},
        }
        base.update(kw)
        return base

    def reset(self, seed: int | None = None) -> tuple[dict, dict]:
        self.i = 0
        return {}, self._info()

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        info = self.infos[self.i]
        self.i += 1
        return {}, 1.0, False, self.i == len(self.infos), info


class ScriptedPolicy:
    def __init__(self, actions: list[int]) -> None:
        self.actions = actions
        self.i = 0

    def predict(self, obs: Any, state: Any = None, deterministic: bool = True) -> tuple:
        a = self.actions[self.i]
        self.i += 1
        return np.int64(a), state


def test_known_departures_offsets_and_distance() -> None:
    mk = ScriptedEnv._info
    infos = [
        mk(distance=25.0, lateral_offset=0.1),
        mk(distance=50.0, lateral_offset=-0.3, lane_departure=True),
        mk(distance=75.0, lateral_offset=0.2),
        mk(distance=100.0, lateral_offset=-1.2, lane_departure=True, crashed=True),
    ]
    st = run_episode(ScriptedEnv(infos), ScriptedPolicy([MetaAction.IDLE] * 4), seed=0)
    assert st.distance == 100.0 and st.steps == 4
    assert st.departures == 2 and st.collided and not st.success
    row = summarize([st])
    assert row["km"] == pytest.approx(0.1)
    assert row["departures_per_km"] == pytest.approx(20.0)
    assert row["rms_offset_m"] == pytest.approx(np.sqrt(np.mean([0.01, 0.09, 0.04, 1.44])))
    assert row["max_offset_m"] == pytest.approx(1.2)
    assert row["collisions"] == 1 and row["success_rate"] == 0.0


def test_lane_change_outcomes_are_judged_by_ground_truth() -> None:
    mk = ScriptedEnv._info
    infos = [
        # MetaAction.LANE_LEFT accepted, completes in lane 0: ok.
        mk(distance=25.0, lane_change=1, lane_index=1),
        mk(distance=50.0, lane_changes_completed=1, lane_index=0),
        # MetaAction.LANE_RIGHT refused: failed.
        mk(distance=75.0, lane_changes_completed=1, lane_index=0, lane_change_refused=True),
        # MetaAction.LANE_RIGHT accepted, aborted: failed.
        mk(distance=100.0, lane_changes_completed=1, lane_index=0, lane_change=-1),
        mk(distance=125.0, lane_changes_completed=1, lane_changes_aborted=1, lane_index=0),
        # MetaAction.LANE_RIGHT accepted, "completes" but ends two lanes over: failed.
        mk(distance=150.0, lane_changes_completed=1, lane_changes_aborted=1, lane_change=-1),
        mk(distance=175.0, lane_changes_completed=2, lane_changes_aborted=1, lane_index=2),
    ]
    actions = [
        MetaAction.LANE_LEFT,
        MetaAction.IDLE,
        MetaAction.LANE_RIGHT,
        MetaAction.LANE_RIGHT,
        MetaAction.IDLE,
        MetaAction.LANE_RIGHT,
        MetaAction.IDLE,
    ]
    st = run_episode(ScriptedEnv(infos), ScriptedPolicy(actions), seed=0)
    assert st.lane_changes_ok == 1
    assert st.lane_changes_failed == 3
    # Offsets are not collected while a change is under way.
    assert len(st.offsets) < st.steps


def test_both_correct_and_preview() -> None:
    mk = ScriptedEnv._info
    miss = {"mean_abs_error": float("nan"), "preview": float("nan"), "correct": 0.0}
    ok = {"mean_abs_error": 0.01, "preview": 100.0, "correct": 1.0}
    infos = [
        mk(distance=10.0, detection={"ego_left": ok, "ego_right": ok}),
        mk(distance=20.0, detection={"ego_left": ok, "ego_right": miss}),
    ]
    row = summarize(
        [
            run_episode(
                ScriptedEnv(infos), ScriptedPolicy([MetaAction.IDLE, MetaAction.IDLE]), seed=0
            )
        ]
    )
    assert row["both_correct"] == 0.5
    assert row["mean_preview_m"] == pytest.approx((100 + 100 + 100 + 0) / 4)


def test_summarize_needs_episodes() -> None:
    with pytest.raises(ValueError, match="at least one"):
        summarize([])
    assert EpisodeStats(seed=0).success
