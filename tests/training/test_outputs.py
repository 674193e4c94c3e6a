"""A training's output folder: finding its files, writing them atomically, picking the
model to evaluate."""

from __future__ import annotations

from pathlib import Path

import pytest
from _cli import usage_error

from aldm_gym.errors import CheckpointError
from aldm_gym.training.outputs import (
    can_resume,
    checkpoint_paths,
    find_training_file,
    holds_training,
    latest_checkpoint,
    rllib_checkpoint_path,
    save_atomic,
    trained_model,
)
from aldm_gym.training.sb3.checkpoints import vecnormalize_for


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


@pytest.mark.parametrize(
    "made", ["model.zip", "rllib_model/rllib_checkpoint.json", "checkpoints/rllib_64/x"]
)
def test_either_backends_model_or_checkpoint_alone_holds_a_training(
    tmp_path: Path, made: str
) -> None:
    _touch(tmp_path / made)
    assert holds_training(tmp_path) and not can_resume(tmp_path)


@pytest.mark.parametrize(
    ("files", "picked", "what"),
    [
        (["best_model.zip", "model.zip"], "best_model.zip", "the best validation's model"),
        (["model.zip"], "model.zip", "the final model"),
        (["rllib_model/rllib_checkpoint.json"], "rllib_model", "the final RLlib checkpoint"),
    ],
)
def test_an_output_folder_offers_its_best_else_its_final_model(
    tmp_path: Path, files: list[str], picked: str, what: str
) -> None:
    for name in files:
        _touch(tmp_path / name)
    assert trained_model(tmp_path) == (tmp_path / picked, what)


def test_an_unfinished_training_names_its_newest_checkpoint(tmp_path: Path) -> None:
    with pytest.raises(CheckpointError, match="holds no trained model") as exc:
        trained_model(tmp_path)
    assert "e.g." not in str(exc.value)
    for steps in (32, 64):
        _touch(checkpoint_paths(tmp_path, steps)[0])
    _touch(rllib_checkpoint_path(tmp_path, 128) / "x")
    with pytest.raises(CheckpointError, match=r"e\.g\. .*model_64_steps\.zip"):
        trained_model(tmp_path)


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
