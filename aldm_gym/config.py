"""Validated configuration: unknown keys and impossible values raise ``ValueError``.

Every configurable component (road generator, line sensor, detector, environment)
declares its defaults as a frozen dataclass. :func:`build_config` turns a user's
mapping into an instance, naming any unknown key together with the allowed ones,
so that a misspelled key can never be silently ignored.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, TypeVar

T = TypeVar("T")


def build_config(cls: type[T], overrides: Mapping[str, Any] | T | None, *, where: str) -> T:
    """Build a config dataclass ``cls`` from defaults updated with ``overrides``.

    :param cls: a dataclass type whose fields are the allowed keys.
    :param overrides: a mapping of keys to values, an instance of ``cls``, or ``None``.
    :param where: the component's name, used in error messages (e.g. ``"sensor"``).
    :raises TypeError: when ``overrides`` is neither a mapping nor a ``cls``.
    :raises ValueError: naming the unknown key(s) and the allowed ones.
    """
    if overrides is None:
        return cls()
    if isinstance(overrides, cls):
        return overrides
    if not isinstance(overrides, Mapping):
        raise TypeError(
            f"{where} config must be a mapping or {cls.__name__}, got {type(overrides).__name__}"
        )
    allowed = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    unknown = sorted(str(k) for k in overrides if k not in allowed)
    if unknown:
        raise ValueError(
            f"unknown {where} config key(s) {unknown}; allowed keys: {sorted(allowed)}"
        )
    return cls(**dict(overrides))


def check_range(
    where: str,
    name: str,
    value: Any,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    integer: bool = False,
) -> None:
    """Raise ``ValueError`` unless ``value`` is a finite number within ``[lo, hi]``.

    :param where: component name for the message.
    :param name: the key being checked.
    :param lo_open: exclude ``lo`` itself (``value > lo``).
    :param integer: require an integral value.
    """
    ok_type = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok_type or not math.isfinite(float(value)):
        raise ValueError(f"{where}.{name} must be a finite number, got {value!r}")
    if integer and float(value) != int(value):
        raise ValueError(f"{where}.{name} must be an integer, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        op = ">" if lo_open else ">="
        raise ValueError(f"{where}.{name} must be {op} {lo}, got {value!r}")
    if hi is not None and value > hi:
        raise ValueError(f"{where}.{name} must be <= {hi}, got {value!r}")


def check_choice(where: str, name: str, value: Any, choices: tuple[Any, ...]) -> None:
    """Raise ``ValueError`` unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{where}.{name} must be one of {list(choices)}, got {value!r}")
