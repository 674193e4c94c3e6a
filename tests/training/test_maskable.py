"""MaskablePPO (``--algo maskable-ppo``): trained on the env's action masks, recorded in
``training.json``, loaded, resumed and played with the masks; refused where it cannot
run.

Tests that train are marked slow (a few seconds each on 2 cores).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from _cli import usage_error
from sb3_contrib import MaskablePPO

from aldm_gym import ENV_ID
from aldm_gym.agents.episodes import run_episode
from aldm_gym.cli import main
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.training.models import load_policy
from aldm_gym.training.sb3.backend import train
from aldm_gym.training.settings import ALGORITHMS, PPOParams, algorithm_name

from ._helpers import TINY_KWARGS, tiny_train


class RecordingPolicy:
    """Wraps a masked policy; records each mask it was given and the action taken."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.uses_action_masks = True
        self.calls: list[tuple[np.ndarray, int]] = []

    def predict(self, observation: Any, deterministic: bool = True, **kwargs: Any) -> Any:
        action, state = self.policy.predict(observation, deterministic=False, **kwargs)
        self.calls.append((np.array(kwargs["action_masks"]), int(action)))
        return action, state


def test_algorithm_names() -> None:
    assert algorithm_name("ppo") == "PPO" and algorithm_name("maskable-ppo") == "MaskablePPO"
    with pytest.raises(ConfigError, match=r"algo must be one of \('ppo', 'maskable-ppo'\)"):
        algorithm_name("dqn")
    assert set(ALGORITHMS) == {"ppo", "maskable-ppo"}


@pytest.mark.slow
def test_maskable_training_is_recorded_loaded_and_played_with_masks(tmp_path: Path) -> None:
    out = tmp_path / "run"
    extra = ("--overtaking-reward", "0.3", "--learning-rate", "3e-4", "--ent-coef", "0.02")
    assert tiny_train(out, 64, "--algo", "maskable-ppo", "--detector", "aldm", *extra) == 0
    meta = json.loads((out / "training.json").read_text())
    assert meta["algorithm"] == "MaskablePPO"
    assert meta["env_config"]["overtaking_reward"] == 0.3
    assert (meta["ppo"]["learning_rate"], meta["ppo"]["ent_coef"]) == (3e-4, 0.02)
    assert [p.name for p in (out / "tb").iterdir()] == ["MaskablePPO_1"]
    assert MaskablePPO.load(out / "model.zip", device="cpu").num_timesteps == 64

    policy, _ = load_policy(out / "model.zip")
    assert type(policy.model) is MaskablePPO and policy.uses_action_masks
    # Sampling (not the argmax) from a barely trained policy: every action is likely,
    # so a mask that were ignored would show.
    recorder = RecordingPolicy(policy)
    env = gym.make(ENV_ID, config={"duration": 20, "vehicles_count": 5})
    stats = run_episode(env, recorder, seed=3)
    env.close()
    assert stats.steps == len(recorder.calls) > 10
    masks = np.array([m for m, _ in recorder.calls])
    assert masks.shape == (stats.steps, 5) and masks.dtype == bool
    assert not masks.all(), "a 4-lane road has steps with a lane change masked out"
    assert all(mask[action] for mask, action in recorder.calls)
    assert stats.lane_changes_failed == 0  # no refused command: none was sampled

    # Resuming keeps the algorithm; a contradicting --algo is refused.
    assert main(["train", "--resume", "--timesteps", "96", "--out", str(out), "--no-progress"]) == 0
    assert MaskablePPO.load(out / "model.zip", device="cpu").num_timesteps == 96


@pytest.mark.slow
def test_maskable_resume_refuses_another_algo(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    model = train(
        tmp_path, timesteps=32, algo="maskable-ppo", params=PPOParams(n_steps=32), **TINY_KWARGS
    )
    assert type(model) is MaskablePPO
    line = usage_error(["train", "--resume", "--algo", "ppo", "--out", str(tmp_path)], capsys)
    assert "argument --algo: ppo contradicts the training being resumed (maskable-ppo)" in line
    argv = ["train", "--resume", "--overtaking-reward", "0.1", "--out", str(tmp_path)]
    assert "--overtaking-reward: 0.1 contradicts the training being resumed (None)" in usage_error(
        argv, capsys
    )


def test_ppo_model_refuses_a_mask(tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    from aldm_gym.training.sb3.policy import NormalizedModel

    env = gym.make(ENV_ID, config={"duration": 2, "vehicles_count": 2})
    policy = NormalizedModel(PPO("MultiInputPolicy", env, n_steps=8, batch_size=8, device="cpu"))
    obs, info = env.reset(seed=0)
    assert not policy.uses_action_masks
    with pytest.raises(InputError, match="PPO takes no action_masks"):
        policy.predict(obs, action_masks=info["action_mask"])
    env.close()


def test_both_backends_train_both_algorithms_and_name_the_others() -> None:
    from aldm_gym.training.rllib.backend import RLlibBackend
    from aldm_gym.training.sb3.backend import SB3Backend

    for backend in (SB3Backend, RLlibBackend):
        backend.require_algorithm("PPO")
        backend.require_algorithm("MaskablePPO")
    with pytest.raises(ConfigError, match="the RLlib backend trains PPO, MaskablePPO, not DQN"):
        RLlibBackend.require_algorithm("DQN")
