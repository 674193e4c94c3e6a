"""Speed of :func:`aldm_gym.sensor.detect_lanes` as a ratio to ``np.argsort``.

Four frames: the paper's worst case (§ALDM, eq. 1: 100 lines × 100 points = 10,000
points; here 100 parallel continuous markings 3.5 m apart, sampled every 2 m with a
per-line phase, 2 cm noise); the CarMaker-grid worst case (100 straight solid lines
3.5 m apart, every line at the sensor's x grid x = 5.52 + 2p, no noise: exact ties in
x across lines and in y along each line, as CarMaker's sensor delivers a straight
road); a typical 4-lane per-dash highway frame; and a 4-line CarMaker-grid frame.
For each, the best of 15 repeats of ``detect_lanes`` is divided by the best time of
``np.argsort`` of the same frame's x coordinates in the same run, repeats
interleaved (sorting is the floor of any method that orders points). The
plain-Python reference (all kernels run as Python with ``NUMBA_DISABLE_JIT=1``) is
timed on the typical frame.

Run: ``.venv/bin/python benchmarks/bench_aldm.py``
"""

from __future__ import annotations

import subprocess
import sys
import time
import timeit
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))


def worst_case_frame(seed: int = 0) -> np.ndarray:
    """100 lines × 100 points (x from 5.52 m every 2 m), 3.5 m apart, shuffled."""
    rng = np.random.default_rng(seed)
    lines = []
    for j in range(100):
        x = 5.52 + rng.uniform(0.0, 2.0) + 2.0 * np.arange(100)
        y = (j - 49.5) * 3.5 + x * x / 2000.0 + rng.normal(0.0, 0.02, 100)
        lines.append(np.column_stack([x, y, np.zeros(100)]))
    pts = np.concatenate(lines)
    return pts[rng.permutation(len(pts))]


def typical_frame(seed: int = 0) -> np.ndarray:
    """A 4-lane highway, per-dash objects, R = 800 m, 2 cm noise (~400 points)."""
    import _synthetic as S

    road = S.highway(lanes=4, ego_lane=1, radius=800.0)
    pts, _ = S.sample(road, noise=0.02, seed=seed)
    return pts


def grid_worst_case_frame(seed: int = 0) -> np.ndarray:
    """100 straight solid lines 3.5 m apart at the sensor's x grid, no noise, shuffled."""
    import _synthetic as S

    return S.grid_frame(100, seed=seed)


def grid_typical_frame(seed: int = 0) -> np.ndarray:
    """4 straight solid lines 3.5 m apart at the sensor's x grid (392 points)."""
    import _synthetic as S

    return S.grid_frame(4, seed=seed)


def best_alternating(fns: list, number: int, repeat: int = 15) -> list[float]:
    """Best time per call of each of ``fns``, repeats interleaved (the machine is noisy)."""
    times = [[] for _ in fns]
    for _ in range(repeat):
        for f, t in zip(fns, times, strict=True):
            t.append(timeit.timeit(f, number=number) / number)
    return [min(t) for t in times]


def main() -> None:
    t0 = time.perf_counter()
    from aldm_gym.sensor.aldm import detect_lanes

    t_import = time.perf_counter() - t0
    t0 = time.perf_counter()
    detect_lanes(typical_frame())
    detect_lanes(typical_frame(), mode="paper")
    t_first = time.perf_counter() - t0
    print(
        f"import {t_import * 1e3:.0f} ms; first calls (robust + paper, numba cache "
        f"load or compile) {t_first * 1e3:.0f} ms"
    )
    rows = []
    for name, pts in (
        ("worst case 10,000 pts", worst_case_frame()),
        ("CarMaker grid 100 lines", grid_worst_case_frame()),
        ("typical 4-lane per-dash", typical_frame()),
        ("CarMaker grid 4 lines", grid_typical_frame()),
    ):
        x = pts[:, 0].copy()
        number = 100 if len(pts) > 2000 else 1000
        fns = [lambda x=x: np.argsort(x)]
        fns += [lambda pts=pts, m=m: detect_lanes(pts, mode=m) for m in ("robust", "paper")]
        t_sort, *t_dets = best_alternating(fns, number)
        for mode, t_det in zip(("robust", "paper"), t_dets, strict=True):
            rows.append((name, len(pts), mode, t_det, t_sort))
    print(
        f"{'frame':26s} {'N':>6s} {'mode':7s} {'detect [us]':>12s} "
        f"{'argsort [us]':>13s} {'ratio':>6s}"
    )
    for name, n, mode, t_det, t_sort in rows:
        print(
            f"{name:26s} {n:6d} {mode:7s} {t_det * 1e6:12.1f} {t_sort * 1e6:13.1f} "
            f"{t_det / t_sort:6.2f}"
        )
    # Plain-Python reference on the typical frame, in a fresh interpreter.
    code = (
        f"import sys, timeit; sys.path[:0] = [{str(ROOT)!r}, {str(ROOT / 'benchmarks')!r}]\n"
        "from bench_aldm import typical_frame\n"
        "from aldm_gym.sensor.aldm import detect_lanes\n"
        "p = typical_frame(); detect_lanes(p)\n"
        "print(min(timeit.repeat(lambda: detect_lanes(p), number=3, repeat=3)) / 3)\n"
    )
    env = {"NUMBA_DISABLE_JIT": "1", "PATH": "/usr/bin:/bin"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    t_py = float(out.stdout.strip().splitlines()[-1])
    t_nb = next(r[3] for r in rows if r[0].startswith("typical") and r[2] == "robust")
    print(
        f"plain-Python reference, typical frame, robust: {t_py * 1e3:.1f} ms "
        f"-> numba speed-up {t_py / t_nb:.0f}x"
    )


if __name__ == "__main__":
    main()
