"""PPO on Ray RLlib: :class:`RLlibBackend`, :func:`train_rllib` (``--backend rllib``).

:func:`train_rllib` trains the same task as the SB3 backend (the PPO mapping:
:mod:`aldm_gym.training.rllib.config`) on a local Ray instance or a running cluster
(:mod:`aldm_gym.training.rllib.cluster`). What every training does (lock, signals,
fallback to an older checkpoint when the newest does not restore, ``training.json``)
is :func:`~aldm_gym.training.backend.train_with`'s.

Output folder (beside SB3's files, :mod:`aldm_gym.training.outputs`)::

    <out>/training.json                 as SB3's, with "backend": "rllib"
    <out>/rllib_model/                  the final RLlib checkpoint
    <out>/checkpoints/rllib_<steps>/    a checkpoint every checkpoint_freq steps
    <out>/tb/RLlib_PPO/                 tensorboard events (returns, losses, rates)

Its chunks are RLlib's training iterations: the first Ctrl-C or SIGTERM lets the
iteration in progress finish and saves a checkpoint of it; a second one stops at once
(that iteration is lost: RLlib's learner state mid-update is not one to save). Unlike
the SB3 path a resume is not bit-exact: the env runners start new episodes, seeded
``seed + steps done``.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from aldm_gym.errors import CheckpointError
from aldm_gym.training.backend import Backend, CheckpointRef, train_with
from aldm_gym.training.outputs import (
    RLLIB_MODEL_DIR,
    TENSORBOARD_DIR,
    rllib_checkpoint_path,
)
from aldm_gym.training.progress import postfix, training_bar
from aldm_gym.training.record import TrainingRecord
from aldm_gym.training.rllib import import_rllib
from aldm_gym.training.rllib.checkpoints import (
    STEPS_FILE,
    checkpoint_steps,
    checkpoints,
    push_runner_statistics,
    save_checkpoint,
)
from aldm_gym.training.rllib.cluster import connect
from aldm_gym.training.rllib.config import ppo_config
from aldm_gym.training.settings import (
    DEFAULT_COLLISION_REWARD,
    PPOParams,
    algorithm_name,
    env_config,
)
from aldm_gym.training.signals import StopRequest

logger = logging.getLogger(__name__)

TB_RUN = "RLlib_PPO"
"""The tensorboard run folder under ``<out>/tb``."""

LOGGED = {
    "env_runners": ("episode_return_mean", "episode_len_mean", "num_episodes"),
    "learners/default_policy": (
        "policy_loss",
        "vf_loss",
        "entropy",
        "vf_explained_var",
        "default_optimizer_learning_rate",
    ),
}
"""The results written to tensorboard, by section of RLlib's result dict."""


def tb_scalars(result: Mapping[str, Any]) -> dict[str, float]:
    """The scalars of one RLlib result to log (tag -> value)."""
    scalars = {}
    for section, keys in LOGGED.items():
        node: Any = result
        for part in section.split("/"):
            node = node.get(part, {}) if isinstance(node, Mapping) else {}
        for key in keys:
            value = node.get(key) if isinstance(node, Mapping) else None
            if value is not None and np.isfinite(float(value)):
                scalars[f"{section.split('/')[0]}/{key}"] = float(value)
    scalars["perf/iteration_s"] = float(result.get("time_this_iter_s", np.nan))
    return {k: v for k, v in scalars.items() if np.isfinite(v)}


def sampled_steps(result: Mapping[str, Any]) -> int:
    """Env steps sampled in one iteration; 0 (with a warning) for an iteration whose
    env runners returned nothing (RLlib then reports NaN, e.g. when every runner's
    sample timed out on an overloaded machine)."""
    value = result.get("env_runners", {}).get("num_env_steps_sampled")
    if value is None or not np.isfinite(float(value)):
        warnings.warn(
            "an iteration sampled no env steps (the env runners returned nothing)",
            UserWarning,
            stacklevel=2,
        )
        return 0
    return int(value)


def result_postfix(result: Mapping[str, Any]) -> dict[str, str]:
    """The bar's postfix (:func:`~aldm_gym.training.progress.postfix`) from an
    iteration's result: its recent training episodes' mean return and length."""
    runners = result.get("env_runners", {})
    return postfix(runners.get("episode_return_mean"), runners.get("episode_len_mean"))


class RLlibBackend(Backend[CheckpointRef]):
    """PPO on Ray RLlib (see the module docstring).

    Its chunks are RLlib's training iterations: the first signal lets the one in
    progress finish (:attr:`stops_at_once` is False).

    :param address: a running Ray cluster (``"auto"`` or ``"host:port"``); None starts
        a local Ray instance for the training.
    :ivar algo: the RLlib algorithm (None before :meth:`build` or :meth:`restore`).
    :ivar steps: env steps trained [env steps].
    """

    name: ClassVar[str] = "rllib"
    stops_at_once: ClassVar[bool] = False
    algorithms: ClassVar[tuple[str, ...]] = ("PPO", "MaskablePPO")

    def __init__(
        self,
        out: Path,
        record: TrainingRecord,
        saved: TrainingRecord | None,
        progress: bool,
        address: str | None = None,
    ) -> None:
        # RLlib reads a relative path as a URI without a scheme.
        super().__init__(Path(out).absolute(), record, saved, progress)
        self.address = address
        self.algo: Any = None
        self.writer: Any = None
        self.steps = self.last_saved = 0

    @staticmethod
    def require() -> None:
        """Import Ray RLlib and torch (:func:`~aldm_gym.training.rllib.import_rllib`)."""
        import_rllib()

    @contextmanager
    def session(self) -> Iterator[None]:
        """A local Ray instance, or the cluster at :attr:`address`, for the training
        (torch on one thread: the env runners need the cores; the MLP is tiny).

        :raises ClusterError: see :func:`~aldm_gym.training.rllib.cluster.connect`.
        """
        import ray
        import torch

        torch.set_num_threads(1)
        connect(self.address, self.record.run.num_env_runners)
        try:
            yield
        finally:
            ray.shutdown()

    def checkpoints(self) -> list[CheckpointRef]:
        """The complete RLlib checkpoint folders, newest first."""
        return checkpoints(self.out)

    def checkpoint_fault(self, checkpoint: CheckpointRef) -> str | None:
        """Why a checkpoint folder cannot be used: an unreadable :data:`STEPS_FILE`."""
        try:
            checkpoint_steps(checkpoint.path)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            return f"{checkpoint.path}: unreadable {STEPS_FILE} ({exc})"
        return None

    def _build(self, done: int) -> None:
        """The algorithm of the training at ``done`` steps (its envs seeded
        ``seed + done``, so a resume does not replay the first episodes)."""
        record, run = self.record, self.record.run
        self.algo = ppo_config(
            record.env_config,
            self.params,
            timesteps=run.timesteps,
            num_env_runners=run.num_env_runners,
            seed=run.seed + done,
            masked=record.algorithm == "MaskablePPO",
        ).build_algo()
        self.steps = self.last_saved = done

    def build(self) -> None:
        """A new algorithm at step 0."""
        self._build(0)

    def restore(self, checkpoint: CheckpointRef) -> str:
        """An algorithm at the checkpoint's steps, restored from it; the env runners
        get its observation statistics."""
        done = checkpoint_steps(checkpoint.path)
        self._build(done)
        try:
            self.algo.restore_from_path(str(checkpoint.path))
        except Exception as exc:  # a damaged checkpoint fails in pickle, torch or RLlib
            self.algo.stop()
            self.algo = None
            raise CheckpointError(
                f"{checkpoint.path}: does not restore ({type(exc).__name__}: {exc})"
            ) from exc
        push_runner_statistics(self.algo)
        return (
            f"restored {checkpoint.path}; the env runners start new episodes, "
            f"seeded {self.record.run.seed + done}"
        )

    def learn(self, stop: StopRequest) -> None:
        """RLlib iterations until the budget or a stop request, a checkpoint every
        ``checkpoint_freq`` steps; tensorboard gets :data:`LOGGED` of each."""
        from torch.utils.tensorboard import SummaryWriter

        total = self.record.run.timesteps
        self.writer = SummaryWriter(str(self.out / TENSORBOARD_DIR / TB_RUN))
        with training_bar(total, self.steps, self.progress) as bar:
            while self.steps < total and not stop.requested:
                result = self.algo.train()
                sampled = sampled_steps(result)
                self.steps += sampled
                bar.update(sampled)
                bar.set_postfix(result_postfix(result), refresh=True)
                for tag, value in tb_scalars(result).items():
                    self.writer.add_scalar(tag, value, self.steps)
                self.writer.flush()  # tensorboard (and a watcher) sees each iteration
                if self.steps - self.last_saved >= self.record.run.checkpoint_freq:
                    self.save_checkpoint()

    def save_checkpoint(self) -> CheckpointRef | None:
        """Save ``checkpoints/rllib_<steps>`` if an iteration ended since the last one."""
        if self.algo is None or self.steps <= self.last_saved:
            return None
        path = save_checkpoint(self.algo, rllib_checkpoint_path(self.out, self.steps), self.steps)
        self.last_saved = self.steps
        return CheckpointRef(self.steps, path)

    def save_final(self) -> Path:
        """The last checkpoint (unless saved) and ``rllib_model``."""
        self.save_checkpoint()
        return save_checkpoint(self.algo, self.out / RLLIB_MODEL_DIR, self.steps)

    def close(self, interrupted: bool) -> None:
        """Close tensorboard's writer and stop the algorithm (its env runners)."""
        if self.writer is not None:
            self.writer.close()
        if self.algo is not None:
            try:
                self.algo.stop()
            except Exception as exc:  # the cluster went away: nothing left to stop
                logger.warning("stopping the algorithm failed: %s", exc)

    @classmethod
    def load_policy(cls, path: Path) -> tuple[Any, TrainingRecord]:
        """An RLlib checkpoint folder
        (:func:`~aldm_gym.training.rllib.policy.load_rllib_policy`)."""
        from aldm_gym.training.rllib.policy import load_rllib_policy

        return load_rllib_policy(path)


def train_rllib(
    out: Path,
    *,
    detector: str = "aldm",
    marking_model: str = "per_dash",
    timesteps: int | None = None,
    num_env_runners: int | None = None,
    address: str | None = None,
    seed: int | None = None,
    checkpoint_freq: int | None = None,
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = DEFAULT_COLLISION_REWARD,
    overtaking_reward: float | None = None,
    env_overrides: Mapping[str, Any] | None = None,
    params: PPOParams | None = None,
    resume: bool = False,
    progress: bool = True,
    algo: str = "ppo",
) -> int:
    """Train (or resume) a PPO policy with RLlib; return the steps trained [env steps].

    :param out: output folder (see the module docstring); held locked while training.
    :param timesteps: total env steps (counting those before a resume), rounded up to
        whole updates; default :data:`~aldm_gym.training.settings.DEFAULT_TIMESTEPS`.
    :param num_env_runners: remote env runners, one CPU each (default
        :data:`~aldm_gym.training.settings.DEFAULT_ENV_RUNNERS`; 0 samples in the
        driver process).
    :param address: a running Ray cluster (``"auto"`` or ``"host:port"``); None starts
        a local Ray instance for this training.
    :param seed: seed of the envs and networks (0).
    :param checkpoint_freq: checkpoint every this many env steps (default
        :data:`~aldm_gym.training.settings.DEFAULT_CHECKPOINT_FREQ`), and at the end.
    :param duration, vehicles_count, collision_reward, overtaking_reward: env overrides, as for
        :func:`~aldm_gym.training.sb3.backend.train`.
    :param env_overrides: any other env settings, as for
        :func:`~aldm_gym.training.sb3.backend.train`.
    :param algo: ``"ppo"``, or ``"maskable-ppo"``: PPO through RLlib's action-masking
        module (:mod:`aldm_gym.training.rllib.masking`); a resume keeps the training's.
    :param resume: continue from the newest complete checkpoint of ``out`` with the env
        config, hyperparameters and run settings of its ``training.json`` (settings
        given here override the saved ones).
    :raises FileExistsError: ``out`` holds a training and ``resume`` is False.
    :raises FileNotFoundError: ``resume`` without a ``training.json`` in ``out``.
    :raises ConfigError: a bad setting.
    :raises ResumeError: ``resume`` of an SB3 training.
    :raises ClusterError: the cluster is not there, refuses this process or is too
        small.
    :raises MissingRayDependencies: Ray RLlib / torch missing.
    :raises KeyboardInterrupt: stopped by Ctrl-C or SIGTERM (after saving a checkpoint
        of the last iteration that finished).
    """
    backend = train_with(
        RLlibBackend,
        out,
        given={
            "timesteps": timesteps,
            "num_env_runners": num_env_runners,
            "seed": seed,
            "checkpoint_freq": checkpoint_freq,
        },
        config=env_config(
            detector,
            marking_model,
            duration,
            vehicles_count,
            collision_reward,
            overtaking_reward,
            env_overrides,
        ),
        params=params,
        resume=resume,
        progress=progress,
        algorithm=algorithm_name(algo),
        address=address,
    )
    return backend.steps
