"""Lane-detection metrics as the field reports them, on aldm-gym's ground truth.

Per frame, the detected lines (ego left/right, left/right adjacent) are matched one to
one to the true markings around the vehicle's lane by minimum cost (Hungarian method,
``scipy.optimize.linear_sum_assignment``), Gen-LaneNet's cost: over the grid points
(below) either line covers, the lateral distance clipped at 1.5 m, and 1.5 m where only
one covers. Each matched pair is judged at two thresholds:

- **strict**, this project's headline rule (:func:`~aldm_gym.sensor.ground_truth.score_line`):
  every detected point within 0.3 m of the true marking, the first point within 25 m and
  the line's :func:`preview` at least 60 m (the paper's minimum preview, §ALDM); here
  against the true line alone (``score_line`` also takes the other stripe of a double
  line, ``ground_truth.PAIR_GAP``);
- **loose**, the 3D-lane metric of Gen-LaneNet (Guo et al., ECCV 2020), which OpenLane
  adopts: both lines sampled at the sensor's x grid (every 2 m from the field-of-view
  start to the end of the view, the range or a shorter visibility; a line covers the
  grid points between its first and last x), a
  grid point counts when both lines cover it and lie within 1.5 m of each other there;
  the true line is recalled when at least 75 % of the grid points it covers count, the
  detected line is precise when at least 75 % of those it covers count.

Counting follows OpenLane: at each threshold a true line is a true positive (TP) when
its pair recalls it, else a false negative (FN); a detected line is a false positive
(FP) when it is not precise (or not matched). Precision = precise detected lines /
detected lines, recall = TP / true lines, F1 their harmonic mean (0 when nothing is
recalled), each summed over frames and lines. At the strict threshold a pair passes or
fails as a whole, so TP + FP is the number of lines detected; at the loose one a pair
can recall its true line while its detected line is not precise (a long line that
leaves the marking after it) or the reverse (a short correct piece of a long marking),
so TP + FP need not equal the lines detected and precision is not TP / (TP + FP): the
summaries report the lines detected beside the counts. Lateral errors
are reported as the field does, near (x ≤ 40 m) and far (40 m < x, to the end of the
view), as the mean and the 95th percentile of |Δy| [m] of the detected points of the
lines precise at the loose threshold; and per kind of true line: ``"dashed"`` (broken
or dotted paint), ``"edge"`` (a solid line with no lane beyond it: the outer lines of
the ego and adjacent lanes where nothing lies further out), ``"solid"`` (a solid line
between lanes).

The loose rule is not a relaxation of the strict one in every respect: it asks for
75 % of the line in view, the strict rule for a 60 m preview, so a line correct to
0.3 m that ends at 140 m of a 200 m view passes the strict rule and fails the loose.

The preview (:func:`~aldm_gym.sensor.lane_detection.line_preview`) is what a
controller can use: the far end of the part of the line that starts within 25 m and
runs on without a gap longer than 36 m (a dash and two gaps: one worn or unseen dash
does not end it; the robust ALDM bridges as far); a line starting farther out has
none. A 6 m dash at 183–189 m therefore previews 0 m, not 189 m.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import boundary_y, line_markings, true_markings
from aldm_gym.sensor.lane_detection import (
    LINE_NAMES,
    PREVIEW_GAP,
    PREVIEW_START,
    LaneDetection,
    line_preview,
)
from aldm_gym.types import FloatArray

__all__ = [
    "FAR",
    "KINDS",
    "LOOSE_SHARE",
    "LOOSE_TOLERANCE",
    "NEAR",
    "PREVIEW_GAP",
    "THRESHOLDS",
    "FrameMetrics",
    "LineMatch",
    "MetricsTotals",
    "frame_metrics",
    "totals",
]

NEAR = 40.0
"""Near/far boundary of the lateral errors [m] (the 3D-lane metrics' 0–40 m)."""
FAR = math.inf
"""The far errors reach to the end of the view."""
LOOSE_TOLERANCE = 1.5
"""A grid point of a loose match lies within this lateral distance [m]."""
LOOSE_SHARE = 0.75
"""... and at least this share of the grid points covered by either line does."""
STRICT_TOLERANCE = 0.3
"""Every point of a strict match lies within this lateral distance [m] ..."""
START_MAX = PREVIEW_START
"""... its first point within this x [m] ..."""
PREVIEW_MIN = 60.0
"""... and its preview reaches this far [m] (the paper's minimum preview)."""
GRID_STEP = 2.0
"""The x step of the sensor's grid the loose criterion samples [m]."""
THRESHOLDS = ("strict", "loose")
"""The two thresholds a pair is judged at."""
KINDS = ("solid", "dashed", "edge")
"""Kinds of true line the metrics are broken down by."""


@dataclass(frozen=True)
class LineMatch:
    """A detected line matched to a true line (:func:`frame_metrics`).

    :ivar detected: the detected line's name (:data:`LINE_NAMES`).
    :ivar truth: the true line's name.
    :ivar kind: the true line's kind (:data:`KINDS`).
    :ivar cost: mean |Δy| over their common x [m].
    :ivar strict: the pair matches at the strict threshold.
    :ivar loose: the true line is recalled at the loose threshold.
    :ivar loose_precise: the detected line is precise at the loose threshold.
    :ivar errors: ``(K, 2)`` x [m] and |Δy| [m] of the detected points where the true
        line is there.
    """

    detected: str
    truth: str
    kind: str
    cost: float
    strict: bool
    loose: bool
    loose_precise: bool
    errors: FloatArray


@dataclass(frozen=True)
class FrameMetrics:
    """The metrics of one frame.

    :ivar detected: names of the lines the detector found (at least 2 points).
    :ivar truths: names of the true lines present in the frame, with their kinds.
    :ivar matches: the one-to-one matching (every pair with a finite cost).
    :ivar previews: :func:`~aldm_gym.sensor.lane_detection.line_preview` of each
        detected line [m].
    """

    detected: tuple[str, ...]
    truths: dict[str, str]
    matches: tuple[LineMatch, ...]
    previews: dict[str, float]

    def counts(self, threshold: str) -> tuple[int, int, int]:
        """``(TP, FP, FN)`` at ``threshold`` (``"strict"`` or ``"loose"``): the true lines
        recalled, the detected lines not precise, the true lines not recalled."""
        if threshold not in THRESHOLDS:
            raise InputError(f"threshold must be one of {list(THRESHOLDS)}, got {threshold!r}")
        recalled = sum(getattr(m, threshold) for m in self.matches)
        precise_name = "loose_precise" if threshold == "loose" else threshold
        precise = sum(getattr(m, precise_name) for m in self.matches)
        return recalled, len(self.detected) - precise, len(self.truths) - recalled

    def match_of(self, truth: str) -> LineMatch | None:
        """The pair holding true line ``truth``, if any."""
        return next((m for m in self.matches if m.truth == truth), None)


EDGE_CLEARANCE = 1.0
"""A solid line is an edge when no other true marking lies more than this far [m]
beyond it (away from the ego lane) anywhere along it in view."""


def _kind(road: Road, marking: Any, name: str, on_grid: FloatArray, y_line: FloatArray) -> str:
    """:data:`KINDS` of true line ``name`` (module docstring), from its paint and from the
    true markings of the frame: ``on_grid`` (all markings on the grid), ``y_line`` (this
    line's y there)."""
    rows = (int(marking),) if isinstance(marking, int | np.integer) else tuple(marking)
    if int(road.marking_table["type"][rows[0]]) in (2, 3):
        return "dashed"
    side = 1.0 if name in ("ego_left", "left_adjacent") else -1.0
    others = np.delete(on_grid, list(rows), axis=0)
    seen = np.isfinite(y_line)
    with np.errstate(invalid="ignore"):
        beyond = side * (others[:, seen] - y_line[seen]) > EDGE_CLEARANCE
    return "solid" if bool(np.any(beyond)) else "edge"


def _grid(frame: SensorFrame, view: float | None) -> FloatArray:
    """The sensor's x grid [m] the loose criterion samples, up to the end of the view."""
    end = frame.range if view is None else min(frame.range, view)
    return np.arange(frame.fov_start, end + 1e-9, GRID_STEP)


def _cover(x: FloatArray, grid: FloatArray) -> np.ndarray:
    """Grid points between a line's first and last x."""
    return (grid >= x[0]) & (grid <= x[-1])


def _check_view(frame: SensorFrame, view: Any) -> float | None:
    """``view`` as a float, or an :class:`InputError` when it is not a distance that
    leaves at least two grid points in view."""
    if view is None:
        return None
    if isinstance(view, bool) or not isinstance(view, int | float | np.floating | np.integer):
        raise InputError(f"view must be a distance [m] or None, got {view!r}")
    least = frame.fov_start + GRID_STEP
    if not float(view) >= least:  # NaN fails too
        raise InputError(
            f"view must be at least {least:g} m (two grid points from the field of view's "
            f"start, {frame.fov_start:g} m), got {view!r}"
        )
    return float(view)


def frame_metrics(
    detection: LaneDetection,
    road: Road,
    frame: SensorFrame,
    lane_id: Any,
    view: float | None = None,
) -> FrameMetrics:
    """Match a detection to the true lines of the vehicle's lane and judge the pairs
    (module docstring).

    :param lane_id: the vehicle's true lane (the road's lane key).
    :param view: the farthest x the sensor sees [m], when shorter than the frame's range
        (its ``visibility``): the loose criterion samples up to there, as benchmarks
        annotate only what a camera could see. ``None``: the range.
    :raises InputError: ``view`` is not a distance leaving two grid points in view.
    """
    grid = _grid(frame, _check_view(frame, view))
    marks = line_markings(road, lane_id, frame.origin)
    lines = {n: detection.line(n) for n in LINE_NAMES if len(detection.line(n)) >= 2}
    xs = np.concatenate([grid, *(line[:, 0] for line in lines.values())])
    y_all = true_markings(road, frame, xs)
    on_grid = y_all[:, : len(grid)]
    truth_grid = {}
    truths: dict[str, str] = {}
    for name, marking in marks.items():
        if marking is None:
            continue
        yg = boundary_y(on_grid, marking, grid, frame)
        if np.count_nonzero(np.isfinite(yg)) >= 2:
            truth_grid[name] = yg
            truths[name] = _kind(road, marking, name, on_grid, yg)
    start = len(grid)
    det_truth: dict[str, dict[str, FloatArray]] = {}
    det_grid: dict[str, tuple[np.ndarray, FloatArray]] = {}
    for name, line in lines.items():
        rows = y_all[:, start : start + len(line)]
        start += len(line)
        det_truth[name] = {t: boundary_y(rows, marks[t], line[:, 0], frame) for t in truths}
        det_grid[name] = (_cover(line[:, 0], grid), np.interp(grid, line[:, 0], line[:, 1]))
    detected = tuple(lines)
    truth_names = tuple(truths)
    # Gen-LaneNet's matching cost: over the grid points either line covers, |dy| clipped
    # at the loose tolerance, and the tolerance where only one covers.
    cost = np.zeros((len(detected), len(truth_names)))
    for i, d in enumerate(detected):
        covered_d, y_d = det_grid[d]
        for j, t in enumerate(truth_names):
            yt = truth_grid[t]
            covered_t = np.isfinite(yt)
            union = covered_d | covered_t
            with np.errstate(invalid="ignore"):
                dy = np.minimum(np.abs(y_d - yt), LOOSE_TOLERANCE)
            per_point = np.where(covered_d & covered_t, dy, LOOSE_TOLERANCE)
            cost[i, j] = float(per_point[union].mean()) if union.any() else LOOSE_TOLERANCE
    matches = []
    if cost.size:
        from scipy.optimize import linear_sum_assignment  # not at import: a cold start

        for i, j in zip(*(a.tolist() for a in linear_sum_assignment(cost)), strict=True):
            d, t = detected[i], truth_names[j]
            line = lines[d]
            diff = np.abs(line[:, 1] - det_truth[d][t])
            err = np.where(np.isnan(diff), np.inf, diff)
            strict = bool(
                np.all(err <= STRICT_TOLERANCE)
                and line[0, 0] <= START_MAX
                and line_preview(line) >= PREVIEW_MIN
            )
            covered_d, y_d = det_grid[d]
            yt = truth_grid[t]
            both = covered_d & np.isfinite(yt)
            with np.errstate(invalid="ignore"):
                close = int(np.count_nonzero(both & (np.abs(y_d - yt) <= LOOSE_TOLERANCE)))
            n_t, n_d = int(np.count_nonzero(np.isfinite(yt))), int(np.count_nonzero(covered_d))
            seen = np.isfinite(diff)
            matches.append(
                LineMatch(
                    detected=d,
                    truth=t,
                    kind=truths[t],
                    cost=float(cost[i, j]),
                    strict=strict,
                    loose=close >= LOOSE_SHARE * n_t,
                    # a line that covers no grid point in view cannot be precise
                    loose_precise=n_d > 0 and close >= LOOSE_SHARE * n_d,
                    errors=np.column_stack([line[seen, 0], diff[seen]]),
                )
            )
    return FrameMetrics(
        detected=detected,
        truths=truths,
        matches=tuple(matches),
        previews={n: line_preview(lines[n]) for n in detected},
    )


def _prf(tp: int, fp: int, fn: int, detected: int) -> tuple[float, float, float]:
    """Precision, recall and F1 (NaN where undefined) from the true positives ``tp``
    (true lines recalled), ``fp``, ``fn`` and the number of detected lines."""
    p = (detected - fp) / detected if detected else math.nan
    r = tp / (tp + fn) if tp + fn else math.nan
    if r == 0.0:
        return p, r, 0.0  # nothing recalled: F1 0 whatever the precision
    if p != p or r != r:
        return p, r, math.nan
    return p, r, (2 * p * r / (p + r) if p + r else 0.0)


@dataclass
class MetricsTotals:
    """Sums of :class:`FrameMetrics` over frames, and the summary of them.

    :ivar frames: frames added.
    """

    frames: int = 0
    _counts: dict[str, list[int]] = field(
        default_factory=lambda: {"strict": [0, 0, 0], "loose": [0, 0, 0]}
    )
    _detected: int = 0
    _near: list[float] = field(default_factory=list)
    _far: list[float] = field(default_factory=list)
    _kind: dict[str, list[int]] = field(default_factory=lambda: {k: [0, 0, 0, 0] for k in KINDS})
    _ego_previews: list[float] = field(default_factory=list)

    def add(self, metrics: FrameMetrics) -> None:
        """Add one frame's metrics."""
        self.frames += 1
        self._detected += len(metrics.detected)
        for threshold, c in self._counts.items():
            for k, v in enumerate(metrics.counts(threshold)):
                c[k] += v
        for m in metrics.matches:
            if m.loose_precise:
                x, e = m.errors[:, 0], m.errors[:, 1]
                self._near.extend(e[x <= NEAR].tolist())
                self._far.extend(e[x > NEAR].tolist())
        for t, kind in metrics.truths.items():
            m = metrics.match_of(t)
            k = self._kind[kind]
            k[0] += bool(m is not None and m.strict)
            k[1] += bool(m is not None and m.loose)
            k[2] += 1
        for name in ("ego_left", "ego_right"):
            self._ego_previews.append(metrics.previews.get(name, 0.0))

    def summary(self) -> dict[str, float]:
        """The metrics as a flat dict: ``lines_detected``; per threshold ``{t}_tp``,
        ``{t}_fp``, ``{t}_fn``, ``{t}_precision``, ``{t}_recall``, ``{t}_f1``; ``near_mean_m``,
        ``near_p95_m``, ``far_mean_m``, ``far_p95_m``; per kind ``recall_{kind}``
        (strict) and ``loose_recall_{kind}``; ``mean_preview_m`` of the ego lines (0
        where missing)."""
        out: dict[str, float] = {
            "frames": float(self.frames),
            "lines_detected": float(self._detected),
        }
        for threshold, (tp, fp, fn) in self._counts.items():
            p, r, f1 = _prf(tp, fp, fn, self._detected)
            out.update(
                {
                    f"{threshold}_tp": float(tp),
                    f"{threshold}_fp": float(fp),
                    f"{threshold}_fn": float(fn),
                    f"{threshold}_precision": p,
                    f"{threshold}_recall": r,
                    f"{threshold}_f1": f1,
                }
            )
        for label, values in (("near", self._near), ("far", self._far)):
            arr = np.asarray(values)
            out[f"{label}_mean_m"] = float(arr.mean()) if len(arr) else math.nan
            out[f"{label}_p95_m"] = float(np.percentile(arr, 95)) if len(arr) else math.nan
        for kind, (strict, loose, n) in ((k, v[:3]) for k, v in self._kind.items()):
            out[f"recall_{kind}"] = strict / n if n else math.nan
            out[f"loose_recall_{kind}"] = loose / n if n else math.nan
        out["mean_preview_m"] = (
            float(np.mean(self._ego_previews)) if self._ego_previews else math.nan
        )
        return out


def totals(metrics: Iterable[FrameMetrics]) -> MetricsTotals:
    """:class:`MetricsTotals` of several frames."""
    out = MetricsTotals()
    for m in metrics:
        out.add(m)
    return out
