"""OpenSCENARIO expressions: ``$name`` references and ``${...}`` expressions.

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

Declarations and their constraints are :mod:`aldm_gym.scenario.declarations`,
parameter variations :mod:`aldm_gym.scenario.distributions`. Every error is a
:class:`~aldm_gym.errors.ScenarioError` (an ``InputError``) whose message starts with
the place (file, line, element and attribute when known).
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, TypeAlias

import numpy as np

from aldm_gym.errors import ScenarioError

__all__ = [
    "INTEGER_PATTERN",
    "NAME_PATTERN",
    "NUMBER_PATTERN",
    "ParamValue",
    "evaluate",
    "format_value",
    "parameter_name",
    "place_prefix",
    "resolve",
    "resolve_number",
    "to_float",
]

ParamValue: TypeAlias = bool | int | float | str
"""The value of a parameter or an expression (``dateTime`` values stay strings)."""

NAME_PATTERN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""A parameter's name (``fullmatch``)."""


def parameter_name(raw: str) -> str:
    """A parameter's name as a file writes it where a name (not a value) is meant: a
    declaration's ``name``, a ``parameterRef``, a distribution's ``parameterName``.
    OpenSCENARIO 1.0's own examples (and scenariogeneration's output) write these with
    the ``$`` of a reference (``name="$owner"``), as esmini accepts; the name is the
    rest. Anything else is returned as it is (and checked where it is used)."""
    if raw.startswith("$") and NAME_PATTERN.fullmatch(raw[1:]):
        return raw[1:]
    return raw


NUMBER_PATTERN = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
"""A decimal number literal (``fullmatch``)."""
INTEGER_PATTERN = re.compile(r"[+-]?\d+")
"""An integer literal (``fullmatch``)."""
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


def place_prefix(where: str) -> str:
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
            f"{place_prefix(where)}an expression of {len(text)} characters "
            f"(at most {MAX_EXPRESSION})"
        )
    try:
        return _eval(_parse(text), params)
    except _ExprError as exc:
        raise ScenarioError(
            f"{place_prefix(where)}{text!r}, column {exc.pos + 1}: {exc.problem}"
        ) from None
    except (OverflowError, ValueError, ZeroDivisionError, RecursionError) as exc:
        raise ScenarioError(f"{place_prefix(where)}{text!r} cannot be evaluated: {exc}") from None


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
        if not NAME_PATTERN.fullmatch(name):
            raise ScenarioError(
                f"{place_prefix(where)}{raw!r} is neither a parameter reference ($name) "
                "nor an expression (${...})"
            )
        if name not in params:
            raise ScenarioError(f"{place_prefix(where)}{raw!r}: {_unknown(name, params)}")
        value = params[name]
        return value.item() if isinstance(value, np.generic) else value
    return raw


def to_float(value: ParamValue, where: str, what: str) -> float:
    """``value`` as a finite float; ``what`` names the expected thing in the message."""
    if _is_number(value):
        number = float(value)
    elif isinstance(value, str) and NUMBER_PATTERN.fullmatch(value.strip()):
        number = float(value)
    else:
        shown = format_value(value) if isinstance(value, bool) else value
        raise ScenarioError(f"{place_prefix(where)}expected {what}, got {_kind(value)} {shown!r}")
    if not math.isfinite(number):
        raise ScenarioError(f"{place_prefix(where)}expected {what}, got {format_value(number)}")
    return number


def resolve_number(raw: str, params: Mapping[str, ParamValue], where: str = "") -> float:
    """An attribute's value (:func:`resolve`) as a finite float.

    :raises ScenarioError: as :func:`resolve`, or the value is not a number (a boolean,
        a string that does not read as a number, NaN or an infinity).
    """
    return to_float(resolve(raw, params, where), where, "a number")
