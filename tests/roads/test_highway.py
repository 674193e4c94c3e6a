"""Roads: generated geometry, markings, highway-env lane interface, ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aldm_gym.roads import (
    HighwayRoad,
    MarkingRole,
    MarkingType,
    ReferenceLine,
    RoadConfig,
    Segment,
    curvature_profile,
)


def test_default_road_is_long_curved_and_respects_min_radius() -> None:
    road = HighwayRoad()
    assert road.length >= 5000.0
    kappa = road.reference.kappa
    assert np.abs(kappa).max() > 1 / 3000.0  # it does curve
    assert np.abs(kappa).max() <= 1 / 500.0 + 1e-12  # R >= 500 m by default
    assert (kappa > 1e-6).any() and (kappa < -1e-6).any()  # curves both ways


def test_curvature_profile_is_seeded() -> None:
    a = curvature_profile(RoadConfig(seed=7))
    b = curvature_profile(RoadConfig(seed=7))
    c = curvature_profile(RoadConfig(seed=8))
    assert a == b
    assert a != c


@pytest.mark.parametrize("min_radius", [100.0, 250.0, 800.0])
def test_min_radius_is_configurable(min_radius: float) -> None:
    road = HighwayRoad({"min_radius": min_radius, "max_radius": 2 * min_radius, "seed": 1})
    assert np.abs(road.reference.kappa).max() <= 1 / min_radius + 1e-12
    assert np.abs(road.reference.kappa).max() >= 0.5 / (2 * min_radius)


def test_curvature_of_the_tabulated_line_matches_the_profile() -> None:
    """Heading change over an arc equals length / R (exact geometry, not just the table)."""
    ref = ReferenceLine([Segment(100.0), Segment(300.0, 1 / 400.0, 1 / 400.0), Segment(100.0)])
    dh = ref.heading_at(400.0) - ref.heading_at(100.0)
    assert dh == pytest.approx(-300.0 / 400.0, abs=1e-9)  # left curve: world heading decreases
    # Chord of the arc: 2 R sin(theta / 2).
    chord = np.linalg.norm(ref.position(400.0) - ref.position(100.0))
    assert chord == pytest.approx(2 * 400.0 * np.sin(300.0 / 800.0), abs=1e-6)


def test_left_curve_turns_towards_the_drivers_left() -> None:
    ref = ReferenceLine([Segment(10.0), Segment(200.0, 1 / 200.0, 1 / 200.0)])
    s0 = 10.0
    p0, h0 = ref.position(s0), float(ref.heading_at(s0))
    left = np.array([np.sin(h0), -np.cos(h0)])
    assert (ref.position(150.0) - p0) @ left > 10.0


@pytest.mark.parametrize("lanes", [1, 2, 4, 6])
@pytest.mark.parametrize("width", [3.5, 3.75])
def test_lanes_and_markings_layout(lanes: int, width: float) -> None:
    road = HighwayRoad({"lanes_count": lanes, "lane_width": width, "length": 500.0})
    assert len(road.network.lanes_list()) == lanes
    paint = [m for m in road.markings if m.role != MarkingRole.GUARD_RAIL]
    assert len(paint) == lanes + 1
    assert paint[0].type == MarkingType.CONTINUOUS and paint[-1].type == MarkingType.CONTINUOUS
    assert all(m.type == MarkingType.DASHED for m in paint[1:-1])
    offsets = np.array([m.offset for m in paint])
    np.testing.assert_allclose(-np.diff(offsets), width)
    for i in range(lanes):
        left, right = road.lane_boundaries(i)
        assert left.offset - right.offset == pytest.approx(width)
        assert road.lane(i).width_at(0.0) == width
        assert road.lane_offset(i) == pytest.approx(0.5 * (left.offset + right.offset))


def test_lane_zero_is_leftmost_as_in_highway_env(straight_road: HighwayRoad) -> None:
    """highway-env's LANE_LEFT decreases the lane id: lane 0 must be on the driver's left."""
    s = 100.0
    h = float(straight_road.reference.heading_at(s))
    left = np.array([np.sin(h), -np.cos(h)])
    p0 = straight_road.lane(0).position(s, 0.0)
    p1 = straight_road.lane(1).position(s, 0.0)
    assert (p0 - p1) @ left == pytest.approx(straight_road.lane_width)
    # highway-env's lateral coordinate is positive towards higher lane ids.
    assert straight_road.lane(1).local_coordinates(p0)[1] == pytest.approx(-3.75)


@settings(max_examples=200, deadline=None)
@given(
    s=st.floats(-40.0, 6040.0),
    d=st.floats(-25.0, 25.0),
)
def test_projection_inverts_position(s: float, d: float) -> None:
    road = _PROJ_ROAD
    p = road.reference.position(s, d)
    s2, d2 = road.reference.project(p)
    assert s2 == pytest.approx(s, abs=1e-6)
    assert d2 == pytest.approx(d, abs=1e-6)


_PROJ_ROAD = HighwayRoad({"min_radius": 100.0, "max_radius": 400.0, "seed": 11})


def test_projection_kernel_matches_plain_python() -> None:
    from aldm_gym.roads.reference_line import project_point, project_point_py

    ref = _PROJ_ROAD.reference
    for s, d in [(10.0, 3.0), (2500.0, -12.0), (5900.0, 20.0)]:
        p = ref.position(s, d)
        xy, heading, step, _, _, _, _, coarse, window = ref.lookup
        args = (xy, heading, step, coarse, window, float(p[0]), float(p[1]))
        assert project_point(*args) == project_point_py(*args)


def test_dash_length_and_gap_along_the_marking() -> None:
    road = HighwayRoad({"dash_length": 3.0, "gap_length": 9.0, "min_radius": 200.0, "seed": 2})
    mk = road.markings[1]
    u = np.linspace(0.0, 500.0, 50001)
    on = mk.painted(u)
    cuts = np.flatnonzero(np.diff(on.astype(np.int8))) + 1
    starts, ends = cuts[:-1], cuts[1:]
    runs = u[ends] - u[starts]
    painted_runs = runs[on[starts]]
    gaps = runs[~on[starts]]
    np.testing.assert_allclose(painted_runs, 3.0, atol=0.02)
    np.testing.assert_allclose(gaps, 9.0, atol=0.02)
    assert len(painted_runs) >= 40


def test_marking_arc_length_follows_the_curve() -> None:
    """On an arc of radius R the line at left offset d has length L (1 - d / R)."""
    road = HighwayRoad({"segments": ((50.0, 0.0, 0.0), (400.0, 1 / 300.0, 1 / 300.0))})
    for j, mk in enumerate(road.markings):
        du = road.marking_arc_length(j, 450.0) - road.marking_arc_length(j, 50.0)
        assert du == pytest.approx(400.0 * (1 - mk.offset / 300.0), rel=1e-6)


def test_guard_rails_have_height() -> None:
    road = HighwayRoad({"guard_rail": True, "length": 500.0})
    rails = [m for m in road.markings if m.role == MarkingRole.GUARD_RAIL]
    assert len(rails) == 2
    assert all(m.height > 0 for m in rails)
    assert all(m.height == 0 for m in road.markings if m.role != MarkingRole.GUARD_RAIL)


def test_marking_position_and_lane_id_at(curvy_road: HighwayRoad) -> None:
    for lane_id in range(curvy_road.lanes_count):
        p = curvy_road.lane(lane_id).position(1234.0, 0.4)
        assert curvy_road.lane_id_at(p) == lane_id
        left, _ = curvy_road.lane_boundaries(lane_id)
        q = curvy_road.marking_position(left.index, 1234.0)
        s, r = curvy_road.lane(lane_id).local_coordinates(q)
        assert s == pytest.approx(1234.0, abs=1e-6)
        assert r == pytest.approx(-curvy_road.lane_width / 2, abs=1e-6)


def test_marking_models_share_geometry(curvy_road: HighwayRoad) -> None:
    ed = curvy_road.with_marking_model("editor")
    assert ed.marking_model == "editor" and curvy_road.marking_model == "per_dash"
    assert ed.reference is curvy_road.reference
    assert ed.markings == curvy_road.markings


@pytest.mark.parametrize(
    ("key", "value", "match"),
    [
        ("lanes_count", 7, "lanes_count"),
        ("lanes_count", 2.5, "lanes_count"),
        ("lane_width", float("nan"), "lane_width"),
        ("min_radius", 50.0, "min_radius"),
        ("dash_length", 0.0, "dash_length"),
        ("marking_model", "opendrive", "marking_model"),
        ("segments", ((10.0, 0.5, 0.5),), "kappa"),
        ("straight_length", (10.0,), "straight_length"),
    ],
)
def test_bad_road_config_names_the_key(key: str, value: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        HighwayRoad({key: value})


def test_unknown_road_key_lists_allowed_keys() -> None:
    with pytest.raises(ValueError, match=r"lane_widht.*allowed keys.*lane_width"):
        HighwayRoad({"lane_widht": 3.5})
    with pytest.raises(ValueError, match="lane_id"):
        HighwayRoad({"length": 500.0}).lane_boundaries(4)


@pytest.mark.parametrize("bad", [(np.nan, 0.0), (0.0, np.inf), (1.0,), "ab", None])
def test_road_methods_name_a_bad_point(bad: object) -> None:
    road = HighwayRoad({"seed": 0, "length": 1000.0})
    with pytest.raises(ValueError, match="position"):
        road.locate(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="position"):
        road.lane_id_at(bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("method", ["marking_position", "marking_arc_length"])
def test_road_methods_name_a_bad_arc_length(method: str) -> None:
    road = HighwayRoad({"seed": 0, "length": 1000.0})
    with pytest.raises(ValueError, match="s must be finite"):
        getattr(road, method)(0, np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match="s must be finite"):
        road.curvature_at(float("inf"))
