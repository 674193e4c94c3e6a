"""Deprecated: the stable-baselines3 gate is :mod:`aldm_gym.training.sb3`.

This module re-exports its public names and warns (``DeprecationWarning``) on import.
"""

from __future__ import annotations

import warnings

from aldm_gym.training.sb3 import MissingRLDependencies, import_sb3

__all__ = ["MissingRLDependencies", "import_sb3"]

warnings.warn(
    "aldm_gym.agents.sb3 is deprecated; import from aldm_gym.training.sb3",
    DeprecationWarning,
    stacklevel=2,
)
