"""RLlib checkpoint folders: written whole, found by their step count.

A checkpoint folder (``<out>/checkpoints/rllib_<steps>/`` every ``checkpoint_freq``
steps, ``<out>/rllib_model/`` at the end) is written under a temporary name, flushed
to disk and renamed into place once complete (it then holds :data:`STEPS_FILE`), so a
kill never leaves a half-written one that ``--resume`` would take.

Observation statistics: each env runner normalises with its own running mean/std
(RLlib 2.60 does not merge ``MeanStdFilter`` states across remote runners, and leaves
the local runner's, which a checkpoint stores, empty); before every save the first
remote runner's statistics are copied into the local runner
(:func:`pull_runner_statistics`), and a resume gives the restored statistics to every
runner (:func:`push_runner_statistics`).
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

from aldm_gym.training.backend import CheckpointRef
from aldm_gym.training.outputs import RLLIB_CHECKPOINT, numbered_checkpoints, temporary_folder

STEPS_FILE = "aldm_gym.json"
"""Written into a checkpoint folder last: its step count; marks it complete."""

RLLIB_MARKER = "rllib_checkpoint.json"
"""The file RLlib writes into every checkpoint folder."""

ENV_TO_MODULE = "env_to_module_connector"
"""The env runner's component holding the observation statistics."""


def is_checkpoint(path: Path) -> bool:
    """``path`` is a complete RLlib checkpoint folder written by a training."""
    path = Path(path)
    return (path / RLLIB_MARKER).is_file() and (path / STEPS_FILE).is_file()


def checkpoint_steps(path: Path) -> int:
    """The step count of a checkpoint folder [env steps]."""
    return int(json.loads((Path(path) / STEPS_FILE).read_text())["steps"])


def checkpoints(out: Path) -> list[CheckpointRef]:
    """The complete ``<out>/checkpoints/rllib_<steps>`` folders, newest first."""
    return [
        CheckpointRef(steps, path)
        for steps, path in numbered_checkpoints(out, RLLIB_CHECKPOINT)
        if is_checkpoint(path)
    ]


def newest_checkpoint(out: Path) -> Path | None:
    """The complete ``<out>/checkpoints/rllib_<steps>`` with the most steps, or None."""
    found = checkpoints(out)
    return found[0].path if found else None


def save_checkpoint(algo: Any, path: Path, steps: int) -> Path:
    """Save ``algo`` as the checkpoint folder ``path`` (written aside, then renamed in;
    an older folder of that name is replaced)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    pull_runner_statistics(algo)
    tmp = temporary_folder(path)
    algo.save_to_path(str(tmp))
    (tmp / STEPS_FILE).write_text(json.dumps({"steps": int(steps)}) + "\n")
    fsync_tree(tmp)
    # Replacing a folder (only rllib_model) leaves a moment without it; the checkpoint
    # folder saved just before holds the same state.
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.tmp-old-{os.getpid()}")
        path.rename(old)
    tmp.rename(path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return path


def fsync_tree(folder: Path) -> None:
    """Flush every file of ``folder`` and the folders themselves to disk."""
    for root, _, files in os.walk(folder):
        for name in files:
            fd = os.open(os.path.join(root, name), os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        fd = os.open(root, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _connector_state(runner: Any) -> Any:
    """An env runner's env-to-module connector state (the observation statistics)."""
    return runner.get_state(components=[ENV_TO_MODULE])


def pull_runner_statistics(algo: Any) -> None:
    """Copy the first remote env runner's observation statistics into the local env
    runner, whose state is what a checkpoint stores.

    With remote env runners, RLlib 2.60 neither merges their ``MeanStdFilter``
    statistics nor updates the local runner's (measured: each runner keeps its own,
    the local one stays empty), so without this a checkpoint would normalise with empty
    statistics. Each runner normalises with its own running statistics while training.
    """
    group = algo.env_runner_group
    if group.num_healthy_remote_workers() == 0:
        return  # the local runner samples itself: its statistics are the training's
    states = group.foreach_env_runner(
        _connector_state, local_env_runner=False, remote_worker_ids=[group.healthy_worker_ids()[0]]
    )
    if states:
        algo.env_runner.set_state(states[0])


def push_runner_statistics(algo: Any) -> None:
    """Give every remote env runner the (restored) local runner's statistics."""
    group = algo.env_runner_group
    if group.num_healthy_remote_workers() == 0:
        return
    state = _connector_state(algo.env_runner)
    group.foreach_env_runner(lambda runner: runner.set_state(state), local_env_runner=False)
