"""Cold start: how long a fresh install waits for numba, stage by stage.

Runs a child interpreter with an empty ``NUMBA_CACHE_DIR`` (a temporary folder), so
every kernel compiles as on the first run after an install, and prints the wall time
of each first use: import, a generated road, a sensor frame, the robust ALDM, the naive
detector, ``gym.make`` + ``reset``, the first ``step`` (the time to the first env step
is the sum so far), then paper mode (compiled only when used). Usage::

    .venv/bin/python -m benchmarks.cold_start [--rounds 2]

Figures move with machine load by tens of percent: compare versions in one run,
alternating (e.g. two checkouts, each with ``--rounds 1``, twice).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

_CHILD = """
import time
t = [("start", time.perf_counter())]
def mark(name): t.append((name, time.perf_counter()))
import gymnasium as gym
import aldm_gym
mark("import")
from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor, detect_lanes, naive_detect
road = HighwayRoad({"seed": 0, "length": 1000.0})
mark("road")
pose = (*road.reference.position(500.0, road.lane_offset(1)), road.reference.heading_at(500.0))
frame = LineSensor().measure(road, tuple(float(v) for v in pose))
mark("sensor frame")
detect_lanes(frame)
mark("ALDM (robust)")
naive_detect(frame)
mark("naive")
env = gym.make("ALDMHighway-v0")
env.reset(seed=0)
mark("env make + reset")
env.step(1)
mark("first env step")
first_step = t[-1][1] - t[0][1]
detect_lanes(frame, mode="paper")
mark("ALDM (paper)")
for (_, a), (name, b) in zip(t, t[1:]):
    print(f"{name:18s} {b - a:6.1f} s")
print(f"{'to first env step':18s} {first_step:6.1f} s")
"""


def main(argv: list[str] | None = None) -> None:
    """Print the per-stage cold-start times of ``--rounds`` fresh child processes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args(argv)
    print(
        f"machine: {os.uname().machine}, nproc={os.cpu_count()}, "
        f"load average {os.getloadavg()[0]:.1f}"
    )
    for k in range(args.rounds):
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "NUMBA_CACHE_DIR": cache}
            env.pop("NUMBA_DISABLE_JIT", None)
            out = subprocess.run(
                [sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True
            )
        print(f"-- round {k + 1}")
        print(out.stdout if out.returncode == 0 else out.stderr[-2000:], end="")


if __name__ == "__main__":
    main()
