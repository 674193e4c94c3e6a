"""The stable-baselines3 backend: PPO on vectorised envs of one machine.

:func:`~aldm_gym.training.sb3.backend.train` (``aldm-gym train``) fits an SB3 PPO
``MultiInputPolicy`` on the meta actions (``Discrete(5)``) of ``ALDMHighway-v0``.
Modules:

* :mod:`~aldm_gym.training.sb3.backend`: :class:`~aldm_gym.training.sb3.backend.SB3Backend`
  and :func:`~aldm_gym.training.sb3.backend.train`.
* :mod:`~aldm_gym.training.sb3.envs`: the training envs and the process's RNG states.
* :mod:`~aldm_gym.training.sb3.checkpoints`: snapshots and checkpoint files.
* :mod:`~aldm_gym.training.sb3.callbacks`: the SB3 callbacks (checkpoints,
  validation, progress bar).
* :mod:`~aldm_gym.training.sb3.policy`: a saved model as a policy.

stable-baselines3 and torch are optional (the ``[rl]`` extra) and heavy: the modules
import them inside functions through :func:`import_sb3` (only ``callbacks``, which
subclasses SB3's callbacks, imports them at its top and is itself imported when a
training runs), so ``import aldm_gym`` and the ``aldm-gym`` parser stay light.
"""

from __future__ import annotations

from typing import Any

from aldm_gym.errors import MissingRLDependencies
from aldm_gym.training.backend import import_extra

__all__ = ["MissingRLDependencies", "import_sb3", "model_class"]


def import_sb3() -> Any:
    """Import stable_baselines3 (and torch) or raise :class:`MissingRLDependencies`."""
    import_extra(
        ("stable_baselines3", "torch"),
        MissingRLDependencies,
        "training needs stable-baselines3, torch and tensorboard",
        "rl",
    )
    import stable_baselines3

    return stable_baselines3


def model_class(algorithm: str) -> Any:
    """The SB3 model class of an algorithm name (``training.json``'s ``algorithm``):
    stable-baselines3's ``PPO``, or sb3-contrib's ``MaskablePPO``.

    :raises MissingRLDependencies: its library is missing.
    :raises ValueError: an algorithm without an SB3 class.
    """
    import_sb3()
    if algorithm == "PPO":
        from stable_baselines3 import PPO

        return PPO
    if algorithm == "MaskablePPO":
        import_extra(
            ("sb3_contrib",),
            MissingRLDependencies,
            "MaskablePPO needs sb3-contrib",
            "rl",
        )
        from sb3_contrib import MaskablePPO

        return MaskablePPO
    raise ValueError(f"no SB3 model class for the algorithm {algorithm!r}")
