"""Painted markings <-> OSI dash states, both ways."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aldm_gym.errors import InputError
from aldm_gym.osi.boundaries import (
    DASH_CONTINUE,
    DASH_END,
    DASH_GAP,
    DASH_START,
    OPEN_END,
    _run_points,
    painted_intervals,
    sample_boundaries,
)
from aldm_gym.roads import HighwayRoad, OpenDriveRoad, shipped_map
from aldm_gym.sensor import LineSensor


def _grammar_ok(dash: np.ndarray) -> bool:
    """START opens, END closes, CONTINUE only inside; a view may begin or end inside."""
    inside = dash[0] == DASH_CONTINUE
    for d in dash:
        if d == DASH_START:
            if inside:
                return False
            inside = True
        elif d == DASH_END:
            if not inside:
                return False
            inside = False
        elif d == DASH_CONTINUE and not inside:
            return False
    return True


def _u(xy: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


@pytest.mark.parametrize("radius", [250.0, 500.0])
def test_dashes_on_a_curve_are_6_m_with_12_m_gaps(radius: float) -> None:
    road = HighwayRoad(
        {"seed": 1, "min_radius": radius, "max_radius": radius, "marking_model": "per_dash"}
    )
    sensor = LineSensor()
    for s in (800.0, 1600.0, 2400.0):
        pose = road.reference.position(s, road.lane_offset(1))
        frame = sensor.measure(road, (*pose, road.reference.heading_at(s)))
        samples = sample_boundaries(road, frame.origin, frame.yaw, sensor.config.x_grid)
        assert len(samples) == 5
        for b in samples:
            assert _grammar_ok(b.dash)
            u = _u(b.xy)
            starts, ends = u[b.dash == DASH_START], u[b.dash == DASH_END]
            if int(road.marking_table["broken"][b.marking]):
                assert len(starts) >= 9
                first = int(np.argmax(ends > starts[0]))
                lengths = ends[first : first + len(starts) - 1] - starts[: len(starts) - 1]
                # 6 m along the marking, measured here on 2 m chords: within 2 cm
                np.testing.assert_allclose(lengths[: len(lengths)], 6.0, atol=0.02)
                np.testing.assert_allclose(np.diff(starts), 18.0, atol=0.02)
            else:  # solid: one stretch, the view's cut at both ends
                assert len(starts) == len(ends) == 0
                assert b.dash[0] == b.dash[-1] == DASH_CONTINUE


def test_dash_states_across_lane_sections_and_type_changes() -> None:
    """The shipped features map changes lane sections, mark types (broken → solid) and
    has botts dots: every boundary the writer emits is well formed."""
    road = OpenDriveRoad.from_file(shipped_map("features"), marking_model="per_dash")
    sensor = LineSensor()
    rng = np.random.default_rng(0)
    seen = 0
    for pose in road.sample_poses(30, rng):
        frame = sensor.measure(road, pose.pose)
        for b in sample_boundaries(road, frame.origin, frame.yaw, sensor.config.x_grid):
            assert _grammar_ok(b.dash), b.dash
            assert len(b.dash) >= 2 and np.all(np.diff(b.x) > 0)
            seen += int((b.dash == DASH_START).sum())
    assert seen > 100


def test_run_points_put_dash_ends_between_samples() -> None:
    x = np.arange(0.0, 40.0, 2.0)
    u = x + 0.3
    px, _, dash = _run_points(x, np.zeros_like(x), u, np.array([[0.0, 6.0], [18.0, 24.0]]))
    assert list(dash[:4]) == [DASH_CONTINUE, DASH_CONTINUE, DASH_CONTINUE, DASH_END]
    assert px[3] == pytest.approx(5.7)
    assert px[dash == DASH_START] == pytest.approx([17.7])
    assert px[dash == DASH_END] == pytest.approx([5.7, 23.7])
    # u running against x (a marking painted the other way): same places
    px2, _, dash2 = _run_points(x, np.zeros_like(x), 100.0 - x, np.array([[80.0, 86.0]]))
    assert px2[dash2 == DASH_START] == pytest.approx([14.0])
    assert px2[dash2 == DASH_END] == pytest.approx([20.0])


@pytest.mark.parametrize(
    ("dash", "expect"),
    [
        ([DASH_START, DASH_END, DASH_START, DASH_CONTINUE, DASH_END], [[0, 1], [2, 4]]),
        ([DASH_CONTINUE, DASH_END, DASH_START, DASH_CONTINUE], [[0, 1], [2, 3 + OPEN_END]]),
        ([DASH_START, DASH_CONTINUE, DASH_GAP, DASH_START, DASH_END], [[0, 1], [3, 4]]),
        ([0, 0, 0, 0, 0], [[0, 4 + OPEN_END]]),  # a solid line: no states
        ([DASH_GAP, DASH_START, DASH_END, DASH_GAP, DASH_GAP], [[1, 2]]),
        # CONTINUE after a gap: on a dash whose start the view missed
        (
            [DASH_GAP, DASH_CONTINUE, DASH_END, DASH_GAP, DASH_CONTINUE, DASH_CONTINUE],
            [[1, 2], [4, 5 + OPEN_END]],
        ),
    ],
)
def test_painted_intervals_from_dash_states(dash: list[int], expect: list) -> None:
    got = painted_intervals(np.arange(float(len(dash))), np.array(dash))
    np.testing.assert_allclose(got, np.array(expect, dtype=float))


def test_dashed_lines_without_states_pair_their_points() -> None:
    """OSI: a point at the start and one at the end of each dash (esmini's way)."""
    got = painted_intervals(np.array([0.0, 3.0, 12.0, 15.0, 24.0]), np.zeros(5), dashed=True)
    np.testing.assert_allclose(got, [[0, 3], [12, 15]])


def test_botts_dots_without_states_are_one_dot_per_point() -> None:
    got = painted_intervals(
        np.array([0.0, 1.2, 2.4]), np.zeros(3, dtype=int), botts=True, width=0.1
    )
    np.testing.assert_allclose(got, [[-0.05, 0.05], [1.15, 1.25], [2.35, 2.45]])


def test_painted_intervals_checks_lengths() -> None:
    with pytest.raises(InputError, match="same length"):
        painted_intervals(np.arange(3.0), np.zeros(4, dtype=int))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.5, 30.0), min_size=2, max_size=16),
    st.floats(0.0, 18.0),
)
def test_writer_and_reader_agree_on_any_paint(pieces: list[float], offset: float) -> None:
    """Alternating paint/gap lengths along a straight run: the reader's stretches from
    the writer's dash states are the paint, clipped to the view."""
    bounds = offset + np.cumsum([0.0, *pieces])
    intervals = np.stack([bounds[:-1:2], bounds[1::2][: len(bounds[:-1:2])]], axis=1)
    intervals = intervals[intervals[:, 1] > intervals[:, 0]]
    x = np.arange(0.0, 120.0, 2.0)
    px, _, dash = _run_points(x, np.zeros_like(x), x.copy(), intervals)
    if len(dash) < 2:
        return
    got = painted_intervals(px, dash)
    want = np.clip(intervals, x[0], x[-1])
    want = want[want[:, 1] - want[:, 0] > 1e-6]
    # a dash the view cuts at its end stays open there (OPEN_END beyond the last point)
    got[:, 1] = np.where(got[:, 1] > x[-1], x[-1], got[:, 1])
    keep = got[:, 1] - got[:, 0] > 1e-6
    np.testing.assert_allclose(got[keep], want, atol=1e-9)
