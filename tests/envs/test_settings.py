"""One settings object: validated once per ``configure``, read by attribute; the dict
view highway-env reads is read-only."""

from __future__ import annotations

import copy
import dataclasses
import pickle
from typing import Any

import gymnasium as gym
import pytest

import aldm_gym  # noqa: F401  (registers ALDMHighway-v0)
from aldm_gym.envs import config as env_config
from aldm_gym.envs.config import SECTIONS, ConfigView, EnvConfig, MapConfig, parse_config
from aldm_gym.errors import ConfigError
from aldm_gym.roads import RoadConfig, shipped_map


def _env(**config: Any) -> Any:
    return gym.make("ALDMHighway-v0", config={"vehicles_count": 3, **config}).unwrapped


def test_settings_are_one_tree_of_the_section_dataclasses() -> None:
    env = _env(acc={"range": 120.0}, road={"seed": None, "min_radius": 800.0})
    s = env.settings
    assert isinstance(s, EnvConfig)
    for name, cls in SECTIONS.items():
        assert isinstance(getattr(s, name), cls), name
    assert s.acc.range == 120.0 and env.config["acc"]["range"] == 120.0
    assert isinstance(s.road, RoadConfig)
    assert (s.road.min_radius, s.road.seed, s.road.lanes_count) == (800.0, None, 4)
    assert s.road_config(7).seed == 7  # the env draws the seed at each reset
    assert dict(s.detector_params) == {}


def test_the_env_reads_no_section_again_after_configure(monkeypatch: pytest.MonkeyPatch) -> None:
    """Reset and step build no section dataclass: the settings are parsed once."""
    env = _env()
    built: list[str] = []
    for cls in (*SECTIONS.values(), RoadConfig):
        init = cls.__init__

        def counting(self: Any, *args: Any, _init: Any = init, **kwargs: Any) -> None:
            built.append(type(self).__name__)
            _init(self, *args, **kwargs)

        monkeypatch.setattr(cls, "__init__", counting)
    env.reset(seed=0)
    env.step(1)
    assert built == []
    env.configure({"acc": {"range": 90.0}})
    assert "ACCConfig" in built and env.settings.acc.range == 90.0


def test_the_config_view_is_read_only_and_says_how_to_change_it() -> None:
    env = _env()
    assert isinstance(env.config, ConfigView) and isinstance(env.config, dict)
    with pytest.raises(ConfigError, match=r"read-only.*configure\(\{\.\.\.\}\)"):
        env.config["vehicles_count"] = 5
    with pytest.raises(ConfigError, match="read-only"):
        env.config["acc"]["range"] = 5.0
    with pytest.raises(ConfigError, match="read-only"):
        env.config.update({"duration": 3.0})
    plain = copy.deepcopy(env.config)
    assert type(plain) is dict and type(plain["acc"]) is dict and plain == env.config
    assert pickle.loads(pickle.dumps(env.config)) == env.config
    env.configure({"vehicles_count": 5})
    assert env.config["vehicles_count"] == 5 == env.settings.vehicles_count


def test_settings_with_a_map_take_its_lane_count_and_read_it_once() -> None:
    env = _env(road={"xodr": str(shipped_map("two_plus_one"))})
    assert isinstance(env.settings.road, MapConfig) and env.settings.on_map
    assert env.settings.lanes_count == env.config["lanes_count"] == 2


def test_parsing_reads_no_file(monkeypatch: pytest.MonkeyPatch) -> None:
    """Validation is pure: a map path is only checked to be a path; the env reads it."""
    monkeypatch.setattr(env_config.OpenDriveRoad, "from_file", None)  # any read would fail
    settings, view = parse_config(
        env_config.merged_config(env_config.default_config(), {"road": {"xodr": "nowhere.xodr"}})
    )
    assert settings.road == MapConfig(xodr="nowhere.xodr") and view["road"] == {
        "xodr": "nowhere.xodr"
    }


@pytest.mark.parametrize(
    ("config", "match"),
    [
        ({"acc": {"time_gapp": 1.0}}, r"unknown acc key\(s\) \['time_gapp'\].*'time_gap'"),
        ({"road": {"seeed": 1}}, r"unknown road key\(s\) \['seeed'\].*'seed'"),
        ({"acc": 3}, r"config\['acc'\] must be a mapping"),
        ({"road": {"lanes_count": 3}}, r"contradicts config\['lanes_count'\]"),
        ({"road": {"xodr": "m.xodr", "seed": 1}}, r"do not apply to maps"),
    ],
)
def test_section_errors_name_the_key(config: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        _env(**config)


def test_settings_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        _env().settings.duration = 3.0  # type: ignore[misc]


@pytest.mark.parametrize("section", ["acc", "sensor", "road", "detector_params", "lka"])
def test_a_section_given_as_none_is_an_error(section: str) -> None:
    message = rf"config\['{section}'\] must be a mapping, got NoneType"
    with pytest.raises(ConfigError, match=message):
        env_config.merged_config(env_config.default_config(), {section: None})


def test_a_road_config_must_agree_with_the_top_level_keys() -> None:
    road = RoadConfig(lanes_count=2, marking_model="editor")
    with pytest.raises(ConfigError, match=r"road.lanes_count \(2\) contradicts"):
        EnvConfig(lanes_count=4, road=road)
    assert EnvConfig(lanes_count=2, marking_model="editor", road=road).road is road
