"""Deprecated: PPO training moved to :mod:`aldm_gym.training`.

The SB3 trainer is :mod:`aldm_gym.training.sb3.backend`, its envs
:mod:`aldm_gym.training.sb3.envs`, the settings :mod:`aldm_gym.training.settings`.
This module re-exports their public names and warns (``DeprecationWarning``) on import.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from contextlib import contextmanager

from aldm_gym.training.sb3.backend import RUN_SETTINGS, train
from aldm_gym.training.sb3.checkpoints import take_snapshot
from aldm_gym.training.sb3.envs import (
    ResumableEnv,
    global_rng_state,
    make_vec_env,
    set_global_rng_state,
)
from aldm_gym.training.settings import (
    DEFAULT_CHECKPOINT_FREQ,
    DEFAULT_COLLISION_REWARD,
    DEFAULT_TIMESTEPS,
    DEFAULT_VALIDATION_EPISODES,
    DEFAULT_VALIDATION_FREQ,
    LR_SCHEDULES,
    VALIDATION_SEED,
    PPOParams,
    env_config,
    resolve_run_settings,
)

# A model saved with a linear learning rate pickled its schedule under this name.
from aldm_gym.training.settings import linear_schedule as _linear  # noqa: F401
from aldm_gym.training.signals import stop_on_signal

__all__ = [
    "DEFAULT_CHECKPOINT_FREQ",
    "DEFAULT_COLLISION_REWARD",
    "DEFAULT_TIMESTEPS",
    "DEFAULT_VALIDATION_EPISODES",
    "DEFAULT_VALIDATION_FREQ",
    "LR_SCHEDULES",
    "RUN_SETTINGS",
    "VALIDATION_SEED",
    "PPOParams",
    "ResumableEnv",
    "env_config",
    "global_rng_state",
    "make_vec_env",
    "resolve_run_settings",
    "set_global_rng_state",
    "signals_as_interrupt",
    "take_snapshot",
    "train",
]

warnings.warn(
    f"{__name__} is now split over aldm_gym.training.sb3.backend, "
    "aldm_gym.training.sb3.envs and aldm_gym.training.settings; "
    "import from there (the old name will be removed)",
    DeprecationWarning,
    stacklevel=2,
)


@contextmanager
def signals_as_interrupt() -> Iterator[None]:
    """SIGINT and SIGTERM raise KeyboardInterrupt while the block runs
    (:func:`aldm_gym.training.signals.stop_on_signal` with ``at_once``)."""
    with stop_on_signal(at_once=True):
        yield
