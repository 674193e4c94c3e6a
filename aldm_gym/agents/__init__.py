"""Agents: controllers that act on ``ALDMHighway-v0`` observations (SB3-style ``predict``)."""

from __future__ import annotations

from aldm_gym.agents.lka import LKAController

__all__ = ["LKAController"]
