"""The stable-baselines3 backend: tiny trainings write loadable models, checkpoint
between rollouts, validate and keep the best model, resume keeps counting.

Tests that train are marked slow (a few seconds to a minute each on 2 cores).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from _cli import usage_error
from stable_baselines3 import PPO

from aldm_gym import ENV_ID
from aldm_gym.cli import main
from aldm_gym.training.model_evaluation import EVAL_COLUMNS, evaluate
from aldm_gym.training.models import load_policy
from aldm_gym.training.outputs import latest_checkpoint
from aldm_gym.training.sb3.backend import train
from aldm_gym.training.settings import VALIDATION_SEED, PPOParams

from ._helpers import TINY, TINY_KWARGS, tiny_train
from ._sb3_callbacks import InterruptAt


@pytest.mark.slow
def test_checkpoints_follow_the_frequency(tmp_path: Path) -> None:
    out = tmp_path / "freq"
    assert tiny_train(out, 160, "--checkpoint-freq", "64") == 0
    steps = sorted(
        int(p.stem.split("_")[1]) for p in (out / "checkpoints").glob("model_*_steps.zip")
    )
    # Rollouts of 32 steps: a checkpoint after the first rollout ending >= 64 steps after
    # the last one, plus the final state.
    assert steps == [64, 128, 160]


@pytest.mark.slow
def test_train_writes_loadable_model_and_evaluate_prints_table(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "run"
    assert tiny_train(out, 64, "--detector", "aldm", "--checkpoint-freq", "32") == 0
    for name in ("model.zip", "vecnormalize.pkl", "training.json"):
        assert (out / name).is_file()
    assert latest_checkpoint(out)[2] == 64
    assert (out / "checkpoints" / "model_32_steps.zip").is_file()
    assert any((out / "tb").rglob("events.out.tfevents.*"))
    assert PPO.load(out / "model.zip", device="cpu").num_timesteps == 64
    meta = json.loads((out / "training.json").read_text())
    assert meta["env_config"] == {
        "detector": "aldm",
        "marking_model": "per_dash",
        "duration": 5.0,
        "vehicles_count": 5,
        "collision_reward": -2.0,  # the training default
    }
    policy, _ = load_policy(out / "checkpoints" / "model_32_steps.zip")
    assert policy.vecnormalize is not None

    # Writing into an existing training without --resume is refused.
    argv = ["train", "--timesteps", "64", "--out", str(out), *TINY]
    assert "already holds a training" in usage_error(argv, capsys)

    # Evaluate on another detector than trained on: one episode per policy.
    args = ["--model", str(out / "model.zip"), "--episodes", "1", "--detector", "naive"]
    assert main(["evaluate", *args, "--no-progress"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[1].split() == list(EVAL_COLUMNS)
    assert [line.split()[0] for line in lines[2:5]] == ["idle", "rule_based", "model"]
    assert lines[-1].startswith("model (64 steps, trained on aldm/per_dash, evaluated on naive")
    report = json.loads((out / "evaluate_model_naive_per_dash.json").read_text())
    assert [r["policy"] for r in report["rows"]] == ["idle", "rule_based", "model"]


@pytest.mark.slow
def test_validation_keeps_the_model_it_scored_best(tmp_path: Path) -> None:
    import gymnasium as gym
    import numpy as np

    from aldm_gym.agents.episodes import run_episodes

    out = tmp_path / "val"
    extra = ("--validation-freq", "32", "--validation-episodes", "2")
    assert tiny_train(out, 96, *extra) == 0
    record = json.loads((out / "validation.json").read_text())
    history = record["history"]
    # After each update (32, 64 steps) and at the end (96).
    assert [h["steps"] for h in history] == [32, 64, 96]
    assert record["seeds"] == [VALIDATION_SEED, VALIDATION_SEED + 1]
    assert set(record["baselines"]) == {"idle", "rule_based"}
    assert (out / "validation.png").stat().st_size > 0
    best = max(history, key=lambda h: h["mean_return"])
    assert record["best_steps"] == best["steps"]
    # best_model.zip is the validated policy: replaying the validation seeds with it
    # (and its saved normalisation) gives the recorded return exactly.
    policy, trained = load_policy(out / "best_model.zip")
    assert policy.vecnormalize is not None
    assert policy.model.num_timesteps == best["steps"]
    env = gym.make(ENV_ID, config=trained.env_config)
    episodes = run_episodes(env, policy, range(VALIDATION_SEED, VALIDATION_SEED + 2))
    assert float(np.mean([e.reward for e in episodes])) == best["mean_return"]
    # A resume continues the record (same seeds, baselines kept) with the saved settings.
    resume = ["--resume", "--timesteps", "128", "--n-envs", "1", "--no-progress"]
    assert main(["train", "--out", str(out), *resume]) == 0
    resumed = json.loads((out / "validation.json").read_text())
    assert [h["steps"] for h in resumed["history"]] == [32, 64, 96, 128]
    assert resumed["baselines"] == record["baselines"]
    assert any(
        "validation" in line
        for p in (out / "tb").rglob("events.out.tfevents.*")
        for line in [p.read_bytes().decode("latin-1")]
    )


def test_keep_by_score_prefers_the_validation_without_failures(tmp_path: Path) -> None:
    """The return can rank a faster validation with a collision first; the score
    (speed less 10 m/s per failed-episode share) does not."""
    from aldm_gym.errors import ConfigError
    from aldm_gym.training.sb3.callbacks import ValidationCallback

    clean = {"steps": 1, "mean_return": 30.0, "mean_speed": 25.2, "success_rate": 1.0}
    risky = {"steps": 2, "mean_return": 30.4, "mean_speed": 25.6, "success_rate": 0.95}
    ranks = {}
    for keep_by in ("return", "score"):
        cb = ValidationCallback(tmp_path, {}, 1, 1, keep_by=keep_by)
        ranks[keep_by] = max((clean, risky), key=cb._merit)["steps"]
    assert ranks == {"return": 2, "score": 1}
    with pytest.raises(ConfigError, match=r"keep_by must be one of \('return', 'score'\)"):
        ValidationCallback(tmp_path, {}, 1, 1, keep_by="speed")
    with pytest.raises(ConfigError, match="keep_by must be one of"):
        train(tmp_path / "t", keep_by="speed", **TINY_KWARGS)
    assert not (tmp_path / "t").exists()


@pytest.mark.slow
def test_keep_by_is_recorded_and_kept_on_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    from aldm_gym.training.settings import validation_score

    out = tmp_path / "score"
    extra = ("--validation-freq", "32", "--validation-episodes", "2", "--keep-by", "score")
    assert tiny_train(out, 64, *extra) == 0
    record = json.loads((out / "validation.json").read_text())
    assert record["keep_by"] == "score"
    assert json.loads((out / "training.json").read_text())["keep_by"] == "score"
    scores = [validation_score(h) for h in record["history"]]
    assert record["best_steps"] == record["history"][scores.index(max(scores))]["steps"]
    argv = ["train", "--out", str(out), "--resume", "--timesteps", "96", "--keep-by", "return"]
    assert "--keep-by: return contradicts the training being resumed (score)" in usage_error(
        argv, capsys
    )
    assert main(["train", "--out", str(out), "--resume", "--timesteps", "96", "--no-progress"]) == 0
    assert json.loads((out / "validation.json").read_text())["keep_by"] == "score"


@pytest.mark.slow
def test_resume_after_interruption_continues_step_count(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    kwargs = TINY_KWARGS
    with pytest.raises(KeyboardInterrupt):
        train(
            tmp_path,
            timesteps=96,
            params=PPOParams(n_steps=32, lr_schedule="linear"),
            callback=InterruptAt(40),
            **kwargs,
        )
    # Interrupted in the 2nd rollout: the checkpoint holds the state after the 1st update.
    model_path, vecnorm_path, steps = latest_checkpoint(tmp_path)
    assert steps == 32 and vecnorm_path.is_file()
    assert PPO.load(model_path, device="cpu").num_timesteps == 32

    model = train(tmp_path, timesteps=96, resume=True, **kwargs)
    assert model.num_timesteps == 96
    # The linear schedule is restored with the model (not frozen to a constant).
    assert json.loads((tmp_path / "training.json").read_text())["ppo"]["lr_schedule"] == "linear"
    assert model.lr_schedule(1.0) == 5e-4 and model.lr_schedule(0.0) == 0.0
    assert PPO.load(tmp_path / "model.zip", device="cpu").num_timesteps == 96
    assert latest_checkpoint(tmp_path)[2] == 96
    # One tensorboard run, continued.
    assert [p.name for p in (tmp_path / "tb").iterdir()] == ["PPO_1"]

    # The CLI resumes with a larger budget and keeps the saved config.
    assert (
        main(
            [
                "train",
                "--resume",
                "--timesteps",
                "128",
                "--out",
                str(tmp_path),
                "--n-envs",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    assert PPO.load(tmp_path / "model.zip", device="cpu").num_timesteps == 128
    line = usage_error(["train", "--resume", "--detector", "aldm", "--out", str(tmp_path)], capsys)
    assert "argument --detector: aldm contradicts the training being resumed" in line


FULL_RUN_FILES = {
    *("training.json", "train.lock", "model.zip", "vecnormalize.pkl", "checkpoints", "tb"),
    *("best_model.zip", "best_vecnormalize.pkl", "validation.json", "validation.png"),
}
"""What a training with validation leaves in its output folder."""


@pytest.mark.slow
def test_quick_cli_with_subprocess_envs(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """``train --quick`` (2 subprocess envs) and ``evaluate --quick`` end to end: the
    files of a full run, episode return and length on the bar, each validation said
    before it runs and printed beside the baselines; a verdict that says it cannot
    decide on 5 episodes."""
    out = tmp_path / "quick"
    assert main(["train", "--quick", "--n-envs", "2", "--out", str(out)]) == 0
    assert PPO.load(out / "model.zip", device="cpu").num_timesteps == 1024
    assert {p.name for p in out.iterdir()} == FULL_RUN_FILES
    captured = capsys.readouterr()
    assert "ep_rew=" in captured.err and "ep_len=" in captured.err  # the bar's postfix
    lines = captured.out.splitlines()
    assert lines[0].startswith("validating the baselines")
    # Validations after the rollouts ending at or past 512 steps, and at the end.
    for steps in (512, 1024):
        said = lines.index(f"validating at {steps} steps on seeds 20000..20002 (3 episodes)…")
        result = lines[said + 1]
        assert result.startswith(f"validation at {steps} steps: return ")
        assert " | rule-based: return " in result and " | IDLE: return " in result
    policy, _ = load_policy(out / "best_model.zip")
    record = json.loads((out / "validation.json").read_text())
    assert policy.model.num_timesteps == record["best_steps"]
    assert (
        main(["evaluate", "--quick", "--model", str(out / "best_model.zip"), "--no-progress"]) == 0
    )
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("model (")
    assert "is inconclusive against IDLE: 5 episodes are too few for a verdict" in last
    assert "it is inconclusive against the rule-based LCA: 5 episodes" in last


def test_progress_postfix_and_validation_line() -> None:
    from aldm_gym.training.sb3.callbacks import episode_postfix, format_validation

    assert episode_postfix([]) == {"ep_rew": "-", "ep_len": "-"}
    infos = [{"r": 1.0, "l": 10, "t": 0.1}, {"r": 2.0, "l": 20, "t": 0.2}]
    assert episode_postfix(infos) == {"ep_rew": "1.50", "ep_len": "15.0"}
    row = {"mean_return": 9.5, "success_rate": 0.9, "mean_speed": 24.25, "collisions": 1}
    base = {"rule_based": {**row, "collisions": 2}, "idle": {**row, "mean_speed": 22.0}}
    line = format_validation({"steps": 4096, **row}, base, 20, best=True)
    assert line == (
        "validation at 4096 steps: return 9.50, success 90%, 24.2 m/s, 1/20 collided "
        "(best so far) | rule-based: return 9.50, success 90%, 24.2 m/s, 2/20 collided "
        "| IDLE: return 9.50, success 90%, 22.0 m/s, 1/20 collided"
    )


@pytest.mark.slow
def test_env_settings_given_with_env_are_trained_saved_evaluated_and_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``--env`` sets any env setting: the lane-model filter and its confidence in the
    observation here. The model's observation space has the key, ``training.json``
    keeps the settings, evaluation builds the same env, and a resume refuses another
    value (but takes the same one)."""
    out = tmp_path / "run"
    given = ("--env", "detector_params.tracking=model", "--env", "observation.line_confidence=true")
    assert tiny_train(out, 32, "--detector", "aldm", *given) == 0
    meta = json.loads((out / "training.json").read_text())
    assert meta["env_config"]["detector_params"] == {"tracking": "model"}
    assert meta["env_config"]["observation"] == {"line_confidence": True}
    model = PPO.load(out / "model.zip", device="cpu")
    assert "line_confidence" in model.observation_space.spaces

    rows, info = evaluate(out / "model.zip", episodes=1, progress=False)
    assert info["env_config"]["detector_params"] == {"tracking": "model"}
    assert [r["policy"] for r in rows] == ["idle", "rule_based", "model"]
    # On another detector the trained one's parameters are dropped, the rest kept.
    _, info = evaluate(out / "model.zip", episodes=1, detector="naive", progress=False)
    assert "detector_params" not in info["env_config"]
    assert info["env_config"]["observation"] == {"line_confidence": True}
    # more env settings over the training's; the observation stays as trained
    camera = {"sensor": {"preset": "camera"}}
    _, info = evaluate(out / "model.zip", episodes=1, progress=False, env_overrides=camera)
    assert info["env_config"]["sensor"] == {"preset": "camera"}
    assert info["env_config"]["detector_params"] == {"tracking": "model"}
    argv = ["evaluate", "--model", str(out), "--env", "observation.line_confidence=false"]
    assert "observation: the policy was trained on it" in usage_error(argv, capsys)
    argv = ["evaluate", "--model", str(out), "--env", "sensor.prest=camera"]
    assert "'preset'" in usage_error(argv, capsys)

    argv = ["train", "--resume", "--out", str(out), "--env", "detector_params.tracking=true"]
    line = usage_error(argv, capsys)
    assert "argument --env: detector_params.tracking=true contradicts the training being " in line
    assert '("model"); omit it with --resume' in line
    argv = ["train", "--resume", "--out", str(out), "--env", "sensor.preset=camera"]
    assert "sensor.preset was not set in the training being resumed" in usage_error(argv, capsys)
    # the same values (a list as the config's tuple, a default as such) are taken
    again = ("--timesteps", "64", "--env", "observation.line_confidence=true", "--no-progress")
    same = ("--env", "reward_speed_range=[20, 30]")
    assert main(["train", "--resume", "--out", str(out), *again, *same]) == 0
    assert PPO.load(out / "model.zip", device="cpu").num_timesteps == 64
