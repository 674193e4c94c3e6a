"""Tests of ``ALDMHighway-v0``: API conformance, determinism, perception in the loop."""

from __future__ import annotations

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.errors import InputError

CURVED = {"road": {"seed": 0}, "marking_model": "per_dash", "initial_lane_id": 1}


def make(config: dict | None = None, **kw: object) -> gym.Env:
    """A fresh env with ``config`` merged over a small curved default."""
    return gym.make("ALDMHighway-v0", config={**CURVED, **(config or {})}, **kw)


def test_import_is_light_and_registration_idempotent() -> None:
    code = (
        "import sys, importlib, aldm_gym, gymnasium as gym;"
        "importlib.reload(aldm_gym);"
        "assert 'ALDMHighway-v0' in gym.envs.registry;"
        "heavy = [m for m in ('highway_env', 'pygame', 'matplotlib', 'torch') if m in sys.modules];"
        "assert not heavy, heavy"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_gymnasium_and_sb3_check_env() -> None:
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = make({"vehicles_count": 5})
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)
    # info["detection"] holds NaN for a missing line, and the checker compares infos
    # with ``==`` (NaN != NaN): bound the steering so its random actions keep the lines.
    cont = make(
        {"vehicles_count": 5, "action": {"type": "ContinuousAction"}, "lka": {"max_steering": 0.05}}
    )
    check_env(cont.unwrapped, skip_render_check=True)


@pytest.mark.parametrize(
    ("config", "name"),
    [
        ({"lanes_cont": 3}, "lanes_cont"),
        ({"sensor": {"rnage": 100.0}}, "rnage"),
        ({"road": {"min_radus": 500.0}}, "min_radus"),
        ({"lka": {"lookahead": 1.0}}, "lookahead"),
        ({"action": {"typ": "ContinuousAction"}}, "typ"),
        ({"detector": "magic"}, "detector"),
        ({"marking_model": "painted"}, "marking_model"),
        ({"lanes_count": 0}, "lanes_count"),
        ({"sensor": {"dropout": 1.5}}, "dropout"),
        ({"simulation_frequency": 10, "policy_frequency": 3}, "policy_frequency"),
    ],
)
def test_config_errors_name_the_key(config: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        gym.make("ALDMHighway-v0", config=config)


@pytest.mark.parametrize("config", ["abc", 5, [("duration", 5)]])
def test_config_that_is_no_mapping_is_named(config: object) -> None:
    with pytest.raises(
        ValueError, match=r"config must be a mapping .*got " + type(config).__name__
    ):
        gym.make("ALDMHighway-v0", config=config)


def test_unknown_key_lists_allowed_keys() -> None:
    with pytest.raises(ValueError, match=r"allowed keys.*vehicles_count"):
        gym.make("ALDMHighway-v0", config={"vehicle_count": 3})


def test_spaces_and_info_contents() -> None:
    env = make({"vehicles_count": 10})
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    obs, reward, _, _, info = env.step(1)
    assert env.observation_space.contains(obs)
    assert np.isfinite(reward)
    for key in ("lateral_offset", "lane_departure", "lane_index", "crashed", "detection"):
        assert key in info
    assert set(info["detection"]) == {"ego_left", "ego_right"}
    # The ALDM on an exact sensor finds both ego lines, accurately, >= 60 m ahead.
    for score in info["detection"].values():
        assert score["mean_abs_error"] < 0.1
        assert score["preview"] >= 60.0
    assert obs["line_valid"][1] == 1.0 and obs["line_valid"][2] == 1.0
    assert "lane_metrics" not in info  # opt-in: info_metrics


@pytest.mark.parametrize(("detector", "strict_tp"), [("ground_truth", 4), ("naive", None)])
def test_info_lane_metrics(detector: str, strict_tp: int | None) -> None:
    config = {"vehicles_count": 5, "info_metrics": True, "detector": detector}
    env = make({**config, "initial_lane_id": 1})
    env.reset(seed=2)
    for _ in range(3):
        *_, info = env.step(1)
    m = info["lane_metrics"]
    assert set(m) == {"strict", "loose", "near_mean_m", "far_mean_m", "detected"}
    # 4 lanes, the ego in the second: four true lines, each found or missed
    for counts in (m["strict"], m["loose"]):
        assert counts["tp"] + counts["fn"] == 4
    # strictly, every detected line is a TP or an FP
    assert m["strict"]["tp"] + m["strict"]["fp"] == m["detected"] <= 4
    if strict_tp is not None:
        assert m["strict"] == {"tp": strict_tp, "fp": 0, "fn": 0}
        assert m["near_mean_m"] < 1e-6
    else:  # naive on per-dash paint: single dashes, never a 60 m preview
        assert m["strict"]["tp"] < 4 and m["strict"]["fn"] > 0


def test_vehicle_lane_assignment_uses_detected_lines() -> None:
    env = make({"vehicles_count": 25, "initial_lane_id": 1})
    obs, _ = env.reset(seed=4)
    base = env.unwrapped
    for _ in range(3):
        obs, *_ = env.step(1)
    veh = obs["vehicles"]
    present = veh[:, 0] > 0
    assert present.any()
    ego_lane = base.lane_position.lane
    n_checked = 0
    for row, v in zip(veh[present], _nearest_others(base, int(present.sum())), strict=True):
        true_lane = base.highway.lane_id_at(v.position)
        code = int(row[5])
        expected = {ego_lane: 1, ego_lane - 1: 2, ego_lane + 1: 3}.get(true_lane, 0)
        if 5.0 < row[1] < 150.0:  # within the detected lines' x range
            assert code == expected, (row, true_lane, ego_lane)
            n_checked += 1
    assert n_checked > 0


def _nearest_others(base: object, k: int) -> list:
    frame = base.frame
    others = [v for v in base.road.vehicles if v is not base.vehicle]
    dist = [np.hypot(*(v.position - frame.origin)) for v in others]
    order = np.argsort(dist, kind="stable")[:k]
    return [others[i] for i in order]


def test_same_seed_identical_observations_for_200_steps() -> None:
    config = {
        "vehicles_count": 15,
        "policy_frequency": 5,
        "duration": 60.0,
        "sensor": {"lateral_noise": 0.03, "dropout": 0.05},
    }

    def rollout() -> list[dict]:
        env = make(config)
        obs, _ = env.reset(seed=123)
        out = [obs]
        actions = np.random.default_rng(0).integers(0, 5, 200)
        for a in actions:
            obs, _, terminated, truncated, _ = env.step(int(a))
            out.append(obs)
            if terminated or truncated:
                obs, _ = env.reset()
        return out

    a, b = rollout(), rollout()
    assert len(a) == 201
    for oa, ob in zip(a, b, strict=True):
        for key in oa:
            np.testing.assert_array_equal(oa[key], ob[key])
    # Different seeds differ (the check above is not vacuous).
    env = make(config)
    o1, _ = env.reset(seed=1)
    o2, _ = env.reset(seed=2)
    assert not np.array_equal(o1["vehicles"], o2["vehicles"])


def _episode(detector: str, steps: int, seed: int = 0) -> tuple[float, int]:
    env = make({"detector": detector, "vehicles_count": 0, "duration": float(steps)})
    env.reset(seed=seed)
    max_off, departures = 0.0, 0
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(1)
        max_off = max(max_off, abs(info["lateral_offset"]))
        departures += int(info["lane_departure"])
        if terminated or truncated:
            break
    return max_off, departures


def test_closed_loop_aldm_keeps_lane_naive_departs() -> None:
    """The paper's result: on a curved per-dash road, naive detection leaves the lane."""
    aldm_off, aldm_dep = _episode("aldm", 40)  # a full default episode (40 s)
    assert aldm_dep == 0
    assert aldm_off < 0.3
    naive_off, naive_dep = _episode("naive", 20)
    assert naive_dep >= 1
    assert naive_off > 0.875  # a wheel over the marking


def test_lane_change_with_aldm_ends_in_target_lane() -> None:
    env = make({"vehicles_count": 0, "initial_lane_id": 1})
    env.reset(seed=3)
    _, _, _, _, info = env.step(0)  # LANE_LEFT
    assert info["lane_change"] == 1 or info["lane_index"] == 0
    for _ in range(6):
        _, _, _, _, info = env.step(1)
    assert info["lane_index"] == 0
    assert info["lane_change"] == 0
    assert abs(info["lateral_offset"]) < 0.3
    assert info["departures"] == 0
    # Now right twice: lane 0 -> 2.
    for _ in range(2):
        env.step(2)
        for _ in range(6):
            _, _, _, _, info = env.step(1)
    assert info["lane_index"] == 2
    assert abs(info["lateral_offset"]) < 0.3


def test_lane_change_refused_without_adjacent_line() -> None:
    env = make({"vehicles_count": 0, "initial_lane_id": 0})
    env.reset(seed=0)
    _, _, _, _, info = env.step(0)  # no lane left of lane 0: no left adjacent line
    assert info["lane_change_refused"]
    assert info["lane_index"] == 0
    assert info["lane_change"] == 0


def test_continuous_action_steers_iso_left() -> None:
    env = make(
        {"vehicles_count": 0, "action": {"type": "ContinuousAction"}, "road": {"curved": False}}
    )
    env.reset(seed=0)
    offsets = []
    for _ in range(3):
        _, _, _, _, info = env.step(np.array([0.02, 0.0], dtype=np.float32))
        offsets.append(info["lateral_offset"])
    assert offsets[-1] > offsets[0] > -1e-9  # positive steering drifts to the left


def test_make_vec_sync_and_async() -> None:
    for mode in ("sync", "async"):
        envs = gym.make_vec(
            "ALDMHighway-v0",
            num_envs=2,
            vectorization_mode=mode,
            config={**CURVED, "vehicles_count": 3},
        )
        obs, _ = envs.reset(seed=0)
        assert obs["lines"].shape == (2, 4, 13, 2)
        obs, rew, _, _, _ = envs.step(np.array([1, 1]))
        assert rew.shape == (2,)
        envs.close()


def test_render_rgb_array_shape_and_record_video(tmp_path: object) -> None:
    env = make(
        {"vehicles_count": 3, "screen_width": 320, "screen_height": 160}, render_mode="rgb_array"
    )
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (160, 320, 3) and img.dtype == np.uint8
    assert img.std() > 0  # something was drawn
    env.close()
    from gymnasium.wrappers import RecordVideo

    pytest.importorskip("moviepy")
    env = RecordVideo(
        make(
            {"vehicles_count": 2, "screen_width": 160, "screen_height": 96, "duration": 2.0},
            render_mode="rgb_array",
        ),
        str(tmp_path),
    )
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(1)
        done = terminated or truncated
    env.close()
    assert list(tmp_path.glob("*.mp4"))  # type: ignore[attr-defined]


def test_the_lka_follows_the_detections_own_trajectory() -> None:
    """One trajectory: the ego follows ``detection.trajectory``, fitted up to ``path_range``."""
    from aldm_gym.sensor.lane_detection import driving_trajectory

    for path_range in (80.0, 40.0):
        env = make({"vehicles_count": 5, "detector": "naive", "lka": {"path_range": path_range}})
        env.reset(seed=2)
        for _ in range(3):
            env.step(1)
            u = env.unwrapped
            det = u.detection
            assert u.vehicle.trajectory is det.trajectory
            assert len(det.trajectory) >= 2
            # the fit stops where the shorter cut line ends: within the range (+ 1 step)
            assert det.trajectory[-1, 0] <= path_range + 2.0 + 1e-9
            want = driving_trajectory(
                det.ego_left, det.ego_right, u.highway.lane_width, path_range=path_range
            )
            assert det.trajectory.tobytes() == want.tobytes()


def test_lanes_summary_matches_ground_truth_gaps() -> None:
    env = make({"vehicles_count": 25, "initial_lane_id": 1})
    obs, _ = env.reset(seed=4)
    for _ in range(3):
        obs, *_ = env.step(1)
    base = env.unwrapped
    ego = base.vehicle
    ego_lane = base.lane_position.lane
    lanes = obs["lanes"]
    assert lanes.shape == (3, 4) and env.observation_space["lanes"].contains(lanes)
    # Ground truth: nearest vehicle ahead in each true lane, gap along the road.
    s_ego = base.highway.locate(ego.position)[0]
    n_checked = 0
    for row, lane in enumerate((ego_lane - 1, ego_lane, ego_lane + 1)):
        ahead = []
        for v in base.road.vehicles:
            if v is ego or base.highway.lane_id_at(v.position) != lane:
                continue
            ds = base.highway.locate(v.position)[0] - s_ego
            if 5.0 < ds < 90.0:
                ahead.append(ds)
        if ahead:
            assert abs(lanes[row, 0] - (min(ahead) - 5.0)) < 1.0, (row, lanes, ahead)
            n_checked += 1
    assert n_checked > 0


def test_lane_gaps_pick_nearest_vehicle_per_lane() -> None:
    from aldm_gym.envs.observation import LaneCode, lane_gaps

    codes = np.array(
        [LaneCode.EGO, LaneCode.EGO, LaneCode.LEFT, LaneCode.EGO, LaneCode.OTHER], dtype=float
    )
    x = np.array([40.0, 20.0, -30.0, -12.0, 8.0])
    vx = np.array([1.0, -2.0, 3.0, 4.0, -9.0])
    gaps = lane_gaps(codes, x, vx, 100.0)
    np.testing.assert_array_equal(gaps[1], [15.0, -2.0, 7.0, 4.0])  # ego lane
    np.testing.assert_array_equal(gaps[0], [100.0, 0.0, 25.0, 3.0])  # left: one behind
    np.testing.assert_array_equal(gaps[2], [100.0, 0.0, 100.0, 0.0])  # right: empty
    # Overlapping vehicles read a zero gap, never a negative one.
    assert lane_gaps(np.array([1.0]), np.array([2.0]), np.array([0.0]), 100.0)[1, 0] == 0.0
    with pytest.raises(ValueError, match="one length"):
        lane_gaps(codes, x[:3], vx, 100.0)
    with pytest.raises(ValueError, match="finite"):
        lane_gaps(codes, np.where(x > 30, np.nan, x), vx, 100.0)


@pytest.mark.parametrize(
    "action", [1.5, 4.99, 1.0, "1", True, None, float("nan"), float("inf"), [], np.array([1, 2])]
)
def test_meta_actions_must_be_integers(action: object) -> None:
    env = make({"vehicles_count": 2})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="meta action must be an integer"):
        env.step(action)


@pytest.mark.parametrize("action", [np.int64(1), np.array(1), np.array([1]), 1])
def test_integer_like_meta_actions_are_accepted(action: object) -> None:
    from aldm_gym.envs.actions import MetaAction

    env = make({"vehicles_count": 2})
    env.reset(seed=0)
    _, _, _, _, info = env.step(action)
    assert info["action"] is action
    env.step(MetaAction.IDLE)


@pytest.mark.parametrize("action", [np.zeros((2, 1)), np.zeros((1, 2)), [0.0], [0.0, 0.0, 0.0]])
def test_continuous_actions_must_have_shape_2(action: object) -> None:
    env = make({"vehicles_count": 2, "action": {"type": "ContinuousAction"}})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.step(action)


def test_reset_seeds_the_action_space_and_keeps_a_users_seed() -> None:
    env = make({"vehicles_count": 2})
    first = [env.reset(seed=7)[1]["action"] for _ in range(2)]
    assert first[0] == first[1]
    env.action_space.seed(123)
    space = env.action_space
    env.reset()
    assert env.action_space is space  # highway-env's reset rebuilt it before
    draws = [env.action_space.sample() for _ in range(5)]
    space.seed(123)
    space.sample()  # highway-env's reset draws info["action"] from the space
    assert draws == [space.sample() for _ in range(5)]


def test_reset_frees_the_previous_episode_without_a_garbage_collection() -> None:
    """The old road and its vehicles reference each other; reset breaks the cycle so
    reference counting frees them at once (not at Python's next full collection)."""
    import gc
    import weakref

    env = make().unwrapped
    env.reset(seed=0)
    env.step(1)
    others = [weakref.ref(v) for v in env.road.vehicles if v is not env.vehicle]
    ego = weakref.ref(env.vehicle)
    assert others
    gc.disable()
    try:
        env.reset(seed=1)
        assert all(ref() is None for ref in others)
        assert ego() is None
    finally:
        gc.enable()


def test_ego_far_off_a_winding_road_is_sensed_not_refused() -> None:
    """Farther than the projection's reach from a winding road, the ego's arc length may
    belong to another stretch of it; the env then lets the sensor locate itself instead
    of handing it a hint the sensor must refuse."""
    env = make({"road": {"seed": 0, "min_radius": 100.0, "max_radius": 150.0}})
    env.reset(seed=0)
    base = env.unwrapped
    road, ego = base.highway, base.vehicle
    mount = float(base.sensor.config.mount_x)
    rng = np.random.default_rng(0)
    for _ in range(20000):  # a pose whose projected arc length is not the sensor's
        xy = road.reference.position(rng.uniform(0.0, road.length), rng.uniform(60.0, 150.0))
        yaw = rng.uniform(-np.pi, np.pi)
        sensor = xy + mount * np.array([np.cos(yaw), np.sin(yaw)])
        try:
            road._check_hint(sensor, road.lane_position(xy).s + mount)
        except InputError:
            break
    else:
        pytest.fail("no pose with a wrong projection found on this road")
    ego.position = xy
    ego.heading = yaw
    obs, *_ = env.step(1)  # IDLE
    assert env.observation_space.contains(obs)
    assert base.perception.frame is not None
    env.close()
