"""``aldm-gym evaluate``: a trained policy against IDLE and the rule-based LCA.

``--model`` is an SB3 ``.zip`` or an RLlib checkpoint folder (``--backend rllib``);
both play the same seeds through the same code.

Writes ``evaluate_<model>_<detector>_<marking model>.json`` next to the model (or to
``--out``) and prints the table and a one-line verdict
(:mod:`aldm_gym.agents.model_evaluation`).
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from aldm_gym.agents.checkpoints import TRAINING_FILE, find_training_file
from aldm_gym.agents.model_evaluation import (
    EVAL_COLUMNS,
    EVALUATION_SEED,
    evaluate,
    summary_line,
)
from aldm_gym.agents.sb3 import MissingRLDependencies
from aldm_gym.agents.training import VALIDATION_SEED
from aldm_gym.cli.argtypes import (
    BadArgument,
    make_output_dir,
    model_path,
    output_dir,
    positive_int,
    seed,
)
from aldm_gym.cli.report import format_table
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.detectors import DETECTORS

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
        required=True,
        help="model .zip or checkpoint (SB3), or checkpoint folder (RLlib: rllib_model, "
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
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """``aldm-gym evaluate``."""
    episodes = args.episodes or (QUICK_EPISODES if args.quick else EPISODES)
    if find_training_file(args.model) is None:
        raise BadArgument(
            "--model",
            f"no {TRAINING_FILE} next to {args.model} "
            "(models are read from an aldm-gym train output folder)",
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
    except (ValueError, FileNotFoundError) as exc:  # a corrupt model, not a checkpoint
        raise BadArgument("--model", str(exc)) from None
    out = make_output_dir(args.out or args.model.parent)
    cfg = info["env_config"]
    name = args.model.name if args.model.is_dir() else args.model.stem
    path = out / f"evaluate_{name}_{cfg['detector']}_{cfg['marking_model']}.json"
    path.write_text(json.dumps({"rows": rows, **info}, indent=2) + "\n")
    print(f"wrote {path} ({time.perf_counter() - t0:.0f} s)")
    print(format_table(rows, EVAL_COLUMNS))
    print(summary_line(rows, info))
    return 0
