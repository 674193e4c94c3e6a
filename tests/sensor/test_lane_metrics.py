"""Lane-detection metrics: matching, strict/loose TP/FP/FN, near/far errors, preview."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor
from aldm_gym.sensor.ground_truth import ground_truth_detect
from aldm_gym.sensor.lane_detection import (
    LINE_NAMES,
    PREVIEW_GAP,
    LaneDetection,
    line_preview,
)
from aldm_gym.sensor.lane_metrics import MetricsTotals, frame_metrics, totals

ROAD = HighwayRoad({"lanes_count": 4, "curved": False, "seed": 0})


def _frame(lane: int = 1):  # type: ignore[no-untyped-def]
    s = 1000.0
    x, y = ROAD.reference.position(s, ROAD.lane_offset(lane))
    pose = (x, y, float(ROAD.reference.heading_at(s)))
    return LineSensor().measure(ROAD, pose), ROAD.lane_position(pose[:2]).lane


def _truth(lane: int = 1) -> tuple[dict[str, np.ndarray], object, object]:
    frame, lane_id = _frame(lane)
    gt = ground_truth_detect(ROAD, frame, lane_id)
    lines = {n: gt.line(n).copy() for n in LINE_NAMES}
    return lines, frame, lane_id


def _detect(lines: dict[str, np.ndarray]) -> LaneDetection:
    return LaneDetection.from_lines(**lines, lane_width=ROAD.lane_width)


def test_ground_truth_is_four_true_positives_at_both_thresholds() -> None:
    lines, frame, lane_id = _truth()
    m = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    assert set(m.truths) == set(lines)
    assert m.counts("strict") == (4, 0, 0)
    assert m.counts("loose") == (4, 0, 0)
    assert all(np.max(match.errors[:, 1]) < 1e-9 for match in m.matches)
    summary = totals([m]).summary()
    assert summary["strict_f1"] == summary["loose_f1"] == 1.0
    assert summary["near_mean_m"] < 1e-9 and summary["far_mean_m"] < 1e-9


def test_a_line_half_a_metre_off_is_loose_but_not_strict() -> None:
    lines, frame, lane_id = _truth()
    lines["ego_left"][:, 1] += 0.5
    m = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    assert m.counts("strict") == (3, 1, 1)
    assert m.counts("loose") == (4, 0, 0)
    match = m.match_of("ego_left")
    assert match is not None and match.detected == "ego_left"
    assert match.cost == pytest.approx(0.5)
    summary = totals([m]).summary()
    assert summary["strict_precision"] == summary["strict_recall"] == 0.75
    assert summary["strict_f1"] == pytest.approx(0.75)
    # near/far errors are over the loosely matched lines: one of four is 0.5 m off
    assert summary["near_mean_m"] == pytest.approx(0.125, abs=1e-6)


def test_a_line_two_metres_off_fails_both_thresholds() -> None:
    lines, frame, lane_id = _truth()
    lines["ego_right"][:, 1] -= 2.0  # not onto another marking: lanes are 3.75 m apart
    m = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    assert m.counts("strict") == (3, 1, 1)
    assert m.counts("loose") == (3, 1, 1)


def test_matching_is_by_geometry_not_by_name() -> None:
    lines, frame, lane_id = _truth()
    swapped = dict(lines)
    swapped["ego_left"], swapped["left_adjacent"] = lines["left_adjacent"], lines["ego_left"]
    m = frame_metrics(_detect(swapped), ROAD, frame, lane_id)
    assert m.counts("loose") == (4, 0, 0)
    pairs = {match.truth: match.detected for match in m.matches}
    assert pairs["ego_left"] == "left_adjacent" and pairs["left_adjacent"] == "ego_left"


def test_a_far_dash_is_precise_but_does_not_recall_its_marking() -> None:
    lines, frame, lane_id = _truth()
    dash = lines["ego_left"]
    lines["ego_left"] = dash[(dash[:, 0] >= 183.0) & (dash[:, 0] <= 189.0)]
    m = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    assert m.previews["ego_left"] == 0.0
    # loose: its 3-4 grid points lie on the marking (precise), but they cover far less
    # than 75 % of it (not recalled); strict: it fails the start and the preview
    assert m.counts("loose") == (3, 0, 1)
    assert m.counts("strict") == (3, 1, 1)
    assert totals([m]).summary()["mean_preview_m"] < 150.0


def test_a_missing_line_is_a_false_negative_and_no_line_is_nothing_detected() -> None:
    lines, frame, lane_id = _truth()
    lines["right_adjacent"] = np.zeros((0, 2))
    m = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    assert m.counts("strict") == (3, 0, 1)
    empty = frame_metrics(LaneDetection(), ROAD, frame, lane_id)
    assert empty.detected == () and empty.counts("loose") == (0, 0, 4)
    summary = totals([empty]).summary()
    assert math.isnan(summary["strict_precision"]) and summary["strict_recall"] == 0.0
    assert summary["strict_f1"] == 0.0  # nothing recalled
    assert summary["lines_detected"] == 0.0
    with pytest.raises(ValueError, match="threshold must be one of"):
        empty.counts("bogus")


def test_kinds_edge_dashed() -> None:
    lines, frame, lane_id = _truth(lane=0)  # leftmost lane: its left line is the edge
    m = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    assert m.truths["ego_left"] == "edge"
    assert m.truths["ego_right"] == "dashed"
    assert "left_adjacent" not in m.truths
    summary = totals([m]).summary()
    assert summary["recall_edge"] == summary["recall_dashed"] == 1.0
    assert math.isnan(summary["recall_solid"])


def test_totals_sum_frames() -> None:
    lines, frame, lane_id = _truth()
    good = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    lines["ego_left"][:, 1] += 0.5
    bad = frame_metrics(_detect(lines), ROAD, frame, lane_id)
    acc = MetricsTotals()
    acc.add(good)
    acc.add(bad)
    s = acc.summary()
    assert (s["strict_tp"], s["strict_fp"], s["strict_fn"]) == (7.0, 1.0, 1.0)
    assert s["frames"] == 2.0
    assert s["strict_precision"] == pytest.approx(7 / 8)


def test_line_preview() -> None:
    x = np.arange(5.5, 200.0, 2.0)
    line = np.column_stack([x, np.zeros_like(x)])
    assert line_preview(line) == pytest.approx(x[-1])
    assert line_preview(line[x >= 30.0]) == 0.0  # starts beyond 25 m
    gap = line[(x < 80.0) | (x > 120.0)]  # a 42 m gap
    assert line_preview(gap) == pytest.approx(x[x < 80.0][-1])
    worn = line[(x < 80.0) | (x > 108.0)]  # one dash missing: a 30 m gap
    assert line_preview(worn) == pytest.approx(x[-1])
    dash = line[(x >= 183.0) & (x <= 189.0)]
    assert line_preview(dash) == 0.0
    assert line_preview(line[:1]) == 0.0


@given(st.lists(st.floats(0.5, 50.0), min_size=2, max_size=40), st.floats(0.0, 40.0))
def test_line_preview_is_the_end_of_a_gapless_prefix(steps: list[float], x0: float) -> None:
    x = x0 + np.cumsum(steps)
    line = np.column_stack([x, np.zeros_like(x)])
    p = line_preview(line)
    if x[0] > 25.0:
        assert p == 0.0
    else:
        assert p in x
        upto = x[x <= p]
        assert np.all(np.diff(upto) <= PREVIEW_GAP)
        assert p == x[-1] or x[np.searchsorted(x, p) + 1] - p > PREVIEW_GAP


def test_the_loose_rule_judges_within_the_view() -> None:
    lines, frame, lane_id = _truth()
    short = {n: line[line[:, 0] <= 140.0] for n, line in lines.items()}
    # under 140 m of visibility every line reaches the end of the view ...
    m = frame_metrics(_detect(short), ROAD, frame, lane_id, view=140.0)
    assert m.counts("loose") == (4, 0, 0)
    # ... over the 200 m range each covers under 75 % of its marking
    assert frame_metrics(_detect(short), ROAD, frame, lane_id).counts("loose") == (0, 0, 4)
    # ground truth's full lines stay precise within the shorter view
    full = frame_metrics(_detect(lines), ROAD, frame, lane_id, view=140.0)
    assert full.counts("loose") == (4, 0, 0)
    for bad in (float("nan"), 6.0, -1.0):
        with pytest.raises(ValueError, match=r"view must be at least 7\.52 m"):
            frame_metrics(_detect(lines), ROAD, frame, lane_id, view=bad)
    for bad in ("100", True):
        with pytest.raises(ValueError, match="view must be a distance"):
            frame_metrics(_detect(lines), ROAD, frame, lane_id, view=bad)  # type: ignore[arg-type]


def test_a_solid_line_with_a_lane_beyond_is_solid_not_edge() -> None:
    road = HighwayRoad({"lanes_count": 4, "curved": False, "seed": 0, "lane_line_type": 1})
    x, y = road.reference.position(1000.0, road.lane_offset(1))
    pose = (x, y, float(road.reference.heading_at(1000.0)))
    frame = LineSensor().measure(road, pose)
    lane_id = road.lane_position(pose[:2]).lane
    m = frame_metrics(ground_truth_detect(road, frame, lane_id), road, frame, lane_id)
    assert m.truths == {
        "left_adjacent": "edge",  # the road's left edge
        "ego_left": "solid",
        "ego_right": "solid",
        "right_adjacent": "solid",  # the fourth lane lies beyond it
    }


def test_a_piece_beside_a_line_does_not_steal_its_match() -> None:
    """Parallel candidates: the cost counts where the lines cover the grid, so a 20 m
    piece 0.2 m beside the true line does not take it from the full detection."""
    lines, frame, lane_id = _truth()
    piece = lines["ego_left"][(lines["ego_left"][:, 0] >= 30) & (lines["ego_left"][:, 0] <= 50)]
    piece = piece + np.array([0.0, -0.2])
    detection = {"ego_left": lines["ego_left"], "left_adjacent": piece}
    m = frame_metrics(_detect(detection), ROAD, frame, lane_id)
    pairs = {match.truth: match.detected for match in m.matches}
    assert pairs["ego_left"] == "ego_left"
    assert m.counts("strict") == (1, 1, 3)


def test_a_line_covering_no_grid_point_is_not_precise() -> None:
    lines, frame, lane_id = _truth()
    # two points between grid points, 1.4 m off the marking, and a line beyond the range
    x0 = float(lines["ego_left"][7, 0]) + 0.5
    y0 = float(np.interp(x0, *lines["ego_left"].T)) + 1.4
    odd = {
        "ego_left": np.array([[x0, y0], [x0 + 1.0, y0]]),
        "ego_right": np.column_stack([[205.0, 230.0, 260.0], lines["ego_right"][-3:, 1]]),
    }
    m = frame_metrics(_detect(odd), ROAD, frame, lane_id)
    assert all(not match.loose_precise and not match.loose for match in m.matches)
    assert m.counts("loose") == (0, 2, 4)
    assert math.isnan(totals([m]).summary()["far_mean_m"])  # no precise line's errors


def test_at_the_loose_rule_tp_and_fp_need_not_add_up_to_the_lines_detected() -> None:
    lines, frame, lane_id = _truth()
    # a correct 40 m piece of ego_left: precise, but it covers under 75 % of the marking
    piece = lines["ego_left"][lines["ego_left"][:, 0] <= 45.0]
    m = frame_metrics(_detect({**lines, "ego_left": piece}), ROAD, frame, lane_id)
    tp, fp, fn = m.counts("loose")
    assert (tp, fp, fn) == (3, 0, 1) and tp + fp < len(m.detected)
    s = totals([m]).summary()
    assert s["loose_precision"] == 1.0 and s["loose_recall"] == 0.75
    assert s["lines_detected"] == 4.0


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (np.array([1.0, 2.0]), r"\(K, 2\) array"),
        (np.array([[10.0, 0.0], [np.nan, 0.0]]), "finite and sorted"),
        (np.array([[30.0, 0.0], [10.0, 0.0]]), "finite and sorted"),
    ],
)
def test_line_preview_rejects_bad_lines(line: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        line_preview(line)
