"""Action masks: the meta actions that act now, by the rule the env refuses by."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.envs.actions import MetaAction
from aldm_gym.errors import InputError

LEFT, RIGHT = int(MetaAction.LANE_LEFT), int(MetaAction.LANE_RIGHT)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_mask_says_which_lane_changes_start(seed: int) -> None:
    env = gym.make("ALDMHighway-v0", config={"vehicles_count": 10, "duration": 30})
    _, info = env.reset(seed=seed)
    masks = env.get_wrapper_attr("action_masks")
    rng = np.random.default_rng(seed)
    tried = {True: 0, False: 0}
    for _ in range(30):
        mask = masks()
        assert mask.dtype == bool and mask.shape == (5,)
        np.testing.assert_array_equal(info["action_mask"], mask)
        assert mask[[1, 3, 4]].all()  # IDLE, FASTER, SLOWER always act
        ego = env.unwrapped.vehicle
        before = (ego.lane_change, ego.lane_changes_completed, ego.lane_changes_aborted)
        action = int(rng.choice([LEFT, RIGHT, 1, 1]))
        _, _, terminated, truncated, info = env.step(action)
        if action in (LEFT, RIGHT):
            tried[bool(mask[action])] += 1
            direction = 1 if action == LEFT else -1
            started = ego.lane_change == direction or (
                ego.lane_changes_completed + ego.lane_changes_aborted > before[1] + before[2]
            )
            if mask[action]:
                assert started and not info["lane_change_refused"]
            elif before[0] == 0:  # no change under way: the env refuses it
                assert info["lane_change_refused"]
            else:  # one under way: the action is ignored, not refused
                assert not info["lane_change_refused"]
        if terminated or truncated:
            break
    assert tried[True] > 0 and tried[False] > 0  # both kinds were tried
    env.close()


def test_no_lane_change_to_the_left_of_the_leftmost_lane() -> None:
    env = gym.make("ALDMHighway-v0", config={"vehicles_count": 0, "initial_lane_id": 0})
    _, info = env.reset(seed=0)
    assert not info["action_mask"][LEFT] and info["action_mask"][RIGHT]
    _, _, _, _, info = env.step(LEFT)
    assert info["lane_change_refused"]
    _, _, _, _, info = env.step(RIGHT)
    assert info["lane_change"] == -1 and not info["action_mask"][RIGHT]  # under way
    env.close()


def test_continuous_actions_have_no_mask() -> None:
    env = gym.make("ALDMHighway-v0", config={"action": {"type": "ContinuousAction"}})
    _, info = env.reset(seed=0)
    assert "action_mask" not in info
    with pytest.raises(InputError, match="meta actions"):
        env.get_wrapper_attr("action_masks")()
    env.close()


def test_no_lane_change_into_a_lane_that_closes_ahead_or_across_unseen_paint() -> None:
    """The detected lane beside must be at least as wide as the car wherever both its
    lines are seen up to the path range: not a lane whose outer line closes in ahead
    (a taper), where the car would arrive as it ends. And the ego line must lie on
    broken paint: not on none, unless the chauffeur leaves a lane that ends."""
    from aldm_gym.sensor.lane_detection import LaneDetection

    env = gym.make("ALDMHighway-v0", config={"vehicles_count": 0, "initial_lane_id": 0})
    env.reset(seed=0)
    ego = env.unwrapped.vehicle
    det = ego.detection
    assert ego.lane_change_available(-1)
    right = det.ego_right
    for closing, available in ((0.0, True), (0.01, True), (0.04, False)):
        # the outer line 3.5 m out at the sensor, closing in by ``closing`` per metre
        outer = right + np.column_stack([np.zeros(len(right)), -3.5 + closing * right[:, 0]])
        ego.detection = LaneDetection(ego_left=det.ego_left, ego_right=right, right_adjacent=outer)
        assert ego.lane_change_available(-1) is available, closing
    # lines seen at no common x within the path range: nothing says the lane closes
    beyond = right + np.array([200.0, -3.5])
    ego.detection = LaneDetection(ego_left=det.ego_left, ego_right=right, right_adjacent=beyond)
    assert ego._target_wide(-1)
    # both lines 1.5 m off the paint: the ego line is carried with no paint seen under
    # it, which gives no leave to cross it, but the chauffeur leaving a lane that ends
    # may (only paint seen continuous stops it)
    off = np.array([0.0, -1.5])
    ego.detection = LaneDetection(
        ego_left=det.ego_left,
        ego_right=right + off,
        right_adjacent=right + off + np.array([0.0, -3.5]),
    )
    assert ego._target_wide(-1) and ego.paint["ego_right"] == 0
    assert not ego.lane_change_available(-1)
    assert ego.lane_change_available(-1, forced=True)
    env.close()
