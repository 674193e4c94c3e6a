"""OpenSCENARIO parameter variations: a ``ParameterValueDistribution`` file into
concrete runs.

:func:`expand_variation` reads a variation file (deterministic and stochastic
distributions, ASAM OpenSCENARIO XML 1.2) into :class:`ConcreteRun`\\ s and
:func:`filter_runs` drops those that break a constraint of the scenario's declarations
(:mod:`aldm_gym.scenario.declarations`), which the ALKS variation files ask a generator
to do. Every error is a :class:`~aldm_gym.errors.ScenarioError` naming the file, line
and element.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np
from lxml import etree

from aldm_gym.errors import InputError, ScenarioError
from aldm_gym.scenario.declarations import ParameterDeclaration, bind, violations
from aldm_gym.scenario.expressions import format_value, parameter_name, resolve_number
from aldm_gym.xmlfile import ElementReader, children, parse_xml

__all__ = ["MAX_RUNS", "ConcreteRun", "expand_variation", "filter_runs"]

MAX_RUNS = 1_000_000
"""Most concrete runs :func:`expand_variation` produces from one file."""

_MAX_REJECTIONS = 10_000
"""Draws a truncated stochastic distribution may reject for one value."""


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


class _Reader(ElementReader):
    """Reads a variation file's elements: numbers and ranges besides the shared ones."""

    def number(self, el: etree._Element, name: str) -> float:
        """A numeric attribute (a literal or an expression without parameters)."""
        return resolve_number(self.required(el, name), {}, self.where(el, name))

    def range(self, el: etree._Element) -> tuple[float, float]:
        """``(lowerLimit, upperLimit)`` of a ``<Range>``."""
        lower, upper = self.number(el, "lowerLimit"), self.number(el, "upperLimit")
        if upper < lower:
            raise self.error(el, f"upperLimit {upper} is below lowerLimit {lower}")
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
        raise r.error(el, f"stepWidth must be > 0, got {format_value(step)}")
    lower, upper = r.range(r.one(el, ["Range"]))
    span = (upper - lower) / step
    n = math.floor(span + 1e-9 * max(1.0, span))
    if n + 1 > MAX_RUNS:
        raise r.error(el, f"{n + 1} values, more than MAX_RUNS = {MAX_RUNS}")
    return [_grid_value(lower + i * step) for i in range(n + 1)]


def _single(r: _Reader, el: etree._Element) -> list[str]:
    kind = r.one(el, ["DistributionSet", "DistributionRange", "UserDefinedDistribution"])
    if kind.tag == "DistributionSet":
        return [r.required(item, "value") for item in r.many(kind, "Element")]
    if kind.tag == "DistributionRange":
        return _range_values(r, kind)
    raise r.error(kind, "user-defined distributions are not supported")


def _value_sets(r: _Reader, el: etree._Element) -> list[dict[str, str]]:
    """``DeterministicMultiParameterDistribution/ValueSetDistribution``: one
    assignment per ``ParameterValueSet``."""
    out = []
    for value_set in r.many(r.one(el, ["ValueSetDistribution"]), "ParameterValueSet"):
        assignment: dict[str, str] = {}
        for item in r.many(value_set, "ParameterAssignment"):
            name = parameter_name(r.required(item, "parameterRef"))
            if name in assignment:
                raise r.error(item, f"parameter {name} is assigned twice in one set")
            assignment[name] = r.required(item, "value")
        out.append(assignment)
    return out


def _deterministic(r: _Reader, el: etree._Element) -> list[dict[str, str]]:
    """The cross product of the distributions in document order, the last varying
    fastest (ASAM OpenSCENARIO 1.2: deterministic distributions combine as all
    combinations); a parameter may be varied by one distribution only."""
    factors: list[list[dict[str, str]]] = []
    owner: dict[str, int | None] = {}
    for child in children(el):
        if child.tag == "DeterministicSingleParameterDistribution":
            name = parameter_name(r.required(child, "parameterName"))
            factor = [{name: value} for value in _single(r, child)]
        elif child.tag == "DeterministicMultiParameterDistribution":
            factor = _value_sets(r, child)
        elif child.tag == "ParameterValueSet":
            raise r.error(
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
                raise r.error(
                    child,
                    f"parameter {name} is already varied by the distribution at line {owner[name]}",
                )
            owner[name] = child.sourceline
        factors.append(factor)
    total = math.prod(len(f) for f in factors)
    if total > MAX_RUNS:
        raise r.error(el, f"{total} combinations, more than MAX_RUNS = {MAX_RUNS}")
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
        raise r.error(el, "weights must be >= 0 with a positive sum")
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
    where = r.where(kind)
    tag = str(kind.tag)
    if tag == "ProbabilityDistributionSet":
        items = r.many(kind, "Element")
        values = tuple(r.required(item, "value") for item in items)
        return _Stochastic(tag, where, values=values, weights=_weights(r, items, kind))
    if tag == "Histogram":
        bins = r.many(kind, "Bin")
        ranges = tuple(r.range(r.one(b, ["Range"])) for b in bins)
        return _Stochastic(tag, where, bins=ranges, weights=_weights(r, bins, kind))
    if tag == "UniformDistribution":
        return _Stochastic(tag, where, params=r.range(r.one(kind, ["Range"])))
    if tag in ("NormalDistribution", "PoissonDistribution"):
        bounds = None
        for child in children(kind):
            if child.tag != "Range":
                raise r.unexpected(child, ["Range"])
            if bounds is not None:
                raise r.error(child, f"<{tag}> holds at most one <Range>")
            bounds = r.range(child)
        expected = r.number(kind, "expectedValue")
        if tag == "PoissonDistribution":
            if expected < 0:
                raise r.error(kind, f"expectedValue must be >= 0, got {format_value(expected)}")
            return _Stochastic(tag, where, params=(expected,), bounds=bounds)
        variance = r.number(kind, "variance")
        if variance < 0:
            raise r.error(kind, f"variance must be >= 0, got {format_value(variance)}")
        return _Stochastic(tag, where, params=(expected, variance), bounds=bounds)
    raise r.error(kind, f"<{tag}> is not supported")


def _stochastic(r: _Reader, el: etree._Element) -> list[dict[str, str]]:
    """``numberOfTestRuns`` runs, each drawing every distribution in document order
    from one ``numpy.random.default_rng(randomSeed)`` (seed 0 when absent)."""
    count = r.number(el, "numberOfTestRuns")
    if count < 0 or not count.is_integer():
        raise r.error(
            el, f"numberOfTestRuns must be a whole number >= 0, got {format_value(count)}"
        )
    if count > MAX_RUNS:
        raise r.error(el, f"numberOfTestRuns {int(count)} is more than MAX_RUNS = {MAX_RUNS}")
    seed = r.number(el, "randomSeed") if el.get("randomSeed") is not None else 0.0
    if seed < 0 or not seed.is_integer():
        raise r.error(el, f"randomSeed must be a whole number >= 0, got {format_value(seed)}")
    distributions: dict[str, _Stochastic] = {}
    for child in r.many(el, "StochasticDistribution"):
        name = parameter_name(r.required(child, "parameterName"))
        if name in distributions:
            raise r.error(child, f"parameter {name} has two distributions")
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
        raise r.error(root, "the root element is not <OpenSCENARIO>")
    distribution = None
    for child in children(root):
        if child.tag == "ParameterValueDistribution" and distribution is None:
            distribution = child
        elif child.tag != "FileHeader":
            raise r.unexpected(child, ["FileHeader", "ParameterValueDistribution"])
    if distribution is None:
        raise ScenarioError(f"{path}: no <ParameterValueDistribution>: not a variation file")
    scenario = None
    definition = None
    for child in children(distribution):
        if child.tag == "ScenarioFile" and scenario is None:
            scenario = path.parent / r.required(child, "filepath")
        elif child.tag in ("Deterministic", "Stochastic"):
            if definition is not None:
                raise r.error(
                    child,
                    "a ParameterValueDistribution holds either <Deterministic> or "
                    "<Stochastic>, not both",
                )
            definition = child
        else:
            raise r.unexpected(child, ["ScenarioFile", "Deterministic", "Stochastic"])
    if scenario is None:
        raise r.error(distribution, "missing <ScenarioFile>")
    if definition is None:
        raise r.error(distribution, "needs <Deterministic> or <Stochastic>")
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
