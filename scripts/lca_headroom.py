"""How much faster than the rule-based LCA can a lane-change policy be on this task?

Plays hand-tuned variants of :class:`~aldm_gym.agents.policies.RuleBasedLCA` (more
eager to overtake, no keep-right rule, both) and IDLE on the evaluation seeds of
docs/results.md (b) (10000.., per-dash roads, the detector given) and prints, as a
markdown table, each one's mean speed, collisions and departures per km, and its
per-episode mean speed difference to the default rule-based LCA with the 95 % CI
(paired Student's t) and the exact paired test on collisions. A learned policy's lead
is read against these: a variant that changes only the rules shows how much speed the
traffic leaves to be won by lane changes at all.

Run: ``.venv/bin/python scripts/lca_headroom.py --detector aldm --episodes 30``
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import gymnasium as gym  # noqa: E402
from tqdm import tqdm  # noqa: E402

from aldm_gym import ENV_ID  # noqa: E402
from aldm_gym.agents.episodes import EpisodeStats, run_episodes, summarize  # noqa: E402
from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA  # noqa: E402
from aldm_gym.envs.actions import MetaAction  # noqa: E402
from aldm_gym.training.model_evaluation import collision_test, paired_difference  # noqa: E402
from aldm_gym.training.settings import env_config  # noqa: E402

EVALUATION_SEED = 10_000
"""First seed of the evaluation episodes (as ``aldm-gym evaluate``)."""


@dataclasses.dataclass
class NoKeepRight(RuleBasedLCA):
    """The rule-based LCA without the keep-right rule: it moves right only to pass a
    slower or close vehicle ahead when the left is not free (an overtake on the right,
    which German and Austrian motorways forbid)."""

    def act(self, observation: dict[str, Any]) -> int:
        """The rule-based action, with its returns to the right left out."""
        action = super().act(observation)
        if action == MetaAction.LANE_RIGHT:
            self._since = self.cooldown  # the command was not given
            return MetaAction.IDLE
        return action


class AlwaysFaster:
    """No lane changes, ACC set speed raised to the highest target speed (FASTER)."""

    def predict(self, observation: Any, **_: Any) -> tuple[int, None]:
        """FASTER, always."""
        return int(MetaAction.FASTER), None


def traffic_speeds(env: Any, seeds: range) -> list[float]:
    """The other vehicles' target speeds at the start of each episode [m/s]."""
    speeds = []
    for seed in seeds:
        env.reset(seed=seed)
        road = env.unwrapped.road
        speeds += [float(v.target_speed) for v in road.vehicles if v is not env.unwrapped.vehicle]
    return speeds


def variants() -> dict[str, Any]:
    """The policies compared, by name (the default rule-based LCA first)."""
    eager = {"front_gap": 60.0, "slower_by": 0.5, "left_clear": (15.0, 30.0), "cooldown": 2}
    return {
        "rule-based LCA": RuleBasedLCA(),
        "eager": RuleBasedLCA(**eager),
        "no keep-right": NoKeepRight(),
        "eager, no keep-right": NoKeepRight(**eager),
        "IDLE, set speed 30 m/s (FASTER)": AlwaysFaster(),
        "IDLE": IdlePolicy(),
    }


def main() -> int:
    """Play the variants and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--detector", default="aldm", choices=("aldm", "naive", "ground_truth"))
    parser.add_argument("--episodes", type=int, default=30)
    args = parser.parse_args()
    env = gym.make(ENV_ID, config=env_config(detector=args.detector, marking_model="per_dash"))
    seeds = range(EVALUATION_SEED, EVALUATION_SEED + args.episodes)
    traffic = traffic_speeds(env, seeds)
    played: dict[str, list[EpisodeStats]] = {}
    for name, policy in variants().items():
        with tqdm(total=len(seeds), desc=name, unit="ep", leave=False) as bar:
            played[name] = run_episodes(env, policy, seeds, bar.update)
    env.close()

    base = played["rule-based LCA"]
    speed = {n: [statistics.fmean(e.speeds) for e in eps] for n, eps in played.items()}
    print(
        f"{args.episodes} episodes (seeds {seeds[0]}–{seeds[-1]}), {args.detector} detection, "
        f"per-dash roads; the other vehicles' target speeds {min(traffic):.1f}–"
        f"{max(traffic):.1f} m/s (mean {statistics.fmean(traffic):.1f}), the ego's 25 m/s "
        "at the start\n"
    )
    print(
        "| policy | mean_speed | lane_changes ok / failed | departures_per_km | collisions "
        "| − rule-based LCA [m/s] | collisions (p vs rule-based) |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, eps in played.items():
        s = summarize(eps)
        mean, lo, hi = paired_difference(speed[name], speed["rule-based LCA"])
        p = collision_test([e.collided for e in eps], [e.collided for e in base])
        print(
            f"| {name} | {s['mean_speed']:.2f} | {s['lane_changes_ok']:.0f} / "
            f"{s['lane_changes_failed']:.0f} | {s['departures_per_km']:.2f} | "
            f"{s['collisions']:.0f} | {mean:+.2f} ({lo:+.2f} … {hi:+.2f}) | "
            f"{sum(e.collided for e in eps)} vs {sum(e.collided for e in base)} (p = {p:.2f}) |"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
