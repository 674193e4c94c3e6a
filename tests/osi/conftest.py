"""Shared OSI fixtures: traces written by the env, and the frames it measured."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.roads import shipped_map

pytest.importorskip("osi3")
pytest.importorskip("osi_utilities")


def record(path: Path, config: dict[str, Any], steps: int = 3, seed: int = 3) -> tuple[Any, list]:
    """Run the env with an OSI trace at every frame; the env and every frame it measured
    (in the trace's order)."""
    env = gym.make(
        "ALDMHighway-v0", config={**config, "osi": {"trace": str(path), "every": "frame"}}
    )
    frames: list = []
    inner = env.unwrapped
    perceive = inner._perceive

    def keep() -> None:
        perceive()
        frames.append(inner.frame)

    inner._perceive = keep
    env.reset(seed=seed)
    del frames[:-1]  # the reset's frame opens the trace
    for _ in range(steps):
        env.step(1)
    env.close()
    return inner, frames


ROADS = {
    "generated": {},
    "generated_editor_curvy": {"marking_model": "editor", "road": {"min_radius": 250.0}},
    "motorway": {"road": {"xodr": str(shipped_map("motorway"))}},
    "features": {"road": {"xodr": str(shipped_map("features"))}},
}
"""Roads of the round trip: generated (both marking models, tight curves), a map, and
a map with lane sections, type changes, botts dots and double lines."""


@pytest.fixture(scope="session")
def env_trace(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any, list]:
    """A 31-frame MCAP trace of the default env: (path, env, frames)."""
    path = tmp_path_factory.mktemp("osi") / "run.mcap"
    env, frames = record(path, {})
    return path, env, frames
