"""The OpenDRIVE plan view: the reference line's position, heading and curvature at s.

Frame: OpenDRIVE's inertial frame, x east, y north, heading counter-clockwise from x
(right-handed, z up, as ISO 8855). Elevation and superelevation are ignored: every
position is the plan-view (x, y).

``line``, ``arc`` and ``spiral`` are evaluated in closed form (the clothoid through
:func:`scipy.special.fresnel`). ``poly3`` and ``paramPoly3`` are evaluated exactly at a
curve parameter that is found from s by a dense arc-length table (Gauss-Legendre
quadrature on a 0.1 m parameter grid, linear interpolation): the position error from
the table is far below 1 mm for curvatures of roads.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from aldm_gym.errors import MapError
from aldm_gym.roads.opendrive.parse import (
    Arc,
    Geometry,
    Line,
    ParamPoly3,
    Poly3,
    Spiral,
)
from aldm_gym.types import FloatArray

_TABLE_STEP = 0.1
"""Parameter-grid step of the arc-length tables of poly3/paramPoly3 [m]."""

_S_TOLERANCE = 1e-3
"""How far beyond the plan view's ends an s may lie before it is an error [m]."""

# 5-point Gauss-Legendre nodes on [0, 1] and weights (sum 1), for the arc-length tables.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(5)
_GL_X = 0.5 * (_GL_X + 1.0)
_GL_W = 0.5 * _GL_W


def _poly(c: Sequence[float], p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Cubic ``c[0] + c[1] p + c[2] p² + c[3] p³``, its first and second derivative."""
    a, b, cc, d = c
    value = a + p * (b + p * (cc + p * d))
    first = b + p * (2.0 * cc + 3.0 * d * p)
    second = 2.0 * cc + 6.0 * d * p
    return value, first, second


@dataclass(frozen=True)
class _ArcLengthTable:
    """Curve parameter p as a function of arc length along a cubic curve.

    :ivar s: (K,) arc length at the grid parameters [m], from 0, increasing.
    :ivar p: (K,) curve parameters.
    :ivar scale: geometry length / curve arc length between p[0] and p[-1].
    """

    s: FloatArray
    p: FloatArray
    scale: float

    def parameter(self, ds: FloatArray) -> FloatArray:
        """Curve parameter at arc length ``ds`` [m] along the geometry."""
        return np.interp(ds / self.scale, self.s, self.p)


def _speed_table(speed, p_end: float, n: int) -> tuple[FloatArray, FloatArray]:
    """Cumulative arc length of a curve with ``|dr/dp| = speed(p)`` on ``n`` intervals."""
    p = np.linspace(0.0, p_end, n + 1)
    h = p_end / n
    nodes = p[:-1, None] + h * _GL_X[None, :]
    seg = h * (speed(nodes) @ _GL_W)
    return p, np.concatenate(([0.0], np.cumsum(seg)))


def _poly3_table(shape: Poly3, length: float) -> _ArcLengthTable:
    coeffs = (shape.a, shape.b, shape.c, shape.d)

    def speed(u: FloatArray) -> FloatArray:
        return np.hypot(1.0, _poly(coeffs, u)[1])

    # Arc length >= u, so the end (arc length = length) lies at some u <= length.
    n = max(16, math.ceil(length / _TABLE_STEP))
    u, s = _speed_table(speed, max(length, 1e-9), n)
    return _ArcLengthTable(s=s, p=u, scale=1.0)


def _param_poly3_table(shape: ParamPoly3, length: float) -> _ArcLengthTable:
    p_end = 1.0 if shape.p_range == "normalized" else length

    def speed(p: FloatArray) -> FloatArray:
        return np.hypot(_poly(shape.u, p)[1], _poly(shape.v, p)[1])

    n = max(16, math.ceil(length / _TABLE_STEP))
    p, s = _speed_table(speed, max(p_end, 1e-9), n)
    # The geometry runs from p = 0 to p_end over its length; a file whose length is not
    # the curve's arc length is followed proportionally (its end stays the curve's end).
    scale = length / s[-1] if s[-1] > 0.0 else 1.0
    return _ArcLengthTable(s=s, p=p, scale=scale)


def _local(
    shape: object, length: float, table: _ArcLengthTable | None, ds: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Local (x, y, heading, curvature) at ``ds`` from a geometry's start, heading 0."""
    if isinstance(shape, Line) or (isinstance(shape, Arc) and shape.curvature == 0.0):
        zero = np.zeros_like(ds)
        return ds, zero, zero, zero
    if isinstance(shape, Arc):
        k = shape.curvature
        h = k * ds
        # sin/versine forms stay accurate for small k ds (no 1 - cos cancellation).
        return np.sin(h) / k, 2.0 * np.sin(0.5 * h) ** 2 / k, h, np.full_like(ds, k)
    if isinstance(shape, Spiral):
        return _spiral(shape.curv_start, shape.curv_end, length, ds)
    if isinstance(shape, Poly3):
        assert table is not None
        u = table.parameter(ds)
        v, dv, ddv = _poly((shape.a, shape.b, shape.c, shape.d), u)
        return u, v, np.arctan(dv), ddv / (1.0 + dv * dv) ** 1.5
    if isinstance(shape, ParamPoly3):
        assert table is not None
        p = table.parameter(ds)
        u, du, ddu = _poly(shape.u, p)
        v, dv, ddv = _poly(shape.v, p)
        curv = (du * ddv - dv * ddu) / np.maximum(du * du + dv * dv, 1e-300) ** 1.5
        return u, v, np.arctan2(dv, du), curv
    raise TypeError(f"unknown geometry shape {shape!r}")


def _spiral(
    k0: float, k1: float, length: float, ds: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Clothoid from heading 0 with curvature k0 + (k1 - k0) ds / length."""
    rate = (k1 - k0) / length if length > 0.0 else 0.0
    curv = k0 + rate * ds
    heading = ds * (k0 + 0.5 * rate * ds)
    # A curvature change whose heading share stays below 1e-10 rad is an arc (the
    # Fresnel form below divides by the rate).
    if abs(rate) * length * length < 2e-10:
        arc = _local(Arc(k0), length, None, ds)
        return arc[0], arc[1], heading, curv
    # Shift the clothoid parameter to the point of zero curvature, tau = ds + k0/rate:
    # heading = phi + rate tau² / 2 with phi = -k0² / (2 rate); with tau = a t,
    # a = sqrt(pi/|rate|), the integrals of cos/sin(heading) are Fresnel integrals.
    sign = 1.0 if rate > 0.0 else -1.0
    a = math.sqrt(math.pi / abs(rate))
    tau0 = k0 / rate
    phi = -0.5 * k0 * tau0
    from scipy.special import fresnel  # scipy.special: imported by the maps that need it

    s_t, c_t = fresnel((ds + tau0) / a)
    s_0, c_0 = fresnel(tau0 / a)
    dc, ds_ = c_t - c_0, s_t - s_0
    cos_phi, sin_phi = math.cos(phi), math.sin(phi)
    x = a * (cos_phi * dc - sign * sin_phi * ds_)
    y = a * (sin_phi * dc + sign * cos_phi * ds_)
    return x, y, heading, curv


class PlanView:
    """A road's reference line from its ``<planView>`` records.

    Each geometry is used from its own ``s`` up to the next one's ``s`` (the standard's
    rule); the last one up to its ``s + length``.

    :param geometries: records sorted by s (at least one).
    :param where: text naming the road in errors (e.g. ``"map.xodr, road '3'"``).
    """

    def __init__(self, geometries: Sequence[Geometry], where: str = "") -> None:
        if not geometries:
            raise MapError(f"{where}: a plan view needs at least one geometry")
        self.geometries = tuple(geometries)
        self.where = where
        self.starts = np.array([g.s for g in geometries], dtype=np.float64)
        last = geometries[-1]
        self.length = float(last.s + last.length)
        """Arc length of the reference line [m]."""
        tables: list[_ArcLengthTable | None] = []
        for g in geometries:
            if isinstance(g.shape, Poly3):
                tables.append(_poly3_table(g.shape, g.length))
            elif isinstance(g.shape, ParamPoly3):
                tables.append(_param_poly3_table(g.shape, g.length))
            else:
                tables.append(None)
        self._tables = tuple(tables)

    def _evaluate(self, s: FloatArray) -> tuple[FloatArray, ...]:
        s = np.asarray(s, dtype=np.float64)
        if s.size and (s.min() < -_S_TOLERANCE or s.max() > self.length + _S_TOLERANCE):
            raise MapError(
                f"{self.where}: s in [{s.min():.3f}, {s.max():.3f}] m is outside the plan "
                f"view [0, {self.length:.3f}] m"
            )
        s = np.clip(s, 0.0, self.length)
        index = np.clip(np.searchsorted(self.starts, s, side="right") - 1, 0, None)
        x = np.empty_like(s)
        y = np.empty_like(s)
        hdg = np.empty_like(s)
        curv = np.empty_like(s)
        for i in np.unique(index):
            g = self.geometries[i]
            mask = index == i
            lx, ly, lh, lk = _local(g.shape, g.length, self._tables[i], s[mask] - g.s)
            c, sn = math.cos(g.hdg), math.sin(g.hdg)
            x[mask] = g.x + c * lx - sn * ly
            y[mask] = g.y + sn * lx + c * ly
            hdg[mask] = g.hdg + lh
            curv[mask] = lk
        return x, y, hdg, curv

    def position(self, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Reference-line pose at arc lengths ``s`` (any shape) [m].

        :returns: ``(x [m], y [m], heading [rad])``, each shaped like ``s``. Headings are
            continuous within a geometry, not wrapped.
        :raises MapError: ``s`` is outside ``[0, length]`` (by more than 1 mm).
        """
        x, y, hdg, _ = self._evaluate(s)
        return x, y, hdg

    def curvature(self, s: FloatArray) -> FloatArray:
        """Reference-line curvature at ``s`` [1/m], > 0 turning left."""
        return self._evaluate(s)[3]
