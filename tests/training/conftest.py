"""Fixtures of the training tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def rllib() -> object:
    """``ray.rllib``; the test skips without the ``[ray]`` extra."""
    return pytest.importorskip("ray.rllib")
