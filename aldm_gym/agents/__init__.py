"""Agents: controllers that act on ``ALDMHighway-v0`` observations (SB3-style ``predict``).

Modules, one job each:

* :mod:`~aldm_gym.agents.policies`: IDLE and the rule-based lane-change policy.
* :mod:`~aldm_gym.agents.lka`: the lane-keeping controller as an agent.
* :mod:`~aldm_gym.agents.episodes`: the one episode loop and its metrics.
* :mod:`~aldm_gym.agents.closed_loop`: the closed-loop naive-vs-ALDM comparison.
* :mod:`~aldm_gym.agents.figures`: figures (validation history, lateral offsets).

Training PPO policies, and evaluating them against these controllers, is
:mod:`aldm_gym.training`.
"""

from __future__ import annotations

from aldm_gym.agents.lka import LKAController

__all__ = ["LKAController"]
