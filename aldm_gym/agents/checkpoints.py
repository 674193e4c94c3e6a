"""The files of a training's output folder: names, the lock, checkpoints, loading.

Output folder of a training (``aldm-gym train --out <out>``)::

    <out>/training.json        env config, detector, hyperparameters, run settings
    <out>/train.lock           held (``flock``) by the training writing the folder
    <out>/model.zip            final model (SB3 PPO)
    <out>/vecnormalize.pkl     final observation normalisation
    <out>/checkpoints/model_<steps>_steps.zip, vecnormalize_<steps>_steps.pkl,
                      resume_<steps>_steps.pkl   (envs, last observation, RNG states)
                      checkpoint_<steps>_steps.json (sha256 of the three: the
                                                 checkpoint is complete and intact)
    <out>/best_model.zip       the model of the best validation so far, with
    <out>/best_vecnormalize.pkl  its normalisation and
    <out>/validation.json      every validation's metrics, the best one's steps, and
                               IDLE's and the rule-based LCA's on the same seeds
    <out>/validation.png       the same as a figure
    <out>/tb/PPO_1/            tensorboard events

Why it survives faults (see ``docs/reliability.md``):

* one writer: :func:`output_lock` holds an ``flock`` on ``train.lock`` for the whole
  training; a second one is refused naming the holder's pid, and the lock of a killed
  training is released by the kernel and taken over with a warning;
* every file is written under a unique temporary name in its folder and renamed into
  place (:func:`save_atomic`), so a kill never leaves a truncated file and two writers
  never share a temporary file;
* a checkpoint is a :class:`Snapshot` taken between rollouts (the model, its
  normalisation and the resume state of one instant) and its manifest is written
  last: :func:`newest_intact_checkpoint` skips, with a warning naming the file, a
  checkpoint whose manifest is missing or whose files do not match it.

stable-baselines3 is imported only by :func:`load_policy`.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import pickle
import re
import shutil
import tempfile
import warnings
import zipfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aldm_gym.errors import OutputLocked, TrainingWarning

TRAINING_FILE = "training.json"
"""Metadata written next to the model: env config, detector, hyperparameters."""

LOCK_FILE = "train.lock"
"""The lock of the training writing the folder (holds its pid while it runs)."""

MODEL_FILE = "model.zip"
"""The final model."""

VECNORM_FILE = "vecnormalize.pkl"
"""The final model's observation normalisation (``VecNormalize`` statistics)."""

CHECKPOINT_DIR = "checkpoints"
"""Sub-folder of the periodic checkpoints."""

BEST_MODEL_FILE = "best_model.zip"
"""The model of the best validation so far."""

BEST_VECNORM_FILE = "best_vecnormalize.pkl"
"""The normalisation of :data:`BEST_MODEL_FILE`."""

VALIDATION_FILE = "validation.json"
"""Every validation's metrics, the best one's steps and the baselines' metrics."""

VALIDATION_PLOT = "validation.png"
""":data:`VALIDATION_FILE` as a figure."""

TENSORBOARD_DIR = "tb"
"""Sub-folder of the tensorboard events."""

_CHECKPOINT_RE = re.compile(r"model_(\d+)_steps\.zip$")
_TEMP_MARK = ".tmp"


def checkpoint_paths(out: Path, steps: int) -> tuple[Path, Path]:
    """``(model.zip, vecnormalize.pkl)`` paths of the checkpoint at ``steps`` [policy steps]."""
    folder = Path(out) / CHECKPOINT_DIR
    return folder / f"model_{steps}_steps.zip", folder / f"vecnormalize_{steps}_steps.pkl"


def resume_state_path(out: Path, steps: int) -> Path:
    """Path of the resume state (envs, last observation, RNG states) of a checkpoint."""
    return Path(out) / CHECKPOINT_DIR / f"resume_{steps}_steps.pkl"


def manifest_path(out: Path, steps: int) -> Path:
    """Path of a checkpoint's manifest (sha256 of its files, written last)."""
    return Path(out) / CHECKPOINT_DIR / f"checkpoint_{steps}_steps.json"


def _checkpoint_steps(out: Path) -> list[int]:
    """Steps of every ``model_<steps>_steps.zip`` in ``<out>/checkpoints``, newest first."""
    steps = []
    for path in (Path(out) / CHECKPOINT_DIR).glob("model_*_steps.zip"):
        match = _CHECKPOINT_RE.fullmatch(path.name)
        if match:
            steps.append(int(match.group(1)))
    return sorted(steps, reverse=True)


def latest_checkpoint(out: Path) -> tuple[Path, Path, int] | None:
    """``(model.zip, vecnormalize.pkl, steps)`` of the newest checkpoint in
    ``<out>/checkpoints`` with both files, or None (files are not read: see
    :func:`newest_intact_checkpoint`)."""
    for steps in _checkpoint_steps(out):
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
        or latest_checkpoint(out) is not None
    )


def can_resume(out: Path) -> bool:
    """``out`` holds a training that can be resumed: its metadata and a checkpoint."""
    return (Path(out) / TRAINING_FILE).exists() and latest_checkpoint(out) is not None


def read_training(out: Path) -> dict[str, Any]:
    """The ``training.json`` of ``out``."""
    return json.loads((Path(out) / TRAINING_FILE).read_text())


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


def save_model(model: Any, model_path: Path, vecnorm_path: Path) -> None:
    """Save an SB3 model and, if it has one, its ``VecNormalize`` statistics."""
    save_atomic(model.save, model_path)
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        save_atomic(vecnorm.save, vecnorm_path)


@contextmanager
def output_lock(out: Path, quiet: bool = False) -> Iterator[None]:
    """Hold ``<out>/train.lock`` (``flock``, exclusive) while the block runs.

    The file holds the holder's pid. The kernel releases an ``flock`` when its process
    dies, so a lock left by a killed training is taken over (a :class:`TrainingWarning`
    names its pid); a clean exit empties the file.

    :param quiet: do not warn about, nor clear, a stale lock (a check only).
    :raises OutputLocked: another live process holds the lock (the message names its pid).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_FILE
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_pid(fd)
            raise OutputLocked(
                f"{out} is being written by another training (pid {holder or 'unknown'}, "
                f"lock {path}); wait for it to end or choose another --out"
            ) from None
        if quiet:
            fcntl.flock(fd, fcntl.LOCK_UN)
            yield
            return
        previous = _read_pid(fd)
        if previous is not None and previous != os.getpid():
            warnings.warn(
                f"{path}: took over the lock of pid {previous}, which ended without "
                "releasing it (killed?)",
                TrainingWarning,
                stacklevel=3,
            )
        _write_pid(fd, os.getpid())
        try:
            yield
        finally:
            _write_pid(fd, None)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def check_unlocked(out: Path) -> None:
    """Raise :class:`OutputLocked` if a live training holds the lock of ``out``.

    A check before starting (the message then names the writer rather than the files
    it has written); :func:`output_lock` is what excludes a second writer.
    """
    path = Path(out) / LOCK_FILE
    if not path.exists():
        return
    with output_lock(out, quiet=True):
        pass


def _read_pid(fd: int) -> int | None:
    """The pid written in a lock file, or None (empty or unreadable)."""
    text = os.pread(fd, 64, 0).decode(errors="replace").strip()
    return int(text) if text.isdigit() else None


def _write_pid(fd: int, pid: int | None) -> None:
    """Replace the lock file's content by ``pid`` (None: empty it)."""
    os.ftruncate(fd, 0)
    if pid is not None:
        os.pwrite(fd, f"{pid}\n".encode(), 0)
    os.fsync(fd)


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
    :ivar resume_state: None for checkpoints written before resume states existed.
    """

    steps: int
    model: Path
    vecnormalize: Path
    resume_state: Path | None


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
    caught); without one (written by an older version), the zip's CRCs and the
    pickle are checked.
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
        # Written by this version: the manifest is written last, so the checkpoint is
        # incomplete (killed while writing it).
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


def newest_intact_checkpoint(out: Path) -> Checkpoint | None:
    """The newest checkpoint of ``out`` whose files are intact, or None.

    Each newer checkpoint skipped (incomplete, truncated, corrupt) is reported with a
    :class:`TrainingWarning` naming the file.
    """
    for steps in _checkpoint_steps(out):
        fault = checkpoint_fault(out, steps)
        if fault is not None:
            warnings.warn(f"skipping checkpoint {steps}: {fault}", TrainingWarning, stacklevel=2)
            continue
        model, vecnorm = checkpoint_paths(out, steps)
        state = resume_state_path(out, steps)
        return Checkpoint(steps, model, vecnorm, state if state.exists() else None)
    return None


def find_training_file(model_path: Path) -> Path | None:
    """The ``training.json`` of a model: next to it, or one folder up (checkpoints)."""
    model_path = Path(model_path)
    for folder in (model_path.parent, model_path.parent.parent):
        if (folder / TRAINING_FILE).exists():
            return folder / TRAINING_FILE
    return None


def vecnormalize_for(model_path: Path) -> Path | None:
    """The normalisation file saved with a model (final, best or checkpoint), or None."""
    model_path = Path(model_path)
    match = _CHECKPOINT_RE.search(model_path.name)
    if match:
        path = model_path.with_name(f"vecnormalize_{match.group(1)}_steps.pkl")
    elif model_path.name == BEST_MODEL_FILE:
        path = model_path.with_name(BEST_VECNORM_FILE)
    else:
        path = model_path.with_name(VECNORM_FILE)
    return path if path.exists() else None


class NormalizedModel:
    """A trained model with its frozen observation normalisation, SB3 ``predict``.

    :ivar model: the SB3 model.
    :ivar vecnormalize: its ``VecNormalize`` (statistics only), or None.
    """

    def __init__(self, model: Any, vecnormalize: Any = None) -> None:
        self.model = model
        self.vecnormalize = vecnormalize

    @property
    def num_timesteps(self) -> int:
        """Policy steps the model was trained for."""
        return int(self.model.num_timesteps)

    def predict(
        self,
        observation: dict[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """``(action, state)``; observations normalised as in training."""
        if self.vecnormalize is not None:
            observation = self.vecnormalize.normalize_obs(observation)
        return self.model.predict(
            observation, state=state, episode_start=episode_start, deterministic=deterministic
        )


def load_policy(model_path: Path) -> tuple[Any, dict[str, Any]]:
    """Load a model ``.zip`` (final, best or checkpoint) and its ``training.json``.

    A folder is read as an RLlib checkpoint
    (:func:`~aldm_gym.agents.rllib.load_rllib_policy`).

    :return: the policy (with its observation normalisation) and the training metadata.
    :raises FileNotFoundError: no model, or no ``training.json`` next to it or in its
        parent folder.
    :raises ValueError: the model, its normalisation or its ``training.json`` is corrupt
        (naming the file).
    :raises MissingRLDependencies: stable-baselines3 / torch missing (Ray RLlib for a
        folder).
    """
    import pickle

    from aldm_gym.agents.sb3 import import_sb3

    if Path(model_path).is_dir():
        from aldm_gym.agents.rllib import load_rllib_policy

        return load_rllib_policy(model_path)  # type: ignore[return-value]
    import_sb3()

    from stable_baselines3 import PPO

    model_path = Path(model_path)
    if not model_path.is_file():
        raise FileNotFoundError(f"no model file {model_path}")
    meta_path = find_training_file(model_path)
    if meta_path is None:
        raise FileNotFoundError(
            f"no {TRAINING_FILE} next to {model_path} (written by aldm-gym train)"
        )
    try:
        meta = json.loads(meta_path.read_text())
        if not isinstance(meta.get("env_config"), dict):
            raise ValueError("no env_config")
    except (ValueError, AttributeError) as exc:  # AttributeError: JSON but not an object
        raise ValueError(f"{meta_path}: not a training record ({exc})") from exc
    try:
        model = PPO.load(model_path, device="cpu")
    except Exception as exc:  # a corrupt zip fails in zipfile, pickle or torch
        raise ValueError(
            f"{model_path}: not a readable model ({type(exc).__name__}: {exc})"
        ) from exc
    vecnorm = None
    vecnorm_path = vecnormalize_for(model_path)
    if vecnorm_path is not None:
        try:
            with open(vecnorm_path, "rb") as fh:
                vecnorm = pickle.load(fh)  # VecNormalize without its venv: stats only
        except Exception as exc:  # unpickling corrupt bytes raises nearly anything
            raise ValueError(
                f"{vecnorm_path}: not a readable normalisation ({type(exc).__name__}: {exc})"
            ) from exc
        vecnorm.training = False
    return NormalizedModel(model, vecnorm), meta
