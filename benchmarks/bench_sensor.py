"""Line-sensor speed: one 4-lane frame, per-dash and editor, noiseless and noisy.

Run: ``.venv/bin/python -m benchmarks.bench_sensor``. Prints the median time per
``LineSensor.measure`` call over poses along a curved road, and the ratio to
``np.argsort`` of the frame's x coordinates measured in the same run.
"""

from __future__ import annotations

import itertools
import os
import platform
import timeit

import numpy as np

from aldm_gym.roads import HighwayRoad
from aldm_gym.sensor import LineSensor


def _poses(road: HighwayRoad, n: int = 50) -> list[tuple[float, float, float]]:
    out = []
    for s in np.linspace(300.0, road.length - 300.0, n):
        p = road.reference.position(s, road.lane_offset(1))
        out.append((float(p[0]), float(p[1]), float(road.reference.heading_at(s))))
    return out


def bench(repeat: int = 7, number: int = 200) -> list[tuple[str, float, float, int]]:
    """``(case, median µs per frame, ratio to argsort, points per frame)`` per case."""
    road = HighwayRoad({"seed": 0})
    poses = _poses(road)
    rows = []
    for model in ("per_dash", "editor"):
        r = road.with_marking_model(model)
        for label, cfg in (
            ("clean", {}),
            ("noisy 5 cm, 10 %", {"lateral_noise": 0.05, "dropout": 0.1}),
        ):
            sensor = LineSensor(cfg, seed=0)
            sensor.measure(r, poses[0])
            cycle = itertools.cycle(poses)

            def one(sensor: LineSensor = sensor, r: HighwayRoad = r, poses=cycle) -> None:
                sensor.measure(r, next(poses))

            t = min(timeit.repeat(one, repeat=repeat, number=number)) / number
            xs = sensor.measure(r, poses[0]).points()[:, 0].copy()
            ts = min(timeit.repeat(lambda xs=xs: np.argsort(xs), repeat=repeat, number=number))
            ts /= number
            rows.append((f"{model}, {label}", t * 1e6, t / ts, len(xs)))
    return rows


def main() -> None:
    """Print the table."""
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}"
    )
    print(f"{'case':32s} {'µs/frame':>9s} {'x argsort':>10s} {'points':>7s}")
    for case, us, ratio, n in bench():
        print(f"{case:32s} {us:9.1f} {ratio:10.1f} {n:7d}")


if __name__ == "__main__":
    main()
