"""Traffic speed: highway-env's ``Road`` against :class:`aldm_gym.envs.traffic.FastRoad`.

Every configuration runs in this one process and the configurations alternate in
rounds (each round gives every configuration the same number of env steps), so load
from other processes on the machine affects them alike. Actions are IDLE (1) at
``simulation_frequency=10, policy_frequency=1, lanes_count=4``; reset time is not
counted. Reported (medians over rounds): env steps/s, the speed-up over
``highway-fast-v0`` with its own ``Road`` at the same vehicle count, the traffic alone
(``_simulate``: ``road.act`` + ``road.step``) in ms per simulation step, and the cost
ratios of 40 to 20 vehicles (≈ 2 means linear).

Run::

    .venv/bin/python -m benchmarks.bench_traffic            # defaults: 20 and 40 vehicles
    .venv/bin/python -m benchmarks.bench_traffic --rounds 3 --steps 10

To benchmark another env, add one line to :data:`ENV_FACTORIES`.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import gymnasium as gym
import highway_env  # noqa: F401  (registers highway-v0 / highway-fast-v0)
import numpy as np

from aldm_gym.envs.traffic import LIBM_MATCHES_NUMPY, use_fast_road

IDLE = 1
"""``DiscreteMetaAction`` index of IDLE."""

BASE_CONFIG: dict[str, Any] = {
    "lanes_count": 4,
    "simulation_frequency": 10,
    "policy_frequency": 1,
    "duration": 10**6,  # episodes end on crashes only
}
"""Config shared by every env in the benchmark (the vehicle count is added per run)."""

FAST_IDM = "aldm_gym.envs.traffic.FastIDMVehicle"

EnvFactory = Callable[[int], gym.Env[Any, Any]]
"""Builds an env for a given ``vehicles_count``."""


def make_highway(
    vehicles_count: int,
    env_id: str = "highway-fast-v0",
    fast_road: bool = False,
    fast_vehicles: bool = False,
) -> gym.Env[Any, Any]:
    """A highway-env env at the benchmark config, optionally with FastRoad / FastIDMVehicle.

    :param vehicles_count: number of other vehicles.
    :param env_id: registered env id.
    :param fast_road: install :class:`~aldm_gym.envs.traffic.FastRoad`.
    :param fast_vehicles: use :class:`~aldm_gym.envs.traffic.FastIDMVehicle` for traffic.
    :return: the env (not reset).
    """
    config = {**BASE_CONFIG, "vehicles_count": vehicles_count}
    if fast_vehicles:
        config["other_vehicles_type"] = FAST_IDM
    env = gym.make(env_id, config=config)
    if fast_road:
        use_fast_road(env)
    return env


BASELINE = "highway-fast-v0 (Road)"
"""The reference configuration for speed-ups."""

ENV_FACTORIES: dict[str, EnvFactory] = {
    BASELINE: partial(make_highway),
    "highway-fast-v0 + FastRoad": partial(make_highway, fast_road=True),
    "highway-fast-v0 + FastRoad + FastIDMVehicle": partial(
        make_highway, fast_road=True, fast_vehicles=True
    ),
    # "ALDMHighway-v0": partial(make_highway, env_id="ALDMHighway-v0"),
}
"""Configurations to compare: name -> factory(vehicles_count)."""


class _Runner:
    """One env kept alive across rounds; counts only time spent in ``env.step``.

    The env's ``_simulate`` (``road.act`` + ``road.step`` per simulation step: the
    traffic) is timed separately, so the report can say what the traffic alone costs.
    """

    def __init__(self, factory: EnvFactory, vehicles_count: int, seed: int) -> None:
        self.env = factory(vehicles_count)
        self.seed = seed
        self.env.reset(seed=seed)
        base: Any = self.env.unwrapped
        self.frames = int(base.config["simulation_frequency"] // base.config["policy_frequency"])
        self.traffic = 0.0
        simulate = base._simulate

        def timed_simulate(action: Any = None) -> None:
            start = time.perf_counter()
            simulate(action)
            self.traffic += time.perf_counter() - start

        base._simulate = timed_simulate

    def run(self, steps: int) -> tuple[float, float]:
        """Run ``steps`` IDLE env steps; return seconds in ``env.step`` and in traffic."""
        elapsed = 0.0
        self.traffic = 0.0
        for _ in range(steps):
            start = time.perf_counter()
            _, _, terminated, truncated, _ = self.env.step(IDLE)
            elapsed += time.perf_counter() - start
            if terminated or truncated:
                self.seed += 1
                self.env.reset(seed=self.seed)
        return elapsed, self.traffic


def machine_note() -> str:
    """One line describing the machine and the software versions."""
    cores = os.cpu_count()
    usable: int | None
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = cores
    return (
        f"{platform.machine()} {platform.processor() or ''}".strip()
        + f", nproc={usable} (cpu_count={cores}), load avg={_load_average()}"
        + f", Python {platform.python_version()}, numpy {np.__version__}"
        + f", highway-env {_version('highway-env')}, gymnasium {gym.__version__}"
        + f", libm-matches-numpy={LIBM_MATCHES_NUMPY}"
    )


def _load_average() -> str:
    try:
        return "/".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


def _version(distribution: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(distribution)
    except PackageNotFoundError:
        return "?"


def benchmark(
    names: Sequence[str],
    vehicle_counts: Sequence[int],
    rounds: int,
    steps: int,
    seed: int,
) -> dict[tuple[str, int], tuple[float, float]]:
    """Median env steps/s and traffic ms per simulation step, alternating in rounds.

    :param names: keys of :data:`ENV_FACTORIES`.
    :param vehicle_counts: vehicle counts to run.
    :param rounds: number of rounds (each configuration runs once per round).
    :param steps: env steps per configuration per round.
    :param seed: reset seed (incremented on every episode end).
    :return: ``(steps/s, traffic ms per simulation step)`` per ``(name, vehicles_count)``.
    """
    runners = {
        (name, n): _Runner(ENV_FACTORIES[name], n, seed) for name in names for n in vehicle_counts
    }
    for runner in runners.values():  # warm-up: imports, caches, first allocations
        runner.run(1)
    rates: dict[tuple[str, int], list[float]] = {key: [] for key in runners}
    traffic: dict[tuple[str, int], list[float]] = {key: [] for key in runners}
    for _ in range(rounds):
        for key, runner in runners.items():
            elapsed, in_traffic = runner.run(steps)
            rates[key].append(steps / elapsed)
            traffic[key].append(1000 * in_traffic / (steps * runner.frames))
    return {
        key: (statistics.median(rates[key]), statistics.median(traffic[key])) for key in runners
    }


def report(
    results: dict[tuple[str, int], tuple[float, float]], vehicle_counts: Sequence[int]
) -> str:
    """A Markdown table: steps/s, speed-up over the baseline, traffic cost, 40/20 ratio."""
    names = list(dict.fromkeys(name for name, _ in results))
    lo, hi = min(vehicle_counts), max(vehicle_counts)
    columns = ["configuration"]
    columns += [f"steps/s @ {n}" for n in vehicle_counts]
    columns += [f"× baseline @ {n}" for n in vehicle_counts]
    columns += [f"traffic ms/sim-step @ {n}" for n in vehicle_counts]
    if lo != hi:
        columns += [f"step cost {hi}/{lo}", f"traffic cost {hi}/{lo}"]
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for name in names:
        cells = [name]
        cells += [f"{results[name, n][0]:.1f}" for n in vehicle_counts]
        cells += [
            f"{results[name, n][0] / results[BASELINE, n][0]:.2f}" if BASELINE in names else "n/a"
            for n in vehicle_counts
        ]
        cells += [f"{results[name, n][1]:.2f}" for n in vehicle_counts]
        if lo != hi:
            cells.append(f"{results[name, lo][0] / results[name, hi][0]:.2f}")
            cells.append(f"{results[name, hi][1] / results[name, lo][1]:.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    """Parse ``argv`` (defaults when None, as ``python -m benchmarks`` calls it), run, print."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, nargs="+", default=[20, 40])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=20, help="env steps per round")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--only", nargs="+", choices=sorted(ENV_FACTORIES), help="subset of configurations"
    )
    args = parser.parse_args([] if argv is None else argv)
    names = args.only or list(ENV_FACTORIES)
    if BASELINE not in names:
        names = [BASELINE, *names]
    print(machine_note())
    print("command: python -m benchmarks.bench_traffic " + " ".join(argv or []))
    results = benchmark(names, args.vehicles, args.rounds, args.steps, args.seed)
    print(report(results, args.vehicles))


if __name__ == "__main__":
    main(sys.argv[1:])
