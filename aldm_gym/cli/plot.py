"""``aldm-gym plot``: one frame, every point labelled, naive and ALDM side by side.

On a generated road (``--seed``) the car stands at ``--s`` on lane ``--lane``. On an
OpenDRIVE map (``--xodr PATH``) it stands on the centre of lane ``--lane-id`` of road
``--road-id`` at the road's reference arc length ``--s``; without ``--road-id`` the
most curved place of the map's driving lanes (with 80 m of lane ahead) is chosen, where
the detectors' differences show best.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from aldm_gym.cli.argtypes import BadArgument, finite_float, image_file, seed, xodr_file
from aldm_gym.roads.highway import MARKING_MODELS
from aldm_gym.roads.opendrive.parse import SHIPPED_MAPS

CURVE_AHEAD = 80.0
"""The default pose on a map keeps this much lane chain ahead of the car [m]."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym plot`` and its arguments."""
    parser = subparsers.add_parser("plot", help="draw one frame with naive and ALDM detections")
    parser.add_argument("--seed", type=seed, help="generated road: its seed (default: 0)")
    parser.add_argument(
        "--s", type=finite_float, default=None, help="arc length of the car [m] (default 1000)"
    )
    parser.add_argument(
        "--lane", type=int, help="generated road: the car's lane, 0 = leftmost (default: 1)"
    )
    parser.add_argument(
        "--shift", type=finite_float, default=0.0, help="left shift in the lane [m]"
    )
    parser.add_argument(
        "--marking-model",
        choices=MARKING_MODELS,
        default="per_dash",
        help="road model",
    )
    parser.add_argument(
        "--xodr",
        type=xodr_file,
        help="an OpenDRIVE map instead of a generated road: a path, or the name of a "
        f"shipped map ({', '.join(SHIPPED_MAPS)})",
    )
    parser.add_argument(
        "--road-id",
        help="map: the OpenDRIVE road id of the car's lane (with --s; default: the map's "
        "most curved lane)",
    )
    parser.add_argument(
        "--lane-id", type=int, help="map, with --road-id: the OpenDRIVE lane id (default: -1)"
    )
    parser.add_argument(
        "--out",
        type=image_file,
        default=Path("out/frame.png"),
        help="image path (.png, .pdf, ...)",
    )
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """``aldm-gym plot``."""
    from aldm_gym.sensor import LineSensor
    from aldm_gym.sensor.detectors import make_detector
    from aldm_gym.sensor.frame_plot import plot_frames

    _check_applicable(args)
    if args.xodr is not None:
        road, pose, lane, where = _map_pose(args)
        title = f"{args.marking_model} map {args.xodr.name}, {where}"
    else:
        road, pose, lane = _generated_pose(args)
        s = 1000.0 if args.s is None else args.s
        title = f"{args.marking_model} road {args.seed}, s = {s:.0f} m, lane {args.lane}"
    frame = LineSensor().measure(road, pose)
    naive, aldm = make_detector("naive"), make_detector("aldm")
    try:
        plot_frames(
            {"naive": (frame, naive(frame, road, lane)), "ALDM": (frame, aldm(frame, road, lane))},
            args.out,
            suptitle=title,
        )
    except OSError as exc:
        raise BadArgument("--out", f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(f"wrote {args.out}")
    return 0


def _check_applicable(args: argparse.Namespace) -> None:
    """Arguments of the other road source are errors, not ignored; then the defaults.

    :raises BadArgument: ``--road-id``/``--lane-id`` without ``--xodr``, ``--seed``/``--lane``
        with ``--xodr``, or ``--lane-id``/``--s`` on a map without ``--road-id``.
    """
    if args.xodr is None:
        for flag, value in (("--road-id", args.road_id), ("--lane-id", args.lane_id)):
            if value is not None:
                raise BadArgument(flag, "applies to --xodr maps only")
    else:
        for flag, value in (("--seed", args.seed), ("--lane", args.lane)):
            if value is not None:
                raise BadArgument(
                    flag, "applies to generated roads only; on a map use --road-id/--lane-id"
                )
        if args.road_id is None:
            for flag, value in (("--lane-id", args.lane_id), ("--s", args.s)):
                if value is not None:
                    raise BadArgument(flag, "on a map needs --road-id (and --s)")
    args.seed = 0 if args.seed is None else args.seed
    args.lane = 1 if args.lane is None else args.lane
    args.lane_id = -1 if args.lane_id is None else args.lane_id


def _generated_pose(args: argparse.Namespace) -> tuple[Any, tuple[float, float, float], int]:
    from aldm_gym.roads import HighwayRoad

    road = HighwayRoad({"seed": args.seed, "marking_model": args.marking_model})
    s = 1000.0 if args.s is None else args.s
    if not 0 <= args.lane < road.lanes_count:
        raise BadArgument("--lane", f"must be in [0, {road.lanes_count - 1}], got {args.lane}")
    if not 0.0 <= s <= road.length:
        raise BadArgument("--s", f"must be in [0, {road.length:.0f}] m, got {s:g}")
    if abs(args.shift) > road.lane_width:
        raise BadArgument(
            "--shift", f"must be within ±{road.lane_width:g} m (a lane width), got {args.shift:g}"
        )
    p = road.reference.position(s, road.lane_offset(args.lane) + args.shift)
    return road, (float(p[0]), float(p[1]), float(road.reference.heading_at(s))), args.lane


def _map_pose(args: argparse.Namespace) -> tuple[Any, tuple[float, float, float], Any, str]:
    """The map road, the car's pose, its lane key and a description of the place."""
    from aldm_gym.roads import OpenDriveRoad

    try:
        road = OpenDriveRoad.from_file(args.xodr, marking_model=args.marking_model)
    except (OSError, ValueError) as exc:
        raise BadArgument("--xodr", str(exc)) from None
    if args.road_id is not None:
        if args.s is None:
            raise BadArgument("--road-id", "needs --s (reference arc length [m])")
        try:
            x, y, h = road.lane_pose(args.road_id, args.lane_id, args.s)
        except ValueError as exc:
            raise BadArgument("--road-id/--lane-id/--s", str(exc)) from None
        where = f"road {args.road_id} lane {args.lane_id}, s = {args.s:.0f} m"
    else:
        x, y, h, where = _most_curved(road)
    # Shift to the driver's left (highway-env's left of heading h is (sin h, -cos h)).
    x, y = x + args.shift * math.sin(h), y - args.shift * math.cos(h)
    try:
        lane = road.lane_position((x, y)).lane
    except ValueError as exc:  # shifted off the map
        raise BadArgument("--shift", str(exc)) from None
    return road, (x, y, h), lane, where


def _most_curved(road: Any) -> tuple[float, float, float, str]:
    """The centre-line point of greatest |curvature| (smoothed over 20 m) among the map's
    driving lanes with :data:`CURVE_AHEAD` of lane chain ahead: ``(x, y, heading, where)``.

    Lanes with a neighbour (so with a broken lane line, where per-dash objects matter)
    are preferred to single lanes such as ramps.
    """
    net = road.network
    multi = [k for k in road.lanes if len(road.siblings(k)) > 1]
    best: tuple[float, float, float, float, str] | None = None
    for key in multi or road.lanes:
        lane = net.get_lane(net.index_of[key])
        line = lane.reference
        ahead = road.chain_end(key) - road.chain_start(key) - line.s
        width = np.array([lane.width_at(float(s)) for s in line.s[::10]])
        ok = (ahead >= CURVE_AHEAD)[::10] & (width >= 2.5)
        if not ok.any():
            continue
        window = max(int(20.0 / line.step), 1)
        kappa = np.convolve(np.abs(line.kappa), np.ones(window) / window, mode="same")[::10]
        kappa = np.where(ok, kappa, -1.0)
        i = int(np.argmax(kappa))
        if best is None or kappa[i] > best[0]:
            s = float(line.s[10 * i])
            x, y, h = line.pose_at(s)
            radius = 1.0 / kappa[i] if kappa[i] > 0 else math.inf
            best = (float(kappa[i]), x, y, h, f"lane {key}, R ≈ {radius:.0f} m")
    if best is None:
        raise BadArgument("--xodr", f"no driving lane of {road.map.path} has room for a frame")
    return best[1], best[2], best[3], best[4]
