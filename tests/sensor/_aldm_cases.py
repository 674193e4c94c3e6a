"""Shared cases of the ALDM tests: seeded synthetic frames and the line criterion."""

from __future__ import annotations

from typing import Any

import _synthetic as S
import numpy as np

from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection

EGO = ("ego_left", "ego_right")
"""The ego lines' names."""


def line_ok(road: S.SynthRoad, det: LaneDetection, name: str, tol: float = 0.3) -> bool:
    """The strict criterion: within tol of the true marking, start <= 25 m, reach >= 60 m."""
    j = getattr(road, name)
    line = det.line(name)
    if j is None:
        return len(line) == 0
    if len(line) < 2:
        return False
    err = road.lateral_error(j, line)
    return bool(err.max() <= tol and line[0, 0] <= 25.0 and line[-1, 0] >= 60.0)


def frame(seed: int, radius: float = np.inf, noise: float = 0.0, dropout: float = 0.0):  # type: ignore[no-untyped-def]
    """A seeded synthetic 3-lane frame (ego in the middle lane): ``(road, points)``."""
    rng = np.random.default_rng(seed)
    road = S.highway(
        lanes=3,
        ego_lane=1,
        radius=radius,
        lateral=rng.uniform(-0.8, 0.8),
        yaw=rng.uniform(-0.02, 0.02),
        phase=rng.uniform(0.0, 18.0),
    )
    pts, _ = S.sample(road, noise=noise, dropout=dropout, seed=seed)
    return road, pts


def same(a: LaneDetection, b: LaneDetection) -> bool:
    """Two detections with bit-identical lines and trajectory."""
    return all(np.array_equal(a.line(n), b.line(n)) for n in LINE_NAMES) and np.array_equal(
        a.trajectory, b.trajectory
    )


def run_without_jit(code: str) -> Any:
    """Run ``code`` in a subprocess with ``NUMBA_DISABLE_JIT=1`` (every kernel as plain
    Python), importing this checkout's ``aldm_gym``; the JSON its last output line
    prints."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    import aldm_gym

    root = str(Path(aldm_gym.__file__).resolve().parents[1])
    path = os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))
    env = dict(os.environ, NUMBA_DISABLE_JIT="1", PYTHONPATH=path)
    res = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True, cwd=root
    )
    return json.loads(res.stdout.strip().splitlines()[-1])
