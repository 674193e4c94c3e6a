"""How ``aldm-gym train`` and ``evaluate`` show the library's messages.

The training and evaluation code logs (:mod:`logging`) rather than printing. While a
command runs, :func:`console` prints aldm-gym's records of level INFO and up as plain
lines, through ``tqdm.write`` so that they do not break a progress bar: the progress
lines of a training (the logger of :mod:`aldm_gym.training.progress`: validations
announced and their results) to stdout, everything else (resuming, stopping, what was
saved) to stderr.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from tqdm import tqdm

from aldm_gym.training.progress import logger as progress_logger


class LineHandler(logging.Handler):
    """Writes each record's message as one line with ``tqdm.write``.

    :param stdout: write to stdout (else stderr), the stream current when the record
        is written.
    """

    def __init__(self, stdout: bool) -> None:
        super().__init__(logging.INFO)
        self.stdout = stdout

    def emit(self, record: logging.LogRecord) -> None:
        """Write ``record``'s message."""
        try:
            tqdm.write(record.getMessage(), file=sys.stdout if self.stdout else sys.stderr)
        except Exception:  # a closed stream: logging's own report
            self.handleError(record)


@contextmanager
def console() -> Iterator[None]:
    """Print aldm-gym's log records while the block runs (see the module docstring);
    the loggers are left as they were after."""
    package = logging.getLogger("aldm_gym")
    handlers = {package: LineHandler(stdout=False), progress_logger: LineHandler(stdout=True)}
    saved = {logger: (logger.level, logger.propagate) for logger in handlers}
    for logger, handler in handlers.items():
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)
    progress_logger.propagate = False
    try:
        yield
    finally:
        for logger, handler in handlers.items():
            logger.removeHandler(handler)
            logger.setLevel(saved[logger][0])
            logger.propagate = saved[logger][1]
