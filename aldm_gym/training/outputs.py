"""A training's output folder: its file names, ``training.json`` and atomic writes.

Output folder of a training (``aldm-gym train --out <out>``), both backends::

    <out>/training.json        backend, env config, hyperparameters, run settings
                               (SB3: "pretrain", the cloning's settings and report;
                               "keep_by", what the best model is kept by)
    <out>/train.lock           held (``flock``) by the training writing the folder
    <out>/tb/                  tensorboard events (SB3: PPO_1/ or MaskablePPO_1/, RLlib: RLlib_PPO/)

    stable-baselines3 (:mod:`aldm_gym.training.sb3`):
    <out>/model.zip            final model
    <out>/vecnormalize.pkl     final observation normalisation
    <out>/checkpoints/model_<steps>_steps.zip, vecnormalize_<steps>_steps.pkl,
                      resume_<steps>_steps.pkl   (envs, last observation, RNG states)
                      checkpoint_<steps>_steps.json (sha256 of the three: the
                                                 checkpoint is complete and intact)
    <out>/best_model.zip       the model of the best validation so far, with
    <out>/best_vecnormalize.pkl  its normalisation and
    <out>/validation.json      every validation's metrics, the best one's steps (by
                               "keep_by"), and
                               IDLE's and the rule-based LCA's on the same seeds
    <out>/validation.png       the same as a figure

    Ray RLlib (:mod:`aldm_gym.training.rllib`):
    <out>/rllib_model/                  the final RLlib checkpoint
    <out>/checkpoints/rllib_<steps>/    a checkpoint every checkpoint_freq steps

Every file is written under a unique temporary name in its folder and renamed into
place (:func:`save_atomic`), so a kill never leaves a truncated file and two writers
never share a temporary file; :func:`remove_temporary_files` clears what a kill left.
Why the rest survives faults: :mod:`aldm_gym.training.lock` (one writer),
:mod:`aldm_gym.training.backend` (signals, the fallback to an intact checkpoint).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from aldm_gym.errors import CheckpointError

TRAINING_FILE = "training.json"
"""Metadata written next to the model: backend, env config, hyperparameters."""

LOCK_FILE = "train.lock"
"""The lock of the training writing the folder (holds its pid while it runs)."""

MODEL_FILE = "model.zip"
"""The final model (SB3)."""

VECNORM_FILE = "vecnormalize.pkl"
"""The final model's observation normalisation (``VecNormalize`` statistics)."""

CHECKPOINT_DIR = "checkpoints"
"""Sub-folder of the periodic checkpoints."""

BEST_MODEL_FILE = "best_model.zip"
"""The model of the best validation so far (SB3)."""

BEST_VECNORM_FILE = "best_vecnormalize.pkl"
"""The normalisation of :data:`BEST_MODEL_FILE`."""

VALIDATION_FILE = "validation.json"
"""Every validation's metrics, the best one's steps and the baselines' metrics."""

VALIDATION_PLOT = "validation.png"
""":data:`VALIDATION_FILE` as a figure."""

TENSORBOARD_DIR = "tb"
"""Sub-folder of the tensorboard events."""

RLLIB_MODEL_DIR = "rllib_model"
"""The final RLlib checkpoint (a folder)."""

RLLIB_CHECKPOINT_PREFIX = "rllib_"
"""RLlib checkpoint folders: ``<out>/checkpoints/rllib_<steps>/``."""

SB3_CHECKPOINT = re.compile(r"model_(\d+)_steps\.zip")
"""Name of an SB3 checkpoint's model in ``<out>/checkpoints`` (group 1: its steps)."""

RLLIB_CHECKPOINT = re.compile(RLLIB_CHECKPOINT_PREFIX + r"(\d+)")
"""Name of an RLlib checkpoint folder in ``<out>/checkpoints`` (group 1: its steps)."""

TRAINED_MODELS = (
    (BEST_MODEL_FILE, "the best validation's model"),
    (MODEL_FILE, "the final model"),
    (RLLIB_MODEL_DIR, "the final RLlib checkpoint"),
)
"""What :func:`trained_model` takes from an output folder, in order of preference."""

_TEMP_MARK = ".tmp"


def checkpoint_paths(out: Path, steps: int) -> tuple[Path, Path]:
    """``(model.zip, vecnormalize.pkl)`` paths of the SB3 checkpoint at ``steps``
    [policy steps]."""
    folder = Path(out) / CHECKPOINT_DIR
    return folder / f"model_{steps}_steps.zip", folder / f"vecnormalize_{steps}_steps.pkl"


def resume_state_path(out: Path, steps: int) -> Path:
    """Path of the resume state (envs, last observation, RNG states) of a checkpoint."""
    return Path(out) / CHECKPOINT_DIR / f"resume_{steps}_steps.pkl"


def manifest_path(out: Path, steps: int) -> Path:
    """Path of a checkpoint's manifest (sha256 of its files, written last)."""
    return Path(out) / CHECKPOINT_DIR / f"checkpoint_{steps}_steps.json"


def rllib_checkpoint_path(out: Path, steps: int) -> Path:
    """The folder of the RLlib checkpoint at ``steps`` [env steps]."""
    return Path(out) / CHECKPOINT_DIR / f"{RLLIB_CHECKPOINT_PREFIX}{steps}"


def numbered_checkpoints(out: Path, pattern: re.Pattern[str]) -> list[tuple[int, Path]]:
    """``(steps, path)`` of every entry of ``<out>/checkpoints`` whose whole name matches
    ``pattern`` (group 1: the steps), newest (most steps) first."""
    found = []
    for path in (Path(out) / CHECKPOINT_DIR).glob("*"):
        match = pattern.fullmatch(path.name)
        if match:
            found.append((int(match.group(1)), path))
    return sorted(found, reverse=True)


def latest_checkpoint(out: Path) -> tuple[Path, Path, int] | None:
    """``(model.zip, vecnormalize.pkl, steps)`` of the newest SB3 checkpoint in
    ``<out>/checkpoints`` with both files, or None (files are not read: see
    :func:`~aldm_gym.training.sb3.checkpoints.newest_intact_checkpoint`)."""
    for steps, _ in numbered_checkpoints(out, SB3_CHECKPOINT):
        model, vecnorm = checkpoint_paths(out, steps)
        if vecnorm.exists():
            return model, vecnorm, steps
    return None


def holds_training(out: Path) -> bool:
    """``out`` already holds a training (metadata, a final model or a checkpoint)."""
    out = Path(out)
    return (
        (out / TRAINING_FILE).exists()
        or (out / MODEL_FILE).exists()
        or (out / RLLIB_MODEL_DIR).exists()
        or latest_checkpoint(out) is not None
        or bool(numbered_checkpoints(out, RLLIB_CHECKPOINT))
    )


def can_resume(out: Path) -> bool:
    """``out`` holds an SB3 training that can be resumed: its metadata and a checkpoint."""
    return (Path(out) / TRAINING_FILE).exists() and latest_checkpoint(out) is not None


def find_training_file(model_path: Path) -> Path | None:
    """The ``training.json`` of a model: next to it, or one folder up (checkpoints)."""
    model_path = Path(model_path)
    for folder in (model_path.parent, model_path.parent.parent):
        if (folder / TRAINING_FILE).exists():
            return folder / TRAINING_FILE
    return None


def is_output_folder(path: Path) -> bool:
    """``path`` is a training's output folder (a folder holding ``training.json``)."""
    return (Path(path) / TRAINING_FILE).is_file()


def trained_model(out: Path) -> tuple[Path, str]:
    """The model of a training's output folder to evaluate, and what it is.

    The first of :data:`TRAINED_MODELS` that exists: the best validation's model, else
    the final model (SB3's ``model.zip`` or RLlib's ``rllib_model/``).

    :raises CheckpointError: ``out`` holds none of them (naming its newest checkpoint).
    """
    out = Path(out)
    for name, what in TRAINED_MODELS:
        if (out / name).exists():
            return out / name, what
    newest = [
        path
        for pattern in (SB3_CHECKPOINT, RLLIB_CHECKPOINT)
        for _, path in numbered_checkpoints(out, pattern)[:1]
    ]
    hint = f"; evaluate one of its checkpoints instead, e.g. {newest[0]}" if newest else ""
    names = ", ".join(name for name, _ in TRAINED_MODELS)
    raise CheckpointError(f"{out} holds no trained model (none of {names}){hint}")


def write_json(path: Path, record: dict[str, Any]) -> None:
    """Write ``record`` as indented JSON (atomically)."""
    write_bytes_atomic(path, (json.dumps(record, indent=2) + "\n").encode())


def save_atomic(save: Callable[[Path], Any], path: Path) -> None:
    """``save(tmp)`` then rename onto ``path``: a kill never leaves a truncated file.

    ``tmp`` is a fresh, uniquely named file in ``path``'s folder (hidden, ending in
    ``path``'s suffix so SB3's ``save`` keeps the name), so two writers never share
    it; it is synced before the rename and removed if ``save`` fails.
    """
    path = Path(path)
    with tempfile.NamedTemporaryFile(
        dir=path.parent, prefix=f".{path.stem}.", suffix=_TEMP_MARK + path.suffix, delete=False
    ) as fh:
        tmp = Path(fh.name)
    try:
        save(tmp)
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes_atomic(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (:func:`save_atomic`)."""
    save_atomic(lambda p: Path(p).write_bytes(data), path)


def temporary_folder(path: Path) -> Path:
    """A new, uniquely named folder beside ``path`` to write ``path`` into before it is
    renamed into place (:func:`remove_temporary_files` clears one a kill left)."""
    return Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}{_TEMP_MARK}"))


def remove_temporary_files(out: Path) -> list[Path]:
    """Delete the temporary files an interrupted write left in ``out`` and its
    checkpoint folder (call it holding the lock); the paths removed."""
    removed = []
    for folder in (Path(out), Path(out) / CHECKPOINT_DIR):
        for path in folder.glob(f".*{_TEMP_MARK}*"):
            if path.is_dir():  # an RLlib checkpoint folder being written
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed.append(path)
    return removed


def fault_text(exc: BaseException) -> str:
    """An exception as ``Type: message`` for a line saying why a file cannot be used."""
    return f"{type(exc).__name__}: {exc}"
