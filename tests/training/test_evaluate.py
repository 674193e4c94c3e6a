"""``aldm-gym evaluate``: a model file, a checkpoint or a training's output folder;
argument errors in one line.

Tests that train are marked slow.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import pytest
from _cli import usage_error

from aldm_gym.cli import main

from ._helpers import tiny_train


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


def test_an_output_folder_without_a_model_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}}))
    line = usage_error(["evaluate", "--model", str(tmp_path)], capsys)
    assert f"argument --model: {tmp_path} holds no trained model (none of best_model.zip" in line


@pytest.mark.slow
def test_evaluate_takes_the_best_else_the_final_model_of_an_output_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    pytest.importorskip("stable_baselines3")
    out = tmp_path / "run"
    assert tiny_train(out, 64, "--validation-freq", "32", "--validation-episodes", "1") == 0
    capsys.readouterr()
    evaluate = ["evaluate", "--model", str(out), "--episodes", "1", "--no-progress"]
    assert main(evaluate) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == f"evaluating {out / 'best_model.zip'}: the best validation's model"
    assert lines[1].startswith(f"wrote {out / 'evaluate_best_model_aldm_per_dash.json'} (")
    best = json.loads((out / "evaluate_best_model_aldm_per_dash.json").read_text())
    assert best["timesteps"] == json.loads((out / "validation.json").read_text())["best_steps"]
    (out / "best_model.zip").unlink()
    assert main([*evaluate, "--out", str(tmp_path / "eval")]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == f"evaluating {out / 'model.zip'}: the final model"
    final = json.loads((tmp_path / "eval" / "evaluate_model_aldm_per_dash.json").read_text())
    assert final["timesteps"] == 64
    # A model named itself is evaluated without a word about picking it.
    assert main([*evaluate[:2], str(out / "model.zip"), *evaluate[3:]]) == 0
    assert capsys.readouterr().out.startswith("wrote ")
