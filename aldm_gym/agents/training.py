"""PPO lane-change policies on ``ALDMHighway-v0``: ``aldm-gym train`` and ``aldm-gym evaluate``.

:func:`train` fits a stable-baselines3 PPO ``MultiInputPolicy`` on the meta actions
(``Discrete(5)``) of ``ALDMHighway-v0`` with the observation built from one detector's
lanes (``naive``, ``aldm`` or ``ground_truth``). Environments run vectorised
(``SubprocVecEnv`` for more than one), observations are normalised with running
statistics (``VecNormalize``), tensorboard logs go to ``<out>/tb/`` and checkpoints
(model ``.zip`` + normalisation ``.pkl``) to ``<out>/checkpoints/`` every
``checkpoint_freq`` steps and on an interruption (Ctrl-C, SIGTERM). ``resume=True``
continues from the latest checkpoint with the step count, tensorboard run, optimiser
state and normalisation statistics of the interrupted run.

:func:`evaluate` plays a trained model, :class:`~aldm_gym.agents.policies.RuleBasedLCA`
and :class:`~aldm_gym.agents.policies.IdlePolicy` on the same seeds with
:func:`~aldm_gym.agents.evaluation.run_episodes`.

Output folder of a training::

    <out>/training.json        env config, detector, hyperparameters, target steps
    <out>/model.zip            final model (SB3 PPO)
    <out>/vecnormalize.pkl     final observation normalisation
    <out>/checkpoints/model_<steps>_steps.zip, vecnormalize_<steps>_steps.pkl
    <out>/best_model.zip       the model of the best validation so far, with
    <out>/best_vecnormalize.pkl  its normalisation and
    <out>/validation.json      every validation's metrics, the best one's steps, and
                               IDLE's and the rule-based LCA's on the same seeds
    <out>/validation.png       the same as a figure
    <out>/tb/PPO_1/            tensorboard events

Validation: every ``validation_freq`` steps (after the PPO update that ends a rollout)
and at the end, the current policy drives ``validation_episodes`` episodes with the
fixed seeds ``VALIDATION_SEED ..`` (deterministic actions), disjoint from the training
envs' seeds (``seed ..``) and from :func:`evaluate`'s (``10000 ..``). The policy with
the highest mean episode return (the env's reward, i.e. the objective the training
optimises) is kept as ``best_model.zip``. PPO on this task is not monotone: collisions
are rare events and successive checkpoints of one run differ by several collisions in
30 episodes, so choosing on held-out seeds is what makes a training's result
reproducible without peeking at the evaluation seeds.

stable-baselines3 and torch are imported inside the functions: the CLI imports this
module to build its parser, and ``import aldm_gym`` stays light.

Why PPO rather than DQN: PPO is on-policy and collects its rollouts from all vectorised
environments at once, which is how the two cores of this machine are used (the env, not
the network, is the bottleneck); it is robust to hyperparameters on highway-env's meta
actions (highway-env's own PPO example trains in ~2e4 steps), and its state is the
weights, the optimiser and the step count, so a resume loses nothing. DQN would also
need its replay buffer checkpointed (hundreds of MB of Dict observations) for an exact
resume.
"""

from __future__ import annotations

import argparse
import functools
import json
import re
import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from aldm_gym.argtypes import fraction, non_negative_int, positive_float, positive_int
from aldm_gym.envs.config import DETECTORS, MARKING_MODELS
from aldm_gym.report import format_table

ENV_ID = "ALDMHighway-v0"
"""The environment trained and evaluated."""

TRAINING_FILE = "training.json"
"""Metadata written next to the model: env config, detector, hyperparameters."""

MODEL_FILE = "model.zip"
VECNORM_FILE = "vecnormalize.pkl"
CHECKPOINT_DIR = "checkpoints"
BEST_MODEL_FILE = "best_model.zip"
BEST_VECNORM_FILE = "best_vecnormalize.pkl"
VALIDATION_FILE = "validation.json"
VALIDATION_PLOT = "validation.png"

DEFAULT_TIMESTEPS = 49_152
"""Default training budget [policy steps] (about 15 min on 2 cores, see docs/results.md)."""

DEFAULT_COLLISION_REWARD = -2.0
"""Collision weight of a training's reward (the env's default is -1; see docs/results.md)."""

VALIDATION_SEED = 20_000
"""First seed of the validation episodes (training envs use ``seed ..``, evaluation 10000..)."""

EVAL_COLUMNS = (
    "policy",
    "success_rate",
    "mean_speed",
    "lane_changes_ok",
    "lane_changes_failed",
    "departures_per_km",
    "collisions",
)
"""Columns of the evaluation table (metrics from :func:`summarize`)."""

_CHECKPOINT_RE = re.compile(r"model_(\d+)_steps\.zip$")


class MissingRLDependencies(ImportError):
    """stable-baselines3 or torch is not installed."""


def _import_sb3() -> Any:
    """Import stable_baselines3 (and torch) or raise a clear error."""
    try:
        import stable_baselines3
        import torch  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise MissingRLDependencies(
            f"training needs stable-baselines3, torch and tensorboard ({exc}); "
            "install them with: pip install 'aldm-gym[rl]'"
        ) from exc
    return stable_baselines3


@dataclass
class PPOParams:
    """PPO hyperparameters (SB3 names).

    Defaults follow highway-env's PPO example for the meta actions (``gamma`` 0.8:
    at 1 Hz the reward of the next ~5 s matters; lr 5e-4, 10 epochs, batch 64), with
    the learning rate decaying linearly (see ``docs/results.md`` (b) for why).

    :ivar n_steps: rollout length per environment [policy steps].
    :ivar lr_schedule: ``"constant"``, or ``"linear"``: ``learning_rate`` decays
        linearly to 0 at the end of the budget (SB3's ``progress_remaining``).
    """

    n_steps: int = 256
    batch_size: int = 64
    n_epochs: int = 10
    learning_rate: float = 5e-4
    gamma: float = 0.8
    gae_lambda: float = 0.95
    ent_coef: float = 0.01
    clip_range: float = 0.2
    net_arch: list[int] = field(default_factory=lambda: [128, 128])
    lr_schedule: str = "linear"

    def __post_init__(self) -> None:
        if self.lr_schedule not in LR_SCHEDULES:
            raise ValueError(f"lr_schedule must be one of {LR_SCHEDULES}, got {self.lr_schedule!r}")

    def learning_rate_schedule(self) -> float | Callable[[float], float]:
        """What SB3's ``learning_rate`` argument takes for this schedule."""
        if self.lr_schedule == "linear":
            return functools.partial(_linear, self.learning_rate)
        return self.learning_rate


LR_SCHEDULES = ("constant", "linear")
"""Learning-rate schedules of :class:`PPOParams`."""


def _linear(start: float, progress_remaining: float) -> float:
    """``start`` scaled by SB3's ``progress_remaining`` (1 at the start, 0 at the end)."""
    return start * progress_remaining


def env_config(
    detector: str = "aldm",
    marking_model: str = "per_dash",
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = None,
) -> dict[str, Any]:
    """The ``ALDMHighway-v0`` config of a training (only keys that differ from defaults).

    :param collision_reward: weight of the collision term of the reward (env: -1).
    :raises ValueError: unknown detector or marking model.
    """
    if detector not in DETECTORS:
        raise ValueError(f"detector must be one of {DETECTORS}, got {detector!r}")
    if marking_model not in MARKING_MODELS:
        raise ValueError(f"marking_model must be one of {MARKING_MODELS}, got {marking_model!r}")
    config: dict[str, Any] = {"detector": detector, "marking_model": marking_model}
    if duration is not None:
        config["duration"] = float(duration)
    if vehicles_count is not None:
        config["vehicles_count"] = int(vehicles_count)
    if collision_reward is not None:
        config["collision_reward"] = float(collision_reward)
    return config


def _make_env(config: dict[str, Any]) -> Any:
    """One monitored env (module level so ``SubprocVecEnv`` can pickle the factory)."""
    import gymnasium as gym
    from stable_baselines3.common.monitor import Monitor

    import aldm_gym  # noqa: F401  (registers the env in a fresh subprocess)

    return Monitor(gym.make(ENV_ID, config=config))


def make_vec_env(config: dict[str, Any], n_envs: int, seed: int) -> Any:
    """``n_envs`` copies of the env: ``SubprocVecEnv`` for several, else ``DummyVecEnv``.

    The i-th env's first reset uses ``seed + i``.
    """
    _import_sb3()
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    fns: list[Callable[[], Any]] = [functools.partial(_make_env, config) for _ in range(n_envs)]
    venv = SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)
    venv.seed(seed)
    return venv


def latest_checkpoint(out: Path) -> tuple[Path, Path, int] | None:
    """``(model.zip, vecnormalize.pkl, steps)`` of the newest complete checkpoint in
    ``<out>/checkpoints``, or None."""
    found = []
    for path in (Path(out) / CHECKPOINT_DIR).glob("model_*_steps.zip"):
        match = _CHECKPOINT_RE.search(path.name)
        vecnorm = path.with_name(f"vecnormalize_{match.group(1)}_steps.pkl") if match else None
        if match and vecnorm is not None and vecnorm.exists():
            found.append((int(match.group(1)), path, vecnorm))
    if not found:
        return None
    steps, model, vecnorm = max(found)
    return model, vecnorm, steps


def _callbacks(
    out: Path,
    checkpoint_freq: int,
    target: int,
    progress: bool,
    config: dict[str, Any],
    validation_freq: int,
    validation_episodes: int,
) -> Any:
    """SB3 callbacks: periodic checkpoints, validation (see the module docstring) and a
    tqdm bar (SB3's own needs ``rich``).

    :return: ``(checkpoints, list of all callbacks)``.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class Checkpoints(BaseCallback):
        """Save model + VecNormalize at the end of a rollout every ``checkpoint_freq`` steps.

        Saving after the PPO update that ends a rollout (not mid-rollout) keeps a
        checkpoint's weights, optimiser and step count consistent.
        """

        def __init__(self) -> None:
            super().__init__()
            self.last_saved = 0
            self.rollout_start = 0

        def _on_training_start(self) -> None:
            self.last_saved = self.model.num_timesteps
            self.rollout_start = self.model.num_timesteps

        def _on_rollout_start(self) -> None:
            # Called after the previous rollout's update: the state to save on interrupt.
            self.rollout_start = self.model.num_timesteps
            if self.model.num_timesteps - self.last_saved >= checkpoint_freq:
                self.save()

        def _on_step(self) -> bool:
            return True

        def save(self, steps: int | None = None) -> Path:
            steps = self.model.num_timesteps if steps is None else steps
            self.last_saved = steps
            return save_checkpoint(self.model, out, steps)

    class Progress(BaseCallback):
        """tqdm bar over the policy steps of the whole (possibly resumed) training."""

        def __init__(self) -> None:
            super().__init__()
            self.bar: Any = None

        def _on_training_start(self) -> None:
            from tqdm import tqdm

            self.bar = tqdm(
                total=target, initial=self.model.num_timesteps, desc="train", unit="step"
            )

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    class Validation(BaseCallback):
        """Validate on fixed seeds every ``validation_freq`` steps; keep the best model."""

        def __init__(self) -> None:
            super().__init__()
            self.env: Any = None
            self.last = 0
            self.history: list[dict[str, Any]] = []
            self.best: dict[str, Any] | None = None
            self.baselines: dict[str, Any] = {}

        def _on_training_start(self) -> None:
            import gymnasium as gym

            from aldm_gym.agents.evaluation import run_episodes
            from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA

            self.last = self.model.num_timesteps
            self.env = gym.make(ENV_ID, config=config)
            path = out / VALIDATION_FILE
            saved: dict[str, Any] = {}
            if path.exists() and self.model.num_timesteps > 0:  # a resume
                saved = json.loads(path.read_text())
            if saved.get("seeds") != [self.seeds[0], self.seeds[-1]]:
                saved = {}  # other validation episodes: not comparable, start afresh
            if saved:
                self.history = [
                    h for h in saved["history"] if h["steps"] <= self.model.num_timesteps
                ]
                best = [h for h in self.history if h["steps"] == saved.get("best_steps")]
                self.best = best[0] if best else None
            self.baselines = saved.get("baselines") or {
                name: self.row(run_episodes(self.env, policy, self.seeds))
                for name, policy in (("idle", IdlePolicy()), ("rule_based", RuleBasedLCA()))
            }

        @property
        def seeds(self) -> range:
            return range(VALIDATION_SEED, VALIDATION_SEED + validation_episodes)

        @staticmethod
        def row(episodes: list[Any]) -> dict[str, Any]:
            from aldm_gym.agents.evaluation import summarize

            metrics = summarize(episodes)
            return {
                "mean_return": float(sum(e.reward for e in episodes) / len(episodes)),
                **{
                    k: metrics[k]
                    for k in ("success_rate", "mean_speed", "collisions", "departures_per_km")
                },
            }

        def _on_rollout_start(self) -> None:
            if self.model.num_timesteps - self.last >= validation_freq:
                self.validate()

        def _on_step(self) -> bool:
            return True

        def _on_training_end(self) -> None:
            if self.model.num_timesteps > self.last or self.best is None:
                self.validate()
            self.env.close()

        def validate(self) -> None:
            from aldm_gym.agents.evaluation import run_episodes

            steps = self.model.num_timesteps
            self.last = steps
            policy = NormalizedModel(self.model, self.model.get_vec_normalize_env())
            row = {"steps": int(steps), **self.row(run_episodes(self.env, policy, self.seeds))}
            for key in ("mean_return", "success_rate", "mean_speed", "collisions"):
                self.logger.record(f"validation/{key}", row[key])
            self.history.append(row)
            if self.best is None or row["mean_return"] > self.best["mean_return"]:
                self.best = row
                _save_atomic(self.model.save, out / BEST_MODEL_FILE)
                vecnorm = self.model.get_vec_normalize_env()
                if vecnorm is not None:
                    _save_atomic(vecnorm.save, out / BEST_VECNORM_FILE)
            record = {
                "seeds": [VALIDATION_SEED, VALIDATION_SEED + validation_episodes - 1],
                "best_steps": self.best["steps"],
                "baselines": self.baselines,
                "history": self.history,
            }
            _save_atomic(
                lambda p: Path(p).write_text(json.dumps(record, indent=2) + "\n"),
                out / VALIDATION_FILE,
            )
            plot_validation(record, out / VALIDATION_PLOT)

    checkpoints = Checkpoints()
    callbacks: list[Any] = [checkpoints]
    if validation_freq > 0 and validation_episodes > 0:
        callbacks.append(Validation())
    if progress:
        callbacks.append(Progress())
    return checkpoints, callbacks


def save_checkpoint(model: Any, out: Path, steps: int) -> Path:
    """Write ``<out>/checkpoints/model_<steps>_steps.zip`` and its VecNormalize stats.

    The model is saved with ``num_timesteps = steps`` (so an interrupted rollout, whose
    samples never reached an update, is collected again on resume).
    """
    folder = Path(out) / CHECKPOINT_DIR
    folder.mkdir(parents=True, exist_ok=True)
    current = model.num_timesteps
    model.num_timesteps = steps
    try:
        path = folder / f"model_{steps}_steps.zip"
        _save_atomic(model.save, path)
        vecnorm = model.get_vec_normalize_env()
        if vecnorm is not None:
            _save_atomic(vecnorm.save, folder / f"vecnormalize_{steps}_steps.pkl")
    finally:
        model.num_timesteps = current
    return path


def _save_atomic(save: Any, path: Path) -> None:
    """``save(tmp)`` then rename: an interruption never leaves a truncated file."""
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    save(tmp)
    tmp.replace(path)


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt (``kill PID`` checkpoints like Ctrl-C)."""

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def train(
    out: Path,
    *,
    detector: str = "aldm",
    marking_model: str = "per_dash",
    timesteps: int = DEFAULT_TIMESTEPS,
    n_envs: int = 1,
    seed: int = 0,
    checkpoint_freq: int = 4_096,
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = DEFAULT_COLLISION_REWARD,
    params: PPOParams | None = None,
    validation_freq: int = 4_096,
    validation_episodes: int = 20,
    resume: bool = False,
    progress: bool = True,
    verbose: int = 0,
    callback: Any = None,
) -> Any:
    """Train (or resume training) a PPO policy; return the SB3 model.

    :param out: output folder (see the module docstring for its layout).
    :param timesteps: total policy steps of the training (counting steps done before a
        resume), rounded up to whole rollouts (``n_steps × n_envs``).
    :param checkpoint_freq: save a checkpoint every this many steps [policy steps].
    :param duration, vehicles_count, collision_reward: env overrides (None: the env's
        defaults).

    The defaults (one env, 49152 steps, collision weight -2, linearly decaying learning
    rate) are the recipe of ``docs/results.md`` (b). It is sensitive to the rollout size:
    two envs with the same or with halved rollouts missed the aim there.
    :param validation_freq: validate every this many steps (0: never) [policy steps].
    :param validation_episodes: episodes per validation (seeds ``VALIDATION_SEED ..``).
    :param callback: extra SB3 callback(s) (a list or one).
    :param resume: continue from the latest checkpoint of ``out``; the env config and
        hyperparameters are those saved in ``<out>/training.json``, ``n_envs`` and
        ``timesteps`` may change.
    :raises FileExistsError: ``out`` holds a training and ``resume`` is False.
    :raises FileNotFoundError: ``resume`` without a checkpoint in ``out``.
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    """
    _import_sb3()
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    out = Path(out)
    if timesteps < 1 or n_envs < 1 or checkpoint_freq < 1:
        raise ValueError("timesteps, n_envs and checkpoint_freq must be >= 1")
    if validation_freq < 0 or validation_episodes < 0:
        raise ValueError("validation_freq and validation_episodes must be >= 0")
    torch.set_num_threads(1)  # the envs need the cores; the MLP is tiny
    meta_path = out / TRAINING_FILE
    if resume:
        found = latest_checkpoint(out)
        if found is None or not meta_path.exists():
            raise FileNotFoundError(f"nothing to resume in {out}: no checkpoint or {TRAINING_FILE}")
        meta = json.loads(meta_path.read_text())
        config = meta["env_config"]
        # Trainings written before lr_schedule existed ran with a constant rate.
        params = PPOParams(**{"lr_schedule": "constant", **meta["ppo"]})
        model_path, vecnorm_path, done = found
        venv = make_vec_env(config, n_envs, seed + done)
        venv = VecNormalize.load(str(vecnorm_path), venv)
        venv.training = True
        model = PPO.load(model_path, env=venv, device="cpu")
        # PPO.load takes n_envs from venv and rebuilds the rollout buffer for it.
        model.set_random_seed(seed + done)
    else:
        if meta_path.exists() or (out / MODEL_FILE).exists() or latest_checkpoint(out):
            raise FileExistsError(
                f"{out} already holds a training; pass --resume to continue it "
                "or choose another --out"
            )
        config = env_config(detector, marking_model, duration, vehicles_count, collision_reward)
        params = params or PPOParams()
        venv = VecNormalize(make_vec_env(config, n_envs, seed), norm_reward=False, clip_obs=10.0)
        model = PPO(
            "MultiInputPolicy",
            venv,
            n_steps=params.n_steps,
            batch_size=min(params.batch_size, params.n_steps * n_envs),
            n_epochs=params.n_epochs,
            learning_rate=params.learning_rate_schedule(),
            gamma=params.gamma,
            gae_lambda=params.gae_lambda,
            ent_coef=params.ent_coef,
            clip_range=params.clip_range,
            policy_kwargs={"net_arch": list(params.net_arch)},
            tensorboard_log=str(out / "tb"),
            seed=seed,
            device="cpu",
            verbose=verbose,
        )
        done = 0
    out.mkdir(parents=True, exist_ok=True)
    meta = {
        "algorithm": "PPO",
        "env_id": ENV_ID,
        "env_config": config,
        "ppo": asdict(params),
        "n_envs": n_envs,
        "seed": seed,
        "timesteps": int(timesteps),
        "checkpoint_freq": int(checkpoint_freq),
        "validation_freq": int(validation_freq),
        "validation_episodes": int(validation_episodes),
    }
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    model.tensorboard_log = str(out / "tb")
    checkpoints, callbacks = _callbacks(
        out,
        checkpoint_freq,
        int(timesteps),
        progress,
        config,
        validation_freq,
        validation_episodes,
    )
    if callback is not None:
        callbacks += callback if isinstance(callback, list) else [callback]
    interrupted = False
    t0 = time.perf_counter()
    try:
        with _sigterm_as_interrupt():
            if timesteps > done:
                model.learn(
                    total_timesteps=int(timesteps) - done,
                    callback=callbacks,
                    reset_num_timesteps=not resume,
                    tb_log_name="PPO",
                )
    except KeyboardInterrupt:
        interrupted = True
    finally:
        try:
            venv.close()
        except (EOFError, BrokenPipeError, ConnectionResetError):  # workers died with Ctrl-C
            pass
    if interrupted:
        path = checkpoints.save(checkpoints.rollout_start)
        print(
            f"\ninterrupted after {time.perf_counter() - t0:.0f} s; saved {path} "
            f"({checkpoints.rollout_start} steps); continue with --resume",
            file=sys.stderr,
        )
        raise KeyboardInterrupt
    save_checkpoint(model, out, model.num_timesteps)
    _save_atomic(model.save, out / MODEL_FILE)
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        _save_atomic(vecnorm.save, out / VECNORM_FILE)
    return model


def plot_validation(record: dict[str, Any], path: Path) -> None:
    """Plot a ``validation.json`` record: return, collisions and speed over training.

    Horizontal lines: IDLE and the rule-based LCA on the same seeds; the dotted
    vertical line marks the kept (best) model.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    history = record["history"]
    steps = [h["steps"] for h in history]
    n = record["seeds"][1] - record["seeds"][0] + 1
    panels = (
        ("mean_return", "mean return"),
        ("collisions", f"collisions [of {n} episodes]"),
        ("mean_speed", "mean speed [m/s]"),
    )
    fig, axes = plt.subplots(len(panels), 1, figsize=(6.4, 6.4), sharex=True)
    for ax, (key, label) in zip(axes, panels, strict=True):
        ax.plot(steps, [h[key] for h in history], "o-", color="C0", label="PPO")
        colours = {"idle": "C7", "rule_based": "C2"}
        for name, base in record.get("baselines", {}).items():
            ax.axhline(base[key], color=colours.get(name, "C1"), ls="--", lw=1, label=name)
        ax.axvline(record["best_steps"], color="C3", ls=":", lw=1, label="kept (best return)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    axes[-1].set_xlabel("training steps")
    fig.suptitle(f"validation on seeds {record['seeds'][0]}..{record['seeds'][1]}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --------------------------------------------------------------------------- evaluation


class NormalizedModel:
    """A trained model with its frozen observation normalisation, SB3 ``predict``."""

    def __init__(self, model: Any, vecnormalize: Any = None) -> None:
        self.model = model
        self.vecnormalize = vecnormalize

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """``(action, state)``; observations normalised as in training."""
        if self.vecnormalize is not None:
            observation = self.vecnormalize.normalize_obs(observation)
        return self.model.predict(
            observation, state=state, episode_start=episode_start, deterministic=deterministic
        )


def _find_training_file(model_path: Path) -> Path | None:
    for folder in (model_path.parent, model_path.parent.parent):
        if (folder / TRAINING_FILE).exists():
            return folder / TRAINING_FILE
    return None


def _vecnormalize_for(model_path: Path) -> Path | None:
    match = _CHECKPOINT_RE.search(model_path.name)
    if match:
        path = model_path.with_name(f"vecnormalize_{match.group(1)}_steps.pkl")
    elif model_path.name == BEST_MODEL_FILE:
        path = model_path.with_name(BEST_VECNORM_FILE)
    else:
        path = model_path.with_name(VECNORM_FILE)
    return path if path.exists() else None


def load_policy(model_path: Path) -> tuple[NormalizedModel, dict[str, Any]]:
    """Load a model ``.zip`` (final or checkpoint) and its ``training.json``.

    :return: the policy (with its observation normalisation) and the training metadata.
    :raises FileNotFoundError: no model, or no ``training.json`` next to it or in its
        parent folder.
    """
    _import_sb3()
    import pickle

    from stable_baselines3 import PPO

    model_path = Path(model_path)
    if not model_path.is_file():
        raise FileNotFoundError(f"no model file {model_path}")
    meta_path = _find_training_file(model_path)
    if meta_path is None:
        raise FileNotFoundError(
            f"no {TRAINING_FILE} next to {model_path} (written by aldm-gym train)"
        )
    meta = json.loads(meta_path.read_text())
    model = PPO.load(model_path, device="cpu")
    vecnorm = None
    vecnorm_path = _vecnormalize_for(model_path)
    if vecnorm_path is not None:
        with open(vecnorm_path, "rb") as fh:
            vecnorm = pickle.load(fh)  # VecNormalize without its venv: stats only
        vecnorm.training = False
    return NormalizedModel(model, vecnorm), meta


def evaluate(
    model_path: Path,
    episodes: int = 30,
    seed: int = 10_000,
    detector: str | None = None,
    marking_model: str | None = None,
    progress: bool = True,
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Evaluate a model against IDLE and the rule-based LCA on the same seeds.

    :param episodes: episodes per policy (seeds ``seed .. seed + episodes - 1``).
    :param detector, marking_model: override the training env's (None: as trained).
    :return: rows (``idle``, ``rule_based``, ``model``) with the :func:`summarize`
        metrics and ``policy``; and the evaluation's env config and model metadata.
    """
    import gymnasium as gym
    from tqdm import tqdm

    import aldm_gym  # noqa: F401
    from aldm_gym.agents.evaluation import run_episodes, summarize
    from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA

    policy, meta = load_policy(model_path)
    config = dict(meta["env_config"])
    if detector is not None:
        config["detector"] = env_config(detector=detector)["detector"]
    if marking_model is not None:
        config["marking_model"] = env_config(marking_model=marking_model)["marking_model"]
    env = gym.make(ENV_ID, config=config)
    seeds = range(seed, seed + episodes)
    rows = []
    try:
        with tqdm(total=3 * episodes, desc="evaluate", unit="ep", disable=not progress) as bar:
            for name, pol in (("idle", IdlePolicy()), ("rule_based", RuleBasedLCA())):
                rows.append(
                    {"policy": name, **summarize(run_episodes(env, pol, seeds, bar.update))}
                )
            rows.append(
                {"policy": "model", **summarize(run_episodes(env, policy, seeds, bar.update))}
            )
    finally:
        env.close()
    info = {
        "env_config": config,
        "trained_on": meta["env_config"],
        "timesteps": int(policy.model.num_timesteps),
        "seeds": [seed, seed + episodes - 1],
    }
    return rows, info


def summary_line(rows: list[dict[str, Any]], info: dict[str, Any]) -> str:
    """One sentence on the model against IDLE and the rule-based LCA."""
    by = {r["policy"]: r for r in rows}
    m, idle, rule = by["model"], by["idle"], by["rule_based"]
    dv = m["mean_speed"] - idle["mean_speed"]
    if dv > 0 and m["collisions"] <= idle["collisions"]:
        verdict = "beats IDLE on speed without more collisions"
    elif dv > 0:
        verdict = "is faster than IDLE but collides more"
    else:
        verdict = "is not faster than IDLE"
    trained = info["trained_on"]
    cfg = info["env_config"]
    return (
        f"model ({info['timesteps']} steps, trained on {trained['detector']}/"
        f"{trained['marking_model']}, evaluated on {cfg['detector']}/{cfg['marking_model']}, "
        f"{m['episodes']} episodes) {verdict}: success {m['success_rate']:.0%} "
        f"(IDLE {idle['success_rate']:.0%}, rule-based {rule['success_rate']:.0%}), "
        f"mean speed {m['mean_speed']:.1f} m/s ({dv:+.1f} vs IDLE, "
        f"{m['mean_speed'] - rule['mean_speed']:+.1f} vs rule-based), "
        f"collisions {m['collisions']} (IDLE {idle['collisions']}, rule-based "
        f"{rule['collisions']}), lane changes {m['lane_changes_ok']} ok / "
        f"{m['lane_changes_failed']} failed"
    )


# --------------------------------------------------------------------------- CLI


QUICK_TIMESTEPS = 1_024
"""``train --quick``: a smoke-test budget (about a minute)."""


def add_train_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``aldm-gym train``."""
    parser.add_argument(
        "--detector", choices=DETECTORS, default=None, help="lanes in the observation (aldm)"
    )
    parser.add_argument(
        "--marking-model", choices=MARKING_MODELS, default=None, help="road model (per_dash)"
    )
    parser.add_argument(
        "--timesteps",
        type=positive_int,
        default=None,
        help=f"total policy steps, counting steps before a resume ({DEFAULT_TIMESTEPS}; "
        f"--quick {QUICK_TIMESTEPS})",
    )
    parser.add_argument(
        "--n-envs",
        type=positive_int,
        default=1,
        help="parallel envs (1; more run in subprocesses, but change the results)",
    )
    parser.add_argument(
        "--n-steps", type=positive_int, default=None, help="PPO rollout length per env (256)"
    )
    parser.add_argument(
        "--checkpoint-freq",
        type=positive_int,
        default=4_096,
        help="checkpoint every this many steps (4096)",
    )
    parser.add_argument(
        "--gamma",
        type=fraction,
        default=None,
        help=f"discount factor per policy step ({PPOParams.gamma})",
    )
    parser.add_argument(
        "--lr-schedule",
        choices=LR_SCHEDULES,
        default=None,
        help="learning rate constant, or decaying linearly to 0 over --timesteps (linear)",
    )
    parser.add_argument(
        "--validation-freq",
        type=non_negative_int,
        default=None,
        help="validate (and keep best_model.zip) every this many steps, 0 = never "
        "(4096; --quick 0)",
    )
    parser.add_argument(
        "--validation-episodes",
        type=positive_int,
        default=None,
        help=f"episodes per validation, seeds {VALIDATION_SEED}.. (20)",
    )
    parser.add_argument(
        "--duration", type=positive_float, default=None, help="episode length [s] (env: 40)"
    )
    parser.add_argument(
        "--vehicles", type=non_negative_int, default=None, help="other vehicles (env: 20)"
    )
    parser.add_argument(
        "--collision-reward",
        type=float,
        default=None,
        help=f"weight of the collision penalty in the reward ({DEFAULT_COLLISION_REWARD}; "
        "the env's default is -1)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of envs and network (0)")
    parser.add_argument("--out", type=Path, default=Path("out/train"), help="output folder")
    parser.add_argument(
        "--resume", action="store_true", help="continue from the latest checkpoint in --out"
    )
    parser.add_argument("--quick", action="store_true", help="tiny budget (smoke test)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_evaluate_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``aldm-gym evaluate``."""
    parser.add_argument("--model", type=Path, required=True, help="model .zip (or checkpoint)")
    parser.add_argument(
        "--episodes", type=positive_int, default=None, help="episodes per policy (30; quick 5)"
    )
    parser.add_argument(
        "--detector", choices=DETECTORS, default=None, help="override the training detector"
    )
    parser.add_argument(
        "--marking-model", choices=MARKING_MODELS, default=None, help="override the road model"
    )
    parser.add_argument(
        "--seed", type=int, default=10_000, help="first episode seed (10000; training uses 0..)"
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="folder for evaluation JSON (the model's)"
    )
    parser.add_argument("--quick", action="store_true", help="5 episodes per policy")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run_train(args: argparse.Namespace) -> int:
    """``aldm-gym train``."""
    timesteps = args.timesteps or (QUICK_TIMESTEPS if args.quick else DEFAULT_TIMESTEPS)
    n_steps = args.n_steps or (64 if args.quick else 256)
    validation_freq = args.validation_freq
    if validation_freq is None:
        validation_freq = 0 if args.quick else 4_096
    validation_episodes = args.validation_episodes or 20
    out: Path = args.out
    if args.resume:
        meta_path = out / TRAINING_FILE
        if not meta_path.exists() or latest_checkpoint(out) is None:
            raise SystemExit(f"aldm-gym train: nothing to resume in {out} (no checkpoint)")
        meta = json.loads(meta_path.read_text())
        cfg = meta["env_config"]
        for name, value, saved in (
            ("--detector", args.detector, cfg["detector"]),
            ("--marking-model", args.marking_model, cfg["marking_model"]),
            ("--duration", args.duration, cfg.get("duration")),
            ("--vehicles", args.vehicles, cfg.get("vehicles_count")),
            ("--collision-reward", args.collision_reward, cfg.get("collision_reward")),
            ("--n-steps", args.n_steps, meta["ppo"]["n_steps"]),
            ("--lr-schedule", args.lr_schedule, meta["ppo"].get("lr_schedule", "constant")),
            ("--gamma", args.gamma, meta["ppo"]["gamma"]),
        ):
            if value is not None and value != saved:
                raise SystemExit(
                    f"aldm-gym train: {name} {value} contradicts the training being resumed "
                    f"({saved}); omit it with --resume"
                )
        timesteps = args.timesteps or meta["timesteps"]
        if args.validation_freq is None:
            validation_freq = meta.get("validation_freq", validation_freq)
        if args.validation_episodes is None:
            validation_episodes = meta.get("validation_episodes", validation_episodes)
    elif (out / TRAINING_FILE).exists() or latest_checkpoint(out) is not None:
        raise SystemExit(
            f"aldm-gym train: {out} already holds a training; pass --resume to continue it "
            "or choose another --out"
        )
    try:
        t0 = time.perf_counter()
        model = train(
            out,
            detector=args.detector or "aldm",
            marking_model=args.marking_model or "per_dash",
            timesteps=timesteps,
            n_envs=args.n_envs,
            seed=args.seed,
            checkpoint_freq=args.checkpoint_freq,
            duration=args.duration or (10.0 if args.quick else None),
            vehicles_count=args.vehicles,
            collision_reward=(
                DEFAULT_COLLISION_REWARD if args.collision_reward is None else args.collision_reward
            ),
            params=PPOParams(
                n_steps=n_steps,
                gamma=PPOParams.gamma if args.gamma is None else args.gamma,
                lr_schedule=args.lr_schedule or PPOParams.lr_schedule,
            ),
            validation_freq=validation_freq,
            validation_episodes=validation_episodes,
            resume=args.resume,
            progress=not args.no_progress,
        )
    except MissingRLDependencies as exc:
        raise SystemExit(f"aldm-gym train: {exc}") from None
    except KeyboardInterrupt:
        return 130
    print(
        f"trained {model.num_timesteps} steps in {time.perf_counter() - t0:.0f} s; wrote "
        f"{out / MODEL_FILE}, checkpoints in {out / CHECKPOINT_DIR}, tensorboard logs in "
        f"{out / 'tb'} (tensorboard --logdir {out / 'tb'})"
    )
    validation = out / VALIDATION_FILE
    if validation_freq > 0 and validation.exists():
        record = json.loads(validation.read_text())
        best = next(h for h in record["history"] if h["steps"] == record["best_steps"])
        print(
            f"best validation at {best['steps']} steps (mean return {best['mean_return']:.2f}, "
            f"success {best['success_rate']:.2f}, {best['mean_speed']:.2f} m/s): "
            f"{out / BEST_MODEL_FILE}; evaluate it with "
            f"aldm-gym evaluate --model {out / BEST_MODEL_FILE}"
        )
    return 0


def run_evaluate(args: argparse.Namespace) -> int:
    """``aldm-gym evaluate``."""
    episodes = args.episodes or (5 if args.quick else 30)
    if not args.model.is_file():
        raise SystemExit(f"aldm-gym evaluate: --model {args.model} is not a file")
    if _find_training_file(args.model) is None:
        raise SystemExit(
            f"aldm-gym evaluate: no {TRAINING_FILE} next to {args.model} "
            "(models are read from an aldm-gym train output folder)"
        )
    t0 = time.perf_counter()
    try:
        rows, info = evaluate(
            args.model,
            episodes=episodes,
            seed=args.seed,
            detector=args.detector,
            marking_model=args.marking_model,
            progress=not args.no_progress,
        )
    except MissingRLDependencies as exc:
        raise SystemExit(f"aldm-gym evaluate: {exc}") from None
    out: Path = args.out or args.model.parent
    out.mkdir(parents=True, exist_ok=True)
    cfg = info["env_config"]
    path = out / f"evaluate_{args.model.stem}_{cfg['detector']}_{cfg['marking_model']}.json"
    path.write_text(json.dumps({"rows": rows, **info}, indent=2) + "\n")
    print(f"wrote {path} ({time.perf_counter() - t0:.0f} s)")
    print(format_table(rows, EVAL_COLUMNS))
    print(summary_line(rows, info))
    return 0
