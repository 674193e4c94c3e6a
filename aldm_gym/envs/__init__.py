"""Environments: ``ALDMHighway-v0`` and the traffic that scales.

Submodules are imported on use (``aldm_gym.envs.highway`` pulls in highway-env).
"""

from __future__ import annotations
