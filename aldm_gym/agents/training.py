"""PPO lane-change policies on ``ALDMHighway-v0``: :func:`train` (``aldm-gym train``).

:func:`train` fits a stable-baselines3 PPO ``MultiInputPolicy`` on the meta actions
(``Discrete(5)``) of ``ALDMHighway-v0`` with the observation built from one detector's
lanes (``naive``, ``aldm`` or ``ground_truth``). Environments run vectorised
(``SubprocVecEnv`` for more than one), observations are normalised with running
statistics (``VecNormalize``), tensorboard logs go to ``<out>/tb/`` and checkpoints
(model ``.zip`` + normalisation ``.pkl``) to ``<out>/checkpoints/`` every
``checkpoint_freq`` steps and on an interruption (Ctrl-C, SIGTERM). ``resume=True``
continues from the latest checkpoint with the step count, tensorboard run, optimiser
state and normalisation statistics of the interrupted run. The output folder's files
are described in :mod:`aldm_gym.agents.checkpoints`; the callbacks that write them are
in :mod:`aldm_gym.agents.callbacks`.

Validation: every ``validation_freq`` steps (after the PPO update that ends a rollout)
and at the end, the current policy drives ``validation_episodes`` episodes with the
fixed seeds ``VALIDATION_SEED ..`` (deterministic actions), disjoint from the training
envs' seeds (``seed ..``) and from :func:`~aldm_gym.agents.model_evaluation.evaluate`'s
(``10000 ..``). The policy with the highest mean episode return (the env's reward,
i.e. the objective the training optimises) is kept as ``best_model.zip``. PPO on this
task is not monotone: collisions are rare events and successive checkpoints of one run
differ by several collisions in 30 episodes, so choosing on held-out seeds is what
makes a training's result reproducible without peeking at the evaluation seeds.

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

import functools
import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from aldm_gym import ENV_ID
from aldm_gym.agents.checkpoints import (
    MODEL_FILE,
    TENSORBOARD_DIR,
    TRAINING_FILE,
    VECNORM_FILE,
    can_resume,
    holds_training,
    latest_checkpoint,
    read_training,
    save_checkpoint,
    save_model,
    write_json,
)
from aldm_gym.agents.sb3 import import_sb3
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.detectors import DETECTORS

DEFAULT_TIMESTEPS = 49_152
"""Default training budget [policy steps] (about 15 min on 2 cores, see docs/results.md)."""

DEFAULT_COLLISION_REWARD = -2.0
"""Collision weight of a training's reward (the env's default is -1; see docs/results.md)."""

DEFAULT_CHECKPOINT_FREQ = 4_096
"""Default checkpoint period [policy steps]."""

DEFAULT_VALIDATION_FREQ = 4_096
"""Default validation period [policy steps]."""

DEFAULT_VALIDATION_EPISODES = 20
"""Default episodes per validation."""

VALIDATION_SEED = 20_000
"""First seed of the validation episodes (training envs use ``seed ..``, evaluation 10000..)."""

LR_SCHEDULES = ("constant", "linear")
"""Learning-rate schedules of :class:`PPOParams`."""


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
    import_sb3()
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    fns: list[Callable[[], Any]] = [functools.partial(_make_env, config) for _ in range(n_envs)]
    venv = SubprocVecEnv(fns) if n_envs > 1 else DummyVecEnv(fns)
    venv.seed(seed)
    return venv


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
    checkpoint_freq: int = DEFAULT_CHECKPOINT_FREQ,
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = DEFAULT_COLLISION_REWARD,
    params: PPOParams | None = None,
    validation_freq: int = DEFAULT_VALIDATION_FREQ,
    validation_episodes: int = DEFAULT_VALIDATION_EPISODES,
    resume: bool = False,
    progress: bool = True,
    verbose: int = 0,
    callback: Any = None,
) -> Any:
    """Train (or resume training) a PPO policy; return the SB3 model.

    :param out: output folder (its files: :mod:`aldm_gym.agents.checkpoints`).
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
    import_sb3()
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from aldm_gym.agents.callbacks import (
        ProgressCallback,
        RolloutCheckpointCallback,
        ValidationCallback,
    )

    out = Path(out)
    if timesteps < 1 or n_envs < 1 or checkpoint_freq < 1:
        raise ValueError("timesteps, n_envs and checkpoint_freq must be >= 1")
    if validation_freq < 0 or validation_episodes < 0:
        raise ValueError("validation_freq and validation_episodes must be >= 0")
    torch.set_num_threads(1)  # the envs need the cores; the MLP is tiny
    meta_path = out / TRAINING_FILE
    if resume:
        found = latest_checkpoint(out) if can_resume(out) else None
        if found is None:
            raise FileNotFoundError(f"nothing to resume in {out}: no checkpoint or {TRAINING_FILE}")
        meta = read_training(out)
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
        if holds_training(out):
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
            tensorboard_log=str(out / TENSORBOARD_DIR),
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
    write_json(meta_path, meta)
    model.tensorboard_log = str(out / TENSORBOARD_DIR)
    # In this order: on a rollout boundary the checkpoint is written before validating.
    checkpoints = RolloutCheckpointCallback(checkpoint_freq, out)
    callbacks: list[Any] = [checkpoints]
    if validation_freq > 0 and validation_episodes > 0:
        callbacks.append(ValidationCallback(out, config, validation_freq, validation_episodes))
    if progress:
        callbacks.append(ProgressCallback(int(timesteps)))
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
    save_model(model, out / MODEL_FILE, out / VECNORM_FILE)
    return model
