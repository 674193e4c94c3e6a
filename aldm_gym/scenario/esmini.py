"""The reference player: esmini and aldm-gym's player on one file, step by step.

esmini (github.com/esmini/esmini, MPL-2.0) is the open OpenSCENARIO player most of the
field checks against. This module plays a scenario in both with every entity scripted
(the ego's ``ActivateControllerAction`` taken out, so no function under test drives),
records every entity's reference point at every step and when every event starts, and
says where the two agree:

>>> from aldm_gym.scenario.esmini import agreement
>>> report = agreement("cut_in.xosc", binary="esmini/bin/esmini")   # doctest: +SKIP
>>> report.ok, report.worst_distance, report.event_offsets             # doctest: +SKIP

Positions are compared in OpenDRIVE's inertial frame (x east, y north [m]), at the
reference point (a vehicle's rear axle centre), and headings [rad]; event starts by
the time of their ``startTransition`` [s]. The tests run this on a corpus where the binary exists
(docs/scenarios.md, "Agreement with esmini").
"""

from __future__ import annotations

import csv
import math
import re
import subprocess
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from aldm_gym.errors import ScenarioError

__all__ = [
    "Agreement",
    "Trace",
    "agreement",
    "esmini_trace",
    "player_trace",
    "scripted_copy",
]

POSITION_TOLERANCE = 0.05
"""Largest distance [m] between the two players' reference points that agrees."""

HEADING_TOLERANCE = 0.05
"""Largest difference [rad] between the two players' headings that agrees."""


@dataclass(frozen=True)
class Trace:
    """One play of a scenario: every entity at every step.

    :ivar times: ``(K,)`` simulation times [s].
    :ivar poses: per entity ``(K, 4)``: reference point x, y [m] (OpenDRIVE's inertial
        frame), heading [rad] (counter-clockwise from x), speed [m/s]; NaN rows where
        the entity is not in the scenario.
    :ivar starts: per event name, the times [s] it started, in order.
    :ivar stop: the time [s] the storyboard's stop trigger fired, None if it did not.
    """

    times: np.ndarray
    poses: dict[str, np.ndarray]
    starts: dict[str, list[float]] = field(default_factory=dict)
    stop: float | None = None


@dataclass(frozen=True)
class Agreement:
    """How two plays of one scenario agree (:func:`compare`).

    :ivar steps: the number of steps both played.
    :ivar distance: per entity, the largest distance [m] between the reference points.
    :ivar first_off: per entity, the first time [s] the distance exceeded the
        tolerance (None: never).
    :ivar event_offsets: per event, the largest difference [s] of its start times
        (``inf`` when one player started it a different number of times).
    :ivar stop_offset: difference [s] of the stop times (``inf``: one player stopped).
    """

    steps: int
    distance: dict[str, float]
    first_off: dict[str, float | None]
    event_offsets: dict[str, float]
    stop_offset: float
    step: float
    heading: dict[str, float] = field(default_factory=dict)
    """Per entity, the largest difference of the headings [rad]."""
    tolerance: float = POSITION_TOLERANCE

    @property
    def worst_distance(self) -> float:
        """The largest distance [m] of any entity."""
        return max(self.distance.values(), default=0.0)

    @property
    def late_events(self) -> dict[str, float]:
        """Events that start more than one step apart, with their offsets [s]."""
        return {k: v for k, v in self.event_offsets.items() if not v <= self.step + 1e-6}

    @property
    def ok(self) -> bool:
        """Every entity within the tolerances (position and heading), every event start
        and the stop within one step."""
        return (
            self.worst_distance <= self.tolerance
            and max(self.heading.values(), default=0.0) <= HEADING_TOLERANCE
            and not self.late_events
            and self.stop_offset <= self.step + 1e-6
        )

    def summary(self) -> str:
        """One line: the verdict, the worst entity and the late events."""
        worst = max(self.distance, key=self.distance.__getitem__, default="-")
        text = (
            f"{'agrees' if self.ok else 'differs'}: {self.steps} steps, worst {worst} "
            f"{self.worst_distance:.3f} m"
        )
        if self.first_off.get(worst) is not None:
            text += f" (off from {self.first_off[worst]:.1f} s)"
        turned = max(self.heading, key=self.heading.__getitem__, default=None)
        if turned is not None and self.heading[turned] > HEADING_TOLERANCE:
            text += f", {turned}'s heading {self.heading[turned]:.3f} rad apart"
        if self.late_events:
            text += f", events apart: {self.late_events}"
        if self.stop_offset > self.step + 1e-6:
            text += f", stop {self.stop_offset:.2f} s apart"
        return text


# ---------------------------------------------------------------- the scripted copy
_PATH_ATTRIBUTES = (
    ("LogicFile", "filepath"),
    ("SceneGraphFile", "filepath"),
    ("Directory", "path"),
)


def scripted_copy(
    xosc: str | Path,
    folder: str | Path,
    max_time: float = 600.0,
    parameters: Mapping[str, Any] | None = None,
) -> Path:
    """A copy of ``xosc`` in ``folder`` with every ``ActivateControllerAction`` taken
    out (an event, maneuver left empty goes too), so that every entity follows its
    actions in both players, and a stop at ``max_time`` [s] added to the storyboard's
    stop trigger (esmini runs a file without one for ever). Relative map and catalog
    paths are made absolute, and the original folder's entries are linked into
    ``folder`` for paths that parameters give. ``parameters`` override the file's
    declarations (written into the copy, so that both players play them).

    :raises ScenarioError: the file is not XML.
    """
    from aldm_gym.xmlfile import parse_xml

    source = Path(xosc)
    root = parse_xml(source, "OpenSCENARIO").getroot()
    base = source.resolve().parent
    for tag, attr in _PATH_ATTRIBUTES:
        for el in root.iter(tag):
            value = el.get(attr)
            if value and "$" not in value and not Path(value).is_absolute():
                el.set(attr, str((base / value).resolve()))
    _resolve_expressions(source, root, parameters or {})
    for activate in list(root.iter("ActivateControllerAction")):
        holder = activate.getparent()  # ControllerAction
        # up to the PrivateAction (Init, or inside an Action)
        while holder is not None and holder.tag != "PrivateAction":
            holder = holder.getparent()
        if holder is None:
            continue
        _remove_empty(holder)
    _stop_at(root, max_time)
    out = Path(folder) / source.name
    # paths set by parameters (``filepath="$Road"``) resolve beside the copy as beside
    # the original: the original folder's entries are linked into ``folder``
    for entry in base.iterdir():
        link = Path(folder) / entry.name
        if entry.name != source.name and not link.exists():
            link.symlink_to(entry)
    out.write_bytes(etree.tostring(root, xml_declaration=True, encoding="utf-8"))
    return out


def _resolve_expressions(source: Path, root: Any, overrides: Mapping[str, Any]) -> None:
    """Write every ``${...}`` of the file's top-level scope as the double it evaluates
    to (17 significant digits). esmini 3.6 keeps an expression's result as text with 6
    decimals (C++ ``std::to_string``): 60 / 3.6 becomes 16.666667, and a scenario that
    triggers at the very distance its numbers reach breaks the tie by that rounding.
    The copy gives both players the same doubles."""
    from aldm_gym.scenario.declarations import bind, declarations_from_xml
    from aldm_gym.scenario.expressions import format_value, parameter_name, resolve

    top = root.find("ParameterDeclarations")
    values = bind(declarations_from_xml(top), dict(overrides), source.name)
    for decl in top if top is not None else ():
        name = parameter_name(decl.get("name") or "") if isinstance(decl.tag, str) else ""
        if name in values:
            if "${" in (decl.get("value") or "") or name in overrides:
                decl.set("value", format_value(values[name]))
    for el in root.iter():
        if not isinstance(el.tag, str) or el.tag == "ParameterDeclaration":
            continue
        if any(a.tag == "ParameterDeclarations" for a in el.iterancestors()):
            continue  # declarations below the file level: their own scope
        for name, raw in el.attrib.items():
            if name != "name" and raw.strip().startswith("${"):  # names are labels
                value = resolve(raw, values, f"{source.name}:{el.sourceline}")
                el.set(name, format_value(value))


def _stop_at(root: Any, max_time: float) -> None:
    """Add ``SimulationTime > max_time`` as a condition group of the storyboard's stop
    trigger (making one where there is none)."""
    board = root.find("Storyboard")
    if board is None:
        return
    stop = board.find("StopTrigger")
    if stop is None:
        stop = etree.SubElement(board, "StopTrigger")
    group = etree.SubElement(stop, "ConditionGroup")
    condition = etree.SubElement(
        group, "Condition", name="max_time", delay="0", conditionEdge="none"
    )
    by_value = etree.SubElement(condition, "ByValueCondition")
    etree.SubElement(
        by_value, "SimulationTimeCondition", value=repr(float(max_time)), rule="greaterThan"
    )


def _remove_empty(element: Any) -> None:
    """Remove ``element``, then each ancestor that it leaves without a required child."""
    needs = {"Action": "PrivateAction", "Event": "Action", "Maneuver": "Event"}
    parent = element.getparent()
    parent.remove(element)
    while parent is not None and parent.tag in ("Action", "Event", "Maneuver"):
        children = [c for c in parent if c.tag == needs[parent.tag]]
        if parent.tag == "Action":
            children = [c for c in parent if isinstance(c.tag, str)]
        if children:
            return
        grand = parent.getparent()
        grand.remove(parent)
        parent = grand


# ---------------------------------------------------------------- esmini
_START = re.compile(
    r"^\[(\d+\.\d+)\] \[info\] (.+?) standbyState -> startTransition -> runningState"
)
_STOP = re.compile(r"^\[(\d+\.\d+)\] \[info\] storyBoard runningState -> stopTransition")


def esmini_trace(
    xosc: str | Path,
    binary: str | Path,
    step: float = 0.1,
    folder: str | Path | None = None,
    timeout: float = 300.0,
) -> Trace:
    """Play ``xosc`` in esmini headless with a fixed step [s]; its CSV log and log file
    read into a :class:`Trace`.

    :raises ScenarioError: esmini failed or wrote no steps.
    """
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(folder or tmp)
        csv_path, log_path = out / "esmini.csv", out / "esmini.log"
        cmd = [
            str(binary), "--headless", "--osc", str(xosc), "--fixed_timestep", str(step),
            "--csv_logger", str(csv_path), "--logfile_path", str(log_path), "--disable_stdout",
        ]  # fmt: skip
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
        if done.returncode != 0 or not csv_path.is_file():
            tail = (done.stdout + done.stderr).strip().splitlines()[-3:]
            raise ScenarioError(f"{Path(xosc).name}: esmini failed ({done.returncode}): {tail}")
        times, poses = _read_esmini_csv(csv_path)
        for theirs, ours in _inline_trailers(Path(xosc)).items():
            if theirs in poses:
                poses[ours] = poses.pop(theirs)
        starts: dict[str, list[float]] = {}
        stop = None
        for line in log_path.read_text(errors="replace").splitlines():
            m = _START.match(line)
            if m:
                starts.setdefault(m.group(2), []).append(float(m.group(1)))
            m = _STOP.match(line)
            if m:
                stop = float(m.group(1))
    return Trace(times=times, poses=poses, starts=starts, stop=stop)


def _inline_trailers(xosc: Path) -> dict[str, str]:
    """esmini's names of the trailers defined inside their tractors (the tractor's name
    and a ``+``, one more for each trailer down a chain) -> the names the file gives
    them."""
    from aldm_gym.xmlfile import parse_xml

    out: dict[str, str] = {}

    def walk(obj: Any, theirs: str) -> None:
        inner = obj.find("Vehicle/Trailer/Trailer")
        if inner is not None and inner.get("name"):
            out[theirs + "+"] = inner.get("name")
            walk(inner, theirs + "+")

    for obj in parse_xml(xosc).getroot().findall("Entities/ScenarioObject"):
        walk(obj, obj.get("name", ""))
    return out


def _read_esmini_csv(path: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    head = next(i for i, r in enumerate(rows) if r and r[0].startswith("Index"))
    columns = [c.strip() for c in rows[head]]
    width = (
        next(i for i, c in enumerate(columns[3:], 3) if c.startswith("#2 ")) - 2
        if any(c.startswith("#2 ") for c in columns)
        else len(columns) - 2
    )
    names = [re.sub(r"^#1 ", "", c) for c in columns[2 : 2 + width]]
    col = {n.split(" [")[0]: i for i, n in enumerate(names)}
    data = [[c.strip() for c in r] for r in rows[head + 1 :] if r and r[0].strip()]
    times = np.array([float(r[1]) for r in data])
    poses: dict[str, np.ndarray] = {}
    for k, r in enumerate(data):
        for start in range(2, len(r) - width + 1, width):
            block = r[start : start + width]
            name = block[col["Entity_Name"]]
            if not name:
                continue
            arr = poses.setdefault(name, np.full((len(data), 4), np.nan))
            arr[k] = [
                float(block[col["World_Position_X"]]),
                float(block[col["World_Position_Y"]]),
                float(block[col["World_Heading_Angle"]]),
                float(block[col["Current_Speed"]]),
            ]
    return times, poses


# ---------------------------------------------------------------- the player
def player_trace(
    xosc: str | Path,
    step: float = 0.1,
    max_time: float = 600.0,
    parameters: Mapping[str, Any] | None = None,
) -> Trace:
    """Play ``xosc`` in aldm-gym's player with every entity scripted (no env, no
    function under test: the ego follows its actions as the others do) until the stop
    trigger fires or ``max_time`` [s].

    :raises ScenarioError: the file cannot be played, or its ego is handed to a
        function (use :func:`scripted_copy` first).
    """
    from highway_env.road.road import Road

    from aldm_gym.roads.map_road import OpenDriveRoad
    from aldm_gym.scenario.reader import read_scenario
    from aldm_gym.scenario.runner import ScenarioRunner, choose_ego
    from aldm_gym.scenario.world import ScenarioVehicle

    scenario = read_scenario(xosc, parameters)
    road = OpenDriveRoad.from_file(str(scenario.map_path), marking_model="editor")
    try:
        ego = choose_ego(scenario)
    except ScenarioError:  # no ego to tell: every entity is scripted here anyway
        ego = scenario.entities[0].name
    runner = ScenarioRunner(scenario, road, ego)
    traffic = Road(network=road.network, vehicles=[])
    runner.populate(traffic, lambda tr, pos, h, v: ScenarioVehicle(tr, pos, h, v), step)
    if runner.active:
        raise ScenarioError(f"{Path(xosc).name}: the ego is handed to a function in Init")
    names = list(runner.world.entities)
    rows: list[list[float]] = []
    times: list[float] = []

    def record() -> None:
        times.append(runner.world.time)
        row: list[float] = []
        for name in names:
            e = runner.world.entities[name]
            if not runner.on_road(e):  # deleted: not in esmini's log either
                row += [math.nan] * 4
                continue
            ref = e.reference_point()
            row += [float(ref[0]), -float(ref[1]), -e.heading, float(e.speed)]
        rows.append(row)

    record()
    while not runner.finished and runner.world.time < max_time - 1e-9:
        for v in traffic.vehicles:
            v.step(step)
        runner.step(step)
        if runner.active:
            raise ScenarioError(
                f"{Path(xosc).name}: the ego is handed to a function at {runner.world.time} s"
            )
        if not runner.finished:
            record()
    table = np.array(rows).reshape(len(rows), len(names), 4)
    return Trace(
        times=np.array(times),
        poses={n: table[:, i] for i, n in enumerate(names)},
        starts=runner.storyboard.starts("event"),
        stop=runner.storyboard.finished_at,
    )


# ---------------------------------------------------------------- comparison
def compare(reference: Trace, ours: Trace, step: float = 0.1) -> Agreement:
    """Where ``ours`` agrees with ``reference`` at the steps both played."""
    ref_k = {round(t / step): i for i, t in enumerate(reference.times)}
    our_k = {round(t / step): i for i, t in enumerate(ours.times)}
    common = sorted(set(ref_k) & set(our_k))
    distance: dict[str, float] = {}
    heading: dict[str, float] = {}
    first_off: dict[str, float | None] = {}
    for name, ref in reference.poses.items():
        mine = ours.poses.get(name)
        if mine is None:
            distance[name], first_off[name], heading[name] = math.inf, 0.0, math.inf
            continue
        a = ref[[ref_k[k] for k in common], :3]
        b = mine[[our_k[k] for k in common], :3]
        d = np.hypot(*(a[:, :2] - b[:, :2]).T)
        both = ~(np.isnan(a[:, 0]) & np.isnan(b[:, 0]))
        d = np.where(both, np.nan_to_num(d, nan=math.inf), 0.0)
        turn = np.abs((a[:, 2] - b[:, 2] + math.pi) % (2.0 * math.pi) - math.pi)
        heading[name] = float(
            np.where(both, np.nan_to_num(turn, nan=math.inf), 0.0).max(initial=0.0)
        )
        distance[name] = float(d.max(initial=0.0))
        off = np.flatnonzero(d > POSITION_TOLERANCE)
        first_off[name] = common[off[0]] * step if off.size else None
    events: dict[str, float] = {}
    for name, ours_times in ours.starts.items():
        theirs = reference.starts.get(name, [])
        if len(theirs) != len(ours_times):
            events[name] = math.inf
        elif ours_times:
            events[name] = max(abs(a - b) for a, b in zip(theirs, ours_times, strict=True))
    if (reference.stop is None) != (ours.stop is None):
        stop_offset = math.inf
    else:
        stop_offset = abs((reference.stop or 0.0) - (ours.stop or 0.0))
    return Agreement(len(common), distance, first_off, events, stop_offset, step, heading)


def agreement(
    xosc: str | Path,
    binary: str | Path,
    step: float = 0.1,
    parameters: Mapping[str, Any] | None = None,
    max_time: float = 600.0,
) -> Agreement:
    """Play the scripted copy of ``xosc`` (:func:`scripted_copy`, with ``parameters``,
    stopped at ``max_time`` [s] at the latest) in esmini and in the player and compare
    them (:func:`compare`)."""
    with tempfile.TemporaryDirectory() as tmp:
        copy = scripted_copy(xosc, tmp, max_time, parameters)
        ref = esmini_trace(copy, binary, step, tmp)
        ours = player_trace(copy, step, max_time=float(ref.times[-1]) + step)
    return compare(ref, ours, step)
