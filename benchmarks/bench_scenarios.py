"""Concrete scenario runs per minute of ``aldm-gym scenario suite`` (the OSC-ALKS suite).

Plays an evenly spaced subset of every OSC-ALKS variation file (``--max-runs`` runs per
file, the ALDM on per-dash paint) in ``--jobs`` worker processes, as the command line
does, and prints the runs, the wall time and runs per minute (process start-up and the
workers' numba cache loads included: what a user waits for). Simulated seconds per
wall second are printed too: the suite's runs last 20 s to 300 s each. The suite is
read from ``$OSC_ALKS_DIR`` (default ``../shared/osc-alks``); without it the benchmark
says so and stops. Usage::

    .venv/bin/python benchmarks/bench_scenarios.py [--max-runs 3] [--jobs 2]
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path


def _suite() -> Path | None:
    root = Path(
        os.environ.get("OSC_ALKS_DIR", Path(__file__).resolve().parents[2] / "shared" / "osc-alks")
    )
    folder = root / "logical_scenarios"
    return folder if folder.is_dir() else None


def main(argv: list[str] | None = None) -> None:
    """Measure and print (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--max-runs", type=int, default=3)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv or [])
    folder = _suite()
    if folder is None:
        print("the OSC-ALKS suite is not here: set OSC_ALKS_DIR to a clone of it")
        return
    from aldm_gym.harness.suite import plan_suite, play_suite

    jobs = plan_suite(folder, ["aldm"], ["per_dash"], args.max_runs)
    start = time.perf_counter()
    results = play_suite(jobs, processes=args.jobs, progress=False)
    wall = time.perf_counter() - start
    simulated = sum(r.time_s for r in results)
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"{args.jobs} worker processes"
    )
    print(
        f"{len(results)} runs ({simulated:.0f} s simulated) in {wall:.1f} s: "
        f"{60.0 * len(results) / wall:.1f} runs/min, {simulated / wall:.1f} simulated s per s"
    )


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
