"""Agents: controllers that act on ``ALDMHighway-v0`` observations (SB3-style ``predict``).

Modules, one job each:

* :mod:`~aldm_gym.agents.policies`: IDLE and the rule-based lane-change policy.
* :mod:`~aldm_gym.agents.lka`: the lane-keeping controller as an agent.
* :mod:`~aldm_gym.agents.evaluation`: the one episode loop and its metrics.
* :mod:`~aldm_gym.agents.comparison`: the closed-loop naive-vs-ALDM comparison.
* :mod:`~aldm_gym.agents.training`: PPO training (:func:`~aldm_gym.agents.training.train`).
* :mod:`~aldm_gym.agents.callbacks`: the training's stable-baselines3 callbacks.
* :mod:`~aldm_gym.agents.checkpoints`: a training's output folder, saving and loading.
* :mod:`~aldm_gym.agents.model_evaluation`: a trained model against the rule-based ones.
* :mod:`~aldm_gym.agents.plot`: figures (validation history, lateral offsets).
* :mod:`~aldm_gym.agents.sb3`: the optional stable-baselines3 dependency.
"""

from __future__ import annotations

from aldm_gym.agents.lka import LKAController

__all__ = ["LKAController"]
