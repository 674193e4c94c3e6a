"""A trained model against the rule-based policies: ``aldm-gym evaluate``.

:func:`evaluate` plays a trained model, :class:`~aldm_gym.agents.policies.RuleBasedLCA`
and :class:`~aldm_gym.agents.policies.IdlePolicy` on the same seeds with
:func:`~aldm_gym.agents.episodes.run_episodes`; :func:`summary_line` says in one
sentence how the model compares, with its uncertainty.

The verdict is paired on the seeds (every policy drives the same episodes):

* speed: the mean of the per-episode differences of mean speed (model − IDLE) with a
  95 % confidence interval from Student's t (:func:`paired_difference`); the model is
  called faster or slower only when the interval excludes 0;
* collisions: the episodes where only one of the two collided decide (McNemar's exact
  test, :func:`collision_test`); "fewer" or "more" only when p < 0.05;
* under :data:`MIN_EPISODES` episodes the verdict is "inconclusive" whatever the
  numbers (collisions are rare events: 3 episodes cannot tell 10 % from 30 %).

The environment and the policies are imported when :func:`evaluate` runs: the command
line reads :data:`EVALUATION_SEED` to build its parser.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from aldm_gym import ENV_ID
from aldm_gym.envs.config import EnvOverrides, env_overrides, merged_config
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.training.models import load_policy
from aldm_gym.training.settings import NAMED_ENV_KEYS, dotted_settings

EVALUATION_SEED = 10_000
"""First seed of the evaluation episodes (training envs use ``0 ..``, validation 20000..)."""

MIN_EPISODES = 20
"""Fewest episodes for which :func:`summary_line` gives a verdict (else "inconclusive")."""

CONFIDENCE = 0.95
"""Confidence level of the interval on the speed difference."""

SIGNIFICANCE = 0.05
"""Largest p-value of :func:`collision_test` for which collisions are called fewer/more."""

EVAL_COLUMNS = (
    "policy",
    "success_rate",
    "mean_speed",
    "lane_changes_ok",
    "lane_changes_failed",
    "departures_per_km",
    "collisions",
)
"""Columns of the evaluation table (metrics from
:func:`~aldm_gym.agents.episodes.summarize`)."""


PolicyFactory = Callable[[Any], Any]
"""Makes a policy for the env it will drive (a function under test needs the env)."""


def _idle(_env: Any) -> Any:
    from aldm_gym.agents.policies import IdlePolicy

    return IdlePolicy()


def _rule_based(_env: Any) -> Any:
    from aldm_gym.agents.policies import RuleBasedLCA

    return RuleBasedLCA()


RULE_BASED: tuple[tuple[str, PolicyFactory], ...] = (("idle", _idle), ("rule_based", _rule_based))
"""The rule-based policies every evaluation plays beside the one evaluated."""


def evaluate(
    model_path: Path,
    episodes: int = 30,
    seed: int = EVALUATION_SEED,
    detector: str | None = None,
    marking_model: str | None = None,
    progress: bool = True,
    env_overrides: Mapping[str, Any] | None = None,
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Evaluate a model against IDLE and the rule-based LCA on the same seeds.

    :param model_path: what :func:`~aldm_gym.training.models.load_policy` takes: a
        model ``.zip``, an RLlib checkpoint folder or a training's output folder.
    :param episodes: episodes per policy (seeds ``seed .. seed + episodes - 1``).
    :param detector, marking_model: override the training env's (None: as trained);
        another detector than trained drops the trained one's ``detector_params``.
    :param env_overrides: more env settings over the training's (merged as the env merges a
        config, e.g. ``{"sensor": {"preset": "camera"}}``); the policy's observation
        and action (``observation``, ``action``) stay as trained.
    :return: rows (``idle``, ``rule_based``, ``model``) with the
        :func:`~aldm_gym.agents.episodes.summarize` metrics and ``policy``; and the
        evaluation's env config, model metadata (``algorithm``: ``"PPO"`` or
        ``"MaskablePPO"``; ``timesteps``) and, per policy, each episode's mean
        speed [m/s] and whether it collided (``per_episode``, in seed order).
    :raises FileNotFoundError, CheckpointError: see
        :func:`~aldm_gym.training.models.load_policy`.
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    :raises ConfigError: ``env_overrides`` sets the observation or action, or a bad
        setting.
    """
    policy, record = load_policy(model_path)
    trained = record.env_config
    given = trained.to_dict()
    if detector is not None:
        if detector != trained.settings.detector:
            given.pop("detector_params", None)  # the trained detector's own parameters
        given["detector"] = detector
    if marking_model is not None:
        given["marking_model"] = marking_model
    if env_overrides:
        fixed = sorted(set(env_overrides) & {"observation", "action"})
        if fixed:
            raise ConfigError(
                f"{', '.join(fixed)}: the policy was trained on them; they stay as trained"
            )
        given = merged_config(given, env_overrides)
    config = EnvOverrides(given)  # checked once, before any episode
    rows, per_episode = play_policies(
        config,
        (*RULE_BASED, ("model", lambda _env: policy)),
        episodes=episodes,
        seed=seed,
        progress=progress,
    )
    info = {
        "env_config": config.to_dict(),
        "trained_on": trained.to_dict(),
        "timesteps": int(policy.num_timesteps),
        "algorithm": record.algorithm,
        "seeds": [seed, seed + episodes - 1],
        "per_episode": per_episode,
    }
    return rows, info


def play_policies(
    config: Mapping[str, Any],
    policies: Sequence[tuple[str, PolicyFactory]],
    *,
    episodes: int,
    seed: int,
    progress: bool = True,
) -> tuple[list[dict[str, Any]], dict[str, dict[str, list[Any]]]]:
    """Every policy on the same seeds ``seed .. seed + episodes - 1`` of one env.

    :param config: the env's settings (validated once here, if not yet).
    :param policies: ``(name, factory)`` pairs; ``factory(env)`` makes the policy.
    :return: one row per policy (``policy`` and the
        :func:`~aldm_gym.agents.episodes.summarize` metrics), and per policy each
        episode's mean speed [m/s] and whether it collided (``per_episode``).
    """
    import gymnasium as gym
    from tqdm import tqdm

    from aldm_gym.agents.episodes import run_episodes, summarize

    env = gym.make(ENV_ID, config=env_overrides(config))
    seeds = range(seed, seed + episodes)
    rows = []
    per_episode: dict[str, dict[str, list[Any]]] = {}
    total = len(policies) * episodes
    try:
        with tqdm(total=total, desc="evaluate", unit="ep", disable=not progress) as bar:
            for name, factory in policies:
                played = run_episodes(env, factory(env), seeds, bar.update)
                rows.append({"policy": name, **summarize(played)})
                per_episode[name] = {
                    "mean_speed": [_mean(e.speeds) for e in played],
                    "collided": [bool(e.collided) for e in played],
                }
    finally:
        env.close()
    return rows, per_episode


def _mean(values: list[float]) -> float:
    return float(sum(values) / len(values)) if values else float("nan")


def paired_difference(
    a: list[float], b: list[float], confidence: float = CONFIDENCE
) -> tuple[float, float, float]:
    """Mean of ``a[i] - b[i]`` and its confidence interval (Student's t, paired).

    :return: ``(mean, low, high)``; the interval is infinite for fewer than two pairs.
    """
    from scipy import stats

    if len(a) != len(b) or not a:
        raise InputError(f"paired_difference needs equally many values, got {len(a)}, {len(b)}")
    d = [x - y for x, y in zip(a, b, strict=True)]
    mean = _mean(d)
    if len(d) < 2:
        return mean, -math.inf, math.inf
    sd = math.sqrt(sum((x - mean) ** 2 for x in d) / (len(d) - 1))
    half = float(stats.t.ppf(0.5 + confidence / 2, len(d) - 1)) * sd / math.sqrt(len(d))
    return mean, mean - half, mean + half


def collision_test(a: list[bool], b: list[bool]) -> float:
    """p-value (two-sided) that ``a`` and ``b`` collide equally often, paired by episode.

    McNemar's exact test: only episodes where exactly one of the two collided count;
    under the hypothesis each such episode is ``a``'s with probability 1/2.
    """
    from scipy import stats

    only_a = sum(x and not y for x, y in zip(a, b, strict=True))
    only_b = sum(y and not x for x, y in zip(a, b, strict=True))
    if only_a + only_b == 0:
        return 1.0
    return float(stats.binomtest(only_a, only_a + only_b, 0.5).pvalue)


BASELINES: dict[str, str] = {"idle": "IDLE", "rule_based": "the rule-based LCA"}
"""The policies a model is compared with, by their ``per_episode`` key, and their names."""


def verdict(info: dict[str, Any], baseline: str = "idle") -> str:
    """How the model compares with a baseline policy (``"idle"`` or ``"rule_based"``),
    stating the uncertainty (see the module).

    :param info: what :func:`evaluate` returns (its ``per_episode``).
    :raises ConfigError: an unknown baseline (naming the allowed ones).
    """
    if baseline not in BASELINES:
        raise ConfigError(f"unknown baseline {baseline!r}; allowed: {sorted(BASELINES)}")
    name = BASELINES[baseline]
    model, base = info["per_episode"][_evaluated(info)], info["per_episode"][baseline]
    n = len(model["mean_speed"])
    dv, lo, hi = paired_difference(model["mean_speed"], base["mean_speed"])
    p = collision_test(model["collided"], base["collided"])
    cm, cb = sum(model["collided"]), sum(base["collided"])
    speed = (
        f"speed {dv:+.2f} m/s vs {name} ({CONFIDENCE:.0%} CI {lo:+.2f} to {hi:+.2f}, "
        "per-episode means on the same seeds)"
    )
    crashes = f"collisions in {cm} vs {cb} of {n} episodes (paired exact test p = {p:.2f})"
    if n < MIN_EPISODES:
        return (
            f"is inconclusive against {name}: {n} episodes are too few for a verdict "
            f"(at least {MIN_EPISODES}); "
            f"{speed}; {crashes}"
        )
    if lo > 0:
        pace = f"is faster than {name}"
    elif hi < 0:
        pace = f"is slower than {name}"
    else:
        pace = f"is not measurably faster or slower than {name}"
    if p < SIGNIFICANCE:
        safety = "with fewer collisions" if cm < cb else "with more collisions"
    else:
        safety = "with no significant difference in collisions"
    return f"{pace} {safety}: {speed}; {crashes}"


def _evaluated(info: dict[str, Any]) -> str:
    """The evaluated policy's row: ``model``, or ``function`` (a function under test)."""
    return "function" if "function" in info else "model"


def summary_line(rows: list[dict[str, Any]], info: dict[str, Any]) -> str:
    """The model (or function under test) against IDLE and the rule-based LCA: a
    :func:`verdict` against each, with its uncertainty, and the summary figures.

    :param rows, info: what :func:`evaluate` returns (or ``aldm-gym evaluate
        --function``'s rows, with ``info["function"]`` its SPEC).
    """
    by = {r["policy"]: r for r in rows}
    m, idle, rule = by[_evaluated(info)], by["idle"], by["rule_based"]
    cfg = info["env_config"]
    extra = ", ".join(
        f"{k}={json.dumps(v)}"
        for k, v in dotted_settings(cfg)
        if k.split(".", 1)[0] not in NAMED_ENV_KEYS
    )
    where = f"{cfg['detector']}/{cfg['marking_model']}{f' with {extra}' if extra else ''}"
    if "function" in info:
        head = f"function {info['function']} (on {where}, {m['episodes']} episodes)"
    else:
        trained = info["trained_on"]
        head = (
            f"model ({info['timesteps']} steps, trained on {trained['detector']}/"
            f"{trained['marking_model']}, evaluated on {where}, {m['episodes']} episodes)"
        )
    return (
        f"{head} {verdict(info)}; it "
        f"{verdict(info, 'rule_based')}. Success {m['success_rate']:.0%} "
        f"(IDLE {idle['success_rate']:.0%}, rule-based {rule['success_rate']:.0%}), "
        f"mean speed {m['mean_speed']:.1f} m/s (IDLE {idle['mean_speed']:.1f}, rule-based "
        f"{rule['mean_speed']:.1f}), collisions {m['collisions']} (IDLE {idle['collisions']}, "
        f"rule-based {rule['collisions']}), lane changes {m['lane_changes_ok']} ok / "
        f"{m['lane_changes_failed']} failed"
    )
