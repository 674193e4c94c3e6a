"""Deprecated name of :mod:`aldm_gym.agents.episodes`."""

from aldm_gym._compat import moved

moved(__name__, "aldm_gym.agents.episodes")
