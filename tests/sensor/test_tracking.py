"""The tracking ALDM (LaneTracker): occlusion, lane change, clutter, settings, the env."""

from __future__ import annotations

import copy
import math
import pickle

import _synthetic as S
import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.sensor import detect_lanes
from aldm_gym.sensor.aldm_kernels import track as K
from aldm_gym.sensor.detectors import ALDMDetector, TrackingALDMDetector, make_detector
from aldm_gym.sensor.tracking import EgoMotion, LaneTracker, TrackerParams, split_params

SPEED = 25.0
DT = 0.1


_err = S.line_error


def _drive_occluded(frames: int = 30, hide_from: int = 10):
    """A 800 m curve at 25 m/s; from frame ``hide_from`` on, the ego-left line's points
    at 25-85 m ahead are missing (a truck 20-40 m ahead in the ego lane)."""
    tracker = LaneTracker()
    motion = EgoMotion(SPEED, SPEED / 800.0, DT)
    for k in range(frames):
        road = S.highway(lanes=4, ego_lane=1, radius=800.0, phase=-SPEED * DT * k)
        pts, _ = S.sample(road, noise=0.02, seed=k)
        if k >= hide_from:
            near = road.lateral_error(road.ego_left, pts[:, :2]) < 0.3
            pts = pts[~(near & (pts[:, 0] >= 25.0) & (pts[:, 0] <= 85.0))]
        yield k, road, pts, tracker.update(pts, None if k == 0 else motion), tracker


def test_occlusion_of_60_m_is_bridged() -> None:
    for k, road, pts, det, tracker in _drive_occluded():
        if k < 10:
            continue
        single = detect_lanes(pts)
        # single-frame: the trace ends before the hidden stretch (longer than 36 m)
        assert single.preview("ego_left") < 30.0
        # tracking: the line runs through the shadow and on, within 15 cm of the truth
        assert det.preview("ego_left") > 150.0, k
        assert _err(road, road.ego_left, det.ego_left) < 0.15, k
        assert _err(road, road.ego_right, det.ego_right) < 0.15, k
        assert tracker.n_prior > 0
        assert tracker.ids == (0, 1, 2, 3)


def _lane_change(frames: int = 70):
    """:func:`_synthetic.lane_change_drive` with a fresh LaneTracker."""
    tracker = LaneTracker()
    for k, lateral, road, pts, det in S.lane_change_drive(
        tracker.update, frames=frames, speed=SPEED, dt=DT
    ):
        yield k, lateral, road, pts, det, tracker


def test_lane_change_keeps_line_identity() -> None:
    first = last = None
    end = 0.0
    for _k, lateral, road, _pts, det, tracker in _lane_change():
        # the true ego lines from the markings' offsets at the sensor
        offsets = np.array([road.curve(j, np.zeros(1))[0, 1] for j in range(5)])
        left = int(np.argmin(np.where(offsets > 0.0, offsets, np.inf)))
        if np.min(np.abs(offsets)) > 0.3:  # not while the sensor is over a line
            assert _err(road, left, det.ego_left) < 0.15
            assert _err(road, left + 1, det.ego_right) < 0.15
        first = first or tracker.ids
        last = tracker.ids
        end = lateral
    assert end == pytest.approx(3.75, abs=0.05)
    la, el, er, _ra = first
    assert -1 not in first
    # one lane to the left: the old left adjacent is the ego left, the old ego left
    # the ego right, the old ego right the right adjacent; the new left adjacent is new
    assert last[1:] == (la, el, er)
    assert last[0] not in first


def test_clutter_contradicting_the_track_is_rejected() -> None:
    """A tar seam 1.1 m inside the left line (road arc 120-220 m) comes into view far
    ahead and reaches the car: single-frame ALDM takes it for the left line when its
    lane-width check is off (``min_lane_width`` below the seam's 1.1 m, so the seam
    and the marking do not compete: the nearest wins) and not with it; the tracker
    drops its points."""
    tracker = LaneTracker()
    motion = EgoMotion(SPEED, 0.0, DT)
    wrong_single = wrong_unchecked = 0
    for k in range(70):
        s0 = SPEED * DT * k
        road = S.highway(lanes=4, ego_lane=1, phase=-s0)
        pts, _ = S.sample(road, noise=0.02, seed=k)
        xs = np.arange(120.0, 220.0, 2.0) + 0.3 - s0
        xs = xs[(xs >= 5.52) & (xs <= 200.0)]
        seam = np.column_stack([xs, np.full(len(xs), road.markings[1].offset - 1.1), 0 * xs])
        pts = np.concatenate([pts, seam])
        det = tracker.update(pts, None if k == 0 else motion)
        assert _err(road, road.ego_left, det.ego_left) < 0.15, k
        assert tracker.ids == (0, 1, 2, 3)
        if len(xs) and xs[0] < 30.0:
            assert tracker.n_rejected >= len(xs) - 2
        wrong_single += _err(road, road.ego_left, detect_lanes(pts).ego_left) > 0.3
        unchecked = detect_lanes(pts, min_lane_width=1.0).ego_left
        wrong_unchecked += _err(road, road.ego_left, unchecked) > 0.3
    assert wrong_unchecked >= 10
    assert wrong_single == 0


def test_deterministic_and_copyable() -> None:
    runs = [[(det, tr.ids) for _k, _r, _p, det, tr in _drive_occluded(frames=16)] for _ in (0, 1)]
    for (a, ia), (b, ib) in zip(*runs, strict=True):
        assert ia == ib
        for name in ("ego_left", "ego_right", "left_adjacent", "right_adjacent", "trajectory"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    *_, tracker = next(_drive_occluded(frames=1))
    clone = pickle.loads(pickle.dumps(tracker))
    road = S.highway(lanes=4, ego_lane=1, radius=800.0, phase=-SPEED * DT)
    pts, _ = S.sample(road, noise=0.02, seed=1)
    motion = EgoMotion(SPEED, SPEED / 800.0, DT)
    a = copy.deepcopy(tracker).update(pts, motion)
    b = clone.update(pts, motion)
    np.testing.assert_array_equal(a.ego_left, b.ego_left)


def test_reset_and_no_motion_restart() -> None:
    *_, tracker = list(_drive_occluded(frames=3))[-1]
    assert tracker.ids == (0, 1, 2, 3)
    tracker.reset()
    road = S.highway(lanes=4, ego_lane=1)
    pts, _ = S.sample(road, seed=3)
    det = tracker.update(pts, None)
    np.testing.assert_array_equal(det.ego_left, detect_lanes(pts).ego_left)
    assert tracker.ids == (4, 5, 6, 7) and tracker.n_prior == 0


def test_kernels_match_plain_python() -> None:
    """The compiled kernels against their plain-Python twins on a bridged frame."""
    frames = list(_drive_occluded(frames=12))
    *_, tracker = frames[-2]
    _k, _road, pts, _det, _ = frames[-1]
    motion = EgoMotion(SPEED, SPEED / 800.0, DT)
    disp = motion.displacement()
    args = (tracker._lines, tracker._ls, *disp)
    for a, b in zip(K.track_table(*args), K.track_table_py(*args), strict=True):
        np.testing.assert_array_equal(a, b)
    table = K.track_table(*args)[0]
    pargs = (pts, table, np.ones(4, dtype=bool), 0.25, 0.001, 20.0, 4.0, 5.0, 0.5, 60.0)
    for got, want in zip(K.track_prior(*pargs), K.track_prior_py(*pargs), strict=True):
        np.testing.assert_array_equal(got, want)
    # a frame whose hidden line is continued beside its neighbour
    tracker = LaneTracker()
    for k, _road, pts in _hidden_frames(8):
        if k < 7:
            tracker.update(pts, None if k == 0 else HIDDEN_MOTION)
    table = K.track_table(tracker._lines, tracker._ls, *HIDDEN_MOTION.displacement())[0]
    pargs = (pts, table, np.ones(4, dtype=bool), 0.25, 0.001, 20.0, 4.0, 5.0, 0.5, 60.0)
    got, want = K.track_prior(*pargs), K.track_prior_py(*pargs)
    assert np.count_nonzero(got[1] > 60.0) >= 5
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def test_settings_and_registry() -> None:
    assert isinstance(make_detector("aldm"), ALDMDetector)
    assert isinstance(make_detector("aldm", {"tracking": False}), ALDMDetector)
    det = make_detector("aldm", {"tracking": True, "bridge_gap": 24.0, "gate_max": 1.0})
    assert isinstance(det, TrackingALDMDetector)
    assert det.tracker.tracker.bridge_gap == 24.0 and det.tracker.params.gate_max == 1.0
    with pytest.raises(ValueError, match="bridge_gapp"):
        make_detector("aldm", {"tracking": True, "bridge_gapp": 1.0})
    with pytest.raises(ValueError, match=r"track_gate must be > 0"):
        make_detector("aldm", {"tracking": True, "track_gate": -1.0})
    with pytest.raises(ValueError, match="need tracking=True"):
        make_detector("aldm", {"coast_length": 10.0})
    with pytest.raises(ValueError, match=r"aldm\.tracking"):
        split_params({"tracking": "yes"})
    with pytest.raises(ValueError, match=r"motion\.dt"):
        EgoMotion(20.0, 0.0, 0.0)
    with pytest.raises(ValueError, match=r"tracker\.bridge_step"):
        TrackerParams(bridge_step=0.0)
    with pytest.raises(TypeError, match="EgoMotion"):
        LaneTracker().update(np.zeros((0, 2)), (20.0, 0.0, 0.1))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="bridge_gapp"):
        gym.make("ALDMHighway-v0", config={"detector_params": {"tracking": True, "bridge_gapp": 1}})


def test_env_tracking_determinism_pickle_and_reset() -> None:
    cfg = {"detector_params": {"tracking": True}, "vehicles_count": 5, "duration": 3}

    def run():
        env = gym.make("ALDMHighway-v0", config=cfg)
        env.reset(seed=3)
        obs = [env.step(1)[0] for _ in range(4)]
        return env, obs

    env, a = run()
    _, b = run()
    for x, y in zip(a, b, strict=True):
        for key in x:
            np.testing.assert_array_equal(x[key], y[key])
    base = env.unwrapped
    assert isinstance(base._detector, TrackingALDMDetector)
    assert base._detector.tracker.ids[1:3] != (-1, -1)
    clone = pickle.loads(pickle.dumps(base))
    twin = copy.deepcopy(base)
    want = base.step(1)[0]
    for other in (clone, twin):
        got = other.step(1)[0]
        for key in want:
            np.testing.assert_array_equal(got[key], want[key])
    old = base._detector
    env.reset(seed=4)
    assert base._detector is not old
    assert base._detector.tracker._next_id <= 4  # a fresh tracker: no ids carried over
    env.close()


class _Recorder:
    """A detector wrapper keeping every (frame, lane, motion) the env passes."""

    uses_motion = True

    def __init__(self, inner) -> None:
        self.inner = inner
        self.calls: list = []

    def __call__(self, frame, road=None, lane_id=0, motion=None):
        self.calls.append((frame, lane_id, motion))
        return self.inner(frame, road, lane_id, motion=motion)


def test_env_odometry_carries_the_last_frame_onto_this_one() -> None:
    """The env's ego motion, applied as the tracker applies it, moves the last frame's
    true lines onto this frame's (to 2 cm at 120 m) in left and right bends: the yaw
    rate is the sensor frame's (ISO 8855, left positive), not highway-env's heading
    change (which grows clockwise)."""
    from aldm_gym.sensor.ground_truth import ground_truth_detect

    turns = {-1: 0, 1: 0}
    # a right bend, a left bend, and a sensor mounted 0.8 m left of the car's axis
    for road_seed, mount_y in ((0, 0.0), (1, 0.0), (0, 0.8)):
        env = gym.make(
            "ALDMHighway-v0",
            config={
                "detector_params": {"tracking": True},
                "vehicles_count": 0,
                "duration": 12,
                "road": {"seed": road_seed, "min_radius": 300.0, "max_radius": 400.0},
                "sensor": {"mount_y": mount_y},
            },
        )
        env.reset(seed=0)
        base = env.unwrapped
        rec = base._detector = _Recorder(base._detector)
        for _ in range(12):
            env.step(1)
        env.close()
        for (f0, lane0, _), (f1, lane1, motion) in zip(rec.calls, rec.calls[1:], strict=False):
            if motion is None or lane0 != lane1:
                continue
            a = ground_truth_detect(base.highway, f0, lane0).ego_left
            b = ground_truth_detect(base.highway, f1, lane1).ego_left
            moved = K.track_table(a, np.array([0, len(a)]), *motion.displacement())[0][0]
            xs = np.arange(20.0, 121.0, 10.0)
            grid = np.arange(len(moved)) * K.TABLE_STEP
            err = np.interp(xs, grid, moved) - np.interp(xs, *b.T)
            assert np.max(np.abs(err)) < 0.02, (motion, err)
            if abs(motion.yaw_rate) > 0.02:
                turns[int(np.sign(motion.yaw_rate))] += 1
    assert turns[-1] > 0 and turns[1] > 0, turns


HIDDEN_MOTION = EgoMotion(SPEED, -SPEED / 500.0, DT)


def _hidden_frames(frames: int = 30):
    """A 500 m right bend; the car ahead hides the ego-left line beyond 45 m in every
    frame while the other lines are seen to the end."""
    for k in range(frames):
        road = S.highway(lanes=3, ego_lane=1, radius=-500.0, phase=-SPEED * DT * k)
        pts, _ = S.sample(road, noise=0.02, seed=k)
        near = road.lateral_error(road.ego_left, pts[:, :2]) < 0.3
        yield k, road, pts[~(near & (pts[:, 0] >= 45.0))]


def test_line_hidden_behind_the_car_ahead_continues_beside_the_others() -> None:
    """Single-frame ALDM ends the hidden ego-left line at 45 m; the tracker continues
    it parallel to its neighbour (along the normal, not a constant lateral shift) to
    a preview past 80 m, within 15 cm."""
    tracker = LaneTracker()
    for k, road, pts in _hidden_frames():
        det = tracker.update(pts, None if k == 0 else HIDDEN_MOTION)
        if k < 5:
            continue
        assert detect_lanes(pts).preview("ego_left") < 46.0
        assert det.preview("ego_left") > 80.0, k
        assert _err(road, road.ego_left, det.ego_left) < 0.15, k
        assert _err(road, road.ego_right, det.ego_right) < 0.15, k
        assert tracker.ids[1:3] == (1, 2)


def _branching(k: int, worn: bool = True):
    """A straight 3-lane road at 25 m/s; an old marking branches off the ego-left line
    120 m ahead of the first frame (world-fixed) and runs 60 m into the ego lane at
    3 degrees, where the ego-left line's paint is worn away."""
    s_b = 120.0 - SPEED * DT * k
    road = S.highway(lanes=3, ego_lane=1, phase=-SPEED * DT * k)
    left = road.markings[1]
    tail = S.SynthMarking(left.offset, dashed=True, phase=left.phase, start_s=s_b + 60.0)
    left.end_s = s_b if worn else np.inf
    slope = -math.tan(math.radians(3.0))
    old = S.SynthMarking(
        left.offset,
        taper_s=(s_b, s_b + 60.0),
        taper_d=(left.offset, left.offset + 60.0 * slope),
        start_s=s_b,
        end_s=s_b + 60.0,
    )
    road.markings += [tail, old]
    return road


def test_old_marking_branching_off_is_not_followed() -> None:
    """An old marking branches off the ego-left line at 3 degrees where its paint is
    worn: single-frame ALDM follows it and ends up on the ego-right line (3.8 m off)
    in every frame; the tracker's left line stays within 0.4 m of the truth (the
    lanes' common shape and the tracks' gate; the old marking still pulls the
    smoothed line by up to 0.38 m where it is within the gate) with its preview."""
    tracker = LaneTracker()
    motion = EgoMotion(SPEED, 0.0, DT)
    single_wrong = 0
    for k in range(40):
        road = _branching(k)
        pts, _ = S.sample(road, noise=0.02, seed=k)
        det = tracker.update(pts, None if k == 0 else motion)
        single_wrong += _err(road, road.ego_left, detect_lanes(pts).ego_left) > 1.0
        if k >= 1:
            assert _err(road, road.ego_left, det.ego_left) < 0.4, k
            assert det.preview("ego_left") > 150.0, k
    assert single_wrong == 40
    assert tracker.n_held > 0


def test_consensus_pulls_a_straying_track_back() -> None:
    """consensus on tabulated tracks: four parallel lines of a 600 m bend (farther
    apart in y where they turn: not moved), one bent 0.8 m off beyond 100 m, is set
    back onto the common shape (the others untouched); of two lines parting, nothing
    says which strays: both end where they part; one line alone stays."""
    x = np.arange(0.0, 151.0, K.TABLE_STEP)
    radius = 600.0  # a left bend: concentric circles about (0, radius)
    table = np.array(
        [radius - np.sqrt((radius - off) ** 2 - x**2) for off in (5.6, 1.9, -1.9, -5.6)]
    )
    assert K.consensus(table.copy(), np.zeros(4), 0.05, 0.0) == 0
    bent = table.copy()
    bent[1, x > 100.0] += 0.8
    want = bent.copy()
    assert K.consensus(bent, np.zeros(4), 0.2, 0.0) == np.count_nonzero(x > 100.0)
    np.testing.assert_allclose(bent[1], table[1], atol=0.01)
    np.testing.assert_array_equal(bent[[0, 2, 3]], want[[0, 2, 3]])
    two = want[:2].copy()  # two lines part beyond 100 m: which one strays? both end
    far = x > 100.0
    assert K.consensus(two, np.zeros(2), 0.2, 0.0) == 2 * np.count_nonzero(far)
    assert np.isnan(two[:, far]).all()
    np.testing.assert_array_equal(two[:, ~far], want[:2, ~far])
    one = want[1:2].copy()
    assert K.consensus(one, np.zeros(1), 0.2, 0.0) == 0
    again = want.copy()
    assert K.consensus_py(again, np.zeros(4), 0.2, 0.0) == np.count_nonzero(x > 100.0)
    np.testing.assert_array_equal(again, bent)


def test_hold_sets_or_ends_straying_lines() -> None:
    """hold_to_consensus on detected lines (13 vertices each, as the ALDM returns them): a line
    bent 0.8 m off beyond 100 m among three takes the common shape there; of two
    lines parting, both lose their vertices beyond; compiled and plain Python agree."""
    x = np.linspace(6.0, 150.0, 13)
    lines = [np.column_stack([x, np.full(13, off)]) for off in (5.6, 1.9, -1.9)]
    lines[1][x > 100.0, 1] += 0.8
    cat = np.concatenate(lines)
    ls = np.array([0, 13, 26, 39])
    out, out_ls, moved = K.hold_to_consensus(cat, ls, 0.2, 0.0)
    assert moved
    np.testing.assert_array_equal(out_ls, ls)
    np.testing.assert_allclose(out[13:26, 1], 1.9, atol=1e-12)
    np.testing.assert_array_equal(
        out[[*range(13), *range(26, 39)]], cat[[*range(13), *range(26, 39)]]
    )
    two = np.concatenate(lines[1:])
    out2, ls2, moved2 = K.hold_to_consensus(two, np.array([0, 13, 26]), 0.2, 0.0)
    assert moved2 and list(ls2) == [0, 8, 16]  # the vertices up to 90 m
    assert out2[:, 0].max() < 100.0
    for args in ((cat, ls, 0.2, 0.0), (two, np.array([0, 13, 26]), 0.2, 0.0)):
        for a, b in zip(K.hold_to_consensus(*args), K.hold_to_consensus_py(*args), strict=True):
            np.testing.assert_array_equal(a, b)
    same = K.hold_to_consensus(cat[:13].copy(), np.array([0, 13]), 0.2, 0.0)
    assert not same[2]


def test_table_samples_the_lines_parabolas() -> None:
    """track_table (Newton's form, once per segment) gives _interp_line_py's parabola at
    every sample, for a curved line starting 17 m ahead (extrapolated to x = 0), a
    two-vertex line and a moved frame; NaN beyond each line's end."""
    x = np.linspace(17.0, 190.0, 13)
    curved = np.column_stack([x, 1.9 + x**2 / 1600.0 + 0.01 * np.sin(x)])
    short = np.array([[10.0, -1.8], [40.0, -1.7]])
    lines = np.concatenate([curved, short])
    ls = np.array([0, 13, 15])
    for motion in ((0.0, 0.0, 0.0), (2.5, 0.01, 0.003)):
        table, first = K.track_table(lines, ls, *motion)
        np.testing.assert_array_equal(table, K.track_table_py(lines, ls, *motion)[0])
        np.testing.assert_array_equal(first, K.track_table_py(lines, ls, *motion)[1])
        c, s = math.cos(motion[2]), math.sin(motion[2])
        for t in range(2):
            seg = lines[ls[t] : ls[t + 1]] - motion[:2]
            px, py = c * seg[:, 0] + s * seg[:, 1], -s * seg[:, 0] + c * seg[:, 1]
            for g in range(table.shape[1]):
                want = K._interp_line_py(px, py, 0, len(px), g * K.TABLE_STEP)
                if math.isnan(want):
                    assert math.isnan(table[t, g])
                else:
                    assert abs(table[t, g] - want) < 1e-9, (t, g)


def test_consensus_offsets_from_own_samples() -> None:
    """A line starting 40 m ahead, its first vertex 8 cm off, is not moved: its
    distance to the others is measured on its own samples, not on its extrapolation
    back to the sensor (which took it 0.3 m off over 150 m before)."""
    x = np.linspace(6.0, 184.0, 13)
    far = np.linspace(40.0, 184.0, 13)
    lines = [np.column_stack([x, np.full(13, 1.9)]), np.column_stack([x, np.full(13, -1.9)])]
    third = np.column_stack([far, np.full(13, -5.6)])
    third[0, 1] += 0.08
    cat = np.concatenate([*lines, third])
    out, _, moved = K.hold_to_consensus(cat, np.array([0, 13, 26, 39]), 0.2, 0.0)
    assert not moved and out is cat


def test_continuation_is_not_carried_by_a_stray_point() -> None:
    """Three straight tracks; the middle one (tabulated to 40 m) has points to 39 m,
    the others are seen to 190 m; one stray point lies on the middle line at 170 m.
    Prior points continue the middle line beside its neighbour at most tail_length
    (60 m) beyond its last point: to 99 m, not to the stray point."""
    g = np.arange(0.0, 201.0, K.TABLE_STEP)
    table = np.array([np.full(len(g), 3.75), np.zeros(len(g)), np.full(len(g), -3.75)])
    table[1, g > 40.0] = np.nan  # last frame's middle line ended at 40 m
    xs = np.arange(6.0, 191.0, 2.0)
    pts = [np.column_stack([xs, np.full(len(xs), 3.75)])]
    pts.append(np.column_stack([xs[xs <= 39.0], np.zeros(np.count_nonzero(xs <= 39.0))]))
    pts.append(np.column_stack([xs, np.full(len(xs), -3.75)]))
    pts.append(np.array([[170.0, 0.0]]))
    cloud = np.concatenate(pts)
    args = (cloud, table, np.ones(3, dtype=bool), 0.25, 0.001, 20.0, 4.0, 5.0, 0.5, 60.0)
    _, vx, vy, _ = K.track_prior(*args)
    mid = np.abs(vy) < 0.5
    assert vx[mid].min() > 39.0 and 95.0 <= vx[mid].max() <= 39.0 + 60.0 + 1e-9
    for a, b in zip(K.track_prior(*args), K.track_prior_py(*args), strict=True):
        np.testing.assert_array_equal(a, b)


def test_tracker_settings_that_would_do_nothing_are_refused() -> None:
    with pytest.raises(
        ValueError, match=r"tail_length must be 0 \(no continuation\) or > bridge_gap"
    ):
        TrackerParams(tail_length=15.0)
    with pytest.raises(ValueError, match="consensus_tol_slope needs consensus_tol > 0"):
        TrackerParams(consensus_tol=0.0, consensus_tol_slope=0.01)
    assert TrackerParams(tail_length=0.0, consensus_tol=0.0).tail_length == 0.0
