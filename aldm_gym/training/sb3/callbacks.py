"""stable-baselines3 callbacks of :class:`~aldm_gym.training.sb3.backend.SB3Backend`.

* :class:`RolloutCheckpointCallback`: SB3's ``CheckpointCallback`` snapshotting the
  training between rollouts and saving a snapshot periodically and on an interruption.
* :class:`ValidationCallback`: plays fixed validation seeds every ``validation_freq``
  steps and keeps the best model (see :mod:`aldm_gym.training.sb3.backend`); reports a
  progress line before each validation and one with its result beside the rule-based
  LCA's and IDLE's on the same seeds (:func:`format_validation`).
* :class:`ProgressCallback`: the training's progress bar
  (:func:`~aldm_gym.training.progress.training_bar`), showing the mean return and
  length of the recent training episodes (SB3's ``ep_info_buffer``, filled by the
  ``Monitor`` wrapper).

This module imports stable-baselines3 at import time (the classes subclass its
callbacks); the backend imports it only when a training runs.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import gymnasium as gym
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.utils import safe_mean
from tqdm import tqdm

from aldm_gym import ENV_ID
from aldm_gym.agents.episodes import EpisodeStats, run_episodes, summarize
from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA
from aldm_gym.training.outputs import (
    BEST_MODEL_FILE,
    BEST_VECNORM_FILE,
    CHECKPOINT_DIR,
    VALIDATION_FILE,
    VALIDATION_PLOT,
    checkpoint_paths,
    manifest_path,
    write_json,
)
from aldm_gym.training.progress import postfix, report, training_bar
from aldm_gym.training.sb3.checkpoints import (
    Snapshot,
    checkpoint_fault,
    save_model,
    take_snapshot,
    write_checkpoint,
)
from aldm_gym.training.sb3.envs import global_rng_state, set_global_rng_state
from aldm_gym.training.sb3.policy import NormalizedModel
from aldm_gym.training.settings import VALIDATION_SEED, check_keep_by, validation_score


class RolloutCheckpointCallback(CheckpointCallback):
    """SB3's ``CheckpointCallback``, saving consistent snapshots between rollouts.

    At the start of every rollout (after the previous rollout's PPO update) the
    training's state is taken as one :class:`~aldm_gym.training.sb3.checkpoints.Snapshot`:
    model, normalisation statistics, envs, last observation and RNG states of the same
    instant. It is written as a checkpoint (``model_<steps>_steps.zip``, ...) when at
    least ``save_freq`` policy steps have passed since the last one, and by
    :meth:`save_last_snapshot` when training is interrupted. SB3's own callback saves
    every ``save_freq`` calls of ``_on_step``, i.e. mid-rollout, where the weights do
    not reflect the steps counted and the normalisation has seen samples that never
    reached an update; here an interruption anywhere (collecting, or halfway through
    an update) saves the state of the last completed update under its own step count.

    :param save_freq: policy steps between checkpoints [policy steps].
    :param out: the training's output folder.
    :ivar snapshot: the state at the start of the current rollout (None before the
        first rollout).
    """

    def __init__(self, save_freq: int, out: Path, verbose: int = 0) -> None:
        super().__init__(
            save_freq,
            str(Path(out) / CHECKPOINT_DIR),
            name_prefix="model",
            save_vecnormalize=True,
            verbose=verbose,
        )
        self.out = Path(out)
        self.last_saved = 0
        self.snapshot: Snapshot | None = None

    @property
    def snapshot_steps(self) -> int | None:
        """Step count of :attr:`snapshot` [policy steps], or None."""
        return None if self.snapshot is None else self.snapshot.steps

    def _on_training_start(self) -> None:
        self.last_saved = self.model.num_timesteps

    def _on_rollout_start(self) -> None:
        # Called after the previous rollout's update: a consistent state. A signal
        # arriving while it is taken leaves the previous snapshot in place.
        self.snapshot = take_snapshot(self.model)
        if self.snapshot.steps - self.last_saved >= self.save_freq:
            self._write(self.snapshot)

    def _on_step(self) -> bool:
        return True  # saves happen between rollouts, not per step as in SB3's

    def _write(self, snapshot: Snapshot) -> Path:
        self.last_saved = snapshot.steps
        return write_checkpoint(self.out, snapshot)

    def save_last_snapshot(self) -> Path | None:
        """Write :attr:`snapshot` unless an intact checkpoint of its step count exists
        (it holds the same state); the checkpoint's model path, or None if no rollout
        started."""
        if self.snapshot is None:
            return None
        steps = self.snapshot.steps
        if manifest_path(self.out, steps).exists() and checkpoint_fault(self.out, steps) is None:
            return checkpoint_paths(self.out, steps)[0]
        return self._write(self.snapshot)


@contextmanager
def _rng_preserved() -> Iterator[None]:
    """Leave the global RNGs as they were: what runs inside (validation episodes)
    must not change the training's random stream, or a resume would not be exact."""
    state = global_rng_state()
    try:
        yield
    finally:
        set_global_rng_state(state)


_VALIDATION_METRICS = ("success_rate", "mean_speed", "collisions", "departures_per_km")


def validation_row(episodes: list[EpisodeStats]) -> dict[str, Any]:
    """Metrics of one validation: mean return (the training objective) and
    success rate, mean speed [m/s], collisions, departures per km."""
    metrics = summarize(episodes)
    return {
        "mean_return": float(sum(e.reward for e in episodes) / len(episodes)),
        **{k: metrics[k] for k in _VALIDATION_METRICS},
    }


def _row_text(row: dict[str, Any], episodes: int) -> str:
    return (
        f"return {row['mean_return']:.2f}, success {row['success_rate']:.0%}, "
        f"{row['mean_speed']:.1f} m/s, {row['collisions']}/{episodes} collided"
    )


def format_validation(
    row: dict[str, Any], baselines: dict[str, Any], episodes: int, best: bool
) -> str:
    """One progress line: a validation's result with the baselines' on the same seeds.

    :param row: the validation (:func:`validation_row` and ``steps``).
    :param baselines: ``{"rule_based": row, "idle": row}`` (:func:`validation_row`).
    :param episodes: episodes per validation.
    :param best: the validation is the best so far (its model is ``best_model.zip``).
    """
    text = f"validation at {row['steps']} steps: {_row_text(row, episodes)}"
    text += " (best so far)" if best else ""
    for name, title in (("rule_based", "rule-based"), ("idle", "IDLE")):
        if name in baselines:
            text += f" | {title}: {_row_text(baselines[name], episodes)}"
    return text


class ValidationCallback(BaseCallback):
    """Validate on fixed seeds every ``validation_freq`` steps; keep the best model.

    The current policy (deterministic, with the training's normalisation) drives
    ``n_episodes`` episodes with seeds ``VALIDATION_SEED ..``; the one with the highest
    mean return (``keep_by="return"``) or
    :func:`~aldm_gym.training.settings.validation_score` (``keep_by="score"``) is
    saved as ``best_model.zip`` (the earliest of equals). Every validation goes to
    ``validation.json`` (with IDLE's and the rule-based LCA's metrics on the same
    seeds), ``validation.png`` and tensorboard (``validation/*``). A resume continues
    the saved record when its seeds match.

    Not SB3's ``EvalCallback``: that one scores with ``evaluate_policy`` on a
    ``VecEnv`` (no per-episode seeds, returns only) and triggers every ``eval_freq``
    calls mid-rollout; here every policy plays the same seeded episodes through
    :func:`~aldm_gym.agents.episodes.run_episodes` with ground-truth metrics, between
    rollouts.

    :param out: the training's output folder.
    :param env_config: ``ALDMHighway-v0`` config of the training.
    :param validation_freq: policy steps between validations [policy steps].
    :param n_episodes: episodes per validation.
    :param progress: show a bar over each validation's episodes (the training's bar
        stands still meanwhile). The progress lines before and after each validation
        are reported either way.
    :param validate_first: also validate the model as training starts (a model
        pretrained by cloning: it may stay the best).
    :param keep_by: ``"return"`` or ``"score"`` (:data:`~aldm_gym.training.settings.KEEP_BY`).
    """

    def __init__(
        self,
        out: Path,
        env_config: Mapping[str, Any],
        validation_freq: int,
        n_episodes: int,
        progress: bool = False,
        validate_first: bool = False,
        keep_by: str = "return",
    ) -> None:
        super().__init__()
        check_keep_by(keep_by)
        self.keep_by = keep_by
        self.progress = progress
        self.validate_first = validate_first
        self.out = Path(out)
        self.env_config = env_config
        self.validation_freq = validation_freq
        self.n_episodes = n_episodes
        self.env: Any = None
        self.last = 0
        self.history: list[dict[str, Any]] = []
        self.best: dict[str, Any] | None = None
        self.baselines: dict[str, Any] = {}

    @property
    def seeds(self) -> range:
        """The validation episodes' seeds."""
        return range(VALIDATION_SEED, VALIDATION_SEED + self.n_episodes)

    def _on_training_start(self) -> None:
        self.last = self.model.num_timesteps
        self.env = gym.make(ENV_ID, config=self.env_config)
        path = self.out / VALIDATION_FILE
        saved: dict[str, Any] = {}
        if path.exists() and self.model.num_timesteps > 0:  # a resume
            saved = json.loads(path.read_text())
        if saved.get("seeds") != [self.seeds[0], self.seeds[-1]]:
            saved = {}  # other validation episodes: not comparable, start afresh
        if saved:
            self.history = [h for h in saved["history"] if h["steps"] <= self.model.num_timesteps]
            best = [h for h in self.history if h["steps"] == saved.get("best_steps")]
            self.best = best[0] if best else None
        self.baselines = saved.get("baselines") or {}
        if not self.baselines:
            report(f"validating the baselines (IDLE, rule-based) on seeds {self._seed_text}…")
            with _rng_preserved():
                for name, policy in (("idle", IdlePolicy()), ("rule_based", RuleBasedLCA())):
                    self.baselines[name] = validation_row(self._play(policy, name))
        if self.validate_first and not self.history:
            self.validate()

    @property
    def _seed_text(self) -> str:
        return f"{self.seeds[0]}..{self.seeds[-1]} ({self.n_episodes} episodes)"

    def _play(self, policy: Any, name: str) -> list[EpisodeStats]:
        """The validation episodes with ``policy``, under a bar if :attr:`progress`."""
        with tqdm(
            total=self.n_episodes,
            desc=f"validating {name}",
            unit="ep",
            leave=False,
            disable=not self.progress,
        ) as bar:
            return run_episodes(self.env, policy, self.seeds, bar.update)

    def _on_rollout_start(self) -> None:
        if self.model.num_timesteps - self.last >= self.validation_freq:
            self.validate()

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        if self.model.num_timesteps > self.last or self.best is None:
            self.validate()
        self.env.close()

    def _merit(self, row: dict[str, Any]) -> float:
        """What :attr:`keep_by` ranks validations by."""
        return validation_score(row) if self.keep_by == "score" else float(row["mean_return"])

    def validate(self) -> None:
        """Play the validation seeds now; record, log, and keep the model if best."""
        from aldm_gym.agents.figures import plot_validation

        steps = self.model.num_timesteps
        self.last = steps
        policy = NormalizedModel(self.model, self.model.get_vec_normalize_env())
        report(f"validating at {steps} steps on seeds {self._seed_text}…")
        with _rng_preserved():
            episodes = self._play(policy, "model")
        row = {"steps": int(steps), **validation_row(episodes)}
        for key in ("mean_return", "success_rate", "mean_speed", "collisions"):
            self.logger.record(f"validation/{key}", row[key])
        self.history.append(row)
        if self.best is None or self._merit(row) > self._merit(self.best):
            self.best = row
            save_model(self.model, self.out / BEST_MODEL_FILE, self.out / BEST_VECNORM_FILE)
        record = {
            "seeds": [VALIDATION_SEED, VALIDATION_SEED + self.n_episodes - 1],
            "keep_by": self.keep_by,
            "best_steps": self.best["steps"],
            "baselines": self.baselines,
            "history": self.history,
        }
        write_json(self.out / VALIDATION_FILE, record)
        plot_validation(record, self.out / VALIDATION_PLOT, label=type(self.model).__name__)
        report(format_validation(row, self.baselines, self.n_episodes, self.best is row))


class ProgressCallback(BaseCallback):
    """tqdm bar over the policy steps of the whole (possibly resumed) training.

    After every rollout its postfix shows the mean return (``ep_rew``) and length
    (``ep_len`` [policy steps]) of the last training episodes, from SB3's
    ``ep_info_buffer`` (the last episodes the ``Monitor`` wrapper reported, at most
    SB3's ``stats_window_size``, 100), the numbers SB3 logs as ``rollout/ep_rew_mean``
    and ``rollout/ep_len_mean`` (``-`` before the first episode ends).

    Not SB3's ``ProgressBarCallback``: that one needs ``rich`` and counts only the
    steps of the current ``learn`` call.

    :param total: the training's total budget [policy steps].
    """

    def __init__(self, total: int) -> None:
        super().__init__()
        self.total = total
        self.bar: Any = None

    def _on_training_start(self) -> None:
        self.bar = training_bar(self.total, self.model.num_timesteps)

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        return True

    def _on_rollout_end(self) -> None:
        self.bar.set_postfix(episode_postfix(self.model.ep_info_buffer), refresh=True)

    def _on_training_end(self) -> None:
        self.bar.close()


def episode_postfix(ep_info_buffer: Any) -> dict[str, str]:
    """The bar's postfix (:func:`~aldm_gym.training.progress.postfix`) from the
    episodes in SB3's ``ep_info_buffer`` (Monitor's ``{"r": return, "l": length, ...}``
    per episode)."""
    infos = list(ep_info_buffer or ())
    if not infos:
        return postfix(None, None)
    return postfix(
        float(safe_mean([info["r"] for info in infos])),
        float(safe_mean([info["l"] for info in infos])),
    )
