"""Deprecated name of :mod:`aldm_gym.training.sb3`."""

from aldm_gym._compat import moved

moved(__name__, "aldm_gym.training.sb3")
