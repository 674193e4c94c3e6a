"""Deprecated name of :mod:`aldm_gym.agents.target_scenes`."""

from aldm_gym._compat import moved

moved(__name__, "aldm_gym.agents.target_scenes")
