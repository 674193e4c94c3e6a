"""Cost of the tracking ALDM (:class:`aldm_gym.sensor.tracking.LaneTracker`) and of
the lane-model filter (:class:`aldm_gym.sensor.lane_filter.LaneModelFilter`) over the
stateless :func:`aldm_gym.sensor.detect_lanes` on the same frame.

Frames: the typical frame of ``bench_aldm.py`` (4-lane per-dash highway, R = 800 m,
2 cm noise), seen by a car driving at 25 m/s with 10 Hz frames; the tracker has
followed the 10 frames before. Two cases: the plain frame, and the same frame with
60 m of the ego-left line hidden (x = 25-85 m, a truck ahead), where the tracker
bridges the gap. For each, the best of 15 rounds (``detect_lanes`` and the two
``update`` interleaved) of 200 calls each; ``update`` runs on fresh copies of the
tracker (the filter) so that every call starts from the same tracks (model).

Run: ``.venv/bin/python benchmarks/bench_tracking.py``
"""

from __future__ import annotations

import copy
import platform
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

SPEED = 25.0
"""[m/s]"""
DT = 0.1
"""[s]"""
RADIUS = 800.0
"""[m]"""


def frames(occluded: bool, n: int = 11) -> list[np.ndarray]:
    """``n`` consecutive frames of the drive; with ``occluded`` the last one hides
    the ego-left line's points at 25 <= x <= 85 m."""
    import _synthetic as S

    out = []
    for k in range(n):
        road = S.highway(lanes=4, ego_lane=1, radius=RADIUS, phase=-SPEED * DT * k)
        pts, _ = S.sample(road, noise=0.02, seed=k)
        if occluded and k == n - 1:
            near = road.lateral_error(road.ego_left, pts[:, :2]) < 0.3
            pts = pts[~(near & (pts[:, 0] >= 25.0) & (pts[:, 0] <= 85.0))]
        out.append(pts)
    return out


def measure(occluded: bool, calls: int = 200, rounds: int = 15) -> tuple[float, float, float, int]:
    """Best time per call of ``detect_lanes``, ``LaneTracker.update`` and
    ``LaneModelFilter.update`` [s], and the number of points of the frame."""
    from aldm_gym.sensor import detect_lanes
    from aldm_gym.sensor.lane_filter import LaneModelFilter
    from aldm_gym.sensor.tracking import EgoMotion, LaneTracker

    seq = frames(occluded)
    motion = EgoMotion(SPEED, SPEED / RADIUS, DT)
    trackers = [LaneTracker(), LaneModelFilter()]
    for tracker in trackers:
        for k, pts in enumerate(seq[:-1]):
            tracker.update(pts, None if k == 0 else motion)
    pts = seq[-1]
    detect_lanes(pts)
    for tracker in trackers:
        copy.deepcopy(tracker).update(pts, motion)  # warm
    best = [float("inf")] * 3
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(calls):
            detect_lanes(pts)
        best[0] = min(best[0], (time.perf_counter() - t0) / calls)
        for i, tracker in enumerate(trackers):
            copies = [copy.deepcopy(tracker) for _ in range(calls)]
            t0 = time.perf_counter()
            for tr in copies:
                tr.update(pts, motion)
            best[i + 1] = min(best[i + 1], (time.perf_counter() - t0) / calls)
    return best[0], best[1], best[2], len(pts)


def main() -> None:
    """Print the table of ``BENCHMARKS.md``."""
    import numba

    print(
        f"machine: {platform.machine()}, Python {platform.python_version()}, numpy "
        f"{np.__version__}, numba {numba.__version__}"
    )
    print(
        "| frame | N | detect_lanes [µs] | tracker update [µs] | added "
        "| filter update [µs] | filter / detect_lanes |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for occluded in (False, True):
        single, track, model, n = measure(occluded)
        name = "typical, 60 m of ego left hidden" if occluded else "typical"
        print(
            f"| {name} | {n} | {single * 1e6:.0f} | {track * 1e6:.0f} | "
            f"{100.0 * (track / single - 1.0):+.0f} % | {model * 1e6:.0f} | "
            f"{model / single:.2f}x |"
        )


if __name__ == "__main__":
    main()
