"""SIGINT and SIGTERM during a training: stop at a safe point, then checkpoint.

:func:`stop_on_signal` turns the first SIGINT or SIGTERM into a stop request: a backend
whose last consistent state is always at hand (SB3 keeps a snapshot of the last
update in memory) stops at once, with ``KeyboardInterrupt``; one that can only save at
the end of a chunk of training (an RLlib iteration) finishes it and then stops. A
second signal raises ``KeyboardInterrupt`` at once. :func:`signals_deferred` holds
both back while a save completes.
"""

from __future__ import annotations

import logging
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

logger = logging.getLogger(__name__)

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""The signals that stop a training (Ctrl-C, ``kill PID``)."""


@dataclass
class StopRequest:
    """Set by the first stop signal of a training: stop at the next safe point.

    :ivar requested: a signal asked the training to stop.
    """

    requested: bool = False


@contextmanager
def stop_on_signal(at_once: bool) -> Iterator[StopRequest]:
    """While the block runs, the first SIGINT or SIGTERM sets the request it yields
    (and, with ``at_once``, raises ``KeyboardInterrupt``); a second one raises
    ``KeyboardInterrupt``. Outside the main thread the signals stay as they are.

    :param at_once: the trainer can save its last consistent state from any instant.
    """
    stop = StopRequest()

    def handler(signum: int, frame: Any) -> None:
        if at_once or stop.requested:
            raise KeyboardInterrupt
        stop.requested = True
        logger.info(
            "stopping after this iteration and saving a checkpoint "
            "(signal again to stop at once, losing the iteration)"
        )

    try:
        previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    except ValueError:  # not the main thread: signals stay as they are
        yield stop
        return
    try:
        yield stop
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextmanager
def signals_deferred(insist: bool = False) -> Iterator[None]:
    """Hold SIGINT and SIGTERM back while the block runs (a save completes); they are
    raised again when it ends, to the handlers then in place. With ``insist``, a second
    signal while the block runs raises ``KeyboardInterrupt`` at once (a user who presses
    Ctrl-C twice does not wait for a long build).

    The handlers are swapped rather than the signals masked: a process with threads
    (torch's, Ray's) takes a signal on any thread that does not mask it, and Python
    runs its handler on the main thread either way.
    """
    held: list[int] = []

    def hold(signum: int, frame: Any) -> None:
        if insist and held:
            held.clear()
            raise KeyboardInterrupt
        held.append(signum)

    try:
        previous = {sig: signal.signal(sig, hold) for sig in STOP_SIGNALS}
    except ValueError:  # not the main thread: signals stay as they are
        yield
        return
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
        for signum in held:
            signal.raise_signal(signum)


def raised_by_interrupt(exc: BaseException) -> bool:
    """``exc`` is a KeyboardInterrupt, or carries one in its chain.

    A signal handler runs wherever the interpreter checks for signals, also inside a
    C extension's call (a numba kernel boxing its result): the KeyboardInterrupt it
    raises then surfaces as ``SystemError: ... returned a result with an exception
    set``, with the KeyboardInterrupt as its context. Both are the same interruption.
    """
    seen: set[int] = set()
    cur: BaseException | None = exc
    while cur is not None and id(cur) not in seen:
        if isinstance(cur, KeyboardInterrupt):
            return True
        seen.add(id(cur))
        cur = cur.__cause__ or cur.__context__
    return False
