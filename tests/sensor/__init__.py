"""Tests of :mod:`aldm_gym.sensor` (a package, so that test module names may repeat across
folders)."""
