"""Trained models of either backend: the backends by name, and a model as a policy.

:func:`load_policy` takes what ``aldm-gym evaluate --model`` takes: an SB3 model
``.zip`` (final, best or checkpoint), an RLlib checkpoint folder, or a training's
output folder, from which it takes the model
:func:`~aldm_gym.training.outputs.trained_model` picks (the best validation's, else the
final one).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from aldm_gym.training.backend import Backend
from aldm_gym.training.outputs import is_output_folder, trained_model
from aldm_gym.training.record import TrainingRecord
from aldm_gym.training.rllib.backend import RLlibBackend
from aldm_gym.training.sb3.backend import SB3Backend

logger = logging.getLogger(__name__)

BACKENDS: dict[str, type[Backend[Any]]] = {
    SB3Backend.name: SB3Backend,
    RLlibBackend.name: RLlibBackend,
}
"""The training backends by name: stable-baselines3 (one machine), Ray RLlib (a cluster)."""


def model_to_evaluate(path: Path) -> tuple[Path, str | None]:
    """The model a path names: itself, or for an output folder the one
    :func:`~aldm_gym.training.outputs.trained_model` picks; and what was picked (None
    for a model named itself).

    :raises CheckpointError: an output folder without a trained model.
    """
    path = Path(path)
    if is_output_folder(path):
        return trained_model(path)
    return path, None


def load_policy(model_path: Path) -> tuple[Any, TrainingRecord]:
    """Load a trained model as a policy with SB3's ``predict``, and its record
    (``training.json``, read once).

    :param model_path: an SB3 model ``.zip``, an RLlib checkpoint folder, or a
        training's output folder (:func:`model_to_evaluate`).
    :raises FileNotFoundError: no model, or no ``training.json`` next to it or in its
        parent folder.
    :raises CheckpointError: the model, its normalisation or its ``training.json`` is
        corrupt (naming the file), or an output folder holds no trained model.
    :raises MissingRLDependencies: stable-baselines3 / torch missing (Ray RLlib for a
        folder).
    """
    path, what = model_to_evaluate(model_path)
    if what is not None:
        logger.info("evaluating %s: %s", path, what)
    backend = RLlibBackend if path.is_dir() else SB3Backend
    return backend.load_policy(path)
