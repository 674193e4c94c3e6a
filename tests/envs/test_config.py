"""The env's config sections (aldm_gym.envs.config): every key declared with a rule,
defaults in one place, errors that name the key."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from aldm_gym.config import rules
from aldm_gym.envs.actions import ActionConfig
from aldm_gym.envs.config import (
    ALLOWED_KEYS,
    SECTIONS,
    EnvConfig,
    MapConfig,
    default_config,
    merge_config,
)
from aldm_gym.envs.control import LKAConfig, LKAController
from aldm_gym.errors import ConfigError
from aldm_gym.roads.highway import RoadConfig
from aldm_gym.sensor.line_sensor import LineSensorConfig


def test_every_section_field_declares_a_rule() -> None:
    for cls in (EnvConfig, *SECTIONS.values(), RoadConfig, MapConfig):
        missing = [f.name for f in dataclasses.fields(cls) if f.name not in rules(cls)]
        assert not missing, (cls.__name__, missing)


def test_defaults_live_in_the_config_classes() -> None:
    cfg = default_config()
    assert sorted(cfg) == list(ALLOWED_KEYS)
    assert cfg["action"] == dataclasses.asdict(ActionConfig())
    assert cfg["lka"]["path_range"] == LKAConfig.path_range == 80.0
    lka = LKAController()
    assert lka.lookahead_time == LKAConfig.lookahead_time
    assert lka.sensor_x == LineSensorConfig.mount_x
    assert cfg["vehicles_count"] == EnvConfig.vehicles_count


@pytest.mark.parametrize(
    ("update", "match"),
    [
        ({"lanes_count": np.int64(3)}, None),
        ({"vehicles_count": np.int32(5), "duration": np.float64(10.0)}, None),
        ({"vehicle_count": 3}, r"did you mean 'vehicles_count'\?"),
        ({"action": {"target_speed": [20.0]}}, r"did you mean 'target_speeds'\?"),
        ({"road": {"seed": 3.5}}, r"road\.seed must be an integer"),
        ({"road": {"segments": 5}}, r"road\.segments must be a sequence"),
        ({"road": {"segments": [[100.0, 0.0]]}}, r"road\.segments\[0\]"),
        ({"road": {"curved": "yes"}}, r"road\.curved must be a bool"),
        ({"scaling": 33789}, r"config\.scaling must be <= 100"),
        ({"screen_width": -5}, r"config\.screen_width must be >= 16"),
        ({"reward_speed_range": [20.0, 20.001]}, r"reward_speed_range"),
        ({"initial_lane_id": 4}, r"initial_lane_id must be < lanes_count"),
        ({"other_vehicles_type": "no.such.Module"}, r"other_vehicles_type .*cannot be imported"),
        ({"other_vehicles_type": "os.path"}, r"other_vehicles_type"),
        ({"other_vehicles_type": ""}, r"other_vehicles_type"),
        (
            {"other_vehicles_type": "highway_env.vehicle.kinematics.Vehicle"},
            r"randomize_behavior",
        ),
        ({"detector_params": {3: 1.0}}, r"detector_params keys must be strings"),
        ({"lka": {"path_range": None}}, None),
        ({"lka": {"path_range": 5.0}}, r"lka\.path_range must be >= 10"),
    ],
)
def test_env_config_errors_and_accepted_values(update: dict, match: str | None) -> None:
    base = default_config()
    if match is None:
        merged = merge_config(base, update)
        for key, value in update.items():
            if isinstance(value, dict):
                for k, v in value.items():
                    assert merged[key][k] == v
            else:
                assert merged[key] == value and type(merged[key]) in (int, float)
    else:
        with pytest.raises(ValueError, match=match):
            merge_config(base, update)


@pytest.mark.parametrize("bad", [5, "abc", [("lanes_count", 3)]])
def test_non_mapping_config_is_rejected(bad: object) -> None:
    with pytest.raises(ValueError, match="config must be a mapping"):
        merge_config(default_config(), bad)  # type: ignore[arg-type]


def test_road_config_normalises_to_a_hashable_key() -> None:
    a = RoadConfig(segments=[[500.0, 0, 0.001], (300, 0.001, 0.0)], straight_length=[100, 200])
    b = RoadConfig(segments=((500.0, 0.0, 0.001), (300.0, 0.001, 0.0)), straight_length=(100, 200))
    assert a == b and hash(a) == hash(b)


def test_env_overrides_are_validated_once_read_only_and_plain_at_the_edges() -> None:
    import copy
    import json
    import pickle

    from aldm_gym.envs.config import EnvOverrides, env_overrides

    given = {"detector": "naive", "sensor": {"preset": "camera"}}
    made = EnvOverrides(given)
    assert made == given and json.loads(json.dumps(made)) == given
    assert made.settings.sensor.preset == "camera" and made.settings.detector == "naive"
    assert env_overrides(made) is made and copy.deepcopy(made) is made
    assert pickle.loads(pickle.dumps(made)) == made
    with pytest.raises(ConfigError, match="read-only"):
        made["duration"] = 5.0
    with pytest.raises(ConfigError, match="read-only"):
        made["sensor"]["range"] = 50.0
    plain = made.to_dict()
    plain["sensor"]["range"] = 50.0  # a copy: the overrides stay as made
    assert made["sensor"] == {"preset": "camera"}
    merged = made.merged({"sensor": {"range": 50.0}})
    assert merged["sensor"] == {"preset": "camera", "range": 50.0}
    assert merged.without("sensor") == {"detector": "naive"} and made.without("x") is made
    with pytest.raises(ConfigError, match=r"unknown sensor key\(s\) \['rang'\]"):
        made.merged({"sensor": {"rang": 50.0}})
    with pytest.raises(ConfigError, match="did you mean 'detector'"):
        EnvOverrides({"detectr": "naive"})
    # every env made from one record has its own settings (highway-env moves the
    # centering position in place)
    (a, view_a), (b, view_b) = made.parsed(), made.parsed()
    assert a.centering_position == b.centering_position
    assert a.centering_position is not b.centering_position
    assert view_a["centering_position"] is not made.settings.centering_position
    assert dict(view_a) == dict(view_b)
