"""Cold start: how long a fresh install waits before its first env step.

Each measurement is a child interpreter with an empty ``NUMBA_CACHE_DIR`` (a temporary
folder) that imports the package, makes the env, resets it and steps it once, stage by
stage. Three cases:

* **shipped kernels** — the package's ahead-of-time kernels (``aldm_gym/_kernels``,
  generic x86-64, what a wheel carries) and an empty numba cache: a fresh wheel install;
* **JIT** — no shipped kernels, empty cache: every kernel compiles (the first run of a
  source install that skipped ``python -m aldm_gym.warmup``). Stage by stage: a
  generated road, a sensor frame, the robust ALDM, the naive detector, the env, then
  paper mode (compiled only when used). ``--no-jit`` skips it (about a minute).
* **warm cache** — the same child again with the numba cache the JIT child filled
  and the shipped kernels off (``ALDM_GYM_KERNEL_STORE=off``): a second run of a source
  install;

Each case runs the default env and, in a second child, the camera preset with the
lane-model filter. Usage::

    .venv/bin/python -m aldm_gym.warmup --store     # the shipped kernels, if not current
    .venv/bin/python -m benchmarks.cold_start [--rounds 2] [--no-jit]

Figures move with machine load by tens of percent: compare versions in one run,
alternating (e.g. two checkouts, each with ``--rounds 1``, twice).
"""

from __future__ import annotations

import argparse
import compileall
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import aldm_gym

_STAGES = """
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

_ENV = """
import json, sys, time
t0 = time.perf_counter()
import gymnasium as gym
import aldm_gym
t1 = time.perf_counter()
env = gym.make("ALDMHighway-v0", config=json.loads(sys.argv[1]))
env.reset(seed=0)
t2 = time.perf_counter()
env.step(1)
t3 = time.perf_counter()
print(f"import {t1 - t0:.1f} s, make + reset {t2 - t1:.1f} s, step {t3 - t2:.1f} s: "
      f"to first env step {t3 - t0:.1f} s")
"""

CAMERA_FILTER = {"sensor": {"preset": "camera"}, "detector_params": {"tracking": "model"}}
"""The second env of each case: the camera preset and the lane-model filter."""


def _child(code: str, cache: str, store: str, *args: str) -> str:
    """Run ``code`` in a child with ``NUMBA_CACHE_DIR=cache`` and the shipped kernels
    ``store`` (read / off); its output, or its error's tail."""
    env = {**os.environ, "NUMBA_CACHE_DIR": cache, "ALDM_GYM_KERNEL_STORE": store}
    env.pop("NUMBA_DISABLE_JIT", None)
    out = subprocess.run(
        [sys.executable, "-c", code, *args], env=env, capture_output=True, text=True
    )
    compiled = " (compiled kernels)" if "compiling numba kernels" in out.stderr else ""
    text = out.stdout if out.returncode == 0 else out.stderr[-2000:]
    return text.rstrip("\n") + compiled


def main(argv: list[str] | None = None) -> None:
    """Print the cold-start times of ``--rounds`` rounds of fresh child processes."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--no-jit", action="store_true", help="skip the JIT case")
    args = parser.parse_args(argv)
    from aldm_gym._numba import store_status

    print(
        f"machine: {os.uname().machine}, nproc={os.cpu_count()}, "
        f"load average {os.getloadavg()[0]:.1f}, shipped kernels: {store_status()}"
    )
    # .pyc files, as pip writes them at install (the children would compile the sources)
    compileall.compile_dir(str(Path(aldm_gym.__file__).parent), quiet=1)
    camera = json.dumps(CAMERA_FILTER)
    for k in range(args.rounds):
        print(f"-- round {k + 1}")
        with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as c2:
            print("shipped kernels, empty cache:")
            print(_child(_STAGES, cache, "read"))
            print("  camera + filter:", _child(_ENV, c2, "read", camera))
            if not args.no_jit:
                print("JIT (no shipped kernels), empty cache:")
                print(_child(_STAGES, cache, "off"))
                print("  camera + filter:", _child(_ENV, c2, "off", camera))
                print("warm cache (the JIT run's), no shipped kernels:")
                print(_child(_STAGES, cache, "off"))
                print("  camera + filter:", _child(_ENV, c2, "off", camera))


if __name__ == "__main__":
    main()
