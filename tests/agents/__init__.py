"""Tests of :mod:`aldm_gym.agents` (a package, so that test module names may repeat across
folders)."""
