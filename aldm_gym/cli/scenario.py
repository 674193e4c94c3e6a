"""``aldm-gym scenario run|suite``: OpenSCENARIO files on the env, judged by UN R157.

``run FILE.xosc`` plays one concrete scenario with the function under test (LKA on the
detected lanes, ACC, AEB) and prints its criteria. ``suite PATH`` plays many: a
parameter-variation file (its concrete runs, those that break a parameter constraint
discarded), a folder of them, or a folder of concrete scenarios, for every detector and
marking model given,
in parallel processes; it writes ``scenario_runs.csv``, a console table per scenario ×
detector × marking model (runs, pass rate, collisions, departures, min TTC, min time
gap, failing parameter sets) and ``scenario_pass_rates.png``; with ``--address`` the
runs go to a Ray cluster. Criteria:
:mod:`aldm_gym.harness.criteria`; docs/scenarios.md.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from aldm_gym.cli.argtypes import (
    BadArgument,
    add_env_argument,
    add_function_argument,
    check_env,
    existing_file,
    function_spec,
    image_file,
    key_value,
    make_output_dir,
    nested_pairs,
    output_dir,
    positive_int,
    ray_address,
    trace_file,
)

DETECTOR_CHOICES = ("naive", "aldm", "ground_truth")
"""Detectors a suite compares."""

MARKING_CHOICES = ("per_dash", "editor")
"""Marking models a suite compares."""

SCENARIO_OWNS = (
    "road",
    "traffic",
    "lanes_count",
    "vehicles_count",
    "vehicles_density",
    "initial_lane_id",
    "initial_speed",
    "ego_spacing",
    "other_vehicles_type",
    "controlled_vehicles",
)
"""Env settings the scenario decides (its map, its entities as the traffic): given
with ``--env`` they give way to it, with one note."""

OWN_FLAGS = {
    "scenario": "the scenario file",
    "detector": "--detector (suite: --detectors)",
    "marking_model": "--marking-model (suite: --marking-models)",
    "osi": "--osi (scenario run)",
}
"""Env settings the scenario commands set with their own arguments."""


def _names(allowed: tuple[str, ...]) -> Any:
    def parse(text: str) -> list[str]:
        items = [t.strip() for t in text.split(",") if t.strip()]
        bad = [t for t in items if t not in allowed]
        if not items or bad:
            raise argparse.ArgumentTypeError(
                f"must be a comma-separated list of {list(allowed)}, got {text!r}"
            )
        return list(dict.fromkeys(items))

    return parse


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym scenario`` with ``run`` and ``suite``."""
    parser = subparsers.add_parser("scenario", help="play OpenSCENARIO files, judged by UN R157")
    sub = parser.add_subparsers(dest="scenario_command", required=True, metavar="ACTION")
    run = sub.add_parser("run", help="play one concrete scenario")
    run.add_argument("file", type=existing_file, metavar="FILE.xosc", help="a concrete scenario")
    run.add_argument(
        "--param",
        type=key_value,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a value for one of its parameters (repeatable)",
    )
    add_env_argument(run, "for the run; the scenario's map and traffic take precedence")
    add_function_argument(run)
    _add_handover(run)
    run.add_argument("--detector", choices=DETECTOR_CHOICES, default="aldm")
    run.add_argument("--marking-model", choices=MARKING_CHOICES, default="per_dash")
    run.add_argument("--video", type=gif_file, help="an animated GIF of the run (e.g. run.gif)")
    run.add_argument(
        "--osi",
        type=trace_file,
        metavar="TRACE",
        help="write the run as ASAM OSI SensorView + SensorData (a .mcap or .osi trace; "
        "needs the [osi] extra)",
    )
    run.set_defaults(func=run_one)
    suite = sub.add_parser("suite", help="play a folder of scenarios or a variation file")
    suite.add_argument(
        "path", type=Path, metavar="DIR_OR_VARIATION", help="a folder of .xosc or a variation file"
    )
    suite.add_argument("--detectors", type=_names(DETECTOR_CHOICES), default=list(DETECTOR_CHOICES))
    suite.add_argument(
        "--marking-models", type=_names(MARKING_CHOICES), default=list(MARKING_CHOICES)
    )
    suite.add_argument(
        "--max-runs",
        type=positive_int,
        help="per scenario file: at most this many concrete runs, evenly spaced "
        "through the variation's order (default: all)",
    )
    suite.add_argument("--jobs", type=positive_int, default=2, help="parallel processes")
    suite.add_argument(
        "--address",
        type=ray_address,
        help="run on the Ray cluster there ('auto' or host:port; needs the [ray] extra); "
        "--jobs does not apply",
    )
    add_env_argument(suite, "for every run; the scenario's map and traffic take precedence")
    add_function_argument(suite)
    _add_handover(suite)
    suite.add_argument("--out", type=output_dir, default=Path("scenario_results"))
    suite.add_argument("--no-progress", action="store_true", help="no progress bar")
    suite.set_defaults(func=run_suite)
    return parser


def _add_handover(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--handover",
        choices=("action", "init"),
        default="action",
        help="when the function under test takes the ego: at the scenario's "
        "ActivateControllerAction (action, the default), or from the start (init: test "
        "protocols without a controller, as Euro NCAP's files)",
    )


def scenario_env(pairs: list[tuple[str, Any]], handover: str = "action") -> Any:
    """``--env`` pairs as the env settings of a scenario run, checked as the env checks
    them (:class:`BadArgument` naming the key and the allowed ones). Settings the
    command has arguments for are refused; those the scenario decides (its map and
    traffic, :data:`SCENARIO_OWNS`) are dropped with one note on stderr."""
    import sys

    overrides = nested_pairs(pairs)
    for key in overrides:
        if key in OWN_FLAGS:
            raise BadArgument("--env", f"{key} is set by {OWN_FLAGS[key]}, not --env")
    dropped = [key for key in overrides if key in SCENARIO_OWNS]
    if handover != "action":
        overrides["scenario"] = {"handover": handover}
    checked = check_env(overrides)
    if dropped:
        print(
            f"note: the scenario's own map and traffic take precedence over --env "
            f"{', '.join(sorted(dropped))} (ignored)",
            file=sys.stderr,
        )
    return checked.without(*dropped)


def gif_file(text: str) -> Path:
    """An animated GIF to write (``.gif``) in a writable place."""
    path = Path(text)
    if path.suffix.lower() != ".gif":
        raise argparse.ArgumentTypeError(f"{path}: give a .gif file name")
    image_file(str(path.with_suffix(".png")))  # the same checks of the place
    return path


def _scenario_error(argument: str, exc: Exception) -> BadArgument:
    return BadArgument(argument, str(exc))


def run_one(args: argparse.Namespace) -> int:
    """``aldm-gym scenario run``."""
    from aldm_gym.errors import AldmGymError, ConfigError, MissingOSIDependencies
    from aldm_gym.harness.criteria import run_scenario

    frames: list[Any] | None = [] if args.video is not None else None
    config = scenario_env(args.env, args.handover)
    if args.osi is not None:
        config = config.merged({"osi": {"trace": str(args.osi)}})
    function = function_spec(args)
    try:
        result = run_scenario(
            args.file,
            dict(args.param),
            detector=args.detector,
            marking_model=args.marking_model,
            config=config,
            frames=frames,
            function=function,
        )
    except MissingOSIDependencies as exc:
        raise _scenario_error("--osi", exc) from None
    except ConfigError as exc:  # --env sets what the function needs otherwise
        raise _scenario_error("--env", exc) from None
    except AldmGymError as exc:  # the file, its map, a --param, a position off the map
        raise _scenario_error("FILE.xosc", exc) from None
    finally:
        from aldm_gym.function import close_function

        close_function(function)
    what = f"{args.detector}, {args.marking_model}" + (
        "" if args.function == "builtin" else f", function {args.function}"
    )
    if result.error:
        print(f"{result.scenario} ({what}): NOT JUDGED")
        print(f"  {result.error}")
        return 1
    verdict = "PASS" if result.passed else "FAIL"
    print(f"{result.scenario} ({what}): {verdict}")
    for name, ok, detail in (
        (
            "no_collision (R157 5.1.1)",
            result.no_collision,
            f"collision: {result.collision}"
            + ("" if result.collision_required else " (marked unavoidable: not judged)"),
        ),
        ("in_lane (R157 5.2.1)", result.in_lane, f"departure steps: {result.departures}"),
        (
            "time_gap (R157 5.2.3.3)",
            result.time_gap,
            f"min time gap {_fmt(result.min_time_gap_s)} s",
        ),
    ):
        print(f"  {'ok  ' if ok else 'FAIL'} {name}: {detail}")
    print(
        f"  min TTC {_fmt(result.min_ttc_s)} s; {result.time_s:.1f} s simulated; "
        f"{'stop trigger fired' if result.finished else 'ended before the stop trigger'}"
    )
    if args.osi is not None:
        print(f"wrote the OSI trace {args.osi}")
    if frames:
        from aldm_gym.scenario.video import write_gif

        write_gif(frames, args.video)
        print(f"wrote {args.video}")
    return 0 if result.passed else 1


def _check_cluster(address: str) -> None:
    """Ray is installed and something answers at ``address``."""
    try:
        import ray  # noqa: F401
    except ImportError:
        raise BadArgument(
            "--address", "needs Ray: pip install 'aldm-gym[ray]' (docs/cluster.md)"
        ) from None
    from aldm_gym.errors import ClusterError
    from aldm_gym.training.rllib.cluster import check_reachable

    if address != "auto":
        try:
            check_reachable(address)
        except ClusterError as exc:
            raise BadArgument("--address", str(exc)) from None


def _fmt(x: float) -> str:
    return "inf" if not math.isfinite(x) else f"{x:.2f}"


def run_suite(args: argparse.Namespace) -> int:
    """``aldm-gym scenario suite``."""
    from aldm_gym.errors import InputError
    from aldm_gym.harness.suite import plan_suite, play_suite, summarise, write_outputs

    config = scenario_env(args.env, args.handover)
    from aldm_gym.function import close_function

    close_function(function_spec(args))  # loaded once here: a bad SPEC stops the suite now
    try:
        jobs = plan_suite(
            args.path,
            args.detectors,
            args.marking_models,
            args.max_runs,
            config=config,
            function=args.function,
        )
    except (InputError, FileNotFoundError) as exc:
        raise _scenario_error("DIR_OR_VARIATION", exc) from None
    if args.address is not None:
        _check_cluster(args.address)
    out = make_output_dir(args.out)
    results = play_suite(
        jobs, processes=args.jobs, progress=not args.no_progress, address=args.address
    )
    rows = summarise(results)
    write_outputs(results, rows, out)
    from aldm_gym.harness.suite import format_table

    print(format_table(rows))
    print(
        f"wrote {out / 'scenario_runs.csv'}, {out / 'scenario_summary.csv'}, "
        f"{out / 'scenario_pass_rates.png'}"
    )
    return 0
