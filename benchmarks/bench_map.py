"""OpenDRIVE maps: load time, and the cost of a sensor frame on a map vs a generated road.

* Load: parse + build of a 10 km, 3 + 3 lane motorway written with scenariogeneration
  (10 linked roads), and of the shipped ``motorway.xodr`` (cold: the per-content cache
  is cleared before each load). Target: the 10 km map in <= 1 s.
* Frame: ``LineSensor.measure`` (per-dash, noiseless) on poses along driving lanes of
  ``motorway.xodr`` vs along a generated 4-lane highway, alternating in one run.
  Target: a frame on a map <= 1.5x a frame on the generated road.

Run: ``.venv/bin/python -m benchmarks.bench_map``
"""

from __future__ import annotations

import itertools
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from aldm_gym.roads import HighwayRoad, OpenDriveRoad, map_road
from aldm_gym.roads.cache import LRUCache
from aldm_gym.sensor import LineSensor

MAPS = Path(map_road.__file__).parent / "maps"


def write_10km(path: Path) -> None:
    """A 10 km, 3 + 3 lane road of 10 linked 1 km roads (straights and R 1000 m arcs)."""
    from scenariogeneration import xodr

    odr = xodr.OpenDrive("bench10km")
    roads = []
    for i in range(10):
        geo = [xodr.Line(500), xodr.Arc(0.001 * (-1) ** i, 500)]
        roads.append(xodr.create_road(geo, id=i, left_lanes=3, right_lanes=3, lane_width=3.75))
    for a, b in itertools.pairwise(roads):
        a.add_successor(xodr.ElementType.road, b.id, xodr.ContactPoint.start)
        b.add_predecessor(xodr.ElementType.road, a.id, xodr.ContactPoint.end)
    for r in roads:
        odr.add_road(r)
    odr.adjust_roads_and_lanes()
    odr.write_xml(str(path))


def _load_seconds(path: Path, rounds: int = 5) -> float:
    times = []
    for _ in range(rounds):
        map_road._MAPS = LRUCache(4)  # cold load
        t = time.perf_counter()
        OpenDriveRoad.from_file(path)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _poses_map(road: OpenDriveRoad, n: int, rng: np.random.Generator) -> list:
    out = []
    while len(out) < n:
        key = road.lanes[rng.integers(len(road.lanes))]
        rec = road.lane_record(key)
        if rec.type != "driving":
            continue
        s = float(rng.uniform(rec.s0, rec.s1))
        out.append(road.lane_pose(key[0], key[2], s))
    return out


def _poses_generated(road: HighwayRoad, n: int) -> list:
    out = []
    for s in np.linspace(300.0, road.length - 300.0, n):
        p = road.reference.position(s, road.lane_offset(1))
        out.append((float(p[0]), float(p[1]), float(road.reference.heading_at(s))))
    return out


def main() -> None:
    """Print the load times and the per-frame costs with their ratio."""
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "ten_km.xodr"
        write_10km(path)
        print(
            f"load 10 km, 3+3 lanes (10 roads): {_load_seconds(path) * 1e3:.0f} ms (target <= 1000)"
        )
    print(
        f"load motorway.xodr (5.4 km, ramps): {_load_seconds(MAPS / 'motorway.xodr') * 1e3:.0f} ms"
    )
    sensor = LineSensor()
    odr = OpenDriveRoad.from_file(MAPS / "motorway.xodr")
    gen = HighwayRoad({"seed": 0, "length": 6000.0})
    cases = {
        "generated": (gen, _poses_generated(gen, 100)),
        "motorway.xodr": (odr, _poses_map(odr, 100, np.random.default_rng(0))),
    }
    for road, poses in cases.values():
        sensor.measure(road, poses[0])  # compile
    per: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(7):
        for name, (road, poses) in cases.items():
            t = time.perf_counter()
            for p in poses:
                sensor.measure(road, p)
            per[name].append((time.perf_counter() - t) / len(poses))
    med = {k: statistics.median(v) * 1e6 for k, v in per.items()}
    for k, v in med.items():
        print(f"frame on {k}: {v:.1f} us")
    print(f"map / generated: {med['motorway.xodr'] / med['generated']:.2f}x (target <= 1.5x)")


if __name__ == "__main__":
    main()
