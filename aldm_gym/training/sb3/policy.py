"""A saved SB3 model as a policy: :class:`NormalizedModel`, :func:`load_policy`."""

from __future__ import annotations

import pickle
from pathlib import Path
from typing import Any

from aldm_gym.errors import CheckpointError, InputError
from aldm_gym.training.record import TrainingRecord, model_record
from aldm_gym.training.sb3 import model_class
from aldm_gym.training.sb3.checkpoints import vecnormalize_for


class NormalizedModel:
    """A trained model with its frozen observation normalisation, SB3 ``predict``.

    A MaskablePPO model takes the env's action mask (``info["action_mask"]``) in
    ``predict(..., action_masks=...)``; :attr:`uses_action_masks` tells
    :func:`~aldm_gym.agents.episodes.run_episode` to pass it.

    :ivar model: the SB3 model.
    :ivar vecnormalize: its ``VecNormalize`` (statistics only), or None.
    """

    def __init__(self, model: Any, vecnormalize: Any = None) -> None:
        self.model = model
        self.vecnormalize = vecnormalize

    @property
    def uses_action_masks(self) -> bool:
        """The model acts on the env's action mask (MaskablePPO)."""
        return type(self.model).__name__ == "MaskablePPO"

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
        action_masks: Any = None,
    ) -> tuple[Any, Any]:
        """``(action, state)``; observations normalised as in training.

        :param action_masks: the env's action mask (``(5,)`` bool), for a MaskablePPO
            model (None: every action allowed); refused by a PPO model.
        :raises InputError: a mask given to a model that does not use one.
        """
        if self.vecnormalize is not None:
            observation = self.vecnormalize.normalize_obs(observation)
        kwargs: dict[str, Any] = {}
        if action_masks is not None:
            if not self.uses_action_masks:
                raise InputError(
                    f"{type(self.model).__name__} takes no action_masks (MaskablePPO does)"
                )
            kwargs["action_masks"] = action_masks
        return self.model.predict(
            observation,
            state=state,
            episode_start=episode_start,
            deterministic=deterministic,
            **kwargs,
        )


def load_policy(model_path: Path) -> tuple[NormalizedModel, TrainingRecord]:
    """Load a model ``.zip`` (final, best or checkpoint) and its ``training.json``.

    :return: the policy (with its observation normalisation) and the training's record.
    :raises FileNotFoundError: no model, or no ``training.json`` next to it or in its
        parent folder.
    :raises CheckpointError: the model, its normalisation or its ``training.json`` is
        corrupt (naming the file).
    :raises MissingRLDependencies: stable-baselines3 / torch missing (or sb3-contrib
        for a MaskablePPO model).
    """
    model_path = Path(model_path)
    if not model_path.is_file():
        raise FileNotFoundError(f"no model file {model_path}")
    record = model_record(model_path)
    cls = model_class(record.algorithm)
    try:
        model = cls.load(model_path, device="cpu")
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
    return NormalizedModel(model, vecnorm), record
