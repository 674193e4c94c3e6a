"""Scalar float math with numpy's results, without numpy's per-call dispatch.

highway-env's vehicle models call numpy on Python scalars (``np.clip`` alone costs
~4 µs through its dispatch). The functions here return the same floats bit for bit.
An elementary function comes from :mod:`math` (the C library, libm) where numpy's
scalar ufunc gives libm's results on this machine, and from numpy otherwise: numpy
picks SIMD kernels at run time (its AVX-512 ``tan``, ``arcsin`` and ``power`` differ
from libm's in the last bit for some inputs), and its 2-vector ``np.dot`` goes to the
BLAS library, whose FMA kernels (e.g. OpenBLAS on AVX-512 CPUs) round ``a*b + c*d``
once where plain arithmetic rounds twice. Which is which is probed once at import
(:data:`NUMPY_AGREES_WITH_LIBM`).

The compiled traffic engine always uses libm's functions and plain arithmetic
(numba calls the same C library), so it equals the Python path bit for bit exactly
where every probe agrees (:data:`LIBM_MATCHES_NUMPY`); docs/env.md states the
contract on the other CPUs.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from types import MappingProxyType
from typing import Any

import numpy as np

__all__ = [
    "FAST_MATH_MATCHES_NUMPY",
    "LIBM_MATCHES_NUMPY",
    "NUMPY_AGREES_WITH_LIBM",
    "PLAIN_DOT_MATCHES_NUMPY",
    "asin_scalar",
    "atan_scalar",
    "avx2_dispatch_env",
    "clip_scalar",
    "cos_scalar",
    "not_zero_scalar",
    "numpy_simd_features",
    "power_scalar",
    "sin_scalar",
    "tan_scalar",
]

_PROBE_SEED = 8855
"""Seed of the probes' random inputs (fixed: the probe is the same on every run)."""


def _probe_inputs() -> tuple[list[float], list[float], list[tuple[float, float]]]:
    """Angles [rad], values in [-1, 1] and (base, exponent) pairs the probes evaluate:
    grids and special values, plus seeded random draws over the ranges the traffic
    uses (headings, steering and slip angles, IDM speed ratios)."""
    rng = np.random.default_rng(_PROBE_SEED)
    angles = [
        *np.linspace(-3.5, 3.5, 301).tolist(),
        *rng.uniform(-math.pi, math.pi, 1024).tolist(),
        *rng.uniform(-0.8, 0.8, 1024).tolist(),
        1e-9,
        -1e-7,
        1e-4,
        0.3,
        -0.7,
    ]
    unit = [*np.linspace(-1.0, 1.0, 201).tolist(), *rng.uniform(-1.0, 1.0, 1024).tolist()]
    bases = [*np.linspace(0.0, 2.5, 101).tolist(), *rng.uniform(0.0, 1.6, 256).tolist()]
    powers = [(b, e) for b in bases for e in (3.5, 3.9, 4.0, 4.37)]
    return angles, unit, powers


def _dot_matches_plain(pairs: int = 1024) -> bool:
    """Whether ``np.dot`` of two 2-vectors is ``a[0]*b[0] + a[1]*b[1]`` here (each
    product rounded, then the sum: no fused multiply-add in the BLAS kernel)."""
    rng = np.random.default_rng(_PROBE_SEED + 1)
    a = rng.normal(0.0, 30.0, (pairs, 2))
    b = rng.normal(0.0, 1.0, (pairs, 2))
    for (a0, a1), (b0, b1), ra, rb in zip(a.tolist(), b.tolist(), a, b, strict=True):
        if float(np.dot(ra, rb)) != a0 * b0 + a1 * b1:
            return False
    return True


def _probe() -> dict[str, bool]:
    """Per function: whether numpy's scalar result equals libm's on every probe input."""
    angles, unit, powers = _probe_inputs()
    pairs: list[tuple[str, Callable[[Any], Any], Callable[[float], float], list[float]]] = [
        ("sin", np.sin, math.sin, angles),
        ("cos", np.cos, math.cos, angles),
        ("tan", np.tan, math.tan, angles),
        ("arctan", np.arctan, math.atan, angles),
        ("arcsin", np.arcsin, math.asin, unit),
    ]
    agrees = {
        name: all(float(numpy_f(x)) == math_f(x) for x in xs) for name, numpy_f, math_f, xs in pairs
    }
    agrees["power"] = all(float(np.power(b, e)) == math.pow(b, e) for b, e in powers)
    agrees["dot"] = _dot_matches_plain()
    return agrees


NUMPY_AGREES_WITH_LIBM: MappingProxyType[str, bool] = MappingProxyType(_probe())
"""Per function (``sin``, ``cos``, ``tan``, ``arctan``, ``arcsin``, ``power``, and
``dot``: ``np.dot`` of 2-vectors against plain ``a*b + c*d``): True when numpy's
scalar result equals libm's (plain arithmetic's) on every probe input on this machine.
Probed once at import on a few thousand seeded inputs."""

LIBM_MATCHES_NUMPY: bool = all(NUMPY_AGREES_WITH_LIBM.values())
"""True when every probe agrees: the compiled traffic engine then gives the Python
path's (and highway-env's) episodes bit for bit (docs/env.md, "The traffic engine")."""

FAST_MATH_MATCHES_NUMPY: bool = LIBM_MATCHES_NUMPY
"""Alias of :data:`LIBM_MATCHES_NUMPY`, kept for code that imports this name."""

PLAIN_DOT_MATCHES_NUMPY: bool = NUMPY_AGREES_WITH_LIBM["dot"]
"""Whether ``np.dot`` of 2-vectors (and ``np.linalg.norm`` of one) is plain arithmetic
here; where it is not, the Python path leaves plain ``StraightLane`` geometry and the
IDM's desired gap to highway-env's own numpy code."""


def numpy_simd_features() -> dict[str, list[str]]:
    """numpy's SIMD dispatch on this machine: ``{"baseline": [...], "found": [...],
    "disabled": [...]}`` (the ``found`` targets numpy may dispatch to; ``disabled``:
    those turned off by ``NPY_DISABLE_CPU_FEATURES``)."""
    try:
        from numpy._core._multiarray_umath import (  # type: ignore[attr-defined]
            __cpu_baseline__,
            __cpu_dispatch__,
            __cpu_features__,
        )
    except ImportError:  # numpy 1.x
        from numpy.core._multiarray_umath import (  # type: ignore[attr-defined,no-redef]
            __cpu_baseline__,
            __cpu_dispatch__,
            __cpu_features__,
        )
    found = [name for name in __cpu_dispatch__ if __cpu_features__.get(name)]
    wanted = os.environ.get("NPY_DISABLE_CPU_FEATURES", "").replace(",", " ").split()
    disabled = [name for name in __cpu_dispatch__ if name in wanted]
    return {"baseline": list(__cpu_baseline__), "found": found, "disabled": disabled}


def avx2_dispatch_env() -> dict[str, str] | None:
    """Environment variables that make a new process take numpy's and OpenBLAS's AVX2
    paths on this CPU, or None if the CPU has no AVX-512 (they are its paths already).

    ``NPY_DISABLE_CPU_FEATURES`` names numpy's AVX-512 dispatch targets (as this numpy
    calls them: ``X86_V4 AVX512_ICL AVX512_SPR`` in numpy 2.4, ``AVX512F AVX512_SKX
    ...`` before); ``OPENBLAS_CORETYPE=Haswell`` picks OpenBLAS's AVX2 kernels (its
    AVX-512 ``ddot`` fuses multiply and add). ``make test-avx2`` runs the test suite so.
    """
    simd = numpy_simd_features()
    avx512 = [
        name for name in simd["found"] + simd["disabled"] if name == "X86_V4" or "AVX512" in name
    ]
    if not avx512:
        return None
    return {"NPY_DISABLE_CPU_FEATURES": " ".join(avx512), "OPENBLAS_CORETYPE": "Haswell"}


def _numpy_scalar(ufunc: np.ufunc) -> Callable[[float], float]:
    """A scalar function evaluated by a numpy ufunc (where ``math`` differs)."""

    def evaluate(x: float) -> float:
        return float(ufunc(x))

    evaluate.__name__ = f"numpy_{ufunc.__name__}"
    return evaluate


def _pick(name: str, math_f: Callable[[float], float], ufunc: np.ufunc) -> Callable[[float], float]:
    """``math_f`` where the probe found it equal to numpy's ``ufunc``, else the ufunc."""
    return math_f if NUMPY_AGREES_WITH_LIBM[name] else _numpy_scalar(ufunc)


sin_scalar: Callable[[float], float] = _pick("sin", math.sin, np.sin)
"""``float(np.sin(x))`` for an angle ``x`` [rad]."""

cos_scalar: Callable[[float], float] = _pick("cos", math.cos, np.cos)
"""``float(np.cos(x))`` for an angle ``x`` [rad]."""

tan_scalar: Callable[[float], float] = _pick("tan", math.tan, np.tan)
"""``float(np.tan(x))`` for an angle ``x`` [rad]."""

atan_scalar: Callable[[float], float] = _pick("arctan", math.atan, np.arctan)
"""``float(np.arctan(x))`` [rad]."""

asin_scalar: Callable[[float], float] = _pick("arcsin", math.asin, np.arcsin)
"""``float(np.arcsin(x))`` [rad]."""


# np.power special-cases some exponents (e.g. 2 -> square, 0.5 -> sqrt, -1 -> reciprocal):
# those, and anything math.pow rejects, go through numpy itself.
NUMPY_POWER_SPECIAL = frozenset({-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0})
_POWER_FROM_LIBM = NUMPY_AGREES_WITH_LIBM["power"]


def power_scalar(x: float, exponent: float) -> float:
    """``np.power(x, exponent)`` for scalars, bit for bit."""
    if _POWER_FROM_LIBM and exponent not in NUMPY_POWER_SPECIAL:
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
