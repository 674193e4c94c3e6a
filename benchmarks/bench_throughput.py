"""Env steps per second when training: SB3's vectorised envs and RLlib's env runners.

Two measurements on the training env (``ALDMHighway-v0`` with
:func:`~aldm_gym.training.settings.env_config`'s defaults: ALDM, per-dash road, 40 s
episodes, 20 vehicles):

* **sampling**: env steps per second of SB3's ``DummyVecEnv`` and ``SubprocVecEnv`` with
  1 and 2 envs (uniformly random meta actions, seeded) and of RLlib with 1 and 2 env
  runners (``synchronous_parallel_sample``: the runners step with the untrained policy,
  a 128×128 MLP forward per step, ~0.5 ms beside a ~15 ms env step); a warm-up round
  (numba caches loaded, processes started) is not timed; then ``--rounds`` rounds of
  ``--steps`` steps per env, the median of each configuration, every configuration
  timed in every round (all are built first; RLlib's 1-runner case uses one of the same
  two runners). The scaling is 2 envs / 1 env of the same kind. Beside them, the
  machine's own ceiling: 1 vs 2 processes of pure-Python work, timed in the same rounds
  (a VM's second core may be shared with other tenants).
* **training** (``--train-steps N``, 0 skips it): wall time of a PPO training of N
  steps with ``aldm-gym train``'s settings, SB3 with ``--n-envs`` 1 and 2, RLlib with
  ``--num-env-runners`` 1 and 2 (rollout ``--n-steps`` per env or runner, so an update
  sees the same number of steps per env both ways), set-up included.

RLlib's rows are skipped without the ``[ray]`` extra (run it in ``.venv-ray``). Usage::

    .venv-ray/bin/python -m benchmarks.bench_throughput [--rounds 5] [--steps 128]
        [--train-steps 4096] [--n-steps 256]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

Sampler = Callable[[int], int]
"""``sample(steps per env) -> env steps done``."""


def _sb3_sampler(n_envs: int, subprocess: bool) -> tuple[Sampler, Callable[[], None]]:
    """``(sample, close)`` for an SB3 vectorised env."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    from aldm_gym.training.sb3.envs import make_env
    from aldm_gym.training.settings import env_config

    config = env_config()
    fns = [lambda: make_env(config) for _ in range(n_envs)]
    venv = SubprocVecEnv(fns) if subprocess else DummyVecEnv(fns)
    venv.seed(0)
    venv.reset()
    rng = np.random.default_rng(0)

    def sample(steps: int) -> int:
        for _ in range(steps):
            venv.step(rng.integers(0, 5, size=n_envs))
        return steps * n_envs

    return sample, venv.close


def _rllib_samplers() -> tuple[dict[str, Sampler], Callable[[], None]]:
    """Samplers with 1 and 2 of the same two RLlib env runners, and ``close``."""
    import ray

    from aldm_gym.training.rllib.cluster import connect
    from aldm_gym.training.rllib.config import ppo_config
    from aldm_gym.training.settings import PPOParams, env_config

    connect(None, 2)
    config = ppo_config(env_config(), PPOParams(), timesteps=10**6, num_env_runners=2)
    algo = config.build_algo()
    group = algo.env_runner_group

    def on(ids: list[int]) -> Sampler:
        def sample(steps: int) -> int:
            counts = group.foreach_env_runner(
                lambda runner: sum(len(e) for e in runner.sample(num_timesteps=steps)),
                local_env_runner=False,
                remote_worker_ids=ids,
            )
            return int(sum(counts))

        return sample

    def close() -> None:
        algo.stop()
        ray.shutdown()

    return {"RLlib, 1 env runner": on([1]), "RLlib, 2 env runners": on([1, 2])}, close


def _spin(seconds: float) -> int:
    """Pure-Python work for ``seconds``; the loops done."""
    end, n, x = time.perf_counter() + seconds, 0, 0
    while time.perf_counter() < end:
        for i in range(10_000):
            x += i * i
        n += 1
    return n


def _ceiling_samplers() -> tuple[dict[str, Sampler], Callable[[], None]]:
    """1 and 2 processes of pure-Python work: what the machine's cores scale to."""
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(2)
    list(pool.map(_spin, [0.1, 0.1]))

    def on(n: int) -> Sampler:
        def sample(steps: int) -> int:
            return sum(pool.map(_spin, [steps * 0.015] * n))

        return sample

    return {"pure Python, 1 process": on(1), "pure Python, 2 processes": on(2)}, pool.shutdown


def sampling(rounds: int, steps: int, with_rllib: bool) -> dict[str, float]:
    """Median rate of each configuration [env steps/s; loops/s for the pure-Python
    ceiling]. Every configuration is built first; then each round times all of them
    in turn, so the machine's changing load hits all alike."""
    samplers: dict[str, Sampler] = {}
    closers: list[Callable[[], None]] = []
    try:
        built, close = _ceiling_samplers()
        samplers.update(built)
        closers.append(close)
        for name, n, sub in (
            ("SB3 DummyVecEnv, 1 env", 1, False),
            ("SB3 DummyVecEnv, 2 envs", 2, False),
            ("SB3 SubprocVecEnv, 1 env", 1, True),
            ("SB3 SubprocVecEnv, 2 envs", 2, True),
        ):
            samplers[name], close = _sb3_sampler(n, sub)
            closers.append(close)
        if with_rllib:
            built, close = _rllib_samplers()
            samplers.update(built)
            closers.append(close)
        for sample in samplers.values():
            sample(max(8, steps // 8))  # warm-up: caches, processes
        rates: dict[str, list[float]] = {name: [] for name in samplers}
        for r in range(rounds):
            for name, sample in samplers.items():
                t0 = time.perf_counter()
                n = sample(steps)
                rates[name].append(n / (time.perf_counter() - t0))
            print(f"round {r + 1}/{rounds} done", flush=True)
    finally:
        for close in closers:
            close()
    return {name: statistics.median(r) for name, r in rates.items()}


def training(train_steps: int, n_steps: int, with_rllib: bool) -> dict[str, float]:
    """Wall time [s] of a training of ``train_steps`` steps per configuration."""
    from aldm_gym.training.sb3.backend import train
    from aldm_gym.training.settings import PPOParams

    times = {}
    params = PPOParams(n_steps=n_steps)
    runs: list[tuple[str, Callable[[Path], Any]]] = [
        (
            f"SB3, --n-envs {n}",
            lambda out, n=n: train(
                out,
                timesteps=train_steps,
                n_envs=n,
                params=params,
                validation_freq=0,
                progress=False,
            ),
        )
        for n in (1, 2)
    ]
    if with_rllib:
        from aldm_gym.training.rllib.backend import train_rllib

        runs += [
            (
                f"RLlib, --num-env-runners {n}",
                lambda out, n=n: train_rllib(
                    out,
                    timesteps=train_steps,
                    num_env_runners=n,
                    params=params,
                    progress=False,
                ),
            )
            for n in (1, 2)
        ]
    for name, run in runs:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            run(Path(tmp) / "out")
            times[name] = time.perf_counter() - t0
        print(f"{name}: {times[name]:.0f} s for {train_steps} steps", flush=True)
    return times


def _scaling(rates: dict[str, float], one: str, two: str) -> str:
    return f"{rates[two] / rates[one]:.2f}×" if one in rates and two in rates else "-"


def main(argv: list[str] | None = None) -> None:
    """Print the sampling table (and the training times) as Markdown."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=128, help="steps per env per round")
    parser.add_argument("--train-steps", type=int, default=0, help="training budget (0: skip)")
    parser.add_argument("--n-steps", type=int, default=256, help="rollout per env / runner")
    args = parser.parse_args(argv)
    with_rllib = importlib.util.find_spec("ray") is not None
    import numba
    import torch

    print(
        f"machine: {platform.machine()}, nproc={os.cpu_count()}, Python "
        f"{platform.python_version()}, numba {numba.__version__}, torch {torch.__version__}, "
        f"load {os.getloadavg()[0]:.1f}"
    )
    if with_rllib:
        import ray

        print(f"ray {ray.__version__}")
    rates = sampling(args.rounds, args.steps, with_rllib)
    print("\n| sampling | env steps/s (pure Python: loops/s) | 2 vs 1 |\n|---|---:|---:|")
    pairs = {
        "pure Python, 2 processes": "pure Python, 1 process",
        "SB3 DummyVecEnv, 2 envs": "SB3 DummyVecEnv, 1 env",
        "SB3 SubprocVecEnv, 2 envs": "SB3 SubprocVecEnv, 1 env",
        "RLlib, 2 env runners": "RLlib, 1 env runner",
    }
    for name, rate in rates.items():
        scale = _scaling(rates, pairs[name], name) if name in pairs else ""
        print(f"| {name} | {rate:.1f} | {scale} |")
    if args.train_steps > 0:
        times = training(args.train_steps, args.n_steps, with_rllib)
        print(f"\n| training, {args.train_steps} steps | wall time [s] |\n|---|---:|")
        for name, seconds in times.items():
            print(f"| {name} | {seconds:.0f} |")


if __name__ == "__main__":
    main()
