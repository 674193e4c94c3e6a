"""A training survives faults: kills, signals mid-update, a second writer, corrupt files.

Every killed or interrupted training, once resumed, ends at its budget with checkpoints
whose weights and normalisation statistics equal those of an uninterrupted run at the
same step (exact resume). Tests that train are marked slow; each trains a few hundred
steps of 32-step rollouts.
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
import warnings
import zipfile
from pathlib import Path
from typing import Any

import pytest
from _cli import usage_error

from aldm_gym.agents.checkpoints import (
    LOCK_FILE,
    OutputLocked,
    Snapshot,
    TrainingWarning,
    checkpoint_paths,
    manifest_path,
    newest_intact_checkpoint,
    output_lock,
    resume_state_path,
    save_atomic,
    write_checkpoint,
)
from aldm_gym.cli import main

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


# --- checkpoint files, lock: no training needed ----------------------------------------


def _fake_snapshot(steps: int) -> Snapshot:
    return Snapshot(steps, b"model %d" % steps, b"vecnorm %d" % steps, b"state %d" % steps)


def _corrupt(path: Path, how: str) -> None:
    data = path.read_bytes()
    if how == "truncate":
        path.write_bytes(data[: len(data) // 2])
    else:  # flip one byte in the middle
        i = len(data) // 2
        path.write_bytes(data[:i] + bytes([data[i] ^ 0xFF]) + data[i + 1 :])


@pytest.mark.parametrize(
    ("which", "how"),
    [
        ("model", "truncate"),
        ("model", "flip"),
        ("vecnormalize", "truncate"),
        ("vecnormalize", "flip"),
        ("resume", "truncate"),
        ("manifest", "missing"),
    ],
)
def test_corrupt_newest_checkpoint_falls_back_with_a_warning(
    tmp_path: Path, which: str, how: str
) -> None:
    for steps in (32, 64):
        write_checkpoint(tmp_path, _fake_snapshot(steps))
    model, vecnorm = checkpoint_paths(tmp_path, 64)
    path = {
        "model": model,
        "vecnormalize": vecnorm,
        "resume": resume_state_path(tmp_path, 64),
        "manifest": manifest_path(tmp_path, 64),
    }[which]
    if how == "missing":
        path.unlink()
    else:
        _corrupt(path, how)
    with pytest.warns(TrainingWarning, match=f"checkpoint 64: {path}"):
        found = newest_intact_checkpoint(tmp_path)
    assert found is not None and found.steps == 32
    assert found.model.read_bytes() == b"model 32"


def test_intact_checkpoints_need_no_warning(tmp_path: Path) -> None:
    write_checkpoint(tmp_path, _fake_snapshot(32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = newest_intact_checkpoint(tmp_path)
    assert found is not None and found.steps == 32 and found.resume_state is not None


def test_checkpoints_without_manifest_are_checked_by_structure(tmp_path: Path) -> None:
    """Checkpoints of older versions (model + normalisation only) still resume, and a
    truncated zip or pickle among them is skipped."""
    for steps in (32, 64):
        model, vecnorm = checkpoint_paths(tmp_path, steps)
        model.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(model, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("data", "x" * 1000)
        vecnorm.write_bytes(pickle.dumps({"steps": steps}))
    found = newest_intact_checkpoint(tmp_path)
    assert found is not None and (found.steps, found.resume_state) == (64, None)
    _corrupt(checkpoint_paths(tmp_path, 64)[0], "truncate")
    with pytest.warns(TrainingWarning, match="model_64_steps.zip"):
        assert newest_intact_checkpoint(tmp_path).steps == 32  # type: ignore[union-attr]
    _corrupt(checkpoint_paths(tmp_path, 32)[1], "truncate")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert newest_intact_checkpoint(tmp_path) is None
    assert [str(w.message).split(":")[0] for w in caught] == [
        "skipping checkpoint 64",
        "skipping checkpoint 32",
    ]
    assert "vecnormalize_32_steps.pkl" in str(caught[1].message)


def test_atomic_saves_use_unique_temporary_files(tmp_path: Path) -> None:
    names: list[str] = []

    def save(tmp: Path) -> None:
        names.append(tmp.name)
        assert tmp.parent == tmp_path and tmp.name.endswith(".zip")  # SB3 keeps the name
        tmp.write_bytes(b"new")

    save_atomic(save, tmp_path / "model.zip")
    save_atomic(save, tmp_path / "model.zip")
    assert names[0] != names[1]
    assert (tmp_path / "model.zip").read_bytes() == b"new"

    def fail(tmp: Path) -> None:
        tmp.write_bytes(b"half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        save_atomic(fail, tmp_path / "model.zip")
    assert (tmp_path / "model.zip").read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.zip"]


def test_evaluating_a_corrupt_model_names_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    pytest.importorskip("stable_baselines3")
    model = tmp_path / "model.zip"
    with zipfile.ZipFile(model, "w") as archive:
        archive.writestr("data", "{}")
    model.write_bytes(model.read_bytes()[:20])
    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}}))
    line = usage_error(["evaluate", "--model", str(model), "--no-progress"], capsys)
    assert f"argument --model: {model}: not a readable model" in line


_HOLD_LOCK = """
import sys, time
from aldm_gym.agents.checkpoints import output_lock
with output_lock(sys.argv[1]):
    print("locked", flush=True)
    time.sleep(60)
"""


def test_a_second_writer_is_refused_naming_the_holder(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", _HOLD_LOCK, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        with pytest.raises(OutputLocked, match=f"pid {holder.pid}"):
            with output_lock(tmp_path):
                pass
        line = usage_error(["train", "--out", str(tmp_path), "--no-progress"], capsys)
        assert f"argument --out: {tmp_path} is being written by another training " in line
        assert f"(pid {holder.pid}," in line
        argv = ["train", "--resume", "--out", str(tmp_path), "--no-progress"]
        assert f"(pid {holder.pid}," in usage_error(argv, capsys)
    finally:
        holder.kill()
        holder.wait()
    # Killed while holding it: the kernel released the lock; the next writer takes it
    # over and says whose it was.
    with pytest.warns(TrainingWarning, match=f"took over the lock of pid {holder.pid}"):
        with output_lock(tmp_path):
            assert (tmp_path / LOCK_FILE).read_text().strip() == str(os.getpid())
    assert (tmp_path / LOCK_FILE).read_text() == ""  # released cleanly: no warning next
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with output_lock(tmp_path):
            pass


# --- trainings ---------------------------------------------------------------------------


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
    the weights and normalisation after the 1st update, labelled 32 (it used to hold
    the half-updated weights, and statistics of the discarded rollout)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from aldm_gym.agents.training import PPOParams, train

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
    _corrupt(checkpoint_paths(out, 160)[0], "truncate")
    _corrupt(checkpoint_paths(out, 128)[0], "flip")
    _corrupt(checkpoint_paths(out, 96)[1], "truncate")
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
    # The run's checkpoint period was kept (it used to fall back to 4096).
    assert _steps_of(out) == [64, 128, 192]
    meta = json.loads((out / "training.json").read_text())
    assert (meta["checkpoint_freq"], meta["seed"], meta["timesteps"]) == (64, 3, 192)


# --- numba's cache -------------------------------------------------------------------

_KERNEL = """
import numpy as np
import aldm_gym._numba  # the guards (aldm_gym/__init__.py imports it first)
from aldm_gym.sensor.trajectory import _cubic_ok
print(bool(_cubic_ok(np.zeros((5, 2)))))
"""


def _run_kernel(env: dict[str, str], cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", _KERNEL], capture_output=True, text=True, env=env, cwd=cwd
    )


def test_a_corrupt_numba_cache_entry_is_recompiled_with_a_warning(tmp_path: Path) -> None:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    env.pop("NUMBA_DISABLE_JIT", None)
    first = _run_kernel(env)
    assert first.returncode == 0, first.stderr
    # A cold cache announces the compile, once.
    assert first.stderr.count("aldm-gym: compiling numba kernels") == 1, first.stderr
    (index,) = tmp_path.rglob("trajectory._cubic_ok_py-*.nbi")
    (data,) = tmp_path.rglob("trajectory._cubic_ok_py-*.nbc")
    for broken in (data, index):
        broken.write_bytes(broken.read_bytes()[:7])  # truncated, as by a full disk
        run = _run_kernel(env)
        assert run.returncode == 0 and run.stdout.strip() == "False", run.stderr
        lines = [line for line in run.stderr.splitlines() if "NumbaCacheWarning" in line]
        assert len(lines) == 1 and lines[0].startswith(f"{broken}:0: "), run.stderr
        # The entry was written again: the next run loads it silently.
        again = _run_kernel(env)
        assert again.returncode == 0 and "Warning" not in again.stderr, again.stderr
        assert "compiling" not in again.stderr, again.stderr


def test_without_a_writable_numba_cache_the_kernels_compile_in_memory(tmp_path: Path) -> None:
    """A copy of the package whose __pycache__ folders cannot be created, no user cache
    folder and no NUMBA_CACHE_DIR: numba used to refuse to decorate the kernels."""
    package = Path(__file__).resolve().parents[1] / "aldm_gym"
    copy = tmp_path / "aldm_gym"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    for folder in [copy, *[p for p in copy.rglob("*") if p.is_dir()]]:
        (folder / "__pycache__").write_text("a file where numba wants a folder")
    env = {**os.environ, "PYTHONPATH": str(tmp_path), "XDG_CACHE_HOME": "/dev/null/cache"}
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    for name in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT"):
        env.pop(name, None)
    run = _run_kernel(env, cwd=tmp_path)
    assert run.returncode == 0 and run.stdout.strip() == "False", run.stderr
    lines = [line for line in run.stderr.splitlines() if "NumbaCacheWarning" in line]
    assert len(lines) == 1 and "compiling aldm_gym's kernels in memory" in lines[0]


_CALLER = """
import numpy as np
import aldm_gym._numba  # the guards (aldm_gym/__init__.py imports it first)
from aldm_gym.sensor.aldm_kernels.robust import _seed_chains
xs = np.array([1.0, 2.0, 3.0]); ys = np.array([0.0, 0.1, 5.0])
print(_seed_chains(xs, ys, 3, 4.5, 1.5).tolist())
"""


def test_a_kernel_is_recompiled_when_a_kernel_it_calls_changes(tmp_path: Path) -> None:
    """numba keys a cached kernel by its own file's time and size: ``_seed_chains``
    (robust.py) kept the machine code of ``_bucket_order`` (sort.py) after sort.py
    changed. The package keys every kernel by one digest of all kernel sources."""
    package = Path(__file__).resolve().parents[1] / "aldm_gym"
    copy = tmp_path / "pkg" / "aldm_gym"
    shutil.copytree(package, copy, ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(copy.parent), "NUMBA_CACHE_DIR": str(tmp_path / "c")}
    env.pop("NUMBA_DISABLE_JIT", None)

    def run() -> subprocess.CompletedProcess:
        got = subprocess.run(
            [sys.executable, "-c", _CALLER], capture_output=True, text=True, env=env, cwd=tmp_path
        )
        assert got.returncode == 0 and got.stdout.strip() == "[0, 0, 2]", got.stderr
        return got

    assert "compiling" in run().stderr
    assert "compiling" not in run().stderr
    callee = copy / "sensor" / "aldm_kernels" / "sort.py"
    os.utime(callee, (1.0, 1.0))  # a new time, the same text: still cached
    assert "compiling" not in run().stderr
    callee.write_text(callee.read_text() + "\n# edited\n")
    assert "compiling" in run().stderr  # robust.py did not change, its kernel did
