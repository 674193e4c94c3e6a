"""OpenSCENARIO parameters: expressions, declarations, constraints and variations.

An attribute of an OpenSCENARIO file holds a literal, a parameter reference
``$name`` or an expression ``${...}`` (ASAM OpenSCENARIO XML 1.2, "Expressions").
:func:`resolve` tells them apart and :func:`evaluate` computes expressions with a
small recursive-descent parser (Python's ``eval`` is never used).

Expression language, loosest binding first:

==========================  =========================================================
``or``                      boolean, left-associative, short-circuit
``and``                     boolean, left-associative, short-circuit
``not``                     boolean prefix
``== != < <= > >=``         comparison, does not chain (``1 < 2 < 3`` is an error)
``+ -``                     left-associative
``* / %``                   left-associative
``**``                      power, right-associative: ``2 ** 3 ** 2 == 512.0``
``-``                       unary minus, binds tightest: ``-2 ** 2 == 4.0``
atoms                       numbers (``3``, ``2.5``, ``1e-3``), ``$name``, ``true``,
                            ``false``, ``( )``, function calls
==========================  =========================================================

Functions (the standard's list): ``round floor ceil sqrt sin cos tan asin acos atan
sign abs`` of one argument and ``max min pow`` of two.

Where the standard is silent or narrower, this module decides:

- The standard's grammar has the arithmetic operators, ``not``/``and``/``or``,
  ``true``/``false`` and the functions above; power is the function ``pow(x, y)``.
  ``**`` and the comparisons are extensions. The standard ranks unary minus above
  power, so ``-2 ** 2`` is ``(-2) ** 2`` (unlike Python); power chains to the right,
  as in mathematics. ``not`` ranks below the comparisons, so ``not $a < 1`` is
  ``not ($a < 1)``.
- Typing follows the standard's signatures: ``+ - * %``, unary minus, ``abs``,
  ``sign``, ``max`` and ``min`` give an ``int`` when every operand is an ``int`` and
  a ``float`` otherwise; ``/``, ``**``, ``pow``, ``sqrt`` and the trigonometric
  functions always give a ``float``; ``round``, ``floor`` and ``ceil`` give an
  ``int``. Integers do not overflow at 32 bits. Booleans and strings are not numbers.
- ``%`` is the remainder of truncated division, as C's ``fmod`` (the sign of the
  dividend: ``-7 % 3 == -1``); ``round`` rounds halves away from zero.
- ``==`` and ``!=`` compare two numbers, two booleans or two strings; the ordering
  comparisons need numbers.

Declarations (:class:`ParameterDeclaration`, :func:`declarations_from_xml`) are bound
to values in order (:func:`bind`), a default may use earlier parameters, and
:func:`violations` checks their constraint groups. :func:`expand_variation` reads a
``ParameterValueDistribution`` file into concrete runs and :func:`filter_runs` drops
those that break a constraint, which the ALKS variation files ask a generator to do.

Every error is a :class:`~aldm_gym.errors.ScenarioError` (an ``InputError``) whose
message starts with the place (file, line, element and attribute when known).
"""

from __future__ import annotations

import difflib
import itertools
import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from functools import lru_cache
from os import PathLike
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np
from lxml import etree

from aldm_gym.errors import InputError, ScenarioError
from aldm_gym.xmlfile import parse_xml

__all__ = [
    "MAX_RUNS",
    "PARAMETER_TYPES",
    "RULES",
    "ConcreteRun",
    "ParamValue",
    "ParameterDeclaration",
    "ValueConstraint",
    "bind",
    "declarations_from_xml",
    "evaluate",
    "expand_variation",
    "filter_runs",
    "format_value",
    "resolve",
    "resolve_number",
    "violations",
]

ParamValue: TypeAlias = bool | int | float | str
"""The value of a parameter or an expression (``dateTime`` values stay strings)."""

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

MAX_RUNS = 1_000_000
"""Most concrete runs :func:`expand_variation` produces from one file."""

_MAX_REJECTIONS = 10_000
"""Draws a truncated stochastic distribution may reject for one value."""

_INT_BOUNDS = {
    "int": (-(2**31), 2**31 - 1),
    "integer": (-(2**31), 2**31 - 1),
    "unsignedInt": (0, 2**32 - 1),
    "unsignedShort": (0, 2**16 - 1),
}

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_INTEGER = re.compile(r"[+-]?\d+")
_TOKEN = re.compile(
    r"""
    (?P<space>\s+)
    | (?P<number>(?:\d+\.\d*|\.\d+|\d+)(?:[eE][+-]?\d+)?)
    | (?P<param>\$[A-Za-z_][A-Za-z0-9_]*)
    | (?P<name>[A-Za-z_][A-Za-z0-9_]*)
    | (?P<op>\*\*|==|!=|<=|>=|[-+*/%<>(),])
    """,
    re.VERBOSE,
)
_KEYWORDS = ("and", "false", "not", "or", "true")
_COMPARISONS = ("==", "!=", "<", "<=", ">", ">=")


# ---------------------------------------------------------------------------------------
# Expressions


MAX_EXPRESSION = 2000
"""The longest expression read [characters]."""

MAX_TOKENS = 256
"""The most tokens an expression may have (the tree it builds stays shallow)."""

MAX_NESTING = 64
"""The deepest nesting of parentheses, calls and unary operators in an expression."""


class _ExprError(Exception):
    """An expression cannot be parsed or evaluated; ``pos`` indexes the text."""

    def __init__(self, problem: str, pos: int) -> None:
        super().__init__(problem)
        self.problem = problem
        self.pos = pos


@dataclass(frozen=True, slots=True)
class _Literal:
    value: ParamValue
    pos: int


@dataclass(frozen=True, slots=True)
class _Ref:
    name: str
    pos: int


@dataclass(frozen=True, slots=True)
class _Unary:
    op: str
    operand: _Node
    pos: int


@dataclass(frozen=True, slots=True)
class _Binary:
    op: str
    left: _Node
    right: _Node
    pos: int


@dataclass(frozen=True, slots=True)
class _Call:
    name: str
    args: tuple[_Node, ...]
    pos: int


_Node: TypeAlias = "_Literal | _Ref | _Unary | _Binary | _Call"


@dataclass(frozen=True, slots=True)
class _Token:
    kind: str  # "number", "param", "name", "op" or "end"
    text: str
    pos: int


def _tokens(text: str, start: int, end: int) -> list[_Token]:
    out = []
    pos = start
    while pos < end:
        m = _TOKEN.match(text, pos, end)
        if m is None:
            if text[pos] == "$":
                raise _ExprError("'$' must start a parameter name, as in $speed", pos)
            raise _ExprError(f"unexpected character {text[pos]!r}", pos)
        kind = m.lastgroup or ""
        if kind != "space":
            out.append(_Token(kind, m.group(), pos))
        pos = m.end()
    out.append(_Token("end", "", end))
    if len(out) > MAX_TOKENS + 1:
        raise _ExprError(f"{len(out) - 1} tokens, more than the {MAX_TOKENS} allowed", start)
    return out


class _Parser:
    """Recursive descent over the grammar in the module docstring."""

    def __init__(self, tokens: list[_Token]) -> None:
        self.tokens = tokens
        self.i = 0
        self.depth = 0

    def nest(self) -> None:
        """One level deeper (parentheses, a call, a unary operator, a power)."""
        self.depth += 1
        if self.depth > MAX_NESTING:
            raise _ExprError(f"nested deeper than {MAX_NESTING} levels", self.tok.pos)

    @property
    def tok(self) -> _Token:
        return self.tokens[self.i]

    def take(self) -> _Token:
        tok = self.tokens[self.i]
        self.i += 1
        return tok

    def at(self, *texts: str) -> bool:
        return self.tok.kind in ("op", "name") and self.tok.text in texts

    def fail(self, expected: str) -> _ExprError:
        found = "the end" if self.tok.kind == "end" else repr(self.tok.text)
        return _ExprError(f"expected {expected}, found {found}", self.tok.pos)

    def parse(self) -> _Node:
        if self.tok.kind == "end":
            raise _ExprError("empty expression", self.tok.pos)
        node = self.disjunction()
        if self.tok.kind != "end":
            raise self.fail("an operator or the end")
        return node

    def disjunction(self) -> _Node:
        node = self.conjunction()
        while self.at("or"):
            tok = self.take()
            node = _Binary("or", node, self.conjunction(), tok.pos)
        return node

    def conjunction(self) -> _Node:
        node = self.negation()
        while self.at("and"):
            tok = self.take()
            node = _Binary("and", node, self.negation(), tok.pos)
        return node

    def negation(self) -> _Node:
        if self.at("not"):
            tok = self.take()
            self.nest()
            node = _Unary("not", self.negation(), tok.pos)
            self.depth -= 1
            return node
        return self.comparison()

    def comparison(self) -> _Node:
        node = self.additive()
        if self.at(*_COMPARISONS):
            tok = self.take()
            node = _Binary(tok.text, node, self.additive(), tok.pos)
            if self.at(*_COMPARISONS):
                raise _ExprError("comparisons do not chain; join them with 'and'", self.tok.pos)
        return node

    def additive(self) -> _Node:
        node = self.multiplicative()
        while self.at("+", "-"):
            tok = self.take()
            node = _Binary(tok.text, node, self.multiplicative(), tok.pos)
        return node

    def multiplicative(self) -> _Node:
        node = self.power()
        while self.at("*", "/", "%"):
            tok = self.take()
            node = _Binary(tok.text, node, self.power(), tok.pos)
        return node

    def power(self) -> _Node:
        base = self.unary()
        if self.at("**"):
            tok = self.take()
            self.nest()
            node = _Binary("**", base, self.power(), tok.pos)
            self.depth -= 1
            return node
        return base

    def unary(self) -> _Node:
        if self.at("-"):
            tok = self.take()
            self.nest()
            node = _Unary("-", self.unary(), tok.pos)
            self.depth -= 1
            return node
        return self.atom()

    def atom(self) -> _Node:
        tok = self.tok
        if tok.kind == "number":
            self.take()
            if len(tok.text) > 40:
                raise _ExprError(f"a number of {len(tok.text)} characters", tok.pos)
            is_int = not any(c in tok.text for c in ".eE")
            value: int | float = int(tok.text) if is_int else float(tok.text)
            if not math.isfinite(value) or (is_int and abs(value) > 2**63):
                raise _ExprError(f"{tok.text} is out of range", tok.pos)
            return _Literal(value, tok.pos)
        if tok.kind == "param":
            self.take()
            return _Ref(tok.text[1:], tok.pos)
        if tok.kind == "name" and tok.text in ("true", "false"):
            self.take()
            return _Literal(tok.text == "true", tok.pos)
        if tok.kind == "name" and tok.text not in _KEYWORDS:
            return self.call()
        if self.at("("):
            self.take()
            self.nest()
            node = self.disjunction()
            if not self.at(")"):
                raise self.fail("')'")
            self.take()
            self.depth -= 1
            return node
        raise self.fail("a number, $parameter, function or '('")

    def call(self) -> _Node:
        tok = self.take()
        if tok.text not in _FUNCTIONS:
            known = ", ".join(sorted(_FUNCTIONS))
            raise _ExprError(
                f"unknown function {tok.text!r} (parameters start with $); functions: {known}",
                tok.pos,
            )
        if not self.at("("):
            raise self.fail(f"'(' after {tok.text}")
        self.take()
        self.nest()
        args = [self.disjunction()]
        while self.at(","):
            self.take()
            args.append(self.disjunction())
        if not self.at(")"):
            raise self.fail("',' or ')'")
        self.take()
        self.depth -= 1
        arity = _FUNCTIONS[tok.text][0]
        if len(args) != arity:
            raise _ExprError(
                f"{tok.text}() takes {arity} argument{'s' if arity > 1 else ''}, got {len(args)}",
                tok.pos,
            )
        return _Call(tok.text, tuple(args), tok.pos)


@lru_cache(maxsize=4096)
def _parse(text: str) -> _Node:
    """The syntax tree of ``${...}`` (or of a bare expression), positions into ``text``."""
    start = len(text) - len(text.lstrip())
    end = len(text.rstrip())
    if text.startswith("${", start):
        if end - start < 3 or text[end - 1] != "}":
            raise _ExprError("missing the closing '}'", end)
        start, end = start + 2, end - 1
    return _Parser(_tokens(text, start, end)).parse()


def _kind(value: object) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "double"
    return "string"


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _number(value: ParamValue, what: str, pos: int) -> int | float:
    if not _is_number(value):
        raise _ExprError(f"{what} needs numbers, got {_kind(value)} {format_value(value)!r}", pos)
    return value  # type: ignore[return-value]


def _boolean(value: ParamValue, what: str, pos: int) -> bool:
    if not isinstance(value, bool):
        raise _ExprError(f"{what} needs booleans, got {_kind(value)} {format_value(value)!r}", pos)
    return value


def _finite(value: float, what: str, pos: int) -> float:
    if not math.isfinite(value):
        raise _ExprError(f"{what} overflows (the result is not a finite number)", pos)
    return value


def _power(x: float, y: float, what: str, pos: int) -> float:
    try:
        return _finite(math.pow(x, y), what, pos)
    except OverflowError:
        raise _ExprError(f"{what} overflows (the result is not a finite number)", pos) from None
    except ValueError:
        raise _ExprError(
            f"{what} is undefined for {format_value(x)} and {format_value(y)}", pos
        ) from None


def _round_half_away(x: float) -> int:
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


def _unary_float(name: str, fn: Any, domain: Any = None) -> Any:
    def apply(args: list[int | float], pos: int) -> float:
        (x,) = args
        if domain is not None and not domain(x):
            raise _ExprError(f"{name}({format_value(x)}) is undefined (outside its domain)", pos)
        return _finite(fn(float(x)), f"{name}()", pos)

    return apply


def _sign(args: list[int | float], pos: int) -> int | float:
    (x,) = args
    s = (x > 0) - (x < 0)
    return s if isinstance(x, int) else float(s)


def _extreme(pick: Any) -> Any:
    def apply(args: list[int | float], pos: int) -> int | float:
        if all(isinstance(a, int) for a in args):
            return pick(args)
        return float(pick(args))

    return apply


_FUNCTIONS: dict[str, tuple[int, Any]] = {
    "round": (1, lambda a, p: _round_half_away(a[0])),
    "floor": (1, lambda a, p: math.floor(a[0])),
    "ceil": (1, lambda a, p: math.ceil(a[0])),
    "sqrt": (1, _unary_float("sqrt", math.sqrt, lambda x: x >= 0)),
    "sin": (1, _unary_float("sin", math.sin)),
    "cos": (1, _unary_float("cos", math.cos)),
    "tan": (1, _unary_float("tan", math.tan)),
    "asin": (1, _unary_float("asin", math.asin, lambda x: -1 <= x <= 1)),
    "acos": (1, _unary_float("acos", math.acos, lambda x: -1 <= x <= 1)),
    "atan": (1, _unary_float("atan", math.atan)),
    "sign": (1, _sign),
    "abs": (1, lambda a, p: abs(a[0])),
    "max": (2, _extreme(max)),
    "min": (2, _extreme(min)),
    "pow": (2, lambda a, p: _power(float(a[0]), float(a[1]), "pow()", p)),
}
"""Name → (number of arguments, ``apply(args, pos)``); arguments are numbers."""


def _arith(op: str, a: int | float, b: int | float, pos: int) -> int | float:
    what = f"'{op}'"
    if op == "/":
        if b == 0:
            raise _ExprError("division by zero", pos)
        return _finite(a / b, what, pos)
    if op == "%":
        if b == 0:
            raise _ExprError("modulo by zero", pos)
        if isinstance(a, int) and isinstance(b, int):
            r = abs(a) % abs(b)
            return -r if a < 0 else r
        return math.fmod(a, b)
    if op == "**":
        return _power(float(a), float(b), what, pos)
    if isinstance(a, int) and isinstance(b, int):
        return a + b if op == "+" else a - b if op == "-" else a * b
    x, y = float(a), float(b)
    return _finite(x + y if op == "+" else x - y if op == "-" else x * y, what, pos)


def _compare(op: str, a: ParamValue, b: ParamValue, pos: int) -> bool:
    if _is_number(a) and _is_number(b):
        pass
    elif op in ("==", "!=") and _kind(a) == _kind(b):
        pass
    else:
        allowed = "numbers" if op not in ("==", "!=") else "two numbers, booleans or strings"
        raise _ExprError(
            f"'{op}' compares {allowed}, got {_kind(a)} {format_value(a)!r} "
            f"and {_kind(b)} {format_value(b)!r}",
            pos,
        )
    if op == "==":
        return a == b
    if op == "!=":
        return a != b
    x, y = float(a), float(b)
    return x < y if op == "<" else x <= y if op == "<=" else x > y if op == ">" else x >= y


def _eval(node: _Node, params: Mapping[str, ParamValue]) -> ParamValue:
    if isinstance(node, _Literal):
        return node.value
    if isinstance(node, _Ref):
        if node.name not in params:
            raise _ExprError(_unknown(node.name, params), node.pos)
        value = params[node.name]
        return value.item() if isinstance(value, np.generic) else value
    if isinstance(node, _Unary):
        operand = _eval(node.operand, params)
        if node.op == "not":
            return not _boolean(operand, "'not'", node.pos)
        return -_number(operand, "unary '-'", node.pos)
    if isinstance(node, _Binary):
        left = _eval(node.left, params)
        if node.op in ("and", "or"):
            first = _boolean(left, f"'{node.op}'", node.pos)
            if first == (node.op == "or"):
                return first
            return _boolean(_eval(node.right, params), f"'{node.op}'", node.pos)
        right = _eval(node.right, params)
        if node.op in _COMPARISONS:
            return _compare(node.op, left, right, node.pos)
        what = f"'{node.op}'"
        return _arith(
            node.op, _number(left, what, node.pos), _number(right, what, node.pos), node.pos
        )
    args = [_number(_eval(a, params), f"{node.name}()", node.pos) for a in node.args]
    return _FUNCTIONS[node.name][1](args, node.pos)


def _unknown(name: str, known: Mapping[str, Any] | Sequence[str]) -> str:
    names = list(known)
    if not names:
        return f"unknown parameter ${name}; no parameters are declared here"
    close = difflib.get_close_matches(name, names, n=1)
    hint = f" (did you mean ${close[0]}?)" if close else ""
    listed = ", ".join(f"${n}" for n in names[:40])
    if len(names) > 40:
        listed += f", ... ({len(names) - 40} more)"
    return f"unknown parameter ${name}{hint}; known parameters: {listed}"


def _prefix(where: str) -> str:
    return f"{where}: " if where else ""


def evaluate(text: str, params: Mapping[str, ParamValue], where: str = "") -> ParamValue:
    """The value of an OpenSCENARIO expression ``${...}`` (a bare expression works too).

    The language, its typing and its precedence are in the module docstring, e.g.
    ``evaluate("${$v / 3.6}", {"v": 36.0}) == 10.0``,
    ``evaluate("${2 - 3 - 4}", {}) == -5``.

    :param text: the attribute's text, e.g. ``"${($a + $b) / 3.6}"``.
    :param params: the parameters' values by name (without ``$``).
    :param where: the place to name in errors, e.g. ``"file.xosc:57 <AbsoluteTargetSpeed
        value>"``; error messages start with it.
    :raises ScenarioError: a syntax error (with its column), an unknown parameter (named,
        with the known ones), an operand of the wrong type, division by zero, an
        argument outside a function's domain (``sqrt(-1)``), or a non-finite result.
    """
    if len(text) > MAX_EXPRESSION:
        raise ScenarioError(
            f"{_prefix(where)}an expression of {len(text)} characters (at most {MAX_EXPRESSION})"
        )
    try:
        return _eval(_parse(text), params)
    except _ExprError as exc:
        raise ScenarioError(
            f"{_prefix(where)}{text!r}, column {exc.pos + 1}: {exc.problem}"
        ) from None
    except (OverflowError, ValueError, ZeroDivisionError, RecursionError) as exc:
        raise ScenarioError(f"{_prefix(where)}{text!r} cannot be evaluated: {exc}") from None


def format_value(value: ParamValue) -> str:
    """A value as an OpenSCENARIO attribute writes it: ``true``/``false``, ``3``, ``2.5``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value + 0.0)  # + 0.0 turns -0.0 into 0.0
    return str(value)


def resolve(raw: str, params: Mapping[str, ParamValue], where: str = "") -> ParamValue:
    """An attribute's value: ``"${...}"`` evaluated, ``"$name"`` the parameter's value,
    anything else the literal string unchanged.

    :param raw: the attribute's text as in the file.
    :param params: the parameters' values by name (without ``$``).
    :param where: the place to name in errors (messages start with it).
    :raises ScenarioError: an expression that fails (:func:`evaluate`), an unknown
        parameter (named, with the known ones), or a text that starts with ``$`` but is
        neither a reference nor an expression.
    """
    text = raw.strip()
    if text.startswith("${"):
        return evaluate(raw, params, where)
    if text.startswith("$"):
        name = text[1:]
        if not _NAME.fullmatch(name):
            raise ScenarioError(
                f"{_prefix(where)}{raw!r} is neither a parameter reference ($name) "
                "nor an expression (${...})"
            )
        if name not in params:
            raise ScenarioError(f"{_prefix(where)}{raw!r}: {_unknown(name, params)}")
        value = params[name]
        return value.item() if isinstance(value, np.generic) else value
    return raw


def _to_float(value: ParamValue, where: str, what: str) -> float:
    """``value`` as a finite float; ``what`` names the expected thing in the message."""
    if _is_number(value):
        number = float(value)
    elif isinstance(value, str) and _NUMBER.fullmatch(value.strip()):
        number = float(value)
    else:
        shown = format_value(value) if isinstance(value, bool) else value
        raise ScenarioError(f"{_prefix(where)}expected {what}, got {_kind(value)} {shown!r}")
    if not math.isfinite(number):
        raise ScenarioError(f"{_prefix(where)}expected {what}, got {format_value(number)}")
    return number


def resolve_number(raw: str, params: Mapping[str, ParamValue], where: str = "") -> float:
    """An attribute's value (:func:`resolve`) as a finite float.

    :raises ScenarioError: as :func:`resolve`, or the value is not a number (a boolean,
        a string that does not read as a number, NaN or an infinity).
    """
    return _to_float(resolve(raw, params, where), where, "a number")


# ---------------------------------------------------------------------------------------
# Declarations and constraints


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


def _children(el: etree._Element) -> Iterator[etree._Element]:
    """The child elements, without comments and processing instructions."""
    return (child for child in el if isinstance(child.tag, str))


def _source(el: etree._Element) -> str:
    url = el.getroottree().docinfo.URL
    return str(url) if url else "<xml>"


def _fail(file: str | PathLike[str], el: etree._Element, message: str) -> InputError:
    return ScenarioError(f"{file}, <{el.tag}> at line {el.sourceline}: {message}")


def _unexpected(
    file: str | PathLike[str], el: etree._Element, allowed: Sequence[str]
) -> InputError:
    parent = el.getparent()
    inside = f" inside <{parent.tag}>" if parent is not None else ""
    listed = ", ".join(f"<{a}>" for a in allowed) or "nothing"
    return _fail(file, el, f"unknown element{inside}; allowed there: {listed}")


def _attr(file: str | PathLike[str], el: etree._Element, name: str) -> str:
    value = el.get(name)
    if value is None:
        raise _fail(file, el, f"missing attribute {name!r}")
    return str(value)


def declarations_from_xml(element: etree._Element | None) -> list[ParameterDeclaration]:
    """The declarations of an lxml ``<ParameterDeclarations>`` element, in order.

    :param element: the element, or ``None`` (a file without declarations) for ``[]``.
    :raises ScenarioError: a missing attribute, an unknown parameter type or rule, an
        invalid name, an empty ``<ConstraintGroup>`` or an unknown element (naming the
        file, the element and its line).
    """
    if element is None:
        return []
    file = _source(element)
    if element.tag != "ParameterDeclarations":
        raise _fail(file, element, "expected <ParameterDeclarations>")
    out = []
    for child in _children(element):
        if child.tag != "ParameterDeclaration":
            raise _unexpected(file, child, ["ParameterDeclaration"])
        name = _attr(file, child, "name")
        if not _NAME.fullmatch(name):
            raise _fail(file, child, f"invalid parameter name {name!r} (letters, digits, _)")
        ptype = _attr(file, child, "parameterType")
        if ptype not in PARAMETER_TYPES:
            raise _fail(file, child, f"unknown parameterType {ptype!r}; one of {PARAMETER_TYPES}")
        groups = []
        for group in _children(child):
            if group.tag != "ConstraintGroup":
                raise _unexpected(file, group, ["ConstraintGroup"])
            constraints = []
            for item in _children(group):
                if item.tag != "ValueConstraint":
                    raise _unexpected(file, item, ["ValueConstraint"])
                rule = _attr(file, item, "rule")
                if rule not in RULES:
                    raise _fail(file, item, f"unknown rule {rule!r}; one of {RULES}")
                constraints.append(
                    ValueConstraint(rule, _attr(file, item, "value"), item.sourceline)
                )
            if not constraints:
                raise _fail(file, group, "a ConstraintGroup needs at least one ValueConstraint")
            groups.append(tuple(constraints))
        out.append(
            ParameterDeclaration(
                name, ptype, _attr(file, child, "value"), tuple(groups), child.sourceline
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
            f"{_prefix(where)}parameter {decl.name} is of type {ptype}: {shown!r} is not {expected}"
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
        if isinstance(value, str) and not _NUMBER.fullmatch(value.strip()):
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
        if _INTEGER.fullmatch(text):
            integer = int(text)
        elif _NUMBER.fullmatch(text) and float(text).is_integer():
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
            f"{_prefix(where)}rule {constraint.rule} needs a numeric parameter, but "
            f"{decl.name} is of type {ptype}: only equalTo and notEqualTo apply"
        )
    target = resolve(constraint.value_raw, values, where)
    if ptype in ("string", "dateTime"):
        return format_value(target)
    if ptype == "boolean":
        if isinstance(target, str) and target.strip() in ("true", "false", "1", "0"):
            return target.strip() in ("true", "1")
        if not isinstance(target, bool):
            raise ScenarioError(f"{_prefix(where)}expected a boolean, got {target!r}")
        return target
    return _to_float(target, where, f"a number to compare {decl.name} with")


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


# ---------------------------------------------------------------------------------------
# Parameter variation


@dataclass(frozen=True)
class ConcreteRun:
    """One concrete run of a parameter variation.

    :ivar index: its position in :func:`expand_variation`'s list, from 0.
    :ivar parameters: the assigned values as strings, to pass to :func:`bind` as
        overrides; unassigned parameters keep their defaults.
    """

    index: int
    parameters: dict[str, str]


def _read_xml(path: Path) -> etree._Element:
    return parse_xml(path).getroot()


class _Reader:
    """Reads a variation file's elements with errors naming file, element and line."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, el: etree._Element, message: str) -> InputError:
        return _fail(self.path, el, message)

    def unexpected(self, el: etree._Element, allowed: Sequence[str]) -> InputError:
        return _unexpected(self.path, el, allowed)

    def attr(self, el: etree._Element, name: str) -> str:
        return _attr(self.path, el, name)

    def number(self, el: etree._Element, name: str) -> float:
        where = f"{self.path}, <{el.tag}> at line {el.sourceline}, attribute {name}"
        return resolve_number(self.attr(el, name), {}, where)

    def one(self, el: etree._Element, allowed: Sequence[str]) -> etree._Element:
        """The single child element, one of ``allowed``."""
        found = None
        for child in _children(el):
            if child.tag not in allowed:
                raise self.unexpected(child, allowed)
            if found is not None:
                raise self.fail(child, f"<{el.tag}> holds one of {', '.join(allowed)}, not two")
            found = child
        if found is None:
            raise self.fail(el, f"needs one child: {' or '.join(f'<{a}>' for a in allowed)}")
        return found

    def many(self, el: etree._Element, tag: str) -> list[etree._Element]:
        """The child elements, all ``tag``, at least one."""
        out = []
        for child in _children(el):
            if child.tag != tag:
                raise self.unexpected(child, [tag])
            out.append(child)
        if not out:
            raise self.fail(el, f"needs at least one <{tag}>")
        return out

    def range(self, el: etree._Element) -> tuple[float, float]:
        lower, upper = self.number(el, "lowerLimit"), self.number(el, "upperLimit")
        if upper < lower:
            raise self.fail(el, f"upperLimit {upper} is below lowerLimit {lower}")
        return lower, upper


def _grid_value(x: float) -> str:
    """A range value rounded to 12 significant digits, so that float drift of
    ``lower + i * step`` does not show (``0.30000000000000004`` → ``0.3``)."""
    return format_value(float(f"{x:.12g}"))


def _range_values(r: _Reader, el: etree._Element) -> list[str]:
    """``<DistributionRange stepWidth><Range lowerLimit upperLimit/>``: the lower
    limit and its steps, with the upper limit when it lies on the grid."""
    step = r.number(el, "stepWidth")
    if step <= 0:
        raise r.fail(el, f"stepWidth must be > 0, got {format_value(step)}")
    lower, upper = r.range(r.one(el, ["Range"]))
    span = (upper - lower) / step
    n = math.floor(span + 1e-9 * max(1.0, span))
    if n + 1 > MAX_RUNS:
        raise r.fail(el, f"{n + 1} values, more than MAX_RUNS = {MAX_RUNS}")
    return [_grid_value(lower + i * step) for i in range(n + 1)]


def _single(r: _Reader, el: etree._Element) -> list[str]:
    kind = r.one(el, ["DistributionSet", "DistributionRange", "UserDefinedDistribution"])
    if kind.tag == "DistributionSet":
        return [r.attr(item, "value") for item in r.many(kind, "Element")]
    if kind.tag == "DistributionRange":
        return _range_values(r, kind)
    raise r.fail(kind, "user-defined distributions are not supported")


def _value_sets(r: _Reader, el: etree._Element) -> list[dict[str, str]]:
    """``DeterministicMultiParameterDistribution/ValueSetDistribution``: one
    assignment per ``ParameterValueSet``."""
    out = []
    for value_set in r.many(r.one(el, ["ValueSetDistribution"]), "ParameterValueSet"):
        assignment: dict[str, str] = {}
        for item in r.many(value_set, "ParameterAssignment"):
            name = r.attr(item, "parameterRef")
            if name in assignment:
                raise r.fail(item, f"parameter {name} is assigned twice in one set")
            assignment[name] = r.attr(item, "value")
        out.append(assignment)
    return out


def _deterministic(r: _Reader, el: etree._Element) -> list[dict[str, str]]:
    """The cross product of the distributions in document order, the last varying
    fastest (ASAM OpenSCENARIO 1.2: deterministic distributions combine as all
    combinations); a parameter may be varied by one distribution only."""
    factors: list[list[dict[str, str]]] = []
    owner: dict[str, int | None] = {}
    for child in _children(el):
        if child.tag == "DeterministicSingleParameterDistribution":
            name = r.attr(child, "parameterName")
            factor = [{name: value} for value in _single(r, child)]
        elif child.tag == "DeterministicMultiParameterDistribution":
            factor = _value_sets(r, child)
        elif child.tag == "ParameterValueSet":
            raise r.fail(
                child,
                "a ParameterValueSet belongs in <DeterministicMultiParameterDistribution>"
                "<ValueSetDistribution>",
            )
        else:
            raise r.unexpected(
                child,
                [
                    "DeterministicSingleParameterDistribution",
                    "DeterministicMultiParameterDistribution",
                ],
            )
        for name in dict.fromkeys(n for assignment in factor for n in assignment):
            if name in owner:
                raise r.fail(
                    child,
                    f"parameter {name} is already varied by the distribution at line {owner[name]}",
                )
            owner[name] = child.sourceline
        factors.append(factor)
    total = math.prod(len(f) for f in factors)
    if total > MAX_RUNS:
        raise r.fail(el, f"{total} combinations, more than MAX_RUNS = {MAX_RUNS}")
    return [
        {name: value for part in combination for name, value in part.items()}
        for combination in itertools.product(*factors)
    ]


@dataclass(frozen=True)
class _Stochastic:
    """One ``StochasticDistribution``: how to draw its value.

    :ivar kind: the distribution's element name.
    :ivar where: file, element and line, for errors.
    :ivar params: ``(lower, upper)`` of a uniform, ``(expectedValue, variance)`` of a
        normal, ``(expectedValue,)`` of a Poisson distribution.
    :ivar bounds: the truncating ``Range`` (inclusive), or ``None``.
    :ivar values: the values of a probability set.
    :ivar weights: the probabilities of a set's values or of a histogram's bins.
    :ivar bins: a histogram's bins, ``(lower, upper)`` each.
    """

    kind: str
    where: str
    params: tuple[float, ...] = ()
    bounds: tuple[float, float] | None = None
    values: tuple[str, ...] = ()
    weights: tuple[float, ...] = ()
    bins: tuple[tuple[float, float], ...] = ()

    def draw(self, rng: np.random.Generator) -> str:
        """One value as a string."""
        if self.kind == "ProbabilityDistributionSet":
            return self.values[int(rng.choice(len(self.values), p=self.weights))]
        if self.kind == "Histogram":
            lo, hi = self.bins[int(rng.choice(len(self.bins), p=self.weights))]
            return format_value(float(rng.uniform(lo, hi)))
        if self.kind == "UniformDistribution":
            lo, hi = self.params
            return format_value(float(rng.uniform(lo, hi)))
        lo, hi = self.bounds or (-math.inf, math.inf)
        for _ in range(_MAX_REJECTIONS):
            if self.kind == "NormalDistribution":
                mean, variance = self.params
                x: float = float(rng.normal(mean, math.sqrt(variance)))
            else:
                x = int(rng.poisson(self.params[0]))
            if lo <= x <= hi:
                return format_value(x)
        raise ScenarioError(
            f"{self.where}: {_MAX_REJECTIONS} draws fell outside the Range "
            f"[{format_value(lo)}, {format_value(hi)}]"
        )


def _weights(r: _Reader, items: list[etree._Element], el: etree._Element) -> tuple[float, ...]:
    weights = [r.number(item, "weight") for item in items]
    if any(w < 0 for w in weights) or sum(weights) <= 0:
        raise r.fail(el, "weights must be >= 0 with a positive sum")
    total = sum(weights)
    return tuple(w / total for w in weights)


def _stochastic_distribution(r: _Reader, el: etree._Element) -> _Stochastic:
    kind = r.one(
        el,
        [
            "ProbabilityDistributionSet",
            "NormalDistribution",
            "LogNormalDistribution",
            "UniformDistribution",
            "PoissonDistribution",
            "Histogram",
            "UserDefinedDistribution",
        ],
    )
    where = f"{r.path}, <{kind.tag}> at line {kind.sourceline}"
    tag = str(kind.tag)
    if tag == "ProbabilityDistributionSet":
        items = r.many(kind, "Element")
        values = tuple(r.attr(item, "value") for item in items)
        return _Stochastic(tag, where, values=values, weights=_weights(r, items, kind))
    if tag == "Histogram":
        bins = r.many(kind, "Bin")
        ranges = tuple(r.range(r.one(b, ["Range"])) for b in bins)
        return _Stochastic(tag, where, bins=ranges, weights=_weights(r, bins, kind))
    if tag == "UniformDistribution":
        return _Stochastic(tag, where, params=r.range(r.one(kind, ["Range"])))
    if tag in ("NormalDistribution", "PoissonDistribution"):
        bounds = None
        for child in _children(kind):
            if child.tag != "Range":
                raise r.unexpected(child, ["Range"])
            if bounds is not None:
                raise r.fail(child, f"<{tag}> holds at most one <Range>")
            bounds = r.range(child)
        expected = r.number(kind, "expectedValue")
        if tag == "PoissonDistribution":
            if expected < 0:
                raise r.fail(kind, f"expectedValue must be >= 0, got {format_value(expected)}")
            return _Stochastic(tag, where, params=(expected,), bounds=bounds)
        variance = r.number(kind, "variance")
        if variance < 0:
            raise r.fail(kind, f"variance must be >= 0, got {format_value(variance)}")
        return _Stochastic(tag, where, params=(expected, variance), bounds=bounds)
    raise r.fail(kind, f"<{tag}> is not supported")


def _stochastic(r: _Reader, el: etree._Element) -> list[dict[str, str]]:
    """``numberOfTestRuns`` runs, each drawing every distribution in document order
    from one ``numpy.random.default_rng(randomSeed)`` (seed 0 when absent)."""
    count = r.number(el, "numberOfTestRuns")
    if count < 0 or not count.is_integer():
        raise r.fail(el, f"numberOfTestRuns must be a whole number >= 0, got {format_value(count)}")
    if count > MAX_RUNS:
        raise r.fail(el, f"numberOfTestRuns {int(count)} is more than MAX_RUNS = {MAX_RUNS}")
    seed = r.number(el, "randomSeed") if el.get("randomSeed") is not None else 0.0
    if seed < 0 or not seed.is_integer():
        raise r.fail(el, f"randomSeed must be a whole number >= 0, got {format_value(seed)}")
    distributions: dict[str, _Stochastic] = {}
    for child in r.many(el, "StochasticDistribution"):
        name = r.attr(child, "parameterName")
        if name in distributions:
            raise r.fail(child, f"parameter {name} has two distributions")
        distributions[name] = _stochastic_distribution(r, child)
    rng = np.random.default_rng(int(seed))
    return [
        {name: dist.draw(rng) for name, dist in distributions.items()} for _ in range(int(count))
    ]


def expand_variation(path: str | PathLike[str]) -> tuple[Path, list[ConcreteRun]]:
    """The scenario file and the concrete runs of a ``<ParameterValueDistribution>`` file.

    ``<Deterministic>``: the cross product of its distributions in document order, the
    last varying fastest. A ``DeterministicSingleParameterDistribution`` gives its
    ``DistributionSet`` elements, or its ``DistributionRange``'s lower limit and steps
    up to the upper limit (inclusive when on the grid; values rounded to 12
    significant digits). A ``DeterministicMultiParameterDistribution`` gives its
    ``ParameterValueSet`` elements, each assigning several parameters together; it
    is one factor of the product, as in the ALKS files, where a
    (catalog, model) pair or an (ego speed, headway) pair varies together against
    the single-parameter distributions.

    ``<Stochastic numberOfTestRuns randomSeed>``: each run draws every distribution
    once, in document order, from ``numpy.random.default_rng(randomSeed)`` (seed 0 when
    absent), so a file expands the same way every time. Normal (``variance``, not the
    standard deviation) and Poisson distributions are truncated to their ``Range`` by
    redrawing; a histogram picks a bin by weight and a uniform value in it. The
    standard makes a file either deterministic or stochastic, never both.

    :param path: the variation file.
    :returns: the scenario file (``ScenarioFile/@filepath`` relative to the variation
        file's folder) and the runs.
    :raises ScenarioError: a missing or malformed file, or an unknown, missing or
        misplaced element or attribute (naming the file, the element and its line),
        ``LogNormalDistribution`` and ``UserDefinedDistribution`` (not supported), a
        parameter varied twice, or more than :data:`MAX_RUNS` runs.
    """
    path = Path(path)
    root = _read_xml(path)
    r = _Reader(path)
    if root.tag != "OpenSCENARIO":
        raise r.fail(root, "the root element is not <OpenSCENARIO>")
    distribution = None
    for child in _children(root):
        if child.tag == "ParameterValueDistribution" and distribution is None:
            distribution = child
        elif child.tag != "FileHeader":
            raise r.unexpected(child, ["FileHeader", "ParameterValueDistribution"])
    if distribution is None:
        raise ScenarioError(f"{path}: no <ParameterValueDistribution>: not a variation file")
    scenario = None
    definition = None
    for child in _children(distribution):
        if child.tag == "ScenarioFile" and scenario is None:
            scenario = path.parent / r.attr(child, "filepath")
        elif child.tag in ("Deterministic", "Stochastic"):
            if definition is not None:
                raise r.fail(
                    child,
                    "a ParameterValueDistribution holds either <Deterministic> or "
                    "<Stochastic>, not both",
                )
            definition = child
        else:
            raise r.unexpected(child, ["ScenarioFile", "Deterministic", "Stochastic"])
    if scenario is None:
        raise r.fail(distribution, "missing <ScenarioFile>")
    if definition is None:
        raise r.fail(distribution, "needs <Deterministic> or <Stochastic>")
    if definition.tag == "Deterministic":
        assignments = _deterministic(r, definition)
    else:
        assignments = _stochastic(r, definition)
    return scenario, [ConcreteRun(i, a) for i, a in enumerate(assignments)]


def filter_runs(
    runs: Sequence[ConcreteRun], declarations: Sequence[ParameterDeclaration], file: str
) -> tuple[list[ConcreteRun], list[tuple[ConcreteRun, list[str]]]]:
    """The runs whose bound values meet every constraint, and the others with their
    :func:`violations`.

    :param runs: from :func:`expand_variation`.
    :param declarations: the scenario file's declarations.
    :param file: the scenario file, named in errors and reasons.
    :raises ScenarioError: a run assigns an undeclared parameter or a value that does not
        convert to its type (the message starts with the run's index and values).
    """
    kept: list[ConcreteRun] = []
    dropped: list[tuple[ConcreteRun, list[str]]] = []
    for run in runs:
        try:
            reasons = violations(declarations, bind(declarations, run.parameters, file), file)
        except InputError as exc:
            assigned = ", ".join(f"{k}={v}" for k, v in run.parameters.items())
            raise ScenarioError(f"run {run.index} ({assigned}): {exc}") from None
        if reasons:
            dropped.append((run, reasons))
        else:
            kept.append(run)
    return kept, dropped
