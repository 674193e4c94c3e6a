"""A trained model against the rule-based policies: ``aldm-gym evaluate``.

:func:`evaluate` plays a trained model, :class:`~aldm_gym.agents.policies.RuleBasedLCA`
and :class:`~aldm_gym.agents.policies.IdlePolicy` on the same seeds with
:func:`~aldm_gym.agents.evaluation.run_episodes`; :func:`summary_line` says in one
sentence how the model compares. The environment and the policies are imported when
:func:`evaluate` runs: the command line reads :data:`EVALUATION_SEED` to build its parser.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aldm_gym import ENV_ID
from aldm_gym.agents.checkpoints import load_policy
from aldm_gym.agents.training import env_config

EVALUATION_SEED = 10_000
"""First seed of the evaluation episodes (training envs use ``0 ..``, validation 20000..)."""

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
:func:`~aldm_gym.agents.evaluation.summarize`)."""


def evaluate(
    model_path: Path,
    episodes: int = 30,
    seed: int = EVALUATION_SEED,
    detector: str | None = None,
    marking_model: str | None = None,
    progress: bool = True,
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Evaluate a model against IDLE and the rule-based LCA on the same seeds.

    :param episodes: episodes per policy (seeds ``seed .. seed + episodes - 1``).
    :param detector, marking_model: override the training env's (None: as trained).
    :return: rows (``idle``, ``rule_based``, ``model``) with the
        :func:`~aldm_gym.agents.evaluation.summarize` metrics and ``policy``; and the
        evaluation's env config and model metadata.
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    """
    import gymnasium as gym
    from tqdm import tqdm

    from aldm_gym.agents.evaluation import run_episodes, summarize
    from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA

    policy, meta = load_policy(model_path)
    config = dict(meta["env_config"])
    if detector is not None:
        config["detector"] = env_config(detector=detector)["detector"]
    if marking_model is not None:
        config["marking_model"] = env_config(marking_model=marking_model)["marking_model"]
    env = gym.make(ENV_ID, config=config)
    seeds = range(seed, seed + episodes)
    rows = []
    try:
        with tqdm(total=3 * episodes, desc="evaluate", unit="ep", disable=not progress) as bar:
            for name, pol in (("idle", IdlePolicy()), ("rule_based", RuleBasedLCA())):
                rows.append(
                    {"policy": name, **summarize(run_episodes(env, pol, seeds, bar.update))}
                )
            rows.append(
                {"policy": "model", **summarize(run_episodes(env, policy, seeds, bar.update))}
            )
    finally:
        env.close()
    info = {
        "env_config": config,
        "trained_on": meta["env_config"],
        "timesteps": int(policy.model.num_timesteps),
        "seeds": [seed, seed + episodes - 1],
    }
    return rows, info


def summary_line(rows: list[dict[str, Any]], info: dict[str, Any]) -> str:
    """One sentence on the model against IDLE and the rule-based LCA.

    :param rows, info: what :func:`evaluate` returns.
    """
    by = {r["policy"]: r for r in rows}
    m, idle, rule = by["model"], by["idle"], by["rule_based"]
    dv = m["mean_speed"] - idle["mean_speed"]
    if dv > 0 and m["collisions"] <= idle["collisions"]:
        verdict = "beats IDLE on speed without more collisions"
    elif dv > 0:
        verdict = "is faster than IDLE but collides more"
    else:
        verdict = "is not faster than IDLE"
    trained = info["trained_on"]
    cfg = info["env_config"]
    return (
        f"model ({info['timesteps']} steps, trained on {trained['detector']}/"
        f"{trained['marking_model']}, evaluated on {cfg['detector']}/{cfg['marking_model']}, "
        f"{m['episodes']} episodes) {verdict}: success {m['success_rate']:.0%} "
        f"(IDLE {idle['success_rate']:.0%}, rule-based {rule['success_rate']:.0%}), "
        f"mean speed {m['mean_speed']:.1f} m/s ({dv:+.1f} vs IDLE, "
        f"{m['mean_speed'] - rule['mean_speed']:+.1f} vs rule-based), "
        f"collisions {m['collisions']} (IDLE {idle['collisions']}, rule-based "
        f"{rule['collisions']}), lane changes {m['lane_changes_ok']} ok / "
        f"{m['lane_changes_failed']} failed"
    )
