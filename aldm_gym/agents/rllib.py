"""PPO on Ray RLlib: ``aldm-gym train --backend rllib`` (the ``[ray]`` extra).

stable-baselines3 (:mod:`aldm_gym.agents.training`) runs on one machine; RLlib spreads
the env steps over the env runners of a Ray cluster, on one machine or many
(``docs/cluster.md``). :func:`train_rllib` trains the same task as the SB3 path: the
same ``ALDMHighway-v0`` config (:func:`~aldm_gym.agents.training.env_config`), reward
and :class:`~aldm_gym.agents.training.PPOParams`, mapped onto RLlib's PPO on its
current API stack (RLModule, Learner, EnvRunner, ConnectorV2):

* the env is the registered id ``"aldm_gym:ALDMHighway-v0"``: gymnasium imports
  ``aldm_gym`` in every env runner process, on every node, before making it;
* the Dict observation goes through RLlib's ``FlattenObservations`` connector, then
  ``MeanStdFilter`` (running mean/std, clipped at ±10: what ``VecNormalize`` does on
  the SB3 path); both are part of every checkpoint;
* PPO as SB3 runs it: no KL penalty (SB3 has none), value loss weight 0.5, gradient
  norm clipped at 0.5, no value clipping, separate 128×128 tanh networks for policy
  and value; the rollout of one update is ``n_steps`` per env runner (SB3: per env);
  a ``"linear"`` learning rate decays to 0 over the budget as RLlib's piecewise
  schedule over sampled env steps.

Output folder (beside SB3's files, :mod:`aldm_gym.agents.checkpoints`)::

    <out>/training.json                 as SB3's, with "backend": "rllib"
    <out>/rllib_model/                  the final RLlib checkpoint
    <out>/checkpoints/rllib_<steps>/    a checkpoint every checkpoint_freq steps
    <out>/tb/RLlib_PPO/                 tensorboard events (returns, losses, rates)

A checkpoint folder is written under a temporary name, flushed to disk and renamed
into place once complete (it then holds :data:`STEPS_FILE`), so a kill never leaves a
half-written one that ``--resume`` would take; a resume falls back to an older
checkpoint, with a warning, when the newest does not restore. The first Ctrl-C or
SIGTERM lets the iteration in progress finish and saves a checkpoint of it; a second
one stops at once (that iteration is lost: RLlib's learner state mid-update is not one
to save). Unlike the SB3 path a resume is not bit-exact: the env runners start new
episodes, seeded ``seed + steps done``.

Observation statistics: each env runner normalises with its own running mean/std
(RLlib 2.60 does not merge ``MeanStdFilter`` states across remote runners, and leaves
the local runner's, which a checkpoint stores, empty); before every save the first
remote runner's statistics are copied into the local runner, and a resume gives the
restored statistics to every runner.

:class:`RLlibPolicy` plays a checkpoint outside Ray (the RLModule and the saved
connector pipeline, with the observation statistics frozen), so ``aldm-gym evaluate``
compares it with IDLE and the rule-based LCA exactly as it does SB3 models.

Ray, RLlib and torch are imported inside the functions (:func:`import_rllib`).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import socket
import sys
import tempfile
import time
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from aldm_gym import ENV_ID
from aldm_gym.agents.checkpoints import (
    CHECKPOINT_DIR,
    TENSORBOARD_DIR,
    TRAINING_FILE,
    output_lock,
    read_training,
    remove_temporary_files,
    write_json,
)
from aldm_gym.agents.training import (
    DEFAULT_CHECKPOINT_FREQ,
    DEFAULT_COLLISION_REWARD,
    DEFAULT_TIMESTEPS,
    PPOParams,
    env_config,
)
from aldm_gym.errors import ClusterError, MissingRLDependencies, ResumeError

RLLIB_ENV_ID = f"aldm_gym:{ENV_ID}"
"""The env as RLlib's workers make it: gymnasium imports ``aldm_gym`` first."""

MODEL_DIR = "rllib_model"
"""The final RLlib checkpoint (a folder) of a training's output folder."""

CHECKPOINT_PREFIX = "rllib_"
"""Periodic checkpoints: ``<out>/checkpoints/rllib_<steps>/``."""

STEPS_FILE = "aldm_gym.json"
"""Written into a checkpoint folder last: its step count; marks it complete."""

TB_RUN = "RLlib_PPO"
"""The tensorboard run folder under ``<out>/tb``."""

DEFAULT_ENV_RUNNERS = 1
"""Default ``--num-env-runners``."""

CONNECT_TIMEOUT = 5.0
"""Seconds to wait for a cluster's head at ``--address`` to accept a connection."""

_RLLIB_MARKER = "rllib_checkpoint.json"
_ENV_TO_MODULE = "env_to_module_connector"
_LOGGED = {
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


class MissingRayDependencies(MissingRLDependencies):
    """Ray RLlib or torch is not installed."""


def import_rllib() -> Any:
    """Import ``ray.rllib`` (and torch) or raise :class:`MissingRayDependencies`."""
    try:
        import ray.rllib
        import torch  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise MissingRayDependencies(
            f"--backend rllib needs Ray RLlib and torch ({exc}); install them with: "
            "pip install torch==2.13.0 && pip install -e '.[ray]' (from a clone)"
        ) from exc
    return ray.rllib


def flatten_and_normalise(env: Any = None, spaces: Any = None, device: Any = None) -> list[Any]:
    """The env-to-module connectors: flatten the Dict observation, then normalise it.

    RLlib calls it (with the env, the spaces and the device) in every env runner; it is
    module-level so Ray can ship it by reference.
    """
    from ray.rllib.connectors.env_to_module import FlattenObservations, MeanStdFilter

    return [FlattenObservations(), MeanStdFilter(clip_by_value=10.0)]


def ppo_config(
    config: Mapping[str, Any],
    params: PPOParams,
    *,
    timesteps: int,
    num_env_runners: int = DEFAULT_ENV_RUNNERS,
    seed: int = 0,
) -> Any:
    """RLlib's ``PPOConfig`` of a training (see the module docstring for the mapping).

    :param config: the ``ALDMHighway-v0`` config.
    :param timesteps: the budget [env steps] (the end of a linear learning rate).
    :param num_env_runners: remote env runners (0: sample in the driver).
    :param seed: seed of the env runners' envs and of the networks.
    """
    import_rllib()
    from ray.rllib.algorithms.ppo import PPOConfig

    # RLlib warns once per process that PPO runs on its new API stack (it is chosen).
    logging.getLogger("ray.rllib.algorithms.algorithm_config").setLevel(logging.ERROR)
    rollout = params.n_steps * max(1, num_env_runners)
    lr: Any = params.learning_rate
    if params.lr_schedule == "linear":
        lr = [[0, params.learning_rate], [int(timesteps), 0.0]]
    return (
        PPOConfig()
        .environment(RLLIB_ENV_ID, env_config={"config": dict(config)})
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=1,
            rollout_fragment_length="auto",
            env_to_module_connector=flatten_and_normalise,
        )
        .training(
            train_batch_size_per_learner=rollout,
            minibatch_size=min(params.batch_size, rollout),
            num_epochs=params.n_epochs,
            lr=lr,
            gamma=params.gamma,
            lambda_=params.gae_lambda,
            entropy_coeff=params.ent_coef,
            clip_param=params.clip_range,
            use_kl_loss=False,
            vf_loss_coeff=0.5,
            vf_clip_param=float("inf"),
            grad_clip=0.5,
        )
        .rl_module(
            model_config={
                "fcnet_hiddens": list(params.net_arch),
                "fcnet_activation": "tanh",
                "vf_share_layers": False,
            }
        )
        .debugging(seed=seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=100)
    )


def is_checkpoint(path: Path) -> bool:
    """``path`` is a complete RLlib checkpoint folder written by :func:`train_rllib`."""
    path = Path(path)
    return (path / _RLLIB_MARKER).is_file() and (path / STEPS_FILE).is_file()


def checkpoint_steps(path: Path) -> int:
    """The step count of a checkpoint folder [env steps]."""
    return int(json.loads((Path(path) / STEPS_FILE).read_text())["steps"])


def newest_checkpoint(out: Path) -> Path | None:
    """The complete ``<out>/checkpoints/rllib_<steps>`` with the most steps, or None."""
    found = _complete_checkpoints(out)
    return found[0] if found else None


def _save(algo: Any, path: Path, steps: int) -> Path:
    """Save ``algo`` as the checkpoint folder ``path`` (written aside, then renamed in;
    an older folder of that name is replaced)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    _pull_runner_statistics(algo)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}.tmp"))
    algo.save_to_path(str(tmp))
    (tmp / STEPS_FILE).write_text(json.dumps({"steps": int(steps)}) + "\n")
    _fsync_tree(tmp)
    # Replacing a folder (only rllib_model) leaves a moment without it; the checkpoint
    # folder saved just before holds the same state.
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.tmp-old-{os.getpid()}")
        path.rename(old)
    tmp.rename(path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return path


def _fsync_tree(folder: Path) -> None:
    """Flush every file of ``folder`` and the folders themselves to disk."""
    for root, _, files in os.walk(folder):
        for name in files:
            fd = os.open(os.path.join(root, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        fd = os.open(root, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _connect(address: str | None, num_env_runners: int) -> None:
    """Start a local Ray instance (``address`` None) or join a running cluster.

    A local instance is given at least one CPU per env runner (more runners than cores
    share them, with a warning).

    :raises ClusterError: no cluster answers at ``address``, it refuses this process
        (e.g. no or another auth token), or it has fewer CPUs than the env runners need
        (RLlib would wait for them forever).
    """
    import ray

    kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": "ERROR"}
    if address is None:  # "local": a new instance, even where a cluster is running
        cores = os.cpu_count() or 1
        if num_env_runners > cores:
            warnings.warn(
                f"{num_env_runners} env runners share {cores} cores", UserWarning, stacklevel=3
            )
        kwargs.update(address="local", num_cpus=max(cores, num_env_runners))
    else:
        if address != "auto":
            _check_reachable(address)  # ray.init retries a dead address for minutes
        kwargs["address"] = address
    try:
        ray.init(**kwargs)
    except (ConnectionError, RuntimeError, ray.exceptions.RayError) as exc:
        raise ClusterError(
            f"cannot join the Ray cluster at {address!r} ({exc}); a cluster with token "
            "authentication needs RAY_AUTH_MODE=token and its token here (docs/cluster.md)"
        ) from None
    cpus = float(ray.cluster_resources().get("CPU", 0))
    if cpus < num_env_runners:
        ray.shutdown()
        raise ClusterError(
            f"the Ray cluster at {address or 'local'} has {cpus:g} CPUs; "
            f"{num_env_runners} env runners need one each",
            argument="--num-env-runners",
        )
    where = f"the Ray cluster at {address}" if address else "a local Ray instance"
    print(f"training on {where} ({cpus:g} CPUs)", file=sys.stderr)


def _check_reachable(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Raise ValueError unless something accepts TCP connections at ``host:port``."""
    host, _, port = address.rpartition(":")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except (OSError, ValueError) as exc:
        raise ClusterError(
            f"no Ray cluster answers at {address} ({exc}); check the address, or start "
            f"a cluster there (docs/cluster.md)"
        ) from None


def _tb_scalars(result: Mapping[str, Any]) -> dict[str, float]:
    """The scalars of one RLlib result to log (tag -> value)."""
    scalars = {}
    for section, keys in _LOGGED.items():
        node: Any = result
        for part in section.split("/"):
            node = node.get(part, {}) if isinstance(node, Mapping) else {}
        for key in keys:
            value = node.get(key) if isinstance(node, Mapping) else None
            if value is not None and np.isfinite(float(value)):
                scalars[f"{section.split('/')[0]}/{key}"] = float(value)
    scalars["perf/iteration_s"] = float(result.get("time_this_iter_s", np.nan))
    return {k: v for k, v in scalars.items() if np.isfinite(v)}


def _sampled(result: Mapping[str, Any]) -> int:
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


def _postfix(result: Mapping[str, Any]) -> dict[str, str]:
    """The progress bar's postfix: recent training episodes' mean return and length."""
    runners = result.get("env_runners", {})
    rew, length = runners.get("episode_return_mean"), runners.get("episode_len_mean")
    ok = rew is not None and np.isfinite(rew) and length is not None and np.isfinite(length)
    return {"ep_rew": f"{rew:.2f}", "ep_len": f"{length:.1f}"} if ok else {"ep_rew": "-"}


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
    params: PPOParams | None = None,
    resume: bool = False,
    progress: bool = True,
) -> int:
    """Train (or resume) a PPO policy with RLlib; return the steps trained [env steps].

    :param out: output folder (see the module docstring); held locked while training.
    :param timesteps: total env steps (counting those before a resume), rounded up to
        whole updates; default :data:`~aldm_gym.agents.training.DEFAULT_TIMESTEPS`.
    :param num_env_runners: remote env runners, one CPU each (default
        :data:`DEFAULT_ENV_RUNNERS`; 0 samples in the driver process).
    :param address: a running Ray cluster (``"auto"`` or ``"host:port"``); None starts
        a local Ray instance for this training.
    :param seed: seed of the envs and networks (0).
    :param checkpoint_freq: checkpoint every this many env steps (default
        :data:`~aldm_gym.agents.training.DEFAULT_CHECKPOINT_FREQ`), and at the end.
    :param duration, vehicles_count, collision_reward: env overrides, as for
        :func:`~aldm_gym.agents.training.train`.
    :param resume: continue from the newest complete checkpoint of ``out`` with the env
        config, hyperparameters and run settings of its ``training.json`` (settings
        given here override the saved ones).
    :raises FileExistsError: ``out`` holds a training and ``resume`` is False.
    :raises FileNotFoundError: ``resume`` without a ``training.json`` in ``out``.
    :raises ValueError: a bad setting.
    :raises ResumeError: ``resume`` of an SB3 training.
    :raises ClusterError: the cluster is not there, refuses this process or is too
        small.
    :raises MissingRayDependencies: Ray RLlib / torch missing.
    """
    import_rllib()
    from aldm_gym.agents.checkpoints import holds_training

    out = Path(out).absolute()  # RLlib reads a relative path as a URI without a scheme
    for name, value, least in (
        ("timesteps", timesteps, 1),
        ("num_env_runners", num_env_runners, 0),
        ("checkpoint_freq", checkpoint_freq, 1),
    ):
        if value is not None and value < least:
            raise ValueError(f"{name} must be >= {least}, got {value}")
    with output_lock(out):
        for path in remove_temporary_files(out):
            print(f"removed {path}, left by an interrupted write", file=sys.stderr)
        saved: dict[str, Any] | None = None
        if resume:
            if not (out / TRAINING_FILE).exists():
                raise FileNotFoundError(f"nothing to resume in {out}: no {TRAINING_FILE}")
            saved = read_training(out)
            if saved.get("backend", "sb3") != "rllib":
                raise ResumeError(f"{out} holds an SB3 training; resume it without --backend rllib")
        elif holds_training(out):
            raise FileExistsError(
                f"{out} already holds a training; pass --resume to continue it "
                "or choose another --out"
            )
        if saved is not None:
            config = saved["env_config"]
            params = PPOParams(**saved["ppo"])
        else:
            config = env_config(detector, marking_model, duration, vehicles_count, collision_reward)
            params = params or PPOParams()
        old = saved or {}
        run = {
            "timesteps": timesteps or int(old.get("timesteps", DEFAULT_TIMESTEPS)),
            "num_env_runners": (
                num_env_runners
                if num_env_runners is not None
                else int(old.get("num_env_runners", DEFAULT_ENV_RUNNERS))
            ),
            "seed": seed if seed is not None else int(old.get("seed", 0)),
            "checkpoint_freq": checkpoint_freq
            or int(old.get("checkpoint_freq", DEFAULT_CHECKPOINT_FREQ)),
        }
        meta = {
            "algorithm": "PPO",
            "backend": "rllib",
            "env_id": ENV_ID,
            "env_config": config,
            "ppo": asdict(params),
            **run,
        }
        return _train_locked(out, meta, params, address, saved is not None, progress)


class _StopRequest:
    """Set by the first SIGINT/SIGTERM of a training: stop after this iteration."""

    requested = False


@contextmanager
def _stop_between_iterations() -> Iterator[_StopRequest]:
    """The first SIGINT or SIGTERM asks the training to stop after the iteration in
    progress (it then saves a checkpoint); a second one raises KeyboardInterrupt at once.
    """
    stop = _StopRequest()

    def handler(signum: int, frame: Any) -> None:
        if stop.requested:
            raise KeyboardInterrupt
        stop.requested = True
        print(
            "\nstopping after this iteration and saving a checkpoint "
            "(signal again to stop at once, losing the iteration)",
            file=sys.stderr,
        )

    try:
        previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread: signals stay as they are
        yield stop
        return
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _complete_checkpoints(out: Path) -> list[Path]:
    """The complete ``<out>/checkpoints/rllib_<steps>`` folders, newest first."""
    found = []
    for path in (Path(out) / CHECKPOINT_DIR).glob(f"{CHECKPOINT_PREFIX}*"):
        tail = path.name[len(CHECKPOINT_PREFIX) :]
        if tail.isdigit() and is_checkpoint(path):
            found.append((int(tail), path))
    return [path for _, path in sorted(found, reverse=True)]


def _connector_state(runner: Any) -> Any:
    """An env runner's env-to-module connector state (the observation statistics)."""
    return runner.get_state(components=[_ENV_TO_MODULE])


def _pull_runner_statistics(algo: Any) -> None:
    """Copy the first remote env runner's observation statistics into the local env
    runner, whose state is what a checkpoint stores.

    With remote env runners, RLlib 2.60 neither merges their ``MeanStdFilter``
    statistics nor updates the local runner's (measured: each runner keeps its own,
    the local one stays empty), so without this a checkpoint would normalise with empty
    statistics. Each runner normalises with its own running statistics while training.
    """
    group = algo.env_runner_group
    if group.num_healthy_remote_workers() == 0:
        return  # the local runner samples itself: its statistics are the training's
    states = group.foreach_env_runner(
        _connector_state, local_env_runner=False, remote_worker_ids=[group.healthy_worker_ids()[0]]
    )
    if states:
        algo.env_runner.set_state(states[0])


def _push_runner_statistics(algo: Any) -> None:
    """Give every remote env runner the (restored) local runner's statistics."""
    group = algo.env_runner_group
    if group.num_healthy_remote_workers() == 0:
        return
    state = _connector_state(algo.env_runner)
    group.foreach_env_runner(lambda runner: runner.set_state(state), local_env_runner=False)


def _train_locked(
    out: Path,
    meta: dict[str, Any],
    params: PPOParams,
    address: str | None,
    resume: bool,
    progress: bool,
) -> int:
    """:func:`train_rllib`, holding the lock of ``out``; ``meta`` is its
    ``training.json``, written once Ray is up (a failed connection leaves ``out`` as
    it was)."""
    import ray
    import torch

    torch.set_num_threads(1)  # the env runners need the cores; the MLP is tiny
    candidates = _complete_checkpoints(out) if resume else []
    _connect(address, meta["num_env_runners"])
    try:
        write_json(out / TRAINING_FILE, meta)
        return _run(out, meta, params, candidates, resume, progress)
    finally:
        ray.shutdown()


def _build(meta: dict[str, Any], params: PPOParams, done: int) -> Any:
    """The algorithm of a training at ``done`` steps (its envs seeded ``seed + done``,
    so a resume does not replay the first episodes)."""
    return ppo_config(
        meta["env_config"],
        params,
        timesteps=meta["timesteps"],
        num_env_runners=meta["num_env_runners"],
        seed=meta["seed"] + done,
    ).build_algo()


def _restore(meta: dict[str, Any], params: PPOParams, candidates: list[Path]) -> tuple[Any, int]:
    """The algorithm restored from the newest checkpoint that loads (an older one when a
    newer fails, with a :class:`~aldm_gym.agents.checkpoints.TrainingWarning`), and its
    steps; a new one at step 0 if none loads."""
    from aldm_gym.agents.checkpoints import TrainingWarning

    for path in candidates:
        try:
            done = checkpoint_steps(path)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            warnings.warn(
                f"skipping {path}: unreadable {STEPS_FILE} ({exc})", TrainingWarning, stacklevel=2
            )
            continue
        algo = _build(meta, params, done)
        try:
            algo.restore_from_path(str(path))
        except Exception as exc:  # a damaged checkpoint fails in pickle, torch or RLlib
            algo.stop()
            warnings.warn(
                f"skipping {path}: does not restore ({type(exc).__name__}: {exc})",
                TrainingWarning,
                stacklevel=2,
            )
            continue
        _push_runner_statistics(algo)
        print(f"resuming from {path} at {done} steps", file=sys.stderr)
        return algo, done
    print("no checkpoint to resume from: starting at step 0", file=sys.stderr)
    return _build(meta, params, 0), 0


def _run(
    out: Path,
    meta: dict[str, Any],
    params: PPOParams,
    candidates: list[Path],
    resume: bool,
    progress: bool,
) -> int:
    """Build (or restore) the algorithm and train it to the budget, checkpointing."""
    from torch.utils.tensorboard import SummaryWriter
    from tqdm import tqdm

    algo: Any = None
    writer = None
    graceful = False
    t0 = time.perf_counter()
    try:
        with _stop_between_iterations() as stop:
            if resume:
                algo, done = _restore(meta, params, candidates)
            else:
                algo, done = _build(meta, params, 0), 0
            steps = last_saved = done
            writer = SummaryWriter(str(out / TENSORBOARD_DIR / TB_RUN))
            with tqdm(
                total=meta["timesteps"],
                initial=done,
                desc="train",
                unit="step",
                disable=not progress,
            ) as bar:
                while steps < meta["timesteps"] and not stop.requested:
                    result = algo.train()
                    sampled = _sampled(result)
                    steps += sampled
                    bar.update(sampled)
                    bar.set_postfix(_postfix(result), refresh=True)
                    for tag, value in _tb_scalars(result).items():
                        writer.add_scalar(tag, value, steps)
                    if steps - last_saved >= meta["checkpoint_freq"] or stop.requested:
                        _save(algo, out / CHECKPOINT_DIR / f"{CHECKPOINT_PREFIX}{steps}", steps)
                        last_saved = steps
            if stop.requested:
                graceful = True
                newest = newest_checkpoint(out)
                what = f"saved {newest}" if steps > done else "stopped before an iteration ended"
                print(
                    f"\nstopped after {time.perf_counter() - t0:.0f} s; {what}; "
                    "continue with --resume",
                    file=sys.stderr,
                )
                raise KeyboardInterrupt
            if steps > last_saved:
                _save(algo, out / CHECKPOINT_DIR / f"{CHECKPOINT_PREFIX}{steps}", steps)
            _save(algo, out / MODEL_DIR, steps)
            return steps
    except KeyboardInterrupt:
        if not graceful:  # a second signal: the iteration in progress is lost
            newest = newest_checkpoint(out)
            where = f"newest checkpoint {newest}" if newest else "no checkpoint yet"
            print(f"interrupted; {where}; continue with --resume", file=sys.stderr)
        raise
    finally:
        if writer is not None:
            writer.close()
        if algo is not None:
            try:
                algo.stop()
            except Exception as exc:  # the cluster went away: nothing left to stop
                print(f"stopping the algorithm failed: {exc}", file=sys.stderr)


class RLlibPolicy:
    """A trained RLlib checkpoint as a policy with SB3's ``predict``, outside Ray.

    The observation goes through the checkpoint's own connector pipeline (flatten,
    then the training's running mean/std, frozen here: playing does not change the
    statistics), the RLModule gives the action logits; deterministic play takes their
    argmax (RLlib's own choice with ``explore=False``).

    :param path: an RLlib checkpoint folder written by :func:`train_rllib`.
    :ivar num_timesteps: env steps trained when the checkpoint was written.
    """

    def __init__(self, path: Path) -> None:
        import_rllib()
        from ray.rllib.connectors.env_to_module.env_to_module_pipeline import (
            EnvToModulePipeline,
        )
        from ray.rllib.core.rl_module.rl_module import RLModule

        # RLModule.from_checkpoint builds the module the way RLlib itself deprecates.
        logging.getLogger("ray.rllib.core.rl_module.rl_module").setLevel(logging.ERROR)
        path = Path(path).absolute()  # RLlib reads a relative path as a URI
        self.path = path
        self.num_timesteps = checkpoint_steps(path)
        self.module = RLModule.from_checkpoint(
            path / "learner_group" / "learner" / "rl_module" / "default_policy"
        )
        self.pipeline = EnvToModulePipeline.from_checkpoint(
            path / "env_runner" / "env_to_module_connector"
        )
        for piece in self.pipeline.connectors:
            if hasattr(piece, "_update_stats"):  # MeanStdFilter: freeze the statistics
                piece._update_stats = False
        self._rng = np.random.default_rng(0)

    def logits(self, observation: Mapping[str, Any]) -> np.ndarray:
        """The action logits of one (unbatched) observation, shape ``(n_actions,)``."""
        import torch
        from ray.rllib.env.single_agent_episode import SingleAgentEpisode

        episode = SingleAgentEpisode(observations=[dict(observation)])
        batch = self.pipeline(
            rl_module=self.module, batch={}, episodes=[episode], explore=False, shared_data={}
        )
        with torch.no_grad():
            out = self.module.forward_inference(batch)
        return out["action_dist_inputs"][0].numpy()

    def predict(
        self,
        observation: Mapping[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """``(action, state)`` for one observation, as SB3's ``predict``."""
        logits = self.logits(observation)
        if deterministic:
            return np.asarray(int(np.argmax(logits))), state
        p = np.exp(logits - logits.max())
        return np.asarray(int(self._rng.choice(len(p), p=p / p.sum()))), state


def load_rllib_policy(path: Path) -> tuple[RLlibPolicy, dict[str, Any]]:
    """An RLlib checkpoint folder and the ``training.json`` of its output folder.

    :raises FileNotFoundError: not a checkpoint of :func:`train_rllib`, or no
        ``training.json`` beside it.
    :raises ValueError: the checkpoint does not load (naming the folder).
    :raises MissingRayDependencies: Ray RLlib / torch missing.
    """
    from aldm_gym.agents.checkpoints import find_training_file

    path = Path(path)
    if not is_checkpoint(path):
        raise FileNotFoundError(
            f"{path} is a folder but not an RLlib checkpoint of aldm-gym train "
            f"(no {_RLLIB_MARKER} and {STEPS_FILE})"
        )
    meta_path = find_training_file(path)
    if meta_path is None:
        raise FileNotFoundError(f"no {TRAINING_FILE} next to {path} (written by aldm-gym train)")
    meta = json.loads(meta_path.read_text())
    try:
        policy = RLlibPolicy(path)
    except MissingRayDependencies:
        raise
    except Exception as exc:  # a damaged checkpoint fails in pickle, torch or RLlib
        raise ValueError(
            f"{path}: not a readable RLlib checkpoint ({type(exc).__name__}: {exc})"
        ) from exc
    return policy, meta
