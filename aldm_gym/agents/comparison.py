"""The closed-loop half of the naive-vs-ALDM comparison (``aldm-gym compare``).

For every marking model and detector, the LKA with IDLE and the rule-based LCA drive
the same seeded ``ALDMHighway-v0`` episodes; :func:`compare_closed_loop` returns one
row of ground-truth metrics per (marking model, detector) and the first IDLE
episode's lateral-offset trace of each (for
:func:`~aldm_gym.agents.plot.plot_offsets`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import gymnasium as gym

from aldm_gym import ENV_ID
from aldm_gym.agents.evaluation import run_episodes, summarize
from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.detectors import DETECTORS

CLOSED_LOOP_COLUMNS: tuple[str, ...] = (
    "marking_model",
    "detector",
    "episodes",
    "km",
    "departures_per_km",
    "rms_offset_m",
    "max_offset_m",
    "both_correct",
    "mean_preview_m",
    "collisions",
    "lane_changes_ok",
    "lane_changes_failed",
    "mean_speed",
    "success_rate",
    "target_accuracy",
    "missed_rate",
    "false_rate",
    "phantom_braking",
    "aeb_activations",
    "rear_end_collisions",
    "min_time_gap",
)
"""Columns of ``compare.csv`` (closed loop, one row per marking model × detector); the
last seven score the ACC's target selection (``info["target"]``, see
:func:`~aldm_gym.agents.evaluation.summarize`)."""

Trace = list[tuple[float, float]]
"""``(distance from the start [m], signed lateral offset [m])`` per policy step."""


def compare_closed_loop(
    seeds: Sequence[int],
    *,
    marking_models: Iterable[str] = MARKING_MODELS,
    detectors: Iterable[str] = DETECTORS,
    sensor: dict[str, Any] | None = None,
    min_radius: float | None = None,
    xodr: str | os.PathLike[str] | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[list[dict[str, Any]], dict[tuple[str, str], Trace]]:
    """IDLE (LKA only) and the rule-based LCA on the same seeded episodes, per detector.

    :param seeds: episode seeds; each policy plays each seed once per row.
    :param sensor: the env's ``sensor`` config section (e.g. ``lateral_noise``,
        ``dropout``); None: the env's defaults.
    :param min_radius: smallest curve radius of the generated roads [m] (None: the
        env's default).
    :param xodr: drive on this OpenDRIVE map (the env's ``road.xodr``) instead of the
        generated roads (``min_radius`` must then be None).
    :param progress: called with 1 after each episode.
    :return: rows with the keys of :data:`CLOSED_LOOP_COLUMNS` (the
        :func:`~aldm_gym.agents.evaluation.summarize` metrics of both policies'
        episodes together), and the first IDLE episode's trace per
        ``(marking model, detector)``.
    """
    if xodr is not None and min_radius is not None:
        raise ValueError("min_radius applies to generated roads, not to a map (xodr)")
    detectors = list(detectors)
    rows: list[dict[str, Any]] = []
    traces: dict[tuple[str, str], Trace] = {}
    for model in marking_models:
        for det in detectors:
            config: dict[str, Any] = {"marking_model": model, "detector": det}
            if sensor is not None:
                config["sensor"] = dict(sensor)
            if min_radius is not None:
                config["road"] = {"min_radius": min_radius}
            if xodr is not None:
                config["road"] = {"xodr": os.fspath(xodr)}
            env = gym.make(ENV_ID, config=config)
            try:
                idle = run_episodes(env, IdlePolicy(), seeds, progress=progress)
                lca = run_episodes(env, RuleBasedLCA(), seeds, progress=progress)
            finally:
                env.close()
            row = {"marking_model": model, "detector": det, **summarize(idle + lca)}
            rows.append({c: row[c] for c in CLOSED_LOOP_COLUMNS})
            traces[(model, det)] = idle[0].trace
    return rows, traces
