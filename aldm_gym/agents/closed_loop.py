"""The closed-loop half of the naive-vs-ALDM comparison (``aldm-gym compare``).

For every marking model and detector, the LKA with IDLE and the rule-based LCA drive
the same seeded ``ALDMHighway-v0`` episodes; :func:`compare_closed_loop` returns one
row of ground-truth metrics per (marking model, detector) and the first IDLE
episode's lateral-offset trace of each (for
:func:`~aldm_gym.agents.figures.plot_offsets`). The rows are detector *variants*
(:data:`DETECTOR_VARIANTS`): the registry's detectors and the tracking ALDM.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import gymnasium as gym

from aldm_gym import ENV_ID
from aldm_gym.agents.episodes import run_episodes, summarize
from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA
from aldm_gym.envs.config import EnvOverrides, merged_config
from aldm_gym.errors import ConfigError
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.sensor.aldm import MODES as ALDM_MODES
from aldm_gym.sensor.detectors import DETECTORS

CLOSED_LOOP_COLUMNS: tuple[str, ...] = (
    "marking_model",
    "detector",
    "mode",
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
:func:`~aldm_gym.agents.episodes.summarize`)."""

DETECTOR_VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "naive": ("naive", {}),
    "aldm": ("aldm", {}),
    "aldm_tracking": ("aldm", {"tracking": True}),
    "aldm_filter": ("aldm", {"tracking": "model"}),
    "ground_truth": ("ground_truth", {}),
}
"""A closed-loop row's name -> the env's ``detector`` and ``detector_params``: the
registry's detectors (:data:`~aldm_gym.sensor.detectors.DETECTORS`) and the tracking
ALDM (stateful, so it is compared in closed loop only). Also the order of the rows."""

Trace = list[tuple[float, float]]
"""``(distance driven so far [m], signed lateral offset [m])`` per policy step."""


def _idle(_env: Any) -> IdlePolicy:
    return IdlePolicy()


def _rule_based(_env: Any) -> RuleBasedLCA:
    return RuleBasedLCA()


def compare_closed_loop(
    seeds: Sequence[int],
    *,
    marking_models: Iterable[str] = MARKING_MODELS,
    detectors: Iterable[str] = DETECTORS,
    sensor: dict[str, Any] | None = None,
    traffic: dict[str, Any] | None = None,
    min_radius: float | None = None,
    xodr: str | os.PathLike[str] | None = None,
    aldm_mode: str = "robust",
    progress: Callable[[int], None] | None = None,
    env: Mapping[str, Any] | None = None,
    policies: Sequence[Callable[[Any], Any]] | None = None,
) -> tuple[list[dict[str, Any]], dict[tuple[str, str], Trace]]:
    """IDLE (LKA only) and the rule-based LCA on the same seeded episodes, per detector.

    :param seeds: episode seeds; each policy plays each seed once per row.
    :param detectors: row names, keys of :data:`DETECTOR_VARIANTS`.
    :param aldm_mode: the ALDM rows' mode, ``"robust"`` (the default) or ``"paper"``;
        the rows' ``mode`` column names it.
    :param sensor: the env's ``sensor`` config section (e.g. ``lateral_noise``,
        ``dropout``, ``preset``); None: the env's defaults.
    :param traffic: the env's ``traffic`` section (e.g. ``truck_share``); None: cars.
    :param min_radius: smallest curve radius of the generated roads [m] (None: the
        env's default).
    :param xodr: drive on this OpenDRIVE map (the env's ``road.xodr``) instead of the
        generated roads (``min_radius`` must then be None).
    :param progress: called with 1 after each episode.
    :param env: more env settings, merged last (e.g. ``{"acc": {"time_gap": 2.0}}``).
    :param policies: what drives instead of IDLE and the rule-based LCA: per policy a
        factory ``f(env) -> policy`` (a function under test needs the env it drives).
    :return: rows with the keys of :data:`CLOSED_LOOP_COLUMNS` (the
        :func:`~aldm_gym.agents.episodes.summarize` metrics of all policies'
        episodes together), and the first policy's first episode's trace per
        ``(marking model, detector)``.
    """
    if xodr is not None and min_radius is not None:
        raise ConfigError("min_radius applies to generated roads, not to a map (xodr)")
    if aldm_mode not in ALDM_MODES:
        raise ConfigError(f"aldm_mode must be one of {list(ALDM_MODES)}, got {aldm_mode!r}")
    detectors = list(detectors)
    unknown = [d for d in detectors if d not in DETECTOR_VARIANTS]
    if unknown:
        raise ConfigError(f"unknown detector(s) {unknown}; allowed: {list(DETECTOR_VARIANTS)}")
    factories = list(policies) if policies is not None else [_idle, _rule_based]
    rows: list[dict[str, Any]] = []
    traces: dict[tuple[str, str], Trace] = {}
    for model in marking_models:
        for det in detectors:
            name, params = DETECTOR_VARIANTS[det]
            mode = aldm_mode if name == "aldm" else ""
            if mode == "paper":
                params = {**params, "mode": "paper"}
            config: dict[str, Any] = {"marking_model": model, "detector": name}
            if params:
                config["detector_params"] = dict(params)
            if sensor is not None:
                config["sensor"] = dict(sensor)
            if traffic is not None:
                config["traffic"] = dict(traffic)
            if min_radius is not None:
                config["road"] = {"min_radius": min_radius}
            if xodr is not None:
                config["road"] = {"xodr": os.fspath(xodr)}
            if env is not None:
                config = merged_config(config, env)
            made = gym.make(ENV_ID, config=EnvOverrides(config))
            played: list[list[Any]] = []
            try:
                for factory in factories:
                    played.append(run_episodes(made, factory(made), seeds, progress=progress))
            finally:
                made.close()
            row = {
                "marking_model": model,
                "detector": det,
                "mode": mode,
                **summarize([e for episodes in played for e in episodes]),
            }
            rows.append({c: row[c] for c in CLOSED_LOOP_COLUMNS})
            traces[(model, det)] = played[0][0].trace
    return rows, traces


def conditions_scene(
    seed: int,
    *,
    sensor: dict[str, Any],
    traffic: dict[str, Any] | None = None,
    road: dict[str, Any] | None = None,
    marking_model: str = "per_dash",
    max_steps: int = 400,
    settle: int = 50,
) -> dict[str, Any]:
    """A frame of a tracking-ALDM episode where a vehicle ahead hides marking points.

    Drives IDLE (one simulation step at a time) on seed ``seed`` with the tracking
    ALDM and the given sensor conditions and keeps, after the first ``settle`` steps
    (the start places the traffic densely ahead), the frame with the most vehicle
    footprint 15–80 m ahead within 6 m of the sensor's axis (the frame where the
    occlusion shows most), then detects that same frame with the single-frame ALDM
    and naive.

    :param sensor: the env's ``sensor`` section (e.g. ``{"preset": "camera"}``).
    :param traffic: the env's ``traffic`` section (e.g. ``{"truck_share": 0.2}``).
    :param road: the env's ``road`` section (e.g. ``{"xodr": path}``).
    :param max_steps: simulation steps driven (at most: the episode may end first).
    :param settle: simulation steps not considered at the start.
    :return: ``frame``, ``detections`` (``{"naive", "aldm", "aldm_tracking",
        "ground_truth"} -> LaneDetection``), ``boxes`` (``(V, 4, 2)`` corners of the
        other vehicles in the sensor frame [m]), ``step`` and ``seed``.
    """
    import numpy as np

    from aldm_gym.sensor.detectors import make_detector

    config: dict[str, Any] = {
        "marking_model": marking_model,
        "detector": "aldm",
        "detector_params": {"tracking": True},
        "sensor": dict(sensor),
        "policy_frequency": 10,
    }
    if traffic is not None:
        config["traffic"] = dict(traffic)
    if road is not None:
        config["road"] = dict(road)
    env = gym.make(ENV_ID, config=EnvOverrides(config))
    try:
        env.reset(seed=seed)
        u = env.unwrapped
        best: dict[str, Any] | None = None
        for step in range(max_steps):
            _, _, term, trunc, _ = env.step(1)  # IDLE
            frame = u.frame
            boxes, areas = _footprints(_others(u), frame)
            centre = boxes.mean(axis=1)
            near = (centre[:, 0] > 15.0) & (centre[:, 0] < 80.0) & (np.abs(centre[:, 1]) < 6.0)
            area = float(np.sum(areas[near]))
            if step + 1 >= min(settle, max_steps) and (best is None or area > best["area"]):
                best = {
                    "area": area,
                    "frame": frame,
                    "boxes": boxes,
                    "step": step + 1,
                    "tracking": u.detection,
                    "lane": u.lane_position.lane,
                }
            if term or trunc:
                break
        assert best is not None
        road = u.highway
        frame = best["frame"]
        lane = best["lane"]
        path_range = u.path_range
        detections = {
            "naive": make_detector("naive", path_range=path_range)(frame, road, lane),
            "aldm": make_detector("aldm", path_range=path_range)(frame, road, lane),
            "aldm_tracking": best["tracking"],
            "ground_truth": make_detector("ground_truth", path_range=path_range)(frame, road, lane),
        }
        return {
            "frame": frame,
            "detections": detections,
            "boxes": best["boxes"],
            "step": best["step"],
            "seed": seed,
        }
    finally:
        env.close()


def _footprints(vehicles: list[Any], frame: Any) -> tuple[Any, Any]:
    """``(V, 4, 2)`` corners (x, y) [m] of the vehicles' footprints in ``frame``'s
    sensor frame and their ``(V,)`` areas [m²] (the boxes
    :func:`~aldm_gym.sensor.conditions.occluder_array` gives the occlusion)."""
    import numpy as np

    from aldm_gym.envs.observation import to_sensor_frame
    from aldm_gym.sensor.conditions import occluder_array

    if not vehicles:
        return np.zeros((0, 4, 2)), np.zeros(0)
    box = occluder_array(vehicles)
    c, s = np.cos(box[:, 2]), np.sin(box[:, 2])
    ex = np.stack((c, s), axis=1) * (0.5 * box[:, 3:4])
    ey = np.stack((-s, c), axis=1) * (0.5 * box[:, 4:5])
    corners = box[:, None, :2] + np.stack((ex + ey, ex - ey, -ex - ey, -ex + ey), axis=1)
    flat = corners.reshape(-1, 2)
    rel = to_sensor_frame(flat, np.zeros_like(flat), frame.origin, frame.yaw)
    return rel[:, :2].reshape(-1, 4, 2), box[:, 3] * box[:, 4]


def _others(env: Any) -> list[Any]:
    """The env's vehicles other than the ego, in ``road.vehicles`` order."""
    return [v for v in env.road.vehicles if v is not env.vehicle]
