"""A hyperparameter search over short trainings: :func:`tune` (``aldm-gym tune``).

Each trial is one ``aldm-gym train`` run (a subprocess, in ``<out>/trials/<n>/``) with
hyperparameters an optuna TPE sampler proposes from :data:`SEARCH_SPACE` (training from
scratch) or, when the trials start from a clone of the rule-based LCA
(``pretrain_episodes``), from :data:`FINETUNE_SPACE`; ``jobs`` trials run at once. A
trial is scored on its validation episodes (seeds ``VALIDATION_SEED ..``, never the
evaluation seeds) by the model the training kept (``best_model.zip``: by the score
itself with ``keep_by="score"``, which ``aldm-gym tune`` passes by default, else by
mean return; with a clone, possibly the clone itself, validated at step 0):

    score = mean speed [m/s] - FAILURE_PENALTY * (1 - success rate)

so an episode with a collision or a lane departure in 20 costs 0.5 m/s. The reward's
weights are part of the search, so the mean return is not comparable across trials;
the score is what the results compare (speed, with no more collisions or departures).

Why optuna: its TPE sampler is the standard for few, expensive trials, its study is
stored in SQLite (``<out>/study.db``), so an interrupted search continues where it
stopped with the trials already done, and its trials table is the record the docs
quote. It is the ``[tune]`` extra.

Files: ``<out>/study.db`` (the optuna study), ``<out>/trials/<n>/`` (each training and
its ``train.log``), ``<out>/trials.csv`` (one row per trial: number, state, score,
hyperparameters, kept steps, wall time) and ``<out>/best.json`` (the best trial and the
``aldm-gym train`` command that trains it with the full budget); ``aldm-gym tune``
also draws ``<out>/trials.png`` (:func:`plot_trials`); ``<out>/train.lock`` is held
while the search runs (one search per folder).
"""

from __future__ import annotations

import csv
import json
import logging
import math
import shlex
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aldm_gym.errors import MissingRLDependencies
from aldm_gym.training.backend import import_extra
from aldm_gym.training.lock import output_lock
from aldm_gym.training.outputs import VALIDATION_FILE, write_json
from aldm_gym.training.settings import DEFAULT_TIMESTEPS, validation_score

logger = logging.getLogger(__name__)

STUDY_FILE = "study.db"
"""The optuna study (SQLite) in the search's folder."""

TRIALS_DIR = "trials"
"""Sub-folder of the trials' trainings."""

TRIALS_TABLE = "trials.csv"
"""One row per trial."""

BEST_FILE = "best.json"
"""The best trial and the command that trains it."""

TRIALS_FIGURE = "trials.png"
"""The finished trials' validation curves (:func:`plot_trials`)."""

INTERRUPTED = 130
"""Exit code of an ``aldm-gym`` command stopped by Ctrl-C: a trial's training that
exits with it stops the search (its trial is marked failed)."""


@dataclass(frozen=True)
class Choice:
    """A categorical hyperparameter: one of ``values``."""

    values: tuple[Any, ...]


@dataclass(frozen=True)
class LogRange:
    """A continuous hyperparameter, sampled log-uniformly in ``[low, high]``."""

    low: float
    high: float


SEARCH_SPACE: dict[str, Choice | LogRange] = {
    "gamma": Choice((0.8, 0.9, 0.95)),
    "learning_rate": LogRange(1e-4, 1e-3),
    "n_steps": Choice((128, 256, 512)),
    "ent_coef": LogRange(1e-3, 5e-2),
    "collision_reward": Choice((-1.0, -2.0, -3.0)),
    "overtaking_reward": Choice((0.0, 0.1, 0.3)),
}
"""What the search varies for a training from scratch: each name is an ``aldm-gym
train`` flag (``_`` for ``-``)."""

FINETUNE_SPACE: dict[str, Choice | LogRange] = {
    "gamma": Choice((0.9, 0.95, 0.99)),
    "learning_rate": LogRange(1e-5, 3e-4),
    "n_steps": Choice((256, 512, 1024)),
    "ent_coef": Choice((0.0, 1e-4, 1e-3)),
    "collision_reward": Choice((-1.0, -2.0, -3.0)),
    "overtaking_reward": Choice((0.1, 0.3, 0.5)),
}
"""What the search varies when every trial fine-tunes a clone of the rule-based LCA
(``pretrain_episodes`` fixed): lower learning rates and entropy weights than
:data:`SEARCH_SPACE` (2.5e-4 with an entropy weight of 1.6e-3 undid the clone's skill
within 16k steps, on a reward whose lane-keeping term charged every lane change;
docs/results.md), and an overtaking weight that pays."""

SPACES: dict[str, dict[str, Choice | LogRange]] = {
    "scratch": SEARCH_SPACE,
    "finetune": FINETUNE_SPACE,
}
"""The search spaces by name (a study records the one it was started with)."""


def space_name(fixed: Mapping[str, Any]) -> str:
    """``"finetune"`` when the trials clone the rule-based LCA first
    (``fixed["pretrain_episodes"]``), else ``"scratch"``."""
    return "finetune" if fixed.get("pretrain_episodes") else "scratch"


class EnqueueError(ValueError):
    """More enqueued trials would wait than the search has trials left."""


class TrialFailed(RuntimeError):
    """A trial's training exited with an error (its ``train.log`` says why)."""


class StudyMismatch(ValueError):
    """The search folder holds a study started with other fixed flags or space."""


def import_optuna() -> Any:
    """Import optuna, or raise :class:`~aldm_gym.errors.MissingRLDependencies` saying
    how to install the ``[tune]`` extra."""
    import_extra(("optuna",), MissingRLDependencies, "the search needs optuna", "rl,tune")
    import optuna

    return optuna


def parse_params(text: str, space: Mapping[str, Choice | LogRange]) -> dict[str, Any]:
    """Hyperparameters written ``NAME=VALUE,NAME=VALUE`` (names of ``space``), checked
    against ``space``: a trial for :func:`tune` to run first (``enqueue``).

    A name not given is drawn by the sampler. A value of a :class:`Choice` must equal
    one of its values (``512`` or ``512.0`` for ``n_steps``); one of a
    :class:`LogRange` must lie within its bounds.

    :raises ValueError: an empty item, an unknown or repeated name, a value that is not
        a finite number or lies outside ``space``; the message names the allowed names,
        or the name's allowed values.
    """
    names = ", ".join(space)
    params: dict[str, Any] = {}
    for item in text.split(","):
        name, sep, raw = (part.strip() for part in item.partition("="))
        if not item.strip():
            raise ValueError(f"{text!r} has an empty item; write NAME=VALUE,... of {names}")
        if not sep or not name:
            raise ValueError(f"{item.strip()!r} is not NAME=VALUE (names: {names})")
        if name not in space:
            raise ValueError(f"unknown name {name!r}; the search varies {names}")
        if name in params:
            raise ValueError(f"{name} is given twice")
        dim = space[name]
        if isinstance(dim, Choice):
            allowed = "one of " + ", ".join(f"{v:g}" for v in dim.values)
        else:
            allowed = f"a number in [{dim.low:g}, {dim.high:g}]"
        try:
            value = float(raw) if "_" not in raw else math.nan  # float() takes 1_024
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise ValueError(f"{name}={raw!r}: {name} must be {allowed}")
        if isinstance(dim, Choice):
            matches = [v for v in dim.values if v == value]
            if not matches:
                raise ValueError(f"{name}={raw} is not searched: {name} must be {allowed}")
            params[name] = matches[0]
        else:
            if not dim.low <= value <= dim.high:
                raise ValueError(f"{name}={raw} is not searched: {name} must be {allowed}")
            params[name] = value
    return params


def _enqueue(study: Any, enqueue: Sequence[Mapping[str, Any]], left: int) -> None:
    """Queue each of ``enqueue`` that no finished or waiting trial of ``study`` already
    has (a failed one is tried again); at most ``left`` trials may wait.

    :raises EnqueueError: more trials would wait than ``left``.
    """
    from optuna.trial import TrialState

    def taken(params: Mapping[str, Any]) -> bool:
        for t in study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.WAITING)):
            given = (
                t.system_attrs.get("fixed_params", t.params)
                if t.state == TrialState.WAITING
                else t.params
            )
            if all(k in given and given[k] == v for k, v in params.items()):
                return True
        return False

    new = [dict(p) for p in enqueue if not taken(p)]
    waiting = len(study.get_trials(deepcopy=False, states=(TrialState.WAITING,)))
    if waiting + len(new) > left:
        raise EnqueueError(
            f"{waiting + len(new)} enqueued trials to run but only {left} left of the "
            "search's trials (enqueued trials count among them): raise --trials"
        )
    for params in new:
        study.enqueue_trial(params)


def _fail_stale(study: Any) -> None:
    """Mark failed the trials an earlier search left running (it was killed): one
    search runs per folder, so none of them is still running."""
    from optuna.trial import TrialState

    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        logger.warning("trial %d was left running by an earlier search: marked failed", t.number)
        study.tell(t.number, state=TrialState.FAIL)


def score(validation: Mapping[str, Any]) -> tuple[float, dict[str, Any]]:
    """A trial's score from its ``validation.json`` (the kept model's row), and that row.

    :raises TrialFailed: no validation was recorded.
    """
    rows = [h for h in validation.get("history", []) if h["steps"] == validation.get("best_steps")]
    if not rows:
        raise TrialFailed("the training recorded no validation")
    row = rows[0]
    return validation_score(row), row


def train_command(
    params: Mapping[str, Any],
    fixed: Mapping[str, Any],
    out: Path,
    python: str = sys.executable,
    progress: bool = False,
) -> list[str]:
    """The ``aldm-gym train`` command line of a trial (``python -m aldm_gym train``).

    :param params: the sampled hyperparameters (names of :data:`SEARCH_SPACE`); floats
        are passed with 4 significant digits (what the trial trains with).
    :param fixed: the other flags (``algo``, ``detector``, ``timesteps``, ...; None
        values are left out); a list gives its flag once per item (``env``: the
        ``KEY=VALUE`` settings of ``train --env``).
    """
    cmd = [python, "-m", "aldm_gym", "train", "--out", str(out)]
    if not progress:
        cmd.append("--no-progress")
    for name, value in {**fixed, **params}.items():
        if isinstance(value, list | tuple):
            for item in value:
                cmd += [_flag(name), str(item)]
        elif value is not None:
            text = f"{value:.4g}" if isinstance(value, float) else str(value)
            cmd += [_flag(name), text]
    return cmd


def launch(cmd: Sequence[str], log: Path) -> int:
    """Run a trial's training, its output to ``log``; its exit code."""
    with open(log, "w") as fh:
        return subprocess.run(cmd, stdout=fh, stderr=subprocess.STDOUT, check=False).returncode


def _suggest(trial: Any, space_of: Mapping[str, Choice | LogRange]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for name, space in space_of.items():
        if isinstance(space, Choice):
            params[name] = trial.suggest_categorical(name, list(space.values))
        else:
            params[name] = trial.suggest_float(name, space.low, space.high, log=True)
    return params


def _run_trial(trial: Any, out: Path, fixed: Mapping[str, Any]) -> float:
    """Train one trial in a subprocess and score it."""
    params = _suggest(trial, SPACES[space_name(fixed)])
    folder = out / TRIALS_DIR / f"{trial.number:03d}"
    cmd = train_command(params, fixed, folder)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    code = launch(cmd, folder / "train.log")
    trial.set_user_attr("wall_s", round(time.perf_counter() - t0, 1))
    if code in (INTERRUPTED, -signal.SIGINT):
        # the training was interrupted (Ctrl-C at a terminal reaches it too): the
        # search stops, as on the main thread's own KeyboardInterrupt
        raise KeyboardInterrupt(f"trial {trial.number} was interrupted")
    if code != 0:
        raise TrialFailed(f"trial {trial.number} exited with {code}; see {folder / 'train.log'}")
    value, row = score(json.loads((folder / VALIDATION_FILE).read_text()))
    for key in ("steps", "mean_speed", "success_rate", "collisions"):
        trial.set_user_attr(key, row[key])
    baselines = json.loads((folder / VALIDATION_FILE).read_text()).get("baselines", {})
    if "rule_based" in baselines:
        trial.set_user_attr("rule_based_speed", baselines["rule_based"]["mean_speed"])
    return value


def tune(
    out: Path,
    *,
    trials: int = 12,
    jobs: int = 2,
    seed: int = 0,
    fixed: Mapping[str, Any] | None = None,
    on_trial: Callable[[Any], None] | None = None,
    enqueue: Sequence[Mapping[str, Any]] = (),
) -> dict[str, Any]:
    """Run (or continue) the search until ``trials`` trials have finished; the best.

    :param out: the search's folder (see the module docstring); a folder with a study
        continues it.
    :param trials: trials in all, counting those of an earlier run [trials].
    :param jobs: trials at once (each is a training in its own process).
    :param seed: seed of the sampler (the trainings use ``fixed["seed"]``).
    :param fixed: the flags every trial's ``aldm-gym train`` gets (``algo``,
        ``detector``, ``marking_model``, ``timesteps``, ``seed``,
        ``validation_freq``, ``validation_episodes``, ``pretrain_episodes``, ...);
        ``pretrain_episodes`` selects :data:`FINETUNE_SPACE`.
    :param on_trial: called with each finished trial.
    :param enqueue: hyperparameters to try before the sampler's own (e.g. a known
        recipe, from :func:`parse_params`; names not given are sampled), in order. They
        count among ``trials``; one a finished or waiting trial of the study already
        has is not queued again (a continued search does not repeat it; a failed one
        is tried again).
    :return: ``best.json``'s content.
    :raises MissingRLDependencies: optuna missing.
    :raises TrialFailed: no trial finished.
    :raises StudyMismatch: ``out`` holds a study started with other ``fixed`` flags
        or the other search space.
    :raises OutputLocked: another search is running in ``out``.
    :raises EnqueueError: more enqueued trials than trials left to run.
    """
    optuna = import_optuna()
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with output_lock(out, writer="search"):  # one search per folder
        # pretrain_episodes 0 or None: no cloning (train refuses --pretrain-episodes 0)
        fixed = {
            k: v
            for k, v in (fixed or {}).items()
            if not (k in ("pretrain_episodes", "pretrain_epochs") and not v)
        }
        study = optuna.create_study(
            study_name="aldm-gym",
            storage=f"sqlite:///{out / STUDY_FILE}",
            load_if_exists=True,
            direction="maximize",
            sampler=optuna.samplers.TPESampler(seed=seed, n_startup_trials=min(6, trials)),
        )
        space = space_name(fixed)
        _check_continuation(study, out, space, fixed)
        study.set_user_attr("space", space)
        study.set_user_attr("fixed", _as_json(fixed))
        _fail_stale(study)
        done = sum(t.state.name == "COMPLETE" for t in study.trials)
        _enqueue(study, enqueue, max(trials - done, 0))
        if trials > done:
            _optimize(
                study, lambda trial: _run_trial(trial, out, fixed), trials - done, jobs, on_trial
            )
        write_table(study.trials, out / TRIALS_TABLE, SPACES[space])
        complete = [t for t in study.trials if t.state.name == "COMPLETE"]
        if not complete:
            raise TrialFailed(f"no trial finished; see the train.log files in {out / TRIALS_DIR}")
        best = max(complete, key=lambda t: t.value)
        command = train_command(best.params, _full_budget(fixed), Path("OUT"), progress=True)
        record = {
            "trial": best.number,
            "score": best.value,
            "params": best.params,
            "kept": best.user_attrs,
            "space": space,
            "fixed": fixed,
            "command": shlex.join(["aldm-gym", *command[3:]]),
            "trials": len(complete),
        }
        write_json(out / BEST_FILE, record)
        return record


def _optimize(
    study: Any,
    objective: Callable[[Any], float],
    n_trials: int,
    jobs: int,
    on_trial: Callable[[Any], None] | None,
) -> None:
    """Run ``n_trials`` trials of ``objective``, ``jobs`` at once (threads; each trial
    is a training subprocess), by optuna's ask-and-tell interface.

    ``study.optimize(n_jobs=...)`` is not used: with SQLite storage, two of its threads
    can take the same enqueued trial (optuna issues #4002 and #4621), and the second
    then fails on the first one's locked folder. Here a lock makes each ``ask`` alone.
    A trial that raises :class:`TrialFailed` is told as failed and the search goes on;
    any other error, or Ctrl-C, starts no new trial and is raised once the running
    trials have ended (Ctrl-C at a terminal stops their trainings too, each at a safe
    point).
    """
    from optuna.trial import TrialState

    lock = threading.Lock()
    stop = threading.Event()
    left = [n_trials]
    running = [0]

    def worker() -> None:
        try:
            while True:
                with lock:
                    if stop.is_set() or left[0] <= 0:
                        return
                    left[0] -= 1
                    trial = study.ask()
                    running[0] += 1
                try:
                    value = objective(trial)
                except TrialFailed as exc:
                    logger.warning("%s", exc)
                    frozen = study.tell(trial, state=TrialState.FAIL)
                except BaseException:
                    study.tell(trial, state=TrialState.FAIL)
                    raise
                else:
                    frozen = study.tell(trial, value)
                finally:
                    with lock:
                        running[0] -= 1
                if on_trial is not None:
                    with lock:
                        on_trial(frozen)
        except BaseException:
            stop.set()
            raise

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        try:
            futures = [pool.submit(worker) for _ in range(min(jobs, n_trials))]
            for future in futures:
                future.result()
        except BaseException:
            stop.set()
            if running[0]:
                logger.warning("stopping: waiting for the %d running trials to end", running[0])
            raise


def _as_json(value: Any) -> Any:
    """``value`` as JSON gives it back (tuples as lists), to compare with a stored one."""
    return json.loads(json.dumps(value))


def _flag(name: str) -> str:
    """The command-line flag of a train argument (``n_steps`` -> ``--n-steps``)."""
    return "--" + name.replace("_", "-")


def _check_continuation(study: Any, out: Path, space: str, fixed: Mapping[str, Any]) -> None:
    """Refuse to continue ``study`` with other fixed flags or another search space
    (:class:`StudyMismatch`): its trials would not compare, and ``best.json``'s command
    would not train the best of them. A study of an older version, without the record,
    is taken as a search from scratch with any fixed flags."""
    if not study.trials and "space" not in study.user_attrs:
        return
    started = study.user_attrs.get("space", "scratch")
    if started != space:
        given = "with" if started == "finetune" else "without"
        raise StudyMismatch(
            f"{out} holds a search {given} --pretrain-episodes (the {started!r} space); "
            f"continue it {given} --pretrain-episodes, or choose another --out"
        )
    saved = study.user_attrs.get("fixed")
    if saved is None:
        return
    now = _as_json(fixed)
    changed = sorted(k for k in {*saved, *now} if saved.get(k) != now.get(k))
    if changed:
        was = ", ".join(f"{_flag(k)} {saved.get(k, '(not given)')}" for k in changed)
        raise StudyMismatch(
            f"{out} holds a search with {was}; continue it with the same flags, or "
            "choose another --out"
        )


def _full_budget(fixed: Mapping[str, Any]) -> dict[str, Any]:
    """The best trial's flags with the full training's budget: the trials' own when
    they had at least ``train``'s default (a search at the full budget, as fine-tuning
    a clone needs), else that default [policy steps]."""
    trial_steps = fixed.get("timesteps") or 0
    return {**fixed, "timesteps": max(int(trial_steps), DEFAULT_TIMESTEPS)}


def plot_trials(out: Path, title: str) -> Path | None:
    """Draw the validation curves of the search's finished trials (mean speed and
    collisions over training steps, a ring at each kept model, the rule-based LCA and
    IDLE dashed) to ``<out>/trials.png``, from ``trials.csv`` and each trial's
    ``validation.json``.

    :param title: what the trials observe (the figure's title, e.g. ``"ALDM"``).
    :return: the figure's path, or None when no finished trial has a validation.
    """
    from aldm_gym.agents.figures import plot_learning_curves

    out = Path(out)
    with open(out / TRIALS_TABLE, newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["state"] == "COMPLETE"]
    runs = []
    for row in rows:
        path = out / TRIALS_DIR / f"{int(row['trial']):03d}" / VALIDATION_FILE
        if path.exists():
            record = json.loads(path.read_text())
            runs.append((f"trial {row['trial']} ({float(row['score']):.2f})", record))
    if not runs:
        return None
    figure = out / TRIALS_FIGURE
    plot_learning_curves({title: runs}, figure, label="search trials")
    return figure


def write_table(trials: Sequence[Any], path: Path, space: Mapping[str, Any] = SEARCH_SPACE) -> None:
    """One row per trial: number, state, score, the hyperparameters of ``space`` and
    what it kept."""
    extra = ("steps", "mean_speed", "success_rate", "collisions", "rule_based_speed", "wall_s")
    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["trial", "state", "score", *space, *extra])
        for t in trials:
            if t.state.name == "WAITING":  # queued by --enqueue, not run (yet)
                continue
            writer.writerow(
                [
                    t.number,
                    t.state.name,
                    "" if t.value is None else f"{t.value:.4f}",
                    *(t.params.get(name, "") for name in space),
                    *(t.user_attrs.get(name, "") for name in extra),
                ]
            )
