"""Cloning the rule-based LCA before PPO (``train --pretrain-episodes``): the
demonstrations, their returns, the clone, and the training that starts from it.

Tests that train are marked slow (a few seconds each on 2 cores).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from _cli import usage_error
from sb3_contrib import MaskablePPO
from stable_baselines3.common.vec_env import VecNormalize

from aldm_gym.envs.actions import MetaAction
from aldm_gym.errors import ConfigError
from aldm_gym.training.sb3.envs import make_vec_env
from aldm_gym.training.sb3.pretrain import (
    MAX_PRETRAIN_EPISODES,
    PRETRAIN_SEED,
    Demonstrations,
    check_pretrain,
    clone,
    collect_demonstrations,
    demonstration_seeds,
    discounted_returns,
)
from aldm_gym.training.settings import VALIDATION_SEED, env_config

from ._helpers import corrupt, tiny_train

CONFIG = env_config("aldm", "per_dash", duration=8.0, vehicles_count=8)
"""A short, light env for the demonstrations."""


def _model(seed: int = 0, algorithm: Any = MaskablePPO) -> Any:
    venv = VecNormalize(make_vec_env(CONFIG, 1, seed), norm_reward=False, clip_obs=10.0)
    return algorithm("MultiInputPolicy", venv, n_steps=32, batch_size=32, seed=seed, device="cpu")


@pytest.fixture(scope="module")
def demos() -> Demonstrations:
    return collect_demonstrations(CONFIG, demonstration_seeds(0, 6), gamma=0.9)


def test_discounted_returns_stop_at_each_episode_end() -> None:
    rewards = np.array([1.0, 1.0, 1.0, 2.0, 2.0])
    ends = np.array([False, False, True, False, True])
    np.testing.assert_allclose(discounted_returns(rewards, ends, 0.5), [1.75, 1.5, 1.0, 3.0, 2.0])
    np.testing.assert_allclose(discounted_returns(rewards, ends, 0.0), rewards)


def test_demonstration_seeds_keep_apart_from_validation_and_evaluation() -> None:
    assert demonstration_seeds(0, 3) == range(PRETRAIN_SEED, PRETRAIN_SEED + 3)
    assert demonstration_seeds(1, 2)[0] == PRETRAIN_SEED + MAX_PRETRAIN_EPISODES
    every = demonstration_seeds(0, MAX_PRETRAIN_EPISODES)
    assert every[0] > VALIDATION_SEED + 1000 and every[0] > 10_000 + 1000
    assert max(demonstration_seeds(0, MAX_PRETRAIN_EPISODES)) < demonstration_seeds(1, 1)[0]
    for bad in (0, MAX_PRETRAIN_EPISODES + 1):
        with pytest.raises(ConfigError, match=r"pretrain_episodes must be in 1\.\."):
            demonstration_seeds(0, bad)


def test_check_pretrain_names_the_setting() -> None:
    check_pretrain(0, 1)
    check_pretrain(MAX_PRETRAIN_EPISODES, 30)
    with pytest.raises(ConfigError, match=r"pretrain_episodes must be in 0\.\.10000, got -1"):
        check_pretrain(-1, 30)
    with pytest.raises(ConfigError, match="pretrain_epochs must be >= 1, got 0"):
        check_pretrain(5, 0)


def test_demonstrations_are_the_teachers_steps(demos: Demonstrations) -> None:
    n = len(demos)
    assert demos.episodes == 6 and n == 6 * 8  # 8 s episodes at 1 Hz, no collision
    assert demos.actions.shape == (n,) and demos.masks.shape == (n, 5)
    assert all(v.shape[0] == n and v.dtype == np.float32 for v in demos.observations.values())
    assert demos.masks[np.arange(n), demos.actions].all()  # the teacher obeys the masks
    assert (demos.actions == MetaAction.FASTER).any()
    with pytest.raises(ConfigError, match="no demonstration episodes"):
        collect_demonstrations(CONFIG, range(0), gamma=0.9)
    again = collect_demonstrations(CONFIG, demonstration_seeds(0, 6), gamma=0.9)
    np.testing.assert_array_equal(again.actions, demos.actions)
    np.testing.assert_array_equal(again.returns, demos.returns)


def test_clone_fits_the_teacher_and_is_deterministic(demos: Demonstrations) -> None:
    import torch

    seeds = demonstration_seeds(0, 6)
    model = _model()
    with torch.no_grad():
        before = model.policy.predict_values(
            {k: torch.as_tensor(v) for k, v in model.env.normalize_obs(demos.observations).items()}
        )
    report = clone(model, demos, epochs=40, seed=0, seeds=seeds, masked=True)
    assert report.steps == len(demos) and report.seeds == (seeds[0], seeds[-1])
    assert report.accuracy >= 0.9, report
    rms_before = float(
        torch.sqrt(((before.flatten() - torch.as_tensor(demos.returns)) ** 2).mean())
    )
    assert report.value_rmse < 0.5 * rms_before
    assert model.env.obs_rms["ego"].count > len(demos)  # statistics from the demonstrations
    record = report.record()
    assert json.loads(json.dumps(record)) == record
    twin = _model()
    clone(twin, demos, epochs=40, seed=0, seeds=seeds, masked=True)
    for a, b in zip(
        model.policy.state_dict().values(), twin.policy.state_dict().values(), strict=True
    ):
        assert torch.equal(a, b)


def test_clone_of_a_plain_ppo_policy(demos: Demonstrations) -> None:
    from stable_baselines3 import PPO

    report = clone(_model(algorithm=PPO), demos, 60, 0, demonstration_seeds(0, 6), masked=False)
    assert report.steps == len(demos) and report.accuracy >= 0.9, report


def test_clone_leaves_out_steps_the_mask_rules_out(demos: Demonstrations) -> None:
    masks = demos.masks.copy()
    masks[np.arange(3), demos.actions[:3]] = False
    ruled_out = Demonstrations(
        demos.observations, demos.actions, masks, demos.returns, demos.episodes
    )
    report = clone(_model(), ruled_out, 2, 0, demonstration_seeds(0, 6), masked=True)
    assert report.steps == len(demos) - 3 and np.isfinite(report.value_rmse)
    masks[:] = False
    with pytest.raises(ConfigError, match="ruled out by its mask"):
        clone(
            _model(),
            Demonstrations(demos.observations, demos.actions, masks, demos.returns, 6),
            2,
            0,
            demonstration_seeds(0, 6),
            masked=True,
        )
    with pytest.raises(ConfigError, match="pretrain_epochs must be >= 1"):
        clone(_model(), demos, 0, 0, demonstration_seeds(0, 6), masked=True)


@pytest.mark.slow
def test_training_starts_from_the_clone_and_validates_it(tmp_path: Path) -> None:
    out = tmp_path / "run"
    flags = ("--algo", "maskable-ppo", "--pretrain-episodes", "2", "--pretrain-epochs", "3")
    validation = ("--validation-freq", "32", "--validation-episodes", "1")
    assert tiny_train(out, 64, *flags, *validation) == 0
    meta = json.loads((out / "training.json").read_text())
    assert meta["pretrain"]["episodes"] == 2 and meta["pretrain"]["epochs"] == 3
    assert meta["pretrain"]["seeds"] == [PRETRAIN_SEED, PRETRAIN_SEED + 1]
    history = json.loads((out / "validation.json").read_text())["history"]
    assert [h["steps"] for h in history] == [0, 32, 64]
    # a resume keeps the record and does not clone again
    assert tiny_train(out, 96, "--resume", *validation) == 0
    assert json.loads((out / "training.json").read_text())["pretrain"] == meta["pretrain"]
    history = json.loads((out / "validation.json").read_text())["history"]
    assert [h["steps"] for h in history] == [0, 32, 64, 96]


@pytest.mark.slow
def test_a_resume_without_a_checkpoint_clones_again(tmp_path: Path) -> None:
    out = tmp_path / "run"
    flags = ("--algo", "maskable-ppo", "--pretrain-episodes", "2", "--pretrain-epochs", "3")
    assert tiny_train(out, 32, *flags) == 0
    meta = json.loads((out / "training.json").read_text())
    for path in (out / "checkpoints").iterdir():
        corrupt(path, "truncate")
    assert tiny_train(out, 32, "--resume") == 0
    assert json.loads((out / "training.json").read_text())["pretrain"] == meta["pretrain"]
    assert meta["pretrain"]["steps"] > 0  # the report, not only the settings


def test_api_resume_refuses_pretrain_settings(tmp_path: Path) -> None:
    from aldm_gym.training.sb3.backend import train

    with pytest.raises(ConfigError, match="clones before a new training only"):
        train(tmp_path, resume=True, pretrain_episodes=3)


def test_pretrain_flags_are_refused_where_they_cannot_apply(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = str(tmp_path / "run")
    line = usage_error(
        ["train", "--backend", "rllib", "--pretrain-episodes", "3", "--out", out], capsys
    )
    assert "--pretrain-episodes: applies to --backend sb3 only" in line
    line = usage_error(["train", "--pretrain-epochs", "3", "--out", out], capsys)
    assert "--pretrain-epochs: needs --pretrain-episodes" in line
    line = usage_error(["train", "--pretrain-episodes", "0", "--out", out], capsys)
    assert "--pretrain-episodes" in line and "got 0" in line
    assert not (tmp_path / "run").exists()  # refused before --out is made


@pytest.mark.slow
def test_resume_refuses_pretrain_flags(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "run"
    assert tiny_train(out, 32) == 0
    line = usage_error(["train", "--resume", "--pretrain-episodes", "3", "--out", str(out)], capsys)
    assert "clones before a new training only" in line
