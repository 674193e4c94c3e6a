"""The training record: typed, checked once where it is read, the file's layout kept."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from aldm_gym.envs.config import EnvOverrides
from aldm_gym.errors import CheckpointError, ConfigError
from aldm_gym.training.record import RunSettings, TrainingRecord, model_record
from aldm_gym.training.settings import PPOParams, env_config

WRITTEN = {
    "algorithm": "MaskablePPO",
    "backend": "sb3",
    "env_id": "ALDMHighway-v0",
    "env_config": {
        "detector": "aldm",
        "marking_model": "per_dash",
        "collision_reward": -2.0,
        "detector_params": {"tracking": "model"},
    },
    "ppo": {
        "n_steps": 512,
        "batch_size": 64,
        "n_epochs": 10,
        "learning_rate": 0.0009762,
        "gamma": 0.95,
        "gae_lambda": 0.95,
        "ent_coef": 0.001583,
        "clip_range": 0.2,
        "net_arch": [128, 128],
        "lr_schedule": "linear",
    },
    "timesteps": 98304,
    "n_envs": 1,
    "seed": 0,
    "checkpoint_freq": 4096,
    "validation_freq": 4096,
    "validation_episodes": 20,
    "keep_by": "return",
    "pretrain": {"episodes": 2, "epochs": 3, "seeds": [1, 2]},
}
"""A record as a training writes it."""


def test_a_written_record_reads_typed_and_writes_back_the_same_file(tmp_path: Path) -> None:
    path = tmp_path / "training.json"
    path.write_text(json.dumps(WRITTEN, indent=2) + "\n")
    record = TrainingRecord.read(path)
    assert isinstance(record.env_config, EnvOverrides)
    assert record.env_config.settings.detector_params["tracking"] == "model"
    assert record.ppo == PPOParams(
        n_steps=512, learning_rate=0.0009762, gamma=0.95, ent_coef=0.001583
    )
    assert record.run == RunSettings(timesteps=98304)
    assert (record.algorithm, record.keep_by, record.pretrain["epochs"]) == (
        "MaskablePPO",
        "return",
        3,
    )
    assert record.to_dict() == WRITTEN
    assert record.to_json() == path.read_text()
    record.write(tmp_path / "again.json")
    assert TrainingRecord.read(tmp_path / "again.json") == record


def test_sb3_settings_are_refused_in_an_rllib_record() -> None:
    for key, value in (("keep_by", "return"), ("pretrain", {"episodes": 1, "epochs": 1})):
        with pytest.raises(ConfigError, match=f"{key} is an SB3 setting"):
            TrainingRecord.from_dict({"backend": "rllib", "env_config": {}, key: value})


def test_an_older_record_takes_what_it_was_trained_with() -> None:
    record = TrainingRecord.from_dict({"env_config": {}, "ppo": {"n_steps": 64}})
    assert (record.backend, record.algorithm, record.keep_by) == ("sb3", "PPO", "return")
    assert record.ppo.lr_schedule == "constant" and record.run == RunSettings()
    rllib = TrainingRecord.from_dict({"backend": "rllib", "env_config": {}, "num_env_runners": 2})
    assert rllib.keep_by is None and rllib.run_settings == {
        "timesteps": RunSettings.timesteps,
        "num_env_runners": 2,
        "seed": 0,
        "checkpoint_freq": RunSettings.checkpoint_freq,
    }
    assert "n_envs" not in rllib.to_dict() and "keep_by" not in rllib.to_dict()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"timestep": 5}, r"unknown key\(s\) \['timestep'\]; allowed keys: \[.*'timesteps'"),
        ({"backend": "tf"}, "backend must be one of"),
        ({"algorithm": "DQN"}, "algorithm must be one of"),
        ({"env_config": {"detectr": "aldm"}}, "did you mean 'detector'"),
        ({"env_config": []}, "env_config must be an object"),
        ({"ppo": {"n_steps": 10**9}}, r"n_steps must be an integer in \[2, 1000000\]"),
        ({"ppo": {"net_arch": [10**7]}}, "net_arch must be"),
        ({"ppo": {"momentum": 0.9}}, "ppo: .*momentum"),
        ({"timesteps": 0}, r"timesteps must be in \[1, "),
        ({"n_envs": 100_000}, r"n_envs must be in \[1, 64\], got 100000"),
        ({"seed": -5}, r"seed must be in \[0, 2147483647\], got -5"),
        ({"pretrain": {"episodes": "x", "epochs": 3}}, "pretrain.episodes must be an integer"),
        ({"pretrain": {"episodes": 2}}, "pretrain.epochs must be an integer"),
        ({"seed": 1.5}, "seed must be an integer"),
        ({"keep_by": "speed"}, "keep_by must be one of"),
        ({"num_env_runners": 2}, "not run settings of the sb3 backend"),
    ],
)
def test_a_bad_record_is_refused_naming_the_file_and_the_key(
    tmp_path: Path, change: dict[str, Any], message: str
) -> None:
    path = tmp_path / "training.json"
    path.write_text(json.dumps({**WRITTEN, **change}))
    with pytest.raises(CheckpointError, match=f"training.json: not a training record .*{message}"):
        TrainingRecord.read(path)


def test_a_file_that_is_not_a_record_is_refused_before_it_is_parsed(tmp_path: Path) -> None:
    path = tmp_path / "training.json"
    for text in ("", "[1, 2]", "{", "null", "[" * 100_000):
        path.write_text(text)
        with pytest.raises(CheckpointError, match="not a training record"):
            TrainingRecord.read(path)
    path.write_bytes(b" " * (2 << 20))
    with pytest.raises(CheckpointError, match="bytes; a record is at most"):
        TrainingRecord.read(path)
    with pytest.raises(FileNotFoundError, match=r"no training\.json next to"):
        model_record(tmp_path / "elsewhere" / "deeper" / "model.zip")


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=8),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=8,
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    key=st.sampled_from([*WRITTEN, "ppo.n_steps", "ppo.net_arch", "env_config.duration", "x"]),
    value=_JSON,
)
def test_any_value_anywhere_reads_as_a_record_or_a_named_refusal(key: str, value: Any) -> None:
    data = json.loads(json.dumps(WRITTEN))
    section, _, name = key.rpartition(".")
    (data[section] if section else data)[name] = value
    try:
        record = TrainingRecord.from_json(json.dumps(data))
    except ConfigError as exc:
        assert str(exc)
        return
    assert TrainingRecord.from_json(record.to_json()) == record


def test_env_config_of_a_training_is_validated_once_and_taken_by_the_env(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import gymnasium as gym

    from aldm_gym import ENV_ID
    from aldm_gym.envs import config as config_module
    from aldm_gym.envs import highway

    made = env_config("naive", duration=5.0, env_overrides={"sensor": {"preset": "camera"}})
    calls = []
    original = config_module.parse_config
    monkeypatch.setattr(highway, "parse_config", lambda c: calls.append(c) or original(c))
    env = gym.make(ENV_ID, config=made)
    try:
        assert calls == []  # taken as it was validated
        assert env.unwrapped.settings.detector == "naive"
        assert env.unwrapped.settings.sensor.preset == "camera"
        env.unwrapped.configure({"duration": 7.0})  # a later change is validated
        assert len(calls) == 1 and env.unwrapped.settings.duration == 7.0
    finally:
        env.close()
