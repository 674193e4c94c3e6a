"""RLlib's ``PPOConfig`` of a training: the SB3 backend's PPO, mapped onto RLlib.

The same ``ALDMHighway-v0`` config (:func:`~aldm_gym.training.settings.env_config`),
reward and :class:`~aldm_gym.training.settings.PPOParams` as on the SB3 path, on
RLlib's current API stack (RLModule, Learner, EnvRunner, ConnectorV2):

* the env is the registered id ``"aldm_gym:ALDMHighway-v0"``: gymnasium imports
  ``aldm_gym`` in every env runner process, on every node, before making it;
* the Dict observation goes through RLlib's ``FlattenObservations`` connector, then
  ``MeanStdFilter`` (running mean/std, clipped at ±10: what ``VecNormalize`` does on
  the SB3 path); both are part of every checkpoint;
* PPO as SB3 runs it: no KL penalty (SB3 has none), value loss weight 0.5, gradient
  norm clipped at 0.5, no value clipping, separate 128×128 tanh networks for policy
  and value; the rollout of one update is ``n_steps`` per env runner (SB3: per env);
  a ``"linear"`` learning rate decays to 0 over the budget as RLlib's piecewise
  schedule over sampled env steps;
* with ``masked`` (MaskablePPO), the pipeline adds the step's ``info["action_mask"]``
  after the filter and RLlib's action-masking module applies it
  (:mod:`aldm_gym.training.rllib.masking`).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from typing import Any

from aldm_gym import ENV_ID
from aldm_gym.envs.config import env_overrides
from aldm_gym.training.rllib import import_rllib
from aldm_gym.training.rllib.connectors import flatten_and_normalise
from aldm_gym.training.settings import DEFAULT_ENV_RUNNERS, PPOParams

RLLIB_ENV_ID = f"aldm_gym:{ENV_ID}"
"""The env as RLlib's workers make it: gymnasium imports ``aldm_gym`` first."""

__all__ = ["RLLIB_ENV_ID", "flatten_and_normalise", "ppo_config"]


def ppo_config(
    config: Mapping[str, Any],
    params: PPOParams,
    *,
    timesteps: int,
    num_env_runners: int = DEFAULT_ENV_RUNNERS,
    seed: int = 0,
    masked: bool = False,
) -> Any:
    """RLlib's ``PPOConfig`` of a training (see the module docstring for the mapping).

    :param config: the ``ALDMHighway-v0`` config.
    :param timesteps: the budget [env steps] (the end of a linear learning rate).
    :param num_env_runners: remote env runners (0: sample in the driver).
    :param seed: seed of the env runners' envs and of the networks.
    :param masked: mask the actions the env rules out (MaskablePPO).
    """
    import_rllib()
    from ray.rllib.algorithms.ppo import PPOConfig

    # RLlib warns once per process that PPO runs on its new API stack (it is chosen).
    logging.getLogger("ray.rllib.algorithms.algorithm_config").setLevel(logging.ERROR)
    rollout = params.n_steps * max(1, num_env_runners)
    lr: Any = params.learning_rate
    if params.lr_schedule == "linear":
        lr = [[0, params.learning_rate], [int(timesteps), 0.0]]
    model_config = {
        "fcnet_hiddens": list(params.net_arch),
        "fcnet_activation": "tanh",
        "vf_share_layers": False,
    }
    connectors: Any = flatten_and_normalise
    module: dict[str, Any] = {"model_config": model_config}
    if masked:
        from aldm_gym.training.rllib.masking import masked_connectors, masking_module_spec

        connectors = masked_connectors
        module = {"rl_module_spec": masking_module_spec(model_config)}
    return (
        PPOConfig()
        .environment(RLLIB_ENV_ID, env_config={"config": env_overrides(config)})
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=1,
            rollout_fragment_length="auto",
            env_to_module_connector=connectors,
        )
        .training(
            train_batch_size_per_learner=rollout,
            minibatch_size=min(params.batch_size, rollout),
            num_epochs=params.n_epochs,
            lr=lr,
            gamma=params.gamma,
            lambda_=params.gae_lambda,
            entropy_coeff=params.ent_coef,
            clip_param=params.clip_range,
            use_kl_loss=False,
            vf_loss_coeff=0.5,
            vf_clip_param=float("inf"),
            grad_clip=0.5,
        )
        .rl_module(**module)
        .debugging(seed=seed, log_level="ERROR")
        .reporting(metrics_num_episodes_for_smoothing=100)
    )
