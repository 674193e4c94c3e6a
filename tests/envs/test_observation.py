"""The observation's parts (aldm_gym.envs.observation)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.envs.observation import (
    LANE_ROWS,
    ObservationConfig,
    build_observation,
    detected_confidence,
    lane_gaps,
    observation_space,
)
from aldm_gym.errors import ConfigError
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.sensor.lane_filter import ModelLaneDetection


def _reference_lane_gaps(codes, x, vx, pd, lengths):  # type: ignore[no-untyped-def]
    """The definition, vectorised: per lane the smallest x >= 0 and the largest x < 0
    (the first index on ties), bumper to bumper, clipped to [0, pd]."""
    reach = 0.5 * (lengths + 5.0)
    out = np.tile(np.array([pd, 0.0, pd, 0.0]), (3, 1))
    for row, code in enumerate(LANE_ROWS):
        mine = codes == code
        ahead = np.flatnonzero(mine & (x >= 0.0))
        if len(ahead):
            i = ahead[np.argmin(x[ahead])]
            out[row, 0] = min(max(x[i] - reach[i], 0.0), pd)
            out[row, 1] = vx[i]
        behind = np.flatnonzero(mine & (x < 0.0))
        if len(behind):
            i = behind[np.argmax(x[behind])]
            out[row, 2] = min(max(-x[i] - reach[i], 0.0), pd)
            out[row, 3] = vx[i]
    return out


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 12), st.integers(0, 2**31 - 1))
def test_lane_gaps_is_the_nearest_vehicle_per_lane(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    codes = rng.integers(0, 4, n).astype(np.float64)
    x = rng.choice([-30.0, -10.0, 0.0, 4.0, 10.0, 60.0, 150.0], n)  # ties on purpose
    vx = rng.normal(0.0, 3.0, n)
    lengths = rng.choice([5.0, 12.0, 18.0], n)
    got = lane_gaps(codes, x, vx, 100.0, lengths)
    np.testing.assert_array_equal(got, _reference_lane_gaps(codes, x, vx, 100.0, lengths))


# ---- line_confidence (opt-in) ------------------------------------------------------

_CHEAP = {"vehicles_count": 5, "duration": 3}
"""A small, short env (as the lane-model filter's env test)."""

_FILTER = {"detector": "aldm", "detector_params": {"tracking": "model"}}

_KEYS = {
    "lines",
    "line_valid",
    "trajectory",
    "trajectory_valid",
    "ego",
    "vehicles",
    "lanes",
    "target",
}
"""The keys without ``line_confidence``: the space models were trained on before it."""


def _with_confidence(**config: Any) -> dict[str, Any]:
    return {**_CHEAP, **config, "observation": {"line_confidence": True}}


def _keys(space: Any) -> set[str]:
    assert isinstance(space, gym.spaces.Dict)
    return set(space.spaces)


def test_line_confidence_is_the_filters_confidence() -> None:
    env = gym.make("ALDMHighway-v0", config=_with_confidence(**_FILTER))
    assert _keys(env.observation_space) == {*_KEYS, "line_confidence"}
    base: Any = env.unwrapped
    obs, _ = env.reset(seed=3)
    for _ in range(3):
        det = base.detection
        assert isinstance(det, ModelLaneDetection)
        assert env.observation_space.contains(obs)
        assert obs["line_confidence"].dtype == np.float32
        np.testing.assert_array_equal(obs["line_confidence"], det.confidence.astype(np.float32))
        # the filter gives a confidence only to the lines it draws
        assert np.all(obs["line_confidence"][obs["line_valid"] == 0.0] == 0.0)
        obs, *_ = env.step(1)
    assert obs["line_confidence"][1] > 0.5 and obs["line_confidence"][2] > 0.5
    env.close()


@pytest.mark.parametrize(
    "config",
    [
        {"detector": "aldm"},
        {"detector": "aldm", "detector_params": {"tracking": True}},
        {"detector": "naive"},
        {"detector": "ground_truth"},
    ],
    ids=["single-frame-aldm", "point-tracker", "naive", "ground-truth"],
)
def test_line_confidence_is_line_valid_without_a_confidence(config: dict[str, Any]) -> None:
    env = gym.make("ALDMHighway-v0", config=_with_confidence(**config))
    base: Any = env.unwrapped
    obs, _ = env.reset(seed=3)
    for _ in range(2):
        assert not hasattr(base.detection, "confidence")
        assert env.observation_space.contains(obs)
        np.testing.assert_array_equal(obs["line_confidence"], obs["line_valid"])
        obs, *_ = env.step(1)
    env.close()


def test_line_confidence_is_off_by_default() -> None:
    assert ObservationConfig().line_confidence is False
    assert observation_space(8, 100.0) == observation_space(8, 100.0, line_confidence=False)
    env = gym.make("ALDMHighway-v0", config={**_CHEAP, **_FILTER})
    assert _keys(env.observation_space) == _KEYS
    obs, _ = env.reset(seed=3)
    assert set(obs) == _KEYS and env.observation_space.contains(obs)
    env.close()


def test_detected_confidence_is_zero_where_no_line_is_valid() -> None:
    line = np.column_stack([np.linspace(5.0, 60.0, 13), np.full(13, 1.8)])
    plain = LaneDetection(ego_left=line)
    valid = np.array([0.0, 1.0, 0.0, 0.0])
    np.testing.assert_array_equal(detected_confidence(plain, valid), valid)
    np.testing.assert_array_equal(detected_confidence(None, np.zeros(4)), np.zeros(4))
    # a confidence given for a line that is not there reads 0, as line_valid does
    modelled = ModelLaneDetection(ego_left=line, confidence=np.array([0.3, 0.9, 0.7, 0.0]))
    np.testing.assert_array_equal(detected_confidence(modelled, valid), [0.0, 0.9, 0.0, 0.0])
    obs = build_observation(
        modelled, np.zeros((0, 2)), np.zeros(4), np.zeros((0, 4)), 2, 100.0, line_confidence=True
    )
    assert obs["line_confidence"].dtype == np.float32
    np.testing.assert_array_equal(
        obs["line_confidence"], np.array([0.0, 0.9, 0.0, 0.0], np.float32)
    )
    assert "line_confidence" not in build_observation(
        modelled, np.zeros((0, 2)), np.zeros(4), np.zeros((0, 4)), 2, 100.0
    )


@pytest.mark.parametrize("value", [1, 0, "yes", None, 0.5])
def test_line_confidence_must_be_a_bool(value: object) -> None:
    with pytest.raises(ConfigError, match=r"observation\.line_confidence must be a bool"):
        ObservationConfig(line_confidence=value)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"observation\.line_confidence must be a bool"):
        gym.make("ALDMHighway-v0", config={"observation": {"line_confidence": value}})
    assert ObservationConfig(line_confidence=np.bool_(True)).line_confidence is True  # type: ignore[arg-type]


def test_line_confidence_trains_with_the_sb3_pipeline() -> None:
    """The training's env stack (``make_vec_env``, ``VecNormalize``, PPO's
    ``MultiInputPolicy``) takes the key: a few steps of learning, then a prediction."""
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from aldm_gym.training.sb3.envs import make_vec_env
    from aldm_gym.training.sb3.policy import NormalizedModel

    venv = VecNormalize(
        make_vec_env(_with_confidence(**_FILTER), 1, 0), norm_reward=False, clip_obs=10.0
    )
    assert "line_confidence" in _keys(venv.observation_space)
    model = PPO("MultiInputPolicy", venv, n_steps=8, batch_size=8, n_epochs=1, device="cpu")
    model.learn(8)
    assert "line_confidence" in _keys(model.observation_space)
    assert venv.obs_rms["line_confidence"].mean.shape == (4,)
    obs: Any = venv.get_original_obs()
    assert obs["line_confidence"].shape == (1, 4)
    action, _ = NormalizedModel(model, venv).predict({k: v[0] for k, v in obs.items()})
    assert venv.action_space.contains(int(action))
    venv.close()
