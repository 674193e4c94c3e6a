"""The tables and figure of docs/results.md (b) for a set of trainings.

Given training folders named ``<detector>_s<seed>`` under ``--root`` (written by
``aldm-gym train``), it evaluates each kept model (``aldm-gym evaluate --model <folder>
--episodes 30``: seeds 10000-10029, IDLE and the rule-based LCA on the same seeds; an
evaluation already on disk is reused) and, with ``--cross``, the ALDM-trained models on
naive detection too; then prints, as markdown:

* one row per policy: success rate, mean speed, lane changes ok / failed, departures
  per km, collisions, target accuracy;
* per training, the paired per-episode differences of mean speed against IDLE and the
  rule-based LCA with their 95 % CIs (Student's t), and the paired exact test on
  collisions; the median training seed per detector (by the difference against the
  rule-based LCA);

and draws the learning curves (each training's validations) to ``--figure``.

Run: ``.venv/bin/python scripts/policy_results.py --root out/rl6 --cross
--figure docs/img/learning_curves_maskable.png``
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from aldm_gym.training.model_evaluation import collision_test, paired_difference  # noqa: E402

NAMES = {"aldm": "ALDM", "naive": "naive", "ground_truth": "ground truth"}
RUN = re.compile(r"^(?P<detector>[a-z_]+)_s(?P<seed>\d+)$")


def evaluation(folder: Path, detector: str, episodes: int) -> dict[str, Any]:
    """The evaluation of a training's kept model on ``detector``, run if not on disk."""
    path = folder / f"evaluate_best_model_{detector}_per_dash.json"
    if not path.exists():
        cmd = [sys.executable, "-m", "aldm_gym", "evaluate", "--model", str(folder)]
        cmd += ["--episodes", str(episodes), "--detector", detector, "--no-progress"]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return json.loads(path.read_text())


def _ci(a: list[float], b: list[float]) -> str:
    mean, lo, hi = paired_difference(a, b)
    return f"{mean:+.2f} ({lo:+.2f} … {hi:+.2f})"


def main() -> None:
    """Parse the arguments, evaluate, print the tables, draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, required=True, help="folder of the trainings")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--cross", action="store_true", help="ALDM-trained models on naive too")
    parser.add_argument("--figure", type=Path, default=None, help="learning curves (png)")
    parser.add_argument("--label", default="MaskablePPO", help="the policies' name")
    args = parser.parse_args()

    runs: dict[str, list[tuple[int, Path]]] = {}
    for folder in sorted(args.root.iterdir()):
        m = RUN.match(folder.name)
        if m and (folder / "training.json").exists():
            runs.setdefault(m["detector"], []).append((int(m["seed"]), folder))

    header = (
        "| observations | policy | kept at | success_rate | mean_speed | "
        "lane_changes ok / failed | departures_per_km | collisions | target_accuracy |"
    )
    rows = [header, "|" + "---|" * 9]
    diffs = [
        "| run | − IDLE [m/s] | − rule-based LCA [m/s] | collisions (p vs rule-based) |",
        "|---|---|---|---|",
    ]
    medians = []
    curves: dict[str, list[tuple[str, dict[str, Any]]]] = {}

    def add(detector: str, label: str, result: dict[str, Any], baselines: bool) -> None:
        by = {r["policy"]: r for r in result["rows"]}
        names = (("idle", "IDLE"), ("rule_based", "rule-based LCA")) if baselines else ()
        for key, name in (*names, ("model", label)):
            r = by[key]
            kept = str(result["timesteps"]) if key == "model" else "–"
            rows.append(
                f"| {NAMES[detector]} | {name} | {kept} | {r['success_rate']:.3f} | "
                f"{r['mean_speed']:.2f} | {r['lane_changes_ok']} / {r['lane_changes_failed']} | "
                f"{r['departures_per_km']:.2f} | {r['collisions']} | "
                f"{r['target_accuracy']:.3f} |"
            )
        per = result["per_episode"]
        p = collision_test(per["model"]["collided"], per["rule_based"]["collided"])
        diffs.append(
            f"| {label} on {NAMES[detector]} | "
            f"{_ci(per['model']['mean_speed'], per['idle']['mean_speed'])} | "
            f"{_ci(per['model']['mean_speed'], per['rule_based']['mean_speed'])} | "
            f"{sum(per['model']['collided'])} vs {sum(per['rule_based']['collided'])} "
            f"(p = {p:.2f}) |"
        )

    for detector, items in sorted(runs.items()):
        gains = []
        for i, (seed, folder) in enumerate(sorted(items)):
            result = evaluation(folder, detector, args.episodes)
            add(detector, f"seed {seed}", result, baselines=i == 0)
            per = result["per_episode"]
            gains.append(
                (
                    paired_difference(per["model"]["mean_speed"], per["rule_based"]["mean_speed"])[
                        0
                    ],
                    seed,
                )
            )
            validation = folder / "validation.json"
            if validation.exists():
                curves.setdefault(NAMES[detector], []).append(
                    (f"seed {seed}", json.loads(validation.read_text()))
                )
        median = statistics.median_low(gains)
        medians.append(f"{NAMES[detector]}: seed {median[1]} ({median[0]:+.2f} m/s)")
    if args.cross:
        for seed, folder in sorted(runs.get("aldm", [])):
            add(
                "naive",
                f"ALDM-trained seed {seed}",
                evaluation(folder, "naive", args.episodes),
                baselines=False,
            )
    print("\n".join(rows))
    print()
    print("\n".join(diffs))
    print()
    print(
        "median training seed (by the speed difference against the rule-based LCA): "
        + "; ".join(medians)
    )
    if args.figure is not None and curves:
        from aldm_gym.agents.figures import plot_learning_curves

        plot_learning_curves(curves, args.figure, label=args.label)
        print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
