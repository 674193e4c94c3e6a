"""Action masks on the RLlib backend (``--algo maskable-ppo --backend rllib``).

RLlib masks actions in the RLModule: its ``ActionMaskingTorchRLModule`` (shipped with
RLlib, ``ray.rllib.examples.rl_modules.classes.action_masking_rlm``; the backend's Ray
pin keeps its interface fixed; :class:`MaskedPPOModule` here) takes a Dict observation
``{"action_mask", "observations"}``, builds its networks on ``"observations"`` and
adds ``log(mask)`` (clamped) to the action logits in every forward pass, for sampling,
inference and the PPO loss alike.

The env stays the registered ``ALDMHighway-v0``; the mask reaches the module through
the env-to-module pipeline (:func:`masked_connectors`): the Dict observation is
flattened and normalised as on the unmasked path (RLlib's ``FlattenObservations`` and
``MeanStdFilter``), then :class:`AddActionMask` puts it beside the step's
``info["action_mask"]`` (the env's
:meth:`~aldm_gym.envs.highway.ALDMHighwayEnv.action_masks`). The mask is added after the
filter, so it is never normalised, and the pipeline is part of every checkpoint, so
:class:`~aldm_gym.training.rllib.policy.RLlibPolicy` replays it outside Ray from an
observation and its info.
"""

from __future__ import annotations

import logging
from typing import Any

import gymnasium as gym
import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.training.rllib import import_rllib
from aldm_gym.training.rllib.connectors import flatten_and_normalise

import_rllib()


class _ExampleModuleWarnings(logging.Filter):
    """Drops the two deprecation warnings RLlib's own action-masking module logs when it
    is imported and built (it subclasses a renamed PPO module and passes the old
    ``config`` to it); RLlib's other deprecation warnings pass."""

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        return not ("PPOTorchRLModule" in message or "RLModule(config=" in message)


logging.getLogger("ray._common.deprecation").addFilter(_ExampleModuleWarnings())

from ray.rllib.connectors.env_to_module.observation_preprocessor import (  # noqa: E402
    SingleAgentObservationPreprocessor,
)
from ray.rllib.examples.rl_modules.classes.action_masking_rlm import (  # noqa: E402
    ActionMaskingTorchRLModule,
)

MASK_KEY = "action_mask"
"""The mask's key, in the env's info and in the module's observation."""

OBS_KEY = "observations"
"""The flattened, normalised env observation's key in the module's observation."""


def masked_space(observation_space: gym.Space, n_actions: int) -> gym.spaces.Dict:
    """The module's observation space: ``observation_space`` beside a ``(n_actions,)``
    0/1 mask (a float Box: the module takes the mask's logarithm)."""
    return gym.spaces.Dict(
        {
            MASK_KEY: gym.spaces.Box(0.0, 1.0, (n_actions,), np.float32),
            OBS_KEY: observation_space,
        }
    )


class AddActionMask(SingleAgentObservationPreprocessor):
    """The env-to-module piece that puts the step's ``info["action_mask"]`` beside the
    (already flattened and normalised) observation, as RLlib's action-masking module
    reads it."""

    def recompute_output_observation_space(
        self, input_observation_space: gym.Space, input_action_space: gym.Space
    ) -> gym.Space:
        """The input space beside the mask (see :func:`masked_space`)."""
        if not isinstance(input_action_space, gym.spaces.Discrete):
            raise InputError(
                f"action masks need discrete actions (action.type 'DiscreteMetaAction'), "
                f"not {input_action_space}"
            )
        return masked_space(input_observation_space, int(input_action_space.n))

    def preprocess(self, observation: Any, episode: Any) -> dict[str, Any]:
        """``{"action_mask": info["action_mask"], "observations": observation}`` of the
        episode's last step.

        :raises InputError: the step's info has no ``action_mask``.
        """
        info = episode.get_infos(-1)
        if MASK_KEY not in info:
            raise InputError(f"the env's info has no {MASK_KEY!r} (keys: {sorted(info)})")
        return {MASK_KEY: np.asarray(info[MASK_KEY], dtype=np.float32), OBS_KEY: observation}


def masked_connectors(env: Any = None, spaces: Any = None, device: Any = None) -> list[Any]:
    """The env-to-module connectors of the masked path: flatten, normalise (as
    :func:`~aldm_gym.training.rllib.connectors.flatten_and_normalise`), then
    :class:`AddActionMask`."""
    return [*flatten_and_normalise(env, spaces, device), AddActionMask()]


class MaskedPPOModule(ActionMaskingTorchRLModule):
    """RLlib's action-masking PPO module, unchanged; defined here so that a process that
    builds it from a spec or a checkpoint imports this module (and its warning filter)
    first."""


def masking_module_spec(model_config: dict[str, Any]) -> Any:
    """The ``RLModuleSpec`` of the action-masking PPO module."""
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    return RLModuleSpec(module_class=MaskedPPOModule, model_config=dict(model_config))
