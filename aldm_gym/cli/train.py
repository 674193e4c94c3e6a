"""``aldm-gym train``: train (or resume) a PPO lane-change policy.

``--algo maskable-ppo`` trains PPO on the env's action masks (sb3-contrib's
MaskablePPO, or RLlib's action-masking module).

``--backend sb3`` (the default) trains with stable-baselines3 on this machine
(:func:`~aldm_gym.training.sb3.backend.train`); ``--backend rllib`` with Ray RLlib on a
local Ray instance or, with ``--address``, on a running cluster
(:func:`~aldm_gym.training.rllib.backend.train_rllib`, ``docs/cluster.md``). Flags of
one backend only are refused with the other. ``--resume`` continues with the backend of
the training in ``--out`` (from its newest checkpoint that is intact and restores).

Flags map onto the training functions' arguments; ``--resume`` takes the env config
and hyperparameters saved in ``<out>/training.json`` and refuses flags that contradict
them, and restores the run's settings (budget, workers, seed, checkpoint and
validation periods) unless a flag gives them, saying which it restored and which it
overrode. The training's messages print as lines (:func:`~aldm_gym.cli.console.console`),
warnings (a stale lock taken over, a corrupt checkpoint skipped) as one line each.
stable-baselines3 and Ray are imported only when the command runs.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aldm_gym.cli.argtypes import (
    BadArgument,
    add_env_argument,
    config_setting,
    fraction,
    int_in,
    make_output_dir,
    nested_pairs,
    non_negative_float,
    non_negative_int,
    output_dir,
    positive_float,
    positive_int,
    ray_address,
    seed,
)
from aldm_gym.cli.console import console
from aldm_gym.envs.config import default_config, merge_config
from aldm_gym.errors import (
    CheckpointError,
    ClusterError,
    ConfigError,
    MissingRLDependencies,
    OutputLocked,
    ResumeError,
)
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.detectors import DETECTORS
from aldm_gym.training.lock import check_unlocked
from aldm_gym.training.models import BACKENDS
from aldm_gym.training.outputs import (
    BEST_MODEL_FILE,
    CHECKPOINT_DIR,
    MODEL_FILE,
    RLLIB_MODEL_DIR,
    TENSORBOARD_DIR,
    TRAINING_FILE,
    VALIDATION_FILE,
    holds_training,
)
from aldm_gym.training.record import TrainingRecord
from aldm_gym.training.rllib.backend import TB_RUN, train_rllib
from aldm_gym.training.sb3.backend import train
from aldm_gym.training.sb3.pretrain import MAX_PRETRAIN_EPISODES
from aldm_gym.training.settings import (
    ALGORITHMS,
    DEFAULT_CHECKPOINT_FREQ,
    DEFAULT_COLLISION_REWARD,
    DEFAULT_PRETRAIN_EPOCHS,
    DEFAULT_TIMESTEPS,
    DEFAULT_VALIDATION_EPISODES,
    DEFAULT_VALIDATION_FREQ,
    KEEP_BY,
    LR_SCHEDULES,
    MAX_ENV_RUNNERS,
    MAX_N_ENVS,
    MAX_N_STEPS,
    NAMED_ENV_KEYS,
    VALIDATION_SEED,
    PPOParams,
    dotted_settings,
    env_config,
)

QUICK_TIMESTEPS = 1_024
"""``train --quick``: a smoke-test budget (about a minute)."""

QUICK_N_STEPS = 64
"""``train --quick``: rollout length per env [policy steps]."""

QUICK_DURATION = 10.0
"""``train --quick``: episode length [s]."""

QUICK_VALIDATION_FREQ = 512
"""``train --quick``: validation period [policy steps] (twice in the quick budget)."""

QUICK_VALIDATION_EPISODES = 3
"""``train --quick``: episodes per validation."""

_ONLY = {
    "sb3": (
        "n_envs",
        "validation_freq",
        "validation_episodes",
        "pretrain_episodes",
        "pretrain_epochs",
        "keep_by",
    ),
    "rllib": ("num_env_runners", "address"),
}
"""The flags (argparse dests) of one backend only."""

_ENV_FLAGS = {
    "detector": "detector",
    "marking_model": "marking_model",
    "duration": "duration",
    "vehicles_count": "vehicles",
    "collision_reward": "collision_reward",
    "overtaking_reward": "overtaking_reward",
}
"""The flag (argparse dest) of each env setting that has its own (not ``--env``)."""

_ENV_CONFIG = ("aldm_gym.envs.config", "EnvConfig")
"""Where the env's config rules live (``--duration``, ``--vehicles``, ``--collision-reward``
are checked against them)."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym train`` and its arguments."""
    parser = subparsers.add_parser("train", help="train a PPO lane-change policy")
    parser.add_argument(
        "--backend",
        choices=tuple(BACKENDS),
        default=None,
        help="sb3: stable-baselines3 on this machine; rllib: Ray RLlib, local or on a "
        "cluster ([ray] extra) (sb3; --resume: the training's)",
    )
    parser.add_argument(
        "--algo",
        choices=tuple(ALGORITHMS),
        default=None,
        help="ppo: PPO; maskable-ppo: PPO that never samples a lane change the env's action "
        "mask rules out (sb3: sb3-contrib's MaskablePPO; rllib: RLlib's action-masking "
        "module) (ppo; --resume: the training's)",
    )
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
        type=int_in(1, MAX_N_ENVS),
        default=None,
        help="sb3: parallel envs (1; more run in subprocesses, but change the results)",
    )
    parser.add_argument(
        "--num-env-runners",
        type=int_in(0, MAX_ENV_RUNNERS),
        default=None,
        help="rllib: env runners, one CPU each (1; 0 samples in the driver)",
    )
    parser.add_argument(
        "--address",
        type=ray_address,
        default=None,
        help="rllib: a running Ray cluster, 'auto' or host:port (none: a local Ray instance)",
    )
    parser.add_argument(
        "--n-steps",
        type=int_in(2, MAX_N_STEPS),
        default=None,
        help=f"PPO rollout length per env ({PPOParams.n_steps})",
    )
    parser.add_argument(
        "--checkpoint-freq",
        type=positive_int,
        default=None,
        help=f"checkpoint every this many steps ({DEFAULT_CHECKPOINT_FREQ})",
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
        help=f"learning rate constant, or decaying linearly to 0 over --timesteps "
        f"({PPOParams.lr_schedule})",
    )
    parser.add_argument(
        "--validation-freq",
        type=non_negative_int,
        default=None,
        help="validate (and keep best_model.zip) every this many steps and at the end, "
        f"0 = never ({DEFAULT_VALIDATION_FREQ}; --quick {QUICK_VALIDATION_FREQ})",
    )
    parser.add_argument(
        "--validation-episodes",
        type=positive_int,
        default=None,
        help=f"episodes per validation, seeds {VALIDATION_SEED}.. ({DEFAULT_VALIDATION_EPISODES}; "
        f"--quick {QUICK_VALIDATION_EPISODES})",
    )
    parser.add_argument(
        "--duration",
        type=config_setting(*_ENV_CONFIG, "duration"),
        default=None,
        help="episode length [s] (env: 40)",
    )
    parser.add_argument(
        "--vehicles",
        type=config_setting(*_ENV_CONFIG, "vehicles_count", int),
        default=None,
        help="other vehicles (env: 20)",
    )
    parser.add_argument(
        "--collision-reward",
        type=config_setting(*_ENV_CONFIG, "collision_reward"),
        default=None,
        help=f"weight of the collision penalty in the reward ({DEFAULT_COLLISION_REWARD}; "
        "the env's default is -1)",
    )
    parser.add_argument(
        "--overtaking-reward",
        type=config_setting(*_ENV_CONFIG, "overtaking_reward"),
        default=None,
        help="weight of the overtaking term (vehicles passed minus passed by) in the reward "
        "(env: 0)",
    )
    parser.add_argument(
        "--learning-rate",
        type=positive_float,
        default=None,
        help=f"initial learning rate ({PPOParams.learning_rate})",
    )
    parser.add_argument(
        "--ent-coef",
        type=non_negative_float,
        default=None,
        help=f"entropy bonus weight ({PPOParams.ent_coef})",
    )
    add_pretrain_arguments(
        parser,
        "before PPO, clone the rule-based LCA played on this many episodes into the new "
        "policy (behaviour cloning; off by default)",
    )
    parser.add_argument(
        "--keep-by",
        choices=KEEP_BY,
        default=None,
        help="keep as best_model.zip the validation with the highest mean return, or "
        "score (mean speed less 10 m/s per failed-episode share) (return)",
    )
    add_env_argument(parser, "saved with the training")
    parser.add_argument("--seed", type=seed, default=None, help="seed of envs and network (0)")
    parser.add_argument("--out", type=output_dir, default=Path("out/train"), help="output folder")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue from the newest intact checkpoint in --out, with its settings unless given",
    )
    parser.add_argument("--quick", action="store_true", help="tiny budget (smoke test)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)
    return parser


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _backend(args: argparse.Namespace, record: TrainingRecord | None) -> str:
    """The backend of the run: ``--backend``, else the resumed training's, else sb3;
    refuses flags of the other backend (:class:`BadArgument`)."""
    saved = None if record is None else record.backend
    backend = args.backend or saved or "sb3"
    if saved is not None and backend != saved:
        raise BadArgument(
            "--backend", f"{backend} contradicts the training being resumed ({saved}); omit it"
        )
    for other, dests in _ONLY.items():
        if other == backend:
            continue
        for dest in dests:
            if getattr(args, dest) is not None:
                hint = {"n_envs": "; with rllib use --num-env-runners"}.get(dest, "")
                raise BadArgument(_flag(dest), f"applies to --backend {other} only{hint}")
    return backend


def _env_overrides(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``--env`` pairs as a nested config (``a.b=v`` -> ``{"a": {"b": v}}``), checked
    against the env's rules (:class:`BadArgument` naming the key and the allowed ones)."""
    overrides = nested_pairs(pairs)
    for name in NAMED_ENV_KEYS:
        if name in overrides:
            raise BadArgument("--env", f"{name} has its own flag: {_flag(_ENV_FLAGS[name])}")
    try:
        env_config(env_overrides=overrides)
    except ConfigError as exc:
        raise BadArgument("--env", str(exc)) from None
    return overrides


def add_pretrain_arguments(parser: argparse.ArgumentParser, episodes_help: str) -> None:
    """Declare ``--pretrain-episodes N`` (help ``episodes_help``) and ``--pretrain-epochs
    E``; :func:`check_pretrain_arguments` refuses the second without the first."""
    parser.add_argument(
        "--pretrain-episodes",
        type=int_in(1, MAX_PRETRAIN_EPISODES),
        default=None,
        help=episodes_help,
    )
    parser.add_argument(
        "--pretrain-epochs",
        type=positive_int,
        default=None,
        help=f"passes over the demonstrations of --pretrain-episodes ({DEFAULT_PRETRAIN_EPOCHS})",
    )


def check_pretrain_arguments(args: argparse.Namespace) -> None:
    """Refuse ``--pretrain-epochs`` without ``--pretrain-episodes`` (:class:`BadArgument`)."""
    if args.pretrain_epochs is not None and args.pretrain_episodes is None:
        raise BadArgument("--pretrain-epochs", "needs --pretrain-episodes")


def env_settings(
    pairs: list[tuple[str, Any]], own_flags: tuple[str, ...] = ()
) -> tuple[list[str], dict[str, Any]]:
    """``--env`` pairs of a command that passes them on to ``aldm-gym train``.

    :param own_flags: the env settings the command has flags of its own for (refused
        here, naming the flag); the other settings ``train`` has a flag for come back
        as those flags' values.
    :return: the ``KEY=VALUE`` arguments of ``train --env`` (values as JSON), checked
        as :func:`_env_overrides` checks them, and ``{train flag dest: value}``.
    """
    flags: dict[str, Any] = {}
    rest = []
    for key, value in pairs:
        if key in own_flags:
            raise BadArgument("--env", f"{key} has its own flag: {_flag(key)}")
        if key in _ENV_FLAGS:
            try:
                merge_config(default_config(), {key: value})
            except ConfigError as exc:
                raise BadArgument("--env", str(exc)) from None
            flags[_ENV_FLAGS[key]] = value
        else:
            rest.append((key, value))
    _env_overrides(rest)
    return [f"{key}={json.dumps(value)}" for key, value in rest], flags


def _check_resume(args: argparse.Namespace, record: TrainingRecord) -> None:
    """Refuse flags that contradict the training being resumed (:class:`BadArgument`)."""
    cfg, ppo = record.env_config, record.ppo
    if args.env:
        # compared as JSON values (the config view holds tuples where --env gives lists)
        saved_env = {k: json.loads(json.dumps(v)) for k, v in dotted_settings(cfg.parsed()[1])}
        for key, value in dotted_settings(_env_overrides(args.env)):
            if key not in saved_env:
                raise BadArgument(
                    "--env",
                    f"{key} was not set in the training being resumed (its default "
                    "applies); omit it with --resume",
                )
            if saved_env[key] != json.loads(json.dumps(value)):
                raise BadArgument(
                    "--env",
                    f"{key}={json.dumps(value)} contradicts the training being resumed "
                    f"({json.dumps(saved_env[key])}); omit it with --resume",
                )
    for name, value in (
        ("--pretrain-episodes", args.pretrain_episodes),
        ("--pretrain-epochs", args.pretrain_epochs),
    ):
        if value is not None:
            raise BadArgument(
                name, "clones before a new training only; a resume keeps the training's own"
            )
    algo = {name: key for key, name in ALGORITHMS.items()}.get(record.algorithm)
    for name, value, saved in (
        ("--algo", args.algo, algo),
        ("--detector", args.detector, cfg["detector"]),
        ("--marking-model", args.marking_model, cfg["marking_model"]),
        ("--duration", args.duration, cfg.get("duration")),
        ("--vehicles", args.vehicles, cfg.get("vehicles_count")),
        ("--collision-reward", args.collision_reward, cfg.get("collision_reward")),
        ("--overtaking-reward", args.overtaking_reward, cfg.get("overtaking_reward")),
        ("--learning-rate", args.learning_rate, ppo.learning_rate),
        ("--ent-coef", args.ent_coef, ppo.ent_coef),
        ("--n-steps", args.n_steps, ppo.n_steps),
        ("--lr-schedule", args.lr_schedule, ppo.lr_schedule),
        ("--gamma", args.gamma, ppo.gamma),
        ("--keep-by", args.keep_by, record.keep_by),
    ):
        if value is not None and value != saved:
            raise BadArgument(
                name,
                f"{value} contradicts the training being resumed ({saved}); omit it with --resume",
            )


def _common_settings(args: argparse.Namespace, quick: bool) -> dict[str, Any]:
    """The keyword arguments both backends' training functions take from the flags."""
    n_steps = args.n_steps or (QUICK_N_STEPS if quick else PPOParams.n_steps)
    return {
        "algo": args.algo or "ppo",
        "detector": args.detector or "aldm",
        "marking_model": args.marking_model or "per_dash",
        "timesteps": args.timesteps or (QUICK_TIMESTEPS if quick else None),
        "seed": args.seed,
        "checkpoint_freq": args.checkpoint_freq,
        "duration": args.duration or (QUICK_DURATION if quick else None),
        "vehicles_count": args.vehicles,
        "collision_reward": (
            DEFAULT_COLLISION_REWARD if args.collision_reward is None else args.collision_reward
        ),
        "overtaking_reward": args.overtaking_reward,
        "env_overrides": _env_overrides(args.env),
        "params": PPOParams(
            n_steps=n_steps,
            learning_rate=(
                PPOParams.learning_rate if args.learning_rate is None else args.learning_rate
            ),
            ent_coef=PPOParams.ent_coef if args.ent_coef is None else args.ent_coef,
            gamma=PPOParams.gamma if args.gamma is None else args.gamma,
            lr_schedule=args.lr_schedule or PPOParams.lr_schedule,
        ),
        "resume": args.resume,
        "progress": not args.no_progress,
    }


def _call_training(func: Callable[..., Any], out: Path, **kwargs: Any) -> Any:
    """``func(out, **kwargs)`` (either backend's training) with warnings as one line
    each; its result, or None when interrupted (Ctrl-C, SIGTERM). What the user can fix
    is raised as :class:`BadArgument` naming the flag, a missing extra as SystemExit."""
    try:
        with console(), warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return func(out, **kwargs)
    except MissingRLDependencies as exc:
        raise SystemExit(f"aldm-gym train: {exc}") from None
    except ClusterError as exc:  # absent, refusing our token, or too small
        raise BadArgument(exc.argument, str(exc)) from None
    except ResumeError as exc:
        raise BadArgument("--resume", str(exc)) from None
    except (OutputLocked, FileExistsError, FileNotFoundError) as exc:  # a race on --out
        raise BadArgument("--out", str(exc)) from None
    except KeyboardInterrupt:
        return None


def _one_line_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    file: Any = None,
    line: str | None = None,
) -> None:
    """Print a warning as ``aldm-gym train: warning: <message>``."""
    print(f"aldm-gym train: warning: {message}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    """``aldm-gym train``."""
    out: Path = args.out
    quick = args.quick and not args.resume  # a resume keeps the run's own settings
    try:
        check_unlocked(out)
    except OutputLocked as exc:
        raise BadArgument("--out", str(exc)) from None
    record = None
    if args.resume:
        if not (out / TRAINING_FILE).exists():
            raise BadArgument("--resume", f"nothing to resume in {out} (no {TRAINING_FILE})")
        try:
            record = TrainingRecord.read(out / TRAINING_FILE)
        except CheckpointError as exc:
            raise BadArgument("--resume", str(exc)) from None
    elif holds_training(out):
        raise BadArgument(
            "--out",
            f"{out} already holds a training; pass --resume to continue it or choose another --out",
        )
    backend = _backend(args, record)
    if record is not None:
        _check_resume(args, record)
    _env_overrides(args.env)  # a bad --env is refused before --out is made
    check_pretrain_arguments(args)
    make_output_dir(out)
    if backend == "rllib":
        return _run_rllib(args, quick)
    validation_freq = args.validation_freq
    validation_episodes = args.validation_episodes
    if quick:
        validation_freq = QUICK_VALIDATION_FREQ if validation_freq is None else validation_freq
        validation_episodes = validation_episodes or QUICK_VALIDATION_EPISODES
    t0 = time.perf_counter()
    model = _call_training(
        train,
        out,
        n_envs=args.n_envs,
        validation_freq=validation_freq,
        validation_episodes=validation_episodes,
        pretrain_episodes=args.pretrain_episodes or 0,
        pretrain_epochs=args.pretrain_epochs or DEFAULT_PRETRAIN_EPOCHS,
        keep_by=args.keep_by,
        **_common_settings(args, quick),
    )
    if model is None:
        return 130
    tb = out / TENSORBOARD_DIR
    print(
        f"trained {model.num_timesteps} steps in {time.perf_counter() - t0:.0f} s; wrote "
        f"{out / MODEL_FILE}, checkpoints in {out / CHECKPOINT_DIR}, tensorboard logs in "
        f"{tb} (tensorboard --logdir {tb})"
    )
    validation = out / VALIDATION_FILE
    if TrainingRecord.read(out / TRAINING_FILE).run.validation_freq > 0 and validation.exists():
        record = json.loads(validation.read_text())
        best = next(h for h in record["history"] if h["steps"] == record["best_steps"])
        print(
            f"best validation by {record.get('keep_by', 'return')} at {best['steps']} steps "
            f"(mean return {best['mean_return']:.2f}, "
            f"success {best['success_rate']:.2f}, {best['mean_speed']:.2f} m/s): "
            f"{out / BEST_MODEL_FILE}; evaluate it with aldm-gym evaluate --model {out}"
        )
    return 0


def _run_rllib(args: argparse.Namespace, quick: bool) -> int:
    """``aldm-gym train --backend rllib``."""
    out: Path = args.out
    t0 = time.perf_counter()
    steps = _call_training(
        train_rllib,
        out,
        num_env_runners=args.num_env_runners,
        address=args.address,
        **_common_settings(args, quick),
    )
    if steps is None:
        return 130
    tb = out / TENSORBOARD_DIR
    print(
        f"trained {steps} steps in {time.perf_counter() - t0:.0f} s; "
        f"wrote {out / RLLIB_MODEL_DIR}, checkpoints in {out / CHECKPOINT_DIR}, "
        f"tensorboard logs in {tb / TB_RUN} "
        f"(tensorboard --logdir {tb}); evaluate it with "
        f"aldm-gym evaluate --model {out}"
    )
    return 0
