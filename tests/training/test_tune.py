"""``aldm-gym tune``: the search's bookkeeping (scores, table, best command, continuing a
study, failed trials), with a stand-in for the training each trial runs."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("optuna")

from aldm_gym.training import tune as tune_module
from aldm_gym.training.settings import DEFAULT_TIMESTEPS, FAILURE_PENALTY
from aldm_gym.training.tune import (
    FINETUNE_SPACE,
    SEARCH_SPACE,
    Choice,
    LogRange,
    StudyMismatch,
    TrialFailed,
    parse_params,
    score,
    train_command,
    tune,
)

FAKE_TRAIN = """
import json, sys
args = dict(zip(sys.argv[1::2], sys.argv[2::2]))
gamma = float(args["--gamma"])
if gamma == 0.95 and args.get("--fail") == "1":
    sys.exit(3)
row = {"steps": 64, "mean_return": 1.0, "mean_speed": 20 + 10 * gamma,
       "success_rate": 0.9 if float(args["--collision-reward"]) == -1 else 1.0, "collisions": 0}
json.dump({"best_steps": 64, "history": [row], "seeds": [20000, 20009],
           "baselines": {"rule_based": {"mean_speed": 25.0, "collisions": 0}}},
          open(args["--out"] + "/validation.json", "w"))
"""


@pytest.fixture
def fake_training(monkeypatch: pytest.MonkeyPatch) -> None:
    """Trials run :data:`FAKE_TRAIN` instead of a training: speed from gamma, a
    failure in 10 episodes with collision weight -1."""

    def launch(cmd: Sequence[str], log: Path) -> int:
        assert list(cmd[1:4]) == ["-m", "aldm_gym", "train"] and "--no-progress" in cmd
        flags = [a for a in cmd[4:] if a != "--no-progress"]
        return subprocess.run([sys.executable, "-c", FAKE_TRAIN, *flags], check=False).returncode

    monkeypatch.setattr(tune_module, "launch", launch)


def test_score_is_the_kept_models_speed_less_the_failures() -> None:
    rows = [
        {"steps": 10, "mean_speed": 30.0, "success_rate": 0.5},
        {"steps": 20, "mean_speed": 25.0, "success_rate": 0.9},
    ]
    value, row = score({"best_steps": 20, "history": rows})
    assert row is rows[1]
    assert value == pytest.approx(25.0 - FAILURE_PENALTY * 0.1)
    with pytest.raises(TrialFailed, match="no validation"):
        score({"best_steps": 5, "history": rows})


def test_train_command_passes_every_flag() -> None:
    cmd = train_command(
        {"learning_rate": 0.000123456, "n_steps": 256},
        {"algo": "maskable-ppo", "seed": None},
        Path("o"),
        python="py",
    )
    assert cmd == [
        *("py", "-m", "aldm_gym", "train", "--out", "o", "--no-progress"),
        *("--algo", "maskable-ppo", "--learning-rate", "0.0001235", "--n-steps", "256"),
    ]
    env = ['detector_params.tracking="model"', "observation.line_confidence=true"]
    cmd = train_command({}, {"env": env, "detector": "aldm"}, Path("o"), python="py")
    assert cmd[7:] == [
        *("--env", 'detector_params.tracking="model"'),
        *("--env", "observation.line_confidence=true", "--detector", "aldm"),
    ]


def test_search_writes_table_and_best_and_continues(tmp_path: Path, fake_training: None) -> None:
    seen: list[int] = []
    best = tune(
        tmp_path,
        trials=4,
        jobs=2,
        fixed={"timesteps": 64},
        on_trial=lambda t: seen.append(t.number),
    )
    assert sorted(seen) == [0, 1, 2, 3]
    with open(tmp_path / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["trial"] for r in rows] == ["0", "1", "2", "3"]
    assert list(rows[0])[3 : 3 + len(SEARCH_SPACE)] == list(SEARCH_SPACE)
    scores = {int(r["trial"]): float(r["score"]) for r in rows}
    assert best["trial"] == max(scores, key=scores.get)
    expected = 20 + 10 * best["params"]["gamma"]
    if best["params"]["collision_reward"] == -1.0:
        expected -= FAILURE_PENALTY * 0.1
    assert best["score"] == pytest.approx(expected)
    assert best["kept"]["rule_based_speed"] == 25.0
    # The command trains the best trial with the full budget: train's default here,
    # the trials' own when that is more (a search at the full budget).
    assert best["command"].startswith("aldm-gym train --out OUT")
    assert f"--timesteps {DEFAULT_TIMESTEPS}" in best["command"]
    assert "--no-progress" not in best["command"]
    full = tune(tmp_path / "full", trials=1, jobs=1, fixed={"timesteps": 2 * DEFAULT_TIMESTEPS})
    assert f"--timesteps {2 * DEFAULT_TIMESTEPS}" in full["command"]
    assert json.loads((tmp_path / "best.json").read_text())["trial"] == best["trial"]

    # The same folder continues the study: two more trials, four kept.
    again = tune(tmp_path, trials=6, jobs=1, fixed={"timesteps": 64})
    assert again["trials"] == 6
    assert sorted(p.name for p in (tmp_path / "trials").iterdir()) == [f"{i:03d}" for i in range(6)]


def test_a_search_from_a_clone_varies_the_fine_tuning_space(
    tmp_path: Path, fake_training: None
) -> None:
    """``pretrain_episodes`` among the fixed flags: every trial clones first, the
    sampler draws from :data:`FINETUNE_SPACE`, and the folder keeps that space."""
    fixed = {"timesteps": 64, "pretrain_episodes": 5}
    best = tune(tmp_path / "ft", trials=3, jobs=1, fixed=fixed)
    assert best["space"] == "finetune"
    assert "--pretrain-episodes 5" in best["command"]
    with open(tmp_path / "ft" / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0])[3 : 3 + len(FINETUNE_SPACE)] == list(FINETUNE_SPACE)
    ent, lr = FINETUNE_SPACE["ent_coef"], FINETUNE_SPACE["learning_rate"]
    assert isinstance(ent, Choice) and isinstance(lr, LogRange)
    assert {float(r["ent_coef"]) for r in rows} <= set(ent.values)
    assert all(lr.low <= float(r["learning_rate"]) <= lr.high for r in rows)
    # A folder holds one space: the search from scratch is refused there, and back.
    with pytest.raises(StudyMismatch, match=r"with --pretrain-episodes \(the 'finetune' space"):
        tune(tmp_path / "ft", trials=4, jobs=1, fixed={"timesteps": 64})
    tune(tmp_path / "sc", trials=1, jobs=1, fixed={"timesteps": 64, "pretrain_episodes": 0})
    with pytest.raises(StudyMismatch, match="search without --pretrain-episodes"):
        tune(tmp_path / "sc", trials=2, jobs=1, fixed=fixed)


def test_a_study_continues_only_with_its_fixed_flags(
    tmp_path: Path, fake_training: None, capsys: pytest.CaptureFixture[str]
) -> None:
    """Other fixed flags would make trials incomparable and best.json's command wrong."""
    fixed = {"timesteps": 64, "seed": 0, "env": ["lane_keeping_reward=0"]}
    tune(tmp_path, trials=1, jobs=1, fixed=fixed)
    with pytest.raises(StudyMismatch, match=r"with --seed 0; continue it with the same flags"):
        tune(tmp_path, trials=2, jobs=1, fixed={**fixed, "seed": 1})
    with pytest.raises(StudyMismatch, match=r"with --env \['lane_keeping_reward=0'\], --x \(not"):
        tune(tmp_path, trials=2, jobs=1, fixed={**fixed, "env": [], "x": 1})
    assert tune(tmp_path, trials=2, jobs=1, fixed=dict(fixed))["trials"] == 2
    # The command line says which folder and how to go on (usage error, exit code 2).
    from aldm_gym.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["tune", "--trials", "3", "--seed", "5", "--out", str(tmp_path), "--no-progress"])
    assert exc.value.code == 2
    assert "argument --out: " in capsys.readouterr().err


def test_one_search_per_folder(tmp_path: Path, fake_training: None) -> None:
    """A second search on a folder whose search runs is refused, naming the holder."""
    from aldm_gym.errors import OutputLocked
    from aldm_gym.training.lock import output_lock

    with output_lock(tmp_path):  # as the running search holds it
        with pytest.raises(OutputLocked, match=r"being written by another search \(pid"):
            tune(tmp_path, trials=1, jobs=1, fixed={"timesteps": 64})
    assert not (tmp_path / "study.db").exists()
    assert tune(tmp_path, trials=1, jobs=1, fixed={"timesteps": 64})["trials"] == 1


def test_an_older_study_is_a_search_from_scratch(tmp_path: Path, fake_training: None) -> None:
    """A study without the record (an older version's) continues from scratch only."""
    optuna = pytest.importorskip("optuna")
    study = optuna.create_study(
        study_name="aldm-gym", storage=f"sqlite:///{tmp_path / 'study.db'}", direction="maximize"
    )
    gamma = optuna.distributions.CategoricalDistribution([0.8, 0.9, 0.95])
    study.add_trial(
        optuna.trial.create_trial(params={"gamma": 0.9}, distributions={"gamma": gamma}, value=1.0)
    )
    with pytest.raises(StudyMismatch, match="without --pretrain-episodes"):
        tune(tmp_path, trials=2, jobs=1, fixed={"pretrain_episodes": 3})
    assert tune(tmp_path, trials=3, jobs=1, fixed={"timesteps": 64})["trials"] == 3


def test_trial_commands_parse_as_train_arguments() -> None:
    """Every value the searches draw reaches ``aldm-gym train`` as drawn."""
    from aldm_gym.cli import build_parser

    parser = build_parser()
    for space in (SEARCH_SPACE, FINETUNE_SPACE):
        for i in range(3):
            params = {
                name: dim.values[i] if isinstance(dim, Choice) else (dim.low, dim.high, dim.low)[i]
                for name, dim in space.items()
            }
            fixed = {"algo": "maskable-ppo", "pretrain_episodes": 7, "pretrain_epochs": 2}
            args = parser.parse_args(train_command(params, fixed, Path("o"))[3:])
            assert args.pretrain_episodes == 7 and args.pretrain_epochs == 2
            for name, value in params.items():
                assert getattr(args, name) == pytest.approx(value, rel=1e-3), name


def test_failed_trials_are_recorded_not_fatal(tmp_path: Path, fake_training: None) -> None:
    best = tune(tmp_path, trials=6, jobs=1, seed=1, fixed={"fail": 1})
    with open(tmp_path / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    failed = [r for r in rows if r["state"] == "FAIL"]
    # The sampler seeded 1 proposes gamma 0.95 (which the stand-in fails) in six trials.
    assert len(rows) == 6 and failed
    assert [r for r in rows if r["gamma"] == "0.95"] == failed
    assert all(r["score"] == "" for r in failed)
    assert best["trials"] == 6 - len(failed) and best["params"]["gamma"] != 0.95


def test_env_settings_with_a_train_flag_go_to_that_flag() -> None:
    """``tune --env``: settings ``train`` has a flag for reach the trials as that flag,
    the rest as ``--env``; the search's own flags are refused."""
    from aldm_gym.cli.argtypes import BadArgument
    from aldm_gym.cli.train import env_settings

    own = ("detector", "marking_model")
    pairs = [("vehicles_count", 8), ("sensor.preset", "camera"), ("duration", 20.0)]
    env, flags = env_settings(pairs, own_flags=own)
    assert env == ['sensor.preset="camera"']
    assert flags == {"vehicles": 8, "duration": 20.0}
    cmd = train_command({}, {**flags, "env": env}, Path("o"), python="py")
    assert cmd[7:] == [*("--vehicles", "8", "--duration", "20", "--env", 'sensor.preset="camera"')]
    with pytest.raises(BadArgument, match="marking_model has its own flag: --marking-model"):
        env_settings([("marking_model", "editor")], own_flags=own)


RECIPE = "gamma=0.95, learning_rate=1e-4,n_steps=512,ent_coef=0,collision_reward=-2"


def test_parse_params_checks_names_and_values_against_the_space() -> None:
    params = parse_params(RECIPE, FINETUNE_SPACE)
    assert params == {
        "gamma": 0.95,
        "learning_rate": 1e-4,
        "n_steps": 512,
        "ent_coef": 0.0,
        "collision_reward": -2.0,
    }
    assert isinstance(params["n_steps"], int)  # the choice's own value, as train parses it
    bad = {
        "gamma=0.95,momentum=1": r"unknown name 'momentum'; the search varies gamma, learning",
        "gamma=0.97": r"gamma=0.97 is not searched: gamma must be one of 0.9, 0.95, 0.99",
        "learning_rate=1e-3": r"learning_rate must be a number in \[1e-05, 0.0003\]",
        "gamma=0.95,gamma=0.9": "gamma is given twice",
        "n_steps=many": "n_steps='many': n_steps must be one of 256, 512, 1024",
        "n_steps=1_024": "n_steps must be one of 256, 512, 1024",
        "learning_rate=nan": r"learning_rate must be a number in \[",
        "gamma": "'gamma' is not NAME=VALUE \\(names: gamma, learning_rate",
        "=0.9": "'=0.9' is not NAME=VALUE",
        "gamma=0.9,": "has an empty item; write NAME=VALUE,... of gamma, learning_rate",
        "": "has an empty item",
    }
    for text, message in bad.items():
        with pytest.raises(ValueError, match=message):
            parse_params(text, FINETUNE_SPACE)


def test_an_enqueued_recipe_runs_first_and_once(tmp_path: Path, fake_training: None) -> None:
    """``enqueue``: the given trial runs before the sampler's (names not given are
    drawn), and a continued search does not queue it again."""
    fixed = {"timesteps": 64, "pretrain_episodes": 5}
    recipe = parse_params(RECIPE, FINETUNE_SPACE)
    tune(tmp_path, trials=2, jobs=1, fixed=fixed, enqueue=[recipe])
    tune(tmp_path, trials=3, jobs=1, fixed=fixed, enqueue=[recipe])
    with open(tmp_path / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3
    first = {k: float(rows[0][k]) for k in recipe}
    assert first == recipe
    assert float(rows[0]["overtaking_reward"]) in FINETUNE_SPACE["overtaking_reward"].values
    assert all({k: float(r[k]) for k in recipe} != recipe for r in rows[1:])


def test_enqueued_trials_run_once_each_with_parallel_jobs(
    tmp_path: Path, fake_training: None
) -> None:
    """Two trials at once take two different enqueued trials (with optuna's own
    parallel loop both could take the same one and the second fail on its folder)."""
    recipes = [
        parse_params(f"gamma={g},learning_rate={lr},n_steps=256", FINETUNE_SPACE)
        for g, lr in ((0.9, 1e-5), (0.95, 2e-5), (0.99, 3e-5), (0.9, 4e-5))
    ]
    tune(tmp_path, trials=4, jobs=2, fixed={"pretrain_episodes": 5}, enqueue=recipes)
    with open(tmp_path / "trials.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["state"] for r in rows] == ["COMPLETE"] * 4
    ran = sorted((float(r["gamma"]), float(r["learning_rate"])) for r in rows)
    assert ran == sorted((r["gamma"], r["learning_rate"]) for r in recipes)


def test_the_cli_refuses_a_bad_enqueue_before_making_the_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from aldm_gym.cli import main

    out = tmp_path / "search"
    with pytest.raises(SystemExit) as exc:
        main(["tune", "--pretrain-episodes", "5", "--enqueue", "gamma=0.8", "--out", str(out)])
    assert exc.value.code == 2
    assert "argument --enqueue: gamma=0.8 is not searched: gamma must be one of 0.9, 0.95" in (
        capsys.readouterr().err
    )
    assert not out.exists()


def test_the_cli_refuses_more_enqueued_trials_than_trials(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from aldm_gym.cli import main

    out = tmp_path / "search"
    argv = ["tune", "--pretrain-episodes", "5", "--trials", "1", "--out", str(out)]
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--enqueue", "gamma=0.9", "--enqueue", "gamma=0.95"])
    assert exc.value.code == 2
    assert "argument --enqueue: 2 trials enqueued but --trials is 1" in capsys.readouterr().err
    assert not out.exists()


def test_an_interrupted_trial_stops_the_search(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A training that exits 130 (Ctrl-C reached it) fails its trial and starts no new
    one, as the main thread's own KeyboardInterrupt does."""
    optuna = pytest.importorskip("optuna")
    launched: list[Path] = []

    def launch(cmd: Sequence[str], log: Path) -> int:
        launched.append(log)
        return tune_module.INTERRUPTED

    monkeypatch.setattr(tune_module, "launch", launch)
    with pytest.raises(KeyboardInterrupt, match="trial 0 was interrupted"):
        tune(tmp_path, trials=4, jobs=1, fixed={"pretrain_episodes": 5})
    assert len(launched) == 1
    study = optuna.load_study(study_name="aldm-gym", storage=f"sqlite:///{tmp_path / 'study.db'}")
    assert [t.state.name for t in study.trials] == ["FAIL"]


def test_enqueued_trials_count_among_the_trials(
    tmp_path: Path, fake_training: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """More enqueued trials than trials left are refused; a failed enqueued trial runs
    again when the search continues; a trial left running by a killed search is marked
    failed when the next one starts."""
    from aldm_gym.training.tune import EnqueueError

    fixed = {"pretrain_episodes": 5, "fail": 1}  # the stand-in fails gamma 0.95
    recipes = [parse_params(f"gamma={g}", FINETUNE_SPACE) for g in (0.9, 0.95, 0.99)]
    with pytest.raises(EnqueueError, match="3 enqueued trials to run but only 2 left"):
        tune(tmp_path, trials=2, jobs=1, fixed=fixed, enqueue=recipes)
    tune(tmp_path, trials=3, jobs=1, fixed=fixed, enqueue=recipes)
    with open(tmp_path / "trials.csv") as fh:
        states = [(r["gamma"], r["state"]) for r in csv.DictReader(fh)]
    assert states == [("0.9", "COMPLETE"), ("0.95", "FAIL"), ("0.99", "COMPLETE")]
    # Continued: the failed recipe is queued again, the finished ones are not.
    optuna = pytest.importorskip("optuna")
    study = optuna.load_study(study_name="aldm-gym", storage=f"sqlite:///{tmp_path / 'study.db'}")
    stale = study.ask()  # as a search killed while this trial trained
    failing = tune_module.launch

    def launch(cmd: Sequence[str], log: Path) -> int:  # the stand-in fails no more
        cmd = list(cmd)
        del cmd[cmd.index("--fail") : cmd.index("--fail") + 2]
        return failing(cmd, log)

    monkeypatch.setattr(tune_module, "launch", launch)
    tune(tmp_path, trials=3, jobs=1, fixed=fixed, enqueue=recipes)
    with open(tmp_path / "trials.csv") as fh:
        rows = [(r["trial"], r["state"], r["gamma"]) for r in csv.DictReader(fh)]
    assert rows[3:] == [(str(stale.number), "FAIL", ""), ("4", "COMPLETE", "0.95")]


class _FakeStudy:
    """A study whose ``ask`` records whether the caller holds ``tune``'s lock."""

    def __init__(self) -> None:
        self.asked: list[int] = []
        self.told: list[tuple[int, Any]] = []
        self.lock: Any = None

    def ask(self) -> Any:
        assert self.lock is not None and self.lock.locked(), "ask outside the lock"
        self.asked.append(len(self.asked))
        return self.asked[-1]

    def tell(self, trial: int, value: Any = None, state: Any = None) -> tuple[int, Any]:
        self.told.append((trial, state.name if state is not None else value))
        return self.told[-1]


def test_optimize_asks_under_its_lock_and_stops_on_an_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import threading

    study = _FakeStudy()
    real_lock = threading.Lock

    def lock() -> Any:  # the first lock _optimize makes is its own (then its Event's)
        made = real_lock()
        if study.lock is None:
            study.lock = made
        return made

    monkeypatch.setattr(tune_module.threading, "Lock", lock)
    seen: list[Any] = []
    tune_module._optimize(study, lambda t: float(t), 5, 2, seen.append)
    assert sorted(study.asked) == [0, 1, 2, 3, 4] and len(seen) == 5
    assert sorted(v for _, v in study.told) == [0.0, 1.0, 2.0, 3.0, 4.0]

    def objective(trial: int) -> float:
        if trial == 1:
            raise TrialFailed("trial 1 exited with 3")
        if trial == 2:
            raise RuntimeError("broken")
        return 0.0

    study = _FakeStudy()
    monkeypatch.setattr(tune_module.threading, "Lock", real_lock)
    study.lock = real_lock()
    study.lock.acquire()  # this part checks stopping, not the lock
    with pytest.raises(RuntimeError, match="broken"):
        tune_module._optimize(study, objective, 10, 1, None)
    # A failed training is a failed trial and the search goes on; any other error
    # fails its trial and starts no new one.
    assert study.told == [(0, 0.0), (1, "FAIL"), (2, "FAIL")]


def test_the_cli_draws_the_trials(
    tmp_path: Path, fake_training: None, capsys: pytest.CaptureFixture[str]
) -> None:
    """``aldm-gym tune`` writes trials.png beside the table and names it."""
    from aldm_gym.cli import main
    from aldm_gym.training.tune import plot_trials

    out = tmp_path / "search"
    args = ["tune", "--trials", "2", "--jobs", "1", "--timesteps", "64", "--no-progress"]
    assert main([*args, "--out", str(out)]) == 0
    assert (out / "trials.png").stat().st_size > 0
    assert f"wrote {out / 'trials.csv'}, {out / 'trials.png'} and" in capsys.readouterr().out
    # No finished trial with a validation: nothing to draw.
    for folder in (out / "trials").iterdir():
        (folder / "validation.json").unlink()
    assert plot_trials(out, "ALDM") is None
