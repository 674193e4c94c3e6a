"""A training survives faults: kills, signals mid-update or inside a kernel call,
corrupt checkpoints.

Every killed or interrupted training, once resumed, ends at its budget with checkpoints
whose weights and normalisation statistics equal those of an uninterrupted run at the
same step (exact resume). Tests that train are marked slow; each trains a few hundred
steps of 32-step rollouts. (A second writer and corrupt checkpoint files without a
training: ``test_lock.py``, ``test_checkpoints.py``.)
"""

from __future__ import annotations

import io
import json
import os
import pickle
import random
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("stable_baselines3")

from aldm_gym.cli import main
from aldm_gym.training.outputs import checkpoint_paths, latest_checkpoint
from aldm_gym.training.sb3.backend import train
from aldm_gym.training.settings import PPOParams

from ._helpers import TINY_KWARGS, corrupt
from ._sb3_callbacks import RaiseAt, SignalInKernelAt

BUDGET = 160
"""Policy steps of the fault runs (five 32-step rollouts)."""

RUN = [
    *("--n-envs", "1", "--n-steps", "32", "--duration", "5", "--vehicles", "5"),
    *("--detector", "naive", "--validation-freq", "0", "--checkpoint-freq", "32"),
    "--no-progress",
]
"""A training of a few seconds, a checkpoint after every rollout."""


def _cli(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "aldm_gym.cli", "train", "--out", str(out), *extra]


def _steps_of(out: Path) -> list[int]:
    return sorted(
        int(p.name.split("_")[1]) for p in (out / "checkpoints").glob("model_*_steps.zip")
    )


def _weights(model_zip: Path) -> dict[str, Any]:
    import torch

    with zipfile.ZipFile(model_zip) as archive:
        return torch.load(io.BytesIO(archive.read("policy.pth")), map_location="cpu")


def _obs_stats(vecnorm_pkl: Path) -> dict[str, Any]:
    with open(vecnorm_pkl, "rb") as fh:
        vecnorm = pickle.load(fh)
    return {k: (rms.mean, rms.var, rms.count) for k, rms in vecnorm.obs_rms.items()}


def _assert_same_state(a: tuple[Path, Path], b: tuple[Path, Path]) -> None:
    import numpy as np
    import torch

    wa, wb = _weights(a[0]), _weights(b[0])
    assert wa.keys() == wb.keys()
    assert all(torch.equal(wa[k], wb[k]) for k in wa), f"{a[0]} != {b[0]}"
    sa, sb = _obs_stats(a[1]), _obs_stats(b[1])
    assert sa.keys() == sb.keys()
    for k in sa:
        assert np.array_equal(sa[k][0], sb[k][0]) and np.array_equal(sa[k][1], sb[k][1])
        assert sa[k][2] == sb[k][2], f"{a[1]}: normalisation counts differ for {k}"


def _assert_matches_reference(out: Path, reference: Path) -> None:
    """Every checkpoint of ``out`` and its final model hold the reference's state."""
    steps = _steps_of(out)
    if steps and steps[0] == 0:
        # A SIGTERM before the first rollout saves the untrained start (the reference,
        # never interrupted, has no such snapshot): it must load at step 0.
        from stable_baselines3 import PPO

        assert PPO.load(checkpoint_paths(out, 0)[0], device="cpu").num_timesteps == 0
        steps = steps[1:]
    assert steps and set(steps) <= set(_steps_of(reference))
    for s in steps:
        _assert_same_state(checkpoint_paths(out, s), checkpoint_paths(reference, s))
    _assert_same_state(
        (out / "model.zip", out / "vecnormalize.pkl"),
        (reference / "model.zip", reference / "vecnormalize.pkl"),
    )
    assert not [p for p in out.rglob(".*") if p.is_file() and ".tmp" in p.name]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, float]:
    """An uninterrupted run of :data:`BUDGET` steps, and its wall time [s]."""
    out = tmp_path_factory.mktemp("faults") / "reference"
    t0 = time.perf_counter()
    subprocess.run(_cli(out, "--timesteps", str(BUDGET), *RUN), check=True, capture_output=True)
    assert _steps_of(out) == [32, 64, 96, 128, 160]
    return out, time.perf_counter() - t0


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sig", "seed"),
    [(signal.SIGKILL, 0), (signal.SIGKILL, 1), (signal.SIGTERM, 0), (signal.SIGTERM, 1)],
)
def test_killed_training_resumes_to_the_uninterrupted_result(
    tmp_path: Path, reference: tuple[Path, float], sig: signal.Signals, seed: int
) -> None:
    """Two kills at seeded random instants (startup, collecting, updating, saving),
    then ``--resume`` until done: the budget is reached and every checkpoint equals
    the uninterrupted run's at its step."""
    ref, wall = reference
    rng = random.Random(seed)
    out = tmp_path / "run"
    killed = 0
    for _attempt in range(6):
        resume = ["--resume"] if (out / "training.json").exists() else []
        args = ["--timesteps", str(BUDGET), *RUN] if not resume else ["--no-progress"]
        proc = subprocess.Popen(
            _cli(out, *resume, *args), stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        if killed < 2:
            try:
                proc.wait(timeout=rng.uniform(0.3, 1.0) * wall)
            except subprocess.TimeoutExpired:
                proc.send_signal(sig)
                killed += 1
        _, err = proc.communicate(timeout=300)
        if proc.returncode == 0:
            break
        # SIGTERM: 130 after saving, or -15 when it came before the handler was set.
        assert proc.returncode in (-int(sig), 130), err.decode()[-2000:]
    else:
        pytest.fail("the training never completed")
    import torch  # noqa: F401  (the checks below read torch files)
    from stable_baselines3 import PPO

    assert PPO.load(out / "model.zip", device="cpu").num_timesteps == BUDGET
    assert json.loads((out / "training.json").read_text())["checkpoint_freq"] == 32
    _assert_matches_reference(out, ref)


@pytest.mark.slow
def test_sigterm_during_the_update_saves_the_last_consistent_state(
    tmp_path: Path, reference: tuple[Path, float]
) -> None:
    """SIGTERM after a few gradient steps of the 2nd update: the checkpoint saved holds
    the weights and normalisation after the 1st update, labelled 32 (not the
    half-updated weights, nor statistics of the discarded rollout)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class SigtermInSecondUpdate(BaseCallback):
        def _on_rollout_end(self) -> None:
            if self.num_timesteps < 64:
                return
            optimizer = self.model.policy.optimizer
            step, calls = optimizer.step, [0]

            def counting_step(*args: Any, **kwargs: Any) -> Any:
                calls[0] += 1
                if calls[0] == 4:
                    os.kill(os.getpid(), signal.SIGTERM)
                return step(*args, **kwargs)

            optimizer.step = counting_step

        def _on_step(self) -> bool:
            return True

    ref, _ = reference
    kwargs: dict[str, Any] = dict(
        detector="naive",
        duration=5.0,
        vehicles_count=5,
        validation_freq=0,
        progress=False,
        params=PPOParams(n_steps=32),
    )
    with pytest.raises(KeyboardInterrupt):
        train(
            tmp_path,
            timesteps=BUDGET,
            checkpoint_freq=1000,
            callback=SigtermInSecondUpdate(),
            **kwargs,
        )
    assert _steps_of(tmp_path) == [32]
    _assert_same_state(checkpoint_paths(tmp_path, 32), checkpoint_paths(ref, 32))
    # Resumed with the saved settings (checkpoint_freq 1000: only the final one).
    model = train(tmp_path, resume=True, **kwargs)
    assert model.num_timesteps == BUDGET
    assert _steps_of(tmp_path) == [32, 160]
    _assert_matches_reference(tmp_path, ref)


@pytest.mark.slow
def test_resume_skips_a_corrupt_newest_checkpoint(
    tmp_path: Path, reference: tuple[Path, float], capfd: pytest.CaptureFixture
) -> None:
    ref, _ = reference
    out = tmp_path / "run"
    shutil.copytree(ref, out)
    for name in ("model.zip", "vecnormalize.pkl"):
        (out / name).unlink()
    # The three newest checkpoints: a truncated zip, a flipped byte, a truncated pickle.
    corrupt(checkpoint_paths(out, 160)[0], "truncate")
    corrupt(checkpoint_paths(out, 128)[0], "flip")
    corrupt(checkpoint_paths(out, 96)[1], "truncate")
    assert main(["train", "--resume", "--out", str(out)]) == 0
    err = capfd.readouterr().err
    for steps, path in (
        (160, checkpoint_paths(out, 160)[0]),
        (128, checkpoint_paths(out, 128)[0]),
        (96, checkpoint_paths(out, 96)[1]),
    ):
        assert f"warning: skipping checkpoint {steps}: {path}" in err
    assert "resuming" in err and "at 64 steps" in err
    _assert_matches_reference(out, ref)


@pytest.mark.slow
def test_resume_restores_the_run_settings_unless_given(
    tmp_path: Path, capfd: pytest.CaptureFixture
) -> None:
    out = tmp_path / "run"
    i = RUN.index("--checkpoint-freq")
    run = RUN[:i] + RUN[i + 2 :]
    extra = ("--checkpoint-freq", "64", "--seed", "3")
    assert main(["train", "--out", str(out), "--timesteps", "64", *extra, *run]) == 0
    capfd.readouterr()
    assert main(["train", "--resume", "--out", str(out), "--timesteps", "192"]) == 0
    err = capfd.readouterr().err
    assert "checkpoint_freq=64" in err and "seed=3" in err
    assert "overridden: timesteps=192 (was 64)" in err
    # The run's checkpoint period is kept (not the default 4096).
    assert _steps_of(out) == [64, 128, 192]
    meta = json.loads((out / "training.json").read_text())
    assert (meta["checkpoint_freq"], meta["seed"], meta["timesteps"]) == (64, 3, 192)


@pytest.mark.slow
def test_a_signal_inside_a_kernel_call_still_saves_the_checkpoint(tmp_path: Path) -> None:
    """SIGTERM landing in a numba call (a ``SystemError`` carrying the interrupt) is an
    interruption like any other: the checkpoint is saved."""
    with pytest.raises(KeyboardInterrupt):
        train(
            tmp_path,
            timesteps=96,
            params=PPOParams(n_steps=32),
            callback=SignalInKernelAt(40),
            **TINY_KWARGS,
        )
    assert latest_checkpoint(tmp_path)[2] == 32
    # A SystemError of another cause is not taken for an interruption.
    with pytest.raises(SystemError):
        train(
            tmp_path / "other",
            timesteps=96,
            params=PPOParams(n_steps=32),
            callback=RaiseAt(40, SystemError("a real fault")),
            **TINY_KWARGS,
        )
