"""``aldm-gym compare``: naive vs ALDM vs ground truth, frame by frame and in closed loop.

Open loop: the same seeded frames of both road models (``per_dash``, ``editor``)
through every detector (:func:`~aldm_gym.sensor.open_loop.compare_detectors`),
written to ``compare_frames.csv`` with the figures ``compare_frames.png``,
``frame_per_dash.png`` and ``frame_editor.png``. Closed loop: the LKA (IDLE) and the
rule-based LCA on the same seeded episodes
(:func:`~aldm_gym.agents.closed_loop.compare_closed_loop`), written to ``compare.csv``
and ``offset.png`` (with the ACC's target-selection metrics). Target selection where
it is hard (:mod:`~aldm_gym.agents.target_scenes`: curves of R 500–1500 m,
vehicles 60–150 m ahead in the ego and adjacent lanes, cut-ins), generated roads
only: ``compare_targets.csv`` and ``compare_targets.png``. With ``--xodr PATH`` both
halves run on that OpenDRIVE map instead of seeded generated roads (frames on its
driving lanes, episodes with ``road.xodr``).

Sensor conditions (``--sensor-preset camera``, ``--sensor KEY=VALUE``) apply to both
halves (the open loop has no traffic, so no occlusion there) and add the tracking
ALDM and the lane-model filter to the closed loop (``aldm_tracking``,
``aldm_filter``; ``--tracking`` adds them without conditions) and the figure
``frame_conditions.png``: a closed-loop frame with the vehicles, their shadows and
the clutter under every detector's lines. ``--trucks``
sets the closed loop's share of trucks.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from aldm_gym.cli.argtypes import (
    FUNCTION_HELP,
    BadArgument,
    add_env_argument,
    check_env,
    finite_float,
    fraction,
    function_spec,
    key_value,
    make_output_dir,
    nested_pairs,
    non_negative_float,
    output_dir,
    positive_int,
    seed,
    xodr_file,
)
from aldm_gym.cli.report import format_table, write_csv
from aldm_gym.config import defaults, rules
from aldm_gym.errors import ConfigError
from aldm_gym.roads.highway import MIN_RADIUS_BY_SPEED, RoadConfig
from aldm_gym.roads.opendrive.parse import SHIPPED_MAPS


def min_radius(text: str) -> float:
    """``--min-radius`` [m]: from ``RoadConfig.min_radius``'s lower bound to the
    generator's default ``max_radius`` (the radii are drawn between the two)."""
    lo, hi = rules(RoadConfig)["min_radius"].lo, defaults(RoadConfig)["max_radius"]
    value = finite_float(text)
    if not lo <= value <= hi:
        raise argparse.ArgumentTypeError(f"must be in [{lo:.0f}, {hi:.0f}] m, got {text}")
    return value


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym compare`` and its arguments."""
    parser = subparsers.add_parser("compare", help="naive vs ALDM vs ground truth on seeded frames")
    parser.add_argument("--quick", action="store_true", help="small run (about a minute)")
    parser.add_argument("--seed", type=seed, default=0, help="seed of roads and poses")
    parser.add_argument("--out", type=output_dir, default=Path("out/compare"), help="output folder")
    parser.add_argument(
        "--roads", type=positive_int, help="number of seeded roads (default: 5; 2 with --quick)"
    )
    parser.add_argument(
        "--xodr",
        type=xodr_file,
        help="an OpenDRIVE map to compare on (instead of generated roads): a path, or the "
        f"name of a shipped map ({', '.join(SHIPPED_MAPS)})",
    )
    parser.add_argument(
        "--frames",
        type=positive_int,
        help="frames per road and marking model (with --xodr: times --roads, on the one map; "
        "default: 400; 100 with --quick)",
    )
    parser.add_argument(
        "--noise", type=non_negative_float, help="lateral noise σ [m] (sensor lateral_noise: 0)"
    )
    parser.add_argument("--dropout", type=fraction, help="point dropout share (sensor dropout: 0)")
    parser.add_argument(
        "--sensor-preset",
        choices=_presets(),
        help="sensor conditions preset (docs/sensor.md; default: CarMaker's ideal sensor)",
    )
    parser.add_argument(
        "--sensor",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a sensor setting, repeatable, e.g. occlusion=true worn_stretch_rate=2 "
        "(LineSensorConfig; wins over the preset)",
    )
    parser.add_argument(
        "--trucks",
        type=fraction,
        help="share of trucks in the closed loop's traffic (traffic.truck_share; default: 0)",
    )
    parser.add_argument(
        "--tracking",
        action="store_true",
        help="add the tracking ALDM and the lane-model filter to the closed loop (on with "
        "sensor conditions)",
    )
    parser.add_argument(
        "--min-radius",
        type=min_radius,
        help=f"smallest curve radius of the generated roads [m] (default: {MIN_RADIUS:g})",
    )
    parser.add_argument(
        "--episodes",
        type=positive_int,
        help="closed-loop episodes per detector and policy (default: 10; 2 with --quick)",
    )
    parser.add_argument(
        "--mode",
        choices=("robust", "paper"),
        help="the ALDM's mode in the closed loop and the target scenes (default: robust, "
        "the paper's algorithm with its gaps filled, docs/aldm.md; the open loop reports "
        "both)",
    )
    parser.add_argument(
        "--no-closed-loop", action="store_true", help="only the frame-level comparison"
    )
    add_env_argument(
        parser,
        "closed loop; the sensor, detector, road and trucks have their own flags: "
        + ", ".join(sorted(set(COMPARE_FLAGS.values()))),
    )
    parser.add_argument(
        "--function",
        default="builtin",
        metavar="SPEC",
        help="the closed loop's function under test (builtin: IDLE and the rule-based "
        "LCA, each on every seed); " + FUNCTION_HELP.partition(": ")[2],
    )
    parser.add_argument(
        "--scenes",
        type=positive_int,
        help="target-selection scenes per road, generated roads only (default: 200; 50 with "
        "--quick)",
    )
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (there is none either when the output is not a terminal)",
    )
    parser.set_defaults(func=run)
    return parser


FRAME_CONSOLE_COLUMNS: dict[str, str] = {
    "marking_model": "model",
    "detector": "detector",
    "mode": "mode",
    "both_correct": "both ok",
    "strict_f1": "F1",
    "loose_f1": "F1 1.5m",
    "strict_precision": "prec",
    "strict_recall": "recall",
    "strict_tp_fp_fn": "TP/FP/FN",
    "near_mean_m": "err<40m",
    "far_mean_m": "err>40m",
    "mean_preview_m": "preview",
}
"""The open-loop columns printed (with their short headers; ``strict_tp_fp_fn`` joins
the three strict counts); ``compare_frames.csv`` has all of
:data:`~aldm_gym.sensor.open_loop.COLUMNS`."""

CONSOLE_COLUMNS: dict[str, str] = {
    "marking_model": "model",
    "detector": "detector",
    "mode": "mode",
    "departures_per_km": "dep/km",
    "rms_offset_m": "rms off",
    "max_offset_m": "max off",
    "both_correct": "both ok",
    "mean_preview_m": "preview",
    "collisions": "collisions",
    "success_rate": "success",
    "target_accuracy": "target ok",
}
"""The closed-loop columns printed (with their short headers); ``compare.csv`` has all
of :data:`~aldm_gym.agents.closed_loop.CLOSED_LOOP_COLUMNS`."""


def _no_bar(args: argparse.Namespace) -> bool | None:
    """tqdm's ``disable``: True with ``--no-progress``, else None (tqdm leaves the bar
    out when stderr is not a terminal, so a log or a pipe gets no ``\\r`` lines)."""
    return True if args.no_progress else None


def _presets() -> list[str]:
    from aldm_gym.sensor.line_sensor import PRESETS

    return list(PRESETS)


def sensor_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The ``sensor`` settings of the run: preset, ``--sensor`` pairs, noise, dropout.

    :raises BadArgument: naming ``--sensor`` when a key is unknown (with the allowed
        ones) or a value breaks its rule.
    """
    from aldm_gym.config import build_config
    from aldm_gym.sensor.line_sensor import LineSensorConfig

    settings: dict[str, Any] = {}
    if args.sensor_preset is not None:
        settings["preset"] = args.sensor_preset
    settings.update(dict(args.sensor))
    if args.noise is not None:
        settings["lateral_noise"] = args.noise
    if args.dropout is not None:
        settings["dropout"] = args.dropout
    try:
        build_config(LineSensorConfig, settings, where="sensor")
    except (TypeError, ValueError) as exc:
        raise BadArgument("--sensor", str(exc)) from None
    return settings


def conditions_on(settings: dict[str, Any]) -> bool:
    """Whether ``settings`` turn on a sensor condition beyond CarMaker's sensor with
    noise and dropout (the preset, occlusion, wear, clutter, ...)."""
    from aldm_gym.sensor.line_sensor import CONDITIONS_OFF, LineSensorConfig

    config = LineSensorConfig(**settings)
    return any(getattr(config, k) != v for k, v in CONDITIONS_OFF.items() if k != "lateral_noise")


def _describe(settings: dict[str, Any]) -> str:
    """The sensor settings in one phrase, e.g. ``preset camera, occlusion False``."""
    if not settings:
        return "CarMaker's ideal"
    return ", ".join(f"{k} {v}" for k, v in settings.items())


COMPARE_FLAGS = {
    "detector": "the rows",
    "detector_params": "the rows",
    "marking_model": "the rows",
    "sensor": "--sensor/--sensor-preset",
    "road.xodr": "--xodr",
    "road.min_radius": "--min-radius",
    "traffic.truck_share": "--trucks",
}
"""``--env`` keys ``compare`` sets itself, and what sets them."""


def compare_env(args: argparse.Namespace) -> Any:
    """``--env`` (and ``--config``) of the closed loop, checked; :class:`BadArgument`
    for a key the command sets itself (:data:`COMPARE_FLAGS`)."""
    overrides = nested_pairs(args.env)
    for key, _ in args.env:
        for own, flag in COMPARE_FLAGS.items():
            if key == own or key.startswith(own + "."):
                raise BadArgument("--env", f"{key} is set by {flag}, not --env")
    return check_env(overrides)


MIN_RADIUS = MIN_RADIUS_BY_SPEED[110]
"""Default smallest curve radius of the generated roads [m]."""


def check_applicable(args: argparse.Namespace) -> None:
    """Arguments that would have no effect in this run are errors, not ignored.

    :raises BadArgument: a generated-road argument with ``--xodr``, a closed-loop
        argument with ``--no-closed-loop``, or ``--noise``/``--dropout`` and a
        ``--sensor`` pair setting the same value.
    """
    if args.xodr is not None:
        for flag, value in (("--min-radius", args.min_radius), ("--scenes", args.scenes)):
            if value is not None:
                raise BadArgument(flag, "applies to generated roads only, not with --xodr")
    if args.no_closed_loop and args.xodr is not None and args.mode is not None:
        raise BadArgument(
            "--mode", "applies to the closed loop and the target scenes: neither runs here"
        )
    if args.no_closed_loop:
        for flag, given in (
            ("--episodes", args.episodes is not None),
            ("--trucks", args.trucks is not None),
            ("--tracking", args.tracking),
            ("--env", bool(args.env)),
            ("--function", args.function != "builtin"),
        ):
            if given:
                raise BadArgument(flag, "applies to the closed loop, not with --no-closed-loop")
    pairs = dict(args.sensor)
    for flag, key, value in (
        ("--noise", "lateral_noise", args.noise),
        ("--dropout", "dropout", args.dropout),
    ):
        if value is not None and key in pairs:
            raise BadArgument(flag, f"sets {key}, and so does --sensor {key}=...: give one")


def run(args: argparse.Namespace) -> int:
    """``aldm-gym compare``: frame-level comparison, then closed-loop episodes."""
    check_applicable(args)
    if args.min_radius is None:
        args.min_radius = MIN_RADIUS
    if args.trucks is None:
        args.trucks = 0.0
    args.sensor_settings = sensor_settings(args)
    args.env_settings = compare_env(args)
    args.function_object = None if args.function == "builtin" else function_spec(args)
    if args.xodr is not None:
        from aldm_gym.roads import OpenDriveRoad

        try:
            OpenDriveRoad.from_file(args.xodr)
        except (OSError, ValueError) as exc:
            raise BadArgument("--xodr", str(exc)) from None
    out = make_output_dir(args.out)
    written = _compare_frames(args, out)
    if args.xodr is None:
        written += _compare_targets(args, out)
    if not args.no_closed_loop:
        written += _compare_closed_loop(args, out)
    print("wrote " + ", ".join(str(p) for p in written))
    return 0


def _compare_frames(args: argparse.Namespace, out: Path) -> list[Path]:
    """Open loop: the same seeded frames through every detector; table, CSV, figures."""
    from tqdm import tqdm

    from aldm_gym.roads import MARKING_MODELS, HighwayRoad, OpenDriveRoad
    from aldm_gym.sensor import LineSensor
    from aldm_gym.sensor.frame_plot import plot_detector_bars
    from aldm_gym.sensor.open_loop import COLUMNS, compare_detectors

    n_roads = args.roads or (2 if args.quick else 5)
    n_frames = args.frames or (100 if args.quick else 400)
    sensor = LineSensor(args.sensor_settings)
    if args.xodr is not None:
        n_frames *= n_roads  # one map: as many frames as the generated roads would give
        base: list[Any] = [OpenDriveRoad.from_file(args.xodr)]
    else:
        base = [
            HighwayRoad({"seed": args.seed + i, "min_radius": args.min_radius})
            for i in range(n_roads)
        ]
    t0 = time.perf_counter()
    with tqdm(
        total=len(base) * len(MARKING_MODELS) * n_frames,
        desc="frames",
        unit="frame",
        disable=_no_bar(args),
    ) as bar:
        rows = compare_detectors(
            base, frames_per_road=n_frames, sensor=sensor, seed=args.seed, progress=bar.update
        )
    write_csv(out / "compare_frames.csv", rows, COLUMNS)
    print("Frame by frame (open loop, the same frames for every row):")
    shown = [
        {**r, "strict_tp_fp_fn": f"{r['strict_tp']:.0f}/{r['strict_fp']:.0f}/{r['strict_fn']:.0f}"}
        for r in rows
    ]
    print(format_table(shown, list(FRAME_CONSOLE_COLUMNS), FRAME_CONSOLE_COLUMNS))
    print(
        f"{'map ' + str(args.xodr) + ', ' if args.xodr else ''}"
        f"{len(base)} road(s) x {n_frames} frames, each on {len(MARKING_MODELS)} marking "
        f"models, sensor {_describe(args.sensor_settings)}, "
        f"{time.perf_counter() - t0:.1f} s. both ok: both ego lines within 0.3 m of the "
        "true markings, starting <= 25 m, preview >= 60 m; F1, prec, recall, TP/FP/FN: the "
        "four lines matched one to one to the true ones, at that threshold (F1 1.5m: 75 % of "
        "the grid within 1.5 m, as OpenLane); err<40m / err>40m: mean |lateral error| "
        "[m] near and far; preview: how far the ego lines are usable [m] (docs/results.md). "
        f"All {len(COLUMNS)} columns: {out / 'compare_frames.csv'}\n"
    )
    written = [out / "compare_frames.csv"]
    written += _plot_naive_failure(base[0], sensor, n_frames, args.seed, out)
    plot_detector_bars(rows, out / "compare_frames.png")
    written.append(out / "compare_frames.png")
    return written


def worst_naive_frame(
    road: Any, sensor: Any, n_frames: int, seed: int
) -> tuple[Any, Any, float] | None:
    """The frame of the comparison's first road where the naive detection errs most.

    The frames are those :func:`~aldm_gym.sensor.open_loop.compare_detectors` scores
    for road index 0 (same poses, same noise seeds), measured on the road's
    ``per_dash`` model. A frame's naive error is the largest |lateral error| of its ego
    lines (:class:`~aldm_gym.sensor.ground_truth.LineScore`'s ``max_abs_error``) where
    a line is wrong, so the pick is a frame where naive follows the wrong marking.

    :return: ``(frame, lane, error [m])``, or ``None`` if naive is right everywhere.
    """
    from aldm_gym.sensor import score_detection
    from aldm_gym.sensor.detectors import make_detector
    from aldm_gym.sensor.open_loop import sample_poses

    road = road.with_marking_model("per_dash")
    naive = make_detector("naive")
    best: tuple[Any, Any, float] | None = None
    # The seeding of compare_detectors for road index 0.
    rng = np.random.default_rng([seed, 0])
    for pose in sample_poses(road, n_frames, rng):
        noise_rng = np.random.default_rng([seed, 0, int(pose.s * 1000)])
        frame = sensor.measure(road, pose.pose, rng=noise_rng)
        sc = score_detection(naive(frame, road, pose.lane_id), road, frame, pose.lane_id)
        errors = [
            sc[name].max_abs_error
            for name in ("ego_left", "ego_right")
            if not sc[name].correct and np.isfinite(sc[name].max_abs_error)
        ]
        if errors and (best is None or max(errors) > best[2]):
            best = (frame, pose.lane_id, float(max(errors)))
    return best


def _plot_naive_failure(road: Any, sensor: Any, n_frames: int, seed: int, out: Path) -> list[Path]:
    """Figures ``frame_<model>.png``: the per-dash frame of the comparison where the
    naive detection errs most (:func:`worst_naive_frame`), and the same sensor pose on
    the editor road, each with every detector; the paths written (none if naive never
    errs)."""
    from aldm_gym.roads import MARKING_MODELS
    from aldm_gym.sensor.detectors import make_detector
    from aldm_gym.sensor.frame_plot import plot_frames
    from aldm_gym.sensor.open_loop import remeasure

    titles = {"naive": "naive", "aldm": "ALDM", "ground_truth": "ground truth"}
    detectors = {name: make_detector(name) for name in titles}
    found = worst_naive_frame(road, sensor, n_frames, seed)
    if found is None:
        return []
    frame, lane, error = found
    written = []
    for model in MARKING_MODELS:
        r = road.with_marking_model(model)
        f = frame if model == "per_dash" else remeasure(r, frame)
        plot_frames(
            {
                f"{title} ({model})": (f, detectors[name](f, r, lane))
                for name, title in titles.items()
            },
            out / f"frame_{model}.png",
            suptitle=(
                f"{model} road, seed {seed}, lane {lane}: the comparison's frame where naive "
                f"errs most on per_dash (an ego line {error:.1f} m off the true marking); "
                "points labelled side,index"
            ),
        )
        written.append(out / f"frame_{model}.png")
    return written


def _compare_closed_loop(args: argparse.Namespace, out: Path) -> list[Path]:
    """Closed loop: LKA (IDLE) and the rule-based LCA on the same seeded episodes."""
    from tqdm import tqdm

    from aldm_gym.agents.closed_loop import CLOSED_LOOP_COLUMNS, compare_closed_loop
    from aldm_gym.agents.figures import plot_offsets
    from aldm_gym.function import FunctionPolicy, close_function, env_for
    from aldm_gym.roads import MARKING_MODELS
    from aldm_gym.sensor.detectors import DETECTORS

    n_ep = args.episodes or (2 if args.quick else 10)
    seeds = [args.seed + i for i in range(n_ep)]
    settings = args.sensor_settings
    detectors = list(DETECTORS)
    if args.tracking or conditions_on(settings):
        at = detectors.index("aldm") + 1
        detectors[at:at] = ["aldm_tracking", "aldm_filter"]
    traffic = {"truck_share": args.trucks} if args.trucks else None
    function = args.function_object
    env = dict(args.env_settings)
    policies = None
    if function is not None:
        try:
            env = env_for(function, env, given=set(env))
        except ConfigError as exc:
            raise BadArgument("--env", str(exc)) from None
        policies = [lambda made: FunctionPolicy(made, function)]
    t0 = time.perf_counter()
    total = len(MARKING_MODELS) * len(detectors) * (2 if policies is None else 1) * n_ep
    try:
        with tqdm(total=total, desc="episodes", unit="ep", disable=_no_bar(args)) as bar:
            rows, traces = compare_closed_loop(
                seeds,
                detectors=detectors,
                sensor=settings,
                traffic=traffic,
                min_radius=None if args.xodr else args.min_radius,
                xodr=args.xodr,
                aldm_mode=args.mode or "robust",
                progress=bar.update,
                env=env or None,
                policies=policies,
            )
    finally:
        close_function(function)
    write_csv(out / "compare.csv", rows, CLOSED_LOOP_COLUMNS)
    who = "LKA with IDLE and the rule-based LCA" if policies is None else args.function
    print(f"Closed loop ({who}, same seeds):")
    print(format_table(rows, list(CONSOLE_COLUMNS), CONSOLE_COLUMNS))
    print(
        f"{n_ep} seeds × {2 if policies is None else 1} policies per row, "
        f"{time.perf_counter() - t0:.1f} s. dep/km: a "
        "wheel over a marking without a lane change, per km; rms/max offset from the lane "
        "centre [m] without lane changes; both ok: share of steps with both ego lines "
        "correct; preview [m]; success: episodes without collision or departure; target "
        f"ok: the ACC's target right. All {len(CLOSED_LOOP_COLUMNS)} columns: "
        f"{out / 'compare.csv'}\n"
    )
    plot_offsets(traces, out / "offset.png", crashed=_crashed(traces, args))
    written = [out / "compare.csv", out / "offset.png"]
    if conditions_on(settings):
        written.append(_plot_conditions(args, traffic, out))
    return written


def _plot_conditions(args: argparse.Namespace, traffic: dict[str, Any] | None, out: Path) -> Path:
    """``frame_conditions.png``: a closed-loop frame of the first seed under the
    conditions, with vehicles, shadows and clutter, under every detector's lines."""
    from aldm_gym.agents.closed_loop import conditions_scene
    from aldm_gym.sensor.frame_plot import plot_conditions_frame

    scene = conditions_scene(
        args.seed,
        sensor=args.sensor_settings,
        traffic=traffic,
        road={"xodr": str(args.xodr)} if args.xodr else {"min_radius": args.min_radius},
    )
    trucks = f", trucks {args.trucks:.0%}" if args.trucks else ""
    plot_conditions_frame(
        scene,
        out / "frame_conditions.png",
        title=(
            f"sensor {_describe(args.sensor_settings)}{trucks}: per_dash road, seed "
            f"{args.seed}, t = {scene['step'] / 10:.1f} s, the frame with most vehicles ahead"
        ),
    )
    return out / "frame_conditions.png"


def _crashed(traces: dict[tuple[str, str], list[Any]], args: argparse.Namespace) -> dict:
    """Which traces end in a collision: with the comparison's env config (no
    ``offroad_terminal``/``departure_terminal``, 40 s episodes ending far before the
    road does), a generated-road episode that has fewer steps than the longest of the
    same seed was terminated, and only a collision terminates it. On a map an episode
    also ends where the ego leaves the map, so no trace is marked there."""
    if args.xodr is not None or not traces:
        return {}
    longest = max(len(t) for t in traces.values())
    return {key: 0 < len(t) < longest for key, t in traces.items()}


def _compare_targets(args: argparse.Namespace, out: Path) -> list[Path]:
    """Target selection in hard scenes (curves, vehicles in adjacent lanes, cut-ins)."""
    from tqdm import tqdm

    from aldm_gym.agents.figures import plot_target_selection
    from aldm_gym.agents.target_scenes import (
        DISTANCE_BINS,
        TARGET_COLUMNS,
        compare_target_selection,
    )
    from aldm_gym.roads import MARKING_MODELS
    from aldm_gym.sensor.detectors import DETECTORS

    n_roads = args.roads or (2 if args.quick else 5)
    per_road = args.scenes or (50 if args.quick else 200)
    seeds = [args.seed + i for i in range(n_roads)]
    t0 = time.perf_counter()
    total = n_roads * per_road * len(MARKING_MODELS) * len(DETECTORS)
    with tqdm(total=total, desc="target scenes", unit="scene", disable=_no_bar(args)) as bar:
        rows, curves = compare_target_selection(
            seeds, per_road, aldm_mode=args.mode or "robust", progress=bar.update
        )
    write_csv(out / "compare_targets.csv", rows, TARGET_COLUMNS)
    print("ACC target selection (curves R 500-1500 m, one vehicle ahead per scene):")
    print(format_table(rows, TARGET_COLUMNS))
    print(
        f"{n_roads} roads x {per_road} scenes, {time.perf_counter() - t0:.1f} s. A scene is "
        "correct when the vehicle is selected exactly when it is in the ego lane.\n"
    )
    plot_target_selection(curves, DISTANCE_BINS, out / "compare_targets.png")
    return [out / "compare_targets.csv", out / "compare_targets.png"]
