"""``--function`` and ``--config`` on the commands: every kind of SPEC on the OSC-ALKS
cut-in, the precedence of ``--env`` over ``--config``, and bad files and keys."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from aldm_gym.cli import main
from tests._cli import usage_error
from tests.scenario._build import write
from tests.scenario.test_alks import SUITE

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "lane_centering.py"


CUT_IN = (
    SUITE / "concrete_scenarios" / "alks_scenario_4_4_1_cut_in_no_collision_template.xosc"
    if SUITE
    else None
)
needs_suite = pytest.mark.skipif(SUITE is None, reason="the OSC-ALKS suite is not here")


def _run_cut_in(spec: str, capsys: pytest.CaptureFixture[str], *extra: str) -> str:
    capsys.readouterr()
    code = main(["scenario", "run", str(CUT_IN), "--function", spec, *extra])
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"function {spec}): PASS" in out.splitlines()[0] or spec == "builtin", out
    return out


@needs_suite
@pytest.mark.parametrize(
    "spec", ["builtin", f"{EXAMPLE}:PurePursuitLKA", f"{EXAMPLE}:LaneCenteringChauffeur"]
)
def test_the_cut_in_with_python_functions(spec: str, capsys: pytest.CaptureFixture[str]) -> None:
    out = _run_cut_in(spec, capsys)
    assert "PASS" in out


@needs_suite
def test_the_cut_in_with_an_fmu(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("fmpy")
    pytest.importorskip("pythonfmu")
    from pythonfmu import FmuBuilder

    fmu = FmuBuilder.build_FMU(Path(__file__).with_name("fmu_lane_centering.py"), dest=tmp_path)
    _run_cut_in(str(fmu), capsys, "--env", "sensor.preset=camera")


@needs_suite
@pytest.mark.slow
def test_the_cut_in_with_a_trained_policy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("stable_baselines3")
    from tests.training._helpers import tiny_train

    out = tmp_path / "run"
    assert tiny_train(out, 32, "--algo", "maskable-ppo") == 0
    capsys.readouterr()
    code = main(["scenario", "run", str(CUT_IN), "--function", str(out)])
    text = capsys.readouterr().out
    assert code in (0, 1), text  # the tiny policy may change lanes; the run is judged
    assert f"function {out})" in text and ("PASS" in text or "FAIL" in text)


def _config(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_env_wins_over_config_and_yaml_equals_json(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    yaml_file = _config(tmp_path, "c.yaml", "duration: 5\nacc:\n  time_gap: 2.2\n")
    json_file = _config(tmp_path, "c.json", '{"duration": 5, "acc": {"time_gap": 2.2}}')
    got = []
    for i, file in enumerate((yaml_file, json_file)):
        out = tmp_path / f"out{i}"
        argv = ["evaluate", "--function", "builtin", "--episodes", "1", "--no-progress"]
        argv += ["--config", str(file), "--env", "duration=3", "--out", str(out)]
        assert main(argv) == 0
        (result,) = out.glob("evaluate_function_*.json")
        got.append(json.loads(result.read_text())["env_config"])
    assert got[0] == got[1]
    assert got[0]["duration"] == 3  # --env wins
    assert got[0]["acc"] == {"time_gap": 2.2}


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("bad_key.yaml", "acc:\n  time_gapp: 2\n", r"time_gapp.*did you mean 'time_gap'"),
        ("bad_value.json", '{"duration": -1}', "duration"),
        ("corrupt.yaml", "acc: [1, 2\n", "not YAML"),
        ("corrupt.json", "{", "not JSON"),
        ("list.yaml", "- 1\n- 2\n", "a mapping of settings, got list"),
        ("section.yaml", "sensor: 3\n", "sensor"),
    ],
)
def test_a_bad_config_file_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, text: str, message: str
) -> None:
    path = _config(tmp_path, name, text)
    line = usage_error(["evaluate", "--function", "builtin", "--config", str(path)], capsys)
    assert "argument --config" in line
    assert re.search(message, line), line


def test_config_reaches_every_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = _config(tmp_path, "bad.yaml", "nope: 1\n")
    for name in ("x.xosc", "x.mcap"):
        (tmp_path / name).write_text("")
    for argv in (
        ["compare", "--quick"],
        ["scenario", "run", str(tmp_path / "x.xosc")],
        ["scenario", "suite", str(tmp_path)],
        ["train"],
        ["tune"],
        ["osi", "detect", str(tmp_path / "x.mcap"), str(tmp_path / "y.mcap")],
    ):
        line = usage_error([*argv, "--config", str(bad)], capsys)
        assert "--config" in line and "nope" in line, line


def test_a_scenario_own_map_wins_over_a_config_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, stop=2.0, activate_at=0.0)
    config = _config(tmp_path, "c.yaml", "road:\n  xodr: motorway\nsensor:\n  preset: camera\n")
    code = main(["scenario", "run", str(path), "--config", str(config), "--detector", "naive"])
    out = capsys.readouterr()
    assert code == 0, out.out + out.err
    assert out.err.count("take precedence over --env road (ignored)") == 1


def test_compare_refuses_env_keys_it_sets_itself(capsys: pytest.CaptureFixture[str]) -> None:
    line = usage_error(["compare", "--quick", "--env", "detector=naive"], capsys)
    assert "detector is set by the rows" in line
    line = usage_error(["compare", "--quick", "--env", "road.xodr=motorway"], capsys)
    assert "set by --xodr" in line
    line = usage_error(["compare", "--no-closed-loop", "--env", "duration=3"], capsys)
    assert "--env" in line and "closed loop" in line


def test_a_bad_function_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, stop=2.0, activate_at=0.0)
    line = usage_error(["scenario", "run", str(path), "--function", "nope:Thing"], capsys)
    assert "argument --function: cannot import nope" in line
    line = usage_error(["evaluate", "--episodes", "1"], capsys)
    assert "give --model or --function" in line


def test_compare_drives_the_closed_loop_with_a_function(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["compare", "--quick", "--no-progress", "--roads", "1", "--frames", "2"]
    argv += ["--episodes", "1", "--out", str(tmp_path), "--env", "duration=3"]
    argv += ["--function", f"{EXAMPLE}:PurePursuitLKA"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert f"Closed loop ({EXAMPLE}:PurePursuitLKA, same seeds)" in out
    assert "1 seeds × 1 policies per row" in out
