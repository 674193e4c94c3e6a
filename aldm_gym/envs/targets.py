"""ACC target selection on the *perceived* lanes (sensor frame, ISO 8855: x forward, y left).

The paper motivates the ALDM's long preview with the longitudinal functions: an ACC
uses the line detection "to determine whether a vehicle in front is on the VUT lane
or not", and a highway chauffeur "needs to know the course of the road for a higher
distance to distinguish if a target is on the currently driving lane or not". In a
curve a vehicle 100 m ahead in the *neighbouring* lane lies straight ahead of the
car; only the lane course tells that it is not the target.

So an object is assigned by its lateral position relative to the detected lines *at
its own x along their course* (:func:`~aldm_gym.envs.observation.eval_line`: linear
interpolation, linear extrapolation beyond a line's ends), with its width: its
lateral *overlap* with the corridor (:func:`lane_overlap`). The corridor is the ego
lane, and while a lane change is under way also the lane the ego changes into
(:func:`corridor_bounds`). :func:`select_in_corridor` picks the nearest object ahead
whose overlap reaches ``enter_overlap`` (a cut-in becomes the target as soon as that
much of it is in the lane); the current target is kept while its overlap stays above
the smaller ``exit_overlap`` (a cut-out is released only once it has nearly left):
hysteresis. :class:`TargetSelector` holds that state. The same core runs on ground
truth (the env's ``info["target"]``), so perception and truth differ only by what the
detector gets wrong.

Everything here takes arrays in the sensor frame and a
:class:`~aldm_gym.sensor.lane_detection.LaneDetection`: no env, no road. It runs at every
simulation step, so the per-object loops are small numba kernels (the package habit:
``_name_py`` is the plain-Python reference, ``_name`` its compiled twin): with numpy a
step's few dozen tiny array operations cost a quarter of an env step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.types import FloatArray, IntArray

NO_TARGET = -1
"""The id of "no target"."""

_FIELDS = ("ids", "x", "y", "vx", "width", "length", "vy")


def _empty() -> FloatArray:
    return np.zeros(0)


@dataclass(frozen=True)
class Objects:
    """Other road users in the sensor frame (one row each; all arrays ``(N,)``).

    :ivar ids: a stable id per object (the env uses the index in ``road.vehicles``).
    :ivar x: longitudinal position of the object's centre [m].
    :ivar y: lateral position of the object's centre [m], > 0 left.
    :ivar vx: longitudinal speed relative to the ego [m/s] (< 0: closing in).
    :ivar width: the object's width [m].
    :ivar length: the object's length [m].
    :ivar vy: lateral speed relative to the ego [m/s] (> 0: moving left); not given
        (or empty): zeros, an object sensor without lateral velocity (nothing is then
        predicted to move sideways).
    """

    ids: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    x: FloatArray = field(default_factory=_empty)
    y: FloatArray = field(default_factory=_empty)
    vx: FloatArray = field(default_factory=_empty)
    width: FloatArray = field(default_factory=_empty)
    length: FloatArray = field(default_factory=_empty)
    vy: FloatArray = field(default_factory=_empty)

    def __post_init__(self) -> None:
        n = len(self.ids)
        if n and np.shape(self.vy) == (0,):
            object.__setattr__(self, "vy", np.zeros(n))
        for name in _FIELDS[1:]:
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            if arr.shape != (n,):
                raise InputError(f"Objects.{name} must have shape ({n},) like ids, got {arr.shape}")
            if not np.all(np.isfinite(arr)):
                raise InputError(f"Objects.{name} must be finite")
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "ids", np.asarray(self.ids, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.ids)

    @classmethod
    def trusted(cls, **fields: np.ndarray) -> Objects:
        """Build from arrays known to be valid (the env's own), skipping the checks.

        :param fields: every field, as float64 (``ids`` int64) arrays of one length
            (``vy`` may be left out: zeros).
        """
        out = object.__new__(cls)
        for name in _FIELDS[:-1]:
            object.__setattr__(out, name, fields[name])
        vy = fields.get("vy")  # optional: a sensor without lateral velocity
        object.__setattr__(out, "vy", np.zeros(len(fields["ids"])) if vy is None else vy)
        return out

    def take(self, rows: IntArray) -> Objects:
        """The objects of ``rows`` (already validated: no checks again)."""
        return Objects.trusted(**{n: getattr(self, n)[rows] for n in _FIELDS})

    def index_of(self, object_id: int) -> int:
        """Row of the object with id ``object_id``, or -1."""
        rows = np.flatnonzero(self.ids == object_id)
        return int(rows[0]) if len(rows) else -1


def _segment_py(line: FloatArray, x: float) -> int:
    """Index ``i`` of the segment ``line[i:i + 2]`` that :func:`line_y` evaluates at ``x``
    (the first or last beyond the ends)."""
    k = line.shape[0]
    if x <= line[0, 0]:
        return 0
    if x >= line[k - 1, 0]:
        return k - 2
    i = int(np.searchsorted(line[:, 0], x, side="right")) - 1
    return min(max(i, 0), k - 2)


_segment = numba.njit(cache=True)(_segment_py)


def line_y_py(line: FloatArray, offset: float, x: float) -> float:
    """y [m] of ``line`` shifted by ``offset`` at ``x``: linear interpolation inside,
    linear extrapolation beyond its ends (the observation's ``eval_line`` rule).

    :param line: ``(K >= 2, 2)`` points sorted by x.
    """
    i = _segment(line, x)
    x0, x1 = line[i, 0], line[i + 1, 0]
    y0, y1 = line[i, 1], line[i + 1, 1]
    if x1 > x0:
        return y0 + (y1 - y0) * (x - x0) / (x1 - x0) + offset
    return y0 + offset


line_y = numba.njit(cache=True)(line_y_py)


def line_slope_py(line: FloatArray, x: float) -> float:
    """dy/dx of ``line`` at ``x`` (the slope of the segment :func:`line_y` evaluates)."""
    i = _segment(line, x)
    dx = line[i + 1, 0] - line[i, 0]
    return (line[i + 1, 1] - line[i, 1]) / dx if dx > 0.0 else 0.0


line_slope = numba.njit(cache=True)(line_slope_py)


def corridor_overlaps_py(
    x: FloatArray,
    y: FloatArray,
    width: FloatArray,
    left: FloatArray,
    left_offset: float,
    right: FloatArray,
    right_offset: float,
) -> FloatArray:
    """Each object's overlap [m] with the corridor between two (shifted) lines."""
    n = x.shape[0]
    out = np.empty(n)
    for i in range(n):
        yl = line_y(left, left_offset, x[i])
        yr = line_y(right, right_offset, x[i])
        half = 0.5 * width[i]
        out[i] = min(y[i] + half, yl) - max(y[i] - half, yr)
    return out


corridor_overlaps = numba.njit(cache=True)(corridor_overlaps_py)


def _shifted_overlap_py(
    y: float, half: float, shift: float, y_left: float, y_right: float
) -> float:
    """The largest overlap [m] of ``[y - half, y + half]`` with ``[y_right, y_left]``
    while it moves by anything from 0 to ``shift`` [m].

    The overlap is a concave function of the shift (the smaller of two rising ramps
    minus the larger of two), so its largest value over the window lies at the shift
    in ``[0, shift]`` nearest the one that centres the object in the corridor.
    """
    centre = 0.5 * (y_left + y_right) - y
    d = min(max(centre, min(shift, 0.0)), max(shift, 0.0))
    return min(y + d + half, y_left) - max(y + d - half, y_right)


_shifted_overlap = numba.njit(cache=True)(_shifted_overlap_py)


def _window_shift_py(
    gap: float, vx: float, lateral: float, horizon: float, min_lateral_speed: float
) -> float:
    """One object's predicted lateral displacement [m] (:func:`prediction_shifts`)."""
    if horizon <= 0.0 or abs(lateral) < min_lateral_speed:
        return 0.0
    window = horizon
    if vx < 0.0:
        window = min(window, max(gap, 0.0) / -vx)
    return lateral * window


_window_shift = numba.njit(cache=True)(_window_shift_py)


def predicted_overlaps_py(
    y: FloatArray, width: FloatArray, shift: FloatArray, y_left: FloatArray, y_right: FloatArray
) -> FloatArray:
    """The largest overlap [m] each object reaches with the corridor while its lateral
    position moves from ``y`` to ``y + shift`` (constant velocity over the window; the
    closed form of :func:`_shifted_overlap_py`).

    :param y: ``(N,)`` lateral positions now [m]; ``width``: ``(N,)`` [m].
    :param shift: ``(N,)`` lateral displacements over the window [m] (0: the overlap now).
    :param y_left, y_right: ``(N,)`` the corridor's bounds at each object [m].
    """
    n = y.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = _shifted_overlap(y[i], 0.5 * width[i], shift[i], y_left[i], y_right[i])
    return out


predicted_overlaps = numba.njit(cache=True)(predicted_overlaps_py)


def prediction_shifts_py(
    gap: FloatArray,
    vx: FloatArray,
    lateral_speed: FloatArray,
    horizon: float,
    min_lateral_speed: float,
) -> FloatArray:
    """Each object's predicted lateral displacement [m] relative to the lanes: its
    lateral speed times its window, ``min(horizon, time for the ego to reach it)``
    (an object that will cross the ego's lane only after the ego has passed it is no
    target); 0 for a lateral speed below ``min_lateral_speed`` (what the lanes' and the
    object sensor's errors alone give) or a horizon of 0.

    :param gap: ``(N,)`` bumper-to-bumper gaps from the ego [m].
    :param vx: ``(N,)`` longitudinal speeds relative to the ego [m/s] (< 0: closing in).
    :param lateral_speed: ``(N,)`` lateral speeds relative to the lanes [m/s].
    :param horizon: the prediction horizon [s].
    :param min_lateral_speed: the smallest lateral speed predicted [m/s].
    """
    n = gap.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = _window_shift(gap[i], vx[i], lateral_speed[i], horizon, min_lateral_speed)
    return out


prediction_shifts = numba.njit(cache=True)(prediction_shifts_py)


def _predicted_corridor_py(
    x: FloatArray,
    y: FloatArray,
    vx: FloatArray,
    vy: FloatArray,
    width: FloatArray,
    length: FloatArray,
    left: FloatArray,
    left_offset: float,
    right: FloatArray,
    right_offset: float,
    ego_speed: float,
    ego_x: float,
    ego_length: float,
    horizon: float,
    min_lateral_speed: float,
) -> FloatArray:
    """Each object's predicted overlap [m] with the corridor between two (shifted) lines.

    Its lateral speed relative to the lanes is ``vy − slope · vx_road`` [m/s] (> 0:
    moving left relative to the lanes): the rate of its y minus that of the corridor
    line on its side (the left one for an object left of the corridor's centre, else
    the right one) at its x, where ``vx_road = vx + ego_speed`` is its speed along x
    over the road. An object that follows a curved lane has none, however much its
    heading differs from the ego's; the line on its side, not the corridor's centre,
    so that a taper or an opening of the ego's lane tilts no neighbour into it. Its
    window and displacement: :func:`prediction_shifts_py`; the overlap it reaches:
    :func:`_shifted_overlap_py`.
    """
    n = x.shape[0]
    out = np.empty(n)
    for i in range(n):
        yl = line_y(left, left_offset, x[i])
        yr = line_y(right, right_offset, x[i])
        line = left if y[i] >= 0.5 * (yl + yr) else right
        lateral = vy[i] - line_slope(line, x[i]) * (vx[i] + ego_speed)
        gap = x[i] - ego_x - 0.5 * (length[i] + ego_length)
        shift = _window_shift(gap, vx[i], lateral, horizon, min_lateral_speed)
        out[i] = _shifted_overlap(y[i], 0.5 * width[i], shift, yl, yr)
    return out


_predicted_corridor = numba.njit(cache=True)(_predicted_corridor_py)


def _select_py(
    ids: IntArray,
    x: FloatArray,
    overlap: FloatArray,
    width: FloatArray,
    previous: int,
    max_range: float,
    enter_overlap: float,
    enter_fraction: float,
    exit_overlap: float,
) -> tuple[int, np.ndarray]:
    """:func:`select_in_corridor`'s loop: ``(target id or -1, (N,) inside mask)``; an
    object enters at ``min(enter_overlap, enter_fraction · width)``, so that a narrow
    object (a motorbike, a pedestrian) with that share of its width in the lane is in
    it, and the previous target stays above the smaller of that and ``exit_overlap``."""
    n = x.shape[0]
    inside = np.zeros(n, dtype=np.bool_)
    best, best_x = -1, np.inf
    for i in range(n):
        limit = min(enter_overlap, enter_fraction * width[i])
        if ids[i] == previous and previous != -1:
            limit = min(exit_overlap, limit)
        if overlap[i] >= limit and x[i] > 0.0 and x[i] <= max_range:
            inside[i] = True
            if x[i] < best_x:
                best, best_x = ids[i], x[i]
    return best, inside


_select = numba.njit(cache=True)(_select_py)


def _to_sensor_py(
    xy: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    origin_x: float,
    origin_y: float,
    yaw: float,
    ego_vx: float,
    ego_vy: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """World states as sensor-frame ``(x, y, relative vx, relative vy)`` (the arithmetic
    of :func:`~aldm_gym.envs.observation.to_sensor_frame`; highway-env's world, where
    the driver's left is ``(sin yaw, -cos yaw)``, and velocity is
    ``speed (cos, sin)(heading)``).
    """
    n = xy.shape[0]
    x, y, vx, vy = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    cy, sy = np.cos(yaw), np.sin(yaw)
    for i in range(n):
        px, py = xy[i, 0] - origin_x, xy[i, 1] - origin_y
        wx = speed[i] * np.cos(heading[i]) - ego_vx
        wy = speed[i] * np.sin(heading[i]) - ego_vy
        x[i] = px * cy + py * sy
        y[i] = px * sy - py * cy
        vx[i] = wx * cy + wy * sy
        vy[i] = wx * sy - wy * cy
    return x, y, vx, vy


_to_sensor = numba.njit(cache=True)(_to_sensor_py)


def objects_from_world(
    ids: IntArray,
    xy: FloatArray,
    speed: FloatArray,
    heading: FloatArray,
    width: FloatArray,
    length: FloatArray,
    origin: FloatArray,
    yaw: float,
    ego_velocity: FloatArray,
) -> Objects:
    """:class:`Objects` in the sensor frame from world states (an ideal object sensor).

    :param xy: ``(N, 2)`` world positions [m]; ``speed`` [m/s], ``heading`` [rad],
        ``width``, ``length`` [m]: ``(N,)`` each, highway-env's conventions.
    :param origin: the sensor's world position [m]; ``yaw`` its world heading [rad].
    :param ego_velocity: the ego's world velocity [m/s] (``vx`` and ``vy`` are
        relative to it).
    """
    x, y, vx, vy = _to_sensor(
        np.ascontiguousarray(xy, dtype=np.float64),
        # contiguous (views of a state table are not): one compiled layout per kernel
        np.ascontiguousarray(speed, dtype=np.float64),
        np.ascontiguousarray(heading, dtype=np.float64),
        float(origin[0]),
        float(origin[1]),
        float(yaw),
        float(ego_velocity[0]),
        float(ego_velocity[1]),
    )
    return Objects.trusted(
        ids=np.asarray(ids, dtype=np.int64),
        x=x,
        y=y,
        vx=vx,
        width=np.ascontiguousarray(width, dtype=np.float64),
        length=np.ascontiguousarray(length, dtype=np.float64),
        vy=vy,
    )


ARC_STEP = 5.0
"""x step of the arc that stands in for missing lines (the curvature fallback) [m]."""


def arc_line(curvature: float, reach: float) -> FloatArray:
    """``(K, 2)`` points of ``y = curvature x² / 2`` from x = 0 to ``reach`` [m]."""
    x = np.arange(0.0, reach + ARC_STEP, ARC_STEP)
    return np.column_stack([x, 0.5 * curvature * x * x])


def corridor_lines(
    detection: LaneDetection | None,
    *,
    side: int = 0,
    lane_width: float = 3.75,
    curvature: float = 0.0,
    reach: float = 250.0,
) -> tuple[FloatArray, float, FloatArray, float]:
    """The perceived corridor as its left and right line, each with a lateral shift.

    The corridor is the ego lane between ``ego_left`` and ``ego_right``, widened by
    the adjacent lane on ``side`` (+1 left, -1 right) during a lane change. A missing
    line is replaced by its neighbour shifted by ``lane_width`` (an ego line by the
    other ego line, an adjacent line by the ego line); with no ego line at all the
    corridor is one lane wide around the arc the ego's current curvature predicts
    (``y = curvature x² / 2`` up to ``reach``), the usual fallback of an ACC without
    lane data.

    :return: ``(left line (K, 2), its shift [m], right line (K, 2), its shift [m])``.
    """
    empty = np.zeros((0, 2))
    el = detection.ego_left if detection is not None else empty
    er = detection.ego_right if detection is not None else empty
    if len(el) < 2 and len(er) < 2:
        arc = arc_line(curvature, reach)
        left, lo, right, ro = arc, 0.5 * lane_width, arc, -0.5 * lane_width
    elif len(el) < 2:
        left, lo, right, ro = er, lane_width, er, 0.0
    elif len(er) < 2:
        left, lo, right, ro = el, 0.0, el, -lane_width
    else:
        left, lo, right, ro = el, 0.0, er, 0.0
    if side > 0:
        la = detection.left_adjacent if detection is not None else empty
        left, lo = (la, 0.0) if len(la) >= 2 else (left, lo + lane_width)
    elif side < 0:
        ra = detection.right_adjacent if detection is not None else empty
        right, ro = (ra, 0.0) if len(ra) >= 2 else (right, ro - lane_width)
    return left, lo, right, ro


def corridor_bounds(
    detection: LaneDetection | None,
    x: FloatArray,
    *,
    side: int = 0,
    lane_width: float = 3.75,
    curvature: float = 0.0,
) -> tuple[FloatArray, FloatArray]:
    """Left and right bound [m] (y, > 0 left) of the perceived corridor at ``x`` [m].

    See :func:`corridor_lines` (the corridor, missing lines, the fallback).

    :param x: ``(N,)`` longitudinal positions [m].
    :return: ``(y_left, y_right)``, each ``(N,)``.
    """
    x = np.asarray(x, dtype=np.float64)
    reach = max(250.0, float(np.max(x, initial=0.0)))
    left, lo, right, ro = corridor_lines(
        detection, side=side, lane_width=lane_width, curvature=curvature, reach=reach
    )
    yl = np.array([line_y(left, lo, float(v)) for v in x])
    yr = np.array([line_y(right, ro, float(v)) for v in x])
    return yl, yr


def lane_overlap(
    y: FloatArray, width: FloatArray, y_left: FloatArray, y_right: FloatArray
) -> FloatArray:
    """Lateral overlap of objects with a corridor [m] (negative: the free distance between).

    An object spans ``[y - width/2, y + width/2]``, the corridor ``[y_right, y_left]``.

    :return: ``(N,)``: ``min(y + w/2, y_left) - max(y - w/2, y_right)``.
    """
    half = 0.5 * np.asarray(width, dtype=np.float64)
    return np.minimum(y + half, y_left) - np.maximum(y - half, y_right)


def select_in_corridor(
    ids: IntArray,
    x: FloatArray,
    overlap: FloatArray,
    previous: int,
    *,
    max_range: float,
    enter_overlap: float,
    exit_overlap: float,
    width: FloatArray | None = None,
    enter_fraction: float = 1.0,
) -> tuple[int, np.ndarray]:
    """The nearest object ahead in the corridor, with hysteresis.

    An object is in the corridor when its overlap reaches ``enter_overlap`` or, given
    its ``width``, ``enter_fraction`` of it if that is less (a narrow object);
    the ``previous`` target stays while it reaches ``exit_overlap`` (<= that). Candidates
    lie ahead of the ego's centre and within ``max_range``: ``0 < x <= max_range``, with
    ``x`` measured from the ego's centre.

    :param ids: ``(N,)`` object ids (>= 0).
    :param x: ``(N,)`` longitudinal positions from the ego's centre [m].
    :param overlap: ``(N,)`` overlaps with the corridor [m] (:func:`lane_overlap`, or
        the predicted ones of :func:`predicted_overlaps`).
    :param previous: the id selected at the previous step, or :data:`NO_TARGET`.
    :param width: ``(N,)`` the objects' widths [m]; ``None``: ``enter_overlap`` alone.
    :return: ``(target id or NO_TARGET, (N,) bool mask of the objects in the corridor)``.
    """
    x = np.asarray(x, dtype=np.float64)
    if width is None:
        width, enter_fraction = np.full(x.shape, np.inf), 1.0
    target, inside = _select(
        np.asarray(ids, dtype=np.int64),
        x,
        np.asarray(overlap, dtype=np.float64),
        np.asarray(width, dtype=np.float64),
        int(previous),
        float(max_range),
        float(enter_overlap),
        float(enter_fraction),
        float(exit_overlap),
    )
    return int(target), inside


@dataclass
class TargetSelector:
    """Target selection with prediction and hysteresis on one stream of detections
    (see the module).

    :ivar max_range: farthest target, from the ego's centre [m].
    :ivar enter_overlap: an object enters the corridor (a cut-in) when this much of
        its width is inside [m], or ...
    :ivar enter_fraction: ... this share of its width, if that is less (a narrow object).
    :ivar exit_overlap: the target leaves (a cut-out) when its overlap falls below this [m].
    :ivar horizon: objects are predicted this far ahead [s] (0: not predicted): the
        overlap an object reaches within ``min(horizon, time for the ego to reach it)``
        at its lateral speed relative to the lanes counts.
    :ivar min_lateral_speed: lateral speeds below this are not predicted [m/s].
    :ivar lane_width: width assumed for a missing line [m].
    :ivar ego_x: x of the ego's centre in the sensor frame [m] (``-mount_x``).
    :ivar ego_length: the ego's length [m] (for the gaps of the prediction windows).
    :ivar target: the id selected last, or :data:`NO_TARGET`.
    """

    max_range: float = 150.0
    enter_overlap: float = 0.5
    exit_overlap: float = 0.1
    enter_fraction: float = 1.0
    horizon: float = 0.0
    min_lateral_speed: float = 0.25
    lane_width: float = 3.75
    ego_x: float = -1.0
    ego_length: float = 5.0
    target: int = NO_TARGET
    inside: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    """The ids of the objects found in the corridor at the last selection."""

    def reset(self) -> None:
        """Forget the target (a new episode)."""
        self.target = NO_TARGET
        self.inside = np.zeros(0, dtype=np.int64)

    def gaps(self, x: FloatArray, length: FloatArray) -> FloatArray:
        """Bumper-to-bumper gaps [m] from the ego to objects at ``x`` (sensor frame)."""
        return x - self.ego_x - 0.5 * (length + self.ego_length)

    def shifts(
        self, x: FloatArray, vx: FloatArray, length: FloatArray, lateral: FloatArray
    ) -> FloatArray:
        """Predicted lateral displacements [m] (:func:`prediction_shifts`)."""
        return prediction_shifts(
            self.gaps(x, length), vx, lateral, self.horizon, self.min_lateral_speed
        )

    def overlaps(
        self,
        detection: LaneDetection | None,
        objects: Objects,
        *,
        side: int = 0,
        curvature: float = 0.0,
        ego_speed: float = 0.0,
    ) -> FloatArray:
        """Each object's predicted overlap with the perceived corridor [m]: the largest
        it reaches within its window (:func:`predicted_overlaps`); without prediction
        (``horizon`` 0), the overlap now (:func:`lane_overlap`).

        :param ego_speed: the ego's speed [m/s] (objects' speeds over the road are
            their relative speeds plus it).
        """
        left, lo, right, ro = corridor_lines(
            detection,
            side=side,
            lane_width=self.lane_width,
            curvature=curvature,
            reach=self.max_range + 10.0,
        )
        if self.horizon <= 0.0:
            return corridor_overlaps(objects.x, objects.y, objects.width, left, lo, right, ro)
        return _predicted_corridor(
            objects.x,
            objects.y,
            objects.vx,
            objects.vy,
            objects.width,
            objects.length,
            left,
            lo,
            right,
            ro,
            float(ego_speed),
            self.ego_x,
            self.ego_length,
            self.horizon,
            self.min_lateral_speed,
        )

    def select(
        self,
        detection: LaneDetection | None,
        objects: Objects,
        *,
        side: int = 0,
        curvature: float = 0.0,
        ego_speed: float = 0.0,
    ) -> int:
        """Select the target among ``objects`` (sensor frame) and remember it.

        :param side: +1 / -1 while a lane change to the left / right is under way and
            the target lane is still the adjacent one (0 otherwise).
        :param curvature: the ego's path curvature [1/m], used only without ego lines.
        :param ego_speed: the ego's speed [m/s] (for the prediction).
        :return: the target's id, or :data:`NO_TARGET`.
        """
        if len(objects) == 0:
            self.reset()
            return NO_TARGET
        overlap = self.overlaps(
            detection, objects, side=side, curvature=curvature, ego_speed=ego_speed
        )
        return self.select_overlaps(objects.ids, objects.x, overlap, objects.width)

    def select_overlaps(
        self, ids: IntArray, x: FloatArray, overlap: FloatArray, width: FloatArray | None = None
    ) -> int:
        """:meth:`select` from overlaps computed elsewhere (ground truth does that).

        :param ids: ``(N,)`` object ids.
        :param x: ``(N,)`` their x in the sensor frame [m].
        :param overlap: ``(N,)`` their (predicted) overlaps with the corridor [m].
        :param width: ``(N,)`` their widths [m], for ``enter_fraction`` (``None``: the
            ``enter_overlap`` alone).
        """
        self.target, inside = select_in_corridor(
            ids,
            x - self.ego_x,
            overlap,
            self.target,
            max_range=self.max_range,
            enter_overlap=self.enter_overlap,
            exit_overlap=self.exit_overlap,
            width=width,
            enter_fraction=self.enter_fraction,
        )
        self.inside = ids[inside]
        return self.target
