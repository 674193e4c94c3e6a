"""Tests of :mod:`aldm_gym.cli` (a package, so that test module names may repeat across
folders)."""
