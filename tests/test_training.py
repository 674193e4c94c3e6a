"""``aldm-gym train`` / ``evaluate``: tiny budgets; checkpoints load; resume keeps counting.

Tests that train are marked slow (a few seconds to a minute each on 2 cores).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from _cli import usage_error
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback

from aldm_gym import ENV_ID
from aldm_gym.agents.checkpoints import (
    can_resume,
    checkpoint_paths,
    find_training_file,
    holds_training,
    latest_checkpoint,
    load_policy,
    vecnormalize_for,
)
from aldm_gym.agents.model_evaluation import EVAL_COLUMNS
from aldm_gym.agents.training import VALIDATION_SEED, PPOParams, train
from aldm_gym.cli import main

TINY = [
    *("--n-envs", "1", "--n-steps", "32", "--duration", "5", "--vehicles", "5"),
    *("--validation-freq", "0", "--no-progress"),
]
"""A few seconds of training: 1 env, 32-step rollouts, 5 s episodes, 5 vehicles, no
validation (tested on its own)."""


def _tiny_train(out: Path, timesteps: int, *extra: str) -> int:
    return main(["train", "--timesteps", str(timesteps), "--out", str(out), *TINY, *extra])


@pytest.mark.slow
def test_checkpoints_follow_the_frequency(tmp_path: Path) -> None:
    out = tmp_path / "freq"
    assert _tiny_train(out, 160, "--checkpoint-freq", "64") == 0
    steps = sorted(
        int(p.stem.split("_")[1]) for p in (out / "checkpoints").glob("model_*_steps.zip")
    )
    # Rollouts of 32 steps: a checkpoint after the first rollout ending >= 64 steps after
    # the last one, plus the final state.
    assert steps == [64, 128, 160]


def test_import_stays_light() -> None:
    """Building the CLI parser must not import stable-baselines3 or torch."""
    code = (
        "import sys, aldm_gym, aldm_gym.cli as c; c.build_parser(); "
        "print(any(m in sys.modules for m in ('stable_baselines3', 'torch')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize(
    "argv",
    [
        ["train", "--timesteps", "0"],
        ["train", "--timesteps", "ten"],
        ["train", "--detector", "canny"],
        ["train", "--n-envs", "-2"],
        ["train", "--duration", "-1"],
        ["train", "--lr-schedule", "cosine"],
        ["train", "--gamma", "1.5"],
        ["train", "--validation-freq", "-1"],
        ["train", "--validation-episodes", "0"],
        ["evaluate"],  # --model is required
        ["evaluate", "--model", "m.zip", "--episodes", "0"],
        ["evaluate", "--model", "m.zip", "--marking-model", "dashed"],
    ],
)
def test_bad_arguments_are_rejected(argv: list[str], capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert "error" in capsys.readouterr().err


def _touch(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"")


def test_checkpoint_store_finds_the_newest_complete_checkpoint(tmp_path: Path) -> None:
    assert latest_checkpoint(tmp_path) is None
    assert not holds_training(tmp_path) and not can_resume(tmp_path)
    for steps in (64, 128, 1024):
        model, vecnorm = checkpoint_paths(tmp_path, steps)
        _touch(model)
        if steps != 1024:  # the newest lacks its normalisation: incomplete
            _touch(vecnorm)
    model, vecnorm, steps = latest_checkpoint(tmp_path)
    assert steps == 128  # numerically newest, not lexically (1024 < 128 < 64 as text)
    assert (model.name, vecnorm.name) == ("model_128_steps.zip", "vecnormalize_128_steps.pkl")
    # A checkpoint without training.json is a training (refuse to overwrite) that
    # cannot be resumed.
    assert holds_training(tmp_path) and not can_resume(tmp_path)
    _touch(tmp_path / "training.json")
    assert can_resume(tmp_path)
    # Models find their metadata and normalisation: checkpoints one folder down.
    assert find_training_file(model) == tmp_path / "training.json"
    assert vecnormalize_for(model) == vecnorm
    assert vecnormalize_for(checkpoint_paths(tmp_path, 1024)[0]) is None
    _touch(tmp_path / "best_model.zip")
    _touch(tmp_path / "best_vecnormalize.pkl")
    assert vecnormalize_for(tmp_path / "best_model.zip") == tmp_path / "best_vecnormalize.pkl"
    assert find_training_file(tmp_path / "elsewhere" / "deeper" / "m.zip") is None


def test_a_final_model_alone_also_holds_a_training(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    _touch(tmp_path / "model.zip")
    assert holds_training(tmp_path) and not can_resume(tmp_path)
    line = usage_error(["train", "--out", str(tmp_path), "--no-progress"], capsys)
    assert "argument --out: " in line and "already holds a training" in line


def test_linear_learning_rate_decays_to_zero_over_the_budget() -> None:
    schedule = PPOParams(learning_rate=4e-4, lr_schedule="linear").learning_rate_schedule()
    assert callable(schedule)
    assert [schedule(p) for p in (1.0, 0.5, 0.0)] == [4e-4, 2e-4, 0.0]
    assert PPOParams(lr_schedule="constant").learning_rate_schedule() == 5e-4
    with pytest.raises(ValueError, match="lr_schedule must be one of"):
        PPOParams(lr_schedule="cosine")


def test_clear_errors_for_missing_model_and_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    line = usage_error(["evaluate", "--model", str(tmp_path / "nope.zip")], capsys)
    assert "argument --model: " in line and "does not exist" in line
    (tmp_path / "stray.zip").write_bytes(b"PK")
    line = usage_error(["evaluate", "--model", str(tmp_path / "stray.zip")], capsys)
    assert "argument --model: no training.json" in line
    line = usage_error(["train", "--resume", "--out", str(tmp_path / "empty")], capsys)
    assert "argument --resume: nothing to resume" in line


@pytest.mark.slow
def test_train_writes_loadable_model_and_evaluate_prints_table(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "run"
    assert _tiny_train(out, 64, "--detector", "aldm", "--checkpoint-freq", "32") == 0
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

    from aldm_gym.agents.evaluation import run_episodes

    out = tmp_path / "val"
    extra = ("--validation-freq", "32", "--validation-episodes", "2")
    assert _tiny_train(out, 96, *extra) == 0
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
    policy, meta = load_policy(out / "best_model.zip")
    assert policy.vecnormalize is not None
    assert policy.model.num_timesteps == best["steps"]
    env = gym.make(ENV_ID, config=meta["env_config"])
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


class _InterruptAt(BaseCallback):
    """Raise KeyboardInterrupt (as Ctrl-C would) once ``steps`` steps are done."""

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = steps

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.steps:
            raise KeyboardInterrupt
        return True


@pytest.mark.slow
def test_resume_after_interruption_continues_step_count(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    kwargs = dict(
        detector="naive",
        n_envs=1,
        duration=5.0,
        vehicles_count=5,
        checkpoint_freq=1000,
        validation_freq=0,
        progress=False,
    )
    with pytest.raises(KeyboardInterrupt):
        train(
            tmp_path,
            timesteps=96,
            params=PPOParams(n_steps=32, lr_schedule="linear"),
            callback=_InterruptAt(40),
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
    from aldm_gym.agents.callbacks import episode_postfix, format_validation

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


class _SignalInKernelAt(_InterruptAt):
    """A signal handler's KeyboardInterrupt raised inside a C call (a numba kernel
    boxing its result) surfaces as ``SystemError`` with the interrupt as context."""

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.steps:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt:
                raise SystemError("<CPUDispatcher> returned a result with an exception set")  # noqa: B904
        return True


def test_an_interrupt_wrapped_by_a_c_call_is_an_interruption() -> None:
    from aldm_gym.agents.training import _raised_by_interrupt

    try:
        _SignalInKernelAt(0)._on_step()
    except SystemError as exc:
        assert _raised_by_interrupt(exc)
    assert _raised_by_interrupt(KeyboardInterrupt())
    assert not _raised_by_interrupt(SystemError("a real fault"))
    try:
        try:
            raise ValueError("x")
        except ValueError:
            raise SystemError("y")  # noqa: B904
    except SystemError as exc:
        assert not _raised_by_interrupt(exc)


@pytest.mark.slow
def test_a_signal_inside_a_kernel_call_still_saves_the_checkpoint(tmp_path: Path) -> None:
    """SIGTERM landing in a numba call used to end the run with exit 1 and no save."""
    with pytest.raises(KeyboardInterrupt):
        train(
            tmp_path,
            timesteps=96,
            params=PPOParams(n_steps=32),
            callback=_SignalInKernelAt(40),
            detector="naive",
            n_envs=1,
            duration=5.0,
            vehicles_count=5,
            checkpoint_freq=1000,
            validation_freq=0,
            progress=False,
        )
    assert latest_checkpoint(tmp_path)[2] == 32
    # A SystemError of another cause is not taken for an interruption.
    with pytest.raises(SystemError):
        train(
            tmp_path / "other",
            timesteps=96,
            params=PPOParams(n_steps=32),
            callback=_RaiseAt(40, SystemError("a real fault")),
            detector="naive",
            n_envs=1,
            duration=5.0,
            vehicles_count=5,
            checkpoint_freq=1000,
            validation_freq=0,
            progress=False,
        )


class _RaiseAt(_InterruptAt):
    """Raise ``exc`` once ``steps`` steps are done."""

    def __init__(self, steps: int, exc: BaseException) -> None:
        super().__init__(steps)
        self.exc = exc

    def _on_step(self) -> bool:
        if self.num_timesteps >= self.steps:
            raise self.exc
        return True
