"""``aldm-gym plot``: one frame, every point labelled, naive and ALDM side by side."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from aldm_gym.roads.highway import MARKING_MODELS


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym plot`` and its arguments."""
    parser = subparsers.add_parser("plot", help="draw one frame with naive and ALDM detections")
    parser.add_argument("--seed", type=int, default=0, help="road seed")
    parser.add_argument("--s", type=float, default=1000.0, help="arc length of the car [m]")
    parser.add_argument("--lane", type=int, default=1, help="lane id (0 = leftmost)")
    parser.add_argument("--shift", type=float, default=0.0, help="left shift in the lane [m]")
    parser.add_argument(
        "--marking-model", choices=MARKING_MODELS, default="per_dash", help="road model"
    )
    parser.add_argument("--out", type=Path, default=Path("out/frame.png"), help="PNG path")
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """``aldm-gym plot``."""
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor
    from aldm_gym.sensor.detectors import make_detector
    from aldm_gym.sensor.plot import plot_frames

    road = HighwayRoad({"seed": args.seed, "marking_model": args.marking_model})
    if not 0 <= args.lane < road.lanes_count:
        raise SystemExit(f"aldm-gym plot: --lane must be in [0, {road.lanes_count - 1}]")
    if not 0.0 <= args.s <= road.length:
        raise SystemExit(f"aldm-gym plot: --s must be in [0, {road.length:.0f}] m")
    p = road.reference.position(args.s, road.lane_offset(args.lane) + args.shift)
    pose = (float(p[0]), float(p[1]), float(road.reference.heading_at(args.s)))
    frame = LineSensor().measure(road, pose)
    naive, aldm = make_detector("naive"), make_detector("aldm")
    plot_frames(
        {
            "naive": (frame, naive(frame, road, args.lane)),
            "ALDM": (frame, aldm(frame, road, args.lane)),
        },
        args.out,
        suptitle=f"{args.marking_model} road {args.seed}, s = {args.s:.0f} m, lane {args.lane}",
    )
    print(f"wrote {args.out}")
    return 0
