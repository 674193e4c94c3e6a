"""One interface for the two trainers (:class:`Backend`) and the training they share.

A backend is one way of training PPO on ``ALDMHighway-v0``: stable-baselines3 on one
machine (:class:`~aldm_gym.training.sb3.backend.SB3Backend`) or Ray RLlib on a Ray
cluster (:class:`~aldm_gym.training.rllib.backend.RLlibBackend`). :func:`train_with`
drives either through a training; what every training does is written here once:

* it holds the output folder's lock (:func:`~aldm_gym.training.lock.output_lock`) and
  removes the temporary files an interrupted write left;
* a new training refuses a folder that holds one; a resume reads ``training.json``,
  refuses another backend's training and restores the env config, the hyperparameters
  and the run settings not given
  (:func:`~aldm_gym.training.record.resolve_run`);
* a resume continues from the newest checkpoint that is intact and restores, skipping
  each newer one with a :class:`~aldm_gym.errors.TrainingWarning` that says why
  (:func:`restore_newest`); with none it starts again from step 0;
* ``training.json`` (:class:`~aldm_gym.training.record.TrainingRecord`) is written
  once the trainer is built (a failure before leaves the
  folder as it was);
* the first SIGINT or SIGTERM stops the training at a safe point
  (:func:`~aldm_gym.training.signals.stop_on_signal`), the last consistent state is
  saved as a checkpoint, a line says what was saved and ``KeyboardInterrupt`` reaches
  the caller; saves are never cut short by a signal.

Lines go to this module's logger; the command line prints them.
"""

from __future__ import annotations

import importlib
import logging
import time
import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping, Sequence
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Generic, Protocol, TypeVar

from aldm_gym.envs.config import EnvOverrides
from aldm_gym.errors import (
    CheckpointError,
    ConfigError,
    MissingRLDependencies,
    ResumeError,
    TrainingWarning,
)
from aldm_gym.training.lock import output_lock
from aldm_gym.training.outputs import (
    TRAINING_FILE,
    holds_training,
    remove_temporary_files,
)
from aldm_gym.training.record import TrainingRecord, resolve_run
from aldm_gym.training.settings import PPOParams, check_run_settings
from aldm_gym.training.signals import (
    StopRequest,
    raised_by_interrupt,
    signals_deferred,
    stop_on_signal,
)

logger = logging.getLogger(__name__)

_TITLES = {"sb3": "SB3", "rllib": "RLlib"}
"""How messages name the backends."""


class CheckpointLike(Protocol):
    """A checkpoint on disk as the shared code sees it."""

    @property
    def steps(self) -> int:
        """Steps trained when it was saved."""
        ...

    @property
    def path(self) -> Path:
        """Its file or folder (the one named in messages)."""
        ...


@dataclass(frozen=True)
class CheckpointRef:
    """A checkpoint on disk: its step count and its file or folder.

    :ivar steps: steps trained when it was saved.
    :ivar path: its file or folder.
    """

    steps: int
    path: Path


C = TypeVar("C", bound=CheckpointLike)


class Backend(ABC, Generic[C]):
    """One way of training PPO on ``ALDMHighway-v0``, driven by :func:`train_with`.

    An instance is one training of one output folder. :func:`train_with` calls
    :meth:`session` around the rest; then :meth:`restore` (a resume, through
    :func:`restore_newest`) or :meth:`build`; :meth:`learn`; and
    :meth:`save_final`, or after a stop :meth:`save_checkpoint`; :meth:`close` last.

    :param out: the output folder.
    :param record: the training's record (``training.json``: backend, env config,
        hyperparameters, run settings).
    :param saved: the record being resumed, or None for a new training.
    :param progress: show a progress bar.
    :cvar name: the backend's name (``training.json``'s ``backend``, ``--backend``).
    :cvar stops_at_once: the first signal stops the training at once (its last
        consistent state is always at hand), rather than at the end of the chunk of
        training in progress.
    :cvar algorithms: the algorithms it trains (class names, ``training.json``'s
        ``algorithm``; :data:`~aldm_gym.training.settings.ALGORITHMS`).
    """

    name: ClassVar[str]
    stops_at_once: ClassVar[bool]
    algorithms: ClassVar[tuple[str, ...]] = ("PPO",)

    def __init__(
        self, out: Path, record: TrainingRecord, saved: TrainingRecord | None, progress: bool
    ) -> None:
        self.out = Path(out)
        self.record = record
        self.saved = saved
        self.progress = progress

    @property
    def params(self) -> PPOParams:
        """The training's hyperparameters."""
        return self.record.ppo

    def write_record(self) -> None:
        """Write :attr:`record` to the output folder's ``training.json``."""
        self.record.write(self.out / TRAINING_FILE)

    @staticmethod
    @abstractmethod
    def require() -> None:
        """Import the backend's libraries, or raise
        :class:`~aldm_gym.errors.MissingRLDependencies` saying how to install them."""

    @classmethod
    def require_algorithm(cls, algorithm: str) -> None:
        """Refuse an algorithm this backend does not train (and, in a subclass, import
        what it needs).

        :raises ConfigError: naming the algorithm and the backend's ones.
        """
        if algorithm not in cls.algorithms:
            known = ", ".join(cls.algorithms)
            raise ConfigError(
                f"the {_TITLES.get(cls.name, cls.name)} backend trains {known}, not {algorithm}"
            )

    def session(self) -> AbstractContextManager[Any]:
        """What the training runs in (the RLlib backend's Ray instance); nothing here."""
        return nullcontext()

    @abstractmethod
    def checkpoints(self) -> list[C]:
        """The checkpoints of the output folder, newest first (not read yet)."""

    @abstractmethod
    def checkpoint_fault(self, checkpoint: C) -> str | None:
        """Why ``checkpoint`` cannot be used (naming the file), or None if intact."""

    @abstractmethod
    def restore(self, checkpoint: C) -> str:
        """Make the trainer from ``checkpoint``; a note for the line announcing the
        resume (how the envs continue).

        :raises CheckpointError: it does not restore (the next older one is tried).
        """

    @abstractmethod
    def build(self) -> None:
        """Make a new trainer, at step 0."""

    @abstractmethod
    def learn(self, stop: StopRequest) -> None:
        """Train to the budget in chunks (SB3: rollouts, RLlib: iterations), saving a
        checkpoint every ``checkpoint_freq`` steps; return early, at a safe point, once
        ``stop`` is requested."""

    @abstractmethod
    def save_checkpoint(self) -> CheckpointLike | None:
        """After a stop: save the last consistent state as a checkpoint, unless one of
        its steps is on disk intact; that checkpoint, or None if nothing new was
        trained."""

    @abstractmethod
    def save_final(self) -> Path:
        """After the budget: save the last checkpoint and the final model; its path."""

    @abstractmethod
    def close(self, interrupted: bool) -> None:
        """Release the trainer (envs, workers); after an interruption without waiting
        for work in progress."""

    @classmethod
    @abstractmethod
    def load_policy(cls, path: Path) -> tuple[Any, dict[str, Any]]:
        """A trained model or checkpoint of this backend as a policy with SB3's
        ``predict`` (:mod:`aldm_gym.agents.episodes` plays it), and the
        ``training.json`` of its output folder.

        :raises FileNotFoundError: no model there, or no ``training.json`` beside it.
        :raises CheckpointError: the model or its ``training.json`` is corrupt.
        """


B = TypeVar("B", bound=Backend[Any])


def import_extra(
    modules: Sequence[str], error: type[MissingRLDependencies], needs: str, extra: str
) -> None:
    """Import ``modules`` (an optional extra's), or raise ``error`` saying how to install
    them.

    :param needs: what needs them, and which they are (the message's start).
    :param extra: the extra that installs them (``rl``, ``ray``).
    """
    try:
        for module in modules:
            importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise error(
            f"{needs} ({exc}); install them with: pip install torch==2.13.0 && "
            f"pip install -e '.[{extra}]' (from a clone)"
        ) from exc


def warn_skipped(checkpoint: CheckpointLike, fault: str) -> None:
    """Warn (:class:`~aldm_gym.errors.TrainingWarning`) that ``checkpoint`` is skipped."""
    warnings.warn(f"skipping checkpoint {checkpoint.steps}: {fault}", TrainingWarning, stacklevel=3)


def first_intact(checkpoints: Iterable[C], fault: Callable[[C], str | None]) -> C | None:
    """The first of ``checkpoints`` without a ``fault``, or None; each one before it is
    skipped with a warning saying why (:func:`warn_skipped`)."""
    for checkpoint in checkpoints:
        why = fault(checkpoint)
        if why is None:
            return checkpoint
        warn_skipped(checkpoint, why)
    return None


def restore_newest(backend: Backend[Any]) -> tuple[int, str]:
    """Restore ``backend`` from the newest checkpoint that is intact and restores (each
    newer one skipped with a warning), else build it new; its steps and a note."""
    for checkpoint in backend.checkpoints():
        fault = backend.checkpoint_fault(checkpoint)
        if fault is None:
            try:
                return checkpoint.steps, backend.restore(checkpoint)
            except CheckpointError as exc:
                fault = str(exc)
        warn_skipped(checkpoint, fault)
    backend.build()
    return 0, "no intact checkpoint: starting again from step 0"


def train_with(
    backend_type: type[B],
    out: Path,
    *,
    given: Mapping[str, int | None],
    config: EnvOverrides,
    params: PPOParams | None,
    resume: bool,
    progress: bool,
    algorithm: str = "PPO",
    **options: Any,
) -> B:
    """Train (or resume) with a backend, holding the lock of ``out``; the backend,
    trained (see the module docstring for what this does).

    :param given: the backend's run settings as given (None: default, or for a resume
        the saved value).
    :param config: the ``ALDMHighway-v0`` config of a new training
        (:func:`~aldm_gym.training.settings.env_config`).
    :param params: hyperparameters of a new training (None: the defaults).
    :param algorithm: the algorithm of a new training (a class name of
        :data:`~aldm_gym.training.settings.ALGORITHMS`; a resume keeps the saved one).
    :param options: the backend's own arguments.
    :raises FileExistsError: ``out`` holds a training and ``resume`` is False.
    :raises FileNotFoundError: ``resume`` without a ``training.json`` in ``out``.
    :raises ResumeError: ``resume`` of another backend's training.
    :raises ConfigError: a run setting out of range, or an algorithm the backend does
        not train.
    :raises OutputLocked: another training is writing ``out``.
    :raises KeyboardInterrupt: stopped by a signal (after saving a checkpoint).
    """
    backend_type.require()
    check_run_settings(given)
    with output_lock(out):
        for path in remove_temporary_files(out):
            logger.info("removed %s, left by an interrupted write", path)
        saved = _saved_training(Path(out), backend_type.name) if resume else None
        if saved is None and holds_training(out):
            raise FileExistsError(
                f"{out} already holds a training; pass --resume to continue it "
                "or choose another --out"
            )
        run, report = resolve_run(given, saved, backend_type.name)
        if saved is not None:
            config, params, algorithm = saved.env_config, saved.ppo, saved.algorithm
        backend_type.require_algorithm(algorithm)
        record = TrainingRecord(
            backend=backend_type.name,
            algorithm=algorithm,
            env_config=config,
            ppo=params or PPOParams(),
            run=run,
        )
        backend = backend_type(out, record, saved, progress, **options)
        with backend.session():
            _train(backend, report)
    return backend


def _saved_training(out: Path, backend: str) -> TrainingRecord:
    """The record a resume of ``backend`` continues."""
    if not (out / TRAINING_FILE).exists():
        raise FileNotFoundError(f"nothing to resume in {out}: no {TRAINING_FILE}")
    saved = TrainingRecord.read(out / TRAINING_FILE)
    other = saved.backend
    if other != backend:
        raise ResumeError(
            f"{out} holds an {_TITLES.get(other, other)} training; resume it with --backend {other}"
        )
    return saved


def _train(backend: Backend[Any], report: list[str]) -> None:
    """Build or restore, learn, and save (see :func:`train_with`)."""
    t0 = time.perf_counter()
    interrupted = stopped = False
    try:
        with stop_on_signal(at_once=backend.stops_at_once) as stop:
            try:
                # Building imports and compiles: an interrupt inside a module's import
                # leaves a broken module (ImportError: initialization failed), so a
                # signal waits until the build is done and then stops it here (a
                # second one stops at once).
                with signals_deferred(insist=True):
                    if backend.saved is not None:
                        done, note = restore_newest(backend)
                        lines = "; ".join([*report, note])
                        logger.info("resuming %s at %d steps; %s", backend.out, done, lines)
                    else:
                        backend.build()
                backend.write_record()
                backend.learn(stop)
            except (KeyboardInterrupt, SystemError) as exc:
                if not raised_by_interrupt(exc):
                    raise
                interrupted = True
        stopped = interrupted or stop.requested
        with signals_deferred():
            if not stopped:
                backend.save_final()
                return
            # A backend that stops only between chunks has nothing consistent to save
            # when a second signal cut one short.
            safe = backend.stops_at_once or not interrupted
            saved = backend.save_checkpoint() if safe else None
            began = (backend.out / TRAINING_FILE).exists()
            logger.info(
                "%s after %.0f s; %s",
                "interrupted" if interrupted else "stopped",
                time.perf_counter() - t0,
                _saved_text(backend, saved) + "; continue with --resume"
                if began
                else "before the training began: nothing to resume",
            )
    finally:
        backend.close(stopped)
    raise KeyboardInterrupt


def _saved_text(backend: Backend[Any], saved: CheckpointLike | None) -> str:
    """What a stopped training saved, for the line saying it stopped."""
    if saved is not None:
        return f"saved {saved.path} ({saved.steps} steps)"
    newest = backend.checkpoints()[:1]
    if newest:
        return f"nothing new to save; the newest checkpoint is {newest[0].path}"
    return "nothing saved yet"
