"""Cost of occlusion on a line-sensor frame: traffic from the env, occlusion off vs on.

Run: ``.venv/bin/python -m benchmarks.bench_occlusion``. Drives ``ALDMHighway-v0``
(default road, ``vehicles_count`` vehicles, IDLE) and records, at every step, the
sensor pose and every vehicle's footprint. Then times ``LineSensor.measure`` on those
frames without and with ``occlusion`` (vehicles given as highway-env-like objects, as
the env passes them, and as an ``(V, 6)`` array), in one run, alternating the cases
per repeat. Goal: occlusion adds at most 2x to a frame.
"""

from __future__ import annotations

import argparse
import os
import platform
import timeit
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.sensor import LineSensor


def _snapshots(vehicles_count: int, steps: int, seed: int) -> tuple[Any, list[Any]]:
    env = gym.make("ALDMHighway-v0", config={"vehicles_count": vehicles_count})
    env.reset(seed=seed)
    base = env.unwrapped
    out = []
    for _ in range(steps):
        ego = base.vehicle
        pose = (float(ego.position[0]), float(ego.position[1]), float(ego.heading))
        arr = np.array(
            [
                (v.position[0], v.position[1], v.heading, v.LENGTH, v.WIDTH, 1.5)
                for v in base.road.vehicles
            ]
        )
        out.append((pose, arr))
        _, _, terminated, truncated, _ = env.step(1)
        if terminated or truncated:
            break
    road = base.highway
    env.close()
    return road, out


def bench(
    vehicles_count: int = 20, steps: int = 40, repeat: int = 7, seed: int = 0
) -> dict[str, Any]:
    """Best-of-repeats µs per frame of each case, visible points, and the ratio to no occlusion."""
    road, snaps = _snapshots(vehicles_count, steps, seed)
    plain = LineSensor()
    occl = LineSensor({"occlusion": True})
    objects = [
        [
            SimpleNamespace(
                position=r[:2].copy(), heading=float(r[2]), LENGTH=float(r[3]), WIDTH=float(r[4])
            )
            for r in arr
        ]
        for _, arr in snaps
    ]

    def off() -> None:
        for pose, _ in snaps:
            plain.measure(road, pose)

    def on_objects() -> None:
        for (pose, _), objs in zip(snaps, objects, strict=True):
            occl.measure(road, pose, occluders=objs)

    def on_array() -> None:
        for pose, arr in snaps:
            occl.measure(road, pose, occluders=arr)

    cases = {
        "occlusion off": off,
        "occlusion on, vehicles": on_objects,
        "occlusion on, array": on_array,
    }
    for f in cases.values():
        f()
    times: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(repeat):
        for name, f in cases.items():
            times[name].append(timeit.timeit(f, number=3) / (3 * len(snaps)))
    points_off = np.mean([plain.measure(road, p).all_points.shape[0] for p, _ in snaps])
    points_on = np.mean([occl.measure(road, p, occluders=a).all_points.shape[0] for p, a in snaps])
    med = {k: float(np.min(v)) * 1e6 for k, v in times.items()}
    return {
        "frames": len(snaps),
        "vehicles": vehicles_count,
        "us": med,
        "points": (float(points_off), float(points_on)),
    }


def main() -> None:
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vehicles", type=int, default=20)
    ap.add_argument("--steps", type=int, default=40)
    args = ap.parse_args()
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, numpy {np.__version__}, "
        f"load {os.getloadavg()[0]:.1f}"
    )
    r = bench(args.vehicles, args.steps)
    base = r["us"]["occlusion off"]
    print(f"{r['frames']} frames, {r['vehicles'] + 1} vehicles on the road")
    print(f"points per frame: {r['points'][0]:.0f} without, {r['points'][1]:.0f} with occlusion")
    for name, us in r["us"].items():
        print(f"{name:26s} {us:8.1f} µs/frame  {us / base:5.2f}x")


if __name__ == "__main__":
    main()
