"""``aldm-gym tune``: a hyperparameter search over short trainings (optuna).

Runs :func:`~aldm_gym.training.tune.tune`: ``--trials`` ``aldm-gym train`` runs of
``--timesteps`` steps each, ``--jobs`` at once, with hyperparameters from
:data:`~aldm_gym.training.tune.SEARCH_SPACE` (or, with ``--pretrain-episodes``, every
trial fine-tuning a clone of the rule-based LCA, from
:data:`~aldm_gym.training.tune.FINETUNE_SPACE`), each scored on its validation seeds. It
writes ``<out>/trials.csv``, ``<out>/trials.png`` (the finished trials' validation
curves) and ``<out>/best.json`` (with the command that trains the
best trial's hyperparameters with the full budget: the trials' own ``--timesteps`` or
train's default, whichever is more); a folder with a study continues it.
optuna is imported only when the command runs (the ``[tune]`` extra).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from tqdm import tqdm

from aldm_gym.cli.argtypes import (
    BadArgument,
    add_env_argument,
    int_in,
    make_output_dir,
    output_dir,
    positive_int,
    seed,
)
from aldm_gym.cli.train import (
    add_pretrain_arguments,
    check_pretrain_arguments,
    env_settings,
)
from aldm_gym.errors import MissingRLDependencies, OutputLocked
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.detectors import DETECTORS
from aldm_gym.training.settings import (
    ALGORITHMS,
    DEFAULT_VALIDATION_EPISODES,
    DEFAULT_VALIDATION_FREQ,
    KEEP_BY,
)

DEFAULT_TRIALS = 12
"""Default ``--trials``."""

DEFAULT_TRIAL_TIMESTEPS = 16_384
"""Default ``--timesteps`` of one trial [policy steps]."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym tune`` and its arguments."""
    parser = subparsers.add_parser(
        "tune", help="search PPO hyperparameters over short trainings (optuna)"
    )
    parser.add_argument("--trials", type=positive_int, default=DEFAULT_TRIALS, help="trials in all")
    parser.add_argument(
        "--jobs", type=int_in(1, 64), default=2, help="trials at once, a process each"
    )
    parser.add_argument(
        "--timesteps",
        type=positive_int,
        default=DEFAULT_TRIAL_TIMESTEPS,
        help="policy steps of each trial",
    )
    parser.add_argument("--algo", choices=tuple(ALGORITHMS), default="maskable-ppo")
    parser.add_argument("--detector", choices=DETECTORS, default="aldm")
    parser.add_argument("--marking-model", choices=MARKING_MODELS, default="per_dash")
    add_env_argument(parser, "every trial gets them")
    parser.add_argument("--seed", type=seed, default=0, help="training seed of every trial")
    parser.add_argument("--sampler-seed", type=seed, default=0, help="seed of optuna's sampler")
    parser.add_argument(
        "--validation-freq",
        type=positive_int,
        default=DEFAULT_VALIDATION_FREQ,
        help="validate every this many steps",
    )
    parser.add_argument(
        "--validation-episodes",
        type=positive_int,
        default=DEFAULT_VALIDATION_EPISODES,
        help="episodes per validation (the score's)",
    )
    add_pretrain_arguments(
        parser,
        "every trial first clones the rule-based LCA played on this many episodes, and the "
        "search varies the fine-tuning's hyperparameters (off by default)",
    )
    parser.add_argument(
        "--enqueue",
        action="append",
        default=[],
        metavar="NAME=VALUE,...",
        help="a trial to run before the sampler's own, e.g. a known recipe: searched "
        "hyperparameters (names as in trials.csv; those not given are sampled); repeatable",
    )
    parser.add_argument(
        "--keep-by",
        choices=KEEP_BY,
        default="score",
        help="what each trial keeps its best model by, the model the trial is scored on: "
        "its validation score (as the trials are compared) or mean return",
    )
    parser.add_argument("--out", type=output_dir, default=Path("out/tune"), help="output folder")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """``aldm-gym tune``."""
    from aldm_gym.envs.rendering import DETECTOR_NAMES
    from aldm_gym.training.tune import (
        BEST_FILE,
        SPACES,
        TRIALS_TABLE,
        EnqueueError,
        StudyMismatch,
        parse_params,
        plot_trials,
        space_name,
        tune,
    )

    # bad flags are refused before --out is made; duration and traffic go to each
    # trial as train's own flags; the searched reward weights cannot be fixed
    check_pretrain_arguments(args)
    pretrain = {
        "pretrain_episodes": args.pretrain_episodes,
        "pretrain_epochs": args.pretrain_epochs,
    }
    space = SPACES[space_name(pretrain)]
    for key, _value in args.env:
        if key in space:
            raise BadArgument("--env", f"{key} is searched (the search varies {', '.join(space)})")
    env, env_flags = env_settings(args.env, own_flags=("detector", "marking_model"))
    enqueue = []
    for text in args.enqueue:
        try:
            enqueue.append(parse_params(text, space))
        except ValueError as exc:
            raise BadArgument("--enqueue", str(exc)) from None
    if len(enqueue) > args.trials:
        raise BadArgument(
            "--enqueue",
            f"{len(enqueue)} trials enqueued but --trials is {args.trials} "
            "(enqueued trials count among them): raise --trials",
        )
    out = make_output_dir(args.out)
    fixed = {
        "algo": args.algo,
        "detector": args.detector,
        "marking_model": args.marking_model,
        "timesteps": args.timesteps,
        "seed": args.seed,
        "validation_freq": args.validation_freq,
        "validation_episodes": args.validation_episodes,
        "keep_by": args.keep_by,
        **pretrain,
        **env_flags,
        "env": env,
    }
    t0 = time.perf_counter()
    with tqdm(total=args.trials, desc="trials", unit="trial", disable=args.no_progress) as bar:

        def on_trial(trial: Any) -> None:
            bar.update(1)
            if trial.value is not None:
                bar.set_postfix(last=f"{trial.value:.2f}")

        try:
            best = tune(
                out,
                trials=args.trials,
                jobs=args.jobs,
                seed=args.sampler_seed,
                fixed=fixed,
                on_trial=on_trial,
                enqueue=enqueue,
            )
        except MissingRLDependencies as exc:
            raise SystemExit(f"aldm-gym tune: {exc}") from None
        except (StudyMismatch, OutputLocked) as exc:
            raise BadArgument("--out", str(exc)) from None
        except EnqueueError as exc:  # with the trials an earlier run left waiting
            raise BadArgument("--trials", str(exc)) from None
    figure = plot_trials(out, DETECTOR_NAMES.get(args.detector, args.detector))
    drawn = "" if figure is None else f", {figure}"
    print(
        f"{best['trials']} trials in {time.perf_counter() - t0:.0f} s; best trial "
        f"{best['trial']} (score {best['score']:.2f}: {best['kept'].get('mean_speed', 0):.2f} "
        f"m/s, success {best['kept'].get('success_rate', 0):.2f} on the validation seeds); "
        f"wrote {out / TRIALS_TABLE}{drawn} and {out / BEST_FILE}\n"
        f"train it with: {best['command']}"
    )
    if args.pretrain_episodes and best["kept"].get("steps") == 0:
        print(
            "the best trial kept its clone (validated at step 0): no fine-tuning beat the "
            "clone, so its hyperparameters are not a finding"
        )
    return 0
