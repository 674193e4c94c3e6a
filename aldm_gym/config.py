"""Validated configuration: unknown keys and impossible values raise ``ValueError``.

Every configurable component (road generator, line sensor, ALDM, LKA, the env's
action / observation sections and the env itself) declares its settings as a frozen
dataclass whose fields carry their default *and* their rule, once::

    @dataclass(frozen=True)
    class RoadConfig:
        lanes_count: int = setting(4, lo=1, hi=6, integer=True)
        max_radius: float = setting(3000.0, lo="min_radius")   # bound by another field

        def __post_init__(self) -> None:
            validate(self, "road")

:func:`validate` is the one validator for all of them: finite numbers within their
range (numpy scalars accepted and turned into Python numbers), integers, booleans,
choices, ``(min, max)`` pairs and number lists, ``None`` where allowed; the message
names ``section.key``. :func:`build_config` turns a user's mapping into an instance,
naming any unknown key together with the allowed ones, so that a misspelled key can
never be silently ignored. Rules that relate several fields in other ways stay in
the class's ``__post_init__``, after :func:`validate`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from aldm_gym.errors import ConfigError

T = TypeVar("T")

Bound = float | str | None
"""A range bound: a number, the name of another field of the same config, or none."""


@dataclass(frozen=True)
class Rule:
    """What a config field accepts (stored in the field's ``metadata["rule"]``).

    :ivar kind: ``"number"`` (int or float), ``"bool"``, ``"str"``, ``"choice"``,
        ``"pair"`` (a (min, max) pair of numbers, min <= max), ``"numbers"`` (a
        non-empty sequence of numbers), ``"any"`` (checked by the owner).
    :ivar lo, hi: inclusive bounds of numbers (of every item for pairs and lists);
        a string names another field whose value is the bound.
    :ivar lo_open: exclude ``lo`` itself.
    :ivar integer: numbers must be integral.
    :ivar choices: allowed values of a ``"choice"``.
    :ivar optional: ``None`` is allowed.
    :ivar increasing: a ``"numbers"`` list must be sorted ascending.
    """

    kind: str = "number"
    lo: Bound = None
    hi: Bound = None
    lo_open: bool = False
    integer: bool = False
    choices: tuple[Any, ...] = ()
    optional: bool = False
    increasing: bool = False


def setting(default: Any = dataclasses.MISSING, **rule: Any) -> Any:
    """A dataclass field with its default and its :class:`Rule` (keyword arguments).

    The kind is inferred when not given: ``bool`` defaults are ``"bool"``, ``str``
    defaults with ``choices`` are ``"choice"``, list defaults are ``"numbers"``
    (copied per instance), everything else ``"number"``.
    """
    if "kind" not in rule:
        if isinstance(default, bool):
            rule["kind"] = "bool"
        elif "choices" in rule:
            rule["kind"] = "choice"
        elif isinstance(default, str):
            rule["kind"] = "str"
        elif isinstance(default, list):
            rule["kind"] = "numbers"
    if "choices" in rule:
        rule["choices"] = tuple(rule["choices"])
    meta = {"rule": Rule(**rule)}
    if isinstance(default, list):
        frozen = list(default)
        return dataclasses.field(default_factory=lambda: list(frozen), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def section(cls: type) -> Any:
    """A dataclass field holding a nested config dataclass ``cls`` (its defaults when
    not given). The owner validates a mapping given for it into a ``cls``."""
    return dataclasses.field(default_factory=cls, metadata={"rule": Rule(kind="any")})


def is_number(value: Any) -> bool:
    """A real number (Python or numpy), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python number it holds; anything else unchanged."""
    if isinstance(value, np.generic) and not isinstance(value, np.bool_):
        if isinstance(value, np.integer):
            return int(value)
        if isinstance(value, np.floating):
            return float(value)
    return value


def _bound(obj: Any, bound: Bound) -> float | None:
    return getattr(obj, bound) if isinstance(bound, str) else bound


def check_value(where: str, name: str, value: Any, rule: Rule, obj: Any = None) -> Any:
    """Check ``value`` against ``rule``; return it normalised (numpy scalars made plain).

    :param obj: the config holding the field, to resolve bounds that name fields.
    :raises ConfigError: naming ``where.name``, what is allowed and what was given.
    """
    if value is None and rule.optional:
        return None
    kind = rule.kind
    lo, hi = _bound(obj, rule.lo), _bound(obj, rule.hi)
    if kind == "any":
        return value
    if kind == "bool":
        if isinstance(value, bool):
            return value
        if isinstance(value, np.bool_):
            return bool(value)
        raise ConfigError(f"{where}.{name} must be a bool, got {value!r}")
    if kind == "choice":
        if isinstance(value, str | numbers.Number) and value in rule.choices:
            return _plain(value)
        raise ConfigError(f"{where}.{name} must be one of {list(rule.choices)}, got {value!r}")
    if kind == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{where}.{name} must be a string, got {value!r}")
        return value
    if kind == "number":
        value = _plain(value)
        check_range(where, name, value, lo, hi, lo_open=rule.lo_open, integer=rule.integer)
        return int(value) if rule.integer else value
    if kind in ("pair", "numbers"):
        if isinstance(value, str | bytes) or not hasattr(value, "__len__"):
            raise ConfigError(f"{where}.{name} must be a sequence of numbers, got {value!r}")
        items = [_plain(v) for v in value]
        if kind == "pair" and len(items) != 2:
            raise ConfigError(f"{where}.{name} must be a (min, max) pair, got {value!r}")
        if not items:
            raise ConfigError(f"{where}.{name} must be a non-empty list, got {value!r}")
        for k, v in enumerate(items):
            check_range(
                where, f"{name}[{k}]", v, lo, hi, lo_open=rule.lo_open, integer=rule.integer
            )
        if kind == "pair" and items[1] < items[0]:
            raise ConfigError(f"{where}.{name} must be (min, max) with min <= max, got {value!r}")
        if rule.increasing and items != sorted(items):
            raise ConfigError(f"{where}.{name} must be increasing, got {value!r}")
        items = [int(v) if rule.integer else float(v) for v in items]
        return tuple(items) if kind == "pair" else items
    raise TypeError(f"unknown rule kind {kind!r} for {where}.{name}")


def validate(obj: Any, where: str) -> None:
    """Check every field of config dataclass ``obj`` that declares a :class:`Rule`.

    Fields are checked in declaration order, so a bound may name an earlier field.
    Normalised values (numpy scalars made plain, pairs made tuples) are written back,
    also on frozen dataclasses.

    :param where: the section name for messages (``"road"``, ``"sensor"``, ...).
    :raises ConfigError: naming ``where.key`` and the rule it breaks.
    """
    for f in dataclasses.fields(obj):
        rule = f.metadata.get("rule")
        if rule is None:
            continue
        value = getattr(obj, f.name)
        new = check_value(where, f.name, value, rule, obj)
        if new is not value:
            object.__setattr__(obj, f.name, new)


def rules(cls: Any) -> dict[str, Rule]:
    """Field name -> :class:`Rule` of a config dataclass (for docs and tests)."""
    return {f.name: f.metadata["rule"] for f in dataclasses.fields(cls) if "rule" in f.metadata}


def defaults(cls: Any) -> dict[str, Any]:
    """Field name -> default value of a config dataclass (fresh copies)."""
    return dataclasses.asdict(cls())


def build_config(cls: type[T], overrides: Mapping[str, Any] | T | None, *, where: str) -> T:
    """Build a config dataclass ``cls`` from defaults updated with ``overrides``.

    :param cls: a dataclass type whose fields are the allowed keys.
    :param overrides: a mapping of keys to values, an instance of ``cls``, or ``None``.
    :param where: the component's name, used in error messages (e.g. ``"sensor"``).
    :raises TypeError: when ``overrides`` is neither a mapping nor a ``cls``.
    :raises ConfigError: naming the unknown key(s) and the allowed ones.
    """
    if overrides is None:
        return cls()
    if isinstance(overrides, cls):
        return overrides
    if not isinstance(overrides, Mapping):
        raise TypeError(
            f"{where} config must be a mapping or {cls.__name__}, got {type(overrides).__name__}"
        )
    check_keys(f"{where} config", overrides, [f.name for f in dataclasses.fields(cls)])  # type: ignore[arg-type]
    return cls(**dict(overrides))


def check_keys(where: str, keys: Any, allowed: Any) -> None:
    """Raise :class:`ConfigError` unless every key of ``keys`` is a string among ``allowed``.

    The one unknown-key check of every configurable component: the message names the
    unknown keys, the nearest allowed one and all allowed ones, e.g. ``unknown acc
    key(s) ['time_gapp'] (did you mean 'time_gap'?); allowed keys: [...]``.

    :param where: what the keys configure (``"config"``, ``"acc"``, ``"sensor config"``).
    """
    bad = [k for k in keys if not isinstance(k, str)]
    if bad:
        raise ConfigError(f"{where} keys must be strings, got {bad!r}")
    allowed = list(allowed)
    unknown = sorted(k for k in keys if k not in allowed)
    if unknown:
        raise ConfigError(
            f"unknown {where} key(s) {unknown}{close_match(unknown, allowed)}; "
            f"allowed keys: {sorted(allowed)}"
        )


def close_match(unknown: list[str], allowed: Any) -> str:
    """``" (did you mean 'key'?)"`` for the first unknown key's closest allowed key,
    or ``""`` when none is close (for error messages naming unknown keys)."""
    close = difflib.get_close_matches(unknown[0], list(allowed), n=1) if unknown else []
    return f" (did you mean {close[0]!r}?)" if close else ""


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
    if not is_number(value) or not math.isfinite(float(value)):
        raise ConfigError(f"{where}.{name} must be a finite number, got {value!r}")
    if integer and float(value) != math.floor(value):
        raise ConfigError(f"{where}.{name} must be an integer, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        op = ">" if lo_open else ">="
        raise ConfigError(f"{where}.{name} must be {op} {lo}, got {value!r}")
    if hi is not None and value > hi:
        raise ConfigError(f"{where}.{name} must be <= {hi}, got {value!r}")


def check_choice(where: str, name: str, value: Any, choices: tuple[Any, ...]) -> None:
    """Raise ``ValueError`` unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ConfigError(f"{where}.{name} must be one of {list(choices)}, got {value!r}")
