"""Parse an OpenDRIVE (.xodr) file into plain frozen dataclasses.

Only what shapes the painted markings is read: the plan view, ``laneOffset``, lane
sections, lanes (widths, borders, road marks, links), road links, junction
connections, and the ``elevationProfile`` (it tells a bridge from a flat crossing,
:mod:`aldm_gym.roads.opendrive.bridges`). Everything else (signals, objects,
superelevation and the rest of the lateral profile, surface, controllers, ...) is
skipped and reported in one summary :func:`warnings.warn`.

Every error names the file; errors in a road also name the road id, the element and
its line in the file. Numbers must be finite; lengths must not be negative.
"""

from __future__ import annotations

import math
import os
import warnings
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from aldm_gym.errors import MapError, MapNotFoundError
from aldm_gym.roads.position import MAX_COORDINATE
from aldm_gym.xmlfile import ElementReader, parse_xml

GEOMETRY_KINDS = ("line", "arc", "spiral", "poly3", "paramPoly3")
"""Plan-view geometry element names this reader evaluates."""

ROAD_MARK_TYPES = (
    "none",
    "solid",
    "broken",
    "solid solid",
    "solid broken",
    "broken solid",
    "broken broken",
    "botts dots",
    "grass",
    "curb",
    "custom",
    "edge",
)
"""``roadMark/@type`` values of ASAM OpenDRIVE 1.4-1.8."""

ROAD_MARK_COLOURS = (
    "standard",
    "white",
    "yellow",
    "blue",
    "green",
    "red",
    "orange",
    "violet",
    "black",
)
"""``roadMark/@color`` values of ASAM OpenDRIVE 1.4-1.8 (``standard`` is white)."""

MAPS_DIR = Path(__file__).resolve().parents[1] / "maps"

MAX_LENGTH = 1e6
"""Largest arc length a file may give (a road's or geometry's length, an ``s`` or
``sOffset``) [m]: 1000 km, beyond any road; larger ones are refused before they size
a table."""
"""The folder of the example maps that ship inside the package."""

SHIPPED_MAPS: tuple[str, ...] = ("bridges", "features", "motorway", "two_plus_one")
"""Names of the shipped example maps (``docs/roads.md``, "Example maps")."""


def shipped_map(name: str) -> Path:
    """The absolute path of a shipped example map, from any working directory.

    :param name: one of :data:`SHIPPED_MAPS`, with or without ``.xodr``.
    :raises MapError: not a shipped map (naming the shipped ones).
    """
    stem = str(name).removesuffix(".xodr")
    if stem not in SHIPPED_MAPS:
        raise MapError(f"no shipped map {name!r}; shipped maps: {list(SHIPPED_MAPS)}")
    return MAPS_DIR / f"{stem}.xodr"


def not_found(path: str | os.PathLike[str]) -> MapNotFoundError:
    """The error for a missing OpenDRIVE file; when its file name is a shipped map's,
    the message says where that map is (a relative path from the clone's README read
    in another folder)."""
    name = os.fspath(path)
    message = f"OpenDRIVE file not found: {name!r}"
    stem = Path(name).name.removesuffix(".xodr")
    if stem in SHIPPED_MAPS:
        if not Path(name).is_absolute():
            message += f" (relative to {os.getcwd()!r})"
        message += (
            f"; the shipped map {stem!r} is {str(shipped_map(stem))!r}, also "
            f"aldm_gym.roads.shipped_map({stem!r})"
        )
    return MapNotFoundError(message)


@dataclass(frozen=True)
class Header:
    """The file's ``<header>``.

    :ivar rev_major: OpenDRIVE major revision.
    :ivar rev_minor: OpenDRIVE minor revision.
    :ivar name: database name ("" if absent).
    :ivar geo_reference: the ``<geoReference>`` PROJ string of the projection whose
        coordinates the inertial frame is ("" if absent).
    :ivar offset: the ``<offset>`` ``(x [m], y [m], z [m], hdg [rad])``: a point of the
        inertial frame is at ``R(hdg) p + (x, y, z)`` in the projection's frame
        (OpenDRIVE 1.6 §2.4, as OSI's ``proj_frame_offset``); zeros if absent.
    """

    rev_major: int
    rev_minor: int
    name: str
    geo_reference: str = ""
    offset: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Line:
    """A straight ``<line>`` geometry."""


@dataclass(frozen=True)
class Arc:
    """An ``<arc>`` of constant curvature.

    :ivar curvature: curvature [1/m], > 0 turning left.
    """

    curvature: float


@dataclass(frozen=True)
class Spiral:
    """A ``<spiral>`` (clothoid): curvature linear in s from start to end.

    :ivar curv_start: curvature at the start [1/m].
    :ivar curv_end: curvature at the end [1/m].
    """

    curv_start: float
    curv_end: float


@dataclass(frozen=True)
class Poly3:
    """A ``<poly3>``: v = a + b u + c u² + d u³ in the geometry's local (u, v) frame.

    :ivar a: [m]. :ivar b: [1]. :ivar c: [1/m]. :ivar d: [1/m²].
    """

    a: float
    b: float
    c: float
    d: float


@dataclass(frozen=True)
class ParamPoly3:
    """A ``<paramPoly3>``: u(p), v(p) cubic in the parameter p.

    :ivar u: (aU, bU, cU, dU).
    :ivar v: (aV, bV, cV, dV).
    :ivar p_range: ``"arcLength"`` (p in [0, length] [m]) or ``"normalized"`` (p in [0, 1]).
    """

    u: tuple[float, float, float, float]
    v: tuple[float, float, float, float]
    p_range: str


Shape = Line | Arc | Spiral | Poly3 | ParamPoly3


@dataclass(frozen=True)
class Geometry:
    """One ``<planView/geometry>`` record.

    :ivar s: start arc length on the reference line [m].
    :ivar x: start x (world, east) [m].
    :ivar y: start y (world, north) [m].
    :ivar hdg: start heading [rad], counter-clockwise from x.
    :ivar length: arc length [m] (>= 0).
    :ivar shape: the curve type and its parameters.
    """

    s: float
    x: float
    y: float
    hdg: float
    length: float
    shape: Shape


@dataclass(frozen=True)
class Cubic:
    """A cubic record ``a + b ds + c ds² + d ds³`` valid from ``s`` on.

    Used for ``laneOffset`` (``s`` is the road's s) and for lane ``width`` and
    ``border`` records (``s`` is the ``sOffset`` from the lane section's start).

    :ivar s: start of validity [m].
    :ivar a: [m]. :ivar b: [1]. :ivar c: [1/m]. :ivar d: [1/m²].
    """

    s: float
    a: float
    b: float
    c: float
    d: float


@dataclass(frozen=True)
class MarkLine:
    """One ``<roadMark/type/line>``: a painted line and its dash pattern.

    :ivar length: painted length of one dash [m] (0 for ``solid`` lines by convention).
    :ivar space: gap between dashes [m] (0 for a continuous line).
    :ivar t_offset: lateral offset from the lane border [m], left positive.
    :ivar s_offset: start of the pattern after the road mark's start [m].
    :ivar rule: ``"caution"``, ``"no passing"``, ``"none"`` or None.
    :ivar width: painted width [m] or None (use the road mark's).
    :ivar color: colour name or None (use the road mark's).
    """

    length: float
    space: float
    t_offset: float
    s_offset: float
    rule: str | None
    width: float | None
    color: str | None


@dataclass(frozen=True)
class RoadMark:
    """One ``<roadMark>`` record of a lane, valid from ``s_offset`` in its section.

    :ivar s_offset: start after the lane section's start [m].
    :ivar type: one of :data:`ROAD_MARK_TYPES`.
    :ivar weight: ``"standard"`` or ``"bold"`` (None if absent).
    :ivar color: colour name (``"standard"`` if absent).
    :ivar width: painted width [m] or None.
    :ivar height: height above the road [m] or None.
    :ivar lane_change: ``"increase"``, ``"decrease"``, ``"both"``, ``"none"`` or None.
    :ivar type_name: ``<type name>`` of an explicit pattern ("" without one).
    :ivar type_width: ``<type width>`` [m] or None.
    :ivar lines: the explicit pattern lines (empty: pattern from ``type``).
    """

    s_offset: float
    type: str
    weight: str | None
    color: str
    width: float | None
    height: float | None
    lane_change: str | None
    type_name: str
    type_width: float | None
    lines: tuple[MarkLine, ...]


@dataclass(frozen=True)
class Lane:
    """One ``<lane>`` of a lane section.

    :ivar id: lane id (0 centre, > 0 left of the reference line, < 0 right).
    :ivar type: lane type (``driving``, ``shoulder``, ``entry``, ``onRamp``, ...).
    :ivar level: the ``level`` attribute.
    :ivar direction: OpenDRIVE 1.8 ``direction`` (``standard``, ``reversed``, ``both``)
        or None.
    :ivar predecessors: ids of the linked lanes before this one.
    :ivar successors: ids of the linked lanes after this one.
    :ivar widths: ``<width>`` records sorted by sOffset.
    :ivar borders: ``<border>`` records sorted by sOffset (ignored when widths exist).
    :ivar road_marks: ``<roadMark>`` records sorted by sOffset.
    """

    id: int
    type: str
    level: bool
    direction: str | None
    predecessors: tuple[int, ...]
    successors: tuple[int, ...]
    widths: tuple[Cubic, ...]
    borders: tuple[Cubic, ...]
    road_marks: tuple[RoadMark, ...]


@dataclass(frozen=True)
class LaneSection:
    """One ``<laneSection>``.

    :ivar s: start on the road's reference line [m].
    :ivar single_side: the ``singleSide`` attribute.
    :ivar lanes: all lanes including the centre lane, sorted by id from left (highest)
        to right (lowest).
    """

    s: float
    single_side: bool
    lanes: tuple[Lane, ...]

    def lane(self, lane_id: int) -> Lane | None:
        """The lane with this id, or None."""
        for lane in self.lanes:
            if lane.id == lane_id:
                return lane
        return None


@dataclass(frozen=True)
class RoadLink:
    """A road's ``<predecessor>`` or ``<successor>``.

    :ivar element_type: ``"road"`` or ``"junction"``.
    :ivar element_id: id of the linked road or junction.
    :ivar contact_point: ``"start"``, ``"end"`` or None (junctions).
    """

    element_type: str
    element_id: str
    contact_point: str | None


@dataclass(frozen=True)
class Road:
    """One ``<road>``.

    :ivar id: road id (string, as in the file).
    :ivar name: road name ("" if absent).
    :ivar length: ``length`` attribute [m].
    :ivar junction: id of the junction this road belongs to ("-1" for none).
    :ivar rule: traffic rule, ``"RHT"`` (default) or ``"LHT"``.
    :ivar predecessor: link at s = 0 or None.
    :ivar successor: link at s = length or None.
    :ivar geometries: plan view records sorted by s.
    :ivar lane_offsets: ``laneOffset`` records sorted by s.
    :ivar sections: lane sections sorted by s.
    :ivar elevation: ``elevationProfile`` records sorted by s (height of the reference
        line [m] as a cubic in s); empty: the road is level at 0 m.
    """

    id: str
    name: str
    length: float
    junction: str
    rule: str
    predecessor: RoadLink | None
    successor: RoadLink | None
    geometries: tuple[Geometry, ...]
    lane_offsets: tuple[Cubic, ...]
    sections: tuple[LaneSection, ...]
    elevation: tuple[Cubic, ...] = ()


@dataclass(frozen=True)
class LaneLinkPair:
    """A junction connection's ``<laneLink>``: lane ``from_id`` of the incoming road
    continues in lane ``to_id`` of the connecting road."""

    from_id: int
    to_id: int


@dataclass(frozen=True)
class Connection:
    """One ``<junction/connection>``.

    :ivar id: connection id.
    :ivar incoming_road: road that enters the junction.
    :ivar connecting_road: road that continues it (``connectingRoad``, or ``linkedRoad``
        in a direct junction).
    :ivar contact_point: ``"start"`` or ``"end"`` of the connecting road (None: not
        given, which OpenDRIVE 1.8 allows; :class:`~aldm_gym.roads.opendrive.OpenDriveMap`
        takes it from the connecting road's link to the incoming road).
    :ivar lane_links: lane correspondences.
    """

    id: str
    incoming_road: str
    connecting_road: str
    contact_point: str | None
    lane_links: tuple[LaneLinkPair, ...]


@dataclass(frozen=True)
class Junction:
    """One ``<junction>``.

    :ivar id: junction id.
    :ivar name: junction name ("" if absent).
    :ivar type: ``default``, ``direct``, ``virtual`` or ``crossing``.
    :ivar connections: its connections.
    """

    id: str
    name: str
    type: str
    connections: tuple[Connection, ...]


@dataclass(frozen=True)
class OpenDriveFile:
    """A parsed OpenDRIVE file.

    :ivar path: the file read.
    :ivar header: its header.
    :ivar roads: roads in file order.
    :ivar junctions: junctions in file order.
    :ivar skipped: element path -> count of elements skipped (not affecting markings).
    """

    path: str
    header: Header
    roads: tuple[Road, ...]
    junctions: tuple[Junction, ...]
    skipped: tuple[tuple[str, int], ...]


# Children read by this parser, per parent element; any other child is counted as skipped.
_READ = {
    "OpenDRIVE": {"header", "road", "junction"},
    "road": {"link", "planView", "lanes", "elevationProfile"},
    "elevationProfile": {"elevation"},
    "lanes": {"laneOffset", "laneSection"},
    "laneSection": {"left", "center", "right"},
    "lane": {"link", "width", "border", "roadMark"},
    "roadMark": {"type"},
    "junction": {"connection"},
    "connection": {"laneLink"},
}


class _Reader(ElementReader):
    """Reads attributes with errors that name the file, element, line and road."""

    def __init__(self, path: str) -> None:
        super().__init__(path, MapError)
        self.road = ""
        self.skipped: Counter[str] = Counter()

    def where(self, el: etree._Element, attr: str | None = None) -> str:
        """``file:line <Tag>`` (and ``attr``), with the road being read."""
        base = super().where(el, attr)
        return f"{base} (road {self.road!r})" if self.road else base

    def text(self, el: etree._Element, name: str, default: str | None = None) -> str:
        value = el.get(name)
        if value is None:
            if default is None:
                raise self.error(el, f"missing attribute {name!r}")
            return default
        return value.strip()

    def opt_text(self, el: etree._Element, name: str) -> str | None:
        value = el.get(name)
        return None if value is None else value.strip()

    def num(self, el: etree._Element, name: str, default: float | None = None) -> float:
        raw = el.get(name)
        if raw is None:
            if default is None:
                raise self.error(el, f"missing attribute {name!r}")
            return default
        try:
            value = float(raw)
        except ValueError:
            raise self.error(el, f"attribute {name}={raw!r} is not a number") from None
        if not math.isfinite(value):
            raise self.error(el, f"attribute {name}={raw!r} is not finite")
        return value

    def opt_num(self, el: etree._Element, name: str) -> float | None:
        return None if el.get(name) is None else self.num(el, name)

    def length(self, el: etree._Element, name: str, default: float | None = None) -> float:
        value = self.num(el, name, default)
        if value < 0.0:
            raise self.error(el, f"attribute {name}={value!r} is negative")
        if value > MAX_LENGTH:
            raise self.error(el, f"attribute {name}={value!r} is more than {MAX_LENGTH:g} m")
        return value

    def coordinate(self, el: etree._Element, name: str) -> float:
        value = self.num(el, name)
        if abs(value) > MAX_COORDINATE:
            raise self.error(
                el, f"attribute {name}={value!r} is more than {MAX_COORDINATE:g} m from the origin"
            )
        return value

    def integer(self, el: etree._Element, name: str) -> int:
        raw = self.text(el, name)
        try:
            return int(float(raw)) if float(raw).is_integer() else int(raw)
        except ValueError:
            raise self.error(el, f"attribute {name}={raw!r} is not an integer") from None

    def children(self, el: etree._Element, parent: str) -> list[etree._Element]:
        """Element children; unread ones (and comments) are counted as skipped."""
        read = _READ[parent]
        out = []
        for child in el:
            if not isinstance(child.tag, str):
                continue  # comments, processing instructions
            if child.tag in read:
                out.append(child)
            elif len(child) or child.attrib or (child.text or "").strip():
                # Empty placeholders such as <lateralProfile/> carry nothing to skip.
                self.skipped[f"{parent}/{child.tag}"] += 1
        return out


def _cubic(r: _Reader, el: etree._Element, s_name: str) -> Cubic:
    return Cubic(
        s=r.length(el, s_name),
        a=r.num(el, "a"),
        b=r.num(el, "b"),
        c=r.num(el, "c"),
        d=r.num(el, "d"),
    )


def _geometry(r: _Reader, el: etree._Element) -> Geometry:
    kinds = [c for c in el if isinstance(c.tag, str)]
    if len(kinds) != 1:
        names = [c.tag for c in kinds]
        raise r.error(el, f"expected exactly one of {GEOMETRY_KINDS}, found {names}")
    k = kinds[0]
    shape: Shape
    if k.tag == "line":
        shape = Line()
    elif k.tag == "arc":
        shape = Arc(r.num(k, "curvature"))
    elif k.tag == "spiral":
        shape = Spiral(r.num(k, "curvStart"), r.num(k, "curvEnd"))
    elif k.tag == "poly3":
        shape = Poly3(r.num(k, "a"), r.num(k, "b"), r.num(k, "c"), r.num(k, "d"))
    elif k.tag == "paramPoly3":
        p_range = r.text(k, "pRange", "normalized")
        if p_range not in ("arcLength", "normalized"):
            raise r.error(k, f"pRange={p_range!r} is not 'arcLength' or 'normalized'")
        shape = ParamPoly3(
            tuple(r.num(k, n) for n in ("aU", "bU", "cU", "dU")),  # type: ignore[arg-type]
            tuple(r.num(k, n) for n in ("aV", "bV", "cV", "dV")),  # type: ignore[arg-type]
            p_range,
        )
    else:
        raise r.error(k, f"unknown geometry type (expected one of {GEOMETRY_KINDS})")
    return Geometry(
        s=r.length(el, "s"),
        x=r.coordinate(el, "x"),
        y=r.coordinate(el, "y"),
        hdg=r.num(el, "hdg"),
        length=r.length(el, "length"),
        shape=shape,
    )


def _road_mark(r: _Reader, el: etree._Element) -> RoadMark:
    kind = r.text(el, "type")
    if kind not in ROAD_MARK_TYPES:
        raise r.error(el, f"unknown roadMark type {kind!r} (expected one of {ROAD_MARK_TYPES})")
    type_name, type_width, lines = "", None, []
    for t in r.children(el, "roadMark"):  # only <type>
        type_name = r.text(t, "name", "")
        type_width = r.opt_num(t, "width")
        for ln in t:
            if not isinstance(ln.tag, str):
                continue
            if ln.tag != "line":
                r.skipped[f"roadMark/type/{ln.tag}"] += 1
                continue
            lines.append(
                MarkLine(
                    length=r.length(ln, "length"),
                    space=r.length(ln, "space"),
                    t_offset=r.num(ln, "tOffset", 0.0),
                    s_offset=r.length(ln, "sOffset", 0.0),
                    rule=r.opt_text(ln, "rule"),
                    width=r.opt_num(ln, "width"),
                    color=r.opt_text(ln, "color"),
                )
            )
    color = r.text(el, "color", "standard")
    for item, c in [(el, color)] + [(el, ln.color) for ln in lines]:
        if c is not None and c not in ROAD_MARK_COLOURS:
            raise r.error(item, f"unknown colour {c!r} (expected one of {ROAD_MARK_COLOURS})")
    if kind == "custom" and not lines:
        r.skipped["roadMark type 'custom' without <type>/<line> (no paint)"] += 1
    width = r.opt_num(el, "width")
    height = r.opt_num(el, "height")
    if width is not None and width < 0.0:
        raise r.error(el, f"attribute width={width!r} is negative")
    return RoadMark(
        s_offset=r.length(el, "sOffset"),
        type=kind,
        weight=r.opt_text(el, "weight"),
        color=color,
        width=width,
        height=height,
        lane_change=r.opt_text(el, "laneChange"),
        type_name=type_name,
        type_width=type_width,
        lines=tuple(lines),
    )


def _lane_links(r: _Reader, link: etree._Element) -> tuple[tuple[int, ...], tuple[int, ...]]:
    pred: list[int] = []
    succ: list[int] = []
    for item in link:
        if item.tag == "predecessor":
            pred.append(r.integer(item, "id"))
        elif item.tag == "successor":
            succ.append(r.integer(item, "id"))
    return tuple(pred), tuple(succ)


def _lane(r: _Reader, el: etree._Element) -> Lane:
    lane_id = r.integer(el, "id")
    widths, borders, marks = [], [], []
    pred: tuple[int, ...] = ()
    succ: tuple[int, ...] = ()
    for child in r.children(el, "lane"):
        if child.tag == "link":
            pred, succ = _lane_links(r, child)
        elif child.tag == "width":
            widths.append(_cubic(r, child, "sOffset"))
        elif child.tag == "border":
            borders.append(_cubic(r, child, "sOffset"))
        else:
            marks.append(_road_mark(r, child))
    if lane_id == 0 and (widths or borders):
        # OpenDRIVE gives the centre lane no width; files that do (esmini's own maps
        # among them) mean nothing by it, and esmini ignores it: so does the reader
        r.skipped["center/lane/width" if widths else "center/lane/border"] += 1
        widths, borders = [], []
    level = r.text(el, "level", "false").lower() in ("true", "1")
    return Lane(
        id=lane_id,
        # the centre lane has no width and carries no traffic: OpenDRIVE 1.8 files
        # (ASAM's qc-opendrive examples among them) leave its type out
        type=r.text(el, "type", "none") if lane_id == 0 else r.text(el, "type"),
        level=level,
        direction=r.opt_text(el, "direction"),
        predecessors=pred,
        successors=succ,
        widths=tuple(sorted(widths, key=lambda c: c.s)),
        borders=tuple(sorted(borders, key=lambda c: c.s)),
        road_marks=tuple(sorted(marks, key=lambda m: m.s_offset)),
    )


def _lane_section(r: _Reader, el: etree._Element) -> LaneSection:
    lanes: list[Lane] = []
    for side in r.children(el, "laneSection"):
        for child in side:
            if not isinstance(child.tag, str):
                continue
            if child.tag != "lane":
                r.skipped[f"{side.tag}/{child.tag}"] += 1
                continue
            lane = _lane(r, child)
            expected = {"left": lane.id > 0, "center": lane.id == 0, "right": lane.id < 0}
            if not expected[side.tag]:
                raise r.error(child, f"lane id {lane.id} in <{side.tag}>")
            lanes.append(lane)
    ids = [lane.id for lane in lanes]
    if len(set(ids)) != len(ids):
        raise r.error(el, f"duplicate lane ids {sorted(ids)}")
    if 0 not in ids:
        raise r.error(el, "no centre lane (id 0)")
    for side in (1, -1):
        n = sum(1 for i in ids if i * side > 0)
        if sorted(abs(i) for i in ids if i * side > 0) != list(range(1, n + 1)):
            raise r.error(el, f"lane ids {sorted(ids)} are not consecutive from the centre")
    single = r.text(el, "singleSide", "false").lower() in ("true", "1")
    if single:
        r.skipped["laneSection@singleSide (read as a full section)"] += 1
    return LaneSection(
        s=r.length(el, "s"),
        single_side=single,
        lanes=tuple(sorted(lanes, key=lambda lane: -lane.id)),
    )


def _road_link(r: _Reader, el: etree._Element) -> RoadLink:
    element_type = r.text(el, "elementType", "road")
    if element_type not in ("road", "junction"):
        raise r.error(el, f"elementType={element_type!r} is not 'road' or 'junction'")
    contact = r.opt_text(el, "contactPoint")
    if element_type == "road" and contact not in ("start", "end"):
        raise r.error(el, f"contactPoint={contact!r} is not 'start' or 'end'")
    return RoadLink(element_type, r.text(el, "elementId"), contact)


def _road(r: _Reader, el: etree._Element) -> Road:
    r.road = ""
    road_id = r.text(el, "id")
    r.road = road_id
    rule = r.text(el, "rule", "RHT")
    if rule not in ("RHT", "LHT"):
        raise r.error(el, f"rule={rule!r} is not 'RHT' or 'LHT'")
    pred = succ = None
    geometries: list[Geometry] = []
    offsets: list[Cubic] = []
    sections: list[LaneSection] = []
    elevation: list[Cubic] = []
    for child in r.children(el, "road"):
        if child.tag == "link":
            for item in child:
                if item.tag == "predecessor":
                    pred = _road_link(r, item)
                elif item.tag == "successor":
                    succ = _road_link(r, item)
                elif isinstance(item.tag, str):
                    r.skipped[f"link/{item.tag}"] += 1
        elif child.tag == "planView":
            geometries += [_geometry(r, g) for g in child if g.tag == "geometry"]
        elif child.tag == "elevationProfile":
            elevation += [_cubic(r, item, "s") for item in r.children(child, "elevationProfile")]
        elif child.tag == "lanes":
            for item in r.children(child, "lanes"):
                if item.tag == "laneOffset":
                    offsets.append(_cubic(r, item, "s"))
                else:
                    sections.append(_lane_section(r, item))
    if not geometries:
        raise r.error(el, "no <planView/geometry>")
    if not sections:
        raise r.error(el, "no <lanes/laneSection>")
    road = Road(
        id=road_id,
        name=r.text(el, "name", ""),
        length=r.length(el, "length"),
        junction=r.text(el, "junction", "-1"),
        rule=rule,
        predecessor=pred,
        successor=succ,
        geometries=tuple(sorted(geometries, key=lambda g: g.s)),
        lane_offsets=tuple(sorted(offsets, key=lambda c: c.s)),
        sections=tuple(sorted(sections, key=lambda sec: sec.s)),
        elevation=tuple(sorted(elevation, key=lambda c: c.s)),
    )
    r.road = ""
    return road


def _junction(r: _Reader, el: etree._Element) -> Junction:
    connections = []
    for c in r.children(el, "junction"):
        links = tuple(
            LaneLinkPair(r.integer(ll, "from"), r.integer(ll, "to"))
            for ll in r.children(c, "connection")
        )
        # optional since OpenDRIVE 1.8: the connecting road's own link then says it
        # (resolved by the map, which knows the roads)
        contact = r.opt_text(c, "contactPoint")
        if contact not in ("start", "end", None):
            raise r.error(c, f"contactPoint={contact!r} is not 'start' or 'end'")
        # A direct junction (OpenDRIVE 1.7) names the continuing road linkedRoad.
        name = "connectingRoad" if c.get("connectingRoad") is not None else "linkedRoad"
        if c.get(name) is None:
            raise r.error(c, "missing attribute 'connectingRoad' (or 'linkedRoad')")
        connections.append(
            Connection(
                id=r.text(c, "id"),
                incoming_road=r.text(c, "incomingRoad"),
                connecting_road=r.text(c, name),
                contact_point=contact,
                lane_links=links,
            )
        )
    return Junction(
        id=r.text(el, "id"),
        name=r.text(el, "name", ""),
        type=r.text(el, "type", "default"),
        connections=tuple(connections),
    )


def parse_file(path: str | os.PathLike[str], *, warn: bool = True) -> OpenDriveFile:
    """Parse an OpenDRIVE file.

    :param path: the ``.xodr`` file.
    :param warn: issue one :class:`UserWarning` summarising skipped elements.
    :raises FileNotFoundError: the file does not exist.
    :raises MapError: malformed XML (file and line named) or a record that cannot be
        evaluated (file, road id, element and line named).
    """
    name = os.fspath(path)
    if not Path(name).is_file():
        raise not_found(name)
    root = parse_xml(name, error=MapError).getroot()
    r = _Reader(name)
    if root.tag != "OpenDRIVE":
        raise r.error(root, "the root element is not <OpenDRIVE>")
    header = Header(1, 0, "")
    roads: list[Road] = []
    junctions: list[Junction] = []
    for child in r.children(root, "OpenDRIVE"):
        if child.tag == "header":
            geo, offset = "", (0.0, 0.0, 0.0, 0.0)
            for item in child:
                if item.tag == "geoReference":
                    geo = " ".join((item.text or "").split())
                elif item.tag == "offset":
                    offset = tuple(r.num(item, k, 0.0) for k in ("x", "y", "z", "hdg"))  # type: ignore[assignment]
                elif isinstance(item.tag, str):
                    r.skipped[f"header/{item.tag}"] += 1
            header = Header(
                rev_major=int(r.num(child, "revMajor", 1.0)),
                rev_minor=int(r.num(child, "revMinor", 0.0)),
                name=r.text(child, "name", ""),
                geo_reference=geo,
                offset=offset,
            )
        elif child.tag == "road":
            roads.append(_road(r, child))
        else:
            junctions.append(_junction(r, child))
    ids = [road.id for road in roads]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise MapError(f"{name}: duplicate road ids {dup}")
    skipped = tuple(sorted(r.skipped.items()))
    if warn and skipped:
        listing = ", ".join(f"{k} x{n}" for k, n in skipped)
        warnings.warn(
            f"{name}: skipped elements that do not affect markings: {listing}",
            UserWarning,
            stacklevel=2,
        )
    return OpenDriveFile(name, header, tuple(roads), tuple(junctions), skipped)
