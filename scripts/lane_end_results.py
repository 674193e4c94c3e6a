"""The lane-drop scenarios (``aldm_gym.harness.lane_drop``) with each source of the
lane end, as one table in docs/results.md (the block ``<!-- generated:lane-ends -->``).

Every case (the 2+1 road's overtaking lane, the motorway's acceleration lane) × speed
(15, 25 m/s) × traffic in the lane to merge into (none, one car alongside, a platoon)
× detector (ground truth, ALDM) × ``lane_end.source`` (off, map, perception), played
by the built-in function; a run passes the UN R157 criteria of the suite. Usage::

    python scripts/lane_end_results.py [--jobs 2]
"""

from __future__ import annotations

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from tqdm import tqdm

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results.md"
BLOCK = "lane-ends"
SOURCES = ("off", "map", "perception")
DETECTORS = ("ground_truth", "aldm")


def _run(job: tuple[str, str, float, str, str, str]) -> dict:
    """One run (in a worker process) of a scenario file written before."""
    import warnings

    from aldm_gym.harness.criteria import run_scenario

    path, case, speed, traffic, detector, source = job
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = run_scenario(path, detector=detector, config={"lane_end": {"source": source}})
    return {"case": case, "speed": speed, "traffic": traffic, "detector": detector,
            "source": source, "passed": result.passed, "departures": result.departures,
            "collision": result.collision}  # fmt: skip


def table(rows: list[dict]) -> str:
    """Pass counts per detector and source, one row per case and traffic."""
    head = "| lane drop | traffic in the target lane | runs |"
    rule = "|---|---|---:|"
    for det in DETECTORS:
        for src in SOURCES:
            name = "ground truth" if det == "ground_truth" else "ALDM"
            head += f" {name}, {src} |"
            rule += "---:|"
    lines = [head, rule]
    keys = sorted({(r["case"], r["traffic"]) for r in rows}, key=lambda k: (k[0], k[1]))
    for case, traffic in keys:
        cell = [r for r in rows if r["case"] == case and r["traffic"] == traffic]
        runs = len({r["speed"] for r in cell})
        line = f"| {case} | {traffic} | {runs} |"
        for det in DETECTORS:
            for src in SOURCES:
                sel = [r for r in cell if r["detector"] == det and r["source"] == src]
                passed = sum(r["passed"] for r in sel)
                dep = sum(r["departures"] > 0 for r in sel)
                line += f" {passed}/{len(sel)}" + (f" ({dep} dep.)" if dep else "") + " |"
        lines.append(line)
    return "\n".join(lines)


def main() -> None:
    """Run every combination and rewrite the block in docs/results.md."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    args = parser.parse_args()
    from aldm_gym.harness.lane_drop import LANE_DROPS, TRAFFIC, lane_drop_scenario

    with tempfile.TemporaryDirectory() as folder:
        # Every file written once, before any worker reads one.
        files = {(c, v, t): str(lane_drop_scenario(folder, c, v, t))
                 for c in LANE_DROPS for v in (15.0, 25.0) for t in TRAFFIC}  # fmt: skip
        jobs = [(files[c, v, t], c, v, t, d, s) for c, v, t in files
                for d in DETECTORS for s in SOURCES]  # fmt: skip
        with ProcessPoolExecutor(args.jobs) as pool:
            rows = list(tqdm(pool.map(_run, jobs), total=len(jobs), desc="lane drops"))
    text = RESULTS.read_text()
    start, end = f"<!-- generated:{BLOCK} -->", f"<!-- /generated:{BLOCK} -->"
    i, j = text.index(start) + len(start), text.index(end)
    RESULTS.write_text(text[:i] + "\n" + table(rows) + "\n" + text[j:])
    print(table(rows))


if __name__ == "__main__":
    main()
