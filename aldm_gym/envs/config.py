"""Validated configuration of :class:`~aldm_gym.envs.highway.ALDMHighwayEnv`.

highway-env keeps an environment's configuration in a plain ``dict`` and merges user
dicts into it without checking (``AbstractEnv.configure``), so a misspelled key is
silently ignored. Here every key is declared once, with its default and its rule, in
a config dataclass (:mod:`aldm_gym.config`):

=====================  =============================================================
section                declared by
=====================  =============================================================
top level              :class:`EnvConfig` (below)
``action``             :class:`aldm_gym.envs.actions.ActionConfig`
``observation``        :class:`aldm_gym.envs.observation.ObservationConfig`
``lka``                :class:`aldm_gym.envs.control.LKAConfig`
``acc``                :class:`aldm_gym.envs.longitudinal.ACCConfig`
``traffic``            :class:`aldm_gym.envs.traffic.mix.TrafficConfig` (trucks)
``sensor``             :class:`aldm_gym.sensor.line_sensor.LineSensorConfig`
``road``               :class:`aldm_gym.roads.highway.RoadConfig`, or :class:`MapConfig`
                       with ``road.xodr`` (an OpenDRIVE map)
``detector_params``    the detector's own parameters (:mod:`aldm_gym.sensor.detectors`)
=====================  =============================================================

:func:`merge_config` and :func:`validate_config` reject unknown keys (naming them and
the allowed ones) and impossible values; the env keeps the validated plain dict that
highway-env expects. The keys keep highway-env's meaning where highway-env has them
(``lanes_count``, ``vehicles_count``, ``vehicles_density``, ``duration``,
``simulation_frequency``, ``policy_frequency``, ``initial_lane_id``, ``ego_spacing``,
the reward weights, the rendering keys); the rest are aldm-gym's. The full table is in
``docs/env.md``.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from aldm_gym.config import build_config, close_match, rules, setting, validate
from aldm_gym.envs.actions import ACTION_TYPES, ActionConfig
from aldm_gym.envs.control import LKAConfig
from aldm_gym.envs.longitudinal import ACCConfig
from aldm_gym.envs.observation import ObservationConfig
from aldm_gym.envs.traffic.mix import TrafficConfig
from aldm_gym.errors import ConfigError
from aldm_gym.roads.highway import MARKING_MODELS, RoadConfig
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.roads.opendrive import DEFAULT_BROKEN_PATTERN, DEFAULT_SAMPLE_STEP
from aldm_gym.sensor.detectors import DETECTORS, make_detector
from aldm_gym.sensor.line_sensor import LineSensorConfig

__all__ = [
    "ACTION_TYPES",
    "ALLOWED_KEYS",
    "DETECTORS",
    "MARKING_MODELS",
    "SECTIONS",
    "EnvConfig",
    "MapConfig",
    "default_config",
    "map_config",
    "map_road",
    "merge_config",
    "road_config",
    "validate_config",
]

REWARD_KEYS = (
    "collision_reward",
    "right_lane_reward",
    "high_speed_reward",
    "lane_change_reward",
    "progress_reward",
    "lane_keeping_reward",
    "departure_reward",
)
"""The reward weights (the env's ``_rewards`` keys)."""


def _reward(default: float) -> Any:
    return setting(default, lo=-100.0, hi=100.0)


@dataclass(frozen=True)
class EnvConfig:
    """The env's top-level keys: defaults and rules (sections are dicts, see the module).

    highway-env's ``AbstractEnv`` keys: ``simulation_frequency`` [Hz],
    ``policy_frequency`` [Hz], ``other_vehicles_type`` (a class path of a highway-env
    vehicle), the rendering keys (``screen_width``/``screen_height`` [px], ``scaling``
    [px/m], ``centering_position`` (fractions of the screen), ``show_trajectories``,
    ``render_agent``, ``offscreen_rendering``, ``manual_control``,
    ``real_time_rendering``), ``neighbour_vehicles_connected_lanes``. highway-env's
    ``HighwayEnv`` keys: ``lanes_count``, ``vehicles_count``, ``controlled_vehicles``
    (1), ``initial_lane_id`` (``None``: random), ``duration`` [s], ``ego_spacing``,
    ``vehicles_density``, the reward weights, ``reward_speed_range`` [m/s],
    ``normalize_reward``, ``offroad_terminal``. aldm-gym's: ``initial_speed`` [m/s],
    ``marking_model``, ``detector``, ``progress_reward``, ``lane_keeping_reward``,
    ``departure_reward``, ``departure_terminal``, and the sections ``detector_params``,
    ``sensor``, ``road``, ``lka``, ``acc`` (ACC and AEB), ``traffic`` (trucks).
    Meanings: ``docs/env.md``.
    """

    # --- highway-env: AbstractEnv
    observation: Any = setting(None, kind="any")
    action: Any = setting(None, kind="any")
    simulation_frequency: int = setting(10, lo=1, hi=1000, integer=True)
    policy_frequency: int = setting(1, lo=1, hi=1000, integer=True)
    other_vehicles_type: str = setting("aldm_gym.envs.traffic.FastIDMVehicle")
    screen_width: int = setting(800, lo=16, hi=8192, integer=True)
    screen_height: int = setting(300, lo=16, hi=8192, integer=True)
    centering_position: list[float] = setting([0.3, 0.5], lo=0.0, hi=1.0)
    scaling: float = setting(5.5, lo=0.05, hi=100.0)
    show_trajectories: bool = setting(False)
    render_agent: bool = setting(True)
    offscreen_rendering: bool | None = setting(None, kind="bool", optional=True)
    manual_control: bool = setting(False)
    real_time_rendering: bool = setting(False)
    neighbour_vehicles_connected_lanes: bool = setting(False)
    # --- highway-env: HighwayEnv
    lanes_count: int = setting(4, lo=1, hi=6, integer=True)
    vehicles_count: int = setting(20, lo=0, hi=500, integer=True)
    controlled_vehicles: int = setting(1, choices=(1,))
    initial_lane_id: int | None = setting(None, lo=0, hi=5, integer=True, optional=True)
    duration: float = setting(40.0, lo=0.0, lo_open=True, hi=10_000.0)
    ego_spacing: float = setting(2.0, lo=0.0, lo_open=True, hi=100.0)
    vehicles_density: float = setting(1.0, lo=0.0, lo_open=True, hi=100.0)
    collision_reward: float = _reward(-1.0)
    right_lane_reward: float = _reward(0.0)
    high_speed_reward: float = _reward(0.3)
    lane_change_reward: float = _reward(0.0)
    reward_speed_range: tuple[float, float] = setting((20.0, 30.0), kind="pair", lo=0.0, hi=100.0)
    normalize_reward: bool = setting(True)
    offroad_terminal: bool = setting(False)
    # --- aldm-gym
    initial_speed: float = setting(25.0, lo=0.0, hi=40.0)
    marking_model: str = setting("per_dash", choices=MARKING_MODELS)
    detector: str = setting("aldm", choices=DETECTORS)
    detector_params: Any = setting(None, kind="any")
    sensor: Any = setting(None, kind="any")
    road: Any = setting(None, kind="any")
    lka: Any = setting(None, kind="any")
    acc: Any = setting(None, kind="any")
    traffic: Any = setting(None, kind="any")
    progress_reward: float = _reward(0.2)
    lane_keeping_reward: float = _reward(0.3)
    departure_reward: float = _reward(-0.5)
    departure_terminal: bool = setting(False)

    def __post_init__(self) -> None:
        validate(self, "config")
        if self.simulation_frequency % self.policy_frequency != 0:
            raise ConfigError(
                "config.simulation_frequency must be a multiple of config.policy_frequency, "
                f"got {self.simulation_frequency} and {self.policy_frequency}"
            )
        if self.initial_lane_id is not None and self.initial_lane_id >= self.lanes_count:
            raise ConfigError(
                f"config.initial_lane_id must be < lanes_count ({self.lanes_count}), "
                f"got {self.initial_lane_id!r}"
            )
        lo, hi = self.reward_speed_range
        if len(self.reward_speed_range) != 2 or hi - lo < 0.1:
            raise ConfigError(
                "config.reward_speed_range must be (min, max) with max >= min + 0.1 [m/s], "
                f"got {self.reward_speed_range!r}"
            )
        if len(self.centering_position) != 2:
            raise ConfigError(
                f"config.centering_position must be 2 fractions, got {self.centering_position!r}"
            )


@dataclass(frozen=True)
class MapConfig:
    """The ``road`` section when the env drives on an OpenDRIVE map (``road.xodr`` set).

    :ivar xodr: path of the ``.xodr`` file.
    :ivar broken_pattern: (dash, gap) [m] of ``broken`` marks without an explicit
        pattern (the reader's default: the paper's 6 m / 12 m).
    :ivar sample_step: sampling step along the map's reference lines [m].

    The generator's keys (:class:`~aldm_gym.roads.highway.RoadConfig`) do not apply;
    ``marking_model`` is the top-level key, ``lanes_count`` comes from the map.
    """

    xodr: str = setting("", kind="str")
    broken_pattern: list[float] = setting(list(DEFAULT_BROKEN_PATTERN), lo=0.0, lo_open=True)
    sample_step: float = setting(DEFAULT_SAMPLE_STEP, lo=0.0, lo_open=True, hi=10.0)

    def __post_init__(self) -> None:
        validate(self, "road")
        if not self.xodr:
            raise ConfigError("road.xodr must be the path of an OpenDRIVE file, got ''")
        if len(self.broken_pattern) != 2:
            raise ConfigError(
                f"road.broken_pattern must be (dash, gap) [m], got {self.broken_pattern!r}"
            )


MAP_KEYS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(MapConfig))
"""The ``road`` keys of a map."""


SECTIONS: dict[str, Any] = {
    "observation": ObservationConfig,
    "action": ActionConfig,
    "lka": LKAConfig,
    "acc": ACCConfig,
    "traffic": TrafficConfig,
    "sensor": LineSensorConfig,
    "road": RoadConfig,
}
"""The config sections declared by a dataclass (``detector_params`` is the detector's)."""

_FULL_SECTIONS = ("observation", "action", "lka", "acc", "traffic")
"""Sections held complete (defaults filled in); ``sensor`` and ``road`` hold only what
the user set, since ``road`` takes ``lanes_count``/``marking_model`` from the top level."""

ALLOWED_KEYS: tuple[str, ...] = tuple(sorted(f.name for f in dataclasses.fields(EnvConfig)))
"""Every top-level key the environment accepts."""


def default_config() -> dict[str, Any]:
    """The default configuration (a fresh dict): :class:`EnvConfig` with its sections."""
    cfg = {
        f.name: copy.deepcopy(getattr(EnvConfig(), f.name)) for f in dataclasses.fields(EnvConfig)
    }
    for name in _FULL_SECTIONS:
        cfg[name] = dataclasses.asdict(SECTIONS[name]())
    for name in ("sensor", "road", "detector_params"):
        cfg[name] = {}
    return cfg


def _unknown(where: str, keys: Any, allowed: tuple[str, ...]) -> None:
    bad = [k for k in keys if not isinstance(k, str)]
    if bad:
        raise ConfigError(f"{where} keys must be strings, got {bad!r}")
    unknown = sorted(k for k in keys if k not in allowed)
    if unknown:
        raise ConfigError(
            f"unknown {where} key(s) {unknown}{close_match(unknown, allowed)}; "
            f"allowed keys: {sorted(allowed)}"
        )


def merge_config(base: Mapping[str, Any], update: Mapping[str, Any] | None) -> dict[str, Any]:
    """``base`` updated with ``update``, section dicts merged key by key, then validated.

    :raises ConfigError: naming any unknown key (with the allowed ones) or bad value.
    """
    out = copy.deepcopy(dict(base))
    if update is not None:
        if not isinstance(update, Mapping):
            raise ConfigError(f"config must be a mapping, got {type(update).__name__}")
        _unknown("config", list(update), ALLOWED_KEYS)
        for key, value in update.items():
            if key in (*SECTIONS, "detector_params"):
                if not isinstance(value, Mapping):
                    raise ConfigError(
                        f"config[{key!r}] must be a mapping, got {type(value).__name__}"
                    )
                merged = dict(out.get(key) or {})
                merged.update(copy.deepcopy(dict(value)))
                out[key] = merged
            else:
                out[key] = copy.deepcopy(value)
    return validate_config(out)


def validate_config(config: Mapping[str, Any]) -> dict[str, Any]:
    """Check a complete configuration; return it (values and sections normalised).

    :raises ConfigError: unknown keys (top level or in a section), naming the allowed
        ones, or a value out of its range / not among its choices.
    """
    cfg = dict(config)
    _unknown("config", list(cfg), ALLOWED_KEYS)
    missing = sorted(k for k in ALLOWED_KEYS if k not in cfg)
    if missing:
        raise ConfigError(f"config is missing key(s) {missing}")
    top = EnvConfig(**cfg)
    out = {f.name: getattr(top, f.name) for f in dataclasses.fields(EnvConfig)}
    _check_vehicle_class(top.other_vehicles_type)
    for name, cls in SECTIONS.items():
        section = cfg[name]
        if not isinstance(section, Mapping):
            raise ConfigError(f"config[{name!r}] must be a mapping, got {type(section).__name__}")
        allowed = tuple(f.name for f in dataclasses.fields(cls))
        _unknown(name, list(section), allowed + MAP_KEYS if name == "road" else allowed)
        if name in _FULL_SECTIONS:
            out[name] = dataclasses.asdict(build_config(cls, section, where=name))
        else:
            out[name] = dict(section)
    for key in ("lanes_count", "marking_model"):
        if key in out["road"] and out["road"][key] != out[key]:
            raise ConfigError(
                f"config['road'][{key!r}] ({out['road'][key]!r}) contradicts config[{key!r}] "
                f"({out[key]!r}); set the top-level key only"
            )
    road = map_road(out)
    if road is None:
        road_config(out, 0)
    else:
        # The lane count comes from the map: the most lanes side by side in one direction.
        most = max(len(road.siblings(k)) for k in road.lanes)
        out["lanes_count"] = min(most, int(rules(EnvConfig)["lanes_count"].hi))
    LineSensorConfig(**out["sensor"])
    params = cfg["detector_params"]
    if not isinstance(params, Mapping):
        raise ConfigError("config['detector_params'] must be a mapping")
    if params and out["detector"] != "aldm":
        raise ConfigError("config['detector_params'] is only used with detector='aldm'")
    bad = [k for k in params if not isinstance(k, str)]
    if bad:
        raise ConfigError(f"detector_params keys must be strings, got {bad!r}")
    if params:
        make_detector(out["detector"], params)
    out["detector_params"] = dict(params)
    return out


def _check_vehicle_class(path: str) -> None:
    """``other_vehicles_type`` names an importable highway-env vehicle class.

    :raises ConfigError: naming the key, when the path does not resolve to a subclass
        of highway-env's ``Vehicle`` with ``create_random`` and ``randomize_behavior``.
    """
    from highway_env.vehicle.kinematics import Vehicle

    module, _, name = path.rpartition(".")
    try:
        cls = getattr(importlib.import_module(module), name) if module else None
    except (ImportError, AttributeError, ValueError) as exc:
        raise ConfigError(
            f"config.other_vehicles_type {path!r} cannot be imported ({exc})"
        ) from None
    ok = isinstance(cls, type) and issubclass(cls, Vehicle)
    if not ok or not all(hasattr(cls, m) for m in ("create_random", "randomize_behavior")):
        raise ConfigError(
            f"config.other_vehicles_type must name a highway-env vehicle class with "
            f"create_random and randomize_behavior (e.g. "
            f"{EnvConfig.other_vehicles_type!r}), got {path!r}"
        )


def road_config(cfg: Mapping[str, Any], seed: int) -> RoadConfig:
    """The :class:`~aldm_gym.roads.RoadConfig` of a validated env config.

    ``road.seed`` may be ``None``: the caller then passes a seed drawn from the
    environment's ``np_random``.
    """
    road = dict(cfg["road"])
    road["lanes_count"] = cfg["lanes_count"]
    road["marking_model"] = cfg["marking_model"]
    if road.get("seed", 0) is None:
        road["seed"] = seed
    return RoadConfig(**road)


def map_config(cfg: Mapping[str, Any]) -> MapConfig | None:
    """The :class:`MapConfig` of a config whose ``road.xodr`` is set, else ``None``.

    :raises ConfigError: naming a generator key given with ``road.xodr`` (it does not
        apply to maps), or a map key given without it.
    """
    road = dict(cfg["road"])
    if road.get("xodr") is None:
        road.pop("xodr", None)
        stray = sorted(k for k in road if k in MAP_KEYS)
        if stray:
            raise ConfigError(f"road key(s) {stray} apply only to maps: set road.xodr too")
        return None
    road.pop("marking_model", None)  # the top-level key's value (checked to agree)
    generator = sorted(k for k in road if k not in MAP_KEYS)
    if generator:
        raise ConfigError(
            f"road key(s) {generator} do not apply to maps (road.xodr is set); "
            f"a map takes only {list(MAP_KEYS)} (and the top-level marking_model)"
        )
    return MapConfig(**road)


def map_road(cfg: Mapping[str, Any]) -> OpenDriveRoad | None:
    """The map road of a config with ``road.xodr`` (cached per file content), else ``None``.

    :raises FileNotFoundError: naming the file.
    :raises ConfigError: as :func:`map_config`, or the reader's error naming file, road
        and element.
    """
    mc = map_config(cfg)
    if mc is None:
        return None
    return OpenDriveRoad.from_file(
        mc.xodr,
        marking_model=cfg["marking_model"],
        broken_pattern=tuple(mc.broken_pattern),
        sample_step=mc.sample_step,
    )
