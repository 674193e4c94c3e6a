"""Deprecated name of :mod:`aldm_gym.roads.reference_line`."""

from aldm_gym._compat import moved

moved(__name__, "aldm_gym.roads.reference_line")
