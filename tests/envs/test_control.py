"""Tests of the pure-pursuit LKA: geometry, SB3-style predict, closed loop on curves."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # noqa: F401
from aldm_gym.agents import LKAController


def circle_path(radius: float, n: int = 60, left: bool = True) -> np.ndarray:
    """Points of a circle tangent to the x axis at the rear axle (sensor frame)."""
    lka = LKAController()
    rear = lka.sensor_x + 0.5 * lka.wheelbase
    phi = np.linspace(0.0, min(0.9, 120.0 / radius), n)
    x = radius * np.sin(phi) - rear
    y = radius * (1.0 - np.cos(phi)) * (1 if left else -1)
    return np.column_stack([x, y])


@pytest.mark.parametrize("radius", [100.0, 500.0, 2000.0])
def test_steering_is_exact_on_circles(radius: float) -> None:
    lka = LKAController()
    for left in (True, False):
        delta = lka.steering(circle_path(radius, left=left), 25.0)
        assert delta is not None
        expected = np.arctan(lka.wheelbase / radius) * (1 if left else -1)
        assert delta == pytest.approx(expected, rel=0.02)


def test_straight_path_no_steering_and_empty_path() -> None:
    lka = LKAController()
    straight = np.column_stack([np.linspace(0, 100, 20), np.zeros(20)])
    assert lka.steering(straight, 30.0) == pytest.approx(0.0)
    assert lka.steering(np.zeros((0, 2)), 30.0) is None
    offset = straight + np.array([0.0, 1.0])  # path to the left: steer left
    assert lka.steering(offset, 30.0) > 0


def test_lookahead_grows_with_speed() -> None:
    lka = LKAController(lookahead_time=1.0, min_lookahead=8.0)
    assert lka.lookahead(2.0) == 8.0
    assert lka.lookahead(30.0) == 30.0


def test_bad_parameters_raise() -> None:
    with pytest.raises(ValueError, match="lookahead_time"):
        LKAController(lookahead_time=-1.0)
    with pytest.raises(ValueError, match="max_steering"):
        LKAController(max_steering=3.0)


def test_predict_single_and_batched() -> None:
    lka = LKAController(target_speed=25.0)
    traj = np.column_stack([np.linspace(0, 60, 13), np.full(13, 0.5)]).astype(np.float32)
    obs = {
        "trajectory": traj,
        "trajectory_valid": np.ones(1, np.float32),
        "ego": np.array([20.0, 0, 0, 0], np.float32),
    }
    action, state = lka.predict(obs, deterministic=True)
    assert action.shape == (2,) and action.dtype == np.float32 and state is None
    assert action[0] > 0 and action[1] > 0
    batch = {k: np.stack([v, v]) for k, v in obs.items()}
    actions, _ = lka.predict(batch)
    assert actions.shape == (2, 2)
    np.testing.assert_allclose(actions[0], action)
    obs["trajectory_valid"] = np.zeros(1, np.float32)
    assert lka.predict(obs)[0][0] == 0.0


def _closed_loop(radius: float, speed: float, left: bool) -> tuple[float, int]:
    k = (1.0 if left else -1.0) / radius
    arc = min(1500.0, 2.5 * radius)  # keep the road from turning back onto itself
    segments = [[100, 0, 0], [80, 0, k], [arc, k, k], [80, k, 0], [600, 0, 0]]
    env = gym.make(
        "ALDMHighway-v0",
        config={
            "detector": "ground_truth",
            "vehicles_count": 0,
            "initial_lane_id": 1,
            "initial_speed": speed,
            "policy_frequency": 10,
            "duration": 30.0,
            "action": {"type": "ContinuousAction"},
            "road": {"segments": segments},
        },
    )
    lka = LKAController(target_speed=speed)
    obs, _ = env.reset(seed=0)
    worst, departures = 0.0, 0
    done = False
    while not done:
        action, _ = lka.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        worst = max(worst, abs(info["lateral_offset"]))
        departures += int(info["lane_departure"])
        done = terminated or truncated
    return worst, departures


@pytest.mark.parametrize(
    ("radius", "speed", "tol"),
    [(500.0, 20.0, 0.2), (500.0, 36.0, 0.3), (100.0, 15.0, 0.3)],
)
def test_closed_loop_on_curves_with_ground_truth(radius: float, speed: float, tol: float) -> None:
    for left in (True, False):
        worst, departures = _closed_loop(radius, speed, left)
        assert departures == 0
        assert worst < tol


def _blind_env(radius: float) -> gym.Env:
    """The built-in LKA (meta actions) with ground truth on a long left bend of
    ``radius``, no traffic, no ACC, 10 Hz steps."""
    k = 1.0 / radius
    segments = [[60, 0, 0], [60, 0, k], [1200, k, k]]
    return gym.make(
        "ALDMHighway-v0",
        config={
            "detector": "ground_truth",
            "vehicles_count": 0,
            "initial_lane_id": 1,
            "initial_speed": 25.0,
            "policy_frequency": 10,
            "duration": 30.0,
            "acc": {"enabled": False},
            "road": {"segments": segments},
        },
    )


def test_without_a_path_the_lka_follows_the_last_one_then_stops_the_car() -> None:
    """No path in the detection (every line lost): the LKA follows the last path on,
    carried by the car's own motion, and once it has run out holds the steering and
    brakes to a stop at MRM_DECELERATION; a path that comes back ends the manoeuvre.
    (Holding the last steering at speed used to drive circles off the road.)"""
    from aldm_gym.envs.vehicle import MRM_DECELERATION
    from aldm_gym.sensor.lane_detection import LaneDetection

    env = _blind_env(500.0)
    env.reset(seed=0)
    base = env.unwrapped
    ego = base.vehicle
    for _ in range(35):  # into the bend, on the path
        env.step(1)
    seeing = base._detector
    base._detector = lambda *args, **kwargs: LaneDetection()
    speeds, offsets, risk = [], [], []
    for _ in range(120):
        _, _, terminated, truncated, info = env.step(1)
        assert not (terminated or truncated)
        speeds.append(ego.speed)
        offsets.append(abs(info["lateral_offset"]))
        risk.append(ego.minimal_risk)
    assert ego.blind
    # the last path (80 m) carries the car for 2-3 s (until it ends before the
    # look-ahead point) without braking
    first = int(np.argmax(risk))
    assert 15 <= first <= 40 and speeds[first - 1] == pytest.approx(25.0, abs=0.5)
    assert max(offsets[:first]) < 0.3
    # then it brakes at the MRM's rate to a stop, and stays stopped, in its lane
    rate = (speeds[first + 5] - speeds[first + 25]) / 2.0
    assert rate == pytest.approx(MRM_DECELERATION, rel=0.05)
    assert speeds[-1] == 0.0 and max(offsets) < 1.0
    base._detector = seeing
    for _ in range(2):  # the first steps act on the detection made before
        env.step(1)
    assert not ego.blind and not ego.minimal_risk and ego.speed > 0.0
