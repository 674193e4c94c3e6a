"""Trajectory shapes (aldm_gym.scenario.shapes): geometry, times, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from aldm_gym.errors import ScenarioError
from aldm_gym.scenario.positions import WorldPos
from aldm_gym.scenario.shapes import Clothoid, ClothoidSpline, Nurbs, Polyline

WORLD = None  # world positions resolve without a world


def test_a_clothoid_of_constant_curvature_is_an_arc() -> None:
    # R 100 m to the left (OpenDRIVE), a quarter circle: from (0, 0) heading east
    path = Clothoid(WorldPos(0.0, 0.0, 0.0), 0.01, 0.0, 50 * math.pi, 2.0, 7.0).resolve(WORLD)
    end = path.points[-1] * np.array([1.0, -1.0])  # back to OpenDRIVE's frame
    assert end == pytest.approx([100.0, 100.0], abs=1e-3)
    assert path.headings[-1] == pytest.approx(-math.pi / 2)  # highway-env's world
    assert path.times is not None and path.times[[0, -1]] == pytest.approx([2.0, 7.0])
    assert np.hypot(*np.diff(path.points, axis=0).T).max() <= 0.5 + 1e-9


def test_a_clothoid_spline_continues_its_heading_and_times() -> None:
    segments = [
        (0.0, 0.02, 50.0, 0.0, 0.0, WorldPos(10.0, 5.0, 0.0)),
        (0.02, 0.0, 50.0, 0.0, 2.0, None),
    ]
    path = ClothoidSpline(segments, 4.0).resolve(WORLD)  # type: ignore[arg-type]
    turned = 0.5 * 0.02 * 50 + 0.5 * 0.02 * 50  # ∫κ ds over both segments
    assert path.headings[-1] == pytest.approx(-turned, abs=1e-9)
    assert path.times is not None
    assert path.times[0] == 0.0 and path.times[-1] == pytest.approx(4.0)
    assert np.all(np.diff(path.times) > 0)


def test_a_nurbs_runs_from_its_first_to_its_last_control_point() -> None:
    points = [(WorldPos(x, y), t, w) for x, y, t, w in ((0, 0, 0, 1), (10, 0, 1, 3), (20, 5, 2, 1))]
    path = Nurbs(3, points, [0, 0, 0, 1, 1, 1]).resolve(WORLD)  # type: ignore[arg-type]
    assert path.points[0] == pytest.approx([0.0, 0.0])
    assert path.points[-1] == pytest.approx([20.0, -5.0])
    assert path.times is not None and path.times[[0, -1]] == pytest.approx([0.0, 2.0])


@pytest.mark.parametrize(
    ("shape", "message"),
    [
        (Nurbs(3, [(WorldPos(0, 0), None, 1.0)] * 3, [0, 1]), "need 6 knots"),
        (Nurbs(3, [(WorldPos(0, 0), None, 1.0)] * 2, [0] * 5), "at least 3 control points"),
        (Nurbs(2, [(WorldPos(0, 0), None, -1.0)] * 2, [0, 0, 1, 1]), "weights must be > 0"),
        (
            Nurbs(2, [(WorldPos(0, 0), None, 1.0)] * 2, [0, 1, 0, 1]),
            "must be finite and not decrease",
        ),
        (Clothoid(WorldPos(0, 0), 0.0, 0.0, -5.0), "length must be finite and > 0"),
        (Clothoid(WorldPos(0, 0), 0.0, 0.0, 1e12), "longer than the player samples"),
        (ClothoidSpline([(0.0, 0.0, 5.0, 0.0, None, None)]), "needs a positionStart"),
    ],
)
def test_a_shape_it_cannot_sample_is_refused_by_name(shape: object, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        shape.resolve(WORLD)  # type: ignore[attr-defined]


def test_a_polyline_keeps_its_vertices_and_their_headings() -> None:
    path = Polyline([(0.0, WorldPos(0, 0)), (1.0, WorldPos(10, 0, 0.5))]).resolve(WORLD)
    assert path.points.tolist() == [[0.0, 0.0], [10.0, 0.0]]
    assert path.headings == [None, -0.5]
