"""Deprecated name of :mod:`aldm_gym.sensor.lane_detection`."""

from aldm_gym._compat import moved

moved(__name__, "aldm_gym.sensor.lane_detection")
