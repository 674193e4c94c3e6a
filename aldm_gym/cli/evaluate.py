"""``aldm-gym evaluate``: a trained policy or a function under test against IDLE and
the rule-based LCA.

``--model`` is an SB3 ``.zip``, an RLlib checkpoint folder (``--backend rllib``), or a
training's output folder: from that it takes the best validation's model, else the
final model (:func:`~aldm_gym.training.models.model_to_evaluate`), and says which.
Both backends' models play the same seeds through the same code. ``--function SPEC``
evaluates any function under test instead (:func:`aldm_gym.function.load_function`;
a model given there is evaluated as with ``--model``), on the env's default settings
with ``--env``/``--config`` over them.

Writes ``evaluate_<model>_<detector>_<marking model>.json`` next to the model (or to
``--out``; a function's ``evaluate_function_<name>_...`` into ``--out``, default
``evaluate_results``) and prints the table and a one-line verdict
(:mod:`aldm_gym.training.model_evaluation`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from aldm_gym.cli.argtypes import (
    FUNCTION_HELP,
    BadArgument,
    add_env_argument,
    check_env,
    function_spec,
    make_output_dir,
    model_path,
    nested_pairs,
    output_dir,
    positive_int,
    seed,
)
from aldm_gym.cli.console import console
from aldm_gym.cli.report import format_table
from aldm_gym.errors import CheckpointError, MissingRLDependencies
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.detectors import DETECTORS
from aldm_gym.training.model_evaluation import (
    EVAL_COLUMNS,
    EVALUATION_SEED,
    evaluate,
    summary_line,
)
from aldm_gym.training.models import model_to_evaluate
from aldm_gym.training.outputs import TRAINING_FILE, find_training_file
from aldm_gym.training.settings import VALIDATION_SEED

EPISODES = 30
"""Default episodes per policy."""

QUICK_EPISODES = 5
"""``evaluate --quick``: episodes per policy."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym evaluate`` and its arguments."""
    parser = subparsers.add_parser(
        "evaluate", help="evaluate a trained policy against rule-based ones"
    )
    parser.add_argument(
        "--model",
        type=model_path,
        help="a training's output folder (its best model, else its final one), a model "
        ".zip or checkpoint (SB3), or a checkpoint folder (RLlib: rllib_model, "
        "checkpoints/rllib_<steps>)",
    )
    parser.add_argument(
        "--episodes",
        type=positive_int,
        default=None,
        help=f"episodes per policy ({EPISODES}; quick {QUICK_EPISODES})",
    )
    parser.add_argument(
        "--detector", choices=DETECTORS, default=None, help="override the training detector"
    )
    parser.add_argument(
        "--marking-model", choices=MARKING_MODELS, default=None, help="override the road model"
    )
    parser.add_argument(
        "--seed",
        type=seed,
        default=EVALUATION_SEED,
        help=f"first episode seed (training uses 0.., validation {VALIDATION_SEED}..)",
    )
    parser.add_argument(
        "--out", type=output_dir, default=None, help="folder for evaluation JSON (the model's)"
    )
    parser.add_argument(
        "--quick", action="store_true", help=f"{QUICK_EPISODES} episodes per policy"
    )
    add_env_argument(parser, "over the training's; its observation and action stay as trained")
    parser.add_argument(
        "--function",
        default=None,
        metavar="SPEC",
        help="evaluate a function under test instead of --model: " + FUNCTION_HELP,
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)
    return parser


def _env(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``--env`` pairs as env settings, checked (:class:`BadArgument` naming the key);
    the detector and marking model have their own flags, the policy's observation and
    action stay as trained."""
    overrides = nested_pairs(pairs)
    for key, flag in (("detector", "--detector"), ("marking_model", "--marking-model")):
        if key in overrides:
            raise BadArgument("--env", f"{key} has its own flag: {flag}")
    for key in ("observation", "action"):
        if key in overrides:
            raise BadArgument("--env", f"{key}: the policy was trained on it; it stays as trained")
    check_env(overrides)
    return overrides


def run(args: argparse.Namespace) -> int:
    """``aldm-gym evaluate``."""
    episodes = args.episodes or (QUICK_EPISODES if args.quick else EPISODES)
    if (args.model is None) == (args.function is None):
        raise BadArgument("--model", "give --model or --function (one of them)")
    if args.function is not None:
        from aldm_gym.function.builtin import PolicyFunction

        function = function_spec(args)
        if not (isinstance(function, PolicyFunction) and Path(args.function).exists()):
            return _run_function(args, function, episodes)
        args.model = Path(args.function)  # a trained model: evaluated as --model
    overrides = _env(args.env)
    try:
        model, picked = model_to_evaluate(args.model)
    except CheckpointError as exc:  # an output folder without a trained model
        raise BadArgument("--model", str(exc)) from None
    if find_training_file(model) is None:
        raise BadArgument(
            "--model",
            f"no {TRAINING_FILE} next to {model} "
            "(models are read from an aldm-gym train output folder)",
        )
    if picked is not None:
        print(f"evaluating {model}: {picked}")
    t0 = time.perf_counter()
    try:
        with console():
            rows, info = evaluate(
                model,
                episodes=episodes,
                seed=args.seed,
                detector=args.detector,
                marking_model=args.marking_model,
                progress=not args.no_progress,
                env_overrides=overrides,
            )
    except MissingRLDependencies as exc:
        raise SystemExit(f"aldm-gym evaluate: {exc}") from None
    except (ValueError, FileNotFoundError) as exc:  # a corrupt model, not a checkpoint
        raise BadArgument("--model", str(exc)) from None
    out = make_output_dir(args.out or model.parent)
    cfg = info["env_config"]
    name = model.name if model.is_dir() else model.stem
    path = out / f"evaluate_{name}_{cfg['detector']}_{cfg['marking_model']}.json"
    _report(path, rows, info, t0)
    return 0


def _report(path: Path, rows: list[dict[str, Any]], info: dict[str, Any], t0: float) -> None:
    """Write the evaluation's JSON, then print the table and the verdict."""
    path.write_text(json.dumps({"rows": rows, **info}, indent=2, default=str) + "\n")
    print(f"wrote {path} ({time.perf_counter() - t0:.0f} s)")
    print(format_table(rows, EVAL_COLUMNS))
    print(summary_line(rows, info))


def _run_function(args: argparse.Namespace, function: Any, episodes: int) -> int:
    """``evaluate --function``: the function against IDLE and the rule-based LCA on
    the env's default settings (``--detector``, ``--marking-model``, ``--env`` over
    them)."""
    from aldm_gym.errors import ConfigError
    from aldm_gym.function import FunctionPolicy, close_function, env_for
    from aldm_gym.training.model_evaluation import RULE_BASED, play_policies

    overrides = nested_pairs(args.env)
    for key, value in (("detector", args.detector), ("marking_model", args.marking_model)):
        if value is not None:
            overrides[key] = value
    base = check_env(overrides)
    try:
        config = env_for(function, base, given=set(overrides))
    except ConfigError as exc:
        raise BadArgument("--env", str(exc)) from None
    t0 = time.perf_counter()
    try:
        with console():
            # the rule-based policies on the settings as given (their rate included),
            # the function on what it needs (env_for): the same seeds for both
            rows, per_episode = play_policies(
                base, RULE_BASED, episodes=episodes, seed=args.seed, progress=not args.no_progress
            )
            more, per = play_policies(
                config,
                (("function", lambda env: FunctionPolicy(env, function)),),
                episodes=episodes,
                seed=args.seed,
                progress=not args.no_progress,
            )
            rows += more
            per_episode.update(per)
    finally:
        close_function(function)
    detector, marking_model = config.settings.detector, config.settings.marking_model
    info = {
        "function": args.function,
        "env_config": {"detector": detector, "marking_model": marking_model} | base.to_dict(),
        "function_env_config": config.to_dict(),
        "seeds": [args.seed, args.seed + episodes - 1],
        "per_episode": per_episode,
    }
    out = make_output_dir(args.out or Path("evaluate_results"))
    name = Path(args.function.replace(":", "_")).name
    path = out / f"evaluate_function_{name}_{detector}_{marking_model}.json"
    _report(path, rows, info, t0)
    return 0
