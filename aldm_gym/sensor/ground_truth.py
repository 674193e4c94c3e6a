"""Ground truth in the sensor frame: the true lines, a perfect detector, and detection metrics.

Used as the upper bound in comparisons (``detector="ground_truth"``) and to score
every detector. A line is *correct* when every returned point lies within
``tol`` (0.3 m) of the true marking (or of the other stripe of its double line,
below), it starts within ``start_max`` (25 m) and
reaches at least ``preview_min`` (60 m, the paper's minimum preview) ahead.

A border painted as a double line (OpenDRIVE's ``solid broken``, ``solid solid``, or
a mark's own ``<line>`` elements) has two stripes a stripe's width or two from each
other. The true line is the stripe nearest the lane (the road's
``boundary_markings``; what the perfect detector reports), but a detected point on
the other stripe is on the same border's paint: a point's error is its distance to
the nearest marking that runs within :data:`PAIR_GAP` of the true line at every x of
the detected line where both are (a line that leaves or joins it by more than that
within the detected line's reach, at a lane's opening or end, does not count).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.roads.markings import MarkingChain
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection, line_preview
from aldm_gym.types import FloatArray

PAIR_GAP = 0.4
"""Markings closer than this to the true line [m] are the other stripes of its double
line (the stripes of one are at most a stripe's width and a gap apart, about 0.3 m;
the next border is a lane width away)."""

Boundary = int | tuple[int, ...]
"""A true line: one marking index, or the chain of markings that bound a lane one after
another along its course (on maps a border changes marking, e.g. broken to solid, or
where a lane opens beside it; a road's chains are
:class:`~aldm_gym.roads.markings.MarkingChain`, which say where each takes over)."""


def line_markings(
    road: Road, lane_id: Any, position: FloatArray | None = None
) -> dict[str, Boundary | None]:
    """The true line (:data:`Boundary`) of each of the four lines (:data:`LINE_NAMES`).

    The road answers (``road.boundary_markings``): on a generated highway one marking
    per line, from the lane id alone; on a map, where markings change along the lane,
    the chain of markings ahead of ``position`` (world [m]; the sensor's origin).
    ``None`` where the line does not exist (e.g. no lane left of the leftmost one).
    """
    return road.boundary_markings(lane_id, position)


def boundary_y(
    y: FloatArray, line: Boundary, xs: FloatArray | None = None, frame: SensorFrame | None = None
) -> FloatArray:
    """The rows of ``y`` (``(n_markings, K)``, as from ``road.sample_markings``) of a line.

    A chain takes, at each x, the marking that bounds the lane there: with the x
    positions ``xs`` (``(K,)`` [m]) of ``y``'s columns and the ``frame`` they were
    sampled in, a :class:`~aldm_gym.roads.markings.MarkingChain`'s last marking whose
    start lies at or before x (a marking there before its start bounds another lane:
    the centre line beside a lane that opens). Where that marking is not there, and
    for a plain tuple or without ``xs``: the first of the chain's markings that is
    there (NaN if none).
    """
    if isinstance(line, int | np.integer):
        return y[int(line)]
    out = np.full(y.shape[1], np.nan)
    for j in line:
        out = np.where(np.isnan(out), y[j], out)
    if isinstance(line, MarkingChain) and xs is not None and frame is not None:
        # a marking takes over no nearer than the one before it (a lane that turns back
        # within the chain's reach would otherwise order the starts wrongly in x)
        switch = np.maximum.accumulate(line.switch_x(frame.origin, frame.yaw))
        active = np.searchsorted(switch, np.asarray(xs, dtype=np.float64), side="right")
        rows = np.asarray(line)[active]
        on = y[rows, np.arange(y.shape[1])]
        out = np.where(np.isnan(on), out, on)
    return out


def true_markings(road: Road, frame: SensorFrame, xs: FloatArray) -> FloatArray:
    """True lateral position [m] of every marking at sensor x positions ``xs``
    (``(n_markings, K)``, NaN where a marking is not there).

    Each value depends on its own x only (the road interpolates the segment that
    crosses it), so lines scored on different x share one sampling.

    :param xs: ``(K,)`` x positions [m], any order.
    """
    xs = np.asarray(xs, dtype=np.float64)
    order = np.argsort(xs, kind="stable")
    # Sample out to the sensor's range too: how far a road follows a marking depends on
    # the last x asked for, and a detected point may lie far to the side in a curve.
    grid = np.append(xs[order], max(float(frame.range), float(xs[order][-1])))
    y, _ = road.sample_markings(frame.origin, frame.yaw, grid)
    out = np.empty((y.shape[0], len(xs)))
    out[:, order] = y[:, :-1]
    return out


def true_line(road: Road, frame: SensorFrame, marking: Boundary, xs: FloatArray) -> FloatArray:
    """True lateral position [m] of a line at sensor x positions ``xs`` (NaN where unseen).

    :param marking: a marking index, or a chain of them (:data:`Boundary`).
    :param xs: ``(K,)`` x positions [m], any order.
    :return: ``(K,)`` y [m].
    """
    if len(xs) == 0:
        return np.zeros(0)
    return boundary_y(true_markings(road, frame, xs), marking, xs, frame)


def ground_truth_detect(
    road: Road,
    frame: SensorFrame,
    lane_id: int,
    dx: float | None = None,
    path_range: float | None = None,
) -> LaneDetection:
    """A perfect detector: the true markings around lane ``lane_id``, sampled like the sensor.

    Lines are sampled every ``dx`` (default: the frame's 2 m) from the field-of-view
    start to the range of view; painted or not, as a perfect lane model would know them.
    The trajectory fits each ego line up to x = ``path_range`` (at least 4 points)
    [m]; ``None``: the whole line.
    """
    step = 2.0 if dx is None else dx
    xs = np.arange(frame.fov_start, frame.range + 1e-9, step)
    y, _ = road.sample_markings(frame.origin, frame.yaw, xs)
    lines: dict[str, FloatArray] = {}
    for name, j in line_markings(road, lane_id, frame.origin).items():
        if j is None:
            lines[name] = np.zeros((0, 2))
            continue
        yj = boundary_y(y, j, xs, frame)
        ok = ~np.isnan(yj)
        lines[name] = np.column_stack([xs[ok], yj[ok]])
    return LaneDetection.from_lines(
        **lines, source="ground_truth", lane_width=road.lane_width, path_range=path_range
    )


@dataclass(frozen=True)
class LineScore:
    """How one detected line compares with the truth.

    :ivar found: the detector returned at least two points.
    :ivar correct: every point within ``tol`` of the true marking, first point within
        ``start_max`` and the preview at least ``preview_min``.
    :ivar mean_abs_error: mean |y - y_true| of points up to ``preview_min`` [m] (NaN if none).
    :ivar max_abs_error: largest |y - y_true| over all points [m] (NaN if none).
    :ivar preview: how far ahead the line can be used [m]
        (:func:`~aldm_gym.sensor.lane_detection.line_preview`; 0 if not found).
    """

    found: bool
    correct: bool
    mean_abs_error: float
    max_abs_error: float
    preview: float


def score_line(
    line: FloatArray,
    road: Road,
    frame: SensorFrame,
    marking: Boundary | None,
    tol: float = 0.3,
    start_max: float = 25.0,
    preview_min: float = 60.0,
    markings_y: FloatArray | None = None,
) -> LineScore:
    """Score a detected line against true marking ``marking`` (``None``: no such line).

    :param markings_y: every marking's true y at the line's x
        (:func:`true_markings`), if already sampled.

    A point's error is its distance to the nearest stripe of the true line's paint
    (module docstring: the other stripe of a double line counts).
    """
    if len(line) < 2 or marking is None:
        return LineScore(len(line) >= 2, False, float("nan"), float("nan"), 0.0)
    rows = true_markings(road, frame, line[:, 0]) if markings_y is None else markings_y
    truth = boundary_y(rows, marking, line[:, 0], frame)
    err = np.abs(line[:, 1] - truth)  # NaN where the marking does not reach: counts as wrong
    err = np.where(np.isnan(err), np.inf, err)
    # or the distance to a marking beside the true line all along the detected one
    # (the other stripe of a double line; not a line that merely crosses or leaves it)
    with np.errstate(invalid="ignore"):
        gap = np.abs(rows - truth)
        both = np.isfinite(gap)
        beside = np.all(~both | (gap <= PAIR_GAP), axis=1) & both.any(axis=1)
        alt = np.where(both & beside[:, None], np.abs(line[:, 1] - rows), np.inf)
    err = np.minimum(err, alt.min(axis=0))
    near = line[:, 0] <= preview_min
    mean = float(np.mean(err[near])) if near.any() else float("nan")
    preview = line_preview(line)
    correct = bool(np.all(err <= tol) and line[0, 0] <= start_max and preview >= preview_min)
    return LineScore(True, correct, mean, float(np.max(err)), preview)


def score_detection(
    detection: LaneDetection,
    road: Road,
    frame: SensorFrame,
    lane_id: int,
    names: tuple[str, ...] = LINE_NAMES,
    **kwargs: float,
) -> dict[str, LineScore]:
    """Score the lines ``names`` (default: all four, :data:`LINE_NAMES`) of a detection
    for a vehicle in ``lane_id``.

    The true markings are sampled once, at the x of every line that is scored (when
    no line reaches beyond the sensor's range: the reach of the road's sampling grows
    with the farthest x asked for, so such a line is sampled on its own).
    """
    marks = line_markings(road, lane_id, frame.origin)
    lines = {name: detection.line(name) for name in names}
    scored = [n for n in names if len(lines[n]) >= 2 and marks[n] is not None]
    rows: dict[str, FloatArray | None] = dict.fromkeys(names)
    if scored and all(lines[n][:, 0].max() <= frame.range for n in scored):
        y = true_markings(road, frame, np.concatenate([lines[n][:, 0] for n in scored]))
        start = 0
        for n in scored:
            rows[n] = y[:, start : start + len(lines[n])]
            start += len(lines[n])
    return {
        name: score_line(lines[name], road, frame, marks[name], markings_y=rows[name], **kwargs)
        for name in names
    }
