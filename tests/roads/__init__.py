"""Tests of :mod:`aldm_gym.roads` (a package, so that test module names may repeat across
folders)."""
