"""The OSC-ALKS suite with several functions under test on the camera preset, as one
table in docs/results.md (the block ``<!-- generated:functions -->``).

Each column is one ``aldm-gym scenario suite`` run (``--max-runs 6``, per-dash paint,
``sensor.preset=camera``): the built-in function on naive detection, the single-frame
ALDM and the lane-model filter; the lane-centering chauffeur of
``examples/lane_centering.py``; and, with ``--policy DIR``, a trained MaskablePPO
policy as the lane-change layer. Usage::

    python scripts/function_results.py --suite OSC-ALKS/logical_scenarios \\
        [--policy out/rl_record/aldm_s0] [--out out/results] [--jobs 2] [--reuse]

``--reuse`` reads a column's ``scenario_summary.csv`` where an earlier run left one.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results.md"
BLOCK = "functions"

CAMERA = ["--env", "sensor.preset=camera"]
COLUMNS: list[tuple[str, str, list[str]]] = [
    ("camera", "built-in, naive", ["--detectors", "naive,aldm"]),
    ("camera", "built-in, ALDM", []),
    ("camera_filter", "built-in, filter", ["--env", "detector_params.tracking=model"]),
    (
        "chauffeur",
        "lane-centering chauffeur (ALDM)",
        ["--function", "examples/lane_centering.py:LaneCenteringChauffeur"],
    ),
]
"""``(folder, column header, suite arguments)``; the first two share one run."""


def _suite(folder: Path, suite: Path, args: list[str], jobs: int) -> None:
    detectors = [] if "--detectors" in args else ["--detectors", "aldm"]
    cmd = [sys.executable, "-m", "aldm_gym", "scenario", "suite", str(suite), "--max-runs", "6"]
    cmd += ["--marking-models", "per_dash", *CAMERA, *detectors, *args]
    cmd += ["--jobs", str(jobs), "--no-progress", "--out", str(folder)]
    print(" ".join(cmd[2:]), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)


def _rows(folder: Path, detector: str) -> dict[str, dict[str, str]]:
    with (folder / "scenario_summary.csv").open() as f:
        return {r["scenario"]: r for r in csv.DictReader(f) if r["detector"] == detector}


def _cell(row: dict[str, str] | None) -> str:
    if row is None:
        return "–"
    runs = int(row["runs"])
    if runs == 0:
        return "not judged"
    rate = f"{100 * float(row['pass_rate']):.0f} %"
    kinds = (("collisions", "coll."), ("departure_runs", "dep."), ("gap_failures", "gap"))
    notes = [f"{row[key]} {label}" for key, label in kinds if int(row[key])]
    return rate + (f" ({', '.join(notes)})" if notes else "")


def _name(scenario: str) -> str:
    words = scenario.replace("alks_scenario_", "").replace("_template.xosc", "").split("_")
    return f"{words[0]}.{words[1]}_{words[2]} " + " ".join(words[3:])


def table(columns: list[tuple[str, dict[str, dict[str, str]]]]) -> str:
    """The markdown table: a row per scenario, a column per function, and the total."""
    scenarios = sorted({s for _, rows in columns for s in rows})
    head = "| scenario | runs | " + " | ".join(h for h, _ in columns) + " |"
    lines = [head, "|---|---:|" + "---:|" * len(columns)]
    for s in scenarios:
        runs = next(rows[s]["runs"] for _, rows in columns if s in rows)
        cells = " | ".join(_cell(rows.get(s)) for _, rows in columns)
        lines.append(f"| {_name(s)} | {runs} | {cells} |")
    totals = []
    for _, rows in columns:
        n = sum(int(r["runs"]) for r in rows.values())
        passed = sum(
            round(float(r["pass_rate"]) * int(r["runs"])) for r in rows.values() if int(r["runs"])
        )
        totals.append(f"{100 * passed / n:.0f} % ({passed}/{n})" if n else "–")
    n_runs = sum(int(r["runs"]) for r in columns[0][1].values())
    lines.append(f"| all | {n_runs} | " + " | ".join(totals) + " |")
    return "\n".join(lines)


def replace_block(text: str, name: str, content: str) -> str:
    """``text`` with the lines between ``<!-- generated:name -->`` and its end marker
    replaced by ``content``."""
    start, end = f"<!-- generated:{name} -->", f"<!-- /generated:{name} -->"
    if start not in text or end not in text:
        raise ValueError(f"no {start} block")
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n{content}\n{end}{tail}"


def main(argv: list[str] | None = None) -> None:
    """Run the suites (or reuse their summaries) and write the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--suite", type=Path, required=True, help="OSC-ALKS logical_scenarios")
    parser.add_argument("--policy", type=Path, help="a MaskablePPO training folder")
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "results")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--reuse", action="store_true", help="reuse earlier summaries")
    args = parser.parse_args(argv)
    spec = list(COLUMNS)
    if args.policy is not None:
        spec.append(("policy", "MaskablePPO lane changes (ALDM)", ["--function", str(args.policy)]))
    done: set[str] = set()
    columns = []
    for folder, header, extra in spec:
        path = args.out / folder
        if folder not in done and not (args.reuse and (path / "scenario_summary.csv").exists()):
            _suite(path, args.suite, extra, args.jobs)
        done.add(folder)
        columns.append((header, _rows(path, "naive" if "naive" in header else "aldm")))
    RESULTS.write_text(replace_block(RESULTS.read_text(), BLOCK, table(columns)))
    print(f"wrote the {BLOCK} table into {RESULTS}")


if __name__ == "__main__":
    main()
