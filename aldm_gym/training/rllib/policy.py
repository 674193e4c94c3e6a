"""An RLlib checkpoint played outside Ray: :class:`RLlibPolicy`, :func:`load_rllib_policy`.

``aldm-gym evaluate`` compares it with IDLE and the rule-based LCA exactly as it does
SB3 models.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from aldm_gym.errors import CheckpointError, InputError
from aldm_gym.training.record import TrainingRecord, model_record
from aldm_gym.training.rllib import MissingRayDependencies, import_rllib
from aldm_gym.training.rllib.checkpoints import (
    ENV_TO_MODULE,
    RLLIB_MARKER,
    STEPS_FILE,
    checkpoint_steps,
    is_checkpoint,
)


class RLlibPolicy:
    """A trained RLlib checkpoint as a policy with SB3's ``predict``, outside Ray.

    The observation goes through the checkpoint's own connector pipeline (flatten,
    then the training's running mean/std, frozen here: playing does not change the
    statistics), the RLModule gives the action logits; deterministic play takes their
    argmax (RLlib's own choice with ``explore=False``).

    A checkpoint of a masked training (``--algo maskable-ppo``) takes the env's action
    mask (``predict(..., action_masks=info["action_mask"])``, :attr:`uses_action_masks`):
    its pipeline ends in :class:`~aldm_gym.training.rllib.masking.AddActionMask`, which
    reads it from the step's info as in training.

    :param path: an RLlib checkpoint folder written by a training.
    :ivar num_timesteps: env steps trained when the checkpoint was written.
    """

    def __init__(self, path: Path) -> None:
        import_rllib()
        from ray.rllib.connectors.env_to_module.env_to_module_pipeline import (
            EnvToModulePipeline,
        )
        from ray.rllib.core.rl_module.rl_module import RLModule

        # RLModule.from_checkpoint builds the module the way RLlib itself deprecates.
        logging.getLogger("ray.rllib.core.rl_module.rl_module").setLevel(logging.ERROR)
        path = Path(path).absolute()  # RLlib reads a relative path as a URI
        self.path = path
        self.num_timesteps = checkpoint_steps(path)
        self.module = RLModule.from_checkpoint(
            path / "learner_group" / "learner" / "rl_module" / "default_policy"
        )
        self.pipeline = EnvToModulePipeline.from_checkpoint(path / "env_runner" / ENV_TO_MODULE)
        for piece in self.pipeline.connectors:
            if hasattr(piece, "_update_stats"):  # MeanStdFilter: freeze the statistics
                piece._update_stats = False
        self._rng = np.random.default_rng(0)
        from aldm_gym.training.rllib.masking import AddActionMask

        self.uses_action_masks = any(isinstance(p, AddActionMask) for p in self.pipeline.connectors)
        """The checkpoint acts on the env's action mask (a masked training's)."""

    def logits(self, observation: Mapping[str, Any], action_masks: Any = None) -> np.ndarray:
        """The action logits of one (unbatched) observation, shape ``(n_actions,)``;
        for a masked checkpoint, those the mask rules out are (about) -3.4e38.

        :param action_masks: the env's action mask, for a masked checkpoint (None:
            every action allowed).
        :raises InputError: a mask given to an unmasked checkpoint.
        """
        import torch
        from ray.rllib.env.single_agent_episode import SingleAgentEpisode

        info: dict[str, Any] = {}
        if self.uses_action_masks:
            from aldm_gym.training.rllib.masking import MASK_KEY

            n = int(self.module.action_space.n)
            mask = np.ones(n) if action_masks is None else np.asarray(action_masks, np.float64)
            if mask.shape != (n,) or not np.isin(mask, (0.0, 1.0)).all():
                raise InputError(
                    f"action_masks must be {n} booleans, one per action; got {action_masks!r}"
                )
            info[MASK_KEY] = mask
        elif action_masks is not None:
            raise InputError("this RLlib checkpoint was trained without action masks")
        episode = SingleAgentEpisode(observations=[dict(observation)], infos=[info])
        batch = self.pipeline(
            rl_module=self.module, batch={}, episodes=[episode], explore=False, shared_data={}
        )
        with torch.no_grad():
            out = self.module.forward_inference(batch)
        return out["action_dist_inputs"][0].numpy()

    def predict(
        self,
        observation: Mapping[str, Any],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
        action_masks: Any = None,
    ) -> tuple[np.ndarray, Any]:
        """``(action, state)`` for one observation, as SB3's ``predict`` (``action_masks``:
        see :meth:`logits`)."""
        logits = self.logits(observation, action_masks)
        if deterministic:
            return np.asarray(int(np.argmax(logits))), state
        p = np.exp(logits - logits.max())
        return np.asarray(int(self._rng.choice(len(p), p=p / p.sum()))), state


def load_rllib_policy(path: Path) -> tuple[RLlibPolicy, TrainingRecord]:
    """An RLlib checkpoint folder and the ``training.json`` of its output folder.

    :raises FileNotFoundError: not a checkpoint written by a training, or no
        ``training.json`` beside it.
    :raises CheckpointError: the checkpoint or the ``training.json`` does not load
        (naming it).
    :raises MissingRayDependencies: Ray RLlib / torch missing.
    """
    path = Path(path)
    if not is_checkpoint(path):
        raise FileNotFoundError(
            f"{path} is a folder but not an RLlib checkpoint of aldm-gym train "
            f"(no {RLLIB_MARKER} and {STEPS_FILE})"
        )
    record = model_record(path)
    try:
        policy = RLlibPolicy(path)
    except MissingRayDependencies:
        raise
    except Exception as exc:  # a damaged checkpoint fails in pickle, torch or RLlib
        raise CheckpointError(
            f"{path}: not a readable RLlib checkpoint ({type(exc).__name__}: {exc})"
        ) from exc
    return policy, record
