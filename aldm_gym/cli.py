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

from aldm_gym.argtypes import fraction, non_negative_float, positive_int
from aldm_gym.report import format_table


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
    cmp_.add_argument("--roads", type=positive_int, help="number of seeded roads")
    cmp_.add_argument("--frames", type=positive_int, help="frames per road and model")
    cmp_.add_argument("--noise", type=non_negative_float, default=0.0, help="lateral noise σ [m]")
    cmp_.add_argument("--dropout", type=fraction, default=0.0, help="point dropout share")
    cmp_.add_argument(
        "--min-radius", type=float, default=500.0, help="smallest curve radius [m] (>= 100)"
    )
    cmp_.add_argument(
        "--episodes", type=positive_int, help="closed-loop episodes per detector and policy"
    )
    cmp_.add_argument(
        "--no-closed-loop", action="store_true", help="only the frame-level comparison"
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

    # Training and evaluation live in aldm_gym.agents.training (SB3 imported lazily).
    from aldm_gym.agents import training

    training.add_train_arguments(sub.add_parser("train", help="train a PPO lane-change policy"))
    training.add_evaluate_arguments(
        sub.add_parser("evaluate", help="evaluate a trained policy against rule-based ones")
    )
    return parser


CLOSED_LOOP_COLUMNS: tuple[str, ...] = (
    "marking_model",
    "detector",
    "episodes",
    "km",
    "departures_per_km",
    "rms_offset_m",
    "max_offset_m",
    "both_correct",
    "mean_preview_m",
    "collisions",
    "lane_changes_ok",
    "lane_changes_failed",
    "mean_speed",
    "success_rate",
)
"""Columns of ``compare.csv`` (closed loop, one row per marking model × detector)."""


def run_compare(args: argparse.Namespace) -> int:
    """``aldm-gym compare``: frame-level comparison, then closed-loop episodes."""
    if args.min_radius < 100.0:
        raise SystemExit("aldm-gym compare: --min-radius must be >= 100 m")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    written = _compare_frames(args, out)
    if not args.no_closed_loop:
        written += _compare_closed_loop(args, out)
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _write_csv(path: Path, rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(columns))
        writer.writeheader()
        writer.writerows(rows)


def _compare_frames(args: argparse.Namespace, out: Path) -> list[Path]:
    """Open loop: the same seeded frames through naive, ALDM and ground truth."""
    from tqdm import tqdm

    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor, naive_detect, score_detection
    from aldm_gym.sensor.evaluation import COLUMNS, compare_detectors, find_frame, make_detector
    from aldm_gym.sensor.plot import plot_frames

    n_roads = args.roads or (2 if args.quick else 5)
    n_frames = args.frames or (100 if args.quick else 400)
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
    _write_csv(out / "compare_frames.csv", rows, COLUMNS)
    print("Frame by frame (open loop):")
    print(format_table(rows, COLUMNS))
    print(
        f"{len(roads)} roads x {n_frames} frames, noise {args.noise} m, dropout "
        f"{args.dropout:.0%}, {time.perf_counter() - t0:.1f} s. both_correct: both ego lines "
        "within 0.3 m of the true markings, starting <= 25 m and reaching >= 60 m.\n"
    )
    # Figures: a per-dash frame where CarMaker's default picks wrong objects, and the same
    # sensor pose on the editor road, each with naive | ALDM | ground truth.
    aldm = make_detector("aldm")
    gt = make_detector("ground_truth")
    road = base[0]

    def naive_fails(frame: Any, lane_id: int) -> bool:
        sc = score_detection(naive_detect(frame), road, frame, lane_id)
        return not sc["ego_right"].correct and frame.right.n_lines > 3

    written = [out / "compare_frames.csv"]
    found = find_frame(road, LineSensor(), naive_fails, np.random.default_rng(args.seed))
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
            written.append(out / f"frame_{model}.png")
    _plot_bars(rows, out / "compare_frames.png")
    written.append(out / "compare_frames.png")
    return written


def _compare_closed_loop(args: argparse.Namespace, out: Path) -> list[Path]:
    """Closed loop: LKA (IDLE) and the rule-based LCA on the same seeded episodes."""
    import gymnasium as gym
    from tqdm import tqdm

    from aldm_gym.agents.evaluation import run_episodes, summarize
    from aldm_gym.agents.policies import IdlePolicy, RuleBasedLCA

    n_ep = args.episodes or (2 if args.quick else 10)
    seeds = [args.seed + i for i in range(n_ep)]
    models, detectors = ("per_dash", "editor"), ("naive", "aldm", "ground_truth")
    sensor = {"lateral_noise": args.noise, "dropout": args.dropout}
    rows, traces = [], {}
    t0 = time.perf_counter()
    total = len(models) * len(detectors) * 2 * n_ep
    with tqdm(total=total, desc="episodes", unit="ep", disable=args.no_progress) as bar:
        for model in models:
            for det in detectors:
                env = gym.make(
                    "ALDMHighway-v0",
                    config={
                        "marking_model": model,
                        "detector": det,
                        "sensor": sensor,
                        "road": {"min_radius": args.min_radius},
                    },
                )
                idle = run_episodes(env, IdlePolicy(), seeds, progress=bar.update)
                lca = run_episodes(env, RuleBasedLCA(), seeds, progress=bar.update)
                env.close()
                row = {"marking_model": model, "detector": det, **summarize(idle + lca)}
                rows.append({c: row[c] for c in CLOSED_LOOP_COLUMNS})
                traces[(model, det)] = idle[0].trace
    _write_csv(out / "compare.csv", rows, CLOSED_LOOP_COLUMNS)
    print("Closed loop (LKA with IDLE and the rule-based LCA, same seeds):")
    print(format_table(rows, CLOSED_LOOP_COLUMNS))
    print(
        f"{n_ep} episodes per policy and row, {time.perf_counter() - t0:.1f} s. Offsets exclude "
        "lane changes; a departure is a wheel over a marking without a lane change.\n"
    )
    _plot_offsets(traces, out / "offset.png")
    return [out / "compare.csv", out / "offset.png"]


_TRACE_STYLE = {
    "naive": ("tab:red", "-", 1.4),
    "aldm": ("tab:blue", "-", 2.6),
    "ground_truth": ("black", "--", 1.0),
}


def _plot_offsets(traces: dict[tuple[str, str], list[tuple[float, float]]], path: Path) -> None:
    """Lateral offset over distance, one panel per marking model, one line per detector."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = sorted({m for m, _ in traces}, reverse=True)
    fig, axes = plt.subplots(len(models), 1, figsize=(8, 2.6 * len(models)), squeeze=False)
    for ax, model in zip(axes[:, 0], models, strict=True):
        for (m, det), trace in traces.items():
            if m != model or not trace:
                continue
            arr = np.asarray(trace)
            colour, style, width = _TRACE_STYLE.get(det, ("tab:gray", "-", 1.2))
            ax.plot(arr[:, 0], arr[:, 1], style, color=colour, lw=width, label=det)
        for y in (-1.875, 1.875):  # lane edges of the default 3.75 m lane
            ax.axhline(y, color="0.6", lw=0.8, ls=":")
        ax.set_title(f"{model} road: LKA (IDLE), first episode", fontsize=9)
        ax.set_ylabel("lateral offset [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("distance along the road [m]")
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)


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
    if args.command in ("train", "evaluate"):
        from aldm_gym.agents import training

        return training.run_train(args) if args.command == "train" else training.run_evaluate(args)
    raise AssertionError(args.command)  # argparse rejects unknown commands


if __name__ == "__main__":
    sys.exit(main())
