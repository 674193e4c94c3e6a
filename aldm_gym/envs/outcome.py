"""The outcome of a step of ``ALDMHighway-v0``: reward, episode end and ``info``.

Everything here is computed from ground truth (the :class:`~aldm_gym.envs.referee.Referee`'s
lane position, departures, collision) and the ego's own state, after the simulation
steps of a policy step. The reward terms and their weights are the table of
:class:`~aldm_gym.envs.highway.ALDMHighwayEnv`'s docstring and ``docs/env.md``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from highway_env import utils

from aldm_gym.envs.config import EnvConfig
from aldm_gym.envs.referee import Referee
from aldm_gym.envs.scene import ROAD_END_MARGIN
from aldm_gym.roads.position import LanePosition

__all__ = ["REWARD_TERMS", "reward", "reward_terms", "step_info", "terminated", "truncated"]

REWARD_TERMS = (
    "collision_reward",
    "departure_reward",
    "high_speed_reward",
    "progress_reward",
    "lane_keeping_reward",
    "right_lane_reward",
    "lane_change_reward",
    "overtaking_reward",
)
"""The reward terms, each weighted by the setting of the same name."""

TERM_RANGES: dict[str, tuple[float, float]] = {"overtaking_reward": (-1.0, 1.0)}
"""The range of each term that is not [0, 1] (for ``normalize_reward``)."""

PASSING_WINDOW = (60.0, 15.0)
"""Where another vehicle counts for ``overtaking_reward``: within this distance ahead or
behind and to either side of the ego, in the ego's frame [m], before and after the step."""


def passing_positions(ego: Any, vehicles: Any) -> dict[Any, float]:
    """How far ahead of the ego each other vehicle within :data:`PASSING_WINDOW` is:
    ``{vehicle: x}``, x along the ego's heading [m] (> 0 ahead). Keyed by the vehicle
    itself (identity), not by ``id()``: a vehicle removed in the step (a sink, a
    deleted entity) could otherwise hand its id to a new one."""
    reach, side = PASSING_WINDOW
    cos_h, sin_h = math.cos(ego.heading), math.sin(ego.heading)
    ex, ey = float(ego.position[0]), float(ego.position[1])
    out: dict[Any, float] = {}
    for vehicle in vehicles:
        if vehicle is ego:
            continue
        dx, dy = float(vehicle.position[0]) - ex, float(vehicle.position[1]) - ey
        x = dx * cos_h + dy * sin_h
        if abs(x) <= reach and abs(dy * cos_h - dx * sin_h) <= side:
            out[vehicle] = x
    return out


def net_overtakes(before: dict[Any, float], after: dict[Any, float]) -> int:
    """Vehicles the ego passed minus vehicles that passed the ego between two
    :func:`passing_positions` (only those in the window at both times count)."""
    net = 0
    for key, x_after in after.items():
        x_before = before.get(key)
        if x_before is None:
            continue
        net += int(x_before > 0.0 >= x_after) - int(x_before <= 0.0 < x_after)
    return net


def reward_terms(
    settings: EnvConfig,
    ego: Any,
    pos: LanePosition,
    s_before: float,
    departed: bool,
    lane_change: bool,
    overtakes: int = 0,
) -> dict[str, float]:
    """The reward terms of a policy step (``info["rewards"]``), each in [0, 1] but
    those of :data:`TERM_RANGES`.

    :param pos: the ego's true lane position after the step.
    :param s_before: its arc length before the step [m].
    :param departed: a lane departure happened during the step.
    :param lane_change: the action requested a lane change.
    :param overtakes: vehicles passed minus vehicles passed by during the step
        (:func:`net_overtakes`).
    """
    lo, hi = settings.reward_speed_range
    forward_speed = ego.speed * math.cos(ego.heading - pos.heading)
    step_time = 1.0 / settings.policy_frequency
    return {
        "collision_reward": float(ego.crashed),
        "departure_reward": float(departed),
        "high_speed_reward": float(np.clip(utils.lmap(forward_speed, [lo, hi], [0, 1]), 0, 1)),
        "progress_reward": float(np.clip((pos.s - s_before) / (hi * step_time), 0.0, 1.0)),
        "lane_keeping_reward": (
            float(max(0.0, 1.0 - abs(pos.offset) / (0.5 * pos.width))) if pos.width > 0.0 else 0.0
        ),
        "right_lane_reward": pos.index / max(pos.lanes - 1, 1),
        "lane_change_reward": float(lane_change),
        "overtaking_reward": float(np.clip(overtakes, -1, 1)),
    }


def reward(settings: EnvConfig, terms: dict[str, float]) -> float:
    """``Σ_k w_k · r_k`` with the weights of the settings; with ``normalize_reward``
    mapped linearly from the least to the greatest possible sum (each term at the end
    of its range, [0, 1] or :data:`TERM_RANGES`, that makes ``w_k · r_k`` least or
    greatest: for [0, 1] terms the sums of the negative and of the positive weights)
    to ``[0, 1]``."""
    weights = {name: getattr(settings, name) for name in terms}
    total = sum(weights[name] * value for name, value in terms.items())
    if settings.normalize_reward:
        neg = pos = 0.0
        for name, w in weights.items():
            lo, hi = TERM_RANGES.get(name, (0.0, 1.0))
            neg += min(w * lo, w * hi)
            pos += max(w * lo, w * hi)
        if pos > neg:
            total = utils.lmap(total, [neg, pos], [0.0, 1.0])
    return float(total)


def terminated(settings: EnvConfig, ego: Any, referee: Referee) -> bool:
    """The ego crashed, left a map's lanes, or (with ``offroad_terminal``) is off the
    road's edge lane, or (with ``departure_terminal``) departed its lane this step."""
    pos = referee.lane_position
    offroad = pos.edge_lane and abs(pos.offset) > 0.5 * pos.width
    return bool(
        ego.crashed
        or referee.off_map
        or (settings.offroad_terminal and offroad)
        or (settings.departure_terminal and referee.departed_step)
    )


def truncated(settings: EnvConfig, time: float, referee: Referee) -> bool:
    """``duration`` [s] elapsed, or the road ahead ends within :data:`ROAD_END_MARGIN`."""
    road_end = referee.road.ends_within(referee.lane_position, ROAD_END_MARGIN)
    return bool(time >= settings.duration or road_end)


def step_info(ego: Any, referee: Referee, detection: dict, target: dict) -> dict[str, Any]:
    """aldm-gym's ``info`` keys of a step (added to highway-env's ``speed``, ``crashed``,
    ``action``, ``rewards``); ``lane_ends_in`` only on a road whose lanes can end."""
    pos = referee.lane_position
    info = {
        "lateral_offset": pos.offset,
        "lane_departure": bool(referee.departed_step),
        "lane_index": pos.index,
        "lane_change": int(ego.lane_change),
        "lane_change_refused": bool(ego.lane_change_refused),
        "lane_changes_completed": int(ego.lane_changes_completed),
        "lane_changes_aborted": int(ego.lane_changes_aborted),
        "arc_length": pos.s,
        "distance": referee.distance,
        "departures": referee.departures,
        "detection": detection,
        "target": target,
        "collision": referee.collision,
    }
    ends = referee.road.lane_ends_in(pos)
    if ends is not None:
        info["lane_ends_in"] = ends
    return info
