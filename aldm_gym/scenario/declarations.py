"""OpenSCENARIO parameter declarations: types, defaults bound in order, constraints.

:class:`ParameterDeclaration` and :func:`declarations_from_xml` read a
``<ParameterDeclarations>`` element; :func:`bind` gives each declaration a value (a
default may use earlier parameters; expressions: :mod:`aldm_gym.scenario.expressions`)
and :func:`violations` checks the constraint groups. Every error is a
:class:`~aldm_gym.errors.ScenarioError` naming the file, line and element.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np
from lxml import etree

from aldm_gym.errors import InputError, ScenarioError
from aldm_gym.scenario.expressions import (
    INTEGER_PATTERN,
    NAME_PATTERN,
    NUMBER_PATTERN,
    ParamValue,
    format_value,
    parameter_name,
    place_prefix,
    resolve,
    to_float,
)
from aldm_gym.xmlfile import ElementReader, children

__all__ = [
    "PARAMETER_TYPES",
    "RULES",
    "ParameterDeclaration",
    "ValueConstraint",
    "bind",
    "declarations_from_xml",
    "violations",
]

PARAMETER_TYPES = (
    "boolean",
    "dateTime",
    "double",
    "int",
    "integer",
    "string",
    "unsignedInt",
    "unsignedShort",
)
"""``ParameterDeclaration/@parameterType`` values (``int`` is 1.3's name of 1.2's
deprecated ``integer``; both are accepted)."""

RULES = ("equalTo", "greaterThan", "lessThan", "greaterOrEqual", "lessOrEqual", "notEqualTo")
"""``ValueConstraint/@rule`` values."""

_INT_BOUNDS = {
    "int": (-(2**31), 2**31 - 1),
    "integer": (-(2**31), 2**31 - 1),
    "unsignedInt": (0, 2**32 - 1),
    "unsignedShort": (0, 2**16 - 1),
}


@dataclass(frozen=True)
class ValueConstraint:
    """One ``<ValueConstraint rule value>``: the parameter's value must stand in
    ``rule`` (one of :data:`RULES`) to ``value_raw``, which may be a literal, a
    reference or an expression over the other parameters.

    :ivar line: its line in the file, or ``None``.
    """

    rule: str
    value_raw: str
    line: int | None = None


@dataclass(frozen=True)
class ParameterDeclaration:
    """One ``<ParameterDeclaration>``.

    :ivar name: the parameter's name, without ``$``.
    :ivar parameter_type: one of :data:`PARAMETER_TYPES`.
    :ivar default: the ``value`` attribute's raw text (a literal, ``$name`` or
        ``${...}`` over earlier parameters).
    :ivar constraint_groups: the ``<ConstraintGroup>`` elements, each a tuple of its
        constraints: the value is valid when every constraint of at least one group
        holds; no groups means no constraint.
    :ivar line: the line in the file, or ``None``.
    """

    name: str
    parameter_type: str
    default: str
    constraint_groups: tuple[tuple[ValueConstraint, ...], ...] = ()
    line: int | None = None


def _source(el: etree._Element) -> str:
    url = el.getroottree().docinfo.URL
    return str(url) if url else "<xml>"


def declarations_from_xml(element: etree._Element | None) -> list[ParameterDeclaration]:
    """The declarations of an lxml ``<ParameterDeclarations>`` element, in order.

    :param element: the element, or ``None`` (a file without declarations) for ``[]``.
    :raises ScenarioError: a missing attribute, an unknown parameter type or rule, an
        invalid name, an empty ``<ConstraintGroup>`` or an unknown element (naming the
        file, the element and its line).
    """
    if element is None:
        return []
    r = ElementReader(_source(element))
    if element.tag != "ParameterDeclarations":
        raise r.error(element, "expected <ParameterDeclarations>")
    out = []
    for child in children(element):
        if child.tag != "ParameterDeclaration":
            raise r.unexpected(child, ["ParameterDeclaration"])
        name = parameter_name(r.required(child, "name"))
        if not NAME_PATTERN.fullmatch(name):
            raise r.error(child, f"invalid parameter name {name!r} (letters, digits, _)")
        ptype = r.required(child, "parameterType")
        if ptype not in PARAMETER_TYPES:
            raise r.error(child, f"unknown parameterType {ptype!r}; one of {PARAMETER_TYPES}")
        groups = []
        for group in children(child):
            if group.tag != "ConstraintGroup":
                raise r.unexpected(group, ["ConstraintGroup"])
            constraints = []
            for item in children(group):
                if item.tag != "ValueConstraint":
                    raise r.unexpected(item, ["ValueConstraint"])
                rule = r.required(item, "rule")
                if rule not in RULES:
                    raise r.error(item, f"unknown rule {rule!r}; one of {RULES}")
                constraints.append(
                    ValueConstraint(rule, r.required(item, "value"), item.sourceline)
                )
            if not constraints:
                raise r.error(group, "a ConstraintGroup needs at least one ValueConstraint")
            groups.append(tuple(constraints))
        out.append(
            ParameterDeclaration(
                name, ptype, r.required(child, "value"), tuple(groups), child.sourceline
            )
        )
    return out


def _at(file: str, line: int | None) -> str:
    if line is None:
        return file
    return f"{file}:{line}" if file else f"line {line}"


def _convert(value: Any, decl: ParameterDeclaration, where: str) -> ParamValue:
    """``value`` (resolved) as the declaration's type."""
    if isinstance(value, np.generic):
        value = value.item()
    ptype = decl.parameter_type
    shown = format_value(value) if isinstance(value, bool | int | float | str) else value

    def bad(expected: str) -> InputError:
        return ScenarioError(
            f"{place_prefix(where)}parameter {decl.name} is of type {ptype}: "
            f"{shown!r} is not {expected}"
        )

    if ptype == "string":
        if isinstance(value, bool | int | float | str):
            return format_value(value)
        raise bad("a string")
    if ptype == "dateTime":
        if not isinstance(value, str):
            raise bad("a date and time")
        try:
            datetime.fromisoformat(value.strip())
        except ValueError:
            raise bad("an ISO 8601 date and time (2021-07-06T10:00:00)") from None
        return value.strip()
    if ptype == "boolean":
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.strip() in ("true", "false", "1", "0"):
            return value.strip() in ("true", "1")
        raise bad("a boolean (true or false)")
    if ptype == "double":
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            raise bad("a number")
        if isinstance(value, str) and not NUMBER_PATTERN.fullmatch(value.strip()):
            raise bad("a number")
        try:
            number = float(value)
        except OverflowError:  # an integer beyond a double
            raise bad("a finite number") from None
        if not math.isfinite(number):
            raise bad("a finite number")
        return number
    # int, integer, unsignedInt, unsignedShort
    lo, hi = _INT_BOUNDS[ptype]
    integer: int | None = None
    if isinstance(value, int) and not isinstance(value, bool):
        integer = value
    elif isinstance(value, float) and value.is_integer():
        integer = int(value)
    elif isinstance(value, str):
        text = value.strip()
        if INTEGER_PATTERN.fullmatch(text):
            integer = int(text)
        elif NUMBER_PATTERN.fullmatch(text) and float(text).is_integer():
            integer = int(float(text))
    if integer is None:
        raise bad("an integer")
    if not lo <= integer <= hi:
        raise bad(f"in [{lo}, {hi}]")
    return integer


def bind(
    declarations: Sequence[ParameterDeclaration],
    overrides: Mapping[str, Any],
    file: str,
    outer: Mapping[str, ParamValue] | None = None,
) -> dict[str, ParamValue]:
    """The parameters' values: each declaration in order, its default (which may use
    earlier parameters through ``$x`` or ``${...}``) or its override, converted to its
    type (``double`` → ``float``; the integer types → ``int``, in range; ``boolean``
    → ``bool`` from ``true``/``false``/``1``/``0``; ``string`` and ``dateTime`` →
    ``str``). Constraints are not checked here (:func:`violations`).

    :param declarations: the scenario's declarations, in file order.
    :param overrides: values replacing defaults by name: strings are resolved like a
        default (so ``"${...}"`` works), other values are converted directly.
    :param file: the scenario file, named in errors.
    :param outer: the values of the enclosing scope (a ``Story``'s declarations see the
        file's parameters); the result holds them too, the inner ones shadowing.
    :raises ScenarioError: an override for an undeclared parameter (naming it and the
        declared ones), a name declared twice, a default or override that fails to
        resolve or does not convert to its type (naming the parameter and the type).
    """
    declared: dict[str, ParameterDeclaration] = {}
    for decl in declarations:
        if decl.name in declared:
            first = declared[decl.name].line
            raise ScenarioError(
                f"{_at(file, decl.line)}: parameter {decl.name} is declared twice"
                + (f" (first at line {first})" if first is not None else "")
            )
        declared[decl.name] = decl
    unknown = [name for name in overrides if name not in declared]
    if unknown:
        close = difflib.get_close_matches(unknown[0], list(declared), n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        allowed = ", ".join(declared) or "none"
        raise ScenarioError(
            f"{file}: cannot override undeclared parameter{'s' if len(unknown) > 1 else ''} "
            f"{', '.join(unknown)}{hint}; the scenario declares: {allowed}"
        )
    values: dict[str, ParamValue] = dict(outer or {})
    for decl in declarations:
        if decl.name in overrides:
            raw = overrides[decl.name]
            where = f"{file}: override {decl.name}"
        else:
            raw = decl.default
            where = f"{_at(file, decl.line)} <ParameterDeclaration {decl.name} value>"
        value = resolve(raw, values, where) if isinstance(raw, str) else raw
        values[decl.name] = _convert(value, decl, where)
    return values


def _holds(rule: str, value: ParamValue, target: ParamValue) -> bool:
    if rule == "equalTo":
        return value == target
    if rule == "notEqualTo":
        return value != target
    x, y = float(value), float(target)  # numbers only: violations() checks
    if rule == "greaterThan":
        return x > y
    if rule == "lessThan":
        return x < y
    if rule == "greaterOrEqual":
        return x >= y
    return x <= y


def _target(
    decl: ParameterDeclaration,
    constraint: ValueConstraint,
    values: Mapping[str, ParamValue],
    file: str,
) -> ParamValue:
    """The constraint's value, resolved over ``values`` and typed as the parameter."""
    where = f"{_at(file, constraint.line)} <ValueConstraint value>"
    ptype = decl.parameter_type
    if ptype in ("string", "dateTime", "boolean") and constraint.rule not in (
        "equalTo",
        "notEqualTo",
    ):
        raise ScenarioError(
            f"{place_prefix(where)}rule {constraint.rule} needs a numeric parameter, but "
            f"{decl.name} is of type {ptype}: only equalTo and notEqualTo apply"
        )
    target = resolve(constraint.value_raw, values, where)
    if ptype in ("string", "dateTime"):
        return format_value(target)
    if ptype == "boolean":
        if isinstance(target, str) and target.strip() in ("true", "false", "1", "0"):
            return target.strip() in ("true", "1")
        if not isinstance(target, bool):
            raise ScenarioError(f"{place_prefix(where)}expected a boolean, got {target!r}")
        return target
    return to_float(target, where, f"a number to compare {decl.name} with")


def violations(
    declarations: Sequence[ParameterDeclaration],
    values: Mapping[str, ParamValue],
    file: str = "",
) -> list[str]:
    """The constraint violations of bound values (:func:`bind`), one readable string
    per parameter that meets none of its constraint groups; ``[]`` when all hold.

    As the standard says, a parameter with constraint groups is valid when at least one
    group holds, and a group holds when all its constraints hold. A constraint's value
    may be an expression over the parameters (``${-$Ego_InitSpeed_Ve0_kph}``).
    Strings and dateTimes compare as strings, booleans as booleans, the rest as numbers.

    :param file: the scenario file, named in errors and violations.
    :raises ScenarioError: a declared parameter without a value, an ordering rule on a
        string or boolean parameter, or a constraint value that fails to resolve.
    """
    out = []
    for decl in declarations:
        if not decl.constraint_groups:
            continue
        if decl.name not in values:
            raise ScenarioError(f"{_at(file, decl.line)}: no value for parameter {decl.name}")
        value = values[decl.name]
        groups = decl.constraint_groups
        targets = [[_target(decl, c, values, file) for c in group] for group in groups]
        if any(
            all(_holds(c.rule, value, t) for c, t in zip(group, ts, strict=True))
            for group, ts in zip(groups, targets, strict=True)
        ):
            continue
        shown_groups = []
        for group, ts in zip(groups, targets, strict=True):
            shown = []
            for constraint, target in zip(group, ts, strict=True):
                text = f"{constraint.rule} {constraint.value_raw}"
                if constraint.value_raw.strip().startswith("$"):
                    text += f" = {format_value(target)}"
                shown.append(text)
            shown_groups.append(f"[{' and '.join(shown)}]")
        place = f" ({_at(file, decl.line)})" if file or decl.line is not None else ""
        out.append(
            f"{decl.name} = {format_value(value)}{place} meets none of its constraint "
            f"groups: {' or '.join(shown_groups)}"
        )
    return out
