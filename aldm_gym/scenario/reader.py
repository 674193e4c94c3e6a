"""Reading an OpenSCENARIO 1.0–1.3 file into what :mod:`aldm_gym.scenario` plays.

The file is read with lxml, which keeps every element's line, so an error names the
file, the line and the element (``cut_in.xosc:57 <SpeedAction>``). Parameters are
bound once per run (:mod:`aldm_gym.scenario.declarations`: the declarations, the
overrides given, ``${...}`` expressions) and every attribute is resolved as it is
read. The map is the ``RoadNetwork/LogicFile``; vehicles, pedestrians and misc objects
come inline or from the catalogs of ``CatalogLocations`` (with their own parameter
declarations and the reference's assignments).

Anything the player does not support (an element it does not know, an action or
condition it cannot play, a position it cannot resolve) is a
:class:`~aldm_gym.errors.ScenarioError` when the file is read, never a silently
skipped action. The supported set: docs/scenarios.md.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from aldm_gym.errors import OffRoadError, ScenarioError, ScenarioWarning
from aldm_gym.scenario import actions as A
from aldm_gym.scenario import conditions as C
from aldm_gym.scenario import shapes as S
from aldm_gym.scenario.declarations import bind, declarations_from_xml
from aldm_gym.scenario.expressions import (
    ParamValue,
    format_value,
    parameter_name,
    resolve,
    resolve_number,
)
from aldm_gym.scenario.positions import (
    GeoPos,
    LanePos,
    Orientation,
    Position,
    RelativeLanePos,
    RelativeObjectPos,
    RelativeRoadPos,
    RelativeWorldPos,
    RoadPos,
    RoutePos,
    TrajectoryPos,
    WorldPos,
    lane_step,
)
from aldm_gym.scenario.schema import check_structure
from aldm_gym.scenario.storyboard import (
    STATES,
    TRANSITIONS,
    Act,
    ActionElement,
    Condition,
    Event,
    Maneuver,
    ManeuverGroup,
    Story,
    Storyboard,
    Trigger,
)
from aldm_gym.scenario.world import BoundingBox, Entity
from aldm_gym.xmlfile import ElementReader, parse_xml

__all__ = ["EntitySpec", "Scenario", "read_scenario"]

_MISSING: Any = object()

MAX_SIZE = 1000.0
"""Largest bounding-box dimension, and distance of its centre from the reference
point, an entity may have [m] (a road train is 50 m long)."""

_ELEMENT_TYPES = ("story", "act", "maneuverGroup", "maneuver", "event", "action")

_NO_MEANING = {
    "EnvironmentAction": "weather, time of day and road condition have no meaning on the env "
    "(the line sensor's conditions are its own settings)",
    "InfrastructureAction": "traffic signals have no meaning on the env",
    "VisibilityAction": "every entity is seen by the sensors the env models",
    "AppearanceAction": "light states and animations have no meaning on the env",
    "UserDefinedAction": "a command for another tool",
    "AssignControllerAction": "every entity but the function under test follows the storyboard",
    "OverrideControllerValueAction": "the function under test's pedals and steering are its own",
    "SetMonitorAction": "monitors have no meaning on the env",
}
"""Elements the player accepts and ignores, and why (one warning per kind and file)."""

_GENERATED_DRIVERS = (
    "generated vehicles drive as the env's map traffic (IDM/MOBIL): their controllers and "
    "roles are its own"
)
"""Why a traffic definition's controller and role distributions are ignored."""

_SHAPES = ("Polyline", "Clothoid", "ClothoidSpline", "Nurbs")
"""The trajectory shapes."""

_NEVER = {
    "TimeOfDayCondition": "the env has no time of day: the condition never holds",
    "UserDefinedValueCondition": "values of another tool: the condition never holds",
    "TrafficSignalCondition": "the env has no traffic signals: the condition never holds",
    "TrafficSignalControllerCondition": "the env has no traffic signals: the condition never holds",
}
"""Conditions on things the env does not have: accepted, never true, one warning each."""


@dataclass(frozen=True)
class EntitySpec:
    """A ``ScenarioObject`` as read: name, kind, category, box, performance limits
    and whether it has an ``ObjectController``."""

    name: str
    kind: str
    category: str
    box: BoundingBox
    max_speed: float
    max_acceleration: float
    max_deceleration: float
    controlled: bool
    where: str
    hitch: float | None = None
    """``TrailerHitch dx``: the hitch [m] ahead of the reference point (None: none)."""
    coupler: float | None = None
    """``TrailerCoupler dx``: the coupler [m] ahead of the reference point."""
    trailer: str | None = None
    """The trailer it tows from the start (``Trailer``), by name."""

    def entity(self, is_ego: bool) -> Entity:
        """A fresh runtime :class:`~aldm_gym.scenario.world.Entity`."""
        return Entity(
            name=self.name,
            kind=self.kind,
            category=self.category,
            box=self.box,
            max_speed=self.max_speed,
            max_acceleration=self.max_acceleration,
            max_deceleration=self.max_deceleration,
            is_ego=is_ego,
            hitch=self.hitch,
            coupler=self.coupler,
        )


@dataclass
class Scenario:
    """One concrete scenario: a file with its parameters bound.

    :ivar path: the ``.xosc`` file.
    :ivar version: ``(revMajor, revMinor)`` of its ``FileHeader``.
    :ivar parameters: every parameter's value in this run.
    :ivar map_path: the OpenDRIVE file of ``RoadNetwork/LogicFile``.
    :ivar entities: the scenario objects in document order.
    :ivar violations: the parameter constraints this run breaks (the suite's files
        ask that such runs be discarded; :func:`read_scenario` does not refuse them).
    """

    path: Path
    version: tuple[int, int]
    parameters: dict[str, ParamValue]
    map_path: Path
    entities: list[EntitySpec]
    violations: list[str] = field(default_factory=list)
    variables: dict[str, ParamValue] = field(default_factory=dict)
    """The ``VariableDeclarations``' initial values (1.2+)."""
    ignored: dict[str, str] = field(default_factory=dict)
    """Elements with no meaning on the env, by tag: why, and where they are."""
    added: frozenset[str] = frozenset()
    """The entities an ``AddEntityAction`` adds: one that ``Init`` does not place
    starts absent (as in esmini) until it is added."""
    _root: Any = None

    def entity(self, name: str) -> EntitySpec:
        """The scenario object called ``name``.

        :raises ScenarioError: naming it and the scenario's objects.
        """
        for e in self.entities:
            if e.name == name:
                return e
        raise ScenarioError(
            f"{self.path.name}: no scenario object {name!r}; it has "
            f"{[e.name for e in self.entities]}"
        )

    def build(self, entities: Mapping[str, Entity]) -> tuple[list[A.Instance], Storyboard]:
        """A fresh run of the storyboard: the ``Init`` actions' instances (to start in
        order at time 0) and the stories, bound to these runtime entities."""
        reader = _Reader(self.path, self.parameters, self._root, entities)
        out = reader.init(), reader.storyboard()
        self.added = frozenset(reader.added)
        for tag, (_, why, lines) in reader.ignored.items():
            shown = ", ".join(str(n) for n in lines[:5]) + (", ..." if len(lines) > 5 else "")
            self.ignored[tag] = f"{why} (line{'s' if len(lines) > 1 else ''} {shown})"
        return out


def _defined(rule: Callable[[Any, Any], bool], value: float, given: float) -> bool:
    """``rule(value, given)`` for a time headway or a time to collision [s], False
    where it is undefined (inf: the other entity behind, standing still, not closing),
    whatever the rule (as esmini: ``greaterThan`` does not hold for a car behind)."""
    return math.isfinite(value) and bool(rule(value, given))


def read_scenario(path: str | Path, parameters: Mapping[str, Any] | None = None) -> Scenario:
    """Read a concrete scenario with ``parameters`` overriding its declarations.

    :raises ScenarioError: the file is missing or not OpenSCENARIO, a version outside
        1.0–1.3, an unknown parameter given, or anything the player cannot play (the
        message names file, line and element).
    """
    path = Path(path)
    if not path.is_file():
        raise ScenarioError(f"{path}: no such scenario file")
    root = parse_xml(path).getroot()
    if root.tag != "OpenSCENARIO":
        raise ScenarioError(
            f"{path.name}:{root.sourceline}: the root is <{root.tag}>, not <OpenSCENARIO>"
        )
    check_structure(root, path.name)
    header = root.find("FileHeader")
    if header is None:
        raise ScenarioError(f"{path.name}: no <FileHeader>")
    try:
        version = (int(header.get("revMajor", "")), int(header.get("revMinor", "")))
    except ValueError:
        raise ScenarioError(
            f"{path.name}:{header.sourceline} <FileHeader>: revMajor/revMinor must be integers"
        ) from None
    if version[0] != 1 or not 0 <= version[1] <= 3:
        raise ScenarioError(
            f"{path.name}:{header.sourceline} <FileHeader>: OpenSCENARIO {version[0]}.{version[1]} "
            "is not supported (1.0 to 1.3 are)"
        )
    if root.find("Storyboard") is None:
        if root.find("ParameterValueDistribution") is not None:
            raise ScenarioError(
                f"{path.name}: a parameter variation file, not a scenario: run it as a suite "
                "(aldm-gym scenario suite)"
            )
        raise ScenarioError(f"{path.name}: no <Storyboard>")
    declarations = declarations_from_xml(root.find("ParameterDeclarations"))
    from aldm_gym.scenario.declarations import violations

    _Reader(path, {}, root, None).kids(
        root,
        (
            "FileHeader",
            "ParameterDeclarations",
            "VariableDeclarations",
            "MonitorDeclarations",
            "CatalogLocations",
            "RoadNetwork",
            "Entities",
            "Storyboard",
        ),
    )

    values = bind(declarations, dict(parameters or {}), str(path.name))
    broken = violations(declarations, values)
    reader = _Reader(path, values, root, None)
    network = root.find("RoadNetwork")
    if network is not None:
        for k in reader.kids(
            network, ("LogicFile", "SceneGraphFile", "TrafficSignals", "UsedArea")
        ):
            if k.tag == "TrafficSignals" and len(k):
                reader.ignored_network["TrafficSignals"] = (
                    f"traffic signals have no meaning on the env (line {k.sourceline})"
                )
    logic = root.find("RoadNetwork/LogicFile")
    if logic is None:
        raise ScenarioError(
            f"{path.name}: no <RoadNetwork><LogicFile>: the player needs an OpenDRIVE map"
        )
    map_path = (path.parent / reader.attr(logic, "filepath")).resolve()
    if not map_path.is_file():
        raise ScenarioError(
            f"{reader.where(logic)}: the map {map_path} does not exist (a relative path is "
            "read from the scenario's folder; esmini's own examples count on its working "
            "directory being its bin folder)"
        )
    scenario = Scenario(
        path=path,
        version=version,
        parameters=values,
        map_path=map_path,
        entities=reader.entities(),
        violations=broken,
        variables=reader.variables(),
        _root=root,
    )
    # Build the storyboard once now, so that what cannot be played is named before a
    # run starts (positions are resolved only when their action starts).
    scenario.build({e.name: e.entity(False) for e in scenario.entities})
    for tag, why in {**reader.ignored_network, **scenario.ignored}.items():
        scenario.ignored[tag] = why
        warnings.warn(f"{path.name}: <{tag}> ignored: {why}", ScenarioWarning, stacklevel=2)
    return scenario


class _Reader(ElementReader):
    """Reads elements of one file with one set of parameter values."""

    path: Path

    def __init__(
        self,
        path: Path,
        params: Mapping[str, ParamValue],
        root: Any,
        entities: Mapping[str, Entity] | None,
    ) -> None:
        super().__init__(path, ScenarioError)
        self.params = params
        self.root = root
        self.runtime = entities
        self._catalogs: dict[str, dict[str, tuple[Any, Path]]] | None = None
        self.actions: dict[str, ActionElement] = {}
        self.pending: list[tuple[Any, str, str]] = []
        self.ignored: dict[str, tuple[int, str, list[int]]] = {}
        """Elements with no meaning here: tag -> (first line, why, lines)."""
        self.ignored_network: dict[str, str] = {}
        self.added: set[str] = set()
        """The entities an ``AddEntityAction`` names (shared with scoped readers)."""
        self._selections: dict[str, list[str]] | None = None
        self._names: list[str] | None = None
        self.refs: list[str] = []
        """Every entity name read so far (a condition's names are those read while
        reading it), shared with the scoped readers."""

    # ------------------------------------------------------------ attributes
    def attr(self, el: Any, name: str, default: Any = _MISSING) -> str:
        """An attribute, parameters resolved, as text."""
        raw = el.get(name)
        if raw is None:
            if default is _MISSING:
                raise self.error(el, f"missing attribute {name!r}")
            return default
        return str(resolve(raw, self.params, self.where(el, name)))

    def required_raw(self, el: Any, name: str) -> str:
        """An attribute as written (a name, not a value: no parameter is resolved)."""
        raw = el.get(name)
        if raw is None:
            raise self.error(el, f"missing attribute {name!r}")
        return str(raw)

    def num(self, el: Any, name: str, default: Any = _MISSING) -> float:
        """A finite number attribute."""
        raw = el.get(name)
        if raw is None:
            if default is _MISSING:
                raise self.error(el, f"missing attribute {name!r}")
            return default
        return resolve_number(raw, self.params, self.where(el, name))

    def integer(self, el: Any, name: str, default: Any = _MISSING) -> int:
        """An integer attribute."""
        value = self.num(el, name, default)
        if value != int(value):
            raise self.error(el, f"{name} must be an integer, got {value:g}")
        return int(value)

    def flag(self, el: Any, name: str, default: Any = _MISSING) -> bool:
        """A boolean attribute (``true``/``false``)."""
        raw = el.get(name)
        if raw is None:
            if default is _MISSING:
                raise self.error(el, f"missing attribute {name!r}")
            return bool(default)
        value = resolve(raw, self.params, self.where(el, name))
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text not in ("true", "false", "1", "0"):
            raise self.error(el, f"{name}={raw!r} is not a boolean")
        return text in ("true", "1")

    def choice(self, el: Any, name: str, allowed: tuple[str, ...], default: Any = _MISSING) -> str:
        """An enumeration attribute."""
        value = self.attr(el, name, default)
        if value not in allowed:
            raise self.error(el, f"{name}={value!r} is not one of {list(allowed)}")
        return value

    def child(self, el: Any, tag: str) -> Any:
        """The required child ``tag``."""
        found = el.find(tag)
        if found is None:
            raise self.error(el, f"missing <{tag}>")
        return found

    def one(self, el: Any, allowed: tuple[str, ...]) -> Any:
        """The one element child (a choice in the schema) among ``allowed``."""
        kids = [k for k in el if isinstance(k.tag, str)]
        if len(kids) != 1:
            raise self.error(
                el, f"expects one child of {list(allowed)}, has {[k.tag for k in kids]}"
            )
        if kids[0].tag not in allowed:
            raise self.unsupported(kids[0], allowed)
        return kids[0]

    def kids(self, el: Any, allowed: tuple[str, ...]) -> list[Any]:
        """The element children of ``el``, each of them among ``allowed`` (else the
        error for an element the player does not play: nothing is skipped silently)."""
        out = [k for k in el if isinstance(k.tag, str)]
        for k in out:
            if k.tag not in allowed:
                raise self.unsupported(k, allowed)
        return out

    def scoped(self, el: Any) -> _Reader:
        """A reader for ``el``'s content that sees its ``ParameterDeclarations`` (a
        ``Story``, ``Maneuver``, ``Route`` or ``Trajectory`` may declare parameters of
        its own, which see the enclosing ones and shadow them)."""
        decls = declarations_from_xml(el.find("ParameterDeclarations"))
        if not decls:
            return self
        reader = copy.copy(self)
        reader.params = bind(decls, {}, self.where(el), outer=self.params)
        return reader

    def ignore(self, el: Any, why: str) -> None:
        """Note a valid element with no meaning here (one warning per kind and file)."""
        self.ignored.setdefault(el.tag, (el.sourceline, why, []))[2].append(el.sourceline)

    def absent(
        self, el: Any, *names: str, allowed: Mapping[str, tuple[str, ...]] | None = None
    ) -> None:
        """Attributes the player does not play must be absent (or have a value in
        ``allowed``)."""
        for name in names:
            raw = el.get(name)
            if raw is None:
                continue
            ok = (allowed or {}).get(name)
            if ok is not None and str(resolve(raw, self.params, self.where(el, name))) in ok:
                continue
            hint = f" (supported: {list(ok)})" if ok else ""
            raise self.error(el, f"{name}={raw!r} is not supported by the player{hint}")

    def unsupported(self, el: Any, allowed: tuple[str, ...] = ()) -> ScenarioError:
        """The error for an element the player cannot play."""
        hint = f" (supported here: {', '.join(allowed)})" if allowed else ""
        return self.error(el, f"<{el.tag}> is not supported by the player{hint}")

    # ------------------------------------------------------------ catalogs and entities
    def catalogs(self) -> dict[str, dict[str, tuple[Any, Path]]]:
        """Every catalog of ``CatalogLocations``: name -> entry name -> (element, file)."""
        if self._catalogs is None:
            found: dict[str, dict[str, tuple[Any, Path]]] = {}
            for directory in self.root.findall("CatalogLocations/*/Directory"):
                folder = (self.path.parent / self.attr(directory, "path")).resolve()
                if not folder.is_dir():
                    raise self.error(
                        directory,
                        f"the catalog folder {folder} does not exist (a relative path is read "
                        "from the scenario's folder)",
                    )
                for file in sorted(folder.glob("*.xosc")):
                    croot = parse_xml(file).getroot()
                    check_structure(croot, file.name)
                    for catalog in croot.findall("Catalog"):
                        entries = found.setdefault(catalog.get("name", ""), {})
                        for entry in catalog:
                            if isinstance(entry.tag, str) and entry.get("name"):
                                entries[entry.get("name")] = (entry, file)
            self._catalogs = found
        return self._catalogs

    def from_catalog(self, ref: Any) -> tuple[Any, _Reader]:
        """The entry a ``CatalogReference`` names, with a reader for its parameters."""
        name = self.attr(ref, "catalogName")
        entry = self.attr(ref, "entryName")
        catalogs = self.catalogs()
        if name not in catalogs:
            raise self.error(
                ref, f"no catalog {name!r} in CatalogLocations; found {sorted(catalogs)}"
            )
        if entry not in catalogs[name]:
            raise self.error(
                ref, f"catalog {name!r} has no entry {entry!r}; it has {sorted(catalogs[name])}"
            )
        element, file = catalogs[name][entry]
        assigned = {
            parameter_name(self.required_raw(a, "parameterRef")): self.attr(a, "value")
            for a in ref.findall("ParameterAssignments/ParameterAssignment")
        }
        decls = declarations_from_xml(element.find("ParameterDeclarations"))
        values = bind(decls, assigned, file.name) if decls or assigned else {}
        # a reader of the entry's file and parameters that shares everything else
        # (storyboard names and pending checks, entities added, elements ignored)
        reader = copy.copy(self)
        reader.path = file
        reader.params = {**self.params, **values}
        return element, reader

    def entities(self) -> list[EntitySpec]:
        """The ``Entities``' scenario objects."""
        out = []
        entities = self.child(self.root, "Entities")
        self.selections()  # checked here, expanded where they are named
        for obj in self.kids(entities, ("ScenarioObject", "EntitySelection")):
            if obj.tag == "EntitySelection":
                continue
            out += self._scenario_object(obj)
        names = [e.name for e in out]
        if len(set(names)) != len(names):
            raise self.error(entities, f"scenario object names repeat: {names}")
        self._check_trailers(out)
        return out

    def _object_names(self) -> list[str]:
        """The scenario objects' names, the trailers defined inside vehicles too (the
        runtime entities' where the storyboard is built, read once otherwise)."""
        if self._names is None:
            if self.runtime is not None:
                self._names = list(self.runtime)
            else:
                self._names = [s.name for s in self.entities()]
        return self._names

    def _scenario_object(self, obj: Any) -> list[EntitySpec]:
        """A ``ScenarioObject``'s spec, then those of the trailers defined inside it."""
        name = self.attr(obj, "name")
        kids = [k for k in obj if isinstance(k.tag, str) and k.tag != "ObjectController"]
        allowed = ("CatalogReference", "Vehicle", "Pedestrian", "MiscObject")
        if len(kids) != 1:
            raise self.error(obj, f"expects one of {list(allowed)}, has {[k.tag for k in kids]}")
        body = kids[0]
        if body.tag not in allowed:
            raise self.unsupported(body, allowed)
        reader: _Reader = self
        if body.tag == "CatalogReference":
            body, reader = self.from_catalog(body)
        if body.tag not in ("Vehicle", "Pedestrian", "MiscObject"):
            raise self.unsupported(body, ("Vehicle", "Pedestrian", "MiscObject"))
        controlled = obj.find("ObjectController") is not None
        return reader._object_and_trailers(name, body, controlled, self.where(obj))

    def _object_and_trailers(
        self, name: str, body: Any, controlled: bool, where: str
    ) -> list[EntitySpec]:
        """The spec of the object ``body`` defines, then those of the trailers defined
        inside it."""
        spec = self._entity(name, body, controlled, where)
        out = [spec]
        towed = body.find("Trailer") if body.tag == "Vehicle" else None
        if towed is not None:
            # esmini's own catalogs write <EntityRef> for <TrailerRef> (its entityRef
            # empty for "no trailer"), and a trailer's <Vehicle> without its
            # <Trailer> scenario object around it
            inner = self.one(towed, ("Trailer", "TrailerRef", "EntityRef", "Vehicle"))
            if inner.tag == "Trailer":  # a trailer defined here: a scenario object
                out += self._scenario_object(inner)
                trailer: str | None = out[1].name
            elif inner.tag == "Vehicle":  # named after its tractor, as esmini names it
                out += self._object_and_trailers(f"{name}+", inner, False, self.where(inner))
                trailer = out[1].name
            else:
                trailer = self.attr(inner, "entityRef") or None
            out[0] = dataclasses.replace(spec, trailer=trailer)
        return out

    def _check_trailers(self, specs: list[EntitySpec]) -> None:
        """Every trailer named exists and has a coupler, its tractor a hitch; none is
        towed twice, none tows itself through a chain."""
        by_name = {s.name: s for s in specs}
        towed_by: dict[str, str] = {}
        for s in specs:
            if s.trailer is None:
                continue
            where = s.where
            trailer = by_name.get(s.trailer)
            if trailer is None:
                raise ScenarioError(
                    f"{where}: its trailer {s.trailer!r} names no scenario object; the "
                    f"scenario has {list(by_name)}"
                )
            if s.hitch is None:
                raise ScenarioError(f"{where}: {s.name!r} tows a trailer but has no <TrailerHitch>")
            if trailer.coupler is None:
                raise ScenarioError(
                    f"{where}: the trailer {trailer.name!r} has no <TrailerCoupler>"
                )
            if s.trailer in towed_by:
                raise ScenarioError(
                    f"{where}: the trailer {s.trailer!r} is towed by {towed_by[s.trailer]!r} "
                    "already"
                )
            towed_by[s.trailer] = s.name
        for s in specs:  # no chain returns to where it began
            seen, name = {s.name}, s.trailer
            while name is not None:
                if name in seen:
                    raise ScenarioError(f"{s.where}: {s.name!r} tows itself through its trailers")
                seen.add(name)
                name = by_name[name].trailer

    def _entity(self, name: str, body: Any, controlled: bool, where: str) -> EntitySpec:
        kind = {"Vehicle": "vehicle", "Pedestrian": "pedestrian", "MiscObject": "miscObject"}[
            body.tag
        ]
        category = self.attr(
            body,
            {
                "vehicle": "vehicleCategory",
                "pedestrian": "pedestrianCategory",
                "miscObject": "miscObjectCategory",
            }[kind],
            kind,
        )
        bb = self.child(body, "BoundingBox")
        centre, dims = self.child(bb, "Center"), self.child(bb, "Dimensions")
        length, width = self.num(dims, "length"), self.num(dims, "width")
        height = self.num(dims, "height", 0.0)
        if not (0 < length <= MAX_SIZE and 0 < width <= MAX_SIZE and 0 <= height <= MAX_SIZE):
            raise self.error(
                dims,
                f"length and width must be in (0, {MAX_SIZE:g}] m and height in "
                f"[0, {MAX_SIZE:g}] m, got {length:g} x {width:g} x {height:g}",
            )
        cx, cy = self.num(centre, "x"), self.num(centre, "y")
        if max(abs(cx), abs(cy), abs(self.num(centre, "z", 0.0))) > MAX_SIZE:
            raise self.error(
                centre, f"the box's centre must lie within {MAX_SIZE:g} m of the reference point"
            )
        box = BoundingBox(cx=cx, cy=cy, length=length, width=width, height=height)
        perf = body.find("Performance")
        if perf is not None:
            limits = (
                self.num(perf, "maxSpeed"),
                self.num(perf, "maxAcceleration"),
                self.num(perf, "maxDeceleration"),
            )
            if limits[0] < 0 or limits[1] <= 0 or limits[2] <= 0:
                raise self.error(
                    perf,
                    "maxSpeed must be >= 0 and maxAcceleration, maxDeceleration > 0, got "
                    f"{limits[0]:g}, {limits[1]:g}, {limits[2]:g}",
                )
        else:
            limits = (math.inf, math.inf, math.inf)
        hitch = coupler = None
        if kind == "vehicle":
            found = [self._offset(body, tag) for tag in ("TrailerHitch", "TrailerCoupler")]
            hitch, coupler = found
        return EntitySpec(
            name,
            kind,
            category,
            box,
            *limits,
            controlled=controlled,
            where=where,
            hitch=hitch,
            coupler=coupler,
        )

    def _offset(self, body: Any, tag: str) -> float | None:
        """``dx`` [m] of a vehicle's ``TrailerHitch`` or ``TrailerCoupler`` (None
        without one), within :data:`MAX_SIZE` of the reference point."""
        el = body.find(tag)
        if el is None:
            return None
        dx = self.num(el, "dx")
        if abs(dx) > MAX_SIZE:
            raise self.error(el, f"dx must lie within {MAX_SIZE:g} m of the reference point")
        return dx

    # ------------------------------------------------------------ positions
    def position(self, el: Any) -> Position:
        """A ``Position`` element's one child."""
        p = self.one(
            el,
            (
                "LanePosition",
                "RelativeLanePosition",
                "RoadPosition",
                "WorldPosition",
                "RelativeObjectPosition",
                "RelativeRoadPosition",
                "RelativeWorldPosition",
                "TrajectoryPosition",
                "RoutePosition",
                "GeoPosition",
            ),
        )
        where = self.where(p)
        o = p.find("Orientation")
        orient = None
        if o is not None:
            kind = self.choice(o, "type", ("relative", "absolute"), "relative")
            orient = Orientation(h=self.num(o, "h", 0.0), relative=kind == "relative")
        if p.tag == "LanePosition":
            return LanePos(
                self.attr(p, "roadId"),
                self.integer(p, "laneId"),
                self.num(p, "s"),
                self.num(p, "offset", 0.0),
                orient,
                where,
            )
        if p.tag == "RelativeLanePosition":
            self._entity_ref(p, "entityRef")
            ds = self.num(p, "ds", None)
            ds_lane = self.num(p, "dsLane", None)
            if (ds is None) == (ds_lane is None):
                raise self.error(p, "give one of ds and dsLane")
            return RelativeLanePos(
                self.attr(p, "entityRef"),
                self.integer(p, "dLane"),
                ds,
                ds_lane,
                self.num(p, "offset", 0.0),
                orient,
                where,
            )
        if p.tag == "RoadPosition":
            return RoadPos(
                self.attr(p, "roadId"), self.num(p, "s"), self.num(p, "t"), orient, where
            )
        if p.tag == "TrajectoryPosition":
            self.kids(p, ("Orientation", "TrajectoryRef"))
            el, traj = self._trajectory(self.child(p, "TrajectoryRef"))
            shape = traj.shape(traj.one(traj.child(el, "Shape"), _SHAPES))
            return TrajectoryPos(shape, self.num(p, "s"), self.num(p, "t", 0.0), orient, where)
        if p.tag == "RoutePosition":
            return self._route_position(p, orient, where)
        if p.tag == "RelativeRoadPosition":
            self._entity_ref(p, "entityRef")
            return RelativeRoadPos(
                self.attr(p, "entityRef"), self.num(p, "ds"), self.num(p, "dt"), orient, where
            )
        if p.tag == "RelativeWorldPosition":
            self._entity_ref(p, "entityRef")
            return RelativeWorldPos(
                self.attr(p, "entityRef"),
                self.num(p, "dx", 0.0),
                self.num(p, "dy", 0.0),
                orient,
                where,
            )
        if p.tag == "WorldPosition":
            return WorldPos(self.num(p, "x"), self.num(p, "y"), self.num(p, "h", None), where)
        if p.tag == "GeoPosition":
            return self._geo_position(p, orient, where)
        self._entity_ref(p, "entityRef")
        return RelativeObjectPos(
            self.attr(p, "entityRef"), self.num(p, "dx", 0.0), self.num(p, "dy", 0.0), orient, where
        )

    def _geo_position(self, p: Any, orient: Orientation | None, where: str) -> GeoPos:
        """A ``GeoPosition``: ``latitudeDeg``/``longitudeDeg`` [deg], or 1.0's
        deprecated ``latitude``/``longitude`` [rad]; the altitude and
        ``verticalRoadSelection`` are not used (the world is planar)."""
        if p.get("latitudeDeg") is not None or p.get("longitudeDeg") is not None:
            lat, lon = self.num(p, "latitudeDeg"), self.num(p, "longitudeDeg")
        else:
            lat = math.degrees(self.num(p, "latitude"))
            lon = math.degrees(self.num(p, "longitude"))
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise self.error(
                p, f"latitude {lat:g} and longitude {lon:g} [deg] must lie within +-90 and +-180"
            )
        return GeoPos(lat, lon, orient, where)

    def selections(self) -> dict[str, list[str]]:
        """The ``EntitySelection``s: name -> the scenario objects they select (a member
        that is a selection contributes its members; ``ByType`` every object of the
        type), each once, in document order.

        :raises ScenarioError: a selection named like an object or another selection,
            a member that names nothing, a selection that contains itself.
        """
        if self._selections is not None:
            return self._selections
        objects = {self.attr(o, "name"): o for o in self.root.findall("Entities/ScenarioObject")}
        raw: dict[str, Any] = {}
        for sel in self.root.findall("Entities/EntitySelection"):
            name = self.attr(sel, "name")
            if name in objects or name in raw:
                raise self.error(sel, f"the name {name!r} is taken by another entity")
            raw[name] = sel
        kinds = {"vehicle": "Vehicle", "pedestrian": "Pedestrian", "miscellaneous": "MiscObject"}

        def kind_of(obj: Any) -> str:
            body = next(k for k in obj if isinstance(k.tag, str) and k.tag != "ObjectController")
            if body.tag == "CatalogReference":
                element, _ = self.from_catalog(body)
                return str(element.tag)
            return str(body.tag)

        out: dict[str, list[str]] = {}

        def expand(name: str, chain: tuple[str, ...]) -> list[str]:
            if name in out:
                return out[name]
            sel = raw[name]
            members = self.child(sel, "Members")
            self.kids(members, ("EntityRef", "ByType"))
            picked: list[str] = []
            for m in members:
                if not isinstance(m.tag, str):
                    continue
                if m.tag == "ByType":
                    wanted = self.choice(m, "objectType", (*kinds, "external"))
                    if wanted == "external":
                        raise self.error(m, "external objects are not played")
                    picked += [n for n, o in objects.items() if kind_of(o) == kinds[wanted]]
                    continue
                ref = self.attr(m, "entityRef")
                if ref in chain:
                    raise self.error(m, f"the selection {ref!r} contains itself")
                if ref in raw:
                    picked += expand(ref, (*chain, ref))
                elif ref in objects:
                    picked.append(ref)
                else:
                    raise self.error(
                        m, f"entityRef={ref!r} names no scenario object or selection; the "
                        f"scenario has {list(objects)}"
                    )  # fmt: skip
            out[name] = list(dict.fromkeys(picked))
            return out[name]

        for name in raw:
            expand(name, (name,))
        self._selections = out
        return out

    def _entity_refs(self, el: Any, attr: str) -> list[str]:
        """The scenario objects an attribute names: one object, or the members of an
        ``EntitySelection`` (where the standard lets a selection stand for its
        members: actors, triggering entities, ``Init``'s private actions)."""
        name = self.attr(el, attr)
        selected = self.selections().get(name)
        if selected is None:
            return [self._entity_ref(el, attr)]
        self.refs.extend(selected)
        return list(selected)

    def _entity_ref(self, el: Any, attr: str, record: bool = True) -> str:
        """The name of a scenario object in attribute ``attr`` (noted in :attr:`refs`
        with ``record``)."""
        name = self.attr(el, attr)
        known = self._object_names()
        if name in self.selections():
            raise self.error(
                el, f"{attr}={name!r} is an EntitySelection; one scenario object is needed here"
            )
        if name not in known:
            raise self.error(
                el, f"{attr}={name!r} names no scenario object; the scenario has {known}"
            )
        if record:
            self.refs.append(name)
        return name

    def _rt(self, name: str) -> Entity:
        assert self.runtime is not None
        return self.runtime[name]

    # ------------------------------------------------------------ actions
    def private(self, el: Any) -> Callable[[Entity | None], A.Instance]:
        """A ``PrivateAction``: a factory of instances per actor."""
        body = self.one(
            el,
            (
                "LongitudinalAction",
                "LateralAction",
                "TeleportAction",
                "RoutingAction",
                "ControllerAction",
                "ActivateControllerAction",
                "VisibilityAction",
                "AppearanceAction",
                "SynchronizeAction",
                "TrailerAction",
            ),
        )
        where = self.where(body)
        if body.tag == "TrailerAction":
            link = self.one(body, ("ConnectTrailerAction", "DisconnectTrailerAction"))
            if link.tag == "DisconnectTrailerAction":
                return lambda actor: A.TrailerLink(actor, where, None)
            trailer = self._entity_ref(link, "trailerRef")
            return lambda actor: A.TrailerLink(actor, where, trailer)
        if body.tag in _NO_MEANING:
            self.ignore(body, _NO_MEANING[body.tag])
            return lambda actor: A.Ignored(actor, where)
        if body.tag == "SynchronizeAction":
            return self._synchronize(body)
        if body.tag == "TeleportAction":
            pos = self.position(self.child(body, "Position"))
            return lambda actor: A.Teleport(actor, where, pos)
        if body.tag == "LongitudinalAction":
            return self._longitudinal(
                self.one(body, ("SpeedAction", "LongitudinalDistanceAction", "SpeedProfileAction"))
            )
        if body.tag == "LateralAction":
            return self._lateral(
                self.one(body, ("LaneChangeAction", "LaneOffsetAction", "LateralDistanceAction"))
            )
        if body.tag == "RoutingAction":
            routing = self.one(
                body,
                (
                    "FollowTrajectoryAction",
                    "AssignRouteAction",
                    "AcquirePositionAction",
                    "RandomRouteAction",
                ),
            )
            if routing.tag == "RandomRouteAction":
                return lambda actor: A.RandomRoute(actor, where)
            if routing.tag == "AssignRouteAction":
                return self._route(routing)
            if routing.tag == "AcquirePositionAction":
                waypoint = self.position(self.child(routing, "Position"))
                return lambda actor: A.AssignRoute(actor, where, [waypoint])
            return self._routing(routing)
        if body.tag == "ControllerAction":
            parts = self.kids(
                body,
                (
                    "AssignControllerAction",
                    "OverrideControllerValueAction",
                    "ActivateControllerAction",
                ),
            )
            for part in parts:
                if part.tag != "ActivateControllerAction":
                    self.ignore(part, _NO_MEANING[part.tag])
            activate = [p for p in parts if p.tag == "ActivateControllerAction"]
            if not activate:
                return lambda actor: A.Ignored(actor, where)
            body = activate[0]
        # a missing domain means "no change" (the standard)
        lat = self.flag(body, "lateral") if body.get("lateral") is not None else None
        lon = self.flag(body, "longitudinal") if body.get("longitudinal") is not None else None
        for name in ("animation", "lighting"):
            if body.get(name) is not None and self.flag(body, name):
                self.ignore(body, f"{name} has no meaning on the env")
        where = self.where(body)
        return lambda actor: A.ActivateController(actor, where, lat, lon)

    def variables(self) -> dict[str, ParamValue]:
        """The file's ``VariableDeclarations``: name -> initial value, typed."""
        out: dict[str, ParamValue] = {}
        decls = self.root.find("VariableDeclarations")
        if decls is None:
            return out
        for d in self.kids(decls, ("VariableDeclaration",)):
            name = parameter_name(self.required_raw(d, "name"))
            kind = self.choice(
                d,
                "variableType",
                (
                    "double",
                    "int",
                    "integer",
                    "unsignedInt",
                    "unsignedShort",
                    "boolean",
                    "string",
                    "dateTime",
                ),
            )
            if name in out:
                raise self.error(d, f"variable {name} is declared twice")
            out[name] = _typed(self, d, "value", kind)
        return out

    def _store_change(self, body: Any, store: str) -> Callable[[Entity | None], A.Instance]:
        """``ParameterAction`` or ``VariableAction``: set or modify a value at run time."""
        ref_attr = "parameterRef" if store == "parameters" else "variableRef"
        name = parameter_name(self.required_raw(body, ref_attr))
        known = self.params if store == "parameters" else self.variables()
        if name not in known:
            raise self.error(
                body, f"{ref_attr}={name!r} is not declared; declared: {sorted(known)}"
            )
        op = self.one(body, ("SetAction", "ModifyAction"))
        where = self.where(body)
        initial = known[name]
        if op.tag == "SetAction":
            value = self.attr(op, "value")
            return lambda actor: A.StoreChange(actor, where, store, name, "set", value, initial)
        rule = self.one(self.child(op, "Rule"), ("AddValue", "MultiplyByValue"))
        amount = self.num(rule, "value")
        kind = "add" if rule.tag == "AddValue" else "multiply"
        return lambda actor: A.StoreChange(actor, where, store, name, kind, amount, initial)

    def other(self, el: Any) -> Callable[[Entity | None], A.Instance]:
        """A ``GlobalAction`` or ``UserDefinedAction``: those with no meaning on the
        env are ignored (one warning each); the others are refused."""
        where = self.where(el)
        if el.tag == "UserDefinedAction":
            self.ignore(el, _NO_MEANING["UserDefinedAction"])
            return lambda actor: A.Ignored(actor, where)
        body = self.one(
            el,
            (
                "EnvironmentAction",
                "EntityAction",
                "InfrastructureAction",
                "TrafficAction",
                "ParameterAction",
                "VariableAction",
                "SetMonitorAction",
            ),
        )
        if body.tag in _NO_MEANING:
            self.ignore(body, _NO_MEANING[body.tag])
            return lambda actor: A.Ignored(actor, where)
        if body.tag == "ParameterAction":
            return self._store_change(body, "parameters")
        if body.tag == "VariableAction":
            return self._store_change(body, "variables")
        if body.tag == "TrafficAction":
            return self._traffic(body)
        if body.tag == "EntityAction":
            name = self._entity_ref(body, "entityRef")
            change = self.one(body, ("AddEntityAction", "DeleteEntityAction"))
            pos = None
            if change.tag == "AddEntityAction":
                pos = self.position(self.child(change, "Position"))
                self.added.add(name)
            return lambda actor: A.EntityChange(actor, where, name, pos)
        raise self.error(body, f"{body.tag} is not supported yet")

    def _traffic(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        """A ``TrafficAction``: a swarm, source or sink, or a stop of one
        (:mod:`aldm_gym.scenario.traffic`)."""
        from aldm_gym.scenario import traffic as T

        where = self.where(body)
        name = self.attr(body, "trafficName", f"traffic@{body.sourceline}")
        kind = self.one(
            body,
            (
                "TrafficSwarmAction",
                "TrafficSourceAction",
                "TrafficSinkAction",
                "TrafficStopAction",
                "TrafficAreaAction",
            ),
        )
        if kind.tag == "TrafficStopAction":
            if body.get("trafficName") is None:
                raise self.error(body, "a TrafficStopAction needs the trafficName to stop")
            return lambda actor: A.StopTraffic(actor, where, name)
        if kind.tag == "TrafficAreaAction":
            return self._traffic_area(kind, name, where)
        definition = self._traffic_definition(kind)
        speed_range = None
        if kind.find("InitialSpeedRange") is not None:
            limits = self.child(kind, "InitialSpeedRange")
            lo, hi = self.num(limits, "lowerLimit"), self.num(limits, "upperLimit")
            if not 0.0 <= lo <= hi <= T.MAX_SPEED:
                raise self.error(
                    limits,
                    f"needs 0 <= lowerLimit <= upperLimit <= {T.MAX_SPEED:g} [m/s], "
                    f"got {lo:g}, {hi:g}",
                )
            speed_range = (lo, hi)
        speed = self._traffic_speed(kind, "velocity", None)
        if kind.tag == "TrafficSwarmAction":
            self.kids(
                kind,
                (
                    "CentralObject",
                    "CentralSwarmObject",
                    "TrafficDefinition",
                    "TrafficDistribution",
                    "InitialSpeedRange",
                    "DirectionOfTravelDistribution",
                ),
            )
            central_el = kind.find("CentralObject")
            if central_el is None:  # OpenSCENARIO 1.0's name
                central_el = kind.find("CentralSwarmObject")
            if central_el is None:
                raise self.error(kind, "missing <CentralObject>")
            central = self._entity_ref(central_el, "entityRef")
            inner = self.num(kind, "innerRadius")
            major, minor = self.num(kind, "semiMajorAxis"), self.num(kind, "semiMinorAxis")
            count = self.integer(kind, "numberOfVehicles")
            if not (0.0 <= inner and major > 0.0 and minor > 0.0):
                raise self.error(kind, "needs innerRadius >= 0 and semi-axes > 0")
            if not 0 <= count <= T.MAX_GENERATED:
                raise self.error(
                    kind, f"numberOfVehicles must be in [0, {T.MAX_GENERATED}], got {count}"
                )
            same_share = 1.0
            travel = kind.find("DirectionOfTravelDistribution")
            if travel is not None:
                same, opposite = self.num(travel, "same"), self.num(travel, "opposite")
                if same < 0.0 or opposite < 0.0 or same + opposite <= 0.0:
                    raise self.error(travel, "needs weights >= 0, not both 0")
                same_share = same / (same + opposite)
            swarm = {
                "name": name,
                "definition": definition,
                "speed_range": speed_range,
                "speed": speed,
                "central": central,
                "inner_radius": inner,
                "semi_major": major,
                "semi_minor": minor,
                "offset": self.num(kind, "offset", 0.0),
                "count": count,
                "same_share": same_share,
            }
            return lambda actor: A.GenerateTraffic(actor, where, lambda runner: T.Swarm(**swarm))
        self.kids(kind, ("Position", "TrafficDefinition", "TrafficDistribution"))
        position = self.position(self.child(kind, "Position"))
        radius = self.num(kind, "radius")
        if radius < 0.0:
            raise self.error(kind, f"radius must be >= 0, got {radius:g}")
        if kind.tag == "TrafficSourceAction":
            rate = self.num(kind, "rate")
            if rate <= 0.0:
                raise self.error(kind, f"rate must be > 0 [vehicles/s], got {rate:g}")
            speed = self._traffic_speed(kind, "speed", speed)

            def source(runner: Any) -> T.Source:
                return T.Source(
                    name=name,
                    definition=definition,
                    speed_range=speed_range,
                    speed=speed,
                    point=runner.world.point_of(position.resolve(runner.world)),
                    radius=radius,
                    rate=rate,
                    started=runner.world.time,
                )

            return lambda actor: A.GenerateTraffic(actor, where, source)
        rate = self.num(kind, "rate", math.inf)
        if rate <= 0.0:
            raise self.error(kind, f"rate must be > 0 [vehicles/s], got {rate:g}")

        def sink(runner: Any) -> T.Sink:
            return T.Sink(
                name=name,
                definition=definition,
                point=runner.world.point_of(position.resolve(runner.world)),
                radius=radius,
                rate=rate,
            )

        return lambda actor: A.GenerateTraffic(actor, where, sink)

    def _traffic_speed(self, el: Any, name: str, default: float | None) -> float | None:
        """A generated vehicle's speed attribute [m/s], within ``[0, MAX_SPEED]``."""
        from aldm_gym.scenario.traffic import MAX_SPEED

        value = self.num(el, name, default)
        if value is not None and not 0.0 <= value <= MAX_SPEED:
            raise self.error(el, f"{name} must be in [0, {MAX_SPEED:g}] [m/s], got {value:g}")
        return value

    def _traffic_definition(self, kind: Any) -> Any:
        """The ``TrafficDefinition`` of a traffic action: its vehicle categories (the
        controllers and roles are the env's traffic's: ignored, one warning)."""
        from aldm_gym.scenario.traffic import CATEGORY_SIZES, TrafficDefinition

        distribution = kind.find("TrafficDistribution")
        if distribution is not None:
            return self._traffic_distribution(distribution)
        el = kind.find("TrafficDefinition")
        if el is None:
            if kind.tag == "TrafficSinkAction":
                return TrafficDefinition()
            raise self.error(kind, "missing <TrafficDefinition> (or 1.3's <TrafficDistribution>)")
        parts = self.kids(
            el,
            ("VehicleCategoryDistribution", "ControllerDistribution", "VehicleRoleDistribution"),
        )
        categories: list[tuple[str, float]] = []
        for part in parts:
            if part.tag != "VehicleCategoryDistribution":
                self.ignore(part, _GENERATED_DRIVERS)
                continue
            for entry in self.kids(part, ("VehicleCategoryDistributionEntry",)):
                category = self.choice(entry, "category", tuple(CATEGORY_SIZES))
                weight = self.num(entry, "weight")
                if weight < 0.0:
                    raise self.error(entry, f"weight must be >= 0, got {weight:g}")
                if weight > 0.0:
                    categories.append((category, weight))
        if not categories:
            if any(p.tag == "VehicleCategoryDistribution" for p in parts):
                raise self.error(el, "no vehicle category has a weight above 0")
            return TrafficDefinition()
        return TrafficDefinition(tuple(categories))

    def _traffic_distribution(self, el: Any) -> Any:
        """A 1.3 ``TrafficDistribution``: entity templates drawn by the product of the
        entry's and the template's weight (within its ``EntityDistribution``); each a
        vehicle with its category and bounding box (controllers and properties are
        the env's traffic's: ignored, one warning)."""
        from aldm_gym.scenario.traffic import TrafficDefinition

        categories: list[tuple[str, float]] = []
        sizes: list[tuple[float, float]] = []
        for entry in self.kids(el, ("TrafficDistributionEntry",)):
            self.kids(entry, ("EntityDistribution", "Properties"))
            weight = self.num(entry, "weight")
            if weight < 0.0:
                raise self.error(entry, f"weight must be >= 0, got {weight:g}")
            inner = self.kids(self.child(entry, "EntityDistribution"), ("EntityDistributionEntry",))
            weights = [self.num(e, "weight") for e in inner]
            if any(w < 0.0 for w in weights):
                raise self.error(entry, "an EntityDistributionEntry weight is below 0")
            total = sum(weights)
            for e, w in zip(inner, weights, strict=True):
                if weight <= 0.0 or w <= 0.0:
                    continue
                template = self.child(e, "ScenarioObjectTemplate")
                parts = self.kids(
                    template, ("Vehicle", "Pedestrian", "MiscObject", "CatalogReference",
                               "ObjectController")
                )  # fmt: skip
                body = next((p for p in parts if p.tag != "ObjectController"), None)
                if body is None:
                    raise self.error(template, "expects a Vehicle (or a CatalogReference)")
                if any(p.tag == "ObjectController" for p in parts):
                    self.ignore(template, _GENERATED_DRIVERS)
                reader: _Reader = self
                if body.tag == "CatalogReference":
                    body, reader = self.from_catalog(body)
                if body.tag != "Vehicle":
                    raise reader.error(
                        body, f"generated traffic is vehicles here, not a <{body.tag}>"
                    )
                spec = reader._entity("template", body, False, reader.where(body))
                categories.append((spec.category, weight * w / total))
                sizes.append((spec.box.length, spec.box.width))
        if not categories:
            raise self.error(el, "no entity template has a weight above 0")
        return TrafficDefinition(tuple(categories), tuple(sizes))

    def _traffic_area(
        self, kind: Any, name: str, where: str
    ) -> Callable[[Entity | None], A.Instance]:
        """``TrafficAreaAction`` (1.3): road ranges or a polygon."""
        from aldm_gym.scenario import traffic as T

        self.kids(kind, ("TrafficDistribution", "TrafficArea"))
        if kind.find("TrafficDistribution") is None:
            raise self.error(kind, "missing <TrafficDistribution>")
        definition = self._traffic_distribution(kind.find("TrafficDistribution"))
        count = self.integer(kind, "numberOfEntities")
        if not 0 <= count <= T.MAX_GENERATED:
            raise self.error(
                kind, f"numberOfEntities must be in [0, {T.MAX_GENERATED}], got {count}"
            )
        continuous = self.flag(kind, "continuous")
        area = self.child(kind, "TrafficArea")
        shapes = self.kids(area, ("Polygon", "RoadRange"))
        if not shapes:
            raise self.error(area, "expects a <Polygon> or <RoadRange>s")
        if shapes[0].tag == "Polygon":
            if len(shapes) > 1:
                raise self.error(area, "expects one <Polygon>, or <RoadRange>s")
            corners = [self.position(p) for p in self.kids(shapes[0], ("Position",))]
            if len(corners) < 3:
                raise self.error(shapes[0], f"a polygon needs >= 3 positions, has {len(corners)}")

            def make(runner: Any) -> Any:
                world = runner.world
                polygon = [world.point_of(c.resolve(world)) for c in corners]
                return T.Area(
                    name=name, definition=definition, count=count, continuous=continuous,
                    polygon=polygon,
                )  # fmt: skip

            return lambda actor: A.GenerateTraffic(actor, where, make)
        road_ranges: list[tuple[float, list[tuple[str, float | None, tuple[int, ...]]]]] = []
        for rr in shapes:
            if rr.tag != "RoadRange":
                raise self.error(rr, "expects one <Polygon>, or <RoadRange>s")
            cursors = self.kids(rr, ("RoadCursor",))
            if len(cursors) < 2:
                raise self.error(rr, f"a road range needs >= 2 road cursors, has {len(cursors)}")
            limit = self.num(rr, "length", math.inf)
            if not limit > 0.0:
                raise self.error(rr, f"length must be > 0, got {limit:g}")
            points = []
            for c in cursors:
                lanes = tuple(self.integer(lane, "id") for lane in self.kids(c, ("Lane",)))
                points.append((self.attr(c, "roadId"), self.num(c, "s", None), lanes))
            road_ranges.append((limit, points))
        area_where = self.where(area)

        def make_ranges(runner: Any) -> Any:
            ranges = T.road_ranges(runner.world.road, road_ranges, area_where)
            return T.Area(
                name=name, definition=definition, count=count, continuous=continuous,
                ranges=ranges,
            )  # fmt: skip

        return lambda actor: A.GenerateTraffic(actor, where, make_ranges)

    def dynamics(self, el: Any) -> A.Dynamics:
        """``*Dynamics`` with shape, dimension, value."""
        shape = self.choice(el, "dynamicsShape", A.SHAPES)
        # a step has no duration: files written for esmini often leave both out
        step = shape == "step"
        return A.Dynamics(
            shape=shape,
            dimension=self.choice(
                el, "dynamicsDimension", ("time", "distance", "rate"), "time" if step else _MISSING
            ),
            value=self.num(el, "value", 0.0 if step else _MISSING),
            where=self.where(el),
        )

    def _longitudinal(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        where = self.where(body)
        if body.tag == "SpeedAction":
            self.kids(body, ("SpeedActionDynamics", "SpeedActionTarget"))
            dyn = self.dynamics(self.child(body, "SpeedActionDynamics"))
            target_el = self.one(
                self.child(body, "SpeedActionTarget"),
                ("AbsoluteTargetSpeed", "RelativeTargetSpeed"),
            )
            continuous = False
            if target_el.tag == "AbsoluteTargetSpeed":
                v = self.num(target_el, "value")
                target: Callable[[Any], float] = lambda world: v  # noqa: E731
            else:
                ref = self._entity_ref(target_el, "entityRef")
                value = self.num(target_el, "value")
                kind = self.choice(target_el, "speedTargetValueType", ("delta", "factor"), "delta")
                continuous = self.flag(target_el, "continuous")

                def target(
                    world: Any, ref: str = ref, value: float = value, kind: str = kind
                ) -> float:
                    e = world.entities[ref]
                    base = e.current_speed
                    return base + value if kind == "delta" else base * value

            return lambda actor: A.SpeedChange(actor, where, dyn, target, continuous)
        if body.tag == "SpeedProfileAction":
            return self._speed_profile(body)
        self.kids(body, ("DynamicConstraints",))
        ref = self._entity_ref(body, "entityRef")
        distance = self.num(body, "distance", None)
        gap = self.num(body, "timeGap", None)
        if (distance is None) == (gap is None):
            raise self.error(body, "give one of distance and timeGap")
        if distance is not None and distance < 0.0:
            distance = self._magnitude(body, "distance", distance, "m")
        if gap is not None and gap < 0.0:
            gap = self._magnitude(body, "timeGap", gap, "s")
        freespace = self.flag(body, "freespace")
        system = self.choice(body, "coordinateSystem", ("entity", "road", "lane"), "entity")
        displacement = self.choice(
            body,
            "displacement",
            ("trailingReferencedEntity", "leadingReferencedEntity", "any"),
            "trailingReferencedEntity",
        )
        continuous = self.flag(body, "continuous")
        limits = self.constraints(body.find("DynamicConstraints"), rates=True)
        leading: bool | None = {
            "leadingReferencedEntity": True,
            "trailingReferencedEntity": False,
        }.get(displacement)  # None ("any"): the side the actor is on when it starts
        return lambda actor: A.LongitudinalDistance(
            actor, where, ref, distance, gap, freespace, leading, continuous, limits, system
        )

    def _magnitude(self, el: Any, name: str, value: float, unit: str) -> float:
        """A negative ``distance`` or ``timeGap`` of a ``LongitudinalDistanceAction``
        (the schema's range is 0 and up; ``displacement`` gives the side): read as its
        magnitude, as esmini reads it (scenariogeneration's one_action_example writes
        ``distance="-4.0"``), with a warning naming the file and line."""
        warnings.warn(
            f"{self.where(el, name)}: {value:g} {unit} is outside the schema's range "
            f"(0 and up); read as {-value:g} {unit}, as esmini reads it (displacement "
            "gives the side)",
            ScenarioWarning,
            stacklevel=2,
        )
        return -value

    def _synchronize(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        """``SynchronizeAction``: arrive when the master arrives."""
        where = self.where(body)
        self.kids(body, ("TargetPositionMaster", "TargetPosition", "FinalSpeed"))
        master = self._entity_ref(body, "masterEntityRef")
        target_master = self.position(self.child(body, "TargetPositionMaster"))
        target = self.position(self.child(body, "TargetPosition"))
        tolerances = (
            self.num(body, "targetToleranceMaster", 0.0),
            self.num(body, "targetTolerance", 0.0),
        )
        if min(tolerances) < 0:
            raise self.error(body, "the target tolerances must be >= 0")
        final: tuple[str, float] | None = None
        steady: tuple[str, float] | None = None
        final_el = body.find("FinalSpeed")
        if final_el is not None:
            speed = self.one(final_el, ("AbsoluteSpeed", "RelativeSpeedToMaster"))
            if speed.tag == "AbsoluteSpeed":
                final = ("absolute", self.num(speed, "value"))
            else:
                kind = self.choice(speed, "speedTargetValueType", ("delta", "factor"))
                final = (kind, self.num(speed, "value"))
            state = [k for k in speed if isinstance(k.tag, str)]
            for k in state:
                if k.tag == "TargetDistanceSteadyState":
                    steady = ("distance", self.num(k, "distance"))
                elif k.tag == "TargetTimeSteadyState":
                    steady = ("time", self.num(k, "time"))
                else:
                    raise self.unsupported(
                        k, ("TargetDistanceSteadyState", "TargetTimeSteadyState")
                    )
        return lambda actor: A.Synchronize(
            actor, where, master, target_master, target, tolerances, final, steady
        )

    def _speed_profile(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        """``SpeedProfileAction`` (1.2+): speeds reached one after another, each in its
        ``time`` [s] or as fast as the limits allow."""
        where = self.where(body)
        self.kids(body, ("DynamicConstraints", "SpeedProfileEntry"))
        ref = self._entity_ref(body, "entityRef") if body.get("entityRef") is not None else None
        mode = self.choice(body, "followingMode", ("position", "follow"))
        dc = body.find("DynamicConstraints")
        acc = dec = math.inf
        jerks = None
        if dc is not None:
            acc = self.num(dc, "maxAcceleration", math.inf)
            dec = self.num(dc, "maxDeceleration", math.inf)
            if not (acc > 0 and dec > 0):
                raise self.error(dc, "maxAcceleration and maxDeceleration must be > 0")
            rise = self.num(dc, "maxAccelerationRate", math.inf)
            fall = self.num(dc, "maxDecelerationRate", math.inf)
            if not (rise > 0 and fall > 0):
                raise self.error(dc, "maxAccelerationRate and maxDecelerationRate must be > 0")
            if mode == "follow" and math.isfinite(rise) and math.isfinite(fall):
                jerks = (rise, fall)
        entries = []
        for e in body.findall("SpeedProfileEntry"):
            time = self.num(e, "time", None)
            if time is not None and time < 0:
                raise self.error(e, f"time must be >= 0, got {time:g}")
            entries.append((self.num(e, "speed"), time))
        if not entries:
            raise self.error(body, "no <SpeedProfileEntry>")
        return lambda actor: A.SpeedProfile(actor, where, entries, ref, (acc, dec), jerks)

    def _lateral(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        where = self.where(body)
        if body.tag == "LaneChangeAction":
            self.kids(body, ("LaneChangeActionDynamics", "LaneChangeTarget"))
            dyn = self.dynamics(self.child(body, "LaneChangeActionDynamics"))
            offset = self.num(body, "targetLaneOffset", 0.0)
            t = self.one(
                self.child(body, "LaneChangeTarget"), ("RelativeTargetLane", "AbsoluteTargetLane")
            )
            if t.tag == "AbsoluteTargetLane":
                lane_id = self.integer(t, "value")
                target: Callable[[Any, Entity], int] = lambda world, actor: lane_id  # noqa: E731
            else:
                ref = self._entity_ref(t, "entityRef")
                d = self.integer(t, "value")

                def target(world: Any, actor: Entity, ref: str = ref, d: int = d) -> int:
                    # + is the referenced entity's left: along t where it drives along s
                    c = world.coordinates(world.entities[ref])
                    return lane_step(c.lane_id, d * c.direction)

            return lambda actor: A.LaneChange(actor, where, dyn, target, offset)
        if body.tag == "LateralDistanceAction":
            return self._lateral_distance(body)
        self.kids(body, ("LaneOffsetActionDynamics", "LaneOffsetTarget"))
        dyn_el = self.child(body, "LaneOffsetActionDynamics")
        shape = self.choice(dyn_el, "dynamicsShape", A.SHAPES)
        acc = self.num(dyn_el, "maxLateralAcc", None)
        continuous = self.flag(body, "continuous", False)  # LENIENT: esmini's default
        t = self.one(
            self.child(body, "LaneOffsetTarget"),
            ("AbsoluteTargetLaneOffset", "RelativeTargetLaneOffset"),
        )
        value = self.num(t, "value")
        if t.tag == "AbsoluteTargetLaneOffset":

            def offset_target(world: Any, actor: Entity, value: float = value) -> float:
                return float(world.offset_in_lane(actor, value))

        else:
            ref = self._entity_ref(t, "entityRef")

            def offset_target(
                world: Any, actor: Entity, ref: str = ref, value: float = value
            ) -> float:
                return float(world.offset_beside(actor, world.entities[ref], value))

        return lambda actor: A.LaneOffset(actor, where, shape, acc, offset_target, continuous)

    def constraints(self, dc: Any, rates: bool) -> tuple[float, ...] | None:
        """``DynamicConstraints``: ``(maxAcceleration, maxDeceleration, maxSpeed)`` and,
        with ``rates``, ``maxAccelerationRate, maxDecelerationRate`` (inf where not
        given); None without the element or without any acceleration limit (a rigid
        connection).

        :raises ScenarioError: a limit that is not > 0.
        """
        if dc is None:
            return None
        names = ["maxAcceleration", "maxDeceleration", "maxSpeed"]
        if rates:
            names += ["maxAccelerationRate", "maxDecelerationRate"]
        limits = tuple(self.num(dc, name, math.inf) for name in names)
        for name, value in zip(names, limits, strict=True):
            if not value > 0.0:
                raise self.error(dc, f"{name} must be > 0, got {value:g}")
        if math.isinf(limits[0]) and math.isinf(limits[1]):
            return None
        return limits

    def _lateral_distance(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        """``LateralDistanceAction``: a distance across the road from an entity."""
        where = self.where(body)
        self.kids(body, ("DynamicConstraints",))
        ref = self._entity_ref(body, "entityRef")
        distance = self.num(body, "distance", 0.0)
        if distance < 0:
            raise self.error(body, f"distance must be >= 0, got {distance:g}")
        freespace = self.flag(body, "freespace")
        continuous = self.flag(body, "continuous")
        self.choice(body, "coordinateSystem", ("entity", "road", "lane"), "entity")
        side = self.choice(
            body,
            "displacement",
            ("leftToReferencedEntity", "rightToReferencedEntity", "any"),
            "any",
        )
        dc = body.find("DynamicConstraints")
        limits = None
        if dc is not None:
            names = ("maxAcceleration", "maxDeceleration", "maxSpeed", "maxAccelerationRate")
            values = tuple(self.num(dc, name, math.inf) for name in names)
            for name, value in zip(names, values, strict=True):
                if not value > 0.0:
                    raise self.error(dc, f"{name} must be > 0, got {value:g}")
            if any(math.isfinite(v) for v in values[:3]):
                limits = values
        left = {"leftToReferencedEntity": True, "rightToReferencedEntity": False}.get(side)
        return lambda actor: A.LateralDistance(
            actor, where, ref, distance, freespace, left, continuous, limits
        )

    def _route(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        where = self.where(body)
        self.one(body, ("Route", "CatalogReference"))
        route, r = self._inline_or_catalog(body, "Route")
        r.kids(route, ("ParameterDeclarations", "Waypoint"))
        if r.flag(route, "closed", False):
            raise r.error(route, "closed routes are not supported")
        waypoints = []
        for wp in route.findall("Waypoint"):
            r.choice(wp, "routeStrategy", ("fastest", "shortest", "leastIntersections", "random"))
            waypoints.append(r.position(r.child(wp, "Position")))
        if len(waypoints) < 2:
            raise r.error(route, f"a route needs at least 2 waypoints, has {len(waypoints)}")
        return lambda actor: A.AssignRoute(actor, where, waypoints)

    def _routing(self, body: Any) -> Callable[[Entity | None], A.Instance]:
        where = self.where(body)
        self.kids(
            body,
            (
                "TrajectoryRef",
                "Trajectory",
                "CatalogReference",
                "TimeReference",
                "TrajectoryFollowingMode",
            ),
        )
        initial = self.num(body, "initialDistanceOffset", 0.0)
        if initial < 0.0:
            raise self.error(body, f"initialDistanceOffset must be >= 0, got {initial:g}")
        ref = body.find("TrajectoryRef")
        el, r = self._trajectory(ref if ref is not None else body)
        shape = r.shape(r.one(r.child(el, "Shape"), _SHAPES))
        timing: tuple[bool, float, float] | None = (False, 1.0, 0.0)
        timing_el = body.find("TimeReference/Timing")
        if timing_el is not None:
            absolute = (
                self.choice(timing_el, "domainAbsoluteRelative", ("absolute", "relative"))
                == "absolute"
            )
            timing = (
                absolute,
                self.num(timing_el, "scale", 1.0),
                self.num(timing_el, "offset", 0.0),
            )
        elif body.find("TimeReference/None") is not None:
            timing = None
        mode = body.find("TrajectoryFollowingMode")
        follow = mode is not None and (
            self.choice(mode, "followingMode", ("position", "follow")) == "follow"
        )
        if initial and timing is not None and body.find("TimeReference/Timing") is not None:
            raise self.error(body, "initialDistanceOffset with timing is not supported")
        return lambda actor: A.FollowTrajectory(actor, where, shape, timing, initial, follow)

    def _inline_or_catalog(self, holder: Any, tag: str) -> tuple[Any, _Reader]:
        """The ``tag`` element that ``holder`` gives inline or by a ``CatalogReference``,
        with the reader for it: one that sees the element's own parameters (inline:
        their defaults; a catalog entry: bound to the reference's assignments)."""
        el = holder.find(tag)
        if el is not None:
            return el, self.scoped(el)
        catalog = holder.find("CatalogReference")
        if catalog is None:
            raise self.error(holder, f"missing <{tag}> (inline or a CatalogReference)")
        el, reader = self.from_catalog(catalog)
        if el.tag != tag:
            raise self.error(catalog, f"the catalog entry is a <{el.tag}>, not a <{tag}>")
        return el, reader

    def _trajectory(self, holder: Any) -> tuple[Any, _Reader]:
        """The ``Trajectory`` that ``holder`` gives inline or from a catalog, with a
        reader that sees the trajectory's own parameters."""
        traj, r = self._inline_or_catalog(holder, "Trajectory")
        r.kids(traj, ("ParameterDeclarations", "Shape"))
        if r.flag(traj, "closed", False):
            raise r.error(traj, "closed trajectories are not supported")
        return traj, r

    def _route_position(self, p: Any, orient: Orientation | None, where: str) -> Position:
        """``RoutePosition``: a route and where on it."""
        self.kids(p, ("RouteRef", "Orientation", "InRoutePosition"))
        route, r = self._inline_or_catalog(self.child(p, "RouteRef"), "Route")
        r.kids(route, ("ParameterDeclarations", "Waypoint"))
        waypoints = tuple(r.position(r.child(wp, "Position")) for wp in route.findall("Waypoint"))
        if not waypoints:
            raise r.error(route, "a route needs waypoints")
        at = self.one(
            self.child(p, "InRoutePosition"),
            ("FromCurrentEntity", "FromRoadCoordinates", "FromLaneCoordinates"),
        )
        if at.tag == "FromCurrentEntity":
            entity = self._entity_ref(at, "entityRef")
            return RoutePos(waypoints, "entity", entity=entity, orientation=orient, where=where)
        path_s = self.num(at, "pathS")
        if path_s < 0:
            raise self.error(at, f"pathS must be >= 0, got {path_s:g}")
        if at.tag == "FromRoadCoordinates":
            t = self.num(at, "t")
            return RoutePos(waypoints, "road", path_s=path_s, t=t, orientation=orient, where=where)
        return RoutePos(
            waypoints,
            "lane",
            path_s=path_s,
            lane_id=self.integer(at, "laneId"),
            lane_offset=self.num(at, "laneOffset", 0.0),
            orientation=orient,
            where=where,
        )

    def shape(self, el: Any) -> S.Shape:
        """A trajectory's ``Shape`` child."""
        where = self.where(el)
        if el.tag == "Polyline":
            self.kids(el, ("Vertex",))
            vertices: list[tuple[float | None, Position]] = []
            for v in el.findall("Vertex"):
                vertices.append(
                    (self.num(v, "time", None), self.position(self.child(v, "Position")))
                )
            if len(vertices) < 2:
                raise self.error(el, f"a polyline needs at least 2 vertices, has {len(vertices)}")
            return S.Polyline(vertices, where)
        if el.tag == "Clothoid":
            self.kids(el, ("Position",))
            prime = self.num(el, "curvaturePrime", None)
            if prime is None:  # 1.0's name
                prime = self.num(el, "curvatureDot", 0.0)
            return S.Clothoid(
                self.position(self.child(el, "Position")),
                self.num(el, "curvature"),
                prime,
                self.num(el, "length"),
                self.num(el, "startTime", None),
                self.num(el, "stopTime", None),
                where,
            )
        if el.tag == "ClothoidSpline":
            self.kids(el, ("ClothoidSplineSegment",))
            segments = []
            for seg in el.findall("ClothoidSplineSegment"):
                self.kids(seg, ("PositionStart",))
                start = seg.find("PositionStart")
                segments.append(
                    (
                        self.num(seg, "curvatureStart"),
                        self.num(seg, "curvatureEnd"),
                        self.num(seg, "length"),
                        self.num(seg, "hOffset", 0.0),
                        self.num(seg, "timeStart", None),
                        None if start is None else self.position(start),
                    )
                )
            if not segments:
                raise self.error(el, "a clothoid spline needs at least one <ClothoidSplineSegment>")
            return S.ClothoidSpline(segments, self.num(el, "timeEnd", None), where)
        self.kids(el, ("ControlPoint", "Knot"))
        points = [
            (
                self.position(self.child(cp, "Position")),
                self.num(cp, "time", None),
                self.num(cp, "weight", 1.0),
            )
            for cp in el.findall("ControlPoint")
        ]
        knots = [self.num(k, "value") for k in el.findall("Knot")]
        return S.Nurbs(self.integer(el, "order"), points, knots, where)

    # ------------------------------------------------------------ init and storyboard
    def init(self) -> list[A.Instance]:
        """The ``Init`` actions' instances, in document order."""
        out: list[A.Instance] = []
        init = self.child(self.child(self.root, "Storyboard"), "Init")
        self.kids(init, ("Actions",))
        actions = init.find("Actions")
        if actions is None:
            return out
        for el in self.kids(actions, ("GlobalAction", "UserDefinedAction", "Private")):
            if el.tag != "Private":
                out.append(self.other(el)(None))
                continue
            for name in self._entity_refs(el, "entityRef"):
                actor = self._rt(name)
                for pa in self.kids(el, ("PrivateAction",)):
                    out.append(self.private(pa)(actor))
        return out

    def storyboard(self) -> Storyboard:
        """The stories and the stop trigger; checks every element reference."""
        sb = self.child(self.root, "Storyboard")
        self.kids(sb, ("Init", "Story", "StopTrigger"))
        stories = []
        for story in sb.findall("Story"):
            self.kids(story, ("ParameterDeclarations", "Act"))
            inner = self.scoped(story)
            acts = [inner._act(a) for a in story.findall("Act")]
            stories.append(Story(self.attr(story, "name"), self.where(story), acts))
        stop_el = sb.find("StopTrigger")
        stop = self.trigger(stop_el, empty=False) if stop_el is not None else Trigger([], False)
        board = Storyboard(stories, stop)
        for el, kind, name in self.pending:
            if board.element(kind, name) is None:
                raise self.error(
                    el, f"storyboardElementRef={name!r} names no {kind} of the storyboard"
                )
        self.board = board
        return board

    def _act(self, el: Any) -> Act:
        self.kids(el, ("ManeuverGroup", "StartTrigger", "StopTrigger"))
        groups = [self._group(g) for g in el.findall("ManeuverGroup")]
        start_el = el.find("StartTrigger")
        stop_el = el.find("StopTrigger")
        return Act(
            self.attr(el, "name"),
            self.where(el),
            groups,
            self.trigger(start_el, empty=True) if start_el is not None else Trigger([], True),
            self.trigger(stop_el, empty=False) if stop_el is not None else Trigger([], False),
        )

    def _group(self, el: Any) -> ManeuverGroup:
        self.kids(el, ("Actors", "CatalogReference", "Maneuver"))
        actors_el = self.child(el, "Actors")
        self.kids(actors_el, ("EntityRef",))
        select = self.flag(actors_el, "selectTriggeringEntities", False)
        actors = list(
            dict.fromkeys(
                n for r in actors_el.findall("EntityRef") for n in self._entity_refs(r, "entityRef")
            )
        )
        maneuvers = []
        for m in el:  # catalog references and maneuvers, in document order
            if m.tag == "CatalogReference":
                m, inner = self.from_catalog(m)  # its parameters bound to the assignments
                if m.tag != "Maneuver":
                    raise inner.error(m, f"the catalog entry is a <{m.tag}>, not a <Maneuver>")
            elif m.tag == "Maneuver":
                inner = self.scoped(m)
            else:
                continue
            inner.kids(m, ("ParameterDeclarations", "Event"))
            events = [inner._event(e) for e in m.findall("Event")]
            maneuvers.append(Maneuver(inner.attr(m, "name"), inner.where(m), events))
        maximum = self.integer(el, "maximumExecutionCount", 1)
        return ManeuverGroup(
            self.attr(el, "name"), self.where(el), actors, maneuvers, max(maximum, 1), select
        )

    def _event(self, el: Any) -> Event:
        self.kids(el, ("Action", "StartTrigger"))
        actions = []
        for a in el.findall("Action"):
            body = self.one(a, ("PrivateAction", "GlobalAction", "UserDefinedAction"))
            factory = self.private(body) if body.tag == "PrivateAction" else self.other(body)
            runtime = self.runtime

            def make(
                runner: Any, actor: str | None, factory: Any = factory, runtime: Any = runtime
            ) -> Any:
                return factory(None if actor is None else runtime[actor])

            element = ActionElement(self.attr(a, "name"), self.where(a), make)
            actions.append(element)
        start_el = el.find("StartTrigger")
        priority = self.choice(el, "priority", ("overwrite", "override", "skip", "parallel"))
        return Event(
            self.attr(el, "name"),
            self.where(el),
            actions,
            self.trigger(start_el, empty=True) if start_el is not None else Trigger([], True),
            priority,
            max(self.integer(el, "maximumExecutionCount", 1), 1),
        )

    # ------------------------------------------------------------ triggers and conditions
    def trigger(self, el: Any, empty: bool) -> Trigger:
        """A start or stop trigger."""
        groups = []
        for g in self.kids(el, ("ConditionGroup",)):
            groups.append([self.condition(c) for c in self.kids(g, ("Condition",))])
        return Trigger(groups, empty)

    def condition(self, el: Any) -> Condition:
        """One ``Condition`` with its edge and delay."""
        edge = self.choice(
            el, "conditionEdge", ("none", "rising", "falling", "risingOrFalling"), "none"
        )
        delay = self.num(el, "delay", 0.0)
        if delay < 0:
            raise self.error(el, f"delay must be >= 0, got {delay:g}")
        body = self.one(el, ("ByValueCondition", "ByEntityCondition"))
        evaluate = self._by_value(body) if body.tag == "ByValueCondition" else self._by_entity(body)
        # a name is a label: written as it is (esmini files build names from strings)
        return Condition(el.get("name", ""), evaluate, edge, delay, self.where(el))

    def _rule(self, el: Any) -> Callable[[Any, Any], bool]:
        return C.rule(self.choice(el, "rule", tuple(C.RULES)))

    def _by_value(self, body: Any) -> Callable[[Any], bool]:
        c = self.one(
            body,
            (
                "SimulationTimeCondition",
                "StoryboardElementStateCondition",
                "ParameterCondition",
                "VariableCondition",
                "TimeOfDayCondition",
                "UserDefinedValueCondition",
                "TrafficSignalCondition",
                "TrafficSignalControllerCondition",
            ),
        )
        if c.tag == "SimulationTimeCondition":
            value, rule = self.num(c, "value"), self._rule(c)
            return lambda runner: rule(runner.world.time, value)
        if c.tag in ("ParameterCondition", "VariableCondition"):
            store = "parameters" if c.tag == "ParameterCondition" else "variables"
            ref_attr = "parameterRef" if store == "parameters" else "variableRef"
            name = parameter_name(self.required_raw(c, ref_attr))
            known = self.params if store == "parameters" else self.variables()
            if name not in known:
                raise self.error(
                    c, f"{ref_attr}={name!r} is not declared; declared: {sorted(known)}"
                )
            given, rule = self.attr(c, "value"), self._rule(c)
            initial = known[name]
            return lambda runner: _compare(rule, getattr(runner, store).get(name, initial), given)
        if c.tag in _NEVER:
            self.ignore(c, _NEVER[c.tag])
            return lambda runner: False
        kind = self.choice(c, "storyboardElementType", _ELEMENT_TYPES)
        name = self.attr(c, "storyboardElementRef")
        state = self.choice(c, "state", STATES + TRANSITIONS)
        self.pending.append((c, kind, name))

        seen = [0]  # this condition's cursor into the element's transitions

        def evaluate(runner: Any, kind: str = kind, name: str = name, state: str = state) -> bool:
            element = runner.storyboard.element(kind, name)
            shown, seen[0] = element.shows(state, seen[0], runner.storyboard.tick)
            return shown

        return evaluate

    def _by_entity(self, body: Any) -> Callable[[Any], bool]:
        self.kids(body, ("TriggeringEntities", "EntityCondition"))
        te = self.child(body, "TriggeringEntities")
        self.kids(te, ("EntityRef",))
        mode = self.choice(te, "triggeringEntitiesRule", ("any", "all"))
        triggering = list(
            dict.fromkeys(
                n for r in te.findall("EntityRef") for n in self._entity_refs(r, "entityRef")
            )
        )
        if not triggering:
            raise self.error(te, "no <EntityRef>")
        c = self.one(
            self.child(body, "EntityCondition"),
            (
                "RelativeDistanceCondition",
                "TimeHeadwayCondition",
                "TimeToCollisionCondition",
                "SpeedCondition",
                "RelativeSpeedCondition",
                "ReachPositionCondition",
                "DistanceCondition",
                "TraveledDistanceCondition",
                "CollisionCondition",
                "StandStillCondition",
                "AccelerationCondition",
                "EndOfRoadCondition",
                "OffroadCondition",
                "RelativeClearanceCondition",
                "AngleCondition",
                "RelativeAngleCondition",
            ),
        )
        mark = len(self.refs)
        one = self._entity_condition(c)
        named = tuple(dict.fromkeys(self.refs[mark:]))

        def holds(runner: Any, name: str) -> bool:
            # no condition holds on an entity that is not in the scenario (deleted)
            entities = runner.world.entities
            e = entities[name]
            return e.present and all(entities[n].present for n in named) and one(runner, e)

        return C.ByEntity(triggering, mode == "all", holds)

    def _state_condition(self, c: Any) -> Callable[[Any, Entity], bool] | None:
        """Conditions on one entity's state: collisions, standing still, acceleration,
        the end of the road, off road, clearance; None for the others."""
        if c.tag == "CollisionCondition":
            target = self.one(c, ("EntityRef", "ByType"))
            if target.tag == "EntityRef":
                ref = self._entity_ref(target, "entityRef")
                return lambda runner, e: C.boxes_overlap(e, runner.world.entities[ref])
            kind = self.choice(
                target, "type", ("vehicle", "pedestrian", "miscellaneous", "miscObject")
            )
            kind = "miscObject" if kind == "miscellaneous" else kind
            return lambda runner, e: _collides(
                runner.world,
                e,
                [o for o in runner.world.entities.values() if o.kind == kind and o.present],
            )
        if c.tag == "StandStillCondition":
            duration = self.num(c, "duration")
            return lambda runner, e: C.stood_still(runner.world, e, duration)
        if c.tag == "AccelerationCondition":
            self.absent(c, "direction", allowed={"direction": ("longitudinal",)})
            rule, value = self._rule(c), self.num(c, "value")
            return lambda runner, e: rule(C.acceleration(runner.world, e), value)
        if c.tag == "EndOfRoadCondition":
            duration = self.num(c, "duration")
            return lambda runner, e: C.at_road_end(runner.world, e, duration)
        if c.tag == "OffroadCondition":
            duration = self.num(c, "duration")
            return lambda runner, e: C.off_road(runner.world, e, duration)
        if c.tag == "RelativeClearanceCondition":
            return self._clearance(c)
        if c.tag in ("AngleCondition", "RelativeAngleCondition"):
            return self._angle(c)
        return None

    def _angle(self, c: Any) -> Callable[[Any, Entity], bool]:
        """``AngleCondition`` / ``RelativeAngleCondition`` (1.3): the heading, pitch or
        roll within ``angleTolerance`` of ``angle`` [rad], in world, road or lane
        coordinates (relative: also the other entity's frame)."""
        kind = self.choice(c, "angleType", ("heading", "pitch", "roll"))
        target, tolerance = self.num(c, "angle"), self.num(c, "angleTolerance")
        if tolerance < 0.0:
            raise self.error(c, f"angleTolerance must be >= 0, got {tolerance:g}")
        systems = ("entity", "world", "road", "lane", "trajectory")
        if c.tag == "AngleCondition":
            system = self.choice(c, "coordinateSystem", systems, "world")
            if system == "entity":
                raise self.error(c, "an entity's angle in its own coordinate system is 0")
        else:
            system = self.choice(c, "coordinateSystem", systems, "entity")
        if system == "trajectory":
            raise self.error(c, "coordinateSystem='trajectory' is not supported")

        def measure(runner: Any, e: Entity) -> float:
            if c.tag == "AngleCondition":
                return C.angle(runner.world, e, kind, system)
            return C.relative_angle(runner.world, e, runner.world.entities[ref], kind, system)

        ref = self._entity_ref(c, "entityRef") if c.tag == "RelativeAngleCondition" else ""

        def within(runner: Any, e: Entity) -> bool:
            try:
                return C.angle_within(measure(runner, e), target, tolerance)
            except OffRoadError:  # no road or lane to measure against
                return False

        return within

    def _clearance(self, c: Any) -> Callable[[Any, Entity], bool]:
        """``RelativeClearanceCondition``: the lanes ``from``..``to`` (relative to the
        entity's, to its left positive) are clear of other entities over
        ``distanceBackward`` and ``distanceForward`` [m] (the entities named, else all)."""
        self.kids(c, ("RelativeLaneRange", "EntityRef"))
        ranges = [
            (self.integer(r, "from", 0), self.integer(r, "to", 0))
            for r in c.findall("RelativeLaneRange")
        ]
        # an absent entity leaves the lanes clear (it does not make the condition fail)
        refs = [self._entity_ref(r, "entityRef", record=False) for r in c.findall("EntityRef")]
        back, ahead = self.num(c, "distanceBackward"), self.num(c, "distanceForward")
        free_space = self.flag(c, "freeSpace")
        opposite = self.flag(c, "oppositeLanes")

        def clear(runner: Any, e: Entity) -> bool:
            w = runner.world
            others = [w.entities[n] for n in refs] if refs else list(w.entities.values())
            others = [o for o in others if o.present]
            return C.lanes_clear(w, e, others, ranges, back, ahead, free_space, opposite)

        return clear

    def _entity_condition(self, c: Any) -> Callable[[Any, Entity], bool]:
        special = self._state_condition(c)
        if special is not None:
            return special
        if c.tag == "TraveledDistanceCondition":
            traveled = self.num(c, "value")
            return lambda runner, e: e.traveled >= traveled
        if c.tag == "ReachPositionCondition":
            tolerance = self.num(c, "tolerance")
            target = self.position(self.child(c, "Position"))
            return lambda runner, e: (
                C.distance(runner.world, e, _point(runner.world, target), False) <= tolerance
            )
        rule = self._rule(c)
        value = self.num(c, "value")
        systems = ("entity", "road", "lane", "trajectory")
        if c.tag in ("RelativeDistanceCondition", "TimeHeadwayCondition"):
            ref = self._entity_ref(c, "entityRef")
            freespace = self.flag(c, "freespace")
            # 1.1+: coordinateSystem (default entity); 1.0's TimeHeadway: alongRoute
            along = c.get("alongRoute") is not None and self.flag(c, "alongRoute")
            system = self.choice(c, "coordinateSystem", systems, "road" if along else "entity")
            if system == "trajectory":
                raise self.error(c, "coordinateSystem='trajectory' is not supported")
            kinds = ("longitudinal", "lateral", "euclidianDistance", "cartesianDistance")
            if c.tag == "RelativeDistanceCondition":
                kind = self.choice(c, "relativeDistanceType", kinds)

                def rel(runner: Any, e: Entity) -> bool:
                    w = runner.world
                    return rule(
                        C.relative_distance(w, e, w.entities[ref], kind, freespace, system), value
                    )

                return rel
            # the standard's default is the euclidean distance (1.0: alongRoute="false")
            kind = self.choice(c, "relativeDistanceType", kinds, "euclidianDistance")
            if kind == "lateral":
                raise self.error(c, "a time headway along the lateral axis is not supported")

            def head(runner: Any, e: Entity) -> bool:
                w = runner.world
                return _defined(
                    rule, C.headway(w, e, w.entities[ref], freespace, system, kind), value
                )

            return head
        if c.tag == "TimeToCollisionCondition":
            along = c.get("alongRoute") is not None and self.flag(c, "alongRoute")
            system = self.choice(c, "coordinateSystem", systems, "road" if along else "entity")
            if system == "trajectory":
                raise self.error(c, "coordinateSystem='trajectory' is not supported")
            kinds = ("longitudinal", "lateral", "euclidianDistance", "cartesianDistance")
            kind = self.choice(c, "relativeDistanceType", kinds, "euclidianDistance")
            freespace = self.flag(c, "freespace")
            target = self.one(
                self.child(c, "TimeToCollisionConditionTarget"), ("EntityRef", "Position")
            )
            if target.tag == "Position":
                pos = self.position(target)
                return lambda runner, e: _defined(
                    rule,
                    C.time_to_point(runner.world, e, _point(runner.world, pos), freespace),
                    value,
                )
            ref = self._entity_ref(target, "entityRef")
            return lambda runner, e: _defined(
                rule,
                C.time_to_collision(
                    runner.world, e, runner.world.entities[ref], freespace, system, kind
                ),
                value,
            )
        if c.tag in ("SpeedCondition", "RelativeSpeedCondition"):
            # 1.3: the speed along one of the triggering entity's axes, else the total
            direction = c.get("direction")
            if direction is not None:
                direction = self.choice(c, "direction", ("longitudinal", "lateral", "vertical"))
            if c.tag == "SpeedCondition":
                return lambda runner, e: rule(C.speed(e, None, direction), value)
            ref = self._entity_ref(c, "entityRef")
            return lambda runner, e: rule(C.speed(e, runner.world.entities[ref], direction), value)
        # DistanceCondition: to a position, in any system but trajectory
        along = c.get("alongRoute") is not None and self.flag(c, "alongRoute")
        system = self.choice(c, "coordinateSystem", systems, "road" if along else "entity")
        if system == "trajectory":
            raise self.error(c, "coordinateSystem='trajectory' is not supported")
        kind = self.choice(
            c,
            "relativeDistanceType",
            ("longitudinal", "lateral", "euclidianDistance", "cartesianDistance"),
            "euclidianDistance",
        )
        self.choice(c, "routingAlgorithm", ("assumedRoute", "fastest", "leastIntersections",
                                            "shortest", "undefined"), "undefined")  # fmt: skip
        pos = self.position(self.child(c, "Position"))
        freespace = self.flag(c, "freespace")
        if kind in ("euclidianDistance", "cartesianDistance"):
            return lambda runner, e: rule(
                C.distance(runner.world, e, _point(runner.world, pos), freespace), value
            )
        return lambda runner, e: rule(
            C.relative_distance(
                runner.world, e, C.at_point(_point(runner.world, pos)), kind, freespace, system
            ),
            value,
        )


def _compare(rule: Callable[[Any, Any], bool], current: Any, given: str) -> bool:
    """A parameter's or variable's value against a condition's text: as numbers where
    both read as numbers, else as text (booleans as ``true``/``false``)."""
    if isinstance(current, bool):
        return rule(format_value(current), given.strip().lower())
    try:
        return rule(float(current), float(given))
    except (TypeError, ValueError):
        return rule(str(current), given)


def _typed(reader: _Reader, el: Any, attr: str, kind: str) -> ParamValue:
    """An attribute as a value of an OpenSCENARIO type."""
    if kind == "double":
        return reader.num(el, attr)
    if kind in ("int", "integer", "unsignedInt", "unsignedShort"):
        value = reader.integer(el, attr)
        if kind.startswith("unsigned") and value < 0:
            raise reader.error(el, f"{attr} of an {kind} must be >= 0, got {value}")
        return value
    if kind == "boolean":
        return reader.flag(el, attr)
    return reader.attr(el, attr)


def _collides(world: Any, e: Entity, others: Any) -> bool:
    return any(o is not e and C.boxes_overlap(e, o) for o in others)


def _point(world: Any, pos: Position) -> Any:
    """World point of a position (lane positions on their lane's centre + offset)."""
    w = pos.resolve(world)
    if w.lane is not None:
        return world.pose(w.lane, w.u, w.t)[0]
    return w.point
