"""The RLlib backend: PPO settings as on the SB3 path, checkpoints written whole,
resume, a checkpoint played outside Ray, a stop between iterations.

Tests needing Ray RLlib skip without the ``[ray]`` extra (``make test-ray`` runs them;
a real two-node cluster: ``test_rllib_cluster.py``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from aldm_gym.errors import InputError
from aldm_gym.training.rllib.checkpoints import checkpoint_steps, newest_checkpoint
from aldm_gym.training.settings import PPOParams

BIN = Path(sys.executable).parent
SHORT = {"duration": 10.0}


def test_ppo_runs_as_on_the_sb3_path(rllib: object) -> None:
    from aldm_gym.training.rllib.config import RLLIB_ENV_ID, ppo_config

    params = PPOParams(n_steps=128, learning_rate=3e-4, gamma=0.9)
    cfg = ppo_config(SHORT, params, timesteps=4096, num_env_runners=3, seed=7)
    assert cfg.env == RLLIB_ENV_ID and cfg.env_config == {"config": SHORT}
    assert cfg.train_batch_size_per_learner == 3 * 128  # n_steps per env runner
    assert cfg.minibatch_size == params.batch_size and cfg.num_epochs == params.n_epochs
    assert cfg.gamma == 0.9 and cfg.lambda_ == params.gae_lambda
    assert cfg.clip_param == params.clip_range and cfg.entropy_coeff == params.ent_coef
    assert cfg.lr == [[0, 3e-4], [4096, 0.0]]  # linear to 0 over the budget
    assert cfg.use_kl_loss is False and cfg.vf_loss_coeff == 0.5 and cfg.grad_clip == 0.5
    assert cfg.num_env_runners == 3 and cfg.seed == 7
    assert cfg.model_config["fcnet_hiddens"] == [128, 128]
    assert cfg.model_config["fcnet_activation"] == "tanh"  # as SB3's MlpPolicy
    assert cfg.model_config["vf_share_layers"] is False and cfg.vf_clip_param == float("inf")
    constant = ppo_config(SHORT, PPOParams(lr_schedule="constant"), timesteps=10)
    assert constant.lr == PPOParams.learning_rate
    assert constant.train_batch_size_per_learner == PPOParams.n_steps  # 0 runners: 1 env


@pytest.fixture(scope="module")
def trained(rllib: object, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """128 steps on one remote env runner, then resumed to 256; ``out`` given as a
    relative path (as a user types it)."""
    from aldm_gym.training.rllib.backend import train_rllib

    out = tmp_path_factory.mktemp("rllib")
    kwargs = {
        "num_env_runners": 1,
        "duration": 10.0,
        "params": PPOParams(n_steps=64),
        "checkpoint_freq": 128,
        "progress": False,
    }
    cwd = os.getcwd()
    os.chdir(out.parent)
    try:
        relative = Path(out.name)
        assert train_rllib(relative, timesteps=128, **kwargs) == 128
        assert train_rllib(relative, timesteps=256, resume=True, **kwargs) == 256
    finally:
        os.chdir(cwd)
    return out


def test_training_writes_checkpoints_and_resumes(trained: Path) -> None:
    from aldm_gym.training.outputs import RLLIB_MODEL_DIR as MODEL_DIR
    from aldm_gym.training.rllib.backend import train_rllib

    meta = json.loads((trained / "training.json").read_text())
    assert meta["backend"] == "rllib" and meta["timesteps"] == 256
    assert meta["env_config"]["duration"] == 10.0 and meta["ppo"]["n_steps"] == 64
    names = sorted(p.name for p in (trained / "checkpoints").iterdir())
    assert names == ["rllib_128", "rllib_256"]
    assert checkpoint_steps(trained / MODEL_DIR) == 256
    events = list((trained / "tb" / "RLlib_PPO").glob("events.out.tfevents.*"))
    assert len(events) == 2  # one per run, in the same tensorboard run
    with pytest.raises(FileExistsError, match="already holds a training"):
        train_rllib(trained, timesteps=512, progress=False)


def _observations_seen(checkpoint: Path) -> int:
    """How many observations the checkpoint's normalisation statistics count."""
    from aldm_gym.training.rllib.policy import RLlibPolicy

    state = RLlibPolicy(checkpoint).pipeline.get_state()
    return int(state["MeanStdFilter"][None]["running_stats"][0]["num_pushes"])


def test_checkpoints_carry_the_runners_statistics_across_a_resume(trained: Path) -> None:
    # 128 steps (and the resets' observations) before the resume ...
    first = _observations_seen(trained / "checkpoints" / "rllib_128")
    assert 128 <= first < 200
    # ... and the resumed runner started from them: 128 more, not from zero.
    assert _observations_seen(trained / "rllib_model") >= first + 128


def test_resume_falls_back_to_an_older_checkpoint(trained: Path, tmp_path: Path) -> None:
    import shutil

    from aldm_gym.errors import TrainingWarning
    from aldm_gym.training.rllib.backend import train_rllib

    out = tmp_path / "out"
    shutil.copytree(trained, out, ignore=shutil.ignore_patterns("train.lock"))
    for path in (out / "checkpoints" / "rllib_256").rglob("*.pkl"):
        path.write_bytes(b"damaged")
    with pytest.warns(TrainingWarning, match="skipping .*rllib_256: does not restore"):
        steps = train_rllib(out, timesteps=320, resume=True, progress=False)
    assert steps == 320  # from 128, not from 0 nor from the damaged 256
    assert checkpoint_steps(out / "checkpoints" / "rllib_256") == 256  # written anew
    assert _observations_seen(out / "checkpoints" / "rllib_256") >= 256


def test_an_iteration_that_sampled_nothing_counts_no_steps() -> None:
    from aldm_gym.training.rllib.backend import sampled_steps

    assert sampled_steps({"env_runners": {"num_env_steps_sampled": 256}}) == 256
    for result in ({"env_runners": {"num_env_steps_sampled": float("nan")}}, {}):
        with pytest.warns(UserWarning, match="sampled no env steps"):
            assert sampled_steps(result) == 0


def test_an_sb3_training_is_not_resumed_by_rllib(rllib: object, tmp_path: Path) -> None:
    from aldm_gym.training.rllib.backend import train_rllib

    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}, "ppo": {}}))
    with pytest.raises(ValueError, match="holds an SB3 training"):
        train_rllib(tmp_path, resume=True, progress=False)


def test_a_checkpoint_plays_outside_ray_with_frozen_statistics(trained: Path) -> None:
    import gymnasium as gym

    from aldm_gym import ENV_ID
    from aldm_gym.training.models import load_policy

    policy, record = load_policy(trained / "rllib_model")
    assert policy.num_timesteps == 256 and record.backend == "rllib"
    state = json.dumps(policy.pipeline.get_state(), default=str)
    env = gym.make(ENV_ID, config=record.env_config)
    obs, _ = env.reset(seed=3)
    for _ in range(5):
        logits = policy.logits(obs)
        assert logits.shape == (env.action_space.n,) and np.isfinite(logits).all()
        action, _ = policy.predict(obs, deterministic=True)
        assert int(action) == int(np.argmax(logits))
        assert policy.predict(obs)[0] == action  # the same observation, the same action
        obs, *_ = env.step(action)
    env.close()
    # Stochastic play samples the softmax of the logits.
    drawn = [int(policy.predict(obs, deterministic=False)[0]) for _ in range(300)]
    p = np.exp(policy.logits(obs) - policy.logits(obs).max())
    p /= p.sum()
    counts = np.bincount(drawn, minlength=len(p))
    assert np.all(np.abs(counts / 300 - p) < 0.1)
    assert json.dumps(policy.pipeline.get_state(), default=str) == state


def test_evaluate_plays_an_rllib_checkpoint_against_the_baselines(trained: Path) -> None:
    from aldm_gym.training.model_evaluation import evaluate

    rows, info = evaluate(trained / "checkpoints" / "rllib_128", episodes=2, progress=False)
    assert [r["policy"] for r in rows] == ["idle", "rule_based", "model"]
    assert info["timesteps"] == 128 and len(info["per_episode"]["model"]["mean_speed"]) == 2


def test_evaluate_takes_the_final_checkpoint_of_an_output_folder(
    trained: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from aldm_gym.cli import main

    argv = ["evaluate", "--model", str(trained), "--episodes", "1", "--no-progress"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == f"evaluating {trained / 'rllib_model'}: the final RLlib checkpoint"
    record = json.loads((tmp_path / "evaluate_rllib_model_aldm_per_dash.json").read_text())
    assert record["timesteps"] == 256 and [r["policy"] for r in record["rows"]] == [
        "idle",
        "rule_based",
        "model",
    ]


def test_a_damaged_checkpoint_names_the_folder(trained: Path, tmp_path: Path) -> None:
    import shutil

    from aldm_gym.training.rllib.policy import load_rllib_policy

    out = tmp_path / "out"
    shutil.copytree(trained, out, ignore=shutil.ignore_patterns("train.lock"))
    module = out / "rllib_model" / "learner_group" / "learner" / "rl_module" / "default_policy"
    for path in module.rglob("*.pkl"):
        path.write_bytes(b"not a pickle")
    with pytest.raises(ValueError, match="rllib_model: not a readable RLlib checkpoint"):
        load_rllib_policy(out / "rllib_model")


@pytest.mark.slow
def test_sigterm_finishes_the_iteration_and_saves_it(rllib: object, tmp_path: Path) -> None:
    import signal

    out = tmp_path / "out"
    argv = [str(BIN / "aldm-gym"), "train", "--backend", "rllib", "--num-env-runners", "1"]
    argv += ["--timesteps", "100000", "--n-steps", "64", "--duration", "10"]
    argv += ["--checkpoint-freq", "100000", "--out", str(out), "--no-progress"]
    proc = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True)

    first: list[int] = []

    def iterated() -> bool:
        """An iteration's scalars are in the events file: it grew past the version
        record it starts with (the backend flushes after every iteration)."""
        events = list((out / "tb").rglob("events.out.tfevents.*"))
        if not events:
            return False
        size = events[0].stat().st_size
        if not first:
            first.append(size)
        return size > first[0]

    try:
        end = time.monotonic() + 300
        while not iterated():  # training is under way: the signal comes mid-iteration
            assert proc.poll() is None and time.monotonic() < end, proc.stderr.read()[-2000:]
            time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err[-2000:]
    assert "stopping after this iteration" in err and "continue with --resume" in err
    saved = newest_checkpoint(out)
    assert saved is not None and checkpoint_steps(saved) >= 64  # no checkpoint was due


def test_masked_ppo_config_adds_the_mask_after_the_filter(rllib: object) -> None:
    import gymnasium as gym

    from aldm_gym.training.rllib.config import ppo_config
    from aldm_gym.training.rllib.masking import AddActionMask, MaskedPPOModule, masked_space

    cfg = ppo_config(SHORT, PPOParams(), timesteps=1024, masked=True)
    pieces = [type(p).__name__ for p in cfg._env_to_module_connector(None, None, None)]
    assert pieces == ["FlattenObservations", "MeanStdFilter", "AddActionMask"]
    assert cfg.rl_module_spec.module_class is MaskedPPOModule
    assert cfg.rl_module_spec.model_config["fcnet_hiddens"] == [128, 128]
    space = masked_space(gym.spaces.Box(-1.0, 1.0, (7,)), 5)
    assert space["action_mask"].shape == (5,) and space["observations"].shape == (7,)
    piece = AddActionMask()
    with pytest.raises(InputError, match="action masks need discrete actions"):
        piece.recompute_output_observation_space(space["observations"], space["observations"])


class _Episode:
    def __init__(self, info: dict) -> None:
        self.info = info

    def get_infos(self, index: int) -> dict:
        return self.info


def test_the_mask_piece_reads_the_info_and_names_a_missing_mask(rllib: object) -> None:
    from aldm_gym.training.rllib.masking import AddActionMask

    piece = AddActionMask()
    obs = np.arange(3.0)
    out = piece.preprocess(obs, _Episode({"action_mask": np.array([1, 0, 1, 1, 0], bool)}))
    assert out["action_mask"].dtype == np.float32
    assert out["action_mask"].tolist() == [1, 0, 1, 1, 0] and out["observations"] is obs
    with pytest.raises(InputError, match="the env's info has no 'action_mask'"):
        piece.preprocess(obs, _Episode({"speed": 1.0}))


@pytest.fixture(scope="module")
def masked(rllib: object, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``aldm-gym train --backend rllib --algo maskable-ppo``: 64 steps, then resumed
    to 128 without ``--algo`` (the training's algorithm is kept)."""
    from aldm_gym.cli import main

    out = tmp_path_factory.mktemp("masked")
    argv = ["train", "--backend", "rllib", "--num-env-runners", "1", "--n-steps", "64"]
    argv += ["--duration", "10", "--checkpoint-freq", "64", "--no-progress", "--out", str(out)]
    assert main([*argv, "--algo", "maskable-ppo", "--timesteps", "64"]) == 0
    assert main([*argv, "--timesteps", "128", "--resume"]) == 0
    return out


def test_a_masked_checkpoint_never_chooses_a_masked_action(masked: Path) -> None:
    import gymnasium as gym

    from aldm_gym import ENV_ID
    from aldm_gym.training.models import load_policy

    meta = json.loads((masked / "training.json").read_text())
    assert meta["algorithm"] == "MaskablePPO" and meta["timesteps"] == 128
    policy, record = load_policy(masked / "rllib_model")
    assert policy.uses_action_masks and policy.num_timesteps == 128
    env = gym.make(ENV_ID, config=record.env_config)
    obs, info = env.reset(seed=3)
    free = policy.logits(obs, np.ones(5, bool))
    for allowed in ([1, 1, 1, 1, 1], [0, 1, 0, 1, 1], [1, 0, 1, 0, 0], [0, 0, 0, 0, 1]):
        mask = np.array(allowed, bool)
        logits = policy.logits(obs, mask)
        assert np.array_equal(logits[mask], free[mask])  # the mask changes only the others
        assert np.all(logits[~mask] < -1e38)
        assert mask[int(policy.predict(obs, action_masks=mask)[0])]
        drawn = {int(policy.predict(obs, deterministic=False, action_masks=mask)[0])}
        assert all(mask[a] for a in drawn)
    # No mask given: every action allowed.
    assert np.array_equal(policy.logits(obs), free)
    with pytest.raises(InputError, match="5 booleans, one per action"):
        policy.logits(obs, np.ones(3, bool))
    # Stochastic play on the env's masks issues no command the env refuses.
    for _ in range(40):
        action, _ = policy.predict(obs, deterministic=False, action_masks=info["action_mask"])
        obs, _, terminated, truncated, info = env.step(action)
        assert not info["lane_change_refused"]
        if terminated or truncated:
            obs, info = env.reset()
    env.close()


def test_an_unmasked_checkpoint_refuses_a_mask(trained: Path) -> None:
    import gymnasium as gym

    from aldm_gym import ENV_ID
    from aldm_gym.training.models import load_policy

    policy, record = load_policy(trained / "rllib_model")
    env = gym.make(ENV_ID, config=record.env_config)
    obs, info = env.reset(seed=0)
    assert not policy.uses_action_masks
    with pytest.raises(InputError, match="trained without action masks"):
        policy.predict(obs, action_masks=info["action_mask"])
    env.close()


def test_evaluate_gives_a_masked_checkpoint_the_env_mask(masked: Path) -> None:
    from aldm_gym.training.model_evaluation import evaluate

    rows, info = evaluate(masked / "rllib_model", episodes=2, progress=False)
    assert [r["policy"] for r in rows] == ["idle", "rule_based", "model"]
    assert info["timesteps"] == 128 and info["algorithm"] == "MaskablePPO"
