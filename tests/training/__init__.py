"""Tests of :mod:`aldm_gym.training` (a package, so that its test modules' names do not
clash with same-named ones elsewhere in ``tests/``)."""
