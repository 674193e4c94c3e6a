"""What a training is: hyperparameters, env config and run settings."""

from __future__ import annotations

import gymnasium as gym
import pytest

from aldm_gym import ENV_ID
from aldm_gym.errors import ConfigError
from aldm_gym.training.record import RunSettings, TrainingRecord, resolve_run
from aldm_gym.training.settings import PPOParams, check_run_settings, env_config


def test_linear_learning_rate_decays_to_zero_over_the_budget() -> None:
    schedule = PPOParams(learning_rate=4e-4, lr_schedule="linear").learning_rate_schedule()
    assert callable(schedule)
    assert [schedule(p) for p in (1.0, 0.5, 0.0)] == [4e-4, 2e-4, 0.0]
    assert PPOParams(lr_schedule="constant").learning_rate_schedule() == 5e-4
    with pytest.raises(ValueError, match="lr_schedule must be one of"):
        PPOParams(lr_schedule="cosine")


def test_a_record_without_a_schedule_trained_with_a_constant_rate() -> None:
    assert PPOParams.saved({"n_steps": 64}) == PPOParams(n_steps=64, lr_schedule="constant")
    assert PPOParams.saved({"lr_schedule": "linear"}).lr_schedule == "linear"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"detector": "canny"}, "detector must be one of"),
        ({"marking_model": "dashed"}, "marking_model must be one of"),
    ],
)
def test_env_config_names_the_bad_setting(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        env_config(**kwargs)


def test_run_settings_restore_the_saved_ones_unless_given() -> None:
    given = {"timesteps": 192, "n_envs": None, "seed": 3}
    run, report = resolve_run(given, None)
    assert run == RunSettings(timesteps=192, seed=3) and report == []

    def record(backend: str, **run: int) -> TrainingRecord:
        return TrainingRecord(backend, "PPO", env_config(), run=RunSettings(**run))

    saved = record("sb3", timesteps=64, n_envs=2, seed=3, checkpoint_freq=64)
    run, report = resolve_run(given, saved)
    assert (run.timesteps, run.n_envs, run.checkpoint_freq) == (192, 2, 64)
    assert report[0].startswith("restored: env config, PPO hyperparameters, n_envs=2, seed=3")
    assert report[1] == "overridden: timesteps=192 (was 64)"
    run, _ = resolve_run({"num_env_runners": None}, record("rllib", seed=5), "rllib")
    assert run == RunSettings(seed=5)


@pytest.mark.parametrize(
    ("name", "value", "least"),
    [("timesteps", 0, 1), ("n_envs", 0, 1), ("num_env_runners", -1, 0), ("validation_freq", -1, 0)],
)
def test_run_settings_below_their_least_value_are_refused(
    name: str, value: int, least: int
) -> None:
    with pytest.raises(ConfigError, match=f"{name} must be >= {least}, got {value}"):
        check_run_settings({name: value})
    check_run_settings({name: least, "seed": -1})


def test_env_overrides_merge_over_the_named_settings() -> None:
    config = env_config(
        "aldm",
        collision_reward=-2.0,
        env_overrides={
            "detector_params": {"tracking": "model"},
            "observation": {"line_confidence": True},
        },
    )
    assert config["collision_reward"] == -2.0
    assert config["detector_params"] == {"tracking": "model"}
    assert config["observation"] == {"line_confidence": True}
    env = gym.make(ENV_ID, config=config)
    try:
        assert "line_confidence" in env.observation_space.spaces
    finally:
        env.close()


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"detector_params": {"trackin": "model"}}, r"\['trackin'\] \(did you mean 'tracking'"),
        ({"sensr": {"preset": "camera"}}, r"unknown config key\(s\) \['sensr'\]"),
        ({"detector": "naive"}, r"may not set \['detector'\]: give them as the training's own"),
        ({"observation": {"line_confidence": "yes"}}, "line_confidence"),
    ],
)
def test_env_overrides_name_the_bad_setting(overrides: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        env_config(env_overrides=overrides)
