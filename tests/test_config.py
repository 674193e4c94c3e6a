"""The declarative config validator and the env's config sections."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pytest

from aldm_gym.config import rules, setting, validate
from aldm_gym.envs.actions import ActionConfig
from aldm_gym.envs.config import (
    ALLOWED_KEYS,
    SECTIONS,
    EnvConfig,
    default_config,
    merge_config,
)
from aldm_gym.envs.control import LKAConfig, LKAController
from aldm_gym.roads.highway import RoadConfig
from aldm_gym.sensor.line_sensor import LineSensorConfig


@dataclass(frozen=True)
class _Demo:
    n: int = setting(3, lo=1, hi=10, integer=True)
    lo: float = setting(1.0, lo=0.0)
    hi: float = setting(2.0, lo="lo", hi=100.0)
    flag: bool = setting(False)
    mode: str = setting("a", choices=("a", "b"))
    pair: tuple[float, float] = setting((1.0, 2.0), kind="pair", lo=0.0, hi=10.0)
    speeds: list[float] = setting([1.0, 2.0], lo=0.0, hi=5.0, increasing=True)
    maybe: float | None = setting(None, lo=0.0, hi=1.0, optional=True)

    def __post_init__(self) -> None:
        validate(self, "demo")


def test_defaults_pass_and_lists_are_not_shared() -> None:
    a, b = _Demo(), _Demo()
    assert a == b
    assert a.speeds is not b.speeds


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n": 0}, r"demo\.n must be >= 1"),
        ({"n": 11}, r"demo\.n must be <= 10"),
        ({"n": 2.5}, r"demo\.n must be an integer"),
        ({"n": "3"}, r"demo\.n must be a finite number"),
        ({"n": True}, r"demo\.n must be a finite number"),
        ({"lo": float("nan")}, r"demo\.lo must be a finite number"),
        ({"lo": float("inf")}, r"demo\.lo must be a finite number"),
        ({"lo": 5.0, "hi": 4.0}, r"demo\.hi must be >= 5\.0"),
        ({"flag": 1}, r"demo\.flag must be a bool"),
        ({"mode": "c"}, r"demo\.mode must be one of \['a', 'b'\]"),
        ({"pair": (3.0, 1.0)}, r"demo\.pair must be \(min, max\)"),
        ({"pair": (1.0,)}, r"demo\.pair must be a \(min, max\) pair"),
        ({"speeds": []}, r"demo\.speeds must be a non-empty list"),
        ({"speeds": [2.0, 1.0]}, r"demo\.speeds must be increasing"),
        ({"speeds": [1.0, 9.0]}, r"demo\.speeds\[1\] must be <= 5\.0"),
        ({"speeds": "12"}, r"demo\.speeds must be a sequence of numbers"),
        ({"maybe": 2.0}, r"demo\.maybe must be <= 1\.0"),
    ],
)
def test_rules_reject_bad_values_naming_the_key(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _Demo(**kwargs)


def test_numpy_scalars_become_plain_numbers() -> None:
    d = _Demo(n=np.int64(4), lo=np.float32(0.5), flag=np.bool_(True), pair=[np.int64(1), 3])
    assert type(d.n) is int and d.n == 4
    assert type(d.lo) is float and d.lo == 0.5
    assert d.flag is True
    assert d.pair == (1.0, 3.0) and all(type(v) is float for v in d.pair)
    assert _Demo(n=3.0).n == 3 and type(_Demo(n=3.0).n) is int


def test_every_section_field_declares_a_rule() -> None:
    for cls in (EnvConfig, *SECTIONS.values()):
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
