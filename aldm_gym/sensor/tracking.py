"""The tracking ALDM: lanes carried from frame to frame by odometry.

The stateless :func:`~aldm_gym.sensor.aldm.detect_lanes` sees one frame. A marking
hidden behind a truck, or worn away, for longer than its gap search (36 m) ends the
line there, and clutter near the car can be taken for a line. :class:`LaneTracker`
keeps the last frame's lines as *tracks*, moves them into the new sensor frame by the
ego's motion (speed and yaw rate over the frame's time step, :class:`EgoMotion`), and
uses them as the prior of the next detection:

* lanes are parallel: a track straying from the common shape of the others (it
  followed clutter far ahead) is set back onto it;
* points within a gate of a track support it; points inside a tracked lane that
  support no track contradict the track and are dropped (clutter);
* along a track, stretches without support longer than ``bridge_gap`` (an
  occlusion, worn paint), and the start region up to its first supported point, get
  *prior points* on the moved track, so the ALDM's start condition and trace run
  through them and continue on the measured points beyond; beyond its last
  supported point a track goes on parallel to a neighbour seen farther (the car
  ahead hides the ego lane's lines, not the lane beside);
* the detected lines are held to their common shape once more (clutter beyond
  the tracks' reach);
* each detected line takes the identity of the track it continues (mean lateral
  distance), so a marking keeps its id through a lane change while its role changes
  (crossing the ego-left line to the left makes it the ego-right line).

The detection itself is the unchanged ALDM on the filtered points plus the prior
points. The decisions are listed in ``docs/aldm.md``, section "Tracking"; the
kernels are in :mod:`aldm_gym.sensor.aldm_kernels.track`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.config import build_config, check_keys, setting, validate
from aldm_gym.errors import ConfigError
from aldm_gym.sensor.aldm import ALDMParams, as_points, detect_lanes_checked, make_params
from aldm_gym.sensor.aldm_kernels.track import (
    consensus,
    hold_to_consensus,
    match_tracks,
    track_prior,
    track_table,
)
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection
from aldm_gym.sensor.trajectory import PATH_STEP, driving_trajectory, fit_reach

MIN_SUPPORT = 3
"""A track counts as measured in a frame when at least this many points support it
(one or two could be specks of clutter within the gate)."""


@dataclass(frozen=True)
class EgoMotion:
    """The sensor's motion since the previous frame: constant speed and yaw rate.

    :ivar speed: distance travelled over ``dt`` divided by ``dt`` [m/s].
    :ivar yaw_rate: heading change over ``dt`` divided by ``dt``, left positive [rad/s].
    :ivar dt: time since the previous frame [s].
    """

    speed: float = setting(0.0, lo=-200.0, hi=200.0)
    yaw_rate: float = setting(0.0, lo=-10.0, hi=10.0)
    dt: float = setting(0.1, lo=0.0, lo_open=True, hi=10.0)

    def __post_init__(self) -> None:
        validate(self, "motion")

    @property
    def travel(self) -> float:
        """Distance travelled [m]."""
        return abs(self.speed) * self.dt

    def displacement(self) -> tuple[float, float, float]:
        """``(dx, dy, dpsi)``: the new sensor origin in the old frame [m] and the
        heading change [rad], on a circular arc (constant speed and yaw rate)."""
        dpsi = self.yaw_rate * self.dt
        dist = self.speed * self.dt
        if abs(dpsi) < 1e-9:
            return dist, 0.5 * dist * dpsi, dpsi
        # chord of the arc: length 2 R sin(dpsi / 2), direction dpsi / 2
        chord = dist * math.sin(0.5 * dpsi) / (0.5 * dpsi)
        return chord * math.cos(0.5 * dpsi), chord * math.sin(0.5 * dpsi), dpsi


def odometry(
    last: tuple[float, float, float] | None, pose: tuple[float, float, float], dt: float
) -> EgoMotion | None:
    """The sensor's motion between two world poses, as odometry would give it.

    :param last: the previous sensor pose ``(x [m], y [m], heading [rad])`` in
        highway-env's world (``None``: no previous frame).
    :param pose: the current one.
    :param dt: time between them [s].
    :return: the motion, or ``None`` without a previous pose, for a ``dt`` not > 0, or
        after an implausible jump (faster than 200 m/s or turning faster than 10 rad/s).
    """
    if last is None or not dt > 0.0:
        return None
    speed = math.hypot(pose[0] - last[0], pose[1] - last[1]) / dt
    # highway-env's heading grows clockwise (its y axis points right of x): the
    # sensor frame's yaw (ISO 8855, left positive) turns the other way
    turn = -((pose[2] - last[2] + math.pi) % (2.0 * math.pi) - math.pi)
    if speed > 200.0 or abs(turn / dt) > 10.0 or dt > 10.0:
        return None
    return EgoMotion(speed, turn / dt, dt)


@dataclass(frozen=True)
class TrackerParams:
    """Parameters of :class:`LaneTracker` (lengths [m]).

    :ivar track_gate: a point supports a track when its lateral residual to the
        moved track is within ``track_gate + track_gate_slope * x`` ...
    :ivar track_gate_slope: ... the gate's growth with the distance ahead x [m/m]
        (an error of the odometry's heading grows with x).
    :ivar bridge_gap: stretches of a track without support longer than this get
        prior points (the longest gap of a dashed line, 12 m plus a dropped 2 m
        sample and noise, stays below it).
    :ivar bridge_step: spacing of the prior points (below the ALDM's ``link_dx``,
        4.5 m, so that they chain in its start region).
    :ivar coast_length: a track no points support is carried at most this far
        (travelled distance) before it is given up.
    :ivar tail_length: beyond a track's last supported point, prior points continue
        it, parallel to a neighbour seen farther, at most this far beyond a point
        supporting it or its continuation (0: no continuation; else > bridge_gap).
    :ivar consensus_tol: a track or detected line farther than this from the lanes'
        common shape is set onto it (0: lanes are not held parallel) ...
    :ivar consensus_tol_slope: ... plus this much per metre ahead [m/m].
    :ivar match_gate: a detected line continues a track when their mean lateral
        distance is below this (well below a lane width).
    """

    track_gate: float = setting(0.25, lo=0.0, lo_open=True, hi=10.0)
    track_gate_slope: float = setting(0.001, lo=0.0, hi=1.0)
    bridge_gap: float = setting(20.0, lo=0.0, lo_open=True, hi=1000.0)
    bridge_step: float = setting(4.0, lo=0.1, hi=100.0)
    coast_length: float = setting(60.0, lo=0.0, hi=1.0e4)
    tail_length: float = setting(60.0, lo=0.0, hi=1000.0)
    consensus_tol: float = setting(0.2, lo=0.0, hi=10.0)
    consensus_tol_slope: float = setting(0.0, lo=0.0, hi=1.0)
    match_gate: float = setting(1.0, lo=0.0, lo_open=True, hi=10.0)

    def __post_init__(self) -> None:
        validate(self, "tracker")
        if 0.0 < self.tail_length <= self.bridge_gap:
            raise ConfigError(
                f"tracker.tail_length must be 0 (no continuation) or > bridge_gap "
                f"({self.bridge_gap}), got {self.tail_length}: a shorter tail is never filled"
            )
        if self.consensus_tol == 0.0 and self.consensus_tol_slope > 0.0:
            raise ConfigError(
                "tracker.consensus_tol_slope needs consensus_tol > 0 "
                "(consensus_tol=0 turns the lanes' common shape off)"
            )


TRACKER_KEYS: tuple[str, ...] = ("tracking", *TrackerParams.__dataclass_fields__)
"""The ``detector_params`` keys of the tracker (the others are :class:`ALDMParams` and
the lane-model filter's)."""

TRACKING_CHOICES: tuple[bool | str, ...] = (False, True, "model")
"""Values of ``detector_params["tracking"]``: single frame, the point-level
:class:`LaneTracker`, the lane-model filter
(:class:`~aldm_gym.sensor.lane_filter.LaneModelFilter`)."""


def split_params(params: dict[str, Any]) -> tuple[bool, TrackerParams, ALDMParams]:
    """``detector_params`` of ``"aldm"`` -> ``(tracking, tracker params, ALDM params)``.

    ``tracking="model"`` (the lane-model filter) and all three together are parsed by
    :func:`~aldm_gym.sensor.lane_filter.split_aldm_params`.

    :raises ConfigError: an unknown key (naming the allowed ones), a bad value, a
        ``tracking`` other than true or false, or tracker settings without
        ``tracking=True``.
    """
    check_keys("aldm config", params, {*ALDMParams.__dataclass_fields__, *TRACKER_KEYS})
    tracking = params.get("tracking", False)
    if isinstance(tracking, str) and tracking == "model":
        raise ConfigError(
            "aldm.tracking='model' (the lane-model filter) is parsed by "
            "aldm_gym.sensor.lane_filter.split_aldm_params; this parser takes true or false"
        )
    if not isinstance(tracking, (bool, np.bool_)):
        raise ConfigError(
            f"aldm.tracking must be one of {list(TRACKING_CHOICES)} (False: single frame, "
            f"True: the point-level tracker, 'model': the lane-model filter), got {tracking!r}"
        )
    track = {k: v for k, v in params.items() if k in TrackerParams.__dataclass_fields__}
    if track and not tracking:
        raise ConfigError(f"aldm settings {sorted(track)} need tracking=True")
    aldm = {k: v for k, v in params.items() if k not in TRACKER_KEYS}
    return (
        bool(tracking),
        build_config(TrackerParams, track, where="aldm"),
        make_params(None, **aldm),
    )


class LaneTracker:
    """The ALDM with memory: the last lines, moved by odometry, as the next prior.

    Call :meth:`update` once per frame with the points and the motion since the
    previous frame; :meth:`reset` forgets the tracks (a new episode). Deterministic
    (no randomness) and picklable.

    :param params: the ALDM's parameters (:class:`ALDMParams`; default robust).
    :param tracker: the tracker's (:class:`TrackerParams`).
    :param path_range: the trajectory's fit range [m], as for
        :func:`~aldm_gym.sensor.aldm.detect_lanes`.
    """

    def __init__(
        self,
        params: ALDMParams | None = None,
        tracker: TrackerParams | None = None,
        *,
        path_range: float | None = None,
    ) -> None:
        self.params = make_params(params)
        self.tracker = tracker if tracker is not None else TrackerParams()
        if not isinstance(self.tracker, TrackerParams):
            raise TypeError(f"tracker must be TrackerParams, got {type(self.tracker).__name__}")
        self.path_range = path_range
        self._next_id = 0
        self.reset()

    def reset(self) -> None:
        """Forget every track (the next frame is detected without a prior)."""
        self._lines = np.zeros((0, 2))
        self._ls = np.zeros(len(LINE_NAMES) + 1, dtype=np.int64)
        self._coast = np.zeros(len(LINE_NAMES))
        self._ids = np.full(len(LINE_NAMES), -1, dtype=np.int64)
        self.n_prior = 0
        """Prior points added in the last frame."""
        self.n_rejected = 0
        """Points dropped as contradicting the tracks in the last frame."""
        self.n_held = 0
        """Frames whose lines were held to their common shape since the reset."""

    @property
    def ids(self) -> tuple[int, ...]:
        """Track id of each line of the last detection, in :data:`LINE_NAMES` order
        (-1: not found). A marking keeps its id from frame to frame."""
        return tuple(int(i) for i in self._ids)

    def update(self, points: Any, motion: EgoMotion | None) -> LaneDetection:
        """Detect the lanes of one frame with the tracks as prior.

        :param points: ``(N, 2|3)`` points in the sensor frame [m], or a sensor
            frame (as for :func:`~aldm_gym.sensor.aldm.detect_lanes`).
        :param motion: the sensor's motion since the previous frame; ``None``
            restarts the tracks (without odometry the old lines cannot be placed).
        """
        pts = as_points(points)
        if motion is not None and not isinstance(motion, EgoMotion):
            raise TypeError(f"motion must be EgoMotion or None, got {type(motion).__name__}")
        if motion is None or self._ls[-1] == 0:
            det, _, lines, ls = detect_lanes_checked(pts, self.params, self.path_range)
            self.n_prior = self.n_rejected = 0
            self._lines, self._ls = lines.copy(), ls
            self._ids = np.full(len(LINE_NAMES), -1, dtype=np.int64)
            for i in range(len(LINE_NAMES)):
                if self._ls[i + 1] - self._ls[i] >= 2:
                    self._ids[i] = self._next_id
                    self._next_id += 1
            self._coast = np.zeros(len(LINE_NAMES))
            return det
        tp = self.tracker
        travel = motion.travel
        table, first = track_table(self._lines, self._ls, *motion.displacement())
        if tp.consensus_tol > 0.0:
            consensus(table, first, tp.consensus_tol, tp.consensus_tol_slope)
        keep, vx, vy, support = track_prior(
            pts,
            table,
            self._coast <= tp.coast_length - travel,
            tp.track_gate,
            tp.track_gate_slope,
            tp.bridge_gap,
            tp.bridge_step,
            self.params.max_lane_width,
            self.params.z_band,
            tp.tail_length,
        )
        self.n_prior = n_prior = len(vx)
        self.n_rejected = len(keep) - int(np.count_nonzero(keep))
        cloud = pts if self.n_rejected == 0 else pts[keep]
        if n_prior:
            prior = np.zeros((n_prior, pts.shape[1]))
            prior[:, 0] = vx
            prior[:, 1] = vy
            cloud = np.concatenate((cloud, prior))
        det, width, lines, ls = detect_lanes_checked(cloud, self.params, self.path_range)
        if tp.consensus_tol > 0.0 and ls[-1] > 0:
            det, lines, ls = self._hold_together(det, lines, ls, width)
        self._ids, self._coast, self._next_id = match_tracks(
            lines,
            ls,
            table,
            tp.match_gate,
            self._ids,
            self._coast,
            support,
            travel,
            MIN_SUPPORT,
            self._next_id,
        )
        # a copy: the returned detection's lines are views of `lines`
        self._lines, self._ls = lines.copy(), ls
        return det

    def _hold_together(
        self, det: LaneDetection, lines: np.ndarray, ls: np.ndarray, width: float
    ) -> tuple[LaneDetection, np.ndarray, np.ndarray]:
        """The detection's lines held to their common shape (:func:`hold_to_consensus`): where a
        line strays from it (far ahead, on clutter no track reached yet) its points
        are set onto it, where two lines part both end, and the trajectory follows."""
        tp = self.tracker
        out, ls, moved = hold_to_consensus(lines, ls, tp.consensus_tol, tp.consensus_tol_slope)
        if not moved:
            return det, lines, ls
        fields = {name: out[ls[i] : ls[i + 1]] for i, name in enumerate(LINE_NAMES)}
        traj = driving_trajectory(
            fields["ego_left"], fields["ego_right"], width, PATH_STEP, fit_reach(self.path_range)
        )
        self.n_held += 1
        return LaneDetection.trusted(**fields, trajectory=traj, source="aldm"), out, ls


__all__ = [
    "MIN_SUPPORT",
    "TRACKER_KEYS",
    "TRACKING_CHOICES",
    "EgoMotion",
    "LaneTracker",
    "TrackerParams",
    "split_params",
]
