"""Rule-based policies on scripted observations: known vehicles and lines, known actions."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest

from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA
from aldm_gym.envs.actions import MetaAction
from aldm_gym.envs.observation import VEHICLE_LENGTH, LaneCode

ALL_LINES = (1, 1, 1, 1)
"""``line_valid`` with every line detected (left_adjacent, ego_left, ego_right,
right_adjacent)."""


def observation(
    vehicles: Sequence[tuple[float, float, LaneCode]] = (),
    line_valid: tuple[int, int, int, int] = ALL_LINES,
    lane_change: float = 0.0,
    speed: float = 25.0,
    rows: int = 6,
) -> dict[str, Any]:
    """A hand-built observation: ``vehicles`` as ``(x [m], relative vx [m/s], lane code)``;
    only the keys the rule-based policies read, with the env's shapes and dtypes."""
    veh = np.zeros((rows, 6), dtype=np.float32)
    for i, (x, vx, lane) in enumerate(vehicles):
        veh[i] = (1.0, x, 0.0, vx, 0.0, float(lane))
    return {
        "ego": np.array([speed, 0.0, 0.0, lane_change], dtype=np.float32),
        "line_valid": np.asarray(line_valid, dtype=np.float32),
        "vehicles": veh,
    }


def act(obs: dict[str, Any], policy: RuleBasedLCA | None = None) -> MetaAction:
    action, _ = (policy or RuleBasedLCA()).predict(obs, deterministic=True)
    assert np.shape(action) == ()
    return MetaAction(int(action))


BLOCKED = (30.0, -3.0, LaneCode.EGO)
"""A slower vehicle 25 m ahead (bumper to bumper) in the ego lane."""


def test_blocked_ego_lane_and_free_left_lane_overtakes_left() -> None:
    assert act(observation([BLOCKED])) == MetaAction.LANE_LEFT
    # A vehicle in the right lane or beyond the detected lanes does not matter.
    others = [BLOCKED, (5.0, 0.0, LaneCode.RIGHT), (-10.0, 0.0, LaneCode.OTHER)]
    assert act(observation(others)) == MetaAction.LANE_LEFT


def test_close_but_not_slower_lead_is_also_a_reason_to_overtake() -> None:
    close = (VEHICLE_LENGTH + 30.0, 0.0, LaneCode.EGO)  # 30 m gap < front_gap 40 m
    assert act(observation([close])) == MetaAction.LANE_LEFT
    far = (VEHICLE_LENGTH + 60.0, 0.0, LaneCode.EGO)  # neither close nor slower
    assert act(observation([far], line_valid=(1, 1, 0, 0))) == MetaAction.IDLE


def test_lane_change_under_way_keeps_idle() -> None:
    for direction in (1.0, -1.0):
        assert act(observation([BLOCKED], lane_change=direction)) == MetaAction.IDLE
        assert act(observation([], lane_change=direction)) == MetaAction.IDLE


def test_free_right_lane_returns_right() -> None:
    assert act(observation([])) == MetaAction.LANE_RIGHT
    # Vehicles in the right lane far outside the window (25 m behind, 70 m ahead).
    far = [(120.0, 0.0, LaneCode.RIGHT), (-60.0, -2.0, LaneCode.RIGHT)]
    assert act(observation(far)) == MetaAction.LANE_RIGHT


def test_occupied_right_lane_keeps_the_lane() -> None:
    beside = [(10.0, 0.0, LaneCode.RIGHT)]
    # Nothing ahead in the ego lane: speed up instead.
    assert act(observation(beside)) == MetaAction.FASTER
    # A faster vehicle closing in from behind on the right: its gap 35 m is less than
    # closing_time (3 s) x 15 m/s + 5 m.
    closing = [(-40.0, 15.0, LaneCode.RIGHT)]
    assert act(observation(closing)) == MetaAction.FASTER


def test_undetected_lines_forbid_lane_changes() -> None:
    # Left adjacent line missing: no overtaking (the env would refuse it).
    assert act(observation([BLOCKED], line_valid=(0, 1, 1, 1))) != MetaAction.LANE_LEFT
    # Right adjacent line missing (rightmost lane): no return to the right.
    assert act(observation([], line_valid=(1, 1, 1, 0))) == MetaAction.FASTER


def test_occupied_left_lane_blocks_overtaking() -> None:
    beside = [BLOCKED, (0.0, 0.0, LaneCode.LEFT)]
    assert act(observation(beside)) == MetaAction.IDLE
    # A faster vehicle approaching from behind on the left.
    closing = [BLOCKED, (-40.0, 15.0, LaneCode.LEFT)]
    assert act(observation(closing)) == MetaAction.IDLE
    # The left lane's leader, outside the window, is hardly further ahead than ours
    # (less than 10 m): no gain in overtaking; 10 m more and the policy goes.
    lead = (40.0, -3.0, LaneCode.EGO)
    assert act(observation([lead, (48.0, -3.0, LaneCode.LEFT)])) == MetaAction.IDLE
    assert act(observation([lead, (58.0, -3.0, LaneCode.LEFT)])) == MetaAction.LANE_LEFT


def test_close_slower_lead_without_a_gap_slows_down() -> None:
    lead = (VEHICLE_LENGTH + 15.0, -2.0, LaneCode.EGO)  # 15 m < front_gap / 2
    assert act(observation([lead], line_valid=(0, 1, 1, 0))) == MetaAction.SLOWER


def test_cooldown_between_lane_changes_and_reset() -> None:
    policy = RuleBasedLCA(cooldown=4)
    obs = observation([BLOCKED])
    assert act(obs, policy) == MetaAction.LANE_LEFT
    # The next cooldown - 1 steps keep the lane although the situation is unchanged.
    assert [act(obs, policy) for _ in range(3)] == [MetaAction.IDLE] * 3
    assert act(obs, policy) == MetaAction.LANE_LEFT
    act(obs, policy)
    policy.reset()
    assert act(obs, policy) == MetaAction.LANE_LEFT
    # episode_start in predict resets the cooldown too.
    action, _ = policy.predict(obs, episode_start=np.array([True]))
    assert action == MetaAction.LANE_LEFT


def _batch(*observations: dict[str, Any]) -> dict[str, Any]:
    return {k: np.stack([o[k] for o in observations]) for k in observations[0]}


def test_batched_observations_give_a_batch_of_actions() -> None:
    batch = _batch(observation([BLOCKED]), observation([], lane_change=1.0), observation([]))
    # A batch shares one cooldown counter: without a cooldown, rows are independent.
    actions, state = RuleBasedLCA(cooldown=0).predict(batch, state="s")
    assert state == "s"
    assert actions.tolist() == [MetaAction.LANE_LEFT, MetaAction.IDLE, MetaAction.LANE_RIGHT]


@pytest.mark.parametrize("n", [1, 3])
def test_idle_policy_batched_and_single(n: int) -> None:
    policy = IdlePolicy()
    single, state = policy.predict(observation([BLOCKED]), state=None)
    assert single == MetaAction.IDLE and np.shape(single) == () and state is None
    batch = _batch(*[observation([BLOCKED])] * n)
    actions, _ = policy.predict(batch)
    assert actions.shape == (n,)
    assert (actions == MetaAction.IDLE).all()
