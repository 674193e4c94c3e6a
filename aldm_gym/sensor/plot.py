"""Deprecated name of :mod:`aldm_gym.sensor.frame_plot`."""

from aldm_gym._compat import moved

moved(__name__, "aldm_gym.sensor.frame_plot")
