"""Steps per second of ``ALDMHighway-v0`` vs highway-env's ``highway-fast-v0``.

Both envs run in one process, alternating round by round (so machine load hits both
alike), with ``vehicles_count=20, lanes_count=4, simulation_frequency=10,
policy_frequency=1`` and IDLE actions. ``ALDMHighway-v0`` runs the line sensor and
the ALDM at every simulation step. A third env measures the cost ratio of 40 vs 20
vehicles. A fourth runs with ``acc.enabled=False`` (no target selection, ACC or AEB:
v0's constant-speed IDLE) and the ACC + AEB overhead of a step is printed as the
ratio of the medians and the median of per-round ratios. A fifth runs the traffic on
the Python path (``traffic.engine="python"``: the same episodes, bit for bit) and the
compiled engine's gain is printed the same two ways. With ``--xodr PATH`` a sixth
env drives the same settings on that OpenDRIVE map (``road.xodr``; 40 s episodes,
resets not timed) and the map / generated-road ratio is printed (the ratio of the
medians, and the median of the per-round ratios: both envs ran the same seed in a
round). ``--clock cpu`` times with the process's CPU
time instead of the wall clock: on a shared machine other processes then slow the
figures much less. Usage::

    .venv/bin/python benchmarks/bench_env.py [--rounds 5] [--steps 20] [--xodr PATH]
        [--clock wall|cpu] [--profile]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import aldm_gym  # noqa: F401  (registers ALDMHighway-v0)

COMMON = {"lanes_count": 4, "simulation_frequency": 10, "policy_frequency": 1, "duration": 1e4}


MAP_ENV = "ALDMHighway-v0 map (20 veh)"
ACC_OFF_ENV = "ALDMHighway-v0 ACC off (20 veh)"
PYTHON_TRAFFIC_ENV = "ALDMHighway-v0 Python traffic (20 veh)"


def make_envs(xodr: str | None = None) -> dict[str, gym.Env]:
    """The envs of the comparison (the map's with ``xodr``), built once."""
    import highway_env  # noqa: F401  (registers highway-fast-v0)

    envs = {
        "highway-fast-v0 (20 veh)": gym.make(
            "highway-fast-v0", config={**COMMON, "vehicles_count": 20}
        ),
        "ALDMHighway-v0 (20 veh)": gym.make(
            "ALDMHighway-v0", config={**COMMON, "vehicles_count": 20}
        ),
        "ALDMHighway-v0 (40 veh)": gym.make(
            "ALDMHighway-v0", config={**COMMON, "vehicles_count": 40}
        ),
        ACC_OFF_ENV: gym.make(
            "ALDMHighway-v0",
            config={**COMMON, "vehicles_count": 20, "acc": {"enabled": False}},
        ),
        PYTHON_TRAFFIC_ENV: gym.make(
            "ALDMHighway-v0",
            config={**COMMON, "vehicles_count": 20, "traffic": {"engine": "python"}},
        ),
    }
    if xodr is not None:
        config = {**COMMON, "vehicles_count": 20, "duration": 40.0, "road": {"xodr": xodr}}
        envs[MAP_ENV] = gym.make("ALDMHighway-v0", config=config)
    return envs


def steps_per_second(
    env: gym.Env, steps: int, seed: int, clock: Callable[[], float] = time.perf_counter
) -> float:
    """IDLE steps per second over ``steps`` policy steps (resets excluded), by ``clock``."""
    env.reset(seed=seed)
    elapsed = 0.0
    for _ in range(steps):
        t0 = clock()
        _, _, terminated, truncated, _ = env.step(1)
        elapsed += clock() - t0
        if terminated or truncated:
            env.reset()
    return steps / elapsed


def _cpu_model() -> str:
    """The CPU's model name (Linux), else the platform's processor string."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _numerics_line() -> str:
    """The CPU, numpy's SIMD dispatch and which elementary functions agree with libm."""
    from aldm_gym.envs.traffic import scalar

    simd = scalar.numpy_simd_features()
    differ = [name for name, same in scalar.NUMPY_AGREES_WITH_LIBM.items() if not same]
    disabled = f" (disabled: {' '.join(simd['disabled'])})" if simd["disabled"] else ""
    blas = os.environ.get("OPENBLAS_CORETYPE")
    return (
        f"CPU: {_cpu_model()}; numpy {np.__version__} SIMD found: "
        f"{' '.join(simd['found']) or 'baseline only'}{disabled}"
        + (f"; OPENBLAS_CORETYPE={blas}" if blas else "")
        + "; numpy differs from libm in: "
        + (", ".join(differ) if differ else "nothing (engine = Python path bit for bit)")
    )


def _engine_line(env: gym.Env) -> str:
    """Which traffic engine ran the ALDM env's simulation steps (and why not, if not)."""
    engine = env.unwrapped.road.engine
    if engine is None:
        return "traffic engine: python (not configured)"
    from aldm_gym.envs.traffic.compiled import COMPILED

    total = sum(engine.steps.values())
    parts = [f"compiled {engine.steps[COMPILED]}/{total} simulation steps"]
    parts += [f"Python ({reason}) {n}" for reason, n in engine.steps.items() if reason != COMPILED]
    return "traffic engine: " + ", ".join(parts)


def main() -> None:
    """Run the alternating benchmark and print a Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--xodr", help="also time the env on this OpenDRIVE map")
    parser.add_argument("--profile", action="store_true", help="cProfile one ALDM round")
    parser.add_argument(
        "--clock", choices=("wall", "cpu"), default="wall", help="wall clock or process CPU time"
    )
    args = parser.parse_args()
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    envs = make_envs(args.xodr)
    for env in envs.values():  # warm-up: numba caches, imports
        steps_per_second(env, 2, 0)
    rates: dict[str, list[float]] = {name: [] for name in envs}
    for r in range(args.rounds):
        for name, env in envs.items():
            rates[name].append(steps_per_second(env, args.steps, seed=r, clock=clock))
    med = {name: statistics.median(v) for name, v in rates.items()}
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(
        f"machine: {platform.machine()}, nproc={os.cpu_count()}, "
        f"Python {platform.python_version()}, load average {load:.1f}, {args.clock} clock"
    )
    print(_numerics_line())
    print(_engine_line(envs["ALDMHighway-v0 (20 veh)"]) + "\n")
    print("| env | median steps/s | rounds |")
    print("|---|---|---|")
    for name, v in rates.items():
        print(f"| {name} | {med[name]:.1f} | {', '.join(f'{x:.1f}' for x in v)} |")
    hf = med["highway-fast-v0 (20 veh)"]
    a20 = med["ALDMHighway-v0 (20 veh)"]
    a40 = med["ALDMHighway-v0 (40 veh)"]
    paired_speedup = statistics.median(
        a / h
        for a, h in zip(
            rates["ALDMHighway-v0 (20 veh)"], rates["highway-fast-v0 (20 veh)"], strict=True
        )
    )
    print(
        f"\nspeed-up ALDMHighway-v0 / highway-fast-v0 (20 veh): {a20 / hf:.2f}x, "
        f"median of per-round ratios {paired_speedup:.2f}x (target >= 8x)"
    )
    print(f"cost ratio ALDMHighway-v0 40 / 20 vehicles: {a20 / a40:.2f}x (target <= 2.1x)")
    off = rates[ACC_OFF_ENV]
    paired_acc = statistics.median(
        o / a for o, a in zip(off, rates["ALDMHighway-v0 (20 veh)"], strict=True)
    )
    print(
        f"ACC + AEB step cost (ACC on / off, 20 veh): {med[ACC_OFF_ENV] / a20:.3f}x, "
        f"median of per-round ratios {paired_acc:.3f}x (target <= 1.10x)"
    )
    compiled_rates = rates["ALDMHighway-v0 (20 veh)"]
    paired_engine = statistics.median(
        a / p for a, p in zip(compiled_rates, rates[PYTHON_TRAFFIC_ENV], strict=True)
    )
    print(
        f"compiled / Python traffic engine (20 veh): {a20 / med[PYTHON_TRAFFIC_ENV]:.2f}x, "
        f"median of per-round ratios {paired_engine:.2f}x "
        f"(Python traffic: {med[PYTHON_TRAFFIC_ENV] / hf:.2f}x highway-fast-v0)"
    )
    if MAP_ENV in med:
        paired = statistics.median(
            m / g for m, g in zip(rates[MAP_ENV], rates["ALDMHighway-v0 (20 veh)"], strict=True)
        )
        print(
            f"map / generated road (20 veh): {med[MAP_ENV] / a20:.2f}x, "
            f"median of per-round ratios {paired:.2f}x (target >= 0.7x)"
        )
    if args.profile:
        import cProfile
        import pstats

        prof = cProfile.Profile()
        prof.enable()
        steps_per_second(envs["ALDMHighway-v0 (20 veh)"], args.steps, seed=0)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(20)


if __name__ == "__main__":
    main()
