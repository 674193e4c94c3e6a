"""Tests of :mod:`aldm_gym.envs.traffic` (a package, so that test module names may repeat across
folders)."""
