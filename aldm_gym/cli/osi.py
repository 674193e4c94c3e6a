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
    config_file,
    existing_file,
    key_value,
    nested_pairs,
    positive_int,
    trace_file,
)

MARKING_CHOICES = ("per_dash", "editor")
"""How boundaries become line objects: each painted stretch, or each boundary."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Declare ``aldm-gym osi`` with ``detect``."""
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
    return parser


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


def run_detect(args: argparse.Namespace) -> int:
    """``aldm-gym osi detect``."""
    from tqdm import tqdm

    from aldm_gym.errors import MissingOSIDependencies, TraceError
    from aldm_gym.osi import detect_trace

    if args.tracking and args.detector != "aldm":
        raise BadArgument("--tracking", "tracking is the ALDM's: use it with --detector aldm")
    from aldm_gym.config import build_config
    from aldm_gym.errors import ConfigError
    from aldm_gym.sensor.line_sensor import LineSensorConfig

    pairs = list(args.env)
    if args.osi_config:
        kept = [p for p in args.osi_config if p[0].split(".")[0] in OSI_SECTIONS]
        if len(kept) < len(args.osi_config):
            print(
                f"note: osi detect takes the {' and '.join(OSI_SECTIONS)} sections of "
                "--config only; the rest is the env's",
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
    if args.tracking:
        if "tracking" in params:
            raise BadArgument("--env", "detector_params.tracking: so does --tracking; give one")
        params["tracking"] = True
    if params and args.detector != "aldm":
        raise BadArgument("--env", "detector_params are the ALDM's: use --detector aldm")
    if params.get("tracking") and args.jobs > 1:
        raise BadArgument("--jobs", "the tracking ALDM carries lanes between frames: one job")
    try:
        sensor = build_config(LineSensorConfig, sensor_pairs, where="sensor")
    except ConfigError as exc:
        raise BadArgument("--sensor" if not env.get("sensor") else "--env", str(exc)) from None
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
            )
    except MissingOSIDependencies as exc:
        raise BadArgument("IN", str(exc)) from None
    except TraceError as exc:
        raise BadArgument("IN", str(exc)) from None
    found = ", ".join(f"{k} {100 * v:.0f} %" for k, v in summary.found.items())
    print(f"{summary.frames} frames -> {summary.out}; lines found: {found}")
    return 0
