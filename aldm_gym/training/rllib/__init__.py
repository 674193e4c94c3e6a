"""The Ray RLlib backend: PPO whose env runners can sit on the nodes of a Ray cluster.

stable-baselines3 (:mod:`aldm_gym.training.sb3`) runs on one machine; RLlib spreads
the env steps over the env runners of a Ray cluster, on one machine or many
(``docs/cluster.md``). Modules:

* :mod:`~aldm_gym.training.rllib.backend`:
  :class:`~aldm_gym.training.rllib.backend.RLlibBackend` and
  :func:`~aldm_gym.training.rllib.backend.train_rllib` (``aldm-gym train --backend
  rllib``).
* :mod:`~aldm_gym.training.rllib.config`: the training's ``PPOConfig``.
* :mod:`~aldm_gym.training.rllib.checkpoints`: checkpoint folders, written whole.
* :mod:`~aldm_gym.training.rllib.cluster`: joining a cluster (or starting Ray here).
* :mod:`~aldm_gym.training.rllib.policy`: a checkpoint played outside Ray.

Ray, RLlib and torch (the ``[ray]`` extra) are imported inside the functions
(:func:`import_rllib`).
"""

from __future__ import annotations

from typing import Any

from aldm_gym.errors import MissingRayDependencies
from aldm_gym.training.backend import import_extra

__all__ = ["MissingRayDependencies", "import_rllib"]


def import_rllib() -> Any:
    """Import ``ray.rllib`` (and torch) or raise :class:`MissingRayDependencies`."""
    import_extra(
        ("ray.rllib", "torch"),
        MissingRayDependencies,
        "--backend rllib needs Ray RLlib and torch",
        "ray",
    )
    import ray.rllib

    return ray.rllib
