"""OpenDRIVE road marks -> painted marking lines: world polylines with painted intervals.

A ``<roadMark>`` record paints one or more lines along the outer border of its lane
(the centre lane's along the lane offset) from its ``sOffset`` to the next record.
Each line becomes a :class:`MarkPiece`; pieces that continue one another (across
records, lane sections and linked roads, meeting within :data:`CHAIN_TOLERANCE` with
the same type, colour, width and height) are chained into one :class:`MarkingLine`.

Dashes are placed as esmini's RoadManager places them when it generates OSI lane
boundaries (``OpenDrive::SetRoadMarkOSIPoints``): a line's ``<line length space>``
pattern starts at the record's start plus the line's ``sOffset`` and is stepped in the
road's reference s, so a dash at lateral offset t of a reference line of curvature κ is
``length (1 − κ t)`` long on the ground. The pattern restarts at every road-mark record
and so at every lane section; a dash still being painted where its record ends is cut
there. Dashes are kept as intervals of the line's own arc length u
(:attr:`MarkingLine.painted`), converted from s along the piece's vertices.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from aldm_gym.roads.markings import MarkingType
from aldm_gym.roads.opendrive.lanes import SectionSamples
from aldm_gym.roads.opendrive.parse import RoadMark
from aldm_gym.types import FloatArray

DEFAULT_BROKEN_PATTERN = (4.0, 8.0)
"""(dash, gap) [m] of a ``broken`` mark without an explicit pattern (esmini's stand-in)."""

BOTTS_DOTS_PATTERN = (0.1, 1.1)
"""(dot, gap) [m] of ``botts dots`` without an explicit pattern: 10 cm dots every 1.2 m."""

MARK_WIDTH = {"standard": 0.15, "bold": 0.20}
"""Painted width [m] by ``weight`` when neither the line nor the mark gives one (esmini's)."""

CURB_HEIGHT = 0.15
"""Height of a ``curb`` mark without a ``height`` attribute [m]."""

COLOUR_INDEX = {
    "standard": 0,
    "white": 0,
    "yellow": 1,
    "blue": 3,
    "green": 4,
    "red": 5,
    "orange": 6,
    "violet": 7,
    "black": 8,
}
"""CarMaker colour index per OpenDRIVE colour (2 is the generated road's barrier)."""

CHAIN_TOLERANCE = 0.01
"""Marking pieces whose ends lie closer than this continue one another [m]."""

CHAIN_MAX_KINK = math.radians(20.0)
"""Largest heading change where two pieces are chained [rad]."""

_NO_PAINT = ("none", "grass", "edge", "custom")


@dataclass(frozen=True, eq=False)  # arrays: compared by identity
class MarkPiece:
    """One painted line of one road-mark record: the unit that is chained.

    :ivar road_id: the road.
    :ivar section: lane-section index.
    :ivar border: id of the lane whose outer border carries it (0: centre lane).
    :ivar record: index of the road-mark record in the lane.
    :ivar t_offset: lateral offset of the line from the border [m], left positive.
    :ivar s: (N,) reference arc lengths of the vertices [m], increasing.
    :ivar xy: (N, 2) world vertices [m].
    :ivar u: (N,) arc length along ``xy`` from 0 [m].
    :ivar type: CarMaker line type.
    :ivar colour: colour index (:data:`COLOUR_INDEX`).
    :ivar width: painted width [m].
    :ivar height: height above the road [m].
    :ivar lane_change: the record's ``laneChange`` or None.
    :ivar painted_s: (K, 2) painted intervals ``[s_start, s_end]`` in reference s [m],
        increasing, within ``[s[0], s[-1]]``: one row per dash, one for a continuous line.
    """

    road_id: str
    section: int
    border: int
    record: int
    t_offset: float
    s: FloatArray
    xy: FloatArray
    u: FloatArray
    type: MarkingType
    colour: int
    width: float
    height: float
    lane_change: str | None
    painted_s: FloatArray

    @property
    def style(self) -> tuple[int, int, float, float]:
        """What must agree for two pieces to be one marking line."""
        return (int(self.type), self.colour, round(self.width, 3), round(self.height, 3))


@dataclass(frozen=True, eq=False)  # arrays: compared by identity
class MarkingLine:
    """One painted marking line (a CarMaker line object in ``editor`` terms).

    :ivar xy: (N, 2) world polyline [m].
    :ivar u: (N,) arc length along ``xy`` from 0 [m].
    :ivar painted: (P, 2) painted intervals ``[u_start, u_end]`` [m]: one row per dash
        of a broken line, one row per continuous run.
    :ivar type: CarMaker line type (1 continuous, 2 dashed, 3 dotted).
    :ivar colour: colour index (0 white, 1 yellow, see :data:`COLOUR_INDEX`).
    :ivar width: painted width [m].
    :ivar height: height above the road [m] (> 0 for curbs).
    :ivar lane_change: ``laneChange`` of its first record or None.
    :ivar road_ids: roads it runs along, in order.
    :ivar s: (N,) reference arc length of each vertex along the road it lies on [m]
        (monotonic only within one road).
    """

    xy: FloatArray
    u: FloatArray
    painted: FloatArray
    type: MarkingType
    colour: int
    width: float
    height: float
    lane_change: str | None
    road_ids: tuple[str, ...]
    s: FloatArray


@dataclass(frozen=True)
class _LineSpec:
    t_offset: float
    width: float
    colour: int
    pattern: tuple[float, float] | None
    s_offset: float
    type: MarkingType


def _line_specs(
    mark: RoadMark, border: int, broken_pattern: tuple[float, float]
) -> list[_LineSpec]:
    """The painted lines of one record (empty: no paint)."""
    default_width = mark.width if mark.width is not None else mark.type_width
    if default_width is None:
        default_width = MARK_WIDTH.get(mark.weight or "standard", MARK_WIDTH["standard"])
    colour = COLOUR_INDEX[mark.color]
    dotted = mark.type == "botts dots"
    if mark.lines:
        specs = []
        for ln in mark.lines:
            if ln.length <= 0.0 and ln.space > 0.0:
                continue  # only gaps: nothing painted
            pattern = None if ln.space <= 0.0 else (ln.length, ln.space)
            kind = MarkingType.CONTINUOUS if pattern is None else MarkingType.DASHED
            specs.append(
                _LineSpec(
                    t_offset=ln.t_offset,
                    width=ln.width if ln.width is not None else default_width,
                    colour=COLOUR_INDEX[ln.color] if ln.color else colour,
                    pattern=pattern,
                    s_offset=ln.s_offset,
                    type=MarkingType.DOTTED if dotted and pattern else kind,
                )
            )
        return specs
    if mark.type in _NO_PAINT:
        return []
    names = ["botts"] if dotted else mark.type.split()
    # Double marks name their lines from the inside of the road outward (the centre
    # lane's from left to right); inside is towards the reference line. The two lines
    # lie at ±w from the border, as esmini's stand-in lines of ``solid solid`` and
    # ``broken broken``.
    first = -1.0 if border > 0 else 1.0
    offsets = [0.0] if len(names) == 1 else [first * default_width, -first * default_width]
    specs = []
    for name, t in zip(names, offsets, strict=True):
        if name == "broken":
            pattern, kind = broken_pattern, MarkingType.DASHED
        elif name == "botts":
            pattern, kind = BOTTS_DOTS_PATTERN, MarkingType.DOTTED
        else:  # solid, curb
            pattern, kind = None, MarkingType.CONTINUOUS
        specs.append(_LineSpec(t, default_width, colour, pattern, 0.0, kind))
    return specs


def _arc_length(xy: FloatArray) -> FloatArray:
    return np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))


_RECORD_END = 1e-9
"""A dash starting closer than this before its record's end is not painted [m]."""


def record_dashes(
    start: float, record: tuple[float, float], pattern: tuple[float, float] | None
) -> FloatArray:
    """Painted intervals of one line of one road-mark record, in reference s.

    As esmini's ``SetRoadMarkOSIPoints``: dash k spans ``[start + k p, start + k p +
    dash]`` (``p = dash + gap``) cut at the record's end, for every k whose dash starts
    before that end; a continuous line runs from ``start`` to the record's end.

    :param start: reference s where the line's pattern starts (the record's start plus
        the line's ``sOffset``) [m].
    :param record: ``(s_start, s_end)`` of the record [m]; paint before its start is
        not kept.
    :param pattern: ``(dash, gap)`` [m] (``dash > 0``, ``dash + gap > 0``), or None
        for a continuous line.
    :returns: (K, 2) intervals ``[s_start, s_end]`` [m], increasing, none empty.
    """
    lo, hi = record
    if pattern is None:
        rows = np.array([[start, hi]])
    else:
        dash, gap = pattern
        period = dash + gap
        count = max(0, math.floor((hi - _RECORD_END - start) / period) + 1)
        starts = start + period * np.arange(count)
        rows = np.stack([starts, np.minimum(starts + dash, hi)], axis=1)
    rows[:, 0] = np.maximum(rows[:, 0], lo)
    return rows[rows[:, 1] - rows[:, 0] > 1e-9]


def section_pieces(
    section: SectionSamples,
    lanes: Iterable,
    section_end: float,
    broken_pattern: tuple[float, float] = DEFAULT_BROKEN_PATTERN,
) -> list[MarkPiece]:
    """The marking pieces of one sampled lane section.

    :param lanes: the section's parsed lanes (each with ``id`` and ``road_marks``).
    :param section_end: reference s where the section ends [m].
    """
    pieces = []
    s_all = section.s
    s0 = s_all[0]
    for lane in lanes:
        records = lane.road_marks
        t_border = section.borders[lane.id]
        for r, mark in enumerate(records):
            a = s0 + mark.s_offset
            b = s0 + records[r + 1].s_offset if r + 1 < len(records) else section_end
            mask = (s_all >= a - 1e-9) & (s_all <= b + 1e-9)
            if b - a <= 1e-9 or mask.sum() < 2:
                continue
            height = mark.height if mark.height is not None else 0.0
            if mark.type == "curb" and mark.height is None:
                height = CURB_HEIGHT
            for spec in _line_specs(mark, lane.id, broken_pattern):
                t = t_border[mask] + spec.t_offset
                xy = np.stack(
                    [
                        section.x[mask] - t * np.sin(section.hdg[mask]),
                        section.y[mask] + t * np.cos(section.hdg[mask]),
                    ],
                    axis=1,
                )
                pieces.append(
                    MarkPiece(
                        road_id=section.road_id,
                        section=section.index,
                        border=lane.id,
                        record=r,
                        t_offset=spec.t_offset,
                        s=s_all[mask],
                        xy=xy,
                        u=_arc_length(xy),
                        type=spec.type,
                        colour=spec.colour,
                        width=spec.width,
                        height=height,
                        lane_change=mark.lane_change,
                        painted_s=record_dashes(a + spec.s_offset, (a, b), spec.pattern),
                    )
                )
    return pieces


def _unit(v: FloatArray) -> FloatArray:
    n = float(np.hypot(v[0], v[1]))
    return v / n if n > 0.0 else v


def _joins(
    pieces: Sequence[MarkPiece],
    road_ends: dict[str, float],
    linked: set[frozenset[str]],
) -> list[tuple[int, int]]:
    """Endpoint pairs (2 i + end, 2 j + end) that continue one another.

    Greedy: the smallest heading change first; on a tie the same lane border, then the
    nearest ends.
    """
    if len(pieces) < 2:
        return []
    points = np.array([p.xy[e] for p in pieces for e in (0, -1)])
    # Direction leaving the piece through an endpoint and entering it through the same one.
    leave, enter, s_end = [], [], []
    for p in pieces:
        t0, t1 = _unit(p.xy[1] - p.xy[0]), _unit(p.xy[-1] - p.xy[-2])
        leave += [-t0, t1]
        enter += [t0, -t1]
        s_end += [p.s[0], p.s[-1]]
    from scipy.spatial import cKDTree  # 0.15 s to import: only maps with pieces to chain

    cos_max = math.cos(CHAIN_MAX_KINK)
    candidates = []
    for i, j in cKDTree(points).query_pairs(CHAIN_TOLERANCE):
        a, b = pieces[i // 2], pieces[j // 2]
        if i // 2 == j // 2 or a.style != b.style:
            continue
        if a.road_id == b.road_id:
            if abs(s_end[i] - s_end[j]) > 1e-6:
                continue
        else:
            if frozenset((a.road_id, b.road_id)) not in linked:
                continue
            at_end = [
                min(s_end[k], road_ends[p.road_id] - s_end[k]) < 1e-6 for k, p in ((i, a), (j, b))
            ]
            if not all(at_end):
                continue
        cos = float(leave[i] @ enter[j])
        if cos < cos_max:
            continue
        dist = float(np.hypot(*(points[i] - points[j])))
        other_border = a.road_id != b.road_id or a.border != b.border
        candidates.append((round(-cos, 9), other_border, dist, i, j))
    joins: list[tuple[int, int]] = []
    used: set[int] = set()
    for *_, i, j in sorted(candidates):
        if i not in used and j not in used:
            used.update((i, j))
            joins.append((i, j))
    return joins


def _walks(n: int, joins: Sequence[tuple[int, int]]) -> list[list[tuple[int, bool]]]:
    """Order the pieces into chains: lists of (piece, reversed)."""
    partner = {}
    for i, j in joins:
        partner[i], partner[j] = j, i
    seen = [False] * n
    chains = []

    def walk(start: int, reverse: bool) -> list[tuple[int, bool]]:
        chain, piece = [], start
        while True:
            seen[piece] = True
            chain.append((piece, reverse))
            exit_end = 2 * piece + (0 if reverse else 1)
            nxt = partner.get(exit_end)
            if nxt is None or seen[nxt // 2]:
                return chain
            piece, reverse = nxt // 2, nxt % 2 == 1  # entered through its end: reversed

    for k in range(n):  # heads entered through their start
        if not seen[k] and 2 * k not in partner:
            chains.append(walk(k, False))
    for k in range(n):  # heads entered through their end
        if not seen[k] and 2 * k + 1 not in partner:
            chains.append(walk(k, True))
    for k in range(n):  # closed loops: cut before the first piece
        if not seen[k]:
            chains.append(walk(k, False))
    return chains


def _merge(intervals: Sequence[FloatArray]) -> FloatArray:
    if not intervals:
        return np.zeros((0, 2))
    rows = np.concatenate(intervals)
    if rows.size == 0:
        return np.zeros((0, 2))
    rows = rows[np.argsort(rows[:, 0], kind="stable")]
    merged = [rows[0].copy()]
    for lo, hi in rows[1:]:
        if lo <= merged[-1][1] + 1e-6:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append(np.array([lo, hi]))
    return np.array(merged)


def _build(pieces: Sequence[MarkPiece], chain: Sequence[tuple[int, bool]]) -> MarkingLine:
    xy_parts, u_parts, s_parts, painted = [], [], [], []
    u_end = 0.0
    road_ids: list[str] = []
    for n, (k, rev) in enumerate(chain):
        p = pieces[k]
        length = float(p.u[-1])
        xy = p.xy[::-1] if rev else p.xy
        u = (length - p.u[::-1]) if rev else p.u
        s = p.s[::-1] if rev else p.s
        if n:
            # the first vertex repeats the previous piece's last
            xy, u, s = xy[1:], u[1:], s[1:]
        xy_parts.append(xy)
        u_parts.append(u_end + u)
        s_parts.append(s)
        if not road_ids or road_ids[-1] != p.road_id:
            road_ids.append(p.road_id)
        # Each dash from reference s to the piece's own arc length, along its vertices.
        dashes = np.interp(p.painted_s, p.s, p.u)
        painted.append(u_end + ((length - dashes[:, ::-1]) if rev else dashes))
        u_end += length
    first = pieces[chain[0][0]]
    return MarkingLine(
        xy=np.concatenate(xy_parts),
        u=np.concatenate(u_parts),
        painted=_merge(painted),
        type=first.type,
        colour=first.colour,
        width=first.width,
        height=first.height,
        lane_change=first.lane_change,
        road_ids=tuple(road_ids),
        s=np.concatenate(s_parts),
    )


def chain_pieces(
    pieces: Sequence[MarkPiece],
    road_ends: dict[str, float],
    linked: set[frozenset[str]],
) -> tuple[list[MarkingLine], list[int]]:
    """Chain pieces into marking lines.

    :param road_ends: road id -> plan-view length [m] (pieces only chain across roads at
        road ends).
    :param linked: unordered pairs of road ids linked directly or by a junction connection.
    :returns: the marking lines and, per piece, the index of its marking line.
    """
    chains = _walks(len(pieces), _joins(pieces, road_ends, linked))
    owner = [0] * len(pieces)
    lines = []
    for index, chain in enumerate(chains):
        for k, _ in chain:
            owner[k] = index
        lines.append(_build(pieces, chain))
    return lines, owner
