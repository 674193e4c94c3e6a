"""One errors module: a caller can tell a typo from a corrupt map or bad data by kind,
and code that caught the built-in exceptions keeps working."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # noqa: F401  (registers ALDMHighway-v0)
from aldm_gym import errors
from aldm_gym.roads import OpenDriveRoad, shipped_map
from aldm_gym.sensor import detect_lanes


@pytest.mark.parametrize(
    ("cls", "builtin"),
    [
        (errors.ConfigError, ValueError),
        (errors.InputError, ValueError),
        (errors.OffRoadError, errors.InputError),
        (errors.MapError, ValueError),
        (errors.MapNotFoundError, FileNotFoundError),
        (errors.CheckpointError, ValueError),
        (errors.ResumeError, errors.CheckpointError),
        (errors.ClusterError, ValueError),
        (errors.OutputLocked, RuntimeError),
        (errors.MissingRLDependencies, ImportError),
        (errors.NumbaCacheWarning, UserWarning),
        (errors.TrainingWarning, UserWarning),
    ],
)
def test_every_error_is_also_the_builtin_it_replaced(cls: type, builtin: type) -> None:
    assert issubclass(cls, builtin)
    if issubclass(cls, Warning):
        assert issubclass(cls, errors.AldmGymWarning)
    else:
        assert issubclass(cls, errors.AldmGymError)


def test_a_config_typo_is_a_config_error() -> None:
    with pytest.raises(errors.ConfigError, match=r"unknown config key\(s\) \['vehicle_count'\]"):
        gym.make("ALDMHighway-v0", config={"vehicle_count": 3})
    with pytest.raises(errors.ConfigError, match=r"sensor\.dropout"):
        gym.make("ALDMHighway-v0", config={"sensor": {"dropout": 1.0}})


def test_a_corrupt_map_is_a_map_error_and_a_missing_one_not_found(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xodr"
    bad.write_text("<OpenDRIVE><road")
    with pytest.raises(errors.MapError, match=r"bad\.xodr:1: malformed XML"):
        OpenDriveRoad.from_file(bad)
    with pytest.raises(errors.MapNotFoundError, match="OpenDRIVE file not found"):
        OpenDriveRoad.from_file(tmp_path / "missing.xodr")


def test_bad_points_are_an_input_error() -> None:
    with pytest.raises(errors.InputError, match=r"shape \(N, 2\) or \(N, 3\)"):
        detect_lanes(np.zeros((4, 5)))


def test_a_position_off_the_map_is_an_off_road_error() -> None:
    road = OpenDriveRoad.from_file(shipped_map("two_plus_one"))
    with pytest.raises(errors.OffRoadError, match="from any driving lane"):
        road.lane_position((1e5, 1e5))
