"""The reward: the overtaking term (vehicles passed minus passed by) and the
normalisation over each term's range."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from aldm_gym import ENV_ID
from aldm_gym.agents.policies import RuleBasedLCA
from aldm_gym.envs import outcome
from aldm_gym.envs.config import EnvConfig


class _Car:
    """A vehicle as the outcome reads it (hashable by identity, as highway-env's)."""

    def __init__(self, x: float, y: float, heading: float) -> None:
        self.position = np.array([x, y])
        self.heading = heading


def car(x: float, y: float, heading: float = 0.0) -> _Car:
    return _Car(x, y, heading)


def test_net_overtakes_counts_sign_changes_seen_at_both_times() -> None:
    before = {1: 5.0, 2: -3.0, 3: 2.0, 4: 1.0}
    after = {1: -1.0, 2: 2.0, 3: 1.0, 5: -2.0}  # 4 left the window, 5 entered it
    assert outcome.net_overtakes(before, after) == 0  # 1 passed (+1), 2 passed us (-1)
    assert outcome.net_overtakes({1: 0.5, 2: 3.0}, {1: -0.5, 2: -1.0}) == 2
    assert outcome.net_overtakes({1: -0.5}, {1: 0.0}) == 0  # level is not ahead
    assert outcome.net_overtakes({1: 0.1}, {1: 0.0}) == 1


def test_passing_positions_are_along_the_ego_heading_within_the_window() -> None:
    reach, side = outcome.PASSING_WINDOW
    ego = car(100.0, 50.0, heading=math.pi / 2)  # driving towards +y
    others = [
        car(100.0, 60.0),  # 10 m ahead
        car(96.0, 45.0),  # 5 m behind, one lane to the side
        car(100.0, 50.0 + reach + 1.0),  # too far ahead
        car(100.0 + side + 1.0, 50.0),  # too far to the side
    ]
    got = outcome.passing_positions(ego, [ego, *others])
    assert set(got) == {others[0], others[1]}
    assert got[others[0]] == pytest.approx(10.0)
    assert got[others[1]] == pytest.approx(-5.0)


def terms(**values: float) -> dict[str, float]:
    base = dict.fromkeys(outcome.REWARD_TERMS, 0.0)
    return {**base, **values}


def test_normalisation_spans_each_terms_range() -> None:
    settings = EnvConfig(overtaking_reward=0.4, collision_reward=-2.0)
    worst = terms(collision_reward=1.0, departure_reward=1.0, overtaking_reward=-1.0)
    best = terms(
        high_speed_reward=1.0,
        progress_reward=1.0,
        lane_keeping_reward=1.0,
        overtaking_reward=1.0,
    )
    assert outcome.reward(settings, worst) == pytest.approx(0.0)
    assert outcome.reward(settings, best) == pytest.approx(1.0)
    # Without the term (weight 0, the default) the map is the one of the weights' signs.
    default = EnvConfig()
    neg = default.collision_reward + default.departure_reward
    pos = default.high_speed_reward + default.progress_reward + default.lane_keeping_reward
    plain = terms(high_speed_reward=0.5, lane_keeping_reward=1.0, overtaking_reward=1.0)
    total = 0.5 * default.high_speed_reward + default.lane_keeping_reward
    assert outcome.reward(default, plain) == pytest.approx((total - neg) / (pos - neg))


def test_overtaking_term_in_episodes() -> None:
    """The rule-based LCA passes vehicles: the term is +1 at some step of 3 episodes,
    every term is in its range and the normalised reward in [0, 1]."""
    env = gym.make(ENV_ID, config={"overtaking_reward": 0.5, "duration": 30})
    seen, rewards = [], []
    for seed in (10001, 10005, 10006):
        obs, _ = env.reset(seed=seed)
        policy, done = RuleBasedLCA(), False
        while not done:
            obs, reward, terminated, truncated, info = env.step(policy.predict(obs)[0])
            done = terminated or truncated
            seen.append(info["rewards"]["overtaking_reward"])
            rewards.append(reward)
    env.close()
    assert set(seen) <= {-1.0, 0.0, 1.0} and 1.0 in seen
    assert 0.0 <= min(rewards) and max(rewards) <= 1.0


def test_lane_keeping_term_on_a_lane_of_no_width() -> None:
    """Half the lane width divides the offset: a lane of no width (the tip of a lane
    that opens) gives the term 0, not a ZeroDivisionError; a lane 3.5 m wide the
    usual share."""
    from types import SimpleNamespace

    from aldm_gym.roads.position import LanePosition

    ego = SimpleNamespace(speed=25.0, heading=0.0, crashed=False)
    terms = {}
    for width in (0.0, 3.5):
        pos = LanePosition(
            s=10.0,
            offset=0.35,
            lane=("1", 0, -1),
            index=0,
            lanes=1,
            width=width,
            heading=0.0,
            end=100.0,
        )
        terms[width] = outcome.reward_terms(EnvConfig(), ego, pos, 9.0, False, False)
    assert terms[0.0]["lane_keeping_reward"] == 0.0
    assert terms[3.5]["lane_keeping_reward"] == pytest.approx(1.0 - 0.35 / 1.75)
    assert all(math.isfinite(v) for v in terms[0.0].values())
