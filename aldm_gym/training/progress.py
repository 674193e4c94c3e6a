"""What a training shows while it runs: its progress bar and its progress lines.

The bar (:func:`training_bar`, tqdm) counts the steps of the whole, possibly resumed,
training; its postfix (:func:`postfix`) shows the mean return and length of
the recent training episodes. Progress lines (a validation announced, its result) are
records of this module's logger, :data:`logger` (:func:`report`): the command line
prints them to stdout, a library caller sees them by configuring :mod:`logging`.
"""

from __future__ import annotations

import logging
import math
from typing import Any

logger = logging.getLogger(__name__)


def report(line: str) -> None:
    """Log one progress line of the training (INFO, on :data:`logger`)."""
    logger.info(line)


def training_bar(total: int, initial: int, enabled: bool = True) -> Any:
    """A tqdm bar over a training's ``total`` steps, starting at ``initial`` (a resume).

    :param enabled: False: the bar shows nothing.
    """
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc="train", unit="step", disable=not enabled)


def postfix(mean_return: float | None, mean_length: float | None) -> dict[str, str]:
    """The bar's postfix: mean return (``ep_rew``) and length (``ep_len``) of the recent
    training episodes, ``-`` for one not known yet (None or not finite)."""

    def text(value: float | None, fmt: str) -> str:
        return "-" if value is None or not math.isfinite(value) else format(value, fmt)

    return {"ep_rew": text(mean_return, ".2f"), "ep_len": text(mean_length, ".1f")}
