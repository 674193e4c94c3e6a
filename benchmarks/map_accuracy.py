"""Naive vs ALDM on the shipped OpenDRIVE maps (frame level, clean sensor).

For each map in ``aldm_gym/roads/maps`` and both marking models, ``--poses`` seeded
poses on random driving lanes (random reference ``s`` within the lane section, on the
lane centre). Frames where the ground-truth detector is itself not correct (a line
ending within 60 m, e.g. near the end of the map) are skipped; in the rest, the share
of frames where each detector gets both ego lines correct (every point within 0.3 m of
the true line, starting within 25 m, reaching 60 m). Prints a Markdown table.

Run: ``.venv/bin/python -m benchmarks.map_accuracy [--poses 200] [--seed 0]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from aldm_gym.roads import OpenDriveRoad, map_road
from aldm_gym.sensor import (
    LineSensor,
    detect_lanes,
    ground_truth_detect,
    naive_detect,
    score_detection,
)

MAPS = Path(map_road.__file__).parent / "maps"


def accuracy(path: Path, model: str, poses: int, seed: int) -> tuple[int, float, float]:
    """``(frames scored, naive share, ALDM share)`` on one map and marking model."""
    road = OpenDriveRoad.from_file(path, marking_model=model)
    sensor = LineSensor()
    rng = np.random.default_rng(seed)
    ok: dict[str, list[bool]] = {"naive": [], "aldm": []}
    for _ in range(poses):
        key = road.lanes[rng.integers(len(road.lanes))]
        rec = road.lane_record(key)
        pose = road.lane_pose(key[0], key[2], float(rng.uniform(rec.s0, rec.s1)))
        lane = road.lane_position(pose[:2]).lane
        frame = sensor.measure(road, pose)
        truth = score_detection(ground_truth_detect(road, frame, lane), road, frame, lane)
        if not (truth["ego_left"].correct and truth["ego_right"].correct):
            continue
        for name, det in (
            ("naive", naive_detect(frame, road.lane_width)),
            ("aldm", detect_lanes(frame)),
        ):
            sc = score_detection(det, road, frame, lane)
            ok[name].append(sc["ego_left"].correct and sc["ego_right"].correct)
    return len(ok["aldm"]), float(np.mean(ok["naive"])), float(np.mean(ok["aldm"]))


def main(argv: list[str] | None = None) -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    print("| map | frames | per-dash: naive | per-dash: ALDM | editor: naive | editor: ALDM |")
    print("|---|---|---|---|---|---|")
    for path in sorted(MAPS.glob("*.xodr")):
        n, pn, pa = accuracy(path, "per_dash", args.poses, args.seed)
        _, en, ea = accuracy(path, "editor", args.poses, args.seed)
        print(f"| `{path.name}` | {n} | {pn:.0%} | {pa:.0%} | {en:.0%} | {ea:.0%} |")


if __name__ == "__main__":
    main()
