"""Validated configuration of :class:`~aldm_gym.envs.highway.ALDMHighwayEnv`.

highway-env keeps an environment's configuration in a plain ``dict`` and merges user
dicts into it without checking (``AbstractEnv.configure``), so a misspelled key is
silently ignored. Here every key is declared once, with its default and its rule, in
a config dataclass (:mod:`aldm_gym.config`), and a configuration is validated into
one tree of them, :class:`EnvConfig`, the env's ``settings``:

=====================  =============================================================
section                the settings dataclass (``settings.<section>``)
=====================  =============================================================
top level              :class:`EnvConfig` (below)
``action``             :class:`aldm_gym.envs.actions.ActionConfig`
``observation``        :class:`aldm_gym.envs.observation.ObservationConfig`
``lka``                :class:`aldm_gym.envs.control.LKAConfig`
``acc``                :class:`aldm_gym.envs.longitudinal.ACCConfig`
``lane_end``           :class:`aldm_gym.envs.lane_end.LaneEndConfig` (lanes that end)
``traffic``            :class:`aldm_gym.envs.traffic.mix.TrafficConfig` (trucks)
``sensor``             :class:`aldm_gym.sensor.line_sensor.LineSensorConfig`
``road``               :class:`aldm_gym.roads.highway.RoadConfig`, or :class:`MapConfig`
                       with ``road.xodr`` (an OpenDRIVE map)
``detector_params``    the detector's own parameters (a read-only dict, checked by
                       :mod:`aldm_gym.sensor.detectors`)
``scenario``           :class:`aldm_gym.scenario.ScenarioConfig` (an OpenSCENARIO
                       file to play)
``osi``                :class:`aldm_gym.osi.OsiConfig` (an ASAM OSI trace to write)
=====================  =============================================================

:func:`parse_config` validates a complete configuration once: unknown keys (named,
with the allowed ones and the nearest match; :func:`aldm_gym.config.check_keys`) and
impossible values raise :class:`~aldm_gym.errors.ConfigError`, and the result is the
settings tree plus the plain-``dict`` view highway-env's ``AbstractEnv`` reads
(``env.config``, read-only: :class:`ConfigView`). Validation reads no file; the env
reads a map (:func:`load_map`) right after, when it is configured. The keys keep
highway-env's meaning where highway-env has them (``lanes_count``, ``vehicles_count``,
``vehicles_density``, ``duration``, ``simulation_frequency``, ``policy_frequency``,
``initial_lane_id``, ``ego_spacing``, the reward weights, the rendering keys); the rest
are aldm-gym's. The full table is in ``docs/env.md``.
"""

from __future__ import annotations

import copy
import dataclasses
import importlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from aldm_gym.config import Rule, check_keys, rules, section, setting, validate
from aldm_gym.envs.actions import ACTION_TYPES, ActionConfig
from aldm_gym.envs.control import LKAConfig
from aldm_gym.envs.lane_end import LaneEndConfig
from aldm_gym.envs.longitudinal import ACCConfig
from aldm_gym.envs.observation import ObservationConfig
from aldm_gym.envs.traffic.mix import TrafficConfig
from aldm_gym.errors import ConfigError, ScenarioError
from aldm_gym.osi.settings import OsiConfig
from aldm_gym.roads.highway import MARKING_MODELS, RoadConfig
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.roads.opendrive import DEFAULT_BROKEN_PATTERN, DEFAULT_SAMPLE_STEP
from aldm_gym.scenario.settings import ScenarioConfig
from aldm_gym.sensor.detectors import DETECTORS, make_detector
from aldm_gym.sensor.line_sensor import LineSensorConfig

__all__ = [
    "ACTION_TYPES",
    "ALLOWED_KEYS",
    "DETECTORS",
    "MARKING_MODELS",
    "SECTIONS",
    "ConfigView",
    "EnvConfig",
    "EnvOverrides",
    "MapConfig",
    "default_config",
    "env_overrides",
    "load_map",
    "merge_config",
    "parse_config",
    "validate_config",
]


def _reward(default: float) -> Any:
    return setting(default, lo=-100.0, hi=100.0)


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


@dataclass(frozen=True)
class EnvConfig:
    """The env's validated settings: the top-level keys and one dataclass per section.

    ``env.settings`` is one of these, built once per ``configure``; the env and its
    parts read it by attribute (``settings.acc.range``, ``settings.duration``). Built
    from a mapping (:func:`parse_config`), a section given as a mapping is validated
    into its dataclass here (unknown keys named); ``road`` becomes a
    :class:`~aldm_gym.roads.highway.RoadConfig` carrying the top-level ``lanes_count``
    and ``marking_model`` (``road.seed = None``: the env draws a seed at each reset), or
    a :class:`MapConfig` when ``road.xodr`` is set.

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
    ``overtaking_reward``,
    ``departure_reward``, ``departure_terminal``, ``info_metrics`` (``info["lane_metrics"]``,
    :mod:`aldm_gym.sensor.lane_metrics`), and the sections ``detector_params``,
    ``sensor``, ``road``, ``lka``, ``acc`` (ACC and AEB), ``traffic`` (trucks),
    ``scenario`` (an OpenSCENARIO file to play), ``osi`` (an ASAM OSI trace to write).
    Meanings: ``docs/env.md``.
    """

    # --- highway-env: AbstractEnv
    observation: ObservationConfig = section(ObservationConfig)
    action: ActionConfig = section(ActionConfig)
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
    detector_params: Mapping[str, Any] = dataclasses.field(
        default_factory=lambda: ConfigView(), metadata={"rule": Rule(kind="any")}
    )
    sensor: LineSensorConfig = section(LineSensorConfig)
    road: RoadConfig | MapConfig = dataclasses.field(
        default=None,  # type: ignore[assignment]  (built in __post_init__)
        metadata={"rule": Rule(kind="any")},
    )
    lka: LKAConfig = section(LKAConfig)
    acc: ACCConfig = section(ACCConfig)
    lane_end: LaneEndConfig = section(LaneEndConfig)
    traffic: TrafficConfig = section(TrafficConfig)
    scenario: ScenarioConfig = section(ScenarioConfig)
    osi: OsiConfig = section(OsiConfig)
    progress_reward: float = _reward(0.2)
    lane_keeping_reward: float = _reward(0.3)
    departure_reward: float = _reward(-0.5)
    overtaking_reward: float = _reward(0.0)
    departure_terminal: bool = setting(False)
    info_metrics: bool = setting(False)

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
        _check_vehicle_class(self.other_vehicles_type)
        for name, cls in SECTIONS.items():
            value = getattr(self, name)
            if not isinstance(value, cls):
                object.__setattr__(self, name, _build_section(name, cls, value))
        if not isinstance(self.road, RoadConfig | MapConfig):
            object.__setattr__(self, "road", self._road_section(self.road))
        elif isinstance(self.road, RoadConfig):
            for key in ("lanes_count", "marking_model"):
                if getattr(self.road, key) != getattr(self, key):
                    raise ConfigError(
                        f"road.{key} ({getattr(self.road, key)!r}) contradicts "
                        f"config[{key!r}] ({getattr(self, key)!r})"
                    )
        object.__setattr__(self, "detector_params", self._detector_params(self.detector_params))
        if self.scenario.enabled and isinstance(self.road, MapConfig):
            raise ConfigError(
                "road.xodr and scenario.xosc are both set: a scenario brings its own map "
                "(RoadNetwork/LogicFile); drop road.xodr"
            )

    def _road_section(self, given: Any) -> RoadConfig | MapConfig:
        """The ``road`` mapping as a :class:`RoadConfig` (with the top-level
        ``lanes_count`` and ``marking_model``) or, with ``xodr``, a :class:`MapConfig`."""
        road = {} if given is None else dict(_mapping("road", given))  # None: the default
        check_keys("road", road, tuple(f.name for f in dataclasses.fields(RoadConfig)) + MAP_KEYS)
        for key in ("lanes_count", "marking_model"):
            if key in road and road[key] != getattr(self, key):
                raise ConfigError(
                    f"config['road'][{key!r}] ({road[key]!r}) contradicts config[{key!r}] "
                    f"({getattr(self, key)!r}); set the top-level key only"
                )
        if road.get("xodr") is None:
            road.pop("xodr", None)
            stray = sorted(k for k in road if k in MAP_KEYS)
            if stray:
                raise ConfigError(f"road key(s) {stray} apply only to maps: set road.xodr too")
            road["lanes_count"] = self.lanes_count
            road["marking_model"] = self.marking_model
            return RoadConfig(**road)
        road.pop("marking_model", None)  # the top-level key's value (checked to agree)
        generator = sorted(k for k in road if k not in MAP_KEYS)
        if generator:
            raise ConfigError(
                f"road key(s) {generator} do not apply to maps (road.xodr is set); "
                f"a map takes only {list(MAP_KEYS)} (and the top-level marking_model)"
            )
        return MapConfig(**road)

    def _detector_params(self, given: Any) -> Mapping[str, Any]:
        """``detector_params`` checked by the detector it configures, read-only."""
        params = dict(_mapping("detector_params", given))
        if params and self.detector != "aldm":
            raise ConfigError("config['detector_params'] is only used with detector='aldm'")
        bad = [k for k in params if not isinstance(k, str)]
        if bad:
            raise ConfigError(f"detector_params keys must be strings, got {bad!r}")
        if params:
            make_detector(self.detector, params)
        return ConfigView(params)

    @property
    def on_map(self) -> bool:
        """Whether the env drives on an OpenDRIVE map (``road.xodr`` or a scenario set)."""
        return isinstance(self.road, MapConfig) or self.scenario.enabled

    def road_config(self, seed: int) -> RoadConfig:
        """The generated road's :class:`RoadConfig`; ``seed`` replaces a ``None`` seed
        (the env passes one drawn from its ``np_random``).

        :raises ConfigError: on a map (there is no generated road).
        """
        if not isinstance(self.road, RoadConfig):
            raise ConfigError("road_config: the env drives on a map (road.xodr is set)")
        if self.road.seed is None:
            return dataclasses.replace(self.road, seed=seed)
        return self.road


def _mapping(name: str, value: Any) -> Mapping[str, Any]:
    """``value`` as a mapping, or a :class:`ConfigError` naming it."""
    if not isinstance(value, Mapping):
        raise ConfigError(f"config[{name!r}] must be a mapping, got {type(value).__name__}")
    return value


def _build_section(name: str, cls: type, value: Any) -> Any:
    """A section's dataclass from the mapping given for it (unknown keys named)."""
    section = _mapping(name, value)
    check_keys(name, section, tuple(f.name for f in dataclasses.fields(cls)))
    return cls(**section)


SECTIONS: dict[str, Any] = {
    "observation": ObservationConfig,
    "action": ActionConfig,
    "lka": LKAConfig,
    "acc": ACCConfig,
    "lane_end": LaneEndConfig,
    "traffic": TrafficConfig,
    "sensor": LineSensorConfig,
    "scenario": ScenarioConfig,
    "osi": OsiConfig,
}
"""The config sections declared by one dataclass each (``road`` is a
:class:`~aldm_gym.roads.highway.RoadConfig` or a :class:`MapConfig`;
``detector_params`` is the detector's)."""

_GIVEN_SECTIONS = ("sensor", "road", "detector_params")
"""Sections the dict view holds as given (only the keys set), not complete: ``road``
takes ``lanes_count``/``marking_model`` from the top level, so a complete one would
contradict a later change of those."""

ALLOWED_KEYS: tuple[str, ...] = tuple(sorted(f.name for f in dataclasses.fields(EnvConfig)))
"""Every top-level key the environment accepts."""


class ConfigView(dict):  # type: ignore[type-arg]
    """A read-only ``dict``: the env's validated configuration as highway-env reads it
    (``env.config``).

    aldm-gym reads ``env.settings`` (:class:`EnvConfig`); assigning into this view would
    change nothing, so it raises :class:`~aldm_gym.errors.ConfigError` saying how to
    change a setting. Copies (``dict(view)``, ``copy.deepcopy``) are plain dicts.
    """

    def _read_only(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise ConfigError(
            "env.config is the validated configuration, read-only: change settings with "
            "env.unwrapped.configure({...}) and reset(), or pass them to "
            "gymnasium.make('ALDMHighway-v0', config={...})"
        )

    __setitem__ = _read_only
    __delitem__ = _read_only
    __ior__ = _read_only
    clear = _read_only
    pop = _read_only
    popitem = _read_only
    setdefault = _read_only
    update = _read_only

    def __copy__(self) -> dict[str, Any]:
        return dict(self)

    def __deepcopy__(self, memo: dict[int, Any]) -> dict[str, Any]:
        return {k: copy.deepcopy(v, memo) for k, v in self.items()}

    def __reduce__(self) -> tuple[Any, ...]:
        return (ConfigView, (dict(self),))


def _view(settings: EnvConfig, given: Mapping[str, Any]) -> ConfigView:
    """The dict view of ``settings``: top-level values, complete sections (as dicts)
    except :data:`_GIVEN_SECTIONS`, which hold what ``given`` set."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(EnvConfig):
        if f.name in _GIVEN_SECTIONS:
            out[f.name] = ConfigView(copy.deepcopy(dict(given[f.name] or {})))
        elif f.name in SECTIONS:
            out[f.name] = ConfigView(dataclasses.asdict(getattr(settings, f.name)))
        else:
            out[f.name] = getattr(settings, f.name)
    return ConfigView(out)


class EnvOverrides(ConfigView):
    """Env settings that differ from the defaults, validated once, where they are made.

    What passes from the command line, a training, the agents and the scenario harness
    into ``gymnasium.make("ALDMHighway-v0", config=overrides)``: a read-only ``dict`` of
    the settings given (sections hold only their keys given, as in ``gym.make``'s
    ``config``), JSON-ready as it is, and the :class:`EnvConfig` they make. The env
    takes that :class:`EnvConfig` without validating again; a plain ``dict`` keeps
    working for users and is validated by the env.

    :param overrides: env settings (a section's keys one by one), or None.
    :raises ConfigError: naming an unknown key (with the allowed ones) or a bad value.
    """

    __slots__ = ("_settings",)

    def __init__(self, overrides: Mapping[str, Any] | None = None) -> None:
        tree = merged_config({}, overrides)
        settings, _ = parse_config(merged_config(default_config(), tree))
        dict.__init__(
            self, {k: ConfigView(v) if isinstance(v, dict) else v for k, v in tree.items()}
        )
        self._settings = settings

    @property
    def settings(self) -> EnvConfig:
        """The complete settings these overrides make (shared: read, never modify)."""
        return self._settings

    def parsed(self) -> tuple[EnvConfig, ConfigView]:
        """``(settings, view)`` as :func:`parse_config` returns them, copies the caller
        may complete (the env sets a map's lane count on its own)."""
        settings = copy.deepcopy(self._settings)  # lists in it (centering_position) too
        return settings, _view(settings, {**dict.fromkeys(_GIVEN_SECTIONS), **self})

    def merged(self, update: Mapping[str, Any] | None) -> EnvOverrides:
        """These overrides updated with ``update`` (sections key by key), validated.

        :raises ConfigError: as the constructor.
        """
        if not update:
            return self
        return EnvOverrides(merged_config(self, update))

    def without(self, *keys: str) -> EnvOverrides:
        """These overrides without the top-level ``keys`` (their defaults apply)."""
        if not set(keys) & set(self):
            return self
        return EnvOverrides({k: v for k, v in self.items() if k not in keys})

    def to_dict(self) -> dict[str, Any]:
        """A plain, nested ``dict`` copy (for a file, or to edit)."""
        return copy.deepcopy(dict(self))

    def __repr__(self) -> str:
        return f"EnvOverrides({self.to_dict()!r})"

    def __copy__(self) -> EnvOverrides:
        return self

    def __deepcopy__(self, memo: dict[int, Any]) -> EnvOverrides:  # type: ignore[override]
        return self

    def __reduce__(self) -> tuple[Any, ...]:
        return (EnvOverrides, (self.to_dict(),))


def env_overrides(config: Mapping[str, Any] | None) -> EnvOverrides:
    """``config`` as :class:`EnvOverrides` (itself if it is one; validated otherwise).

    :raises ConfigError: as :class:`EnvOverrides`.
    """
    if isinstance(config, EnvOverrides):
        return config
    return EnvOverrides(config)


def default_config() -> dict[str, Any]:
    """The default configuration (a fresh, plain dict): :class:`EnvConfig` with its
    sections."""
    settings = EnvConfig()
    return copy.deepcopy(_view(settings, dict.fromkeys(_GIVEN_SECTIONS)))


def merge_config(base: Mapping[str, Any], update: Mapping[str, Any] | None) -> dict[str, Any]:
    """``base`` updated with ``update``, section dicts merged key by key, then validated
    (:func:`validate_config`).

    :raises ConfigError: naming any unknown key (with the allowed ones) or bad value.
    """
    return parse_config(merged_config(base, update))[1]


def merged_config(base: Mapping[str, Any], update: Mapping[str, Any] | None) -> dict[str, Any]:
    """``base`` updated with ``update`` (section dicts merged key by key), unvalidated.

    :raises ConfigError: ``update`` is not a mapping, has an unknown top-level key, or
        gives a section as something other than a mapping.
    """
    out = copy.deepcopy(dict(base))
    if update is None:
        return out
    if not isinstance(update, Mapping):
        raise ConfigError(f"config must be a mapping, got {type(update).__name__}")
    check_keys("config", update, ALLOWED_KEYS)
    for key, value in update.items():
        if key in (*SECTIONS, *_GIVEN_SECTIONS):
            merged = dict(out.get(key) or {})
            merged.update(copy.deepcopy(dict(_mapping(key, value))))
            out[key] = merged
        else:
            out[key] = copy.deepcopy(value)
    return out


def parse_config(config: Mapping[str, Any]) -> tuple[EnvConfig, ConfigView]:
    """Validate a complete configuration (every top-level key present), once.

    No file is read: a map's ``road.xodr`` is only checked to be a path here
    (:func:`load_map` reads it).

    :return: ``(settings, view)``: the settings tree and the read-only dict view of it
        that highway-env's ``AbstractEnv`` reads.
    :raises ConfigError: unknown keys (top level or in a section), naming the allowed
        ones, or a value out of its range / not among its choices.
    """
    cfg = dict(config)
    check_keys("config", cfg, ALLOWED_KEYS)
    missing = sorted(k for k in ALLOWED_KEYS if k not in cfg)
    if missing:
        raise ConfigError(f"config is missing key(s) {missing}")
    settings = EnvConfig(**cfg)
    return settings, _view(settings, cfg)


def validate_config(config: Mapping[str, Any]) -> dict[str, Any]:
    """Check a complete configuration; return its dict view (:func:`parse_config`).

    :raises ConfigError: as :func:`parse_config`.
    """
    return parse_config(config)[1]


def read_config_scenario(settings: EnvConfig) -> Any:
    """The scenario ``scenario.xosc`` names, read with ``scenario.parameters``.

    :raises ScenarioError: the file is missing (the message names the config key) or
        the player cannot play it (the message names file, line and element).
    """
    from aldm_gym.scenario import read_scenario

    xosc = settings.scenario.xosc
    if not Path(xosc).is_file():
        where = "" if Path(xosc).is_absolute() else f" (relative to {os.getcwd()!r})"
        raise ScenarioError(f"scenario.xosc={xosc!r}: no such scenario file{where}")
    return read_scenario(xosc, settings.scenario.parameters)


def load_map(settings: EnvConfig, scenario: Any = None) -> OpenDriveRoad | None:
    """The map road of settings with ``road.xodr`` or a scenario (its ``LogicFile``;
    ``scenario``: the scenario already read, else it is read here), read once per file
    content and cached; else ``None``.

    :raises MapNotFoundError: naming the file.
    :raises MapError: the reader's error naming file, road and element.
    """
    road = settings.road
    if settings.scenario.enabled:
        if scenario is None:
            scenario = read_config_scenario(settings)
        return OpenDriveRoad.from_file(str(scenario.map_path), marking_model=settings.marking_model)
    if not isinstance(road, MapConfig):
        return None
    return OpenDriveRoad.from_file(
        road.xodr,
        marking_model=settings.marking_model,
        broken_pattern=tuple(road.broken_pattern),
        sample_step=road.sample_step,
    )


def map_lanes_count(road: OpenDriveRoad) -> int:
    """The env's ``lanes_count`` on a map: the most driving lanes side by side in one
    direction (at most ``lanes_count``'s upper bound)."""
    most = max(len(road.siblings(k)) for k in road.lanes)
    return min(most, int(rules(EnvConfig)["lanes_count"].hi))


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
