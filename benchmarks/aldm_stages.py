"""Where a frame's time goes in the robust ALDM: each compiled stage timed alone.

The stages of ``detect_lanes`` in robust mode (``aldm_kernels.output.
_robust_pipeline``): ordering the points (``gather``), the start region's seeds
(``_robust_seeds``), the search grid (``build_grid``), each line's trace
(``_robust_trace``, in the pipeline's order, the first traced line's guide table
between), and the output stage (``_finish``: smoothing, the packed lines, the
driving trajectory); beside them ``detect_lanes`` whole and ``np.argsort`` of the
frame's x, each the best of 7 repeats. A stage called alone pays its own dispatch
(about 0.3 µs), so the stages add up to a little more than the pipeline.

Run: ``.venv/bin/python -m benchmarks.aldm_stages [--frame grid4|typical|grid100]``
(default ``grid4``: the 4-line CarMaker-grid frame of ``bench_aldm.py``).
"""

from __future__ import annotations

import argparse
import sys
import timeit
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _best(fn: Callable[[], object], number: int) -> float:
    """Best time per call over 7 repeats [µs]."""
    return min(timeit.repeat(fn, number=number, repeat=7)) / number * 1e6


def stage_times(pts: np.ndarray, number: int = 1000) -> list[tuple[str, float]]:
    """``(stage, µs)`` rows for one frame (see the module docstring)."""
    from aldm_gym.sensor.aldm import _packed, detect_lanes, make_params
    from aldm_gym.sensor.aldm_kernels import robust as R
    from aldm_gym.sensor.aldm_kernels.layout import N_LINES, P
    from aldm_gym.sensor.aldm_kernels.output import _finish, gather

    params = make_params(None)
    fp, ip = _packed(params)
    detect_lanes(pts, params)  # compile or load
    xs, ys = gather(pts, pts.shape[1] >= 3, fp[P.z_band], fp[P.max_range])
    n = xs.shape[0]
    m = int(np.searchsorted(xs, fp[P.start_x_max], side="right"))
    sig2 = fp[P.noise_std] ** 2
    lam_a = sig2 / fp[P.a_std] ** 2
    lam_b = sig2 / fp[P.b_std] ** 2

    def seeds() -> tuple[float, float]:
        label = np.full(m, -1, dtype=np.int64)
        return R._robust_seeds(xs, ys, m, fp, ip, lam_a, lam_b, label, np.full(N_LINES, np.nan))

    x = pts[:, 0].copy()
    rows = [
        ("np.argsort of x", _best(lambda: np.argsort(x), number)),
        ("detect_lanes", _best(lambda: detect_lanes(pts, params), number)),
        (
            "gather (order the points)",
            _best(lambda: gather(pts, pts.shape[1] >= 3, fp[P.z_band], fp[P.max_range]), number),
        ),
        ("seeds (start region)", _best(seeds, number)),
        ("build_grid", _best(lambda: R.build_grid(xs, ys, fp[P.gate_max]), number)),
    ]
    # the traces in the pipeline's order, as robust_detect runs them (a frame whose
    # ego line is missing from the start region also looks further: not reproduced)
    label = np.full(m, -1, dtype=np.int64)
    offsets = np.full(N_LINES, np.nan)
    a, b = R._robust_seeds(xs, ys, m, fp, ip, lam_a, lam_b, label, offsets)
    mask = np.zeros(n, dtype=np.uint8)
    size, first, last = R.claim_seeds(label, mask)
    grid = R.build_grid(xs, ys, fp[P.gate_max])
    guide = np.zeros((0, 4))
    for s in np.argsort(-size, kind="mergesort"):
        if size[s] == 0.0:
            continue
        bit = np.uint8(1 << s)
        before = mask.copy()

        def trace(
            before: np.ndarray = before, s: int = s, bit: np.uint8 = bit, g: np.ndarray = guide
        ) -> None:
            R._robust_trace(
                xs, ys, first[s], last[s], a, b, fp, lam_a, lam_b, g, grid, before.copy(), bit
            )

        R._robust_trace(xs, ys, first[s], last[s], a, b, fp, lam_a, lam_b, guide, grid, mask, bit)
        steps = int(np.count_nonzero(mask & bit)) - int(size[s])
        rows.append((f"trace of line {s} ({steps} steps)", _best(trace, number)))
        if guide.shape[0] == 0:
            rows.append(
                (
                    "guide table",
                    _best(
                        lambda bit=bit: R._guide_table(xs, ys, mask, bit, fp, a, b, lam_a, lam_b),
                        number,
                    ),
                )
            )
            guide = R._guide_table(xs, ys, mask, bit, fp, a, b, lam_a, lam_b)
    rows.append(
        (
            "output (_finish)",
            _best(
                lambda: _finish(xs, ys, mask.copy(), offsets.copy(), fp, ip, a, b, np.inf), number
            ),
        )
    )
    return rows


def main(argv: list[str] | None = None) -> None:
    """Print the stage times of one frame."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frame", choices=("grid4", "typical", "grid100"), default="grid4")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    sys.path.insert(0, str(ROOT / "tests"))
    import bench_aldm

    make = {
        "grid4": bench_aldm.grid_typical_frame,
        "typical": bench_aldm.typical_frame,
        "grid100": bench_aldm.grid_worst_case_frame,
    }[args.frame]
    pts = make()
    rows = stage_times(pts, number=1000 if len(pts) < 2000 else 50)
    sort = rows[0][1]
    print(f"frame {args.frame}: {len(pts)} points")
    print(f"{'stage':34s} {'[µs]':>8s} {'x argsort':>10s}")
    for name, t in rows:
        print(f"{name:34s} {t:8.1f} {t / sort:10.2f}")


if __name__ == "__main__":
    main()
