"""An OpenDRIVE map as painted marking lines and lanes in the world frame.

:meth:`OpenDriveMap.from_file` parses the file, samples each road's lane sections, turns
road marks into chained :class:`~aldm_gym.roads.opendrive.marks.MarkingLine` objects
and records every lane with its centre line, driving direction and bounding markings.
Frame: OpenDRIVE's inertial x (east), y (north), heading counter-clockwise [rad].
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from aldm_gym.errors import ConfigError, MapError
from aldm_gym.roads.opendrive.bridges import (
    crossings,
    lane_metres,
    levels,
    overpass_segments,
)
from aldm_gym.roads.opendrive.lanes import (
    cubic_at,
    driving_direction,
    outer_borders,
    sample_sections,
    section_end,
    side_border_ids,
)
from aldm_gym.roads.opendrive.marks import (
    DEFAULT_BROKEN_PATTERN,
    MarkingLine,
    MarkPiece,
    chain_pieces,
    section_pieces,
)
from aldm_gym.roads.opendrive.parse import Header, Junction, Lane, Road, parse_file
from aldm_gym.roads.opendrive.plan_view import PlanView
from aldm_gym.types import FloatArray, IntArray

LaneKey = tuple[str, int, int]
"""``(road id, lane-section index, lane id)``."""

DEFAULT_SAMPLE_STEP = 0.5

MAX_SAMPLES = 4e6
"""Most border samples a map may need: the length of every road's reference line and
of its lanes, over the sample step. 4e6 is 500 km of a three-lane road at the default
step, about 1 GB. It bounds the memory a map takes before anything is allocated; a
larger map is a :class:`~aldm_gym.errors.MapError`."""
"""Sampling step along each road's reference line [m]."""


@dataclass(frozen=True, eq=False)  # arrays: compared by identity
class LaneRecord:
    """One lane of one lane section.

    :ivar road_id: the road.
    :ivar section: lane-section index in the road.
    :ivar lane_id: OpenDRIVE lane id (> 0 left of the reference line, < 0 right).
    :ivar type: lane type (``driving``, ``shoulder``, ``entry``, ``onRamp``, ...).
    :ivar direction: +1 if traffic drives along increasing s, -1 against.
    :ivar s0: reference s where the section starts [m].
    :ivar s1: reference s where the section ends [m].
    :ivar s: (N,) reference s of the vertices [m], increasing (whatever ``direction``).
    :ivar xy: (N, 2) lane-centre polyline, world [m].
    :ivar width: (N,) lane width [m].
    :ivar left: (N,) index in :attr:`OpenDriveMap.markings` of the marking line bounding
        the lane on the driver's left (in its driving direction), -1 where unpainted.
    :ivar right: (N,) the same on the driver's right.
    """

    road_id: str
    section: int
    lane_id: int
    type: str
    direction: int
    s0: float
    s1: float
    s: FloatArray
    xy: FloatArray
    width: FloatArray
    left: IntArray
    right: IntArray


def _check_options(broken_pattern: Sequence[float], sample_step: float) -> tuple[float, float]:
    pattern = tuple(float(v) for v in broken_pattern)
    if len(pattern) != 2 or not all(math.isfinite(v) and v > 0.0 for v in pattern):
        raise ConfigError(f"broken_pattern must be (dash > 0, gap > 0) [m], got {broken_pattern!r}")
    if not (math.isfinite(sample_step) and 0.0 < sample_step <= 10.0):
        raise ConfigError(f"sample_step must be in (0, 10] m, got {sample_step!r}")
    return pattern[0], pattern[1]


def _linked_roads(roads: dict[str, Road], junctions: dict[str, Junction]) -> set[frozenset[str]]:
    pairs = set()
    for road in roads.values():
        for link in (road.predecessor, road.successor):
            if link is not None and link.element_type == "road":
                pairs.add(frozenset((road.id, link.element_id)))
    for junction in junctions.values():
        for c in junction.connections:
            pairs.add(frozenset((c.incoming_road, c.connecting_road)))
    return pairs


def _resolved(path: str, junction: Junction, roads: dict[str, Road]) -> Junction:
    """``junction`` with every connection's roads checked and its ``contactPoint``
    taken, where the file leaves it out (OpenDRIVE 1.8), from the end of the
    connecting road that links to the incoming road (in a direct junction, the end of
    the linked road that links to the junction).

    :raises MapError: a connection names an unknown road, or gives no contact point
        and its connecting road has no such end, or two.
    """
    out = []
    for c in junction.connections:
        where = f"{path}, junction {junction.id!r}, connection {c.id!r}"
        for name in (c.incoming_road, c.connecting_road):
            if name not in roads:
                raise MapError(f"{where}: unknown road {name!r}")
        if c.contact_point is None:
            road = roads[c.connecting_road]
            joins = {("road", c.incoming_road), ("junction", junction.id)}
            ends = [
                end
                for end, link in (("start", road.predecessor), ("end", road.successor))
                if link is not None and (link.element_type, link.element_id) in joins
            ]
            if len(ends) != 1:
                raise MapError(
                    f"{where}: no contactPoint, and road {c.connecting_road!r} links to "
                    f"road {c.incoming_road!r} or junction {junction.id!r} at "
                    + ("both ends: say which" if ends else "neither end")
                )
            c = replace(c, contact_point=ends[0])
        out.append(c)
    return replace(junction, connections=tuple(out))


class OpenDriveMap:
    """Painted marking lines and lanes of an OpenDRIVE file.

    :ivar path: the file read.
    :ivar header: its header.
    :ivar roads: road id -> parsed road.
    :ivar junctions: junction id -> parsed junction.
    :ivar plan_views: road id -> its reference line.
    :ivar markings: marking lines, chained across records, sections and linked roads.
    :ivar lanes: lane key -> lane record.
    :ivar lengths: road id -> reference-line length [m].
    :ivar bounds: ``(x_min, y_min, x_max, y_max)`` of all lanes and markings [m].
    :ivar bridges: road id -> the crossings where that road passes over the driven
        level (:mod:`~aldm_gym.roads.opendrive.bridges`); such a road has no lanes or
        markings here, its paint is in ``overpass_lines``.
    :ivar hidden: ids of the roads passing under the driven level (not driven, not seen).
    :ivar overpass_lines: ``(B, 5)`` world segments of the bridges' paint [m].
    """

    def __init__(
        self,
        path: str,
        header: Header,
        roads: dict[str, Road],
        junctions: dict[str, Junction],
        broken_pattern: tuple[float, float],
        sample_step: float,
    ) -> None:
        self.path = path
        self.header = header
        self.roads = roads
        self.junctions = junctions
        self.broken_pattern = broken_pattern
        self.sample_step = sample_step
        # the memory a map takes grows with its roads' lane-metres: bounded before any table
        ends = {rid: max(g.s + g.length for g in r.geometries) for rid, r in roads.items()}
        metres = {rid: ends[rid] + lane_metres(r, ends[rid]) for rid, r in roads.items()}
        samples_needed = sum(metres.values()) / sample_step
        if samples_needed > MAX_SAMPLES:
            largest = max(metres, key=metres.__getitem__)
            raise MapError(
                f"{path}: its roads need {samples_needed:.3g} border samples at "
                f"{sample_step} m (road {largest!r}: {ends[largest]:.6g} m long, "
                f"{metres[largest]:.6g} border-metres), more than the {MAX_SAMPLES:g} a "
                "map may have"
            )
        self.plan_views = {
            rid: PlanView(r.geometries, f"{path}, road {rid!r}") for rid, r in roads.items()
        }
        self.lengths = {rid: pv.length for rid, pv in self.plan_views.items()}
        linked = _linked_roads(roads, junctions)
        found = crossings(roads, self.plan_views, linked)
        weights = {rid: lane_metres(road, self.lengths[rid]) for rid, road in roads.items()}
        self.bridges, self.hidden = levels(self.lengths, linked, found, weights)
        self._off_level = frozenset(self.bridges) | self.hidden
        pieces: list[MarkPiece] = []
        samples = {}
        overpass = [np.zeros((0, 5))]
        for rid, road in roads.items():
            if rid in self.hidden:
                continue
            plan = self.plan_views[rid]
            own: list[MarkPiece] = []
            for sec in sample_sections(road, plan, sample_step, path):
                end = section_end(road, sec.index, plan.length)
                own += section_pieces(sec, road.sections[sec.index].lanes, end, broken_pattern)
                if rid not in self.bridges:
                    samples[(rid, sec.index)] = sec
            if rid in self.bridges:
                overpass.append(overpass_segments(own, road, plan.length, self.bridges[rid]))
            else:
                pieces += own
        self.overpass_lines: FloatArray = np.concatenate(overpass)
        """``(B, 5)`` segments ``(x0, y0, x1, y1, z)`` [m] of the bridges' painted markings
        (OpenDRIVE's frame; ``z`` above the driven road below them)."""
        self.markings: list[MarkingLine]
        self.markings, owner = chain_pieces(pieces, self.lengths, linked)
        self.lanes = self._lane_records(samples, pieces, owner)
        points = [m.xy for m in self.markings] + [ln.xy for ln in self.lanes.values()]
        allxy = np.concatenate(points) if points else np.zeros((1, 2))
        self.bounds = (*allxy.min(axis=0).tolist(), *allxy.max(axis=0).tolist())

    @classmethod
    def from_file(
        cls,
        path: str | os.PathLike[str],
        broken_pattern: Sequence[float] = DEFAULT_BROKEN_PATTERN,
        sample_step: float = DEFAULT_SAMPLE_STEP,
    ) -> OpenDriveMap:
        """Read an OpenDRIVE file.

        :param path: the ``.xodr`` file.
        :param broken_pattern: (dash, gap) [m] of ``broken`` marks without an explicit
            ``<type><line>`` pattern.
        :param sample_step: sampling step along the reference lines [m]; record starts
            are always sampled exactly.
        :raises MapNotFoundError: the file does not exist (a ``FileNotFoundError``).
        :raises MapError: malformed XML, a record that cannot be evaluated (the error
            names file, road and element), or a bad option.
        """
        pattern = _check_options(broken_pattern, sample_step)
        parsed = parse_file(path)
        roads = {r.id: r for r in parsed.roads}
        junctions = {j.id: j for j in parsed.junctions}
        for road in roads.values():
            for link in (road.predecessor, road.successor):
                if link is None:
                    continue
                known = roads if link.element_type == "road" else junctions
                if link.element_id not in known:
                    raise MapError(
                        f"{parsed.path}, road {road.id!r}: link to unknown {link.element_type} "
                        f"{link.element_id!r}"
                    )
        junctions = {jid: _resolved(parsed.path, j, roads) for jid, j in junctions.items()}
        return cls(parsed.path, parsed.header, roads, junctions, pattern, float(sample_step))

    def _lane_records(
        self,
        samples: dict,
        pieces: Sequence[MarkPiece],
        owner: Sequence[int],
    ) -> dict[LaneKey, LaneRecord]:
        by_record: dict[tuple[str, int, int, int], list[int]] = {}
        for k, p in enumerate(pieces):
            by_record.setdefault((p.road_id, p.section, p.border, p.record), []).append(k)

        def bounding(
            rid: str, sec_index: int, border: int, s: FloatArray, nearest_low: bool
        ) -> IntArray:
            """Marking index per vertex on one border; the line nearest the lane wins."""
            sec = self.roads[rid].sections[sec_index]
            marks = sec.lane(border).road_marks  # type: ignore[union-attr]
            out = np.full(s.shape, -1, dtype=np.int64)
            if not marks:
                return out
            starts = np.array([sec.s + m.s_offset for m in marks])
            rec = np.searchsorted(starts, s + 1e-9, side="right") - 1
            for r in np.unique(rec[rec >= 0]):
                ks = by_record.get((rid, sec_index, border, int(r)), [])
                if ks:
                    pick = min if nearest_low else max
                    k = pick(ks, key=lambda i: pieces[i].t_offset)
                    out[rec == r] = owner[k]
            return out

        lanes = {}
        for (rid, k), sec in samples.items():
            road = self.roads[rid]
            for lane in road.sections[k].lanes:
                if lane.id == 0:
                    continue
                plus, minus = side_border_ids(lane.id)
                t_plus, t_minus = sec.borders[plus], sec.borders[minus]
                on_plus = bounding(rid, k, plus, sec.s, nearest_low=True)
                on_minus = bounding(rid, k, minus, sec.s, nearest_low=False)
                direction = driving_direction(road, lane)
                left, right = (on_plus, on_minus) if direction > 0 else (on_minus, on_plus)
                lanes[(rid, k, lane.id)] = LaneRecord(
                    road_id=rid,
                    section=k,
                    lane_id=lane.id,
                    type=lane.type,
                    direction=direction,
                    s0=float(sec.s[0]),
                    s1=float(sec.s[-1]),
                    s=sec.s,
                    xy=sec.world(0.5 * (t_plus + t_minus)),
                    width=t_plus - t_minus,
                    left=left,
                    right=right,
                )
        return lanes

    def _section_of(self, road: Road, lane_id: int, s: float) -> int | None:
        """Index of the section holding ``lane_id`` at ``s`` (the later one on a boundary)."""
        length = self.lengths[road.id]
        found = None
        for k, sec in enumerate(road.sections):
            if sec.s - 1e-9 <= s <= section_end(road, k, length) + 1e-9 and sec.lane(lane_id):
                found = k
        return found

    def lane_pose(self, road_id: str, lane_id: int, s: float) -> tuple[float, float, float]:
        """World pose on a lane's centre at reference arc length ``s``.

        :returns: ``(x [m], y [m], heading [rad])``, heading along the lane's direction of
            travel, in (-pi, pi].
        :raises MapError: no such road, or the lane does not exist at ``s``.
        """
        road = self.roads.get(str(road_id))
        length = self.lengths.get(str(road_id), 0.0)
        k = None
        if road is not None and lane_id != 0 and -1e-9 <= s <= length + 1e-9:
            k = self._section_of(road, lane_id, s)
        if road is None or k is None:
            raise MapError(f"{self.path}: no lane {lane_id} on road {road_id!r} at s={s} m")
        sec = road.sections[k]
        at = np.array([min(max(s, 0.0), length)])
        borders = outer_borders(road, sec, at, self.path)
        plus, minus = side_border_ids(lane_id)
        t = 0.5 * (borders[plus][0] + borders[minus][0])
        dt = 0.5 * (borders[plus][1] + borders[minus][1])
        plan = self.plan_views[road.id]
        x, y, hdg = plan.position(at)
        kappa = plan.curvature(at)
        # Tangent of the offset curve r + t n: (1 - kappa t) T + t' N.
        tangent = float(hdg[0] + np.arctan2(dt[0], 1.0 - kappa[0] * t[0]))
        if driving_direction(road, sec.lane(lane_id)) < 0:  # type: ignore[arg-type]
            tangent += math.pi
        heading = math.remainder(tangent, 2.0 * math.pi)
        if heading == -math.pi:
            heading = math.pi
        return (
            float(x[0] - t[0] * math.sin(hdg[0])),
            float(y[0] + t[0] * math.cos(hdg[0])),
            heading,
        )

    def _entry(self, road_id: str, contact: str | None, lane_ids: Sequence[int]) -> list[LaneKey]:
        road = self.roads[road_id]
        k = 0 if contact == "start" else len(road.sections) - 1
        return [(road_id, k, j) for j in lane_ids if road.sections[k].lane(j) is not None]

    def successors(self, road_id: str, lane_id: int, section: int) -> list[LaneKey]:
        """Lanes that continue a lane in its driving direction.

        Follows lane links to the next lane section, across road links (``contactPoint``
        decides the linked road's first or last section) and through junction
        connections (``laneLink from -> to``). Only explicit links are followed, and
        only onto the driven level: a lane leading onto a bridge or a hidden road ends.

        :returns: lane keys ``(road id, section index, lane id)``; empty at a dead end.
        :raises MapError: no such lane.
        """
        road = self.roads.get(str(road_id))
        lane = None
        if road is not None and 0 <= section < len(road.sections):
            lane = road.sections[section].lane(lane_id)
        if road is None or lane is None or lane_id == 0:
            raise MapError(
                f"{self.path}: no lane {lane_id} in section {section} of road {road_id!r}"
            )
        keys = self._successors(road, lane, section)
        return [key for key in keys if key[0] not in self._off_level]

    def _successors(self, road: Road, lane: Lane, section: int) -> list[LaneKey]:
        lane_id = lane.id
        forward = driving_direction(road, lane) > 0
        links = lane.successors if forward else lane.predecessors
        nxt = section + 1 if forward else section - 1
        if 0 <= nxt < len(road.sections):
            return [(road.id, nxt, j) for j in links if road.sections[nxt].lane(j) is not None]
        link = road.successor if forward else road.predecessor
        if link is None:
            return []
        if link.element_type == "road":
            return self._entry(link.element_id, link.contact_point, links)
        out: list[LaneKey] = []
        for c in self.junctions[link.element_id].connections:
            if c.incoming_road == road.id:
                to = [ll.to_id for ll in c.lane_links if ll.from_id == lane_id]
                out += self._entry(c.connecting_road, c.contact_point, to)
        return out

    def lane_offset(self, road_id: str, s: FloatArray) -> FloatArray:
        """The road's ``laneOffset`` at ``s`` [m] (the centre lane's t)."""
        return cubic_at(self.roads[road_id].lane_offsets, np.asarray(s, dtype=np.float64))[0]
