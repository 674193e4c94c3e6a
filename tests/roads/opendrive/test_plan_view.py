"""The OpenDRIVE reader's plan view (aldm_gym.roads.opendrive.plan_view): every geometry
against its closed form or quadrature."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from aldm_gym.roads.opendrive.parse import (
    Arc,
    Geometry,
    Line,
    ParamPoly3,
    Poly3,
    Spiral,
)

from ._xodr import make_plan

# ---------------------------------------------------------------- geometry


def test_line_and_arc_closed_form() -> None:
    radius, hdg = 500.0, 0.3
    plan = make_plan(
        Geometry(0.0, 10.0, -5.0, hdg, 100.0, Line()),
        Geometry(
            100.0,
            10.0 + 100.0 * math.cos(hdg),
            -5.0 + 100.0 * math.sin(hdg),
            hdg,
            400.0,
            Arc(1.0 / radius),
        ),
    )
    s = np.linspace(0.0, 100.0, 11)
    x, y, h = plan.position(s)
    np.testing.assert_allclose(x, 10.0 + s * math.cos(hdg), atol=1e-9)
    np.testing.assert_allclose(y, -5.0 + s * math.sin(hdg), atol=1e-9)
    g = plan.geometries[1]
    centre = (g.x - radius * math.sin(hdg), g.y + radius * math.cos(hdg))
    s = np.linspace(100.0, 500.0, 801)
    x, y, h = plan.position(s)
    np.testing.assert_allclose(np.hypot(x - centre[0], y - centre[1]), radius, atol=1e-9)
    np.testing.assert_allclose(h, hdg + (s - 100.0) / radius, atol=1e-12)
    np.testing.assert_allclose(plan.curvature(s), 1.0 / radius)


@pytest.mark.parametrize(
    ("k0", "k1"), [(0.0, 1 / 500), (1 / 800, -1 / 600), (-0.002, -0.002 + 1e-15)]
)
def test_spiral_curvature_linear_and_position(k0: float, k1: float) -> None:
    length, hdg = 150.0, -0.7
    plan = make_plan(Geometry(0.0, 3.0, 4.0, hdg, length, Spiral(k0, k1)))
    s = np.linspace(0.0, length, 3001)
    h = plan.position(s)[2]
    # Heading finite differences: curvature linear in s from k0 to k1.
    mid = 0.5 * (s[1:] + s[:-1])
    np.testing.assert_allclose(np.diff(h) / np.diff(s), k0 + (k1 - k0) * mid / length, atol=1e-9)

    # Position against numerical integration of the heading.
    def head(t: float) -> float:
        return hdg + k0 * t + 0.5 * (k1 - k0) / length * t * t

    for t in (37.0, length):
        ex = 3.0 + quad(lambda v: math.cos(head(v)), 0.0, t, epsabs=1e-12)[0]
        ey = 4.0 + quad(lambda v: math.sin(head(v)), 0.0, t, epsabs=1e-12)[0]
        px, py, _ = plan.position(np.array([t]))
        assert abs(px[0] - ex) < 1e-8 and abs(py[0] - ey) < 1e-8


def test_poly3_on_its_polynomial_with_arc_length_spacing() -> None:
    shape = Poly3(0.0, 0.05, 2e-3, -4e-6)
    x0, y0, hdg, length = 5.0, 1.0, 0.4, 200.0
    plan = make_plan(Geometry(0.0, x0, y0, hdg, length, shape))
    s = np.linspace(0.0, length, 2001)
    x, y, _ = plan.position(s)
    c, sn = math.cos(hdg), math.sin(hdg)
    u = c * (x - x0) + sn * (y - y0)
    v = -sn * (x - x0) + c * (y - y0)
    np.testing.assert_allclose(v, shape.a + u * (shape.b + u * (shape.c + u * shape.d)), atol=1e-9)
    # s is arc length: chord lengths match ds (chords of 0.1 m are the arc within 1e-7).
    np.testing.assert_allclose(np.hypot(np.diff(x), np.diff(y)), np.diff(s), atol=1e-5)
    # Arc length from the start, by quadrature, at the last point.
    u_end = u[-1]
    arc = quad(
        lambda q: math.hypot(1.0, shape.b + 2 * shape.c * q + 3 * shape.d * q * q), 0.0, u_end
    )[0]
    assert abs(arc - length) < 1e-3


def test_param_poly3_normalized_equals_arc_length() -> None:
    # A curve with p in [0, length] (arcLength), and the same curve rescaled to p in [0, 1].
    bu, cu, du = 1.0, -2e-4, 1e-7
    bv, cv, dv = 0.0, 3e-3, -1e-5
    length = 120.0
    arc = ParamPoly3((0.0, bu, cu, du), (0.0, bv, cv, dv), "arcLength")
    L = length
    norm = ParamPoly3(
        (0.0, bu * L, cu * L**2, du * L**3), (0.0, bv * L, cv * L**2, dv * L**3), "normalized"
    )
    a = make_plan(Geometry(0.0, 1.0, 2.0, 0.2, length, arc))
    b = make_plan(Geometry(0.0, 1.0, 2.0, 0.2, length, norm))
    s = np.linspace(0.0, length, 777)
    for va, vb in zip(a.position(s), b.position(s), strict=True):
        np.testing.assert_allclose(va, vb, atol=1e-6)
    # The geometry ends at the curve's end, p = length.
    x, y, _ = a.position(np.array([length]))
    u_end = bu * L + cu * L**2 + du * L**3
    v_end = bv * L + cv * L**2 + dv * L**3
    c, sn = math.cos(0.2), math.sin(0.2)
    assert abs(x[0] - (1.0 + c * u_end - sn * v_end)) < 1e-9
    assert abs(y[0] - (2.0 + sn * u_end + c * v_end)) < 1e-9
    # s runs proportionally to the curve's arc length: equal chords for equal ds.
    x, y, _ = a.position(s)
    chords = np.hypot(np.diff(x), np.diff(y))
    np.testing.assert_allclose(chords, chords.mean(), rtol=1e-4)


def test_plan_view_continuous_and_bounded() -> None:
    plan = make_plan(
        Geometry(0.0, 0.0, 0.0, 0.0, 50.0, Line()),
        Geometry(50.0, 50.0, 0.0, 0.0, 30.0, Spiral(0.0, 0.01)),
    )
    x, y, _ = plan.position(np.array([50.0 - 1e-9, 50.0]))
    assert abs(x[0] - x[1]) < 1e-6 and abs(y[0] - y[1]) < 1e-6
    with pytest.raises(ValueError, match="outside the plan view"):
        plan.position(np.array([80.5]))
