"""Lanes that end: the map horizon, the perceived end, the gap check, and the
chauffeur leaving an ending lane in a scenario."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from aldm_gym.envs.lane_end import (
    LaneEndConfig,
    LaneEndMonitor,
    gap_is_free,
    map_lane_end,
    perceived_lane_end,
)
from aldm_gym.errors import ConfigError
from aldm_gym.sensor.lane_detection import LaneDetection

X = np.arange(5.0, 150.0, 2.0)


def line(y: np.ndarray | float) -> np.ndarray:
    """A detected line ``y(x)`` over :data:`X`."""
    return np.column_stack([X, np.broadcast_to(y, X.shape)])


def closing(start: float, end: float, begin: float = 40.0, length: float = 150.0) -> np.ndarray:
    """A line at ``start`` that moves linearly to ``end`` over ``length`` from ``begin``."""
    t = np.clip((X - begin) / length, 0.0, 1.0)
    return start + (end - start) * t


def test_a_two_plus_one_taper_is_left_across_the_staying_line() -> None:
    """The overtaking lane of a 2+1 road: its left line (the centre line) closes in on
    the lane line; the lane on the right keeps its width, the one beyond the centre
    line widens. Leave it to the right."""
    det = LaneDetection.from_lines(
        ego_left=line(closing(1.75, -1.75)),
        ego_right=line(-1.75),
        left_adjacent=line(5.25),
        right_adjacent=line(-5.25),
    )
    end = perceived_lane_end(det, end_width=2.5, ego_x=-1.0)
    assert end is not None and end.side == -1 and end.source == "perception"
    # Width 2.5 m at x = 40 + 150 / 3.5 = 82.9 m; read every 2 m, from the ego's centre.
    assert 83.0 <= end.distance <= 87.0


def test_an_on_ramp_is_left_to_the_left() -> None:
    """An acceleration lane: its edge line closes in from the right, no lane beyond it."""
    det = LaneDetection.from_lines(
        ego_left=line(1.75),
        ego_right=line(closing(-1.75, 1.75)),
        left_adjacent=line(5.25),
    )
    end = perceived_lane_end(det, end_width=2.5)
    assert end is not None and end.side == 1


def test_parallel_lines_end_nothing_and_no_adjacent_lane_gives_no_side() -> None:
    parallel = LaneDetection.from_lines(ego_left=line(1.75), ego_right=line(-1.75))
    assert perceived_lane_end(parallel, end_width=2.5) is None
    assert perceived_lane_end(None, end_width=2.5) is None
    lonely = LaneDetection.from_lines(ego_left=line(1.75), ego_right=line(closing(-1.75, 1.75)))
    end = perceived_lane_end(lonely, end_width=2.5)
    assert end is not None and end.side == 0  # no lane seen to go to: stop at the end
    narrow = LaneDetection.from_lines(ego_left=line(0.5), ego_right=line(-0.5))
    assert perceived_lane_end(narrow, end_width=2.5) is None  # not a taper it is in


def test_the_map_horizon_on_the_two_plus_one_road() -> None:
    from aldm_gym.roads.map_road import OpenDriveRoad
    from aldm_gym.roads.opendrive.parse import shipped_map

    road = OpenDriveRoad.from_file(shipped_map("two_plus_one"))
    overtaking = road.lane_position(road.lane_centre(("1", 0, -1))[200])
    end = map_lane_end(road, overtaking, end_width=2.5)
    assert end is not None and end.side == -1 and end.source == "map"
    # The taper runs from s = 600 to 750 m (a cubic from 3.5 m to 0): narrower than
    # 2.5 m from s ≈ 653 m on, where a car no longer fits.
    assert 645.0 < overtaking.s + end.distance < 660.0
    through = road.lane_position(road.lane_centre(("1", 0, -2))[200])
    assert map_lane_end(road, through) is None and road.lane_end_side(through) == 0


def test_the_gap_check_is_the_rule_based_lane_changes() -> None:
    assert gap_is_free(np.zeros(0), np.zeros(0))
    assert not gap_is_free(np.array([10.0]), np.array([0.0]))  # beside/ahead
    assert gap_is_free(np.array([60.0]), np.array([0.0]))  # far enough ahead
    assert not gap_is_free(np.array([-40.0]), np.array([15.0]))  # closing fast from behind
    assert gap_is_free(np.array([-40.0]), np.array([-1.0]))  # falling back


def test_the_monitor_confirms_perception_then_holds_the_end() -> None:
    det = LaneDetection.from_lines(
        ego_left=line(1.75),
        ego_right=line(closing(-1.75, 1.75)),
        left_adjacent=line(5.25),
    )
    monitor = LaneEndMonitor(LaneEndConfig(source="perception", confirm_steps=3))
    seen = [monitor.update(None, None, det) for _ in range(3)]
    assert seen[0] is None and seen[1] is None and seen[2] is not None
    # Held by odometry while the detector loses it (a taper confuses detectors) ...
    held = monitor.update(None, None, None, travelled=10.0)
    assert held is not None and held.distance == pytest.approx(seen[2].distance - 10.0)
    assert held.side == 1
    # ... until the ego has changed lanes.
    assert monitor.update(None, None, None, travelled=1.0, lane_changes=1) is None
    # Sightings that do not agree with the way travelled are not confirmed.
    fresh = LaneEndMonitor(LaneEndConfig(source="perception", confirm_steps=2))
    assert fresh.update(None, None, det, travelled=0.0) is None
    assert fresh.update(None, None, det, travelled=30.0) is None  # it should have moved
    assert fresh.update(None, None, det, travelled=0.0) is not None
    off = LaneEndMonitor(LaneEndConfig(source="off"))
    assert off.update(None, None, det) is None
    assert LaneEndMonitor(LaneEndConfig(lead_time=8.0, min_distance=100.0)).zone(25.0) == 200.0


def test_an_opening_lane_is_kept_right_of() -> None:
    """A lane opening on the left (no paint between the two yet): the LKA keeps half a
    lane width left of the right line instead of the middle of the widening gap."""
    from aldm_gym.envs.lane_end import opening_path

    det = LaneDetection.from_lines(
        ego_left=line(closing(1.75, 5.25, 20.0, 60.0)), ego_right=line(-1.75)
    )
    path = np.column_stack([X, 0.5 * (det.ego_left[:, 1] + det.ego_right[:, 1])])
    kept = opening_path(path, det, 3.5, 1.25)
    near = X < 20.0
    assert np.array_equal(kept[near], path[near])  # a normal lane: unchanged
    far = X > 60.0
    assert np.allclose(kept[far, 1], 0.0)  # half a lane from the right line
    assert np.all(np.abs(np.diff(kept[:, 1])) < 0.5)  # no jump where it starts
    assert opening_path(path, det, 3.5, 3.0) is path  # never that wide


def test_bad_settings_are_named() -> None:
    with pytest.raises(ConfigError, match=r"lane_end\.source"):
        LaneEndConfig(source="radar")
    with pytest.raises(ConfigError, match=r"lane_end\.confirm_steps"):
        LaneEndConfig(confirm_steps=0)


@pytest.mark.parametrize(
    ("case", "source", "detector"),
    [
        ("two_plus_one", "off", "ground_truth"),
        ("two_plus_one", "map", "ground_truth"),
        ("on_ramp", "perception", "ground_truth"),
    ],
)
def test_the_chauffeur_leaves_a_lane_before_it_ends(
    tmp_path: object, case: str, source: str, detector: str
) -> None:
    """The built-in function in the lane that ends: with the lane end from the map or
    from perception it changes lanes in time (no departure, no collision); without
    (``off``) it drives into the taper."""
    from aldm_gym.harness.criteria import run_scenario
    from aldm_gym.harness.lane_drop import lane_drop_scenario

    path = lane_drop_scenario(tmp_path, case, 25.0, "none")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = run_scenario(path, detector=detector, config={"lane_end": {"source": source}})
    assert result.finished and not result.collision
    if source == "off":
        assert result.departures > 0
    else:
        assert result.departures == 0 and result.passed


def test_a_stop_at_the_end_when_no_gap_comes() -> None:
    """The ACC brakes for the lane's end as for a standing car before it."""
    from aldm_gym.envs.longitudinal import LongitudinalController
    from aldm_gym.envs.targets import Objects

    ctrl = LongitudinalController()
    speed, position = 25.0, 0.0
    end = 150.0
    for _ in range(400):
        cmd = ctrl.update(None, Objects(), speed, 25.0, stop_at=end - position - 5.0)
        speed = max(speed + 0.1 * cmd.acceleration, 0.0)
        position += 0.1 * speed
    # It creeps to a stop at the ACC's standstill gap (4 m) before the stop point.
    assert speed < 0.05 and end - 5.0 - 2.5 - 6.0 < position < end - 5.0 - 2.5


def test_a_narrow_noisy_lane_ends_nowhere() -> None:
    """The threshold follows the lane: a 3.1 m lane with 5 cm of noise on each point is
    no taper (with a fixed 3 m threshold it was one, most frames)."""
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(50):
        noisy = LaneDetection.from_lines(
            ego_left=line(1.55 + rng.normal(0.0, 0.05, X.shape)),
            ego_right=line(-1.55 + rng.normal(0.0, 0.05, X.shape)),
        )
        ends += perceived_lane_end(noisy, end_width=3.0) is not None
    assert ends == 0


def test_both_adjacent_lanes_alike_keep_right() -> None:
    """A lane dropped between two: the lanes on the right shift left into its place, so
    both neighbours keep their width; the chauffeur keeps right."""
    det = LaneDetection.from_lines(
        ego_left=line(1.75),
        ego_right=line(closing(-1.75, 1.75)),
        left_adjacent=line(5.25),
        right_adjacent=line(closing(-5.25, -1.75)),
    )
    end = perceived_lane_end(det, end_width=3.0)
    assert end is not None and end.side == -1


def test_the_gap_check_refuses_oncoming_traffic_and_sees_behind_in_a_curve() -> None:
    from aldm_gym.envs.lane_end import target_lane_free
    from aldm_gym.envs.targets import Objects

    det = LaneDetection.from_lines(
        ego_left=line(1.75), ego_right=line(-1.75), left_adjacent=line(5.25)
    )
    oncoming = Objects(
        ids=np.array([1]), x=np.array([150.0]), y=np.array([3.5]), vx=np.array([-50.0]),
        width=np.array([2.0]), length=np.array([5.0]),
    )  # fmt: skip
    assert not target_lane_free(det, oncoming, 1, lane_width=3.5, ego_speed=25.0)
    assert target_lane_free(det, oncoming, 1, lane_width=3.5, ego_speed=60.0)  # only faster
    # A left curve of R 500 m: a car 60 m behind in the left lane sits 3.6 m right of
    # the lane's straight extrapolation; along the arc it is in the lane, closing in
    # at 20 m/s (3 s + 5 m: 65 m are needed).
    radius, back = 500.0, -60.0
    curve = LaneDetection.from_lines(
        ego_left=np.column_stack([X, 1.75 + 0.5 * X * X / radius]),
        ego_right=np.column_stack([X, -1.75 + 0.5 * X * X / radius]),
        left_adjacent=np.column_stack([X, 5.25 + 0.5 * X * X / radius]),
    )
    behind = Objects(
        ids=np.array([1]), x=np.array([back]), y=np.array([3.5 + 0.5 * back * back / radius]),
        vx=np.array([20.0]), width=np.array([2.0]), length=np.array([5.0]),
    )  # fmt: skip
    assert not target_lane_free(curve, behind, 1, lane_width=3.5, curvature=1 / radius)
    assert target_lane_free(curve, behind, 1, lane_width=3.5)  # straight back: not in it


def test_the_width_kernel_matches_its_python_twin_and_the_sampled_width() -> None:
    from aldm_gym.envs import lane_end as le

    rng = np.random.default_rng(3)
    left = np.column_stack([np.sort(rng.uniform(0.0, 150.0, 40)), rng.uniform(1.0, 3.0, 40)])
    right = np.column_stack([np.sort(rng.uniform(5.0, 120.0, 30)), rng.uniform(-3.0, -1.0, 30)])
    args = (left, right, 5.0, 120.0)
    assert le._width_range(*args) == le._width_range_py(*args)
    xs = np.linspace(5.0, 120.0, 5001)
    sampled = np.interp(xs, left[:, 0], left[:, 1]) - np.interp(xs, right[:, 0], right[:, 1])
    lo, hi = le._width_range(*args)
    assert lo <= sampled.min() + 1e-12 and hi >= sampled.max() - 1e-12
    assert sampled.min() - lo < 0.05 and hi - sampled.max() < 0.05
