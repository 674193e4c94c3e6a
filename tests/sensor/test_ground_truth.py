"""Scoring against the true markings (:mod:`aldm_gym.sensor.ground_truth`)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from aldm_gym.roads import OpenDriveRoad, shipped_map
from aldm_gym.roads.markings import MarkingChain
from aldm_gym.sensor import LineSensor
from aldm_gym.sensor.ground_truth import (
    PAIR_GAP,
    boundary_y,
    ground_truth_detect,
    line_markings,
    score_line,
    true_markings,
)


@pytest.fixture(scope="module")
def double_line() -> tuple:
    """The ``features`` map's lane -1 on its first straight: its left border is the
    centre lane's ``solid broken`` mark, a solid stripe 0.12 m left of the border and
    a broken one 0.12 m right of it (nearer the lane)."""
    road = OpenDriveRoad.from_file(shipped_map("features"), marking_model="per_dash")
    frame = LineSensor().measure(road, road.lane_pose("1", -1, 5.0))
    lane = road.lane_position(frame.origin).lane
    return road, frame, lane


def _line(y: float) -> np.ndarray:
    x = np.linspace(5.0, 80.0, 13)
    return np.column_stack([x, np.full_like(x, y)])


def test_the_true_line_of_a_double_line_is_the_stripe_nearest_the_lane(double_line) -> None:
    road, frame, lane = double_line
    xs = np.array([10.0, 50.0])
    rows = true_markings(road, frame, xs)
    left = line_markings(road, lane, frame.origin)["ego_left"]
    truth = rows[left]
    assert truth == pytest.approx([1.75 - 0.12] * 2, abs=1e-6)
    beside = np.abs(rows - truth) <= PAIR_GAP
    # the true stripe and the other one, 0.24 m further left; nothing else that near
    assert np.count_nonzero(beside[:, 0]) == 2
    assert sorted(rows[beside[:, 0], 0]) == pytest.approx([1.63, 1.87], abs=1e-6)


@pytest.mark.parametrize(
    ("y", "correct"),
    [
        (1.63, True),  # the broken stripe, the true line
        (1.87, True),  # the solid stripe of the same border
        (2.15, True),  # within 0.3 m of the solid stripe
        (2.2, False),  # 0.33 m beyond the solid stripe
        (1.35, True),  # within 0.3 m of the broken stripe
        (1.3, False),  # 0.33 m inside it
    ],
)
def test_a_line_on_either_stripe_of_a_double_line_is_correct(
    double_line, y: float, correct: bool
) -> None:
    road, frame, lane = double_line
    left = line_markings(road, lane, frame.origin)["ego_left"]
    score = score_line(_line(y), road, frame, left)
    assert score.correct is correct
    near = min(abs(y - 1.63), abs(y - 1.87))
    assert score.max_abs_error == pytest.approx(near, abs=1e-6)


def test_a_line_that_leaves_the_true_one_is_not_its_paint() -> None:
    """At a lane's opening the new lane's line leaves the true line: near the split it
    is within ``PAIR_GAP``, farther on it is not, so a detection following it is
    wrong where it is more than 0.3 m off the true line; a stripe beside the true line
    all along counts."""
    x = np.linspace(5.0, 80.0, 13)
    truth = np.full_like(x, 1.6)
    leaving = 1.6 + 0.02 * (x - 5.0)  # 1.5 m off at 80 m
    stripe = truth + 0.24
    rows = np.stack([truth, leaving, stripe])
    on = {name: np.column_stack([x, y]) for name, y in (("leaving", leaving), ("stripe", stripe))}
    follows_leaving = score_line(on["leaving"], None, None, 0, markings_y=rows)  # type: ignore[arg-type]
    assert not follows_leaving.correct
    assert follows_leaving.max_abs_error == pytest.approx(1.5 - 0.24)  # to the stripe
    follows_stripe = score_line(on["stripe"], None, None, 0, markings_y=rows)  # type: ignore[arg-type]
    assert follows_stripe.correct and follows_stripe.max_abs_error == 0.0


def test_a_chain_of_markings_scores_each_part_where_it_is_the_true_line() -> None:
    """A border whose marking changes (a chain): the second marking runs elsewhere
    before it takes over, so it is not beside the true line all along; the true line
    itself is still scored at every x."""
    x = np.linspace(5.0, 80.0, 13)
    first = np.where(x < 40.0, 1.6, np.nan)
    second = np.where(x < 40.0, 5.0, 1.6)
    rows = np.stack([first, second])
    line = np.column_stack([x, np.full_like(x, 1.65)])
    score = score_line(line, None, None, (0, 1), markings_y=rows)  # type: ignore[arg-type]
    assert score.correct and score.max_abs_error == pytest.approx(0.05)


@pytest.mark.parametrize(
    ("lane_id", "s"),
    [
        (-1, 1310.0),  # the passing lane opens on the left 40 m ahead
        (-1, 1340.0),  # ... 10 m ahead
        (-2, 560.0),  # the passing lane on the left closes, 40 m ahead (in R 600 m)
        (-2, 700.0),  # ... while it closes
    ],
)
def test_a_border_follows_the_marking_that_bounds_the_lane_where_a_lane_opens(
    lane_id: int, s: float
) -> None:
    """On the 2+1 road the centre line is one marking all along. Where the passing lane
    opens between it and the ego's lane, the centre line leaves the ego's lane to the
    left and the new lane's line, painted from where the lane opens, bounds it: the ego
    lane keeps its 3.5 m to 90 m ahead, at an opening and at a closing."""
    road = OpenDriveRoad.from_file(shipped_map("two_plus_one"), marking_model="per_dash")
    frame = LineSensor().measure(road, road.lane_pose("1", lane_id, s))
    lane = road.lane_position(frame.origin).lane
    chain = line_markings(road, lane, frame.origin)["ego_left"]
    assert isinstance(chain, MarkingChain) and len(chain) == 2
    truth = ground_truth_detect(road, frame, lane)
    left, right = truth.ego_left, truth.ego_right
    assert np.array_equal(left[:, 0], right[:, 0])
    left, right = left[left[:, 0] <= 90.0], right[right[:, 0] <= 90.0]
    assert left[-1, 0] > 85.0
    # within a few cm (in a bend, y across lines at one x is a little more than the width)
    assert left[:, 1] - right[:, 1] == pytest.approx(np.full(len(left), 3.5), abs=0.05)
    # a detection on the marking that leaves the lane is wrong, one on the lane's border right
    xs = left[:, 0]
    rows = true_markings(road, frame, xs)
    off = np.nanmax(np.abs(rows[list(chain)] - left[:, 1]), axis=1)
    assert off.max() > PAIR_GAP + 0.3
    leaving = np.column_stack([xs, rows[list(chain)[int(np.argmax(off))]]])
    leaving = leaving[np.isfinite(leaving[:, 1])]
    assert not score_line(leaving, road, frame, chain).correct
    assert score_line(left, road, frame, chain).correct


def test_a_chain_takes_the_marking_that_has_taken_over_at_each_x() -> None:
    """Markings 0, 1 and 2 are everywhere (1, 2 and 3 m); the chain takes over from 0
    to 1 at 30 m and to 2 at 50 m ahead of a sensor at (10, 0) facing +y. A start
    projected nearer than the one before it counts from the one before; where the
    active marking is not there, the first of the chain that is."""
    xs = np.array([5.0, 29.0, 31.0, 45.0, 49.0, 51.0, 70.0])
    y = np.array([np.full(7, 1.0), np.full(7, 2.0), np.full(7, 3.0)])
    frame = SimpleNamespace(origin=np.array([10.0, 0.0]), yaw=np.pi / 2)
    chain = MarkingChain((0, 1, 2), np.array([[10.0, 0.0], [10.0, 30.0], [10.0, 50.0]]))
    got = boundary_y(y, chain, xs, frame)  # type: ignore[arg-type]
    assert got.tolist() == [1.0, 1.0, 2.0, 2.0, 2.0, 3.0, 3.0]
    # without the frame, or as a plain tuple: the first marking there
    assert boundary_y(y, chain).tolist() == [1.0] * 7
    assert boundary_y(y, (0, 1, 2), xs, frame).tolist() == [1.0] * 7  # type: ignore[arg-type]
    # marking 2 starting at 20 m, before marking 1's 30 m: from 30 m on
    back = MarkingChain((0, 1, 2), np.array([[10.0, 0.0], [10.0, 30.0], [10.0, 20.0]]))
    assert boundary_y(y, back, xs, frame).tolist() == [1.0, 1.0, 3.0, 3.0, 3.0, 3.0, 3.0]  # type: ignore[arg-type]
    # marking 1 not painted at 45 m: the first of the chain that is
    y[1, 3] = np.nan
    assert boundary_y(y, chain, xs, frame)[3] == 1.0  # type: ignore[arg-type]
