"""aldm-gym: highway driving on an emulated CarMaker line sensor with the ALDM.

Importing this package registers ``ALDMHighway-v0`` with Gymnasium. The import is
kept light: no highway-env, pygame, matplotlib or torch is loaded until used.
"""

from __future__ import annotations

__version__ = "0.1.0"
__all__ = ["ENV_ID", "__version__"]

ENV_ID = "ALDMHighway-v0"
"""Gymnasium id of the environment (:class:`aldm_gym.envs.highway.ALDMHighwayEnv`)."""


def _register() -> None:
    """Register ``ALDMHighway-v0`` once (idempotent: re-imports and reloads are no-ops)."""
    import gymnasium

    if ENV_ID not in gymnasium.envs.registry:
        gymnasium.register(id=ENV_ID, entry_point="aldm_gym.envs.highway:ALDMHighwayEnv")


_register()
