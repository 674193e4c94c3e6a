"""The env-to-module connectors of an RLlib training: flatten, then normalise.

Its own module so that both the plain path (:mod:`aldm_gym.training.rllib.config`)
and the masked path (:mod:`aldm_gym.training.rllib.masking`) build on it without
importing each other.
"""

from __future__ import annotations

from typing import Any


def flatten_and_normalise(env: Any = None, spaces: Any = None, device: Any = None) -> list[Any]:
    """The env-to-module connectors: flatten the Dict observation, then normalise it.

    RLlib calls it (with the env, the spaces and the device) in every env runner; it is
    module-level so Ray can ship it by reference.
    """
    from ray.rllib.connectors.env_to_module import FlattenObservations, MeanStdFilter

    return [FlattenObservations(), MeanStdFilter(clip_by_value=10.0)]
