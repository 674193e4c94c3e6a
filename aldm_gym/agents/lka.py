"""The lane-keeping controller as an agent (SB3-style ``predict``).

It lives in :mod:`aldm_gym.envs.control` because the environment's own meta-action
mode steers with it (layers import only the layers before them); it is re-exported
here for use as an agent in continuous-action mode.
"""

from __future__ import annotations

from aldm_gym.envs.control import LKAController

__all__ = ["LKAController"]
