"""``aldm-gym osi detect``: the line sensor and a detector on an ASAM OSI trace.

``detect IN --out OUT`` reads every ``SensorView`` (or ``GroundTruth``) of a trace
(``.mcap`` or binary ``.osi``, e.g. written by ``esmini --osi_file`` or by the env's
``osi.trace``), measures its lane boundaries with the CarMaker line sensor from the
host vehicle, runs the detector, and writes one ``SensorData`` per frame
(``DetectedLaneBoundary``: :mod:`aldm_gym.osi`). docs/osi.md.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from aldm_gym.cli.argtypes import (
    BadArgument,
    check_env,
    check_parent,
    config_file,
    existing_file,
    key_value,
    nested_pairs,
    positive_int,
    seed,
    trace_file,
)

MARKING_CHOICES = ("per_dash", "editor")
"""How boundaries become line objects: each painted stretch, or each boundary."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym osi`` with ``detect`` and ``fmu``."""
    parser = subparsers.add_parser("osi", help="ASAM OSI traces: lane detection behind a simulator")
    sub = parser.add_subparsers(dest="osi_command", required=True, metavar="ACTION")
    det = sub.add_parser("detect", help="SensorView/GroundTruth trace in, SensorData trace out")
    det.add_argument("input", type=existing_file, metavar="IN", help="a .mcap or .osi trace")
    det.add_argument("--out", type=trace_file, required=True, help="the SensorData trace to write")
    det.add_argument("--detector", choices=("aldm", "naive"), default="aldm")
    det.add_argument(
        "--tracking", action="store_true", help="the tracking ALDM (lanes carried over frames)"
    )
    det.add_argument("--marking-model", choices=MARKING_CHOICES, default="per_dash")
    det.add_argument(
        "--sensor",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a line-sensor setting, repeatable, e.g. preset=camera or mount_x=2.0 "
        "(LineSensorConfig; the mount applies to a GroundTruth input, which has none)",
    )
    det.add_argument(
        "--env",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="an env setting of the sensor or the detector, repeatable: sensor.KEY (as "
        "--sensor KEY) or detector_params.KEY, e.g. detector_params.tracking=model",
    )
    det.add_argument(
        "--config",
        dest="osi_config",
        type=config_file,
        default=None,
        metavar="FILE",
        help="an env settings file (YAML or JSON); its sensor and detector_params sections "
        "apply, the rest is the env's (--env wins)",
    )
    det.add_argument(
        "--seed",
        type=seed,
        default=0,
        help="seed of a noisy sensor's draws (per frame: any --jobs gives the same trace)",
    )
    det.add_argument(
        "--type",
        choices=("SensorView", "GroundTruth"),
        help="the input's message type (default: an MCAP's SensorView channel, else its "
        "GroundTruth one; a .osi file's from its name, *_gt.osi, else SensorView)",
    )
    det.add_argument("--topic", help="the MCAP channel to read (default: by --type)")
    det.add_argument(
        "--jobs",
        type=positive_int,
        default=1,
        help="processes (frames dealt out in turn; not with --tracking)",
    )
    det.add_argument("--no-progress", action="store_true", help="no progress bar")
    det.set_defaults(func=run_detect)
    fmu = sub.add_parser(
        "fmu", help="write the line sensor and a detector as an OSMP sensor-model FMU"
    )
    fmu.add_argument("out", type=fmu_file, metavar="OUT.fmu", help="the FMU to write")
    fmu.add_argument("--detector", choices=("aldm", "naive"), default="aldm")
    fmu.add_argument(
        "--tracking",
        choices=("none", "points", "model"),
        default="none",
        help="the single-frame detector, the tracking ALDM, or the lane-model filter",
    )
    fmu.add_argument("--marking-model", choices=MARKING_CHOICES, default="per_dash")
    fmu.add_argument(
        "--sensor",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a line-sensor setting, repeatable (LineSensorConfig), e.g. preset=camera",
    )
    fmu.add_argument(
        "--env",
        type=key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="sensor.KEY or detector_params.KEY, repeatable (the FMU's start values; its "
        "parameters can change them)",
    )
    fmu.add_argument(
        "--config",
        dest="osi_config",
        type=config_file,
        default=None,
        metavar="FILE",
        help="an env settings file; its sensor and detector_params sections apply",
    )
    fmu.set_defaults(func=run_fmu)
    return parser


def fmu_file(text: str) -> Any:
    """An ``.fmu`` to write, in a writable place."""
    from pathlib import Path

    path = Path(text)
    if path.suffix.lower() != ".fmu":
        raise argparse.ArgumentTypeError(f"{path}: give a .fmu file name")
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{path} is a folder")
    check_parent(path)
    return path


def _sensor_and_detector(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``--env`` pairs of ``osi detect``: the ``sensor`` and ``detector_params``
    sections only (:class:`BadArgument` naming another key, or a bad value of these)."""
    env = nested_pairs(pairs)
    for key in env:
        if key in ("detector", "marking_model"):
            raise BadArgument("--env", f"{key} has its own flag: --{key.replace('_', '-')}")
        if key not in OSI_SECTIONS:
            raise BadArgument(
                "--env",
                f"{key}: osi detect takes the sensor's and the detector's settings only "
                "(sensor.KEY, detector_params.KEY)",
            )
    check_env(env)
    return env


OSI_SECTIONS = ("sensor", "detector_params")
"""The env settings ``osi detect`` takes (``--env``, ``--config``)."""


def _settings(
    args: argparse.Namespace, tracking: dict[str, Any], flag: str
) -> tuple[Any, dict[str, Any], dict[str, Any]]:
    """The line sensor's config (and the settings it was built from) and the
    detector's params of ``osi detect``/``osi fmu`` from ``--sensor``, ``--env``,
    ``--config`` and the tracking flag ``flag``."""
    from aldm_gym.config import build_config
    from aldm_gym.errors import ConfigError
    from aldm_gym.sensor.line_sensor import LineSensorConfig

    pairs = list(args.env)
    if args.osi_config:
        kept = [p for p in args.osi_config if p[0].split(".")[0] in OSI_SECTIONS]
        if len(kept) < len(args.osi_config):
            print(
                f"note: osi {args.osi_command} takes the {' and '.join(OSI_SECTIONS)} "
                "sections of --config only; the rest is the env's",
                file=sys.stderr,
            )
        pairs = [*kept, *pairs]
    env = _sensor_and_detector(pairs)
    sensor_pairs = dict(args.sensor)
    for key, value in env.get("sensor", {}).items():
        if key in sensor_pairs:
            raise BadArgument("--env", f"sensor.{key}: so does --sensor {key}=...; give one")
        sensor_pairs[key] = value
    params = dict(env.get("detector_params", {}))
    if tracking:
        if "tracking" in params:
            raise BadArgument("--env", f"detector_params.tracking: so does {flag}; give one")
        params.update(tracking)
    if params and args.detector != "aldm":
        raise BadArgument("--env", "detector_params are the ALDM's: use --detector aldm")
    try:
        sensor = build_config(LineSensorConfig, sensor_pairs, where="sensor")
    except ConfigError as exc:
        raise BadArgument("--sensor" if not env.get("sensor") else "--env", str(exc)) from None
    return sensor, sensor_pairs, params


def run_detect(args: argparse.Namespace) -> int:
    """``aldm-gym osi detect``."""
    from tqdm import tqdm

    from aldm_gym.errors import MissingOSIDependencies, TraceError
    from aldm_gym.osi import detect_trace

    if args.tracking and args.detector != "aldm":
        raise BadArgument("--tracking", "tracking is the ALDM's: use it with --detector aldm")
    tracking = {"tracking": True} if args.tracking else {}
    sensor, _, params = _settings(args, tracking, "--tracking")
    if params.get("tracking") and args.jobs > 1:
        raise BadArgument("--jobs", "the tracking ALDM carries lanes between frames: one job")
    try:
        with tqdm(desc="frames", unit="frame", disable=True if args.no_progress else None) as bar:
            summary = detect_trace(
                args.input,
                args.out,
                detector=args.detector,
                detector_params=params or None,
                marking_model=args.marking_model,
                sensor=sensor,
                message_type=args.type,
                topic=args.topic,
                jobs=args.jobs,
                progress=bar.update,
                seed=args.seed,
            )
    except MissingOSIDependencies as exc:
        raise BadArgument("IN", str(exc)) from None
    except TraceError as exc:
        raise BadArgument("IN", str(exc)) from None
    found = ", ".join(f"{k} {100 * v:.0f} %" for k, v in summary.found.items())
    print(f"{summary.frames} frames -> {summary.out}; lines found: {found}")
    return 0


def run_fmu(args: argparse.Namespace) -> int:
    """``aldm-gym osi fmu``."""
    from aldm_gym.errors import ConfigError, MissingFMIDependencies, MissingOSIDependencies
    from aldm_gym.osi.osmp import OSMP_VERSION, build_sensor_fmu, detector_params_for

    if args.tracking != "none" and args.detector != "aldm":
        raise BadArgument("--tracking", "tracking is the ALDM's: use it with --detector aldm")
    tracking = detector_params_for(args.tracking)
    _, sensor, params = _settings(args, tracking, "--tracking")
    # the FMU's own parameter: from --tracking, or from --env/--config's
    # detector_params.tracking (True: the tracking ALDM, "model": the filter)
    given = params.pop("tracking", None)
    mode = args.tracking
    if mode == "none" and given is not None:
        modes = {True: "points", False: "none", "model": "model"}
        if isinstance(given, bool | str) and given in modes:
            mode = modes[given]
        else:
            raise BadArgument(
                "--env", f"detector_params.tracking must be true, false or 'model', got {given!r}"
            )
    try:
        path = build_sensor_fmu(
            args.out,
            detector=args.detector,
            tracking=mode,
            marking_model=args.marking_model,
            sensor=sensor,
            detector_params=params,
        )
    except (MissingFMIDependencies, MissingOSIDependencies) as exc:
        raise BadArgument("OUT", str(exc)) from None
    except ConfigError as exc:
        raise BadArgument("--env", str(exc)) from None
    print(
        f"wrote {path}: an OSMP {OSMP_VERSION} sensor-model FMU (FMI 2.0 co-simulation), "
        f"{args.detector}, tracking {mode}, {args.marking_model}; it runs in a "
        "Python with aldm-gym[osi,fmi] installed (docs/osi.md)"
    )
    return 0
