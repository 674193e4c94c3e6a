"""Markings as polylines with explicit paint: the road model of maps, seen by the sensor."""

from __future__ import annotations

import numpy as np
import pytest

from aldm_gym.roads import HighwayRoad
from aldm_gym.roads.polyline import (
    MarkingCurve,
    PolylineMarkings,
    PolylineRoad,
    _near_markings,
    _near_markings_py,
    _sample_polylines,
    _sample_polylines_py,
    arc_length,
)
from aldm_gym.sensor import LineSensor, detect_lanes, naive_detect


def _as_polylines(road: HighwayRoad, step: float = 1.0) -> list[MarkingCurve]:
    """The highway's markings as polylines with the dash intervals of their pattern."""
    s = np.arange(0.0, road.length, step)
    curves = []
    for j, mk in enumerate(road.markings):
        xy = road.marking_position(j, s)
        u = arc_length(xy)
        if mk.broken:
            starts = mk.phase + mk.period * np.arange(int(u[-1] // mk.period) + 1)
            painted = np.column_stack([starts, np.minimum(starts + mk.dash_length, u[-1])])
            painted = painted[painted[:, 1] > painted[:, 0]]
        else:
            painted = np.array([[0.0, u[-1]]])
        curves.append(MarkingCurve(xy, painted, int(mk.type), mk.colour, mk.width, mk.height))
    return curves


@pytest.fixture(scope="module")
def pair() -> tuple[HighwayRoad, PolylineRoad]:
    road = HighwayRoad({"seed": 4, "length": 2500.0, "min_radius": 500.0})
    return road, PolylineRoad(_as_polylines(road, 1.0), "per_dash", road.lane_width)


def test_polylines_cross_the_sensor_grid_where_the_exact_road_does(pair) -> None:
    road, poly = pair
    xs = LineSensor().config.x_grid
    for s in (300.0, 900.0, 1700.0):
        x, y = road.reference.position(s, road.lane_offset(1))
        h = float(road.reference.heading_at(s))
        want_y, want_u = road.sample_markings(np.array([x, y]), h, xs)
        got_y, got_u = poly.sample_markings(np.array([x, y]), h, xs)
        both = ~np.isnan(want_y) & ~np.isnan(got_y)
        assert both.sum() > 0.9 * (~np.isnan(want_y)).sum()
        # 1 m chords on R >= 500 m curves: sagitta < 0.3 mm
        assert np.max(np.abs(got_y[both] - want_y[both])) < 2e-3
        assert np.max(np.abs(got_u[both] - want_u[both])) < 0.05


def test_explicit_dashes_give_the_same_objects_as_the_periodic_pattern(pair) -> None:
    road, poly = pair
    sensor = LineSensor()
    for model in ("per_dash", "editor"):
        r, p = road.with_marking_model(model), poly.with_marking_model(model)
        for s in (400.0, 1000.0, 2000.0):
            x, y = road.reference.position(s, road.lane_offset(2))
            pose = (float(x), float(y), float(road.reference.heading_at(s)))
            a, b = sensor.measure(r, pose), sensor.measure(p, pose)
            # the same line objects with the same points (within the chord error); a
            # point exactly on a dash end may flip, so allow one point of difference
            assert abs(a.n_lines - b.n_lines) <= 1
            assert abs(len(a.all_points) - len(b.all_points)) <= 2
            assert abs(a.n_left - b.n_left) <= 1
            for det in (detect_lanes, lambda f: naive_detect(f, road.lane_width)):
                da, db = det(a), det(b)
                for name in ("ego_left", "ego_right"):
                    la, lb = da.line(name), db.line(name)
                    assert len(la) == len(lb)
                    if len(la):
                        assert np.max(np.abs(la - lb)) < 0.02


def test_kernels_match_their_python_twins(pair) -> None:
    _, poly = pair
    m = poly.markings
    xs = LineSensor().config.x_grid
    rng = np.random.default_rng(0)
    for _ in range(5):
        o = m.xy[rng.integers(len(m.xy))] + rng.normal(0, 3, 2)
        yaw = float(rng.uniform(-np.pi, np.pi))
        args = (m.chunk_mark, m.chunk_i0, m.chunk_i1, m.chunk_centre, m.chunk_radius, len(m))
        near = _near_markings(*args, float(o[0]), float(o[1]), 260.0)
        near_py = _near_markings_py(*args, float(o[0]), float(o[1]), 260.0)
        for a, b in zip(near, near_py, strict=True):
            np.testing.assert_array_equal(a, b)
        rows, lo, hi = near
        outs = []
        for fn in (_sample_polylines, _sample_polylines_py):
            y = np.full((len(rows), len(xs)), np.nan)
            u = np.full((len(rows), len(xs)), np.nan)
            fn(m.xy, m.u, rows, lo, hi, float(o[0]), float(o[1]), yaw, xs, y, u)
            outs.append((y, u))
        np.testing.assert_array_equal(outs[0][0], outs[1][0])
        np.testing.assert_array_equal(outs[0][1], outs[1][1])


def test_a_far_sensor_sees_nothing_and_costs_nothing(pair) -> None:
    _, poly = pair
    rows, y, _ = poly.sample_visible(np.array([1e5, 1e5]), 0.0, LineSensor().config.x_grid)
    assert len(rows) == 0 and y.shape == (0, 98)
    frame = LineSensor().measure(poly, (1e5, 1e5, 0.0))
    assert frame.n_lines == 0


def test_arc_marking_against_the_circle() -> None:
    r = 500.0
    th = np.linspace(-0.2, 0.8, 2000)
    xy = np.column_stack([r * np.sin(th), r - r * np.cos(th)])  # left curve through origin
    road = PolylineRoad([MarkingCurve(xy, np.array([[0.0, 1e4]]))])
    xs = np.arange(5.52, 200.0, 2.0)
    _, y, u = road.sample_visible(np.array([0.0, 0.0]), 0.0, xs)
    # sensor frame y is left: for yaw 0 in highway-env's world, left = -world y
    want = -(r - np.sqrt(r * r - xs**2))
    assert np.max(np.abs(y[0] - want)) < 1e-3
    assert np.all(np.diff(u[0]) > 0)


@pytest.mark.parametrize(
    ("curve", "match"),
    [
        (MarkingCurve(np.zeros((1, 2)), np.zeros((0, 2))), "N >= 2"),
        (MarkingCurve(np.array([[0.0, 0.0], [np.nan, 1.0]]), np.zeros((0, 2))), "NaN"),
        (MarkingCurve(np.array([[0.0, 0.0], [0.0, 0.0]]), np.zeros((0, 2))), "repeated"),
        (MarkingCurve(np.array([[0.0, 0.0], [9.0, 0.0]]), np.array([[5.0, 1.0]])), "sorted"),
    ],
)
def test_bad_curves_are_named(curve: MarkingCurve, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        PolylineMarkings([curve])
