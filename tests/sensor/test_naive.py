"""Naive (CarMaker default) detection and the paper's failure cases."""

from __future__ import annotations

import numpy as np
import pytest

from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LaneDetection, LineSensor, naive_detect, score_detection
from tests.conftest import pose_on_lane


def test_naive_on_per_dash_is_one_dash_on_editor_the_whole_line(
    straight_road: HighwayRoad,
) -> None:
    pose = pose_on_lane(straight_road, 400.0, 1)
    dash = naive_detect(LineSensor().measure(straight_road, pose))
    ed = naive_detect(LineSensor().measure(straight_road.with_marking_model("editor"), pose))
    assert dash.found("ego_left")
    assert dash.extent("ego_left") < 10.0  # a single ~6 m dash
    assert ed.preview("ego_left") >= 60.0
    assert ed.preview("ego_right") >= 60.0
    np.testing.assert_allclose(ed.ego_left[:, 1], 1.875)
    np.testing.assert_allclose(ed.ego_right[:, 1], -1.875)


# The paper's worst case (Fig. 4-5): entering the tightest allowed right curve
# (R = 500 m), the car at the leftmost position of its lane (tyres just inside the
# left line: (3.75 - 2.0) / 2 = 0.875 m left of the lane centre).
R_MIN = 500.0
WORST = HighwayRoad(
    {"segments": ((300.0, 0.0, 0.0), (500.0, -1 / R_MIN, -1 / R_MIN)), "lanes_count": 3}
)
LEFTMOST = (3.75 - 2.0) / 2


@pytest.mark.parametrize("ahead", [-8.0, -4.0, 0.0, 4.0, 8.0])
def test_worst_case_per_dash_picks_wrong_markings(ahead: float) -> None:
    sensor = LineSensor()
    s_car = 300.0 - sensor.config.mount_x + ahead
    f = sensor.measure(WORST, pose_on_lane(WORST, s_car, 1, LEFTMOST))
    left, right = f.left.relevant_line, f.right.relevant_line
    assert left is not None and right is not None
    # Left: a single dash of the left marking. Right: a dash of the *left* marking
    # that has crossed the car's middle axis in the curve (the wrong marking).
    assert left.marking == 1 and left.piece >= 0
    assert right.marking == 1
    scores = score_detection(naive_detect(f), WORST, f, lane_id=1)
    assert not scores["ego_left"].correct
    assert not scores["ego_right"].correct


@pytest.mark.parametrize("ahead", [-8.0, 0.0, 8.0])
def test_worst_case_editor_is_right(ahead: float) -> None:
    sensor = LineSensor()
    road = WORST.with_marking_model("editor")
    f = sensor.measure(road, pose_on_lane(road, 300.0 - 1.0 + ahead, 1, LEFTMOST))
    assert f.left.relevant_line.marking == 1
    assert f.right.relevant_line.marking == 2
    scores = score_detection(naive_detect(f), road, f, lane_id=1)
    assert scores["ego_left"].correct and scores["ego_right"].correct


def test_naive_adjacent_lines(straight_road: HighwayRoad) -> None:
    ed = straight_road.with_marking_model("editor")
    det = naive_detect(LineSensor().measure(ed, pose_on_lane(ed, 400.0, 1)))
    np.testing.assert_allclose(det.left_adjacent[:, 1], 1.875 + 3.75)
    np.testing.assert_allclose(det.right_adjacent[:, 1], -1.875 - 3.75)


def test_naive_needs_a_frame() -> None:
    with pytest.raises(TypeError, match="SensorFrame"):
        naive_detect(np.zeros((10, 3)))  # type: ignore[arg-type]


def test_naive_on_empty_frame_finds_nothing(straight_road: HighwayRoad) -> None:
    det = naive_detect(LineSensor().measure(straight_road, (9000.0, 9000.0, 0.0)))
    assert isinstance(det, LaneDetection)
    assert not det.found("ego_left") and det.trajectory.shape == (0, 2)


def test_naive_path_range_fits_the_near_part_of_the_lines(curvy_road: HighwayRoad) -> None:
    """``path_range`` changes only the trajectory: the fit of the lines up to 80 m."""
    from aldm_gym.sensor.trajectory import driving_trajectory

    road = curvy_road.with_marking_model("editor")
    frame = LineSensor().measure(road, pose_on_lane(road, 400.0, 1))
    whole = naive_detect(frame, lane_width=road.lane_width)
    near = naive_detect(frame, lane_width=road.lane_width, path_range=80.0)
    for name in ("ego_left", "ego_right", "left_adjacent", "right_adjacent"):
        np.testing.assert_array_equal(near.line(name), whole.line(name))
    assert near.preview("ego_left") > 100.0  # long lines: the cut matters
    want = driving_trajectory(near.ego_left, near.ego_right, road.lane_width, path_range=80.0)
    assert near.trajectory.tobytes() == want.tobytes()
    assert near.trajectory[-1, 0] <= 80.0 + 2.0 < whole.trajectory[-1, 0]


def test_naive_judges_sides_on_the_cars_middle_axis(straight_road: HighwayRoad) -> None:
    """A sensor 2 m left of the car's middle axis sees the car's left line 0.125 m to
    its right; CarMaker's rule is the car's middle axis, so it is still the ego left
    line, and the adjacent lines are counted outward from the car's axis too."""
    ed = straight_road.with_marking_model("editor")
    pose = pose_on_lane(ed, 400.0, 1)
    centred = naive_detect(LineSensor().measure(ed, pose))
    off = naive_detect(LineSensor({"mount_y": 2.0}).measure(ed, pose))
    for name in ("ego_left", "ego_right", "left_adjacent", "right_adjacent"):
        assert off.found(name), name
        np.testing.assert_allclose(off.line(name)[:, 1], centred.line(name)[:, 1] - 2.0)


def test_naive_lines_starting_on_the_axis_count_left(straight_road: HighwayRoad) -> None:
    """y = 0 exactly (the sensor right above the car's left line): the paper's
    "otherwise to the left" makes that line the naive ego left line."""
    ed = straight_road.with_marking_model("editor")
    sensor = LineSensor({"mount_y": 0.0})
    frame = sensor.measure(ed, pose_on_lane(ed, 400.0, 1, 1.875))
    first_y = frame.side_offsets()
    j = int(np.flatnonzero(frame.line_marking == 1)[0])
    assert first_y[j] == 0.0  # exactly on the axis
    det = naive_detect(frame)
    np.testing.assert_array_equal(det.ego_left[:, 1], frame.line_points(j)[:, 1])
    assert j < frame.n_left
