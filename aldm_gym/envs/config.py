"""Validated configuration of :class:`~aldm_gym.envs.highway.ALDMHighwayEnv`.

highway-env keeps an environment's configuration in a plain ``dict`` and merges user
dicts into it without checking (``AbstractEnv.configure``), so a misspelled key is
silently ignored. Here every key is known: :func:`validate_config` rejects unknown
keys (naming them and the allowed ones) and impossible values, and normalises the
nested sections (``road``, ``sensor``, ``lka``, ``action``, ``observation``).

The keys keep highway-env's meaning where highway-env has them (``lanes_count``,
``vehicles_count``, ``vehicles_density``, ``duration``, ``simulation_frequency``,
``policy_frequency``, ``initial_lane_id``, ``ego_spacing``, the reward weights, the
rendering keys); the rest are aldm-gym's. The full table is in ``docs/env.md``.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

from aldm_gym.config import check_choice, check_range

DETECTORS = ("aldm", "naive", "ground_truth")
"""Lane detectors the environment can run on each sensor frame."""

ACTION_TYPES = ("DiscreteMetaAction", "ContinuousAction")
"""Action types: highway-env's meta actions (via the LKA), or (steering, acceleration)."""

MARKING_MODELS = ("per_dash", "editor")
"""Marking models of the road (see :class:`aldm_gym.roads.RoadConfig`)."""

LKA_KEYS = ("lookahead_time", "min_lookahead", "max_steering", "path_range")
"""Keys of the ``lka`` section (see :class:`aldm_gym.envs.control.LKAController`)."""

ACTION_KEYS = ("type", "target_speeds", "lane_change_timeout", "max_acceleration")
"""Keys of the ``action`` section."""

OBSERVATION_KEYS = ("type", "vehicles_count", "perception_distance")
"""Keys of the ``observation`` section."""


def default_config() -> dict[str, Any]:
    """The default configuration (a fresh, deep-copied dict).

    highway-env's generic keys (``AbstractEnv.default_config`` and
    ``HighwayEnv.default_config``) with their meaning, plus aldm-gym's own.
    """
    return {
        # --- highway-env: AbstractEnv
        "observation": {
            "type": "ALDMObservation",
            "vehicles_count": 8,
            "perception_distance": 100.0,
        },
        "action": {
            "type": "DiscreteMetaAction",
            "target_speeds": [20.0, 25.0, 30.0],
            "lane_change_timeout": 8.0,
            "max_acceleration": 5.0,
        },
        "simulation_frequency": 10,
        "policy_frequency": 1,
        "other_vehicles_type": "aldm_gym.envs.traffic.FastIDMVehicle",
        "screen_width": 800,
        "screen_height": 300,
        "centering_position": [0.3, 0.5],
        "scaling": 5.5,
        "show_trajectories": False,
        "render_agent": True,
        "offscreen_rendering": None,
        "manual_control": False,
        "real_time_rendering": False,
        "neighbour_vehicles_connected_lanes": False,
        # --- highway-env: HighwayEnv
        "lanes_count": 4,
        "vehicles_count": 20,
        "controlled_vehicles": 1,
        "initial_lane_id": None,
        "duration": 40.0,
        "ego_spacing": 2.0,
        "vehicles_density": 1.0,
        "collision_reward": -1.0,
        "right_lane_reward": 0.0,
        "high_speed_reward": 0.3,
        "lane_change_reward": 0.0,
        "reward_speed_range": [20.0, 30.0],
        "normalize_reward": True,
        "offroad_terminal": False,
        # --- aldm-gym
        "initial_speed": 25.0,
        "marking_model": "per_dash",
        "detector": "aldm",
        "detector_params": {},
        "sensor": {},
        "road": {},
        "lka": {},
        "progress_reward": 0.2,
        "lane_keeping_reward": 0.3,
        "departure_reward": -0.5,
        "departure_terminal": False,
    }


ALLOWED_KEYS: tuple[str, ...] = tuple(sorted(default_config()))
"""Every top-level key the environment accepts."""


def _check_section(name: str, value: Any, allowed: tuple[str, ...]) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        raise ValueError(f"config[{name!r}] must be a mapping, got {type(value).__name__}")
    unknown = sorted(str(k) for k in value if k not in allowed)
    if unknown:
        raise ValueError(f"unknown {name} config key(s) {unknown}; allowed keys: {sorted(allowed)}")
    return dict(value)


def _check_bool(name: str, value: Any) -> None:
    if not isinstance(value, bool):
        raise ValueError(f"config[{name!r}] must be a bool, got {value!r}")


def _check_pair(name: str, value: Any) -> None:
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise ValueError(f"config[{name!r}] must be a (min, max) pair, got {value!r}")
    check_range("config", f"{name}[0]", value[0])
    check_range("config", f"{name}[1]", value[1], value[0], lo_open=True)


def merge_config(base: Mapping[str, Any], update: Mapping[str, Any] | None) -> dict[str, Any]:
    """``base`` updated with ``update``, section dicts merged key by key, then validated.

    :raises ValueError: naming any unknown key (with the allowed ones) or bad value.
    """
    out = copy.deepcopy(dict(base))
    if update:
        if not isinstance(update, Mapping):
            raise ValueError(f"config must be a mapping, got {type(update).__name__}")
        unknown = sorted(str(k) for k in update if k not in ALLOWED_KEYS)
        if unknown:
            raise ValueError(f"unknown config key(s) {unknown}; allowed keys: {list(ALLOWED_KEYS)}")
        for key, value in update.items():
            if key in ("road", "sensor", "lka", "action", "observation", "detector_params"):
                if not isinstance(value, Mapping):
                    raise ValueError(
                        f"config[{key!r}] must be a mapping, got {type(value).__name__}"
                    )
                merged = dict(out.get(key) or {})
                merged.update(copy.deepcopy(dict(value)))
                out[key] = merged
            else:
                out[key] = copy.deepcopy(value)
    return validate_config(out)


def validate_config(config: Mapping[str, Any]) -> dict[str, Any]:
    """Check a complete configuration; return it (sections normalised).

    :raises ValueError: unknown keys (top level or in a section), naming the allowed
        ones, or a value out of its range / not among its choices.
    """
    cfg = dict(config)
    unknown = sorted(str(k) for k in cfg if k not in ALLOWED_KEYS)
    if unknown:
        raise ValueError(f"unknown config key(s) {unknown}; allowed keys: {list(ALLOWED_KEYS)}")
    missing = sorted(k for k in ALLOWED_KEYS if k not in cfg)
    if missing:
        raise ValueError(f"config is missing key(s) {missing}")
    w = "config"
    check_range(w, "simulation_frequency", cfg["simulation_frequency"], 1, 1000, integer=True)
    check_range(w, "policy_frequency", cfg["policy_frequency"], 1, 1000, integer=True)
    if cfg["simulation_frequency"] % cfg["policy_frequency"] != 0:
        raise ValueError(
            "config['simulation_frequency'] must be a multiple of config['policy_frequency'], "
            f"got {cfg['simulation_frequency']} and {cfg['policy_frequency']}"
        )
    check_range(w, "lanes_count", cfg["lanes_count"], 1, 6, integer=True)
    check_range(w, "vehicles_count", cfg["vehicles_count"], 0, 500, integer=True)
    if cfg["controlled_vehicles"] != 1:
        raise ValueError(
            f"config['controlled_vehicles'] must be 1 (one ego), got {cfg['controlled_vehicles']!r}"
        )
    if cfg["initial_lane_id"] is not None:
        check_range(
            w, "initial_lane_id", cfg["initial_lane_id"], 0, cfg["lanes_count"] - 1, integer=True
        )
    check_range(w, "duration", cfg["duration"], 0.0, 10_000.0, lo_open=True)
    check_range(w, "ego_spacing", cfg["ego_spacing"], 0.0, 100.0, lo_open=True)
    check_range(w, "vehicles_density", cfg["vehicles_density"], 0.0, 100.0, lo_open=True)
    check_range(w, "initial_speed", cfg["initial_speed"], 0.0, 40.0)
    for key in (
        "collision_reward",
        "right_lane_reward",
        "high_speed_reward",
        "lane_change_reward",
        "progress_reward",
        "lane_keeping_reward",
        "departure_reward",
    ):
        check_range(w, key, cfg[key], -100.0, 100.0)
    _check_pair("reward_speed_range", cfg["reward_speed_range"])
    for key in (
        "normalize_reward",
        "offroad_terminal",
        "departure_terminal",
        "show_trajectories",
        "render_agent",
        "manual_control",
        "real_time_rendering",
        "neighbour_vehicles_connected_lanes",
    ):
        _check_bool(key, cfg[key])
    check_choice(w, "marking_model", cfg["marking_model"], MARKING_MODELS)
    check_choice(w, "detector", cfg["detector"], DETECTORS)
    if not isinstance(cfg["other_vehicles_type"], str):
        raise ValueError("config['other_vehicles_type'] must be a class path string")

    act = _check_section("action", cfg["action"], ACTION_KEYS)
    act.setdefault("type", "DiscreteMetaAction")
    check_choice("action", "type", act["type"], ACTION_TYPES)
    speeds = act.get("target_speeds", [20.0, 25.0, 30.0])
    if not isinstance(speeds, list | tuple) or len(speeds) < 1:
        raise ValueError(f"action.target_speeds must be a non-empty list, got {speeds!r}")
    for k, v in enumerate(speeds):
        check_range("action", f"target_speeds[{k}]", v, 0.0, 40.0)
    if list(speeds) != sorted(speeds):
        raise ValueError(f"action.target_speeds must be increasing, got {speeds!r}")
    act["target_speeds"] = [float(v) for v in speeds]
    act.setdefault("lane_change_timeout", 8.0)
    check_range("action", "lane_change_timeout", act["lane_change_timeout"], 0.5, 60.0)
    act.setdefault("max_acceleration", 5.0)
    check_range("action", "max_acceleration", act["max_acceleration"], 0.0, 20.0, lo_open=True)
    cfg["action"] = act

    obs = _check_section("observation", cfg["observation"], OBSERVATION_KEYS)
    obs.setdefault("type", "ALDMObservation")
    check_choice("observation", "type", obs["type"], ("ALDMObservation",))
    obs.setdefault("vehicles_count", 8)
    check_range("observation", "vehicles_count", obs["vehicles_count"], 1, 64, integer=True)
    obs.setdefault("perception_distance", 100.0)
    check_range("observation", "perception_distance", obs["perception_distance"], 1.0, 250.0)
    cfg["observation"] = obs

    lka = _check_section("lka", cfg["lka"], LKA_KEYS)
    cfg["lka"] = lka
    road = _check_section("road", cfg["road"], _road_keys())
    for key in ("lanes_count", "marking_model"):
        if key in road and road[key] != cfg[key]:
            raise ValueError(
                f"config['road'][{key!r}] ({road[key]!r}) contradicts config[{key!r}] "
                f"({cfg[key]!r}); set the top-level key only"
            )
    cfg["road"] = road
    cfg["sensor"] = _check_section("sensor", cfg["sensor"], _sensor_keys())
    if not isinstance(cfg["detector_params"], Mapping):
        raise ValueError("config['detector_params'] must be a mapping")
    if cfg["detector_params"] and cfg["detector"] != "aldm":
        raise ValueError("config['detector_params'] is only used with detector='aldm'")
    _validate_components(cfg)
    return cfg


def _road_keys() -> tuple[str, ...]:
    import dataclasses

    from aldm_gym.roads.highway import RoadConfig

    return tuple(f.name for f in dataclasses.fields(RoadConfig))


def _sensor_keys() -> tuple[str, ...]:
    import dataclasses

    from aldm_gym.sensor.line_sensor import LineSensorConfig

    return tuple(f.name for f in dataclasses.fields(LineSensorConfig))


def road_config(cfg: Mapping[str, Any], seed: int) -> Any:
    """The :class:`~aldm_gym.roads.RoadConfig` of a validated env config.

    ``road.seed`` may be ``None``: the caller then passes a seed drawn from the
    environment's ``np_random``.
    """
    from aldm_gym.roads.highway import RoadConfig

    road = dict(cfg["road"])
    road["lanes_count"] = cfg["lanes_count"]
    road["marking_model"] = cfg["marking_model"]
    if road.get("seed", 0) is None:
        road["seed"] = seed
    for key in ("straight_length", "arc_length", "transition_length"):
        if isinstance(road.get(key), list):
            road[key] = tuple(road[key])
    if isinstance(road.get("segments"), list):
        road["segments"] = tuple(tuple(s) for s in road["segments"])
    return RoadConfig(**road)


def _validate_components(cfg: Mapping[str, Any]) -> None:
    """Build the road, sensor, detector and LKA configs once to check their values."""
    from aldm_gym.envs.control import LKAController
    from aldm_gym.sensor.line_sensor import LineSensorConfig

    road_config(cfg, 0)
    LineSensorConfig(**cfg["sensor"])
    lka = dict(cfg["lka"])
    path_range = lka.pop("path_range", 80.0)
    if path_range is not None:
        check_range("lka", "path_range", path_range, 10.0, 1000.0)
    LKAController(**lka)
    if cfg["detector"] == "aldm" and cfg["detector_params"]:
        from aldm_gym.sensor.aldm import make_params

        make_params(None, **cfg["detector_params"])
