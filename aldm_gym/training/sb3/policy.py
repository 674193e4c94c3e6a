"""A saved SB3 model as a policy: :class:`NormalizedModel`, :func:`load_policy`."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

from aldm_gym.errors import CheckpointError
from aldm_gym.training.outputs import TRAINING_FILE, find_training_file, read_training_record
from aldm_gym.training.sb3 import import_sb3
from aldm_gym.training.sb3.checkpoints import vecnormalize_for


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


def load_policy(model_path: Path) -> tuple[NormalizedModel, dict[str, Any]]:
    """Load a model ``.zip`` (final, best or checkpoint) and its ``training.json``.

    :return: the policy (with its observation normalisation) and the training metadata.
    :raises FileNotFoundError: no model, or no ``training.json`` next to it or in its
        parent folder.
    :raises CheckpointError: the model, its normalisation or its ``training.json`` is
        corrupt (naming the file).
    :raises MissingRLDependencies: stable-baselines3 / torch missing.
    """
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
    meta = read_training_record(meta_path)
    try:
        model = PPO.load(model_path, device="cpu")
    except Exception as exc:  # a corrupt zip fails in zipfile, pickle or torch
        raise CheckpointError(
            f"{model_path}: not a readable model ({type(exc).__name__}: {exc})"
        ) from exc
    vecnorm = None
    vecnorm_path = vecnormalize_for(model_path)
    if vecnorm_path is not None:
        try:
            with open(vecnorm_path, "rb") as fh:
                vecnorm = pickle.load(fh)  # VecNormalize without its venv: stats only
        except Exception as exc:  # unpickling corrupt bytes raises nearly anything
            raise CheckpointError(
                f"{vecnorm_path}: not a readable normalisation ({type(exc).__name__}: {exc})"
            ) from exc
        vecnorm.training = False
    return NormalizedModel(model, vecnorm), meta
