"""Every bad argument or path of ``aldm-gym`` ends in the subcommand's usage, one error
line naming the argument, and exit code 2: never a traceback."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from _cli import usage_error

import aldm_gym

MAP = Path(aldm_gym.__file__).parent / "roads" / "maps" / "motorway.xodr"


@pytest.fixture()
def paths(tmp_path: Path) -> dict[str, str]:
    """A plain file, a path below it, a folder, a missing file, and XML that is not
    OpenDRIVE."""
    afile = tmp_path / "afile"
    afile.write_text("hello")
    not_opendrive = tmp_path / "not_opendrive.xodr"
    not_opendrive.write_text("<xml/>")
    return {
        "FILE": str(afile),
        "BELOW_FILE": str(afile / "sub"),
        "DIR": str(tmp_path),
        "MISSING": str(tmp_path / "missing.xodr"),
        "NOT_OPENDRIVE": str(not_opendrive),
        "NOT_XML": str(afile),
        "MAP": str(MAP),
    }


CASES = [
    # compare
    (["compare", "--out", "FILE"], "--out", "exists and is not a folder"),
    (["compare", "--out", "BELOW_FILE"], "--out", "is not a folder"),
    (["compare", "--seed", "-1"], "--seed", "must be in [0, 2**31 - 1]"),
    (["compare", "--seed", "1.5"], "--seed", "must be an integer"),
    (["compare", "--episodes", "0"], "--episodes", "must be >= 1"),
    (["compare", "--min-radius", "50"], "--min-radius", "must be in [100, 3000] m"),
    (["compare", "--min-radius", "nan"], "--min-radius", "must be finite"),
    (["compare", "--min-radius", "5000"], "--min-radius", "must be in [100, 3000] m"),
    (["compare", "--noise", "nan"], "--noise", "must be finite"),
    (["compare", "--dropout", "-0.1"], "--dropout", "must be in [0, 1)"),
    (["compare", "--sensor", "occlusion"], "--sensor", "must be KEY=VALUE, got 'occlusion'"),
    (
        ["compare", "--sensor", "fog=1", "--out", "DIR"],
        "--sensor",
        "unknown sensor config key(s) ['fog']; allowed keys: [",
    ),
    (["compare", "--sensor", "visibility=-5", "--out", "DIR"], "--sensor", "sensor.visibility"),
    (["compare", "--sensor-preset", "lidar"], "--sensor-preset", "invalid choice: 'lidar'"),
    (["compare", "--trucks", "1.5"], "--trucks", "must be in [0, 1)"),
    (["compare", "--xodr", "MISSING"], "--xodr", "does not exist"),
    (["compare", "--xodr", "DIR"], "--xodr", "is not a file"),
    (["compare", "--xodr", "NOT_OPENDRIVE", "--out", "DIR"], "--xodr", "not <OpenDRIVE>"),
    (["compare", "--xodr", "NOT_XML", "--out", "DIR"], "--xodr", "malformed XML"),
    (["compare", "--xodr", "DIR/motorway.xodr"], "--xodr", "give just its name: --xodr motorway"),
    (
        ["compare", "--xodr", "MAP", "--min-radius", "300", "--out", "DIR"],
        "--min-radius",
        "applies to generated roads only, not with --xodr",
    ),
    (["compare", "--xodr", "MAP", "--scenes", "5", "--out", "DIR"], "--scenes", "generated roads"),
    (
        ["compare", "--no-closed-loop", "--episodes", "3", "--out", "DIR"],
        "--episodes",
        "applies to the closed loop, not with --no-closed-loop",
    ),
    (["compare", "--no-closed-loop", "--trucks", "0.2", "--out", "DIR"], "--trucks", "closed loop"),
    (["compare", "--no-closed-loop", "--tracking", "--out", "DIR"], "--tracking", "closed loop"),
    (
        ["compare", "--xodr", "MAP", "--no-closed-loop", "--mode", "paper", "--out", "DIR"],
        "--mode",
        "neither runs here",
    ),
    (
        ["compare", "--noise", "0.1", "--sensor", "lateral_noise=0.2", "--out", "DIR"],
        "--noise",
        "sets lateral_noise, and so does --sensor lateral_noise=...: give one",
    ),
    (["compare", "--dropout", "0.1", "--sensor", "dropout=0", "--out", "DIR"], "--dropout", "one"),
    # scenario
    (["scenario", "run", "MISSING"], "FILE.xosc", "does not exist"),
    (["scenario", "run", "MAP", "--video", "DIR/x.png"], "--video", "give a .gif file name"),
    (["scenario", "run", "MAP"], "FILE.xosc", "the root is <OpenDRIVE>, not <OpenSCENARIO>"),
    (["scenario", "run", "MAP", "--param", "novalue"], "--param", "must be KEY=VALUE"),
    (["scenario", "suite", "DIR", "--detectors", "naive,bogus"], "--detectors", "comma-separated"),
    (["scenario", "suite", "MISSING"], "DIR_OR_VARIATION", "does not exist"),
    (["scenario", "suite", "DIR", "--address", "nowhere"], "--address", "host:port"),
    (["scenario", "run", "MAP", "--env", "sensor.prest=camera"], "--env", "'preset'"),
    (["scenario", "run", "MAP", "--env", "detector=naive"], "--env", "set by --detector"),
    (["scenario", "run", "MAP", "--env", "osi.trace=a.mcap"], "--env", "set by --osi"),
    (["scenario", "suite", "DIR", "--env", "scenario.ego=A"], "--env", "set by the scenario file"),
    (["scenario", "suite", "DIR", "--env", "duration=-1"], "--env", "duration must be > 0"),
    (
        ["scenario", "suite", "DIR", "--env", "sensor=1", "--env", "sensor.preset=camera"],
        "--env",
        "not a section",
    ),
    # plot
    (["plot", "--out", "DIR"], "--out", "is a folder"),
    (["plot", "--out", "FILE"], "--out", "unknown image type"),
    (["plot", "--out", "BELOW_FILE/x.png"], "--out", "is not a folder"),
    (["plot", "--seed", "-1"], "--seed", "must be in [0, 2**31 - 1]"),
    (["plot", "--s", "nan"], "--s", "must be finite"),
    (["plot", "--s", "-5", "--out", "DIR/p.png"], "--s", "must be in [0, "),
    (["plot", "--lane", "-1", "--out", "DIR/p.png"], "--lane", "must be in [0, 3]"),
    (["plot", "--shift", "inf"], "--shift", "must be finite"),
    (["plot", "--shift", "100", "--out", "DIR/p.png"], "--shift", "a lane width"),
    (["plot", "--xodr", "MISSING"], "--xodr", "does not exist"),
    (["plot", "--xodr", "NOT_OPENDRIVE", "--out", "DIR/p.png"], "--xodr", "not <OpenDRIVE>"),
    (["plot", "--road-id", "3", "--out", "DIR/p.png"], "--road-id", "applies to --xodr maps only"),
    (["plot", "--lane-id", "-2", "--out", "DIR/p.png"], "--lane-id", "applies to --xodr maps"),
    (
        ["plot", "--xodr", "MAP", "--seed", "3", "--out", "DIR/p.png"],
        "--seed",
        "applies to generated roads only; on a map use --road-id/--lane-id",
    ),
    (["plot", "--xodr", "MAP", "--lane", "2", "--out", "DIR/p.png"], "--lane", "generated roads"),
    (["plot", "--xodr", "MAP", "--lane-id", "-2", "--out", "DIR/p.png"], "--lane-id", "--road-id"),
    (["plot", "--xodr", "MAP", "--s", "120", "--out", "DIR/p.png"], "--s", "needs --road-id"),
    # train (all found before stable-baselines3 is imported)
    (["train", "--out", "FILE"], "--out", "exists and is not a folder"),
    (["train", "--seed", "-1"], "--seed", "must be in [0, 2**31 - 1]"),
    (["train", "--seed", "99999999999"], "--seed", "must be in [0, 2**31 - 1]"),
    (["train", "--collision-reward", "nan"], "--collision-reward", "must be finite"),
    (["train", "--collision-reward", "1000"], "--collision-reward", "must be <= 100"),
    (["train", "--duration", "1e300"], "--duration", "must be <= 10000"),
    (["train", "--duration", "0"], "--duration", "must be > 0"),
    (["train", "--vehicles", "2.5"], "--vehicles", "must be an integer"),
    (["train", "--vehicles", "100000"], "--vehicles", "must be <= 500"),
    (["train", "--n-envs", "1000"], "--n-envs", "must be in [1, 64]"),
    (["train", "--n-steps", "1"], "--n-steps", "must be in [2, "),
    (["train", "--resume", "--out", "DIR/nothing"], "--resume", "nothing to resume"),
    (["train", "--env", "sensor.preset"], "--env", "must be KEY=VALUE"),
    (["tune", "--env", "sensor.prest=camera", "--out", "DIR/t"], "--env", "'preset'"),
    (["tune", "--env", "detector=naive"], "--env", "detector has its own flag: --detector"),
    (["tune", "--env", "duration=-1"], "--env", "duration must be > 0"),
    (["tune", "--env", "collision_reward=-5"], "--env", "collision_reward is searched"),
    (["tune", "--pretrain-epochs", "3", "--out", "DIR/t"], "--pretrain-epochs", "needs --pretrain"),
    (["tune", "--pretrain-episodes", "0"], "--pretrain-episodes", "must be in [1, 10000]"),
    (
        ["tune", "--pretrain-episodes", "5", "--env", "overtaking_reward=0.2"],
        "--env",
        "overtaking_reward is searched",
    ),
    (["train", "--env", "detector_params.trackin=model"], "--env", "did you mean 'tracking'"),
    (["train", "--env", "detector=naive"], "--env", "detector has its own flag: --detector"),
    (["train", "--env", "vehicles_count=3"], "--env", "has its own flag: --vehicles"),
    (["train", "--env", "sensor.preset=fog"], "--env", "preset"),
    (["train", "--env", "sensor=1", "--env", "sensor.preset=camera"], "--env", "not a section"),
    (["train", "--env", "sensor.preset=camera", "--env", "sensor=1"], "--env", "is a section"),
    (["train", "--backend", "ray"], "--backend", "invalid choice: 'ray'"),
    (["train", "--keep-by", "speed"], "--keep-by", "invalid choice: 'speed'"),
    (
        ["train", "--backend", "rllib", "--keep-by", "score", "--out", "DIR/t"],
        "--keep-by",
        "applies to --backend sb3 only",
    ),
    (["train", "--num-env-runners", "-1"], "--num-env-runners", "must be in [0, 1024]"),
    (["train", "--address", "nohost"], "--address", "must be 'auto' or host:port"),
    (["train", "--address", "h:99999"], "--address", "must be 'auto' or host:port"),
    (
        ["train", "--num-env-runners", "2", "--out", "DIR/t"],
        "--num-env-runners",
        "applies to --backend rllib only",
    ),
    (["train", "--address", "auto", "--out", "DIR/t"], "--address", "applies to --backend rllib"),
    (
        ["train", "--backend", "rllib", "--n-envs", "2", "--out", "DIR/t"],
        "--n-envs",
        "applies to --backend sb3 only; with rllib use --num-env-runners",
    ),
    (
        ["train", "--backend", "rllib", "--validation-freq", "0", "--out", "DIR/t"],
        "--validation-freq",
        "applies to --backend sb3 only",
    ),
    # evaluate
    (["evaluate", "--model", "MISSING"], "--model", "does not exist"),
    (["evaluate", "--model", "DIR"], "--model", "no training.json next to"),
    (["evaluate", "--model", "FILE"], "--model", "no training.json next to"),
    (["evaluate", "--model", "FILE", "--seed", "-1"], "--seed", "must be in [0, 2**31 - 1]"),
    (["evaluate", "--model", "FILE", "--out", "FILE"], "--out", "exists and is not a folder"),
]


@pytest.mark.parametrize(("argv", "argument", "message"), CASES)
def test_bad_argument_names_it_in_one_line(
    argv: list[str],
    argument: str,
    message: str,
    paths: dict[str, str],
    capsys: pytest.CaptureFixture[str],
) -> None:
    placeholder = re.compile(r"\b(" + "|".join(paths) + r")\b")
    argv = [placeholder.sub(lambda m: paths[m.group(1)], a) for a in argv]
    line = usage_error(argv, capsys)
    assert f"error: argument {argument}: " in line
    assert message in line


@pytest.mark.skipif(not MAP.exists(), reason="shipped maps not built")
def test_a_place_off_the_map_names_the_arguments(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["plot", "--xodr", str(MAP), "--out", str(tmp_path / "p.png")]
    line = usage_error([*base, "--road-id", "999", "--s", "5"], capsys)
    assert "argument --road-id/--lane-id/--s: " in line and "no lane -1 on road '999'" in line
    line = usage_error([*base, "--road-id", "3"], capsys)
    assert "argument --road-id: needs --s" in line
    line = usage_error([*base, "--shift", "50"], capsys)
    assert "argument --shift: " in line and "from any driving lane" in line


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc (not writable)")
def test_an_output_that_cannot_be_created(capsys: pytest.CaptureFixture[str]) -> None:
    line = usage_error(["compare", "--out", "/proc/aldm-gym-out", "--no-progress"], capsys)
    assert "argument --out: cannot create /proc/aldm-gym-out" in line
    line = usage_error(["plot", "--out", "/proc/aldm-gym.png"], capsys)
    assert "argument --out: cannot write /proc/aldm-gym.png" in line


def test_a_corrupt_training_record_names_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("stable_baselines3")
    model = tmp_path / "model.zip"
    model.write_bytes(b"PK")
    for record in ("{", "[1]", json.dumps({"steps": 3})):
        (tmp_path / "training.json").write_text(record)
        line = usage_error(["evaluate", "--model", str(model), "--no-progress"], capsys)
        assert f"argument --model: {tmp_path / 'training.json'}: not a training record" in line
        line = usage_error(["train", "--out", str(tmp_path), "--resume"], capsys)
        assert f"argument --resume: {tmp_path / 'training.json'}: not a training record" in line
    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}, "ppo": {"gamma": 2}}))
    line = usage_error(["train", "--out", str(tmp_path), "--resume"], capsys)
    assert line.endswith("not a training record (gamma must be in [0.0, 1.0], got 2)")


def test_the_installed_command_exits_2_without_traceback(tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_text("x")
    run = subprocess.run(
        [sys.executable, "-m", "aldm_gym", "compare", "--out", str(afile)],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 2
    assert "Traceback" not in run.stderr
    assert run.stderr.strip().splitlines()[-1] == (
        f"aldm-gym compare: error: argument --out: {afile} exists and is not a folder"
    )


def test_a_folder_that_is_not_an_rllib_checkpoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "training.json").write_text(json.dumps({"env_config": {}}))
    (tmp_path / "rllib_model").mkdir()
    line = usage_error(["evaluate", "--model", str(tmp_path / "rllib_model")], capsys)
    assert "argument --model: " in line and "is a folder but not an RLlib checkpoint" in line


def test_resuming_with_the_other_backend_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    record = {
        "env_config": {"detector": "aldm", "marking_model": "per_dash"},
        "ppo": {"n_steps": 64, "gamma": 0.8},
    }
    (tmp_path / "training.json").write_text(json.dumps(record))  # an SB3 training
    line = usage_error(["train", "--resume", "--backend", "rllib", "--out", str(tmp_path)], capsys)
    assert "argument --backend: rllib contradicts the training being resumed (sb3)" in line
    (tmp_path / "training.json").write_text(json.dumps({**record, "backend": "rllib"}))
    line = usage_error(["train", "--resume", "--n-envs", "2", "--out", str(tmp_path)], capsys)
    assert "argument --n-envs: applies to --backend sb3 only" in line


def test_xodr_takes_a_shipped_map_by_name(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--xodr motorway`` (or ``motorway.xodr``) is the shipped map from any folder, but
    a file of the working folder wins (``motorway.xodr`` for the bare name too)."""
    from aldm_gym.cli.argtypes import xodr_file

    monkeypatch.chdir(tmp_path)
    assert xodr_file("motorway") == MAP.resolve()
    assert xodr_file("motorway.xodr") == MAP.resolve()
    (tmp_path / "motorway.xodr").write_text("<OpenDRIVE/>")
    assert xodr_file("motorway.xodr") == Path("motorway.xodr")
    assert xodr_file("motorway") == Path("motorway.xodr")
