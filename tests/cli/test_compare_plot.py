"""Command line: compare writes the CSV and figures; bad arguments give clear errors."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from _cli import usage_error

import aldm_gym
from aldm_gym.agents.closed_loop import CLOSED_LOOP_COLUMNS
from aldm_gym.cli import main
from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor.detectors import make_detector
from aldm_gym.sensor.open_loop import COLUMNS, compare_detectors


@pytest.mark.slow
def test_compare_quick_writes_csvs_and_figures(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = ["compare", "--quick", "--roads", "1", "--frames", "12", "--episodes", "1"]
    rc = main([*argv, "--scenes", "12", "--out", str(tmp_path), "--no-progress"])
    assert rc == 0
    with open(tmp_path / "compare_targets.csv") as fh:
        targets = {(r["marking_model"], r["detector"]): r for r in csv.DictReader(fh)}
    assert float(targets[("per_dash", "aldm")]["accuracy"]) == 1.0
    assert (tmp_path / "compare_targets.png").stat().st_size > 10_000
    pairs = {(m, d) for m in ("per_dash", "editor") for d in ("naive", "aldm", "ground_truth")}
    with open(tmp_path / "compare_frames.csv") as fh:
        frames = list(csv.DictReader(fh))
    assert list(frames[0]) == list(COLUMNS)
    assert {(r["marking_model"], r["detector"]) for r in frames} == pairs
    with open(tmp_path / "compare.csv") as fh:
        loop = list(csv.DictReader(fh))
    assert list(loop[0]) == list(CLOSED_LOOP_COLUMNS)
    assert {(r["marking_model"], r["detector"]) for r in loop} == pairs
    required = {"km", "departures_per_km", "rms_offset_m", "max_offset_m", "both_correct"}
    required |= {"mean_preview_m", "collisions", "lane_changes_ok", "lane_changes_failed"}
    assert required <= set(CLOSED_LOOP_COLUMNS)
    by = {(r["marking_model"], r["detector"]): r for r in loop}
    assert float(by[("per_dash", "aldm")]["departures_per_km"]) == 0.0
    assert float(by[("per_dash", "naive")]["both_correct"]) < 0.2
    names = ("compare_frames.png", "frame_per_dash.png", "frame_editor.png", "offset.png")
    for name in names:
        assert (tmp_path / name).stat().st_size > 10_000
    out = capsys.readouterr().out
    assert "Closed loop" in out and "both ok" in out
    assert "F1 1.5m" in out and "robust" in out
    metrics = {"strict_f1", "loose_f1", "strict_tp", "strict_fp", "strict_fn", "near_mean_m"}
    assert metrics <= set(COLUMNS)
    # The ground truth sees the same frames as the detectors, on both marking models.
    for model in ("per_dash", "editor"):
        gt = next(
            r for r in frames if (r["marking_model"], r["detector"]) == (model, "ground_truth")
        )
        assert float(gt["strict_f1"]) == 1.0


@pytest.mark.slow
def test_compare_with_the_camera_preset_adds_tracking_and_the_conditions_frame(
    tmp_path: Path,
) -> None:
    argv = ["compare", "--quick", "--roads", "1", "--frames", "6", "--episodes", "1"]
    argv += ["--scenes", "4", "--sensor-preset", "camera", "--trucks", "0.2"]
    assert main([*argv, "--sensor", "visibility=120", "--out", str(tmp_path), "--no-progress"]) == 0
    with open(tmp_path / "compare.csv") as fh:
        loop = {(r["marking_model"], r["detector"]): r for r in csv.DictReader(fh)}
    detectors = ("naive", "aldm", "aldm_tracking", "aldm_filter", "ground_truth")
    assert set(loop) == {(m, d) for m in ("per_dash", "editor") for d in detectors}
    assert [r[1] for r in loop][:5] == list(detectors)  # the stateful rows beside the ALDM
    assert 0.0 <= float(loop[("per_dash", "aldm_filter")]["both_correct"]) <= 1.0
    # visibility 120 m (wins over the preset's 150 m): no detected line reaches further
    assert float(loop[("per_dash", "aldm")]["mean_preview_m"]) <= 120.0
    assert float(loop[("per_dash", "ground_truth")]["both_correct"]) == 1.0
    assert (tmp_path / "frame_conditions.png").stat().st_size > 10_000


def test_compare_mode_paper_names_the_mode(tmp_path: Path) -> None:
    argv = ["compare", "--quick", "--roads", "1", "--frames", "4", "--scenes", "6"]
    argv += ["--mode", "paper", "--no-closed-loop", "--out", str(tmp_path), "--no-progress"]
    assert main(argv) == 0
    with open(tmp_path / "compare_targets.csv") as fh:
        modes = {r["detector"]: r["mode"] for r in csv.DictReader(fh)}
    assert modes == {"naive": "", "aldm": "paper", "ground_truth": ""}
    with open(tmp_path / "compare_frames.csv") as fh:
        frames = {(r["detector"], r["mode"]) for r in csv.DictReader(fh)}
    assert {("aldm", "robust"), ("aldm", "paper")} <= frames  # the open loop has both


def test_closed_loop_rejects_an_unknown_aldm_mode() -> None:
    from aldm_gym.agents.closed_loop import compare_closed_loop

    with pytest.raises(
        ValueError, match=r"aldm_mode must be one of \['robust', 'paper'\], got 'fast'"
    ):
        compare_closed_loop([0], aldm_mode="fast")


def test_conditions_on_and_detector_variants() -> None:
    import argparse

    from aldm_gym.agents.closed_loop import compare_closed_loop
    from aldm_gym.cli.compare import conditions_on, sensor_settings

    assert not conditions_on({})
    assert not conditions_on({"lateral_noise": 0.1, "dropout": 0.2})
    assert conditions_on({"preset": "camera"})
    assert conditions_on({"occlusion": True})
    assert conditions_on({"preset": "camera", "occlusion": False})  # the rest stay on
    args = argparse.Namespace(
        sensor_preset="camera", sensor=[("occlusion", False)], noise=0.05, dropout=None
    )
    assert sensor_settings(args) == {"preset": "camera", "occlusion": False, "lateral_noise": 0.05}
    with pytest.raises(ValueError, match=r"unknown detector\(s\) \['aldm_tracker'\]"):
        compare_closed_loop([0], detectors=["aldm_tracker"])


def test_headline_naive_fails_on_per_dash_aldm_holds() -> None:
    base = HighwayRoad({"seed": 5})
    roads = [base, base.with_marking_model("editor")]
    rows = compare_detectors(roads, frames_per_road=40, seed=1)
    got = {(r["marking_model"], r["detector"]): r["both_correct"] for r in rows}
    assert got[("per_dash", "naive")] < 0.1
    assert got[("editor", "naive")] > 0.95
    assert got[("per_dash", "aldm")] > 0.95
    assert got[("editor", "aldm")] > 0.95
    assert got[("per_dash", "ground_truth")] == 1.0


def test_plot_writes_png(tmp_path: Path) -> None:
    out = tmp_path / "f.png"
    assert main(["plot", "--s", "1500", "--lane", "2", "--out", str(out)]) == 0
    assert out.stat().st_size > 10_000


@pytest.mark.parametrize(
    "argv",
    [
        ["compare", "--frames", "0"],
        ["compare", "--dropout", "1.5"],
        ["compare", "--noise", "-1"],
        ["compare", "--mode", "fast"],
        ["plot", "--marking-model", "opendrive"],
        ["nonsense"],
    ],
)
def test_bad_arguments_exit_with_usage(argv: list[str], capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert "usage" in capsys.readouterr().err


def test_plot_rejects_a_lane_outside_the_road(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    line = usage_error(["plot", "--lane", "9", "--out", str(tmp_path / "x.png")], capsys)
    assert "argument --lane: must be in [0, 3], got 9" in line


def test_unknown_detector() -> None:
    with pytest.raises(ValueError, match=r"allowed: \['naive', 'aldm', 'ground_truth'\]"):
        make_detector("perfect")


MAP = Path(aldm_gym.__file__).parent / "roads" / "maps" / "motorway.xodr"


@pytest.mark.skipif(not MAP.exists(), reason="shipped maps not built")
def test_compare_frames_on_a_map(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    argv = ["compare", "--xodr", str(MAP), "--quick", "--roads", "1", "--frames", "12"]
    rc = main([*argv, "--no-closed-loop", "--out", str(tmp_path), "--no-progress"])
    assert rc == 0
    with open(tmp_path / "compare_frames.csv") as fh:
        frames = {(r["marking_model"], r["detector"]): r for r in csv.DictReader(fh)}
    assert float(frames[("per_dash", "ground_truth")]["both_correct"]) > 0.9
    assert float(frames[("per_dash", "naive")]["both_correct"]) < 0.5
    assert "motorway.xodr" in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.skipif(not MAP.exists(), reason="shipped maps not built")
def test_compare_closed_loop_on_a_map(tmp_path: Path) -> None:
    argv = ["compare", "--xodr", str(MAP), "--quick", "--roads", "1", "--frames", "4"]
    assert main([*argv, "--episodes", "1", "--out", str(tmp_path), "--no-progress"]) == 0
    with open(tmp_path / "compare.csv") as fh:
        loop = {(r["marking_model"], r["detector"]): r for r in csv.DictReader(fh)}
    assert float(loop[("per_dash", "aldm")]["departures_per_km"]) == 0.0


@pytest.mark.skipif(not MAP.exists(), reason="shipped maps not built")
def test_plot_on_a_map(tmp_path: Path) -> None:
    out = tmp_path / "m.png"
    assert main(["plot", "--xodr", str(MAP), "--out", str(out)]) == 0
    assert out.stat().st_size > 10_000
    out2 = tmp_path / "m2.png"
    argv = ["plot", "--xodr", str(MAP), "--road-id", "3", "--lane-id", "-2", "--s", "100"]
    assert main([*argv, "--out", str(out2)]) == 0


def test_map_arguments_name_the_problem(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    missing = str(tmp_path / "nowhere.xodr")
    line = usage_error(["compare", "--xodr", missing, "--out", str(tmp_path)], capsys)
    assert f"argument --xodr: {missing} does not exist" in line
    line = usage_error(["plot", "--xodr", missing, "--out", str(tmp_path / "x.png")], capsys)
    assert f"argument --xodr: {missing} does not exist" in line
    if MAP.exists():
        argv = ["plot", "--xodr", str(MAP), "--road-id", "3", "--lane-id", "-7", "--s", "9"]
        line = usage_error([*argv, "--out", str(tmp_path / "x.png")], capsys)
        assert "no lane -7" in line
