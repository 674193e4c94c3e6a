"""Deprecated: a trained model's evaluation is :mod:`aldm_gym.training.model_evaluation`.

This module re-exports its public names and warns (``DeprecationWarning``) on import.
"""

from __future__ import annotations

import warnings

from aldm_gym.training.model_evaluation import (
    BASELINES,
    CONFIDENCE,
    EVAL_COLUMNS,
    EVALUATION_SEED,
    MIN_EPISODES,
    SIGNIFICANCE,
    collision_test,
    evaluate,
    paired_difference,
    summary_line,
    verdict,
)

__all__ = [
    "BASELINES",
    "CONFIDENCE",
    "EVALUATION_SEED",
    "EVAL_COLUMNS",
    "MIN_EPISODES",
    "SIGNIFICANCE",
    "collision_test",
    "evaluate",
    "paired_difference",
    "summary_line",
    "verdict",
]

warnings.warn(
    "aldm_gym.agents.model_evaluation is deprecated; "
    "import from aldm_gym.training.model_evaluation",
    DeprecationWarning,
    stacklevel=2,
)
