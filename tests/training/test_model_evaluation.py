"""``aldm-gym evaluate``'s verdict states its uncertainty: paired speed interval, exact
collision test, "inconclusive" under MIN_EPISODES episodes."""

from __future__ import annotations

import math
from typing import Any

import pytest

from aldm_gym.training.model_evaluation import (
    MIN_EPISODES,
    collision_test,
    paired_difference,
    verdict,
)


def _info(
    model_speed: list[float], idle_speed: list[float], model_hit: set[int], idle_hit: set[int]
) -> dict[str, Any]:
    n = len(model_speed)
    return {
        "per_episode": {
            "model": {"mean_speed": model_speed, "collided": [i in model_hit for i in range(n)]},
            "idle": {"mean_speed": idle_speed, "collided": [i in idle_hit for i in range(n)]},
        }
    }


def test_paired_difference_is_students_t_interval() -> None:
    mean, lo, hi = paired_difference([2.0, 4.0, 6.0], [1.0, 2.0, 3.0])
    # Differences 1, 2, 3: mean 2, sd 1, t(0.975, 2) = 4.3027.
    assert mean == 2.0
    assert hi - mean == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    assert mean - lo == pytest.approx(hi - mean)
    assert paired_difference([1.0], [0.0]) == (1.0, -math.inf, math.inf)
    with pytest.raises(ValueError, match="equally many"):
        paired_difference([1.0, 2.0], [1.0])


def test_collision_test_counts_only_discordant_episodes() -> None:
    assert collision_test([True, False], [True, False]) == 1.0  # no discordant episode
    assert collision_test([False] * 3, [True] * 3) == pytest.approx(0.25)
    # 4 vs 7 collisions in 30 episodes can never be told apart at the 5 % level.
    assert collision_test([i < 4 for i in range(30)], [4 <= i < 11 for i in range(30)]) > 0.5
    assert collision_test([i < 10 for i in range(30)], [False] * 30) < 0.01


def test_few_episodes_are_inconclusive_whatever_the_numbers() -> None:
    n = MIN_EPISODES - 1
    text = verdict(_info([30.0 + 0.1 * i for i in range(n)], [20.0] * n, set(), set(range(n))))
    assert text.startswith(f"is inconclusive against IDLE: {n} episodes are too few")
    assert "95% CI" in text and "p = " in text


def test_verdict_calls_differences_only_when_the_data_support_them() -> None:
    n = 30
    faster = [25.0 + 0.1 * (i % 3) for i in range(n)]
    idle = [24.0] * n
    text = verdict(_info(faster, idle, {0, 1, 2, 3}, {4, 5, 6, 7, 8, 9, 10}))
    assert text.startswith("is faster than IDLE with no significant difference in collisions")
    assert "collisions in 4 vs 7 of 30 episodes" in text
    text = verdict(_info(faster, idle, set(range(10)), set()))
    assert text.startswith("is faster than IDLE with more collisions")
    noisy = [24.0 + (1.0 if i % 2 else -0.9) for i in range(n)]
    assert verdict(_info(noisy, idle, set(), set())).startswith(
        "is not measurably faster or slower than IDLE"
    )
    assert verdict(_info([23.0] * n, idle, set(), set(range(10)))).startswith(
        "is slower than IDLE with fewer collisions"
    )


def test_verdict_against_the_rule_based_lca() -> None:
    n = 30
    info = _info([25.0 + 0.1 * (i % 3) for i in range(n)], [24.0] * n, set(), set())
    info["per_episode"]["rule_based"] = {"mean_speed": [26.0] * n, "collided": [False] * n}
    text = verdict(info, "rule_based")
    assert text.startswith("is slower than the rule-based LCA with no significant difference")
    assert "vs the rule-based LCA" in text
    assert verdict(info).startswith("is faster than IDLE")
    with pytest.raises(ValueError, match=r"unknown baseline 'rule'.*idle.*rule_based"):
        verdict(info, "rule")
