"""Deprecated: a training's output folder is :mod:`aldm_gym.training.outputs`, its lock
:mod:`aldm_gym.training.lock`, SB3 checkpoints :mod:`aldm_gym.training.sb3.checkpoints`
and loading a model :mod:`aldm_gym.training.models`.

This module re-exports their public names and warns (``DeprecationWarning``) on import.
"""

from __future__ import annotations

import warnings

from aldm_gym.errors import OutputLocked, TrainingWarning
from aldm_gym.training.lock import check_unlocked, output_lock
from aldm_gym.training.models import load_policy
from aldm_gym.training.outputs import (
    BEST_MODEL_FILE,
    BEST_VECNORM_FILE,
    CHECKPOINT_DIR,
    LOCK_FILE,
    MODEL_FILE,
    TENSORBOARD_DIR,
    TRAINING_FILE,
    VALIDATION_FILE,
    VALIDATION_PLOT,
    VECNORM_FILE,
    can_resume,
    checkpoint_paths,
    find_training_file,
    holds_training,
    latest_checkpoint,
    manifest_path,
    read_training,
    remove_temporary_files,
    resume_state_path,
    save_atomic,
    write_bytes_atomic,
    write_json,
)
from aldm_gym.training.sb3.checkpoints import (
    Checkpoint,
    Snapshot,
    checkpoint_fault,
    newest_intact_checkpoint,
    save_model,
    vecnormalize_for,
    write_checkpoint,
)
from aldm_gym.training.sb3.policy import NormalizedModel

__all__ = [
    "BEST_MODEL_FILE",
    "BEST_VECNORM_FILE",
    "CHECKPOINT_DIR",
    "LOCK_FILE",
    "MODEL_FILE",
    "TENSORBOARD_DIR",
    "TRAINING_FILE",
    "VALIDATION_FILE",
    "VALIDATION_PLOT",
    "VECNORM_FILE",
    "Checkpoint",
    "NormalizedModel",
    "OutputLocked",
    "Snapshot",
    "TrainingWarning",
    "can_resume",
    "check_unlocked",
    "checkpoint_fault",
    "checkpoint_paths",
    "find_training_file",
    "holds_training",
    "latest_checkpoint",
    "load_policy",
    "manifest_path",
    "newest_intact_checkpoint",
    "output_lock",
    "read_training",
    "remove_temporary_files",
    "resume_state_path",
    "save_atomic",
    "save_model",
    "vecnormalize_for",
    "write_bytes_atomic",
    "write_checkpoint",
    "write_json",
]

warnings.warn(
    f"{__name__} is now split over aldm_gym.training.outputs, aldm_gym.training.lock, "
    "aldm_gym.training.sb3.checkpoints and aldm_gym.training.models; "
    "import from there (the old name will be removed)",
    DeprecationWarning,
    stacklevel=2,
)
