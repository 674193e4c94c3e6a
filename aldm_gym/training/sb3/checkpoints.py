"""SB3 checkpoints: snapshots of a training between rollouts, written whole.

A checkpoint is a :class:`Snapshot` taken between rollouts (the model, its
normalisation and the resume state of one instant), written as three files and a
manifest with their sha256, written last (:func:`write_checkpoint`; the file names are
in :mod:`aldm_gym.training.outputs`). :func:`checkpoint_fault` says why one cannot be
used (incomplete, truncated, corrupt); :func:`newest_intact_checkpoint` skips such
ones with a :class:`~aldm_gym.errors.TrainingWarning` naming the file.
"""

from __future__ import annotations

import hashlib
import io
import json
import pickle
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aldm_gym.training.backend import first_intact
from aldm_gym.training.outputs import (
    BEST_MODEL_FILE,
    BEST_VECNORM_FILE,
    SB3_CHECKPOINT,
    VECNORM_FILE,
    checkpoint_paths,
    manifest_path,
    numbered_checkpoints,
    resume_state_path,
    save_atomic,
    write_bytes_atomic,
    write_json,
)
from aldm_gym.training.sb3.envs import global_rng_state, set_global_rng_state


@dataclass(frozen=True)
class Snapshot:
    """A training's state at one instant between rollouts, serialised.

    :ivar steps: policy steps done [policy steps].
    :ivar model: the SB3 model ``.zip`` (weights, optimiser, step count).
    :ivar vecnormalize: the pickled ``VecNormalize`` statistics of the same instant.
    :ivar resume_state: pickled envs, last observation and RNG states (exact resume).
    """

    steps: int
    model: bytes
    vecnormalize: bytes
    resume_state: bytes


@dataclass(frozen=True)
class Checkpoint:
    """The files of one checkpoint on disk.

    :ivar steps: policy steps done [policy steps].
    :ivar resume_state: None for a checkpoint of model and normalisation only.
    """

    steps: int
    model: Path
    vecnormalize: Path
    resume_state: Path | None

    @property
    def path(self) -> Path:
        """The checkpoint's model (the file messages name)."""
        return self.model


def take_snapshot(model: Any) -> Snapshot:
    """The training's state now (call it between rollouts): model, normalisation,
    envs, last observation and RNG states of one instant."""
    buffer = io.BytesIO()
    model.save(buffer)
    vecnorm = model.get_vec_normalize_env()
    state = {
        "n_envs": model.n_envs,
        "envs": model.get_env().env_method("resume_state"),
        "last_obs": model._last_obs,
        "last_episode_starts": model._last_episode_starts,
        "rng": global_rng_state(),
    }
    return Snapshot(
        steps=int(model.num_timesteps),
        model=buffer.getvalue(),
        vecnormalize=pickle.dumps(vecnorm) if vecnorm is not None else b"",
        resume_state=pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL),
    )


def restore_resume_state(model: Any, path: Path) -> None:
    """Put the envs, last observation and RNG states of a checkpoint back into
    ``model`` (loaded from the same checkpoint, with as many envs)."""
    with open(path, "rb") as fh:
        state = pickle.load(fh)
    venv = model.get_env()
    for i, env_state in enumerate(state["envs"]):
        venv.env_method("restore_resume_state", env_state, indices=[i])
    model._last_obs = state["last_obs"]
    model._last_episode_starts = state["last_episode_starts"]
    set_global_rng_state(state["rng"])


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def write_checkpoint(out: Path, snapshot: Snapshot) -> Path:
    """Write ``snapshot`` as the checkpoint ``<steps>``; its model's path.

    Each file is written atomically and the manifest last, so a checkpoint with a
    manifest matching its files is complete.
    """
    model_path, vecnorm_path = checkpoint_paths(out, snapshot.steps)
    state_path = resume_state_path(out, snapshot.steps)
    model_path.parent.mkdir(parents=True, exist_ok=True)
    files = {
        model_path: snapshot.model,
        vecnorm_path: snapshot.vecnormalize,
        state_path: snapshot.resume_state,
    }
    for path, data in files.items():
        write_bytes_atomic(path, data)
    manifest = {
        "steps": snapshot.steps,
        "sha256": {path.name: _sha256(data) for path, data in files.items()},
    }
    write_json(manifest_path(out, snapshot.steps), manifest)
    return model_path


def checkpoint_fault(out: Path, steps: int) -> str | None:
    """Why the checkpoint ``<steps>`` of ``out`` cannot be used, or None if intact.

    With a manifest, every file must match its sha256 (a truncated or flipped byte is
    caught); without one (a checkpoint of model and normalisation only), the zip's
    CRCs and the pickle are checked.
    """
    model_path, vecnorm_path = checkpoint_paths(out, steps)
    mpath = manifest_path(out, steps)
    if mpath.exists():
        try:
            manifest = json.loads(mpath.read_text())
            expected = dict(manifest["sha256"])
        except (ValueError, KeyError, TypeError) as exc:
            return f"{mpath}: unreadable manifest ({exc})"
        for name, digest in expected.items():
            path = mpath.parent / name
            if not path.is_file():
                return f"{path}: missing"
            if _sha256(path.read_bytes()) != digest:
                return f"{path}: contents differ from its manifest (truncated or corrupt)"
        return None
    if resume_state_path(out, steps).exists():
        # The manifest is written last: with a resume state and no manifest, the
        # checkpoint is incomplete (killed while writing it).
        return f"{mpath}: missing (checkpoint incomplete)"
    for path in (model_path, vecnorm_path):
        if not path.is_file():
            return f"{path}: missing"
    try:
        with zipfile.ZipFile(model_path) as archive:
            bad = archive.testzip()
        if bad is not None:
            return f"{model_path}: corrupt member {bad}"
    except (zipfile.BadZipFile, OSError, EOFError) as exc:
        return f"{model_path}: not a readable zip ({exc})"
    try:
        with open(vecnorm_path, "rb") as fh:
            pickle.load(fh)
    except Exception as exc:  # unpickling corrupt bytes raises nearly anything
        return f"{vecnorm_path}: not a readable pickle ({type(exc).__name__}: {exc})"
    return None


def checkpoints(out: Path) -> list[Checkpoint]:
    """Every checkpoint of ``out`` (by its model's name), newest first; not read."""
    found = []
    for steps, _ in numbered_checkpoints(out, SB3_CHECKPOINT):
        model, vecnorm = checkpoint_paths(out, steps)
        state = resume_state_path(out, steps)
        found.append(Checkpoint(steps, model, vecnorm, state if state.exists() else None))
    return found


def newest_intact_checkpoint(out: Path) -> Checkpoint | None:
    """The newest checkpoint of ``out`` whose files are intact, or None.

    Each newer checkpoint skipped (incomplete, truncated, corrupt) is reported with a
    :class:`~aldm_gym.errors.TrainingWarning` naming the file.
    """
    return first_intact(checkpoints(out), lambda found: checkpoint_fault(out, found.steps))


def vecnormalize_for(model_path: Path) -> Path | None:
    """The normalisation file saved with a model (final, best or checkpoint), or None."""
    model_path = Path(model_path)
    match = SB3_CHECKPOINT.fullmatch(model_path.name)
    if match:
        path = model_path.with_name(f"vecnormalize_{match.group(1)}_steps.pkl")
    elif model_path.name == BEST_MODEL_FILE:
        path = model_path.with_name(BEST_VECNORM_FILE)
    else:
        path = model_path.with_name(VECNORM_FILE)
    return path if path.exists() else None


def save_model(model: Any, model_path: Path, vecnorm_path: Path) -> None:
    """Save an SB3 model and, if it has one, its ``VecNormalize`` statistics."""
    save_atomic(model.save, model_path)
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        save_atomic(vecnorm.save, vecnorm_path)
