"""Scalar float math with numpy's results, without numpy's per-call dispatch.

highway-env's vehicle models call numpy on Python scalars (``np.clip`` alone costs
~4 µs through its dispatch). The functions here return the same floats bit for bit:
elementary functions come from :mod:`math` only when it agrees with numpy's scalar
ufuncs on this machine (checked once at import; numpy may use its own SIMD kernels
elsewhere), otherwise they call numpy.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = [
    "FAST_MATH_MATCHES_NUMPY",
    "asin_scalar",
    "atan_scalar",
    "clip_scalar",
    "cos_scalar",
    "not_zero_scalar",
    "power_scalar",
    "sin_scalar",
    "tan_scalar",
]


def _math_matches_numpy() -> bool:
    """Whether ``math``'s functions return numpy's scalar results bit for bit here."""
    angles = [*np.linspace(-3.5, 3.5, 301).tolist(), 1e-9, -1e-7, 1e-4, 0.3, -0.7]
    unit = np.linspace(-1.0, 1.0, 201).tolist()
    pairs: list[tuple[Callable[[Any], Any], Callable[[float], float], list[float]]] = [
        (np.sin, math.sin, angles),
        (np.cos, math.cos, angles),
        (np.tan, math.tan, angles),
        (np.arctan, math.atan, angles),
        (np.arcsin, math.asin, unit),
    ]
    for numpy_f, math_f, xs in pairs:
        if any(float(numpy_f(x)) != math_f(x) for x in xs):
            return False
    bases = np.linspace(0.0, 2.5, 101).tolist()
    return all(
        float(np.power(b, e)) == math.pow(b, e) for b in bases for e in (3.5, 3.9, 4.0, 4.37)
    )


FAST_MATH_MATCHES_NUMPY: bool = _math_matches_numpy()
"""True when the scalar functions use ``math`` (else numpy scalar calls, same results)."""


def _numpy_scalar(ufunc: np.ufunc) -> Callable[[float], float]:
    """A scalar function evaluated by a numpy ufunc (fallback when ``math`` differs)."""

    def evaluate(x: float) -> float:
        return float(ufunc(x))

    return evaluate


sin_scalar: Callable[[float], float] = (
    math.sin if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.sin)
)
"""``float(np.sin(x))`` for an angle ``x`` [rad]."""

cos_scalar: Callable[[float], float] = (
    math.cos if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.cos)
)
"""``float(np.cos(x))`` for an angle ``x`` [rad]."""

tan_scalar: Callable[[float], float] = (
    math.tan if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.tan)
)
"""``float(np.tan(x))`` for an angle ``x`` [rad]."""

atan_scalar: Callable[[float], float] = (
    math.atan if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.arctan)
)
"""``float(np.arctan(x))`` [rad]."""

asin_scalar: Callable[[float], float] = (
    math.asin if FAST_MATH_MATCHES_NUMPY else _numpy_scalar(np.arcsin)
)
"""``float(np.arcsin(x))`` [rad]."""


# np.power special-cases some exponents (e.g. 2 -> square, 0.5 -> sqrt, -1 -> reciprocal):
# those, and anything math.pow rejects, go through numpy itself.
_NUMPY_POWER_SPECIAL = frozenset({-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0})


def power_scalar(x: float, exponent: float) -> float:
    """``np.power(x, exponent)`` for scalars, bit for bit."""
    if FAST_MATH_MATCHES_NUMPY and exponent not in _NUMPY_POWER_SPECIAL:
        try:
            return math.pow(x, exponent)
        except (ValueError, OverflowError):
            pass
    return float(np.power(x, exponent))


def clip_scalar(x: float, low: float, high: float) -> float:
    """``np.clip`` for scalars with non-NaN bounds (same NaN and signed-zero results).

    ``min(max(x, low), high)`` spelled as comparisons (the builtins are several times
    slower): ``max`` keeps ``x`` unless ``low > x``, ``min`` keeps it unless ``high < x``.
    """
    if low > x:
        x = low
    if high < x:
        return high
    return x


def not_zero_scalar(x: float) -> float:
    """``highway_env.utils.not_zero(x)`` (eps = 0.01) with the same comparisons."""
    if abs(x) > 0.01:
        return x
    if x >= 0:
        return 0.01
    return -0.01
