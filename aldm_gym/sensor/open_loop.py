"""Frame-level comparison of lane detectors against ground truth.

Seeded vehicle poses are drawn along a road (a generated highway, or the driving lanes
of an OpenDRIVE map); at each pose the line sensor measures
a frame and every detector is scored with
:func:`~aldm_gym.sensor.ground_truth.score_detection`. This is the open-loop half of
the naive-vs-ALDM comparison (``aldm-gym compare``). Detectors are chosen by name from
the registry :mod:`aldm_gym.sensor.detectors`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from aldm_gym.errors import ConfigError
from aldm_gym.roads.markings import MARKING_MODELS
from aldm_gym.roads.position import Pose
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.detectors import make_detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import score_detection
from aldm_gym.sensor.lane_metrics import MetricsTotals, frame_metrics
from aldm_gym.sensor.line_sensor import LineSensor


def sample_poses(
    road: Road,
    n: int,
    rng: np.random.Generator,
    max_shift: float = 0.875,
    heading_jitter: float = 0.01,
    margin: float = 250.0,
) -> list[Pose]:
    """``n`` seeded poses: uniform arc length, lane, lateral shift within the lane, yaw
    jitter (:meth:`Road.sample_poses <aldm_gym.roads.protocol.Road.sample_poses>`).

    :param max_shift: largest lateral shift from the lane centre [m] (0.875 m: a 2 m
        wide car with its tyres on the lines of a 3.75 m lane).
    :param heading_jitter: standard deviation of the heading error [rad].
    :param margin: distance kept from both road ends [m] (a generated road; on a map
        poses are drawn on every driving lane, weighted by its length, where it is at
        least :data:`~aldm_gym.roads.map_road.MIN_POSE_WIDTH` wide).
    """
    return road.sample_poses(n, rng, max_shift, heading_jitter, margin)


FRAME_DETECTORS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("naive", "", {}),
    ("aldm", "robust", {}),
    ("aldm", "paper", {"mode": "paper"}),
    ("ground_truth", "", {}),
)
"""The open loop's rows: ``(detector, ALDM mode, detector params)``: CarMaker's naive
detection, the ALDM in its robust default and in the paper's mode, and ground truth."""

COLUMNS: tuple[str, ...] = (
    "marking_model",
    "detector",
    "mode",
    "frames",
    "both_correct",
    "left_correct",
    "right_correct",
    "mean_abs_error_m",
    "p95_abs_error_m",
    "mean_preview_m",
    "adjacent_correct",
    "lines_detected",
    "strict_precision",
    "strict_recall",
    "strict_f1",
    "strict_tp",
    "strict_fp",
    "strict_fn",
    "loose_precision",
    "loose_recall",
    "loose_f1",
    "loose_tp",
    "loose_fp",
    "loose_fn",
    "near_mean_m",
    "near_p95_m",
    "far_mean_m",
    "far_p95_m",
    "recall_dashed",
    "recall_solid",
    "recall_edge",
)
"""Columns of :func:`compare_detectors` rows (:mod:`aldm_gym.sensor.lane_metrics` for the
precision/recall/F1 and near/far ones)."""


def compare_detectors(
    roads: Iterable[Road],
    detectors: Iterable[tuple[str, str, dict[str, Any]] | str] = FRAME_DETECTORS,
    frames_per_road: int = 100,
    sensor: LineSensor | None = None,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
    marking_models: Iterable[str] = MARKING_MODELS,
) -> list[dict[str, Any]]:
    """Score detectors on the same seeded frames of each road, in each marking model.

    A frame is a seeded pose of a road (poses seeded by the road's index) measured with
    seeded sensor noise; the same pose and noise are measured on every marking model of
    the road (the same paint; only the line objects differ) and given to every
    detector, so the rows differ only by detector and marking model.

    :param roads: the road geometries (their own marking model does not matter).
    :param detectors: ``(detector, mode, params)`` rows (:data:`FRAME_DETECTORS`), or
        detector names (the ALDM then in its default robust mode).
    :param progress: called with 1 after each frame of one marking model.
    :return: one row per (marking model, detector, mode) with the keys of
        :data:`COLUMNS`: shares of frames with both/left/right ego lines correct (the
        strict rule), mean and 95th percentile of |lateral error| up to 60 m over ego
        lines [m], mean preview of the ego lines [m] (0 for a missing or unusable line,
        :func:`~aldm_gym.sensor.lane_detection.line_preview`), share of adjacent lines
        correct where they exist, and :mod:`~aldm_gym.sensor.lane_metrics` over all four
        lines: the lines detected, and at the strict and the loose threshold precision,
        recall, F1, true positives (recalled true lines), false positives (detected lines
        not precise) and false negatives (true lines not recalled), near and far
        lateral errors, strict recall per kind of true line.
    """
    sensor = sensor or LineSensor()
    view = sensor.config.visibility
    specs = [_detector_spec(d) for d in detectors]
    seen = [(name, mode) for name, mode, _ in specs]
    twice = sorted({s for s in seen if seen.count(s) > 1})
    if twice:
        raise ConfigError(f"detector rows given twice (they would share one row): {twice}")
    rows_spec = [(name, mode, make_detector(name, params)) for name, mode, params in specs]
    models = list(marking_models)
    if not models:
        raise ConfigError("marking_models is empty: name at least one of per_dash, editor")
    acc: dict[tuple[str, str, str], dict[str, list[float]]] = {}
    totals: dict[tuple[str, str, str], MetricsTotals] = {}
    for r_i, road in enumerate(roads):
        rng = np.random.default_rng([seed, r_i])
        variants = {m: road.with_marking_model(m) for m in models}
        for pose in sample_poses(road, frames_per_road, rng):
            for model, r in variants.items():
                noise_rng = np.random.default_rng([seed, r_i, int(pose.s * 1000)])
                frame = sensor.measure(r, pose.pose, rng=noise_rng)
                for name, mode, det_fn in rows_spec:
                    det = det_fn(frame, r, pose.lane_id)
                    key = (model, name, mode)
                    _score_frame(acc.setdefault(key, {}), det, r, frame, pose)
                    totals.setdefault(key, MetricsTotals()).add(
                        frame_metrics(det, r, frame, pose.lane_id, view=view)
                    )
                if progress is not None:
                    progress(1)
    rows = []
    for key, a in acc.items():
        model, name, mode = key
        err = np.asarray(a.get("err", []))
        summary = totals[key].summary()
        row: dict[str, Any] = {
            "marking_model": model,
            "detector": name,
            "mode": mode,
            "frames": len(a["both"]),
            "both_correct": float(np.mean(a["both"])),
            "left_correct": float(np.mean(a["left"])),
            "right_correct": float(np.mean(a["right"])),
            "mean_abs_error_m": float(err.mean()) if len(err) else float("nan"),
            "p95_abs_error_m": float(np.percentile(err, 95)) if len(err) else float("nan"),
            "mean_preview_m": float(np.mean(a["preview"])),
            "adjacent_correct": float(np.mean(a["adj"])) if a.get("adj") else float("nan"),
        }
        row.update({c: summary[c] for c in COLUMNS if c not in row})
        rows.append(row)
    return rows


def _detector_spec(spec: Any) -> tuple[str, str, dict[str, Any]]:
    """A ``(detector, mode, params)`` row of :func:`compare_detectors` from a row or a
    name, its mode checked against its parameters.

    :raises ConfigError: a malformed row, or a mode the parameters contradict.
    """
    if isinstance(spec, str):
        return spec, "robust" if spec == "aldm" else "", {}
    if not (isinstance(spec, tuple | list) and len(spec) == 3 and isinstance(spec[2], dict)):
        raise ConfigError(f"a detector row is a name or (detector, mode, params), got {spec!r}")
    name, mode, params = spec
    runs = params.get("mode", "robust") if name == "aldm" else ""
    if mode != runs:
        raise ConfigError(
            f"detector row {spec!r}: its mode label {mode!r} is not the mode it runs, {runs!r}"
        )
    return str(name), str(mode), dict(params)


def _score_frame(
    a: dict[str, list[float]], det: Any, road: Road, frame: SensorFrame, pose: Pose
) -> None:
    """Add a frame's ego-line scores (the strict rule) to the row's accumulator ``a``."""
    sc = score_detection(det, road, frame, pose.lane_id)
    el, er = sc["ego_left"], sc["ego_right"]
    a.setdefault("both", []).append(float(el.correct and er.correct))
    a.setdefault("left", []).append(float(el.correct))
    a.setdefault("right", []).append(float(er.correct))
    a.setdefault("err", []).extend(
        v for v in (el.mean_abs_error, er.mean_abs_error) if np.isfinite(v)
    )
    a.setdefault("preview", []).extend([el.preview, er.preview])
    for side in ("left_adjacent", "right_adjacent"):
        truth_exists = not (
            (side == "left_adjacent" and pose.index == 0)
            or (side == "right_adjacent" and pose.index == pose.lanes - 1)
        )
        if truth_exists:
            a.setdefault("adj", []).append(float(sc[side].correct))


def remeasure(road: Road, frame: SensorFrame) -> SensorFrame:
    """Measure ``road`` from the sensor pose of an earlier ``frame`` (same place, e.g.
    the other marking model of the same road)."""
    # The frame's origin is the sensor itself: a sensor mounted at the vehicle's
    # reference point (mount_x 0) placed there sees from exactly the same pose.
    sensor = LineSensor({"mount_x": 0.0})
    return sensor.measure(road, (float(frame.origin[0]), float(frame.origin[1]), frame.yaw))


def find_frame(
    road: Road,
    sensor: LineSensor,
    want: Callable[[SensorFrame, Any], bool],
    rng: np.random.Generator,
    tries: int = 400,
) -> tuple[SensorFrame, Any] | None:
    """A seeded frame (and its true lane) satisfying ``want(frame, lane_id)``, or ``None``."""
    for pose in sample_poses(road, tries, rng):
        frame = sensor.measure(road, pose.pose)
        if want(frame, pose.lane_id):
            return frame, pose.lane_id
    return None
