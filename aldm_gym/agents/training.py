"""PPO lane-change policies on ``ALDMHighway-v0``: :func:`train` (``aldm-gym train``).

:func:`train` fits a stable-baselines3 PPO ``MultiInputPolicy`` on the meta actions
(``Discrete(5)``) of ``ALDMHighway-v0`` with the observation built from one detector's
lanes (``naive``, ``aldm`` or ``ground_truth``). Environments run vectorised
(``SubprocVecEnv`` for more than one), observations are normalised with running
statistics (``VecNormalize``), tensorboard logs go to ``<out>/tb/`` and
checkpoints to ``<out>/checkpoints/`` every ``checkpoint_freq`` steps (between
rollouts) and on an interruption (Ctrl-C, SIGTERM). ``resume=True`` continues from the
newest intact checkpoint with the settings, step count, tensorboard run, optimiser
state, normalisation statistics, envs and RNG states of the interrupted run: with the
same ``n_envs`` and ``seed`` it trains on exactly as the uninterrupted run would have.
The output folder's files (and why a kill, a signal during an update, a second writer
or a corrupt checkpoint lose nothing) are described in
:mod:`aldm_gym.agents.checkpoints`; the callbacks that write them are in
:mod:`aldm_gym.agents.callbacks`.

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
weights, the optimiser, the step count and the envs', so a resume loses nothing. DQN
would also need its replay buffer checkpointed (hundreds of MB of Dict observations)
for an exact resume.
"""

from __future__ import annotations

import functools
import io
import pickle
import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym

from aldm_gym import ENV_ID
from aldm_gym.agents.checkpoints import (
    MODEL_FILE,
    TENSORBOARD_DIR,
    TRAINING_FILE,
    VECNORM_FILE,
    Snapshot,
    holds_training,
    newest_intact_checkpoint,
    output_lock,
    read_training,
    remove_temporary_files,
    write_bytes_atomic,
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


def _make_env(config: dict[str, Any]) -> Any:
    """One monitored env (module level so ``SubprocVecEnv`` can pickle the factory)."""
    from stable_baselines3.common.monitor import Monitor

    import aldm_gym  # noqa: F401  (registers the env in a fresh subprocess)

    return ResumableEnv(Monitor(gym.make(ENV_ID, config=config)))


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


def global_rng_state(torch: bool = True) -> dict[str, Any]:
    """States of Python's, numpy's global (and torch's) random generators."""
    import random

    import numpy as np

    state: dict[str, Any] = {"random": random.getstate(), "numpy": np.random.get_state()}  # noqa: NPY002
    if torch:
        import torch as th

        state["torch"] = th.get_rng_state()
    return state


def set_global_rng_state(state: dict[str, Any]) -> None:
    """Restore what :func:`global_rng_state` returned."""
    import random

    import numpy as np

    random.setstate(state["random"])
    # SB3 shuffles minibatches with numpy's global generator: it is part of the state.
    np.random.set_state(state["numpy"])  # noqa: NPY002
    if "torch" in state:
        import torch as th

        th.set_rng_state(state["torch"])


def take_snapshot(model: Any) -> Snapshot:
    """The training's state now (call it between rollouts): model, normalisation,
    envs, last observation and RNG states of one instant."""
    buffer = io.BytesIO()
    model.save(buffer)
    vecnorm = model.get_vec_normalize_env()
    state = {
        "n_envs": model.n_envs,
        "envs": model.get_env().env_method("resume_state"),
        "last_obs": model._last_obs,
        "last_episode_starts": model._last_episode_starts,
        "rng": global_rng_state(),
    }
    return Snapshot(
        steps=int(model.num_timesteps),
        model=buffer.getvalue(),
        vecnormalize=pickle.dumps(vecnorm) if vecnorm is not None else b"",
        resume_state=pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL),
    )


def _restore_resume_state(model: Any, path: Path) -> None:
    """Put the envs, last observation and RNG states of a checkpoint back into
    ``model`` (loaded from the same checkpoint, with as many envs)."""
    with open(path, "rb") as fh:
        state = pickle.load(fh)
    venv = model.get_env()
    for i, env_state in enumerate(state["envs"]):
        venv.env_method("restore_resume_state", env_state, indices=[i])
    model._last_obs = state["last_obs"]
    model._last_episode_starts = state["last_episode_starts"]
    set_global_rng_state(state["rng"])


@contextmanager
def signals_as_interrupt() -> Iterator[None]:
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


def _raised_by_interrupt(exc: BaseException) -> bool:
    """``exc`` is a KeyboardInterrupt, or carries one in its chain.

    A signal handler runs wherever the interpreter checks for signals, also inside a
    C extension's call (a numba kernel boxing its result): the KeyboardInterrupt it
    raises then surfaces as ``SystemError: ... returned a result with an exception
    set``, with the KeyboardInterrupt as its context. Both are the same interruption.
    """
    seen: set[int] = set()
    cur: BaseException | None = exc
    while cur is not None and id(cur) not in seen:
        if isinstance(cur, KeyboardInterrupt):
            return True
        seen.add(id(cur))
        cur = cur.__cause__ or cur.__context__
    return False


@contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back while the block runs (a final save completes);
    they are delivered when it ends."""
    held = {signal.SIGINT, signal.SIGTERM}
    try:
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    except (AttributeError, ValueError):  # no pthread_sigmask, or not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _close_envs(venv: Any, interrupted: bool) -> None:
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


RUN_SETTINGS = (
    "timesteps",
    "n_envs",
    "seed",
    "checkpoint_freq",
    "validation_freq",
    "validation_episodes",
)
"""Settings of a run that ``resume`` restores from ``training.json`` unless given."""


def _run_defaults() -> dict[str, int]:
    """Default value of each of :data:`RUN_SETTINGS`."""
    return {
        "timesteps": DEFAULT_TIMESTEPS,
        "n_envs": 1,
        "seed": 0,
        "checkpoint_freq": DEFAULT_CHECKPOINT_FREQ,
        "validation_freq": DEFAULT_VALIDATION_FREQ,
        "validation_episodes": DEFAULT_VALIDATION_EPISODES,
    }


def resolve_run_settings(
    given: dict[str, int | None], saved: dict[str, Any] | None
) -> tuple[dict[str, int], list[str]]:
    """The run settings of a training and, for a resume, what was restored/overridden.

    :param given: each of :data:`RUN_SETTINGS` as passed (None: not given).
    :param saved: the ``training.json`` being resumed, or None for a new training.
    :return: the settings, and lines saying which were restored from ``saved`` and
        which were overridden (empty for a new training).
    """
    defaults = _run_defaults()
    settings: dict[str, int] = {}
    restored, overridden = [], []
    for name in RUN_SETTINGS:
        value = given.get(name)
        if saved is None:
            settings[name] = defaults[name] if value is None else int(value)
            continue
        was = int(saved.get(name, defaults[name]))
        if value is None:
            settings[name] = was
            restored.append(f"{name}={was}")
        else:
            settings[name] = int(value)
            if int(value) == was:
                restored.append(f"{name}={was}")
            else:
                overridden.append(f"{name}={int(value)} (was {was})")
    report = []
    if saved is not None:
        report.append("restored: env config, PPO hyperparameters, " + ", ".join(restored))
        if overridden:
            report.append("overridden: " + ", ".join(overridden))
    return settings, report


def train(
    out: Path,
    *,
    detector: str = "aldm",
    marking_model: str = "per_dash",
    timesteps: int | None = None,
    n_envs: int | None = None,
    seed: int | None = None,
    checkpoint_freq: int | None = None,
    duration: float | None = None,
    vehicles_count: int | None = None,
    collision_reward: float | None = DEFAULT_COLLISION_REWARD,
    params: PPOParams | None = None,
    validation_freq: int | None = None,
    validation_episodes: int | None = None,
    resume: bool = False,
    progress: bool = True,
    verbose: int = 0,
    callback: Any = None,
) -> Any:
    """Train (or resume training) a PPO policy; return the SB3 model.

    :param out: output folder (its files: :mod:`aldm_gym.agents.checkpoints`); held
        locked while training.
    :param timesteps: total policy steps of the training (counting steps done before a
        resume), rounded up to whole rollouts (``n_steps × n_envs``); default
        :data:`DEFAULT_TIMESTEPS`.
    :param n_envs: envs run in parallel (default 1).
    :param seed: seed of the envs (``seed + i`` for the i-th) and the network (0).
    :param checkpoint_freq: save a checkpoint every this many steps [policy steps]
        (default :data:`DEFAULT_CHECKPOINT_FREQ`).
    :param duration, vehicles_count, collision_reward: env overrides (None: the env's
        defaults).

    The defaults (one env, 49152 steps, collision weight -2, linearly decaying learning
    rate) are the recipe of ``docs/results.md`` (b). It is sensitive to the rollout size:
    two envs with the same or with halved rollouts missed the aim there.
    :param validation_freq: validate every this many steps (0: never) [policy steps]
        (default :data:`DEFAULT_VALIDATION_FREQ`).
    :param validation_episodes: episodes per validation (seeds ``VALIDATION_SEED ..``;
        default :data:`DEFAULT_VALIDATION_EPISODES`).
    :param progress: a tqdm bar over the steps, showing the recent training episodes'
        mean return and length, and one over each validation's episodes (the lines
        announcing and reporting each validation print either way).
    :param callback: extra SB3 callback(s) (a list or one).
    :param resume: continue from the newest intact checkpoint of ``out``; the env
        config and hyperparameters are those saved in ``<out>/training.json``, and so
        is every one of :data:`RUN_SETTINGS` left None (the settings restored and
        overridden are printed to stderr). With the saved ``n_envs`` and ``seed`` the
        envs and RNGs continue exactly where the checkpoint was taken.
    :raises FileExistsError: ``out`` holds a training and ``resume`` is False.
    :raises FileNotFoundError: ``resume`` without a ``training.json`` in ``out`` (one
        without an intact checkpoint starts again from step 0 with its settings).
    :raises OutputLocked: another training is writing ``out``.
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    """
    import_sb3()
    import torch

    out = Path(out)
    given = {
        "timesteps": timesteps,
        "n_envs": n_envs,
        "seed": seed,
        "checkpoint_freq": checkpoint_freq,
        "validation_freq": validation_freq,
        "validation_episodes": validation_episodes,
    }
    for name in ("timesteps", "n_envs", "checkpoint_freq"):
        if given[name] is not None and given[name] < 1:  # type: ignore[operator]
            raise ValueError(f"{name} must be >= 1, got {given[name]}")
    for name in ("validation_freq", "validation_episodes"):
        if given[name] is not None and given[name] < 0:  # type: ignore[operator]
            raise ValueError(f"{name} must be >= 0, got {given[name]}")
    torch.set_num_threads(1)  # the envs need the cores; the MLP is tiny
    with output_lock(out):
        for path in remove_temporary_files(out):
            print(f"removed {path}, left by an interrupted write", file=sys.stderr)
        return _train_locked(
            out,
            given,
            env_config_args=(detector, marking_model, duration, vehicles_count, collision_reward),
            params=params,
            resume=resume,
            progress=progress,
            verbose=verbose,
            callback=callback,
        )


def _train_locked(
    out: Path,
    given: dict[str, int | None],
    *,
    env_config_args: tuple[Any, ...],
    params: PPOParams | None,
    resume: bool,
    progress: bool,
    verbose: int,
    callback: Any,
) -> Any:
    """:func:`train`, holding the lock of ``out``."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from aldm_gym.agents.callbacks import (
        ProgressCallback,
        RolloutCheckpointCallback,
        ValidationCallback,
    )

    saved: dict[str, Any] | None = None
    found = None
    if resume:
        if not (out / TRAINING_FILE).exists():
            raise FileNotFoundError(f"nothing to resume in {out}: no {TRAINING_FILE}")
        saved = read_training(out)
        found = newest_intact_checkpoint(out)
    run, report = resolve_run_settings(given, saved)
    if saved is not None:
        config = saved["env_config"]
        # Trainings written before lr_schedule existed ran with a constant rate.
        params = PPOParams(**{"lr_schedule": "constant", **saved["ppo"]})
    else:
        if holds_training(out):
            raise FileExistsError(
                f"{out} already holds a training; pass --resume to continue it "
                "or choose another --out"
            )
        config = env_config(*env_config_args)
        params = params or PPOParams()
    if found is not None:
        assert saved is not None
        done = found.steps
        exact = (
            found.resume_state is not None
            and run["n_envs"] == int(saved.get("n_envs", 1))
            and run["seed"] == int(saved.get("seed", 0))
        )
        venv = make_vec_env(config, run["n_envs"], run["seed"] + done)
        venv = VecNormalize.load(str(found.vecnormalize), venv)
        venv.training = True
        model = PPO.load(found.model, env=venv, device="cpu")
        # PPO.load takes n_envs from venv and rebuilds the rollout buffer for it.
        if exact:
            assert found.resume_state is not None
            _restore_resume_state(model, found.resume_state)
            report.append(f"envs and RNGs continue exactly from {found.model.name}")
        else:
            model.set_random_seed(run["seed"] + done)
            report.append(
                f"envs restart from seed {run['seed'] + done} (n_envs or seed changed, "
                "or the checkpoint has no resume state)"
            )
    else:
        # A new training, or a resume of one killed before its first checkpoint (or
        # whose checkpoints are all corrupt): from step 0 with the saved settings.
        if saved is not None:
            report.append("no intact checkpoint: starting again from step 0")
        done = 0
        venv = VecNormalize(
            make_vec_env(config, run["n_envs"], run["seed"]), norm_reward=False, clip_obs=10.0
        )
        model = PPO(
            "MultiInputPolicy",
            venv,
            n_steps=params.n_steps,
            batch_size=min(params.batch_size, params.n_steps * run["n_envs"]),
            n_epochs=params.n_epochs,
            learning_rate=params.learning_rate_schedule(),
            gamma=params.gamma,
            gae_lambda=params.gae_lambda,
            ent_coef=params.ent_coef,
            clip_range=params.clip_range,
            policy_kwargs={"net_arch": list(params.net_arch)},
            tensorboard_log=str(out / TENSORBOARD_DIR),
            seed=run["seed"],
            device="cpu",
            verbose=verbose,
        )
    if saved is not None:
        print(f"resuming {out} at {done} steps; " + "; ".join(report), file=sys.stderr)
    meta = {
        "algorithm": "PPO",
        "env_id": ENV_ID,
        "env_config": config,
        "ppo": asdict(params),
        **run,
    }
    write_json(out / TRAINING_FILE, meta)
    model.tensorboard_log = str(out / TENSORBOARD_DIR)
    timesteps = run["timesteps"]
    # In this order: on a rollout boundary the checkpoint is written before validating.
    checkpoints = RolloutCheckpointCallback(run["checkpoint_freq"], out)
    callbacks: list[Any] = [checkpoints]
    if run["validation_freq"] > 0 and run["validation_episodes"] > 0:
        callbacks.append(
            ValidationCallback(
                out,
                config,
                run["validation_freq"],
                run["validation_episodes"],
                progress=progress,
            )
        )
    if progress:
        callbacks.append(ProgressCallback(timesteps))
    if callback is not None:
        callbacks += callback if isinstance(callback, list) else [callback]
    interrupted = False
    t0 = time.perf_counter()
    try:
        with signals_as_interrupt():
            if timesteps > done:
                model.learn(
                    total_timesteps=timesteps - done,
                    callback=callbacks,
                    reset_num_timesteps=found is None,
                    tb_log_name="PPO",
                )
            # The state after the last update (also when resumed with nothing left to
            # do), taken while the envs are open.
            final = take_snapshot(model)
    except (KeyboardInterrupt, SystemError) as exc:
        if not _raised_by_interrupt(exc):
            raise
        interrupted = True
    finally:
        if interrupted:
            # Before closing the envs: a second signal must not cut the save short.
            with _signals_deferred():
                path = checkpoints.save_last_snapshot()
        _close_envs(venv, interrupted)
    if interrupted:
        where = (
            f"saved {path} ({checkpoints.snapshot_steps} steps)"
            if path is not None
            else "nothing new to save (no update finished)"
        )
        print(
            f"\ninterrupted after {time.perf_counter() - t0:.0f} s; {where}; "
            "continue with --resume",
            file=sys.stderr,
        )
        raise KeyboardInterrupt
    with _signals_deferred():
        checkpoints.snapshot = final
        checkpoints.save_last_snapshot()
        write_bytes_atomic(out / MODEL_FILE, final.model)
        write_bytes_atomic(out / VECNORM_FILE, final.vecnormalize)
    return model
