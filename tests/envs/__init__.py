"""Tests of :mod:`aldm_gym.envs` (a package, so that test module names may repeat across
folders)."""
