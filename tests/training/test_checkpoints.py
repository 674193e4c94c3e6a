"""Checkpoints on disk: SB3's are checked against their manifest, RLlib's folders count
once complete; a damaged newest one is skipped with a warning naming the file."""

from __future__ import annotations

import json
import pickle
import warnings
import zipfile
from pathlib import Path

import pytest

from aldm_gym.errors import TrainingWarning
from aldm_gym.training.outputs import (
    checkpoint_paths,
    manifest_path,
    remove_temporary_files,
    resume_state_path,
)
from aldm_gym.training.rllib.checkpoints import (
    STEPS_FILE,
    checkpoint_steps,
    is_checkpoint,
    newest_checkpoint,
)
from aldm_gym.training.sb3.checkpoints import (
    Snapshot,
    newest_intact_checkpoint,
    write_checkpoint,
)

from ._helpers import corrupt


def fake_snapshot(steps: int) -> Snapshot:
    """A snapshot of recognisable bytes."""
    return Snapshot(steps, b"model %d" % steps, b"vecnorm %d" % steps, b"state %d" % steps)


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
        write_checkpoint(tmp_path, fake_snapshot(steps))
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
        corrupt(path, how)
    with pytest.warns(TrainingWarning, match=f"checkpoint 64: {path}"):
        found = newest_intact_checkpoint(tmp_path)
    assert found is not None and found.steps == 32
    assert found.model.read_bytes() == b"model 32"


def test_intact_checkpoints_need_no_warning(tmp_path: Path) -> None:
    write_checkpoint(tmp_path, fake_snapshot(32))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = newest_intact_checkpoint(tmp_path)
    assert found is not None and found.steps == 32 and found.resume_state is not None


def test_checkpoints_without_manifest_are_checked_by_structure(tmp_path: Path) -> None:
    """Checkpoints of model and normalisation only still resume, and a truncated zip or
    pickle among them is skipped."""
    for steps in (32, 64):
        model, vecnorm = checkpoint_paths(tmp_path, steps)
        model.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(model, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("data", "x" * 1000)
        vecnorm.write_bytes(pickle.dumps({"steps": steps}))
    found = newest_intact_checkpoint(tmp_path)
    assert found is not None and (found.steps, found.resume_state) == (64, None)
    corrupt(checkpoint_paths(tmp_path, 64)[0], "truncate")
    with pytest.warns(TrainingWarning, match="model_64_steps.zip"):
        assert newest_intact_checkpoint(tmp_path).steps == 32  # type: ignore[union-attr]
    corrupt(checkpoint_paths(tmp_path, 32)[1], "truncate")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert newest_intact_checkpoint(tmp_path) is None
    assert [str(w.message).split(":")[0] for w in caught] == [
        "skipping checkpoint 64",
        "skipping checkpoint 32",
    ]
    assert "vecnormalize_32_steps.pkl" in str(caught[1].message)


def fake_rllib_checkpoint(path: Path, steps: int | None) -> Path:
    """A folder shaped like an RLlib checkpoint; complete if ``steps`` is given."""
    path.mkdir(parents=True)
    (path / "rllib_checkpoint.json").write_text("{}")
    if steps is not None:
        (path / STEPS_FILE).write_text(json.dumps({"steps": steps}))
    return path


def test_only_complete_rllib_checkpoints_are_resumed_from(tmp_path: Path) -> None:
    ckpt = tmp_path / "checkpoints"
    fake_rllib_checkpoint(ckpt / "rllib_128", 128)
    fake_rllib_checkpoint(ckpt / "rllib_1024", 1024)
    fake_rllib_checkpoint(ckpt / "rllib_2048", None)  # renamed in before its steps file: never
    fake_rllib_checkpoint(ckpt / ".rllib_4096.tmpab12", 4096)  # still being written
    newest = newest_checkpoint(tmp_path)
    assert newest == ckpt / "rllib_1024" and checkpoint_steps(newest) == 1024
    assert not is_checkpoint(ckpt / "rllib_2048")
    removed = remove_temporary_files(tmp_path)
    assert removed == [ckpt / ".rllib_4096.tmpab12"]
    assert not removed[0].exists() and (ckpt / "rllib_1024").exists()


def test_no_rllib_checkpoint_in_an_empty_folder(tmp_path: Path) -> None:
    assert newest_checkpoint(tmp_path) is None
