"""Compile every numba kernel of the package once, before any real work.

The kernels are compiled on first use and cached on disk (``numba.njit(cache=True)``),
so the first run after an install pays the compile (about half a minute to a minute
on 2 cores) and later runs load machine code in well under a second. ``make demo`` and
``make test`` run this module right after installing, so no progress bar and no test
worker includes the compile, and two test workers do not compile the same kernels at
once.

Run: ``python -m aldm_gym.warmup`` (prints what it did and how long it took).
"""

from __future__ import annotations

import sys
import time


def warm_up() -> float:
    """Run each kernel once on small inputs (both ALDM modes, the sensor with noise on a
    generated road and a polyline road, the trajectory fit, the env with each detector).

    :return: the wall time it took [s].
    """
    import gymnasium as gym
    import numpy as np

    import aldm_gym  # noqa: F401  (registers the env)
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.roads.polyline import MarkingCurve, PolylineRoad
    from aldm_gym.sensor import LineSensor, detect_lanes, naive_detect

    start = time.perf_counter()
    road = HighwayRoad({"seed": 0, "length": 1000.0})
    pose = (*road.reference.position(500.0, road.lane_offset(1)), road.reference.heading_at(500.0))
    sensor = LineSensor({"lateral_noise": 0.05, "dropout": 0.1}, seed=0)
    frame = sensor.measure(road, tuple(float(v) for v in pose))
    for mode in ("robust", "paper"):
        detect_lanes(frame, mode=mode)
    naive_detect(frame)
    xy = np.column_stack([np.arange(0.0, 300.0, 1.0), np.zeros(300)])
    poly = PolylineRoad([MarkingCurve(xy, np.array([[0.0, 6.0], [18.0, 24.0]]))])
    LineSensor().measure(poly, (10.0, 0.0, 0.0))
    for detector in ("aldm", "naive", "ground_truth"):
        env = gym.make("ALDMHighway-v0", config={"detector": detector, "vehicles_count": 5})
        env.reset(seed=0)
        env.step(1)
        env.close()
    return time.perf_counter() - start


def main() -> None:
    """Warm up with a one-line message before and after."""
    print("aldm-gym: compiling the numba kernels (cached on disk; once per install)...", flush=True)
    took = warm_up()
    print(f"aldm-gym: kernels ready in {took:.0f} s", file=sys.stdout, flush=True)


if __name__ == "__main__":
    main()
