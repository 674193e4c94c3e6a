"""The ``aldm-gym`` command line.

``aldm-gym compare``: naive vs ALDM vs ground truth on the same seeded frames of both
road models (``per_dash``, ``editor``); writes ``compare.csv`` and PNG figures.
``aldm-gym plot``: one frame, every point labelled, naive and ALDM side by side.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _fraction(text: str) -> float:
    value = float(text)
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"must be in [0, 1), got {value}")
    return value


def _non_negative(text: str) -> float:
    value = float(text)
    if not (value >= 0.0 and np.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``aldm-gym``."""
    parser = argparse.ArgumentParser(
        prog="aldm-gym",
        description="Lane detection on an emulated CarMaker line sensor: naive vs ALDM.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    cmp_ = sub.add_parser("compare", help="naive vs ALDM vs ground truth on seeded frames")
    cmp_.add_argument("--quick", action="store_true", help="small run (about a minute)")
    cmp_.add_argument("--seed", type=int, default=0, help="seed of roads and poses")
    cmp_.add_argument("--out", type=Path, default=Path("out/compare"), help="output folder")
    cmp_.add_argument("--roads", type=_positive_int, help="number of seeded roads")
    cmp_.add_argument("--frames", type=_positive_int, help="frames per road and model")
    cmp_.add_argument("--noise", type=_non_negative, default=0.0, help="lateral noise σ [m]")
    cmp_.add_argument("--dropout", type=_fraction, default=0.0, help="point dropout share")
    cmp_.add_argument(
        "--min-radius", type=float, default=500.0, help="smallest curve radius [m] (>= 100)"
    )
    cmp_.add_argument("--no-progress", action="store_true", help="no progress bar")

    plot = sub.add_parser("plot", help="draw one frame with naive and ALDM detections")
    plot.add_argument("--seed", type=int, default=0, help="road seed")
    plot.add_argument("--s", type=float, default=1000.0, help="arc length of the car [m]")
    plot.add_argument("--lane", type=int, default=1, help="lane id (0 = leftmost)")
    plot.add_argument("--shift", type=float, default=0.0, help="left shift in the lane [m]")
    plot.add_argument(
        "--marking-model", choices=("per_dash", "editor"), default="per_dash", help="road model"
    )
    plot.add_argument("--out", type=Path, default=Path("out/frame.png"), help="PNG path")
    return parser


def _table(rows: list[dict[str, Any]], columns: Sequence[str]) -> str:
    def fmt(v: Any) -> str:
        return f"{v:.3f}" if isinstance(v, float) else str(v)

    cells = [[fmt(r[c]) for c in columns] for r in rows]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths, strict=True))]
    lines += ["  ".join(v.rjust(w) for v, w in zip(row, widths, strict=True)) for row in cells]
    return "\n".join(lines)


def run_compare(args: argparse.Namespace) -> int:
    """``aldm-gym compare``."""
    from tqdm import tqdm

    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor, naive_detect
    from aldm_gym.sensor.evaluation import COLUMNS, compare_detectors, find_frame, make_detector
    from aldm_gym.sensor.plot import plot_frames

    n_roads = args.roads or (2 if args.quick else 5)
    n_frames = args.frames or (100 if args.quick else 400)
    if args.min_radius < 100.0:
        raise SystemExit("aldm-gym compare: --min-radius must be >= 100 m")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    sensor = LineSensor({"lateral_noise": args.noise, "dropout": args.dropout})
    base = [
        HighwayRoad({"seed": args.seed + i, "min_radius": args.min_radius}) for i in range(n_roads)
    ]
    roads = [r.with_marking_model(m) for m in ("per_dash", "editor") for r in base]
    t0 = time.perf_counter()
    with tqdm(
        total=len(roads) * n_frames, desc="frames", unit="frame", disable=args.no_progress
    ) as bar:
        rows = compare_detectors(
            roads, frames_per_road=n_frames, sensor=sensor, seed=args.seed, progress=bar.update
        )
    with open(out / "compare.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(COLUMNS))
        writer.writeheader()
        writer.writerows(rows)
    print(_table(rows, COLUMNS))
    print(
        f"\n{len(roads)} roads x {n_frames} frames, noise {args.noise} m, dropout "
        f"{args.dropout:.0%}, {time.perf_counter() - t0:.1f} s. both_correct: both ego lines "
        "within 0.3 m of the true markings, starting <= 25 m and reaching >= 60 m."
    )
    # Figures: a per-dash frame where CarMaker's default picks wrong objects, and the same
    # pose on the editor road, each with naive | ALDM | ground truth.
    aldm = make_detector("aldm")
    gt = make_detector("ground_truth")
    road = base[0]
    rng = np.random.default_rng(args.seed)

    def naive_fails(frame: Any, lane_id: int) -> bool:
        from aldm_gym.sensor import score_detection

        sc = score_detection(naive_detect(frame), road, frame, lane_id)
        return not sc["ego_right"].correct and frame.right.n_lines > 3

    found = find_frame(road, LineSensor(), naive_fails, rng)
    if found is not None:
        frame, lane = found
        for model in ("per_dash", "editor"):
            r = road.with_marking_model(model)
            f = _remeasure(r, frame)
            plot_frames(
                {
                    f"naive ({model})": (f, naive_detect(f, lane_width=r.lane_width)),
                    f"ALDM ({model})": (f, aldm(f, r, lane)),
                    f"ground truth ({model})": (f, gt(f, r, lane)),
                },
                out / f"frame_{model}.png",
                suptitle=f"{model} road, seed {args.seed}: points labelled side,index",
            )
    _plot_bars(rows, out / "compare.png")
    print(
        f"wrote {out / 'compare.csv'}, {out / 'frame_per_dash.png'}, "
        f"{out / 'frame_editor.png'}, {out / 'compare.png'}"
    )
    return 0


def _remeasure(road: Any, frame: Any) -> Any:
    """Measure ``road`` from the sensor pose of an earlier ``frame`` (same place, other model)."""
    from aldm_gym.sensor import LineSensor

    sensor = LineSensor({"mount_x": 0.0})
    return sensor.measure(road, (float(frame.origin[0]), float(frame.origin[1]), frame.yaw))


def _plot_bars(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = sorted({r["marking_model"] for r in rows}, reverse=True)
    dets = [d for d in ("naive", "aldm", "ground_truth") if any(r["detector"] == d for r in rows)]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    width = 0.8 / len(dets)
    for i, d in enumerate(dets):
        vals = [
            next(
                (r["both_correct"] for r in rows if r["marking_model"] == m and r["detector"] == d),
                0.0,
            )
            for m in models
        ]
        ax.bar(np.arange(len(models)) + i * width, vals, width, label=d)
    ax.set_xticks(np.arange(len(models)) + 0.4 - width / 2, models)
    ax.set_ylabel("frames with both ego lines correct")
    ax.set_ylim(0, 1.05)
    ax.legend()
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


def run_plot(args: argparse.Namespace) -> int:
    """``aldm-gym plot``."""
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor, naive_detect
    from aldm_gym.sensor.evaluation import make_detector
    from aldm_gym.sensor.plot import plot_frames

    road = HighwayRoad({"seed": args.seed, "marking_model": args.marking_model})
    if not 0 <= args.lane < road.lanes_count:
        raise SystemExit(f"aldm-gym plot: --lane must be in [0, {road.lanes_count - 1}]")
    if not 0.0 <= args.s <= road.length:
        raise SystemExit(f"aldm-gym plot: --s must be in [0, {road.length:.0f}] m")
    p = road.reference.position(args.s, road.lane_offset(args.lane) + args.shift)
    pose = (float(p[0]), float(p[1]), float(road.reference.heading_at(args.s)))
    frame = LineSensor().measure(road, pose)
    aldm = make_detector("aldm")
    plot_frames(
        {"naive": (frame, naive_detect(frame)), "ALDM": (frame, aldm(frame, road, args.lane))},
        args.out,
        suptitle=f"{args.marking_model} road {args.seed}, s = {args.s:.0f} m, lane {args.lane}",
    )
    print(f"wrote {args.out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aldm-gym``."""
    args = build_parser().parse_args(argv)
    if args.command == "compare":
        return run_compare(args)
    if args.command == "plot":
        return run_plot(args)
    raise AssertionError(args.command)  # argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())
