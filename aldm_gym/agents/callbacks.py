"""Deprecated: the SB3 callbacks are in :mod:`aldm_gym.training.sb3.callbacks`.

This module re-exports their public names and warns (``DeprecationWarning``) on import.
"""

from __future__ import annotations

import warnings

from aldm_gym.training.sb3.callbacks import (
    ProgressCallback,
    RolloutCheckpointCallback,
    ValidationCallback,
    episode_postfix,
    format_validation,
    validation_row,
)

__all__ = [
    "ProgressCallback",
    "RolloutCheckpointCallback",
    "ValidationCallback",
    "episode_postfix",
    "format_validation",
    "validation_row",
]

warnings.warn(
    "aldm_gym.agents.callbacks is deprecated; import from aldm_gym.training.sb3.callbacks",
    DeprecationWarning,
    stacklevel=2,
)
