"""Planning and playing a suite: variation files, subsets, worker processes, Ray."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from aldm_gym.harness.suite import format_table, plan_suite, play_suite, summarise, write_outputs
from tests.scenario._build import write


def test_a_folder_of_concrete_scenarios_plays_in_two_processes(tmp_path: Path) -> None:
    write(tmp_path, name="a.xosc", stop=2.0, activate_at=0.0)
    write(tmp_path, name="b.xosc", stop=3.0, target=None, activate_at=0.0)
    jobs = plan_suite(tmp_path, ["aldm", "naive"], ["per_dash"])
    assert [(Path(j.xosc).name, j.detector) for j in jobs] == [
        ("a.xosc", "aldm"),
        ("a.xosc", "naive"),
        ("b.xosc", "aldm"),
        ("b.xosc", "naive"),
    ]
    results = play_suite(jobs, processes=2, progress=False)
    assert [r.time_s for r in results] == pytest.approx([2.1, 2.1, 3.1, 3.1])
    assert all(r.finished and not r.error for r in results)
    rows = summarise(results)
    write_outputs(results, rows, tmp_path)
    assert (tmp_path / "scenario_runs.csv").read_text().count("\n") == 5
    assert "a.xosc" in format_table(rows)


def test_a_run_that_cannot_be_played_is_an_error_row(tmp_path: Path) -> None:
    path = write(tmp_path, ego_s=5000.0)  # off the 2 km road: fails when it starts
    results = play_suite(plan_suite(path, ["aldm"], ["per_dash"]), processes=1, progress=False)
    assert "not on the map" in results[0].error and not results[0].passed
    row = summarise(results)[0]
    assert row["errors"] == 1 and row["runs"] == 0 and row["not_judged"] == 0


def test_a_run_the_function_never_drove_in_has_its_own_column(tmp_path: Path) -> None:
    never = write(tmp_path, name="never.xosc", stop=2.0)  # no activation
    write(tmp_path, name="driven.xosc", stop=2.0, activate_at=0.0)
    write(tmp_path, name="off.xosc", ego_s=5000.0)
    results = play_suite(plan_suite(tmp_path, ["aldm"], ["per_dash"]), processes=1, progress=False)
    rows = {r["scenario"]: r for r in summarise(results)}
    assert (rows[never.name]["not_judged"], rows[never.name]["errors"]) == (1, 0)
    assert rows[never.name]["runs"] == 0
    assert (rows["off.xosc"]["not_judged"], rows["off.xosc"]["errors"]) == (0, 1)
    assert (rows["driven.xosc"]["runs"], rows["driven.xosc"]["pass_rate"]) == (1, 1.0)
    table = format_table(list(rows.values()))
    assert "n/j" in table and "never" in table


def test_on_a_ray_cluster(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    import ray

    path = write(tmp_path, stop=2.0, activate_at=0.0)
    try:
        results = play_suite(
            plan_suite(path, ["aldm", "ground_truth"], ["per_dash"]),
            progress=False,
            address="local",
        )
    finally:
        ray.shutdown()
    assert [r.detector for r in results] == ["aldm", "ground_truth"]
    assert all(r.finished and r.passed for r in results)


def test_env_settings_reach_every_run_and_the_scenario_keeps_its_map(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from aldm_gym.cli import main
    from aldm_gym.harness.suite import _play

    path = write(tmp_path, stop=2.0, activate_at=0.0)
    config = {"sensor": {"preset": "camera"}, "detector_params": {"tracking": "model"}}
    jobs = plan_suite(path, ["aldm"], ["per_dash"], config=config)
    assert json.loads(jobs[0].config) == config
    result = _play(jobs[0])
    assert result.finished and not result.error
    # the settings reach the env: a value it refuses is that run's error
    bad = dataclasses.replace(jobs[0], config=json.dumps({"sensor": {"preset": "fog"}}))
    assert "preset" in _play(bad).error
    # from the command line: the scenario's own map wins, with one note
    code = main(
        ["scenario", "run", str(path), "--env", "road.xodr=motorway",
         "--env", "sensor.preset=camera", "--detector", "ground_truth"]
    )  # fmt: skip
    out = capsys.readouterr()
    assert code == 0, out.out + out.err
    assert out.err.count("take precedence over --env road (ignored)") == 1
