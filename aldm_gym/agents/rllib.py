"""Deprecated: the RLlib backend is :mod:`aldm_gym.training.rllib`.

This module re-exports the public names of its modules and warns
(``DeprecationWarning``) on import.
"""

from __future__ import annotations

import warnings

from aldm_gym.errors import ClusterError, MissingRLDependencies, ResumeError
from aldm_gym.training.outputs import RLLIB_CHECKPOINT_PREFIX as CHECKPOINT_PREFIX
from aldm_gym.training.outputs import RLLIB_MODEL_DIR as MODEL_DIR
from aldm_gym.training.rllib import MissingRayDependencies, import_rllib
from aldm_gym.training.rllib.backend import TB_RUN, train_rllib
from aldm_gym.training.rllib.checkpoints import (
    STEPS_FILE,
    checkpoint_steps,
    is_checkpoint,
    newest_checkpoint,
)
from aldm_gym.training.rllib.cluster import CONNECT_TIMEOUT
from aldm_gym.training.rllib.config import RLLIB_ENV_ID, flatten_and_normalise, ppo_config
from aldm_gym.training.rllib.policy import RLlibPolicy, load_rllib_policy
from aldm_gym.training.settings import DEFAULT_ENV_RUNNERS

__all__ = [
    "CHECKPOINT_PREFIX",
    "CONNECT_TIMEOUT",
    "DEFAULT_ENV_RUNNERS",
    "MODEL_DIR",
    "RLLIB_ENV_ID",
    "STEPS_FILE",
    "TB_RUN",
    "ClusterError",
    "MissingRLDependencies",
    "MissingRayDependencies",
    "RLlibPolicy",
    "ResumeError",
    "checkpoint_steps",
    "flatten_and_normalise",
    "import_rllib",
    "is_checkpoint",
    "load_rllib_policy",
    "newest_checkpoint",
    "ppo_config",
    "train_rllib",
]

warnings.warn(
    f"{__name__} is now split over aldm_gym.training.rllib and its modules; "
    "import from there (the old name will be removed)",
    DeprecationWarning,
    stacklevel=2,
)
