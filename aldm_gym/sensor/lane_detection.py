"""The result of lane detection, shared by every detector (naive, ALDM, ground truth).

All coordinates are in the ISO 8855 sensor frame: x forward [m], y left [m].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.roads.markings import MarkingType
from aldm_gym.sensor.trajectory import DEFAULT_LANE_WIDTH, driving_trajectory, fit_cubic
from aldm_gym.types import FloatArray

LINE_NAMES: tuple[str, str, str, str] = ("left_adjacent", "ego_left", "ego_right", "right_adjacent")
"""The four lines, left to right. Observation arrays use this order."""

MIN_PREVIEW = 60.0
"""Preview a line must reach for target selection [m] (paper §ALDM: "The preview
distance must be at least 60 m"); see :meth:`LaneDetection.preview_ok`."""

_EMPTY = np.zeros((0, 2))


def _as_line(points: FloatArray | None, name: str) -> FloatArray:
    """Validate a line: a finite ``(K, 2)`` float array, returned sorted by x."""
    if points is None:
        return _EMPTY.copy()
    arr = np.asarray(points, dtype=np.float64)
    if arr.size == 0:
        return _EMPTY.copy()
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputError(f"LaneDetection.{name} must have shape (K, 2), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"LaneDetection.{name} contains NaN or inf")
    order = np.argsort(arr[:, 0], kind="stable")
    return np.ascontiguousarray(arr[order])


PREVIEW_START = 25.0
"""A line's usable part starts within this x [m] (the paper's start region, 23.52 m,
rounded up)."""

PREVIEW_GAP = 36.0
"""... and has no gap in x longer than this [m]: a dash and two gaps, so one worn or
unseen dash does not end a line (the robust ALDM bridges as far,
``ALDMParams.gap_search_length``)."""


def line_preview(
    line: FloatArray, start_max: float = PREVIEW_START, gap: float = PREVIEW_GAP
) -> float:
    """How far ahead a line can be used [m]: the x of the last point of its part that
    starts within ``start_max`` and has no gap in x longer than ``gap``; 0 when it
    starts farther out or has fewer than 2 points. A single 6 m dash at 183–189 m
    previews 0 m; a traced line from 6 m to 190 m, 190 m.

    :param line: ``(K, 2)`` points (x, y) [m], sorted by x.
    :raises InputError: not a ``(K, 2)`` array, x not finite or not sorted.
    """
    line = np.asarray(line, dtype=np.float64)
    if line.ndim != 2 or line.shape[1] != 2:
        raise InputError(f"a line is a (K, 2) array of (x, y) [m], got shape {line.shape}")
    x = line[:, 0]
    if not np.isfinite(x).all() or np.any(np.diff(x) < 0.0):
        raise InputError("a line's x must be finite and sorted (ascending)")
    if len(line) < 2 or x[0] > start_max:
        return 0.0
    breaks = np.flatnonzero(np.diff(x) > gap)
    end = int(breaks[0]) if len(breaks) else len(x) - 1
    return float(x[end])


def resample_line(points: FloatArray, n: int) -> FloatArray:
    """``n`` points equally spaced in x over the line's x range, linearly interpolated.

    The paper (§"Advanced Lane Detection Model") transmits 13 equally distributed
    points per line. A line with fewer than two points cannot be resampled and
    gives an empty ``(0, 2)`` array.

    :param points: ``(K, 2)`` points sorted by x [m].
    :param n: number of output points (>= 2).
    :return: ``(n, 2)`` points, or ``(0, 2)``.
    """
    if n < 2:
        raise InputError(f"resample needs n >= 2, got {n}")
    if len(points) < 2 or points[-1, 0] <= points[0, 0]:
        return _EMPTY.copy()
    xs = np.linspace(points[0, 0], points[-1, 0], n)
    return np.column_stack([xs, np.interp(xs, points[:, 0], points[:, 1])])


@dataclass(frozen=True)
class LaneDetection:
    """Detected lane lines of one frame, in the sensor frame (x forward, y left) [m].

    Each line is a ``(K, 2)`` float64 array sorted by x; ``K = 0`` when the line was
    not found. ``trajectory`` is the ``(M, 2)`` desired driving path (empty when no
    ego line was found).

    :ivar ego_left: left marking of the ego lane.
    :ivar ego_right: right marking of the ego lane.
    :ivar left_adjacent: left marking of the lane left of the ego lane.
    :ivar right_adjacent: right marking of the lane right of the ego lane.
    :ivar trajectory: desired path midway between the ego lines.
    :ivar source: name of the detector that produced it (``"naive"``, ``"aldm"``, ...).
    """

    ego_left: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    ego_right: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    left_adjacent: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    right_adjacent: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    trajectory: FloatArray = field(default_factory=lambda: _EMPTY.copy())
    source: str = ""

    def __post_init__(self) -> None:
        for name in (*LINE_NAMES, "trajectory"):
            object.__setattr__(self, name, _as_line(getattr(self, name), name))

    @classmethod
    def from_lines(
        cls,
        ego_left: FloatArray | None = None,
        ego_right: FloatArray | None = None,
        left_adjacent: FloatArray | None = None,
        right_adjacent: FloatArray | None = None,
        *,
        source: str = "",
        lane_width: float = DEFAULT_LANE_WIDTH,
        path_range: float | None = None,
    ) -> LaneDetection:
        """Build a detection from lines; the trajectory comes from :func:`driving_trajectory`.

        :param lane_width: lane width for a one-line trajectory [m].
        :param path_range: the trajectory fits each ego line on its points with
            x <= this (at least 4 points) [m]; ``None``: the whole line.
        """
        det = cls(
            ego_left=ego_left,  # type: ignore[arg-type]
            ego_right=ego_right,  # type: ignore[arg-type]
            left_adjacent=left_adjacent,  # type: ignore[arg-type]
            right_adjacent=right_adjacent,  # type: ignore[arg-type]
            source=source,
        )
        traj = driving_trajectory(det.ego_left, det.ego_right, lane_width, path_range=path_range)
        return replace(det, trajectory=traj)

    @classmethod
    def trusted(cls, source: str = "", **lines: FloatArray) -> LaneDetection:
        """Build from arrays that already satisfy the invariants, skipping validation.

        For detectors whose output is by construction finite float64 ``(K, 2)`` arrays
        sorted by x (the ALDM kernels; checked in its tests): validating again costs
        about as much as a whole detection of a typical frame. Missing lines are empty.

        :param lines: any of :data:`LINE_NAMES` and ``trajectory``.
        """
        unknown = set(lines) - {*LINE_NAMES, "trajectory"}
        if unknown:
            raise InputError(f"unknown LaneDetection field(s) {sorted(unknown)}")
        det = object.__new__(cls)
        for name in (*LINE_NAMES, "trajectory"):
            object.__setattr__(det, name, lines[name] if name in lines else _EMPTY.copy())
        object.__setattr__(det, "source", source)
        return det

    def line(self, name: str) -> FloatArray:
        """One line by name (one of :data:`LINE_NAMES`)."""
        if name not in LINE_NAMES:
            raise InputError(f"unknown line {name!r}; allowed: {list(LINE_NAMES)}")
        return getattr(self, name)

    def found(self, name: str) -> bool:
        """Whether line ``name`` has at least two points."""
        return len(self.line(name)) >= 2

    def preview(self, name: str) -> float:
        """How far ahead line ``name`` can be used [m] (:func:`line_preview`); 0 when
        missing."""
        return line_preview(self.line(name))

    def preview_ok(self, name: str, minimum: float = MIN_PREVIEW) -> bool:
        """Whether line ``name`` reaches at least ``minimum`` ahead of the sensor.

        The paper lists "the preview distance must be at least 60 m" among the
        conditions the data has to fulfil (§ALDM), for target selection at long range;
        it gives no rule for a shorter line. No detector drops or shortens a line
        for it: a line with less preview is returned as traced, and this flag says
        that it does not meet the paper's condition (a missing line never does).

        :param minimum: required preview [m] (default :data:`MIN_PREVIEW`, 60 m).
        """
        return self.found(name) and self.preview(name) >= minimum

    def extent(self, name: str) -> float:
        """Length in x covered by line ``name`` (last x - first x) [m]; 0 when missing."""
        line = self.line(name)
        return float(line[-1, 0] - line[0, 0]) if len(line) else 0.0

    def resample(self, n: int = 13) -> LaneDetection:
        """A copy with every line resampled to ``n`` equally spaced points.

        Lines with fewer than two points become empty. The trajectory is kept.
        """
        kw: dict[str, Any] = {name: resample_line(self.line(name), n) for name in LINE_NAMES}
        return replace(self, **kw)

    def as_array(self, n: int = 13) -> tuple[FloatArray, np.ndarray]:
        """Lines as a fixed-size array for observations.

        :return: ``(points, valid)``: ``points`` is ``(4, n, 2)`` in the order of
            :data:`LINE_NAMES` (zeros for missing lines), ``valid`` is a ``(4,)`` bool mask.
        """
        pts = np.zeros((4, n, 2))
        valid = np.zeros(4, dtype=bool)
        for i, name in enumerate(LINE_NAMES):
            r = resample_line(self.line(name), n)
            if len(r):
                pts[i] = r
                valid[i] = True
        return pts, valid


__all__ = [
    "DEFAULT_LANE_WIDTH",
    "LINE_NAMES",
    "MIN_PREVIEW",
    "PREVIEW_GAP",
    "PREVIEW_START",
    "LaneDetection",
    "driving_trajectory",
    "fit_cubic",
    "line_preview",
    "paint_types",
    "resample_line",
]


CROSS_REACH = 50.0
"""How far ahead [m] :func:`paint_types` reads the paint under a line: about where a
lane change started now crosses it (2 s at 25 m/s)."""

ON_LINE_BAND = 0.35
"""A line object lies on a detected line where its points are within this lateral
distance [m] of it: both stripes of a double line (gaps of 0.10–0.18 m between lines
0.10–0.15 m wide, Vienna Convention on Road Signs and Signals, Annex 2: up to 0.33 m
centre to centre) when the line lies on one of them; a tar seam beside a marking only
within 0.35 m (the sensor's seams lie 0.3–1.0 m off)."""

STRIPE_GAP = 0.08
"""A continuous stripe at least this much [m] farther from the car than a broken one
on the same line is the double line's far stripe, which the driver on the broken
stripe's side may cross."""


def paint_types(
    frame: Any,
    detection: LaneDetection,
    names: tuple[str, ...] = ("ego_left", "ego_right"),
    reach: float = CROSS_REACH,
    far_side: bool = False,
) -> dict[str, int]:
    """The type of paint (the line sensor's: 1 continuous, 2 dashed, 3 dotted; 0: none
    seen) each detected line ``names`` lies on from the sensor to ``reach`` [m], as a
    lane-change function reads it from the sensor's line objects; with ``far_side``,
    as a car on the line's other side reads it (a double line's other stripe).

    An object lies on the line when at least half of its points there are within
    :data:`ON_LINE_BAND` of it (a seam beside it does not), and, if continuous, at
    least two (a speck does not; a short dash may give one point). The
    line is continuous where a continuous object lies on it and is not the far stripe
    of a double line (:data:`STRIPE_GAP` outside a broken stripe): a continuous line
    may not be crossed (Vienna Convention on Road Signs and Signals, Art. 26), a
    double line only from its broken stripe's side. Otherwise it is the type of the
    broken object nearest the car, 0 when no object lies on it (the line is carried
    by the detector, hidden, or worn).

    :param frame: the :class:`~aldm_gym.sensor.frame.SensorFrame` the detection is of.
    """
    pts = frame.all_points
    n_obj = len(frame.line_type)
    owner = np.repeat(np.arange(n_obj), np.diff(frame.line_start))
    types = np.asarray(frame.line_type, dtype=np.int64)
    out: dict[str, int] = {}
    for name in names:
        line = detection.line(name)
        out[name] = 0
        if len(line) < 2 or len(pts) == 0:
            continue
        x, y = pts[:, 0], pts[:, 1]
        inside = (x >= line[0, 0]) & (x <= min(float(line[-1, 0]), reach))
        if not inside.any():
            continue
        # > 0 away from the car: the side of the line the car is not on (or, for the
        # far side, is on)
        outward = (1.0 if "left" in name else -1.0) * (-1.0 if far_side else 1.0)
        d = outward * (y - np.interp(x, line[:, 0], line[:, 1]))
        on = inside & (np.abs(d) <= ON_LINE_BAND)
        seen = np.bincount(owner[inside], minlength=n_obj)
        hits = np.bincount(owner[on], minlength=n_obj)
        mean_d = np.bincount(owner[on], weights=d[on], minlength=n_obj) / np.maximum(hits, 1)
        lying = (hits >= 1) & (2 * hits >= seen)
        # a continuous line in view gives more than one point (one is a speck); a
        # short dash may give only one
        solid = lying & (types == MarkingType.CONTINUOUS) & (hits >= 2)
        broken = lying & (types != MarkingType.CONTINUOUS)
        if not (solid.any() or broken.any()):
            continue
        inner = float(mean_d[broken].min()) if broken.any() else math.inf
        if np.any(mean_d[solid] < inner + STRIPE_GAP):
            out[name] = int(MarkingType.CONTINUOUS)
        else:
            out[name] = int(types[broken][np.argmin(mean_d[broken])])
    return out
