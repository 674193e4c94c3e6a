"""The SB3 training envs, and the process's random state they and PPO draw from.

Each env is ``ALDMHighway-v0`` in SB3's ``Monitor`` (episode returns and lengths for the
progress bar and tensorboard), in a :class:`ResumableEnv` whose whole state can be
saved and restored, so that a resumed training continues exactly.
"""

from __future__ import annotations

import functools
import pickle
import random
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np

from aldm_gym import ENV_ID
from aldm_gym.training.sb3 import import_sb3


class ResumableEnv(gym.Wrapper):
    """A training env whose whole state can be saved and restored (exact resume).

    Wraps the ``Monitor``-ed env; :meth:`resume_state` pickles the wrapped env (its
    road, vehicles, RNG and the monitor's episode counters) with the process's global
    RNG states (a ``SubprocVecEnv`` worker has its own), :meth:`restore_resume_state`
    puts them back. The vectorised env reaches both through ``env_method``.
    """

    def resume_state(self) -> bytes:
        """The wrapped env and this process's global RNG states, pickled."""
        return pickle.dumps(
            {"env": self.env, "rng": global_rng_state(torch=False)},
            protocol=pickle.HIGHEST_PROTOCOL,
        )

    def restore_resume_state(self, state: bytes) -> None:
        """Replace the wrapped env and global RNG states by those of ``state``."""
        data = pickle.loads(state)
        self.env = data["env"]
        set_global_rng_state(data["rng"])


def make_env(config: Mapping[str, Any]) -> ResumableEnv:
    """One monitored, resumable env (module level so ``SubprocVecEnv`` can pickle the
    factory)."""
    from stable_baselines3.common.monitor import Monitor

    import aldm_gym  # noqa: F401  (registers the env in a fresh subprocess)

    return ResumableEnv(Monitor(gym.make(ENV_ID, config=config)))


def make_vec_env(config: Mapping[str, Any], n_envs: int, seed: int) -> Any:
    """``n_envs`` copies of the env: ``SubprocVecEnv`` for several, else ``DummyVecEnv``.

    The i-th env's first reset uses ``seed + i``.
    """
    import_sb3()
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    fns: list[Callable[[], Any]] = [functools.partial(make_env, config) for _ in range(n_envs)]
    venv = SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)
    venv.seed(seed)
    return venv


def close_envs(venv: Any, interrupted: bool) -> None:
    """Close the vectorised envs; after an interruption, end subprocess workers outright.

    An interruption may have cut a worker's reply short (a step, or a large
    ``env_method`` result still in the pipe): a polite ``close`` would then wait for a
    worker blocked on sending, so the workers are terminated instead.
    """
    processes = getattr(venv.unwrapped, "processes", None)
    if interrupted and processes:
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(timeout=10)
        venv.unwrapped.closed = True
        return
    try:
        venv.close()
    except (EOFError, BrokenPipeError, ConnectionResetError):  # workers died with Ctrl-C
        pass


def global_rng_state(torch: bool = True) -> dict[str, Any]:
    """States of Python's, numpy's global (and torch's) random generators."""
    state: dict[str, Any] = {"random": random.getstate(), "numpy": np.random.get_state()}  # noqa: NPY002
    if torch:
        import torch as th

        state["torch"] = th.get_rng_state()
    return state


def set_global_rng_state(state: dict[str, Any]) -> None:
    """Restore what :func:`global_rng_state` returned."""
    random.setstate(state["random"])
    # SB3 shuffles minibatches with numpy's global generator: it is part of the state.
    np.random.set_state(state["numpy"])  # noqa: NPY002
    if "torch" in state:
        import torch as th

        th.set_rng_state(state["torch"])
