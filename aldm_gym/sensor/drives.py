"""Drives along map lanes: the lane detectors scored frame after frame.

A detector with memory (the point tracker, the lane-model filter) is only as good as
its worst stretch of road, so it is measured on sequences, not on independent poses.
A *drive* puts the ego on the centre of a chain of driving lanes of an OpenDRIVE map
(:meth:`OpenDriveRoad.successor <aldm_gym.roads.OpenDriveRoad.successor>` from the
lane it starts on), a frame every ``dt`` at ``speed``, and feeds each detector the
line sensor's frame and the odometry between frames
(:func:`~aldm_gym.sensor.tracking.odometry`). Road-fixed conditions stay where they
are (a worn dash is worn in every frame that sees it: the sensor's wear is keyed by
the road, :mod:`aldm_gym.sensor.conditions`), and vehicles move
(:func:`traffic`): one ahead in the ego's lane, whose gap breathes between 18 m and
60 m (it hides the ego's lines beyond roughly 25–125 m), and three in the lanes beside,
passing and being passed.

Each frame is scored as :func:`~aldm_gym.sensor.ground_truth.score_detection` scores
the env's detections (every point within 0.3 m of the true marking, starting within
25 m, a preview of 60 m). Frames whose ground-truth detection is not itself correct
(a line that ends within the preview, the map's end) are not scored, nor frames where
the ego's lane is narrower where the ego is than the ALDM's default smallest plausible
lane (:attr:`~aldm_gym.sensor.aldm.ALDMParams.min_lane_width`, 2.5 m): a drive along a
lane that opens from nothing (a 2+1 road's passing lane) starts at the tip of its
taper, where no driver is in a lane yet and no detector is asked for one. Per detector:
the share of frames with both ego lines correct, the longest run of consecutive
scored frames with either wrong [s], and the share of ego lines missing.

What a detector could know is measured beside it (:class:`SeenPaint`): a frame is
*observed* when each ego line's paint has been measured, in that frame or an earlier
one, within :data:`OBSERVED_PERIOD` of the preview. In a frame that is not, a car
ahead has hidden the lines 40–60 m ahead since they came into view, and a detector
that draws them there draws its road model, not a measurement. The share of observed
frames, and each detector's longest wrong run within observed frames (an unobserved
frame ends a run), say which wrong runs are the detector's and which the sensor's.

``benchmarks/lane_sequences.py`` runs the maps × conditions table
(:data:`CONDITIONS`); docs/aldm.md, "Lane-model filter", reports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.sensor.aldm import ALDMParams, detect_lanes
from aldm_gym.sensor.ground_truth import (
    boundary_y,
    ground_truth_detect,
    line_markings,
    score_detection,
    true_markings,
)
from aldm_gym.sensor.lane_filter import LaneModelFilter
from aldm_gym.sensor.line_sensor import LineSensor
from aldm_gym.sensor.tracking import LaneTracker, odometry
from aldm_gym.types import FloatArray

SPEED = 25.0
"""The ego's speed along its lane [m/s]."""

DT = 0.1
"""Time between frames [s]."""

DETECTORS: tuple[str, ...] = ("single_frame", "filter", "tracker")
"""The detectors a drive scores: the single-frame ALDM
(:func:`~aldm_gym.sensor.aldm.detect_lanes`), the lane-model filter
(:class:`~aldm_gym.sensor.lane_filter.LaneModelFilter`) and the point tracker
(:class:`~aldm_gym.sensor.tracking.LaneTracker`)."""

CAR = (4.5, 1.8, 1.5)
"""A car's length, width and height [m]."""

TRUCK = (12.0, 2.55, 3.8)
"""A truck's [m]."""


# (lateral offset in lanes, left positive; gap at t = 0 [m]; speed relative to the
# ego [m/s]; breathing amplitude [m], 0: none). The first is the car close ahead.
_SCHEDULE: tuple[tuple[float, float, float, float], ...] = (
    (0.0, 39.0, 0.0, 21.0),
    (1.0, 40.0, -2.0, 0.0),
    (-1.0, -10.0, 1.5, 0.0),
    (1.0, 120.0, -1.0, 0.0),
)
PREVIEW_MIN = 60.0
"""The preview a correct line reaches [m] (the score's ``preview_min``)."""

OBSERVED_PERIOD = 18.0
"""A line is observed to the preview (60 m) when paint of it was measured at or beyond
this much short of it [m]: one dash and its gap on a motorway (6 m + 12 m; shorter on
other roads), so that on a dashed line no painted stretch up to the preview went
unseen."""

SEEN_CELL = 0.5
"""The measured paint is kept road-fixed on a grid of this size [m] (world x, y): a
drive's memory is bounded by the road ahead, not by its frames."""

SEEN_TOL = 0.3
"""A measured point is paint of a true line within this lateral distance [m] (the
score's tolerance)."""

_BREATH_PERIOD = 20.0  # [s]
_WRAP = (-40.0, 200.0)  # a vehicle leaving this gap range comes back at the other end


@dataclass(frozen=True)
class Condition:
    """What the sensor sees on a drive.

    :ivar sensor: :class:`~aldm_gym.sensor.LineSensor` settings.
    :ivar vehicles: how many vehicles move around the ego (0 to 4, :func:`traffic`);
        with any, the sensor's ``occlusion`` is on.
    :ivar truck_share: the share of them that are trucks.
    """

    sensor: dict[str, Any] = field(default_factory=dict)
    vehicles: int = 0
    truck_share: float = 0.0

    def __post_init__(self) -> None:
        if not 0 <= self.vehicles <= len(_SCHEDULE):
            raise InputError(f"vehicles must be 0..{len(_SCHEDULE)}, got {self.vehicles}")
        if not 0.0 <= self.truck_share <= 1.0:
            raise InputError(f"truck_share must be in [0, 1], got {self.truck_share}")


CONDITIONS: dict[str, Condition] = {
    "ideal": Condition(),
    "noise": Condition({"lateral_noise": 0.05, "dropout": 0.1}),
    "worn": Condition({"worn_dash_rate": 0.3}),
    "vehicles": Condition(vehicles=4, truck_share=0.3),
    "combined": Condition(
        {"lateral_noise": 0.05, "dropout": 0.1, "worn_dash_rate": 0.2},
        vehicles=4,
        truck_share=0.3,
    ),
}
"""The benchmark's conditions: an ideal sensor; 5 cm noise and 10 % dropout; 30 % of
the dashes worn; four vehicles, 30 % of them trucks; and 5 cm noise, 10 % dropout,
20 % worn dashes and the four vehicles together."""


def lane_path(road: OpenDriveRoad, start: tuple[str, int, int]) -> FloatArray:
    """The centre of the chain of driving lanes from ``start`` on (each lane's
    :meth:`~aldm_gym.roads.OpenDriveRoad.successor` until there is none, or a lane
    comes round again), in highway-env's world frame, in driving order.

    :return: ``(N, 2)`` points [m], consecutive duplicates removed.
    """
    parts: list[FloatArray] = []
    seen: set[tuple[str, int, int]] = set()
    key: tuple[str, int, int] | None = start
    while key is not None and key not in seen:
        seen.add(key)
        rec = road.lane_record(key)
        xy = np.asarray(rec.xy, dtype=np.float64)
        if rec.direction < 0:
            xy = xy[::-1]
        parts.append(xy * np.array([1.0, -1.0]))  # OpenDRIVE's y up -> highway-env's down
        key = road.successor(key)
    xy = np.concatenate(parts)
    keep = np.ones(len(xy), dtype=bool)
    keep[1:] = np.hypot(*np.diff(xy, axis=0).T) > 1e-6
    return xy[keep]


def path_poses(xy: FloatArray, u: FloatArray) -> FloatArray:
    """Poses ``(x, y, heading)`` (highway-env's frame [m, rad]) at arc lengths ``u``
    [m] along the polyline ``xy``, heading along its segment (clipped to its ends)."""
    seg = np.diff(xy, axis=0)
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))))
    u = np.clip(u, 0.0, cum[-1])
    i = np.clip(np.searchsorted(cum, u, side="right") - 1, 0, len(seg) - 1)
    t = (u - cum[i]) / np.maximum(cum[i + 1] - cum[i], 1e-12)
    pos = xy[i] + seg[i] * t[:, None]
    return np.column_stack((pos, np.arctan2(seg[i, 1], seg[i, 0])))


def path_length(xy: FloatArray) -> float:
    """Arc length of the polyline ``xy`` [m]."""
    return float(np.hypot(*np.diff(xy, axis=0).T).sum())


def traffic(
    xy: FloatArray, ego_u: FloatArray, lane_width: float, count: int, truck_share: float, seed: int
) -> FloatArray:
    """Footprints of ``count`` vehicles moving around the ego, per frame.

    Each keeps a lateral offset of whole lane widths from the ego's path (so it moves
    along the path's curve; beside the outermost lanes it drives on the shoulder, and
    still hides what it covers) and a gap to the ego that changes at its speed relative
    to the ego's; one that falls 40 m behind or gets 200 m ahead comes back at the other
    end. The first is ahead in the ego's lane: its gap breathes between 18 m and 60 m
    over 20 s.

    :param xy: the ego's path (:func:`lane_path`) [m].
    :param ego_u: the ego's arc length along it in each frame [m].
    :param lane_width: [m] (one for the whole path: the start lane's).
    :param count: vehicles (0 to 4).
    :param truck_share: the chance of each to be a truck (seeded by ``seed``).
    :return: ``(frames, count, 6)`` world ``(x, y, heading, length, width, height)``.
    """
    rng = np.random.default_rng([seed, 7])
    sizes = [TRUCK if rng.random() < truck_share else CAR for _ in range(count)]
    t = np.arange(len(ego_u)) * DT
    out = np.zeros((len(ego_u), count, 6))
    lo, hi = _WRAP
    for k in range(count):
        lanes, gap0, rel, breath = _SCHEDULE[k]
        gap = gap0 + rel * t + breath * np.sin(2.0 * math.pi * t / _BREATH_PERIOD)
        gap = lo + np.mod(gap - lo, hi - lo)
        pose = path_poses(xy, ego_u + gap)
        h = pose[:, 2]
        off = lanes * lane_width
        # left of the heading in highway-env's frame (y down): (sin h, -cos h)
        out[:, k, 0] = pose[:, 0] + off * np.sin(h)
        out[:, k, 1] = pose[:, 1] - off * np.cos(h)
        out[:, k, 2] = h
        out[:, k, 3:] = sizes[k]
    return out


class SeenPaint:
    """The paint a drive's sensor has measured so far, road-fixed.

    Every frame's points go into world coordinates (the frame's ground-truth
    ``origin`` and ``yaw``) on a :data:`SEEN_CELL` grid; points that fall behind
    the sensor are forgotten. :meth:`reach` says how far ahead each ego line's paint
    has been seen: what any detector could know of it, however long ago it looked.
    """

    def __init__(self) -> None:
        self._cells = np.zeros((0, 2))

    def add(self, frame: Any) -> None:
        """Keep the points of a line-sensor ``frame`` (sensor frame, x forward, y left
        [m]) and forget those more than a cell behind its sensor."""
        pts = np.asarray(frame.points(), dtype=np.float64).reshape(-1, 3)[:, :2]
        c, s = math.cos(frame.yaw), math.sin(frame.yaw)
        world = frame.origin[None, :2] + pts @ np.array([[c, s], [-s, c]])
        cells = np.vstack([self._cells, np.round(world / SEEN_CELL) * SEEN_CELL])
        cells = cells[self._local(frame, cells)[:, 0] >= -SEEN_CELL]
        # one point per cell: the cells as complex numbers, unique in one dimension
        _, first = np.unique(cells[:, 0] + 1j * cells[:, 1], return_index=True)
        self._cells = cells[first]

    def __len__(self) -> int:
        """How many cells of paint are kept."""
        return len(self._cells)

    @staticmethod
    def _local(frame: Any, cells: FloatArray) -> FloatArray:
        """World points ``cells`` [m] in the sensor frame of ``frame`` [m]."""
        c, s = math.cos(frame.yaw), math.sin(frame.yaw)
        d = cells - frame.origin[None, :2]
        return np.column_stack([d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c])

    def reach(
        self, road: OpenDriveRoad, frame: Any, lane: Any, names: tuple[str, ...], up_to: float
    ) -> dict[str, float]:
        """Per line of ``names`` (of the lane ``lane``, as
        :func:`~aldm_gym.sensor.ground_truth.score_detection` names them), the farthest
        x [m] in ``frame`` up to ``up_to`` at which its paint has been measured
        (a point within :data:`SEEN_TOL` of the true line; -inf: none)."""
        local = self._local(frame, self._cells)
        local = local[(local[:, 0] > 0.0) & (local[:, 0] <= up_to)]
        out = dict.fromkeys(names, -math.inf)
        if not len(local):
            return out
        marks = line_markings(road, lane, frame.origin)
        rows = true_markings(road, frame, local[:, 0])
        for name in names:
            if marks[name] is None:
                continue
            truth = boundary_y(rows, marks[name], local[:, 0], frame)
            on = np.abs(local[:, 1] - truth) <= SEEN_TOL
            if on.any():
                out[name] = float(local[on, 0].max())
        return out


@dataclass
class DriveScore:
    """One detector's score on one drive.

    :ivar frames: frames scored.
    :ivar correct: of them, frames with both ego lines correct.
    :ivar longest_wrong: the longest run of consecutive scored frames with an ego line
        wrong (or missing).
    :ivar missed: ego lines missing (fewer than two points), over the scored frames.
    :ivar observed: scored frames in which both ego lines were observed to the preview
        (:class:`SeenPaint`, :data:`OBSERVED_PERIOD`).
    :ivar longest_wrong_observed: the longest run of consecutive observed frames with
        an ego line wrong (a frame that is not observed ends a run).
    """

    frames: int = 0
    correct: int = 0
    longest_wrong: int = 0
    missed: int = 0
    observed: int = 0
    longest_wrong_observed: int = 0
    _run: int = 0
    _run_observed: int = 0

    def add(
        self,
        left_ok: bool,
        right_ok: bool,
        left_found: bool,
        right_found: bool,
        observed: bool = True,
    ) -> None:
        """Count one scored frame (``observed``: both ego lines were observed to the
        preview)."""
        self.frames += 1
        self.observed += observed
        self.missed += (not left_found) + (not right_found)
        if left_ok and right_ok:
            self.correct += 1
            self._run = self._run_observed = 0
            return
        self._run += 1
        self.longest_wrong = max(self.longest_wrong, self._run)
        self._run_observed = self._run_observed + 1 if observed else 0
        self.longest_wrong_observed = max(self.longest_wrong_observed, self._run_observed)

    def merge(self, other: DriveScore) -> None:
        """Add another drive's counts (the longest runs are the longer ones)."""
        self.frames += other.frames
        self.correct += other.correct
        self.missed += other.missed
        self.observed += other.observed
        self.longest_wrong = max(self.longest_wrong, other.longest_wrong)
        self.longest_wrong_observed = max(self.longest_wrong_observed, other.longest_wrong_observed)

    @property
    def share(self) -> float:
        """Share of scored frames with both ego lines correct (NaN: none scored)."""
        return self.correct / self.frames if self.frames else math.nan

    @property
    def longest_wrong_s(self) -> float:
        """The longest wrong run [s]."""
        return self.longest_wrong * DT

    @property
    def longest_wrong_observed_s(self) -> float:
        """The longest wrong run within observed frames [s]."""
        return self.longest_wrong_observed * DT

    @property
    def observed_share(self) -> float:
        """Share of scored frames in which both ego lines were observed to the preview
        (NaN: none scored)."""
        return self.observed / self.frames if self.frames else math.nan

    @property
    def missed_share(self) -> float:
        """Share of ego lines missing (NaN: no frame scored)."""
        return self.missed / (2 * self.frames) if self.frames else math.nan


def drive(
    road: OpenDriveRoad,
    start: tuple[str, int, int],
    condition: Condition,
    *,
    seed: int = 0,
    max_frames: int | None = None,
    detectors: tuple[str, ...] = DETECTORS,
    detector_params: dict[str, dict[str, Any]] | None = None,
) -> dict[str, DriveScore]:
    """Drive the lane chain from ``start`` under ``condition`` and score ``detectors``.

    :param road: the map.
    :param start: the lane the drive starts on (its chain is :func:`lane_path`).
    :param condition: what the sensor sees.
    :param seed: the sensor's noise and the vehicles' kinds.
    :param max_frames: at most this many frames (``None``: to the chain's end, less
        the sensor's 200 m of view).
    :param detectors: which of :data:`DETECTORS`.
    :param detector_params: per detector, keyword settings of its class (e.g.
        ``{"filter": {"filt": FilterParams(...)}}``).
    :return: each detector's :class:`DriveScore`.
    """
    unknown = [d for d in detectors if d not in DETECTORS]
    if unknown:
        raise InputError(f"unknown detectors {unknown}; allowed: {list(DETECTORS)}")
    params = detector_params or {}
    xy = lane_path(road, start)
    frames = int((path_length(xy) - 200.0) / (SPEED * DT))
    if max_frames is not None:
        frames = min(frames, max_frames)
    if frames < 1:
        return {d: DriveScore() for d in detectors}
    u = np.arange(frames) * SPEED * DT
    poses = path_poses(xy, u)
    settings = dict(condition.sensor)
    if condition.vehicles:
        settings["occlusion"] = True
    sensor = LineSensor(settings, seed=seed)
    width = float(np.median(road.lane_record(start).width))
    boxes = traffic(xy, u, width, condition.vehicles, condition.truck_share, seed)
    filt = LaneModelFilter(**params.get("filter", {}))
    tracker = LaneTracker(**params.get("tracker", {}))
    scores = {d: DriveScore() for d in detectors}
    min_width = ALDMParams().min_lane_width
    last: tuple[float, float, float] | None = None
    seen = SeenPaint()
    for k in range(frames):
        pose = tuple(float(v) for v in poses[k])
        motion = odometry(last, pose, DT)  # type: ignore[arg-type]
        last = pose  # type: ignore[assignment]
        frame = sensor.measure(road, pose, occluders=boxes[k] if condition.vehicles else None)
        seen.add(frame)
        here = road.lane_position(poses[k, :2])
        lane = here.lane
        out = {}
        if "single_frame" in detectors:
            out["single_frame"] = detect_lanes(frame, **params.get("single_frame", {}))
        if "filter" in detectors:
            out["filter"] = filt.update(frame, motion)
        if "tracker" in detectors:
            out["tracker"] = tracker.update(frame, motion)
        if here.width < min_width:
            continue  # the tip of a lane that opens, or the end of one that closes
        ego = ("ego_left", "ego_right")
        truth = score_detection(ground_truth_detect(road, frame, lane), road, frame, lane, ego)
        if not (truth["ego_left"].correct and truth["ego_right"].correct):
            continue
        reach = seen.reach(road, frame, lane, ego, PREVIEW_MIN)
        observed = min(reach.values()) >= PREVIEW_MIN - OBSERVED_PERIOD
        for name, det in out.items():
            sc = score_detection(det, road, frame, lane, ego)
            left, right = sc["ego_left"], sc["ego_right"]
            scores[name].add(left.correct, right.correct, left.found, right.found, observed)
    return scores


def drive_starts(road: OpenDriveRoad, min_length: float = 400.0) -> list[tuple[str, int, int]]:
    """The driving lanes a drive starts on: each lane no other lane continues (a chain's
    first lane) whose chain is at least ``min_length`` long [m], in the map's order."""
    continued = {road.successor(k) for k in road.lanes}
    return [
        k
        for k in road.lanes
        if k not in continued
        and road.lane_record(k).type == "driving"
        and path_length(lane_path(road, k)) >= min_length
    ]


__all__ = [
    "CAR",
    "CONDITIONS",
    "DETECTORS",
    "DT",
    "SPEED",
    "TRUCK",
    "Condition",
    "DriveScore",
    "drive",
    "drive_starts",
    "lane_path",
    "path_length",
    "path_poses",
    "traffic",
]
