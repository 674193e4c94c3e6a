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

from aldm_gym.roads.position import Pose
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.detectors import DETECTORS, make_detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import score_detection
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


COLUMNS: tuple[str, ...] = (
    "marking_model",
    "detector",
    "frames",
    "both_correct",
    "left_correct",
    "right_correct",
    "mean_abs_error_m",
    "p95_abs_error_m",
    "mean_preview_m",
    "adjacent_correct",
)
"""Columns of :func:`compare_detectors` rows."""


def compare_detectors(
    roads: Iterable[Road],
    detectors: Iterable[str] = DETECTORS,
    frames_per_road: int = 100,
    sensor: LineSensor | None = None,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
) -> list[dict[str, Any]]:
    """Score detectors on the same seeded frames of each road and marking model.

    Every road is used as given (its ``marking_model``); pass both models of a road to
    compare them. Frames of one road are identical across detectors (same poses, same
    sensor noise).

    :param progress: called with the number of frames done after each frame.
    :return: one row per (marking model, detector) with the keys of :data:`COLUMNS`:
        shares of frames with both/left/right ego lines correct, mean and 95th
        percentile of |lateral error| up to 60 m over ego lines [m], mean preview of the
        ego lines [m], share of adjacent lines found where they exist.
    """
    sensor = sensor or LineSensor()
    names = list(detectors)
    dets = {name: make_detector(name) for name in names}
    acc: dict[tuple[str, str], dict[str, list[float]]] = {}
    for r_i, road in enumerate(roads):
        rng = np.random.default_rng([seed, r_i])
        for pose in sample_poses(road, frames_per_road, rng):
            noise_rng = np.random.default_rng([seed, r_i, int(pose.s * 1000)])
            frame = sensor.measure(road, pose.pose, rng=noise_rng)
            for name in names:
                det = dets[name](frame, road, pose.lane_id)
                sc = score_detection(det, road, frame, pose.lane_id)
                a = acc.setdefault((road.marking_model, name), {})
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
            if progress is not None:
                progress(1)
    rows = []
    for (model, name), a in acc.items():
        err = np.asarray(a.get("err", []))
        rows.append(
            {
                "marking_model": model,
                "detector": name,
                "frames": len(a["both"]),
                "both_correct": float(np.mean(a["both"])),
                "left_correct": float(np.mean(a["left"])),
                "right_correct": float(np.mean(a["right"])),
                "mean_abs_error_m": float(err.mean()) if len(err) else float("nan"),
                "p95_abs_error_m": float(np.percentile(err, 95)) if len(err) else float("nan"),
                "mean_preview_m": float(np.mean(a["preview"])),
                "adjacent_correct": float(np.mean(a["adj"])) if a.get("adj") else float("nan"),
            }
        )
    return rows


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
