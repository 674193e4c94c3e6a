"""LaneDetection container: validation, resampling, trajectory."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from aldm_gym.sensor import LaneDetection, driving_trajectory


def _line(y0: float, curv: float = 0.0, x0: float = 5.52, x1: float = 120.0) -> np.ndarray:
    x = np.arange(x0, x1, 2.0)
    return np.column_stack([x, y0 + 0.5 * curv * x**2])


def test_lines_are_sorted_and_validated() -> None:
    pts = _line(1.8)[::-1]
    det = LaneDetection(ego_left=pts)
    assert np.all(np.diff(det.ego_left[:, 0]) > 0)
    with pytest.raises(ValueError, match=r"ego_right.*shape"):
        LaneDetection(ego_right=np.zeros((4, 3)))
    with pytest.raises(ValueError, match="NaN"):
        LaneDetection(ego_left=np.array([[1.0, np.nan], [2.0, 0.0]]))


def test_resample_gives_n_equally_spaced_points() -> None:
    det = LaneDetection(ego_left=_line(1.8, 1e-3), ego_right=_line(-1.9, x1=40.0))
    r = det.resample(13)
    assert r.ego_left.shape == (13, 2) and r.ego_right.shape == (13, 2)
    assert np.allclose(np.diff(r.ego_left[:, 0]), np.diff(r.ego_left[:, 0])[0])
    assert r.ego_left[0, 0] == det.ego_left[0, 0] and r.ego_left[-1, 0] == det.ego_left[-1, 0]
    assert r.left_adjacent.shape == (0, 2)
    with pytest.raises(ValueError, match="n >= 2"):
        det.resample(1)


def test_trajectory_is_midway_and_single_line_offsets_half_a_lane() -> None:
    left, right = _line(1.9, 1e-3), _line(-1.85, 1e-3)
    traj = driving_trajectory(left, right)
    assert traj[0, 0] == 0.0
    expected = 0.5 * (1.9 - 1.85) + 0.5 * 1e-3 * traj[:, 0] ** 2
    np.testing.assert_allclose(traj[:, 1], expected, atol=1e-6)
    only_left = driving_trajectory(left, np.zeros((0, 2)), lane_width=3.5)
    np.testing.assert_allclose(
        only_left[:, 1], 1.9 - 1.75 + 0.5e-3 * only_left[:, 0] ** 2, atol=1e-6
    )
    only_right = driving_trajectory(np.zeros((0, 2)), right, lane_width=3.5)
    np.testing.assert_allclose(
        only_right[:, 1], -1.85 + 1.75 + 0.5e-3 * only_right[:, 0] ** 2, atol=1e-6
    )
    assert driving_trajectory(np.zeros((0, 2)), np.zeros((0, 2))).shape == (0, 2)


def test_as_array_for_observations() -> None:
    det = LaneDetection.from_lines(ego_left=_line(1.8), ego_right=_line(-1.9))
    pts, valid = det.as_array(13)
    assert pts.shape == (4, 13, 2)
    np.testing.assert_array_equal(valid, [False, True, True, False])
    assert np.all(pts[0] == 0)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 40), st.just(2)), elements=st.floats(-300, 300)))
def test_any_finite_line_resamples_to_finite_points(pts: np.ndarray) -> None:
    det = LaneDetection.from_lines(ego_left=pts, ego_right=pts + np.array([0.0, -3.5]))
    r = det.resample(13)
    assert r.ego_left.shape in ((13, 2), (0, 2))
    assert np.all(np.isfinite(r.ego_left))
    assert np.all(np.isfinite(det.trajectory))
