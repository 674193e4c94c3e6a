"""The files of a training's output folder: names, checkpoints, atomic saves, loading.

Output folder of a training (``aldm-gym train --out <out>``)::

    <out>/training.json        env config, detector, hyperparameters, target steps
    <out>/model.zip            final model (SB3 PPO)
    <out>/vecnormalize.pkl     final observation normalisation
    <out>/checkpoints/model_<steps>_steps.zip, vecnormalize_<steps>_steps.pkl
    <out>/best_model.zip       the model of the best validation so far, with
    <out>/best_vecnormalize.pkl  its normalisation and
    <out>/validation.json      every validation's metrics, the best one's steps, and
                               IDLE's and the rule-based LCA's on the same seeds
    <out>/validation.png       the same as a figure
    <out>/tb/PPO_1/            tensorboard events

Every write goes to a temporary file first and is renamed into place, so an
interruption (Ctrl-C, SIGTERM) never leaves a truncated model. stable-baselines3 is
imported only by :func:`load_policy`.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

TRAINING_FILE = "training.json"
"""Metadata written next to the model: env config, detector, hyperparameters."""

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


def checkpoint_paths(out: Path, steps: int) -> tuple[Path, Path]:
    """``(model.zip, vecnormalize.pkl)`` paths of the checkpoint at ``steps`` [policy steps]."""
    folder = Path(out) / CHECKPOINT_DIR
    return folder / f"model_{steps}_steps.zip", folder / f"vecnormalize_{steps}_steps.pkl"


def latest_checkpoint(out: Path) -> tuple[Path, Path, int] | None:
    """``(model.zip, vecnormalize.pkl, steps)`` of the newest complete checkpoint in
    ``<out>/checkpoints``, or None."""
    found = []
    for path in (Path(out) / CHECKPOINT_DIR).glob("model_*_steps.zip"):
        match = _CHECKPOINT_RE.search(path.name)
        vecnorm = path.with_name(f"vecnormalize_{match.group(1)}_steps.pkl") if match else None
        if match and vecnorm is not None and vecnorm.exists():
            found.append((int(match.group(1)), path, vecnorm))
    if not found:
        return None
    steps, model, vecnorm = max(found)
    return model, vecnorm, steps


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
    save_atomic(lambda p: Path(p).write_text(json.dumps(record, indent=2) + "\n"), path)


def save_atomic(save: Callable[[Path], Any], path: Path) -> None:
    """``save(tmp)`` then rename: an interruption never leaves a truncated file."""
    tmp = path.with_name(path.stem + ".tmp" + path.suffix)
    save(tmp)
    tmp.replace(path)


def save_model(model: Any, model_path: Path, vecnorm_path: Path) -> None:
    """Save an SB3 model and, if it has one, its ``VecNormalize`` statistics."""
    save_atomic(model.save, model_path)
    vecnorm = model.get_vec_normalize_env()
    if vecnorm is not None:
        save_atomic(vecnorm.save, vecnorm_path)


def save_checkpoint(model: Any, out: Path, steps: int) -> Path:
    """Write ``<out>/checkpoints/model_<steps>_steps.zip`` and its VecNormalize stats.

    The model is saved with ``num_timesteps = steps`` (so an interrupted rollout, whose
    samples never reached an update, is collected again on resume).
    """
    model_path, vecnorm_path = checkpoint_paths(out, steps)
    model_path.parent.mkdir(parents=True, exist_ok=True)
    current = model.num_timesteps
    model.num_timesteps = steps
    try:
        save_model(model, model_path, vecnorm_path)
    finally:
        model.num_timesteps = current
    return model_path


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


def load_policy(model_path: Path) -> tuple[NormalizedModel, dict[str, Any]]:
    """Load a model ``.zip`` (final, best or checkpoint) and its ``training.json``.

    :return: the policy (with its observation normalisation) and the training metadata.
    :raises FileNotFoundError: no model, or no ``training.json`` next to it or in its
        parent folder.
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    """
    import pickle

    from aldm_gym.agents.sb3 import import_sb3

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
    meta = json.loads(meta_path.read_text())
    model = PPO.load(model_path, device="cpu")
    vecnorm = None
    vecnorm_path = vecnormalize_for(model_path)
    if vecnorm_path is not None:
        with open(vecnorm_path, "rb") as fh:
            vecnorm = pickle.load(fh)  # VecNormalize without its venv: stats only
        vecnorm.training = False
    return NormalizedModel(model, vecnorm), meta
