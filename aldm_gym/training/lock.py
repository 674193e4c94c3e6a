"""One writer per output folder: an ``flock`` on ``<out>/train.lock``.

A training holds the lock while it runs; a second one is refused naming the holder's
pid (:class:`~aldm_gym.errors.OutputLocked`). The kernel releases the lock of a killed
process, so the next training takes it over, with a
:class:`~aldm_gym.errors.TrainingWarning` naming the old pid.
"""

from __future__ import annotations

import fcntl
import os
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from aldm_gym.errors import OutputLocked, TrainingWarning
from aldm_gym.training.outputs import LOCK_FILE


@contextmanager
def output_lock(out: Path, quiet: bool = False, writer: str = "training") -> Iterator[None]:
    """Hold ``<out>/train.lock`` (``flock``, exclusive) while the block runs.

    The file holds the holder's pid. The kernel releases an ``flock`` when its process
    dies, so a lock left by a killed training is taken over (a :class:`TrainingWarning`
    names its pid); a clean exit empties the file.

    :param quiet: do not warn about, nor clear, a stale lock (a check only).
    :param writer: what holds such a lock, for the message (``"training"``, ``"search"``).
    :raises OutputLocked: another live process holds the lock (the message names its pid).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_FILE
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_pid(fd)
            raise OutputLocked(
                f"{out} is being written by another {writer} (pid {holder or 'unknown'}, "
                f"lock {path}); wait for it to end or choose another --out"
            ) from None
        if quiet:
            fcntl.flock(fd, fcntl.LOCK_UN)
            yield
            return
        previous = _read_pid(fd)
        if previous is not None and previous != os.getpid():
            warnings.warn(
                f"{path}: took over the lock of pid {previous}, which ended without "
                "releasing it (killed?)",
                TrainingWarning,
                stacklevel=3,
            )
        _write_pid(fd, os.getpid())
        try:
            yield
        finally:
            _write_pid(fd, None)
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


def check_unlocked(out: Path) -> None:
    """Raise :class:`OutputLocked` if a live training holds the lock of ``out``.

    A check before starting (the message then names the writer rather than the files
    it has written); :func:`output_lock` is what excludes a second writer.
    """
    path = Path(out) / LOCK_FILE
    if not path.exists():
        return
    with output_lock(out, quiet=True):
        pass


def _read_pid(fd: int) -> int | None:
    """The pid written in a lock file, or None (empty or unreadable)."""
    text = os.pread(fd, 64, 0).decode(errors="replace").strip()
    return int(text) if text.isdigit() else None


def _write_pid(fd: int, pid: int | None) -> None:
    """Replace the lock file's content by ``pid`` (None: empty it)."""
    os.ftruncate(fd, 0)
    if pid is not None:
        os.pwrite(fd, f"{pid}\n".encode(), 0)
    os.fsync(fd)
