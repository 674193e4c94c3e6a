"""Helpers of the training tests: tiny trainings (a few seconds each on 2 cores),
damaged files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aldm_gym.cli import main

TINY = [
    *("--n-envs", "1", "--n-steps", "32", "--duration", "5", "--vehicles", "5"),
    *("--validation-freq", "0", "--no-progress"),
]
"""A few seconds of training: 1 env, 32-step rollouts, 5 s episodes, 5 vehicles, no
validation (tested on its own)."""

TINY_KWARGS: dict[str, Any] = {
    "detector": "naive",
    "n_envs": 1,
    "duration": 5.0,
    "vehicles_count": 5,
    "checkpoint_freq": 1000,
    "validation_freq": 0,
    "progress": False,
}
""":func:`~aldm_gym.training.sb3.backend.train`'s arguments of a tiny training (with
``params=PPOParams(n_steps=32)``), no periodic checkpoint."""


def tiny_train(out: Path, timesteps: int, *extra: str) -> int:
    """``aldm-gym train`` of ``timesteps`` steps with :data:`TINY`; its exit code."""
    return main(["train", "--timesteps", str(timesteps), "--out", str(out), *TINY, *extra])


def corrupt(path: Path, how: str) -> None:
    """Truncate ``path`` to half (``how="truncate"``), or flip one byte in its middle."""
    data = path.read_bytes()
    if how == "truncate":
        path.write_bytes(data[: len(data) // 2])
    else:
        i = len(data) // 2
        path.write_bytes(data[:i] + bytes([data[i] ^ 0xFF]) + data[i + 1 :])
