"""ASAM OSI speed: ``aldm-gym osi detect`` frames per second, and what writing a trace
costs the env.

1. **Detect.** A 1,001-frame trace of the default env (``osi.every="frame"``, 100 env
   steps) is written once; its SensorViews are parsed into memory (file I/O excluded),
   then the line sensor, the ALDM and the SensorData of every frame are timed in one
   process, and in two processes splitting the frames (forked, kernels loaded: the
   wall time of the parallel part). ``detect_trace`` end to end (reading and writing
   the files included) is timed too.
2. **Writing.** Env steps per second without a trace and with ``osi.trace`` (one
   SensorView + SensorData per env step, MCAP), rounds alternating in one process
   (which goes first alternates too), the same seeds: the ratio is the trace's cost.
   The time spent inside the writer over the rest of the traced steps is printed too:
   the slowdown without the noise of two separate runs. Usage::

    .venv/bin/python -m benchmarks.bench_osi [--rounds 5] [--steps 20]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

_MESSAGES: list[Any] = []


def _trace(path: Path) -> None:
    import gymnasium as gym

    env = gym.make("ALDMHighway-v0", config={"osi": {"trace": str(path), "every": "frame"}})
    env.reset(seed=5)
    for _ in range(100):
        env.step(1)
    env.close()


def _process(part: int, parts: int) -> int:
    from aldm_gym.osi import OsiLaneSensor

    model = OsiLaneSensor()
    n = 0
    for i, message in enumerate(_MESSAGES):
        if i % parts == part:
            model.step(message, i)
            n += 1
    return n


def _env_rate(trace: Path | None, steps: int, seed: int) -> tuple[float, float]:
    """Env steps per second, and the seconds spent writing the trace (0 without)."""
    import gymnasium as gym

    config: dict[str, Any] = {"duration": 1000}
    if trace is not None:
        config["osi"] = {"trace": str(trace)}
    env = gym.make("ALDMHighway-v0", config=config)
    env.reset(seed=seed)
    env.step(1)
    recorder = env.unwrapped.osi
    spent = [0.0]
    if recorder is not None:
        record = recorder.record

        def timed(inner: Any) -> None:
            start = time.perf_counter()
            record(inner)
            spent[0] += time.perf_counter() - start

        recorder.record = timed
    start = time.perf_counter()
    for _ in range(steps):
        env.step(1)
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate, spent[0]


def main(argv: list[str] | None = None) -> None:
    """Measure and print (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=20)
    args = parser.parse_args(argv or [])
    import aldm_gym  # noqa: F401
    from aldm_gym.osi import OsiLaneSensor, detect_trace, read_messages

    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "run.mcap"
        _trace(src)
        start = time.perf_counter()
        _MESSAGES[:] = [m for _, m in read_messages(src)]
        read = time.perf_counter() - start
        n = len(_MESSAGES)
        OsiLaneSensor().step(_MESSAGES[0], 0)  # kernels loaded
        one = []
        for _ in range(3):
            start = time.perf_counter()
            _process(0, 1)
            one.append(time.perf_counter() - start)
        ctx = mp.get_context("fork")
        two = []
        with ctx.Pool(2) as pool:
            pool.starmap(_process, [(0, 2), (1, 2)])  # warm the workers
            for _ in range(3):
                start = time.perf_counter()
                pool.starmap(_process, [(0, 2), (1, 2)])
                two.append(time.perf_counter() - start)
        ends = {}
        for jobs in (1, 2):
            start = time.perf_counter()
            detect_trace(src, Path(tmp) / f"sd{jobs}.mcap", jobs=jobs)
            ends[jobs] = time.perf_counter() - start
        print(f"trace: {n} frames, parsed in {read:.2f} s ({n / read:.0f} frames/s)")
        print(
            f"detect (ALDM, I/O excluded, best of 3): 1 process {n / min(one):.0f} frames/s, "
            f"2 processes {n / min(two):.0f} frames/s"
        )
        print(
            f"detect_trace end to end (read, detect, write): jobs=1 {n / ends[1]:.0f} frames/s, "
            f"jobs=2 {n / ends[2]:.0f} frames/s"
        )
        ratios, shares = [], []
        for r in range(args.rounds):
            order = (None, Path(tmp) / f"env{r}.mcap")
            rates = {}
            for trace in order if r % 2 == 0 else order[::-1]:
                rates[trace is not None] = _env_rate(trace, args.steps, 100 + r)
            (plain, _), (traced, spent) = rates[False], rates[True]
            ratios.append(traced / plain)
            # the writing's own time against the rest of the traced steps
            wall = args.steps / traced
            shares.append(spent / (wall - spent))
            print(
                f"round {r}: {plain:.1f} steps/s plain, {traced:.1f} with the trace "
                f"({1e3 * spent / args.steps:.2f} ms per step writing it)"
            )
        print(
            f"env steps/s with a trace / without: median {statistics.median(ratios):.2f}x; "
            f"writing / the rest of a traced step: median {100 * statistics.median(shares):.0f} %"
        )


if __name__ == "__main__":
    import sys

    main(sys.argv[1:])
