"""A road from an OpenDRIVE map, with the same interface as the generated highway.

:class:`OpenDriveRoad` turns an :class:`~aldm_gym.roads.opendrive.OpenDriveMap` into
what the line sensor, the detectors, the ground truth and the environment use:

* the painted marking lines as a :class:`~aldm_gym.roads.polyline.PolylineRoad`
  (``sample_visible``, ``marking_table``, ``marking_model``): ``"per_dash"`` gives one
  line object per painted dash (a converted road, the paper's problem), ``"editor"``
  one per marking line (as CarMaker's road editor draws it);
* ground truth: :meth:`~OpenDriveRoad.lane_position` (the lane that contains a world
  position, the offset from its centre, its width and direction, the arc length along
  the lane's chain of successors) and :meth:`~OpenDriveRoad.boundary_markings` (which
  marking lines bound that lane, and the adjacent lanes, *there*);
* :meth:`~OpenDriveRoad.lane_pose`: a world pose on a lane's centre.

World frame. OpenDRIVE's inertial frame is right-handed (x east, y north, heading
counter-clockwise). highway-env's world, in which vehicles, the sensor and the
renderer work, has y pointing down the screen: the driver's left of heading ``h`` is
``(sin h, -cos h)`` (see :mod:`aldm_gym.roads.reference_line`). A map enters that world
mirrored in y: ``(x, y) -> (x, -y)`` and ``heading -> -heading``; lengths, dashes and
left/right are unchanged, so the sensor frame (ISO 8855, y left) is the same.
"""

from __future__ import annotations

import hashlib
import math
import os
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numba
import numpy as np

from aldm_gym.errors import InputError, MapError, NotDrivenError, OffRoadError
from aldm_gym.roads.cache import LRUCache
from aldm_gym.roads.markings import MarkingChain
from aldm_gym.roads.opendrive import OpenDriveMap
from aldm_gym.roads.opendrive.map import LaneKey, LaneRecord
from aldm_gym.roads.opendrive.parse import not_found
from aldm_gym.roads.polyline import MarkingCurve, PolylineMarkings, PolylineRoad
from aldm_gym.roads.position import LanePosition, Pose, world_heading, world_point
from aldm_gym.types import FloatArray

if TYPE_CHECKING:
    from aldm_gym.roads.map_network import MapNetwork

DRIVING_TYPES = frozenset(
    {"driving", "entry", "exit", "onRamp", "offRamp", "connectingRamp", "bidirectional"}
)
"""OpenDRIVE lane types a vehicle drives on (the rest: shoulders, borders, ...)."""

LOCATE_REACH = 15.0
"""A position is located on lanes whose centre passes within this distance [m]."""

MIN_POSE_WIDTH = 2.5
"""Seeded poses (:meth:`OpenDriveRoad.sample_poses`) are drawn where their lane is at
least this wide [m] (not in tapers)."""

BOUNDARY_REACH = 260.0
"""Ground-truth lines follow a lane's borders this far ahead [m] (the sensor sees 200 m)."""

_MAPS: LRUCache[OpenDriveMap] = LRUCache(4)
_MAP_ROADS: LRUCache[OpenDriveRoad] = LRUCache(4)


def _flip(xy: FloatArray) -> FloatArray:
    """OpenDRIVE's inertial frame -> highway-env's world (mirror in y)."""
    out = np.array(xy, dtype=np.float64, copy=True)
    out[:, 1] = -out[:, 1]
    return out


def _dedupe(xy: FloatArray) -> np.ndarray:
    """Mask of the vertices that are not a repetition of the previous one."""
    keep = np.ones(len(xy), dtype=bool)
    keep[1:] = np.hypot(np.diff(xy[:, 0]), np.diff(xy[:, 1])) > 1e-9
    return keep


def load_map(path: str | os.PathLike[str], **options: Any) -> OpenDriveMap:
    """:meth:`OpenDriveMap.from_file`, cached per file, content and options (a small LRU)."""
    try:
        with open(path, "rb") as fh:
            digest = hashlib.sha256(fh.read()).hexdigest()
    except FileNotFoundError:
        raise not_found(path) from None
    # the path is in the key: a map's errors and paths name the file they came from
    key = (os.path.abspath(path), digest, tuple(sorted((k, repr(v)) for k, v in options.items())))
    return _MAPS.get(key, lambda: OpenDriveMap.from_file(path, **options))


class OpenDriveRoad(PolylineRoad):
    """An OpenDRIVE map as a road of aldm-gym (see the module docstring).

    :ivar map: the parsed map (OpenDRIVE's frame).
    :ivar lanes: the driving lanes, in the order of the lane index.
    :ivar lane_width: the median width of the driving lanes [m] (the nominal width a
        detector uses for a one-line trajectory).
    """

    def __init__(self, odr: OpenDriveMap, marking_model: str = "per_dash") -> None:
        curves = []
        for m in odr.markings:
            xy = _flip(m.xy)
            keep = _dedupe(xy)
            u_theirs = np.asarray(m.u, dtype=np.float64)[keep]
            xy = xy[keep]
            if len(xy) < 2:
                continue
            u_ours = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
            # Painted intervals follow the polyline's own arc length.
            painted = np.interp(np.asarray(m.painted, dtype=np.float64), u_theirs, u_ours)
            painted = painted[painted[:, 1] > painted[:, 0]].reshape(-1, 2)
            curves.append(MarkingCurve(xy, painted, int(m.type), int(m.colour), m.width, m.height))
        # Map marking indices of the file's lines to the kept curves.
        kept = [i for i, m in enumerate(odr.markings) if _dedupe(_flip(m.xy)).sum() >= 2]
        self._marking_of = {i: k for k, i in enumerate(kept)}
        self.map = odr
        self.lanes: list[LaneKey] = [
            key for key, rec in odr.lanes.items() if rec.type in DRIVING_TYPES
        ]
        if not self.lanes:
            raise MapError(f"{odr.path}: no driving lane")
        widths = np.concatenate([odr.lanes[k].width for k in self.lanes])
        super().__init__(curves, marking_model, float(np.median(widths)))
        ends = odr.overpass_lines
        self.overpass_lines = np.column_stack(
            [_flip(ends[:, 0:2]), _flip(ends[:, 2:4]), ends[:, 4]]
        )
        self._build_lane_index()

    @classmethod
    def from_file(
        cls,
        path: str | os.PathLike[str],
        marking_model: str = "per_dash",
        **options: Any,
    ) -> OpenDriveRoad:
        """Read an OpenDRIVE file (cached per content and options).

        :param marking_model: ``"per_dash"`` or ``"editor"``.
        :param options: :meth:`OpenDriveMap.from_file
            <aldm_gym.roads.opendrive.OpenDriveMap.from_file>` options
            (``broken_pattern``, ``sample_step``).
        :raises MapNotFoundError: naming the path (a ``FileNotFoundError``).
        :raises MapError: a malformed or unusable file (naming file, road, element).
        """
        odr = load_map(path, **options)
        # The road (marking tables, lane index, traffic network) is cached with its map:
        # environments reset on the same file share one road. The key holds the map
        # itself (compared by identity), so it cannot be confused with a newer one.
        return _MAP_ROADS.get((cls, odr, marking_model), lambda: cls(odr, marking_model))

    # ------------------------------------------------------------------ lanes
    def _build_lane_index(self) -> None:
        odr = self.map
        centres, self._lane_rev = [], []
        for key in self.lanes:
            rec = odr.lanes[key]
            xy = _flip(rec.xy)
            rev = rec.direction < 0
            if rev:
                xy = xy[::-1]
            keep = _dedupe(xy)
            centres.append(MarkingCurve(xy[keep], np.zeros((0, 2))))
            self._lane_rev.append((rev, keep))
        self._centres = PolylineMarkings(centres)
        self._key_index = {key: i for i, key in enumerate(self.lanes)}
        # Lanes of one section and direction, ordered from the driver's left.
        groups: dict[tuple[str, int, int], list[LaneKey]] = {}
        for key in self.lanes:
            rec = odr.lanes[key]
            groups.setdefault((rec.road_id, rec.section, rec.direction), []).append(key)
        self._siblings: dict[LaneKey, list[LaneKey]] = {}
        for (_, _, direction), keys in groups.items():
            # Travelling along +s the driver's left is +t: higher lane ids first.
            ordered = sorted(keys, key=lambda k: -k[2] * direction)
            for k in ordered:
                self._siblings[k] = ordered
        self._chain_positions()

    def _chain_positions(self) -> None:
        """Arc length of each lane's start along its chain of successors, and the chain's end."""
        odr = self.map
        length = {
            k: float(self._centres.u[self._centres.start[i + 1] - 1])
            for i, k in enumerate(self.lanes)
        }
        succ: dict[LaneKey, LaneKey | None] = {}
        every: dict[LaneKey, tuple[LaneKey, ...]] = {}
        has_pred: set[LaneKey] = set()
        for k in self.lanes:
            nxt = [n for n in odr.successors(k[0], k[2], k[1]) if n in self._key_index]
            every[k] = tuple(nxt)
            succ[k] = self._straightest(k, nxt) if nxt else None
            has_pred.update(nxt)
        self._every_succ = every
        start: dict[LaneKey, float] = {}
        for k in [k for k in self.lanes if k not in has_pred] + list(self.lanes):
            if k in start:
                continue
            s, cur, seen = 0.0, k, set()
            while cur is not None and cur not in seen and cur not in start:
                seen.add(cur)
                start[cur] = s
                s += length[cur]
                cur = succ[cur]
        end: dict[LaneKey, float] = {}
        for k in self.lanes:
            s, cur, seen = start[k], k, set()
            total = start[k]
            while cur is not None and cur not in seen:
                seen.add(cur)
                total = s + length[cur]
                s = total
                cur = succ[cur]
            end[k] = total
        self._start, self._end, self._succ = start, end, succ

    def _end_heading(self, lane: LaneKey) -> float:
        """Heading [rad] of ``lane``'s centre line at its end (driving direction)."""
        row = self._key_index[lane]
        c = self._centres
        a, b = c.xy[c.start[row + 1] - 2], c.xy[c.start[row + 1] - 1]
        return math.atan2(float(b[1] - a[1]), float(b[0] - a[0]))

    def _straightest(self, lane: LaneKey, options: list[LaneKey]) -> LaneKey:
        """Of the lanes continuing ``lane``, the one whose end heading turns least from
        ``lane``'s own (the first of a tie): straight on where a lane splits, as esmini
        chooses at its first junction."""
        if len(options) == 1:
            return options[0]
        h = self._end_heading(lane)
        turns = [abs(math.remainder(self._end_heading(n) - h, 2.0 * math.pi)) for n in options]
        return options[int(np.argmin(turns))]

    def chain_start(self, lane: LaneKey) -> float:
        """Arc length ``s`` [m] where ``lane`` starts along its chain (``LanePosition.s``)."""
        return self._start[lane]

    def chain_end(self, lane: LaneKey) -> float:
        """Arc length ``s`` [m] where the chain of successors of ``lane`` ends."""
        return self._end[lane]

    def lane_length(self, lane: LaneKey) -> float:
        """Length of ``lane``'s centre line in its section [m]."""
        row = self._key_index[lane]
        c = self._centres
        return float(c.u[c.start[row + 1] - 1])

    def siblings(self, lane: LaneKey) -> list[LaneKey]:
        """The driving lanes of ``lane``'s section and direction, from the driver's left."""
        return list(self._siblings[lane])

    def lane_centre(self, lane: LaneKey) -> FloatArray:
        """``(N, 2)`` centre line of a driving lane, world (highway-env's frame) [m],
        in its driving direction."""
        row = self._key_index[lane]
        c = self._centres
        return c.xy[c.start[row] : c.start[row + 1]].copy()

    def lane_arc_lengths(self, lane: LaneKey) -> FloatArray:
        """``(N,)`` arc length [m] along a driving lane's centre line at the vertices of
        :meth:`lane_centre` (0 at its start, :meth:`lane_length` at its end)."""
        row = self._key_index[lane]
        c = self._centres
        return c.u[c.start[row] : c.start[row + 1]].copy()

    def lane_widths(self, lane: LaneKey) -> FloatArray:
        """``(N,)`` width of a driving lane [m] at the vertices of :meth:`lane_centre`."""
        rec = self.map.lanes[lane]
        rev, keep = self._lane_rev[self._key_index[lane]]
        width = rec.width[::-1] if rev else rec.width
        return np.asarray(width, dtype=np.float64)[keep].copy()

    def _beyond(self, lane: LaneKey) -> float:
        """How far the chain of ``lane`` reaches past the end of ``lane`` itself [m]."""
        return self._end[lane] - self._start[lane] - self.lane_length(lane)

    def road_left(self, pos: LanePosition) -> float:
        """Road ahead of a position [m]: to the end of the farthest-reaching chain of the
        lanes beside it (its own and its siblings), measured along its own lane."""
        lane = pos.lane
        rest = self.lane_length(lane) - (pos.s - self._start[lane])
        return rest + max(self._beyond(k) for k in self._siblings[lane])

    def ends_within(self, pos: LanePosition, distance: float) -> bool:
        """Whether the road ahead of ``pos`` (:meth:`road_left`: the farthest-reaching
        lane beside it; its own may end sooner and merge out) ends within ``distance`` [m]."""
        return self.road_left(pos) < distance

    def lateral_offsets(self, xy: FloatArray, pos: LanePosition) -> FloatArray:
        """Lateral position [m] (> 0 left) of world points ``xy`` ``(N, 2)`` relative to
        the centre of the lane at ``pos``: ``(its lane index - theirs) · width + their
        offset``; ``inf`` for a point on no driving lane."""
        y = np.full(len(xy), math.inf)
        for k in range(len(xy)):
            try:
                p = self.lane_position(xy[k])
            except InputError:
                continue  # off the map's lanes: in no lane
            y[k] = (pos.index - p.index) * pos.width + p.offset
        return y

    def sample_poses(
        self,
        n: int,
        rng: np.random.Generator,
        max_shift: float = 0.875,
        heading_jitter: float = 0.01,
        margin: float = 250.0,
    ) -> list[Pose]:
        """``n`` seeded poses on the driving lanes, each lane weighted by its length,
        where it is at least :data:`MIN_POSE_WIDTH` wide; shift and heading jitter as
        :meth:`HighwayRoad.sample_poses <aldm_gym.roads.HighwayRoad.sample_poses>`
        (``margin`` does not apply: lanes are drawn as they are).

        :raises MapError: too few such places (100 draws per pose).
        """
        net = self.network
        keys = list(self.lanes)
        lengths = np.array([self.lane_length(k) for k in keys])
        cum = np.cumsum(lengths)
        out: list[Pose] = []
        for _ in range(100 * n):
            if len(out) == n:
                break
            i = min(
                int(np.searchsorted(cum, rng.uniform(0.0, cum[-1]), side="right")), len(keys) - 1
            )
            key = keys[i]
            lane = net.get_lane(net.index_of[key])
            u = float(rng.uniform(0.0, lane.length))
            shift = float(rng.uniform(-max_shift, max_shift))
            h = float(lane.heading_at(u)) + float(rng.normal(0.0, heading_jitter))
            if lane.width_at(u) < MIN_POSE_WIDTH:
                continue
            p = lane.position(u, -shift)  # lane coordinates: r positive to the right
            siblings = self.siblings(key)
            out.append(
                Pose(
                    self.chain_start(key) + u,
                    key,
                    shift,
                    (float(p[0]), float(p[1]), h),
                    siblings.index(key),
                    len(siblings),
                )
            )
        if len(out) < n:
            raise MapError(f"{self.map.path}: too few places where a driving lane is wide enough")
        return out

    def lane_ends_in(self, pos: LanePosition) -> float:
        """Distance [m] to the end of the position's lane chain if it ends before the road
        (:meth:`road_left`) does, i.e. a lane to merge out of; ``inf`` otherwise."""
        lane = pos.lane
        own = self._beyond(lane)
        if own >= max(self._beyond(k) for k in self._siblings[lane]) - 1.0:
            return math.inf
        return pos.end - pos.s

    def lane_narrows_in(self, pos: LanePosition, width: float, closing: float = 0.0) -> float:
        """Distance [m] along the lane chain from ``pos`` to where its last narrowing
        begins: the first vertex narrower than ``min(width, the chain's widest − closing)``
        after the last one that is not (the taper before the chain ends). The chain's
        end where it ends wide, or where no vertex ahead is that wide (a lane too narrow
        to tell a taper in: its end is the end). A lane that opens (narrow at its start,
        as a 2+1 road's overtaking lane) is not narrowing."""
        lane: LaneKey | None = pos.lane
        c = self._centres
        done = -(pos.s - self._start[pos.lane])  # the way from pos to the lane's start
        dist: list[FloatArray] = []
        widths: list[FloatArray] = []
        for _ in range(len(self.lanes)):  # a chain visits each lane once at most
            if lane is None:
                break
            row = self._key_index[lane]
            u = c.u[c.start[row] : c.start[row + 1]]
            ahead = done + u >= 0.0
            dist.append((done + u)[ahead])
            widths.append(self.lane_widths(lane)[ahead])
            done += float(u[-1])
            lane = self.successor(lane)
        d, w = np.concatenate(dist), np.concatenate(widths)
        if not len(d):
            return 0.0
        wide = np.flatnonzero(w >= min(width, float(np.max(w)) - closing))
        last = int(wide[-1]) if len(wide) else len(d) - 1
        return float(d[last + 1]) if last + 1 < len(d) else float(d[-1])

    def lane_end_side(self, pos: LanePosition) -> int:
        """Where to leave the lane at ``pos`` before it ends: +1 by the left neighbour,
        -1 by the right one, whichever lane chain reaches farther past its own (the
        right on a tie: keep right); 0 when the lane does not end before the road or
        neither neighbour reaches farther."""
        if not math.isfinite(self.lane_ends_in(pos)):
            return 0
        siblings = self._siblings[pos.lane]
        k = siblings.index(pos.lane)
        best, side = self._beyond(pos.lane) + 1.0, 0
        for j, s in ((k + 1, -1), (k - 1, 1)):  # right first: it wins a tie
            if 0 <= j < len(siblings) and self._beyond(siblings[j]) > best:
                best, side = self._beyond(siblings[j]), s
        return side

    @cached_property
    def network(self) -> MapNetwork:
        """highway-env's lane network of the driving lanes (built on first use)."""
        from aldm_gym.roads.map_network import MapNetwork

        return MapNetwork(self)

    def successor(self, lane: LaneKey) -> LaneKey | None:
        """The driving lane continuing ``lane`` in its direction, or ``None``; where the
        lane splits, the straightest of :meth:`successors` (the one whose end heading
        turns least from ``lane``'s, the first of a tie)."""
        return self._succ.get(lane)

    def successors(self, lane: LaneKey) -> list[LaneKey]:
        """Every driving lane continuing ``lane`` in its direction (more than one where
        the lane splits in a junction), in the map's order."""
        if lane not in self._key_index:
            raise InputError(f"unknown driving lane {lane!r}")
        return list(self._every_succ[lane])

    def predecessor(self, lane: LaneKey) -> LaneKey | None:
        """A driving lane that ``lane`` continues, or ``None``: the way back for an
        entity driving against its lane (one whose :meth:`successor` ``lane`` is where
        there is one; else, on a branch that splits off, the lane it splits from)."""
        if lane not in self._key_index:
            return None
        before = self.predecessors(lane)
        return next((p for p in before if self._succ[p] == lane), before[0] if before else None)

    def predecessors(self, lane: LaneKey) -> list[LaneKey]:
        """Every driving lane that ``lane`` continues (more than one where lanes merge in
        a junction), in the map's order."""
        if lane not in self._key_index:
            raise InputError(f"unknown driving lane {lane!r}")
        every = getattr(self, "_every_pred", None)
        if every is None:
            every = {}
            for before, afters in self._every_succ.items():
                for after in afters:
                    every.setdefault(after, []).append(before)
            self._every_pred = every
        return list(every.get(lane, ()))

    def _nearest_lane(
        self, position: FloatArray, only: int = -1, heading: float | None = None
    ) -> tuple[int, int, float, float]:
        """Nearest driving-lane centre: ``(lane row, segment, offset [m] > 0 left, u [m])``.

        ``segment`` counts from the lane's first vertex (-1 when nothing is near). With
        ``heading`` [rad] (highway-env's world frame), the nearest of the lanes whose
        direction of travel there is within 90° of it, if one is near; else the nearest.
        """
        c = self._centres
        rows, lo, hi = c.near(position, LOCATE_REACH)
        if only >= 0:
            pick = rows == only
            rows, lo, hi = rows[pick], lo[pick], hi[pick]
            if len(rows) == 0:
                rows = np.array([only], dtype=np.int64)
                lo = c.start[only : only + 1].copy()
                hi = c.start[only + 1 : only + 2].copy()
        if len(rows) == 0:
            return -1, -1, math.nan, math.nan
        px, py = float(position[0]), float(position[1])
        row, i, offset, u = _nearest_centre(c.xy, c.u, rows, lo, hi, px, py)
        if heading is not None:
            hx, hy = math.cos(heading), math.sin(heading)
            found = (row, i, offset, u)
            while row >= 0:
                dx, dy = c.xy[i + 1] - c.xy[i]
                if dx * hx + dy * hy >= 0.0:
                    break
                # a lane of the other direction (the ego overtaking on a two-way road):
                # the nearest of the rest, without the stretch that was found
                keep = ~((rows == row) & (lo <= i) & (i < hi))
                rows, lo, hi = rows[keep], lo[keep], hi[keep]
                row, i, offset, u = (
                    _nearest_centre(c.xy, c.u, rows, lo, hi, px, py) if len(rows) else (-1,) * 4
                )
            if row < 0:
                row, i, offset, u = found
        return row, i - int(c.start[row]), offset, u

    def lane_position(self, position: FloatArray, heading: float | None = None) -> LanePosition:
        """Ground truth of a world position on the map (see :class:`LanePosition`).

        The lane is the driving lane whose centre line is nearest (the one containing the
        position wherever lanes do not overlap); ``s`` runs along the chain of lanes
        that continue each other (lane links across sections, roads and junctions).
        With ``heading`` [rad] (a vehicle's, highway-env's world frame) only lanes whose
        direction of travel is within 90° of it count, while one is within
        :data:`LOCATE_REACH`: a car overtaking in the oncoming lane of a two-way road
        is on its own lane's side with an offset of about a lane width (a departure),
        not on the oncoming lane, whose road ahead is the way the car came.

        :raises InputError: naming ``position`` unless it is 2 finite numbers;
            :class:`~aldm_gym.errors.OffRoadError` when no
            driving lane passes within :data:`LOCATE_REACH` of it.
        """
        p = world_point("position", position)
        row, seg, offset, u = self._nearest_lane(p, heading=world_heading("heading", heading))
        if row < 0:
            raise OffRoadError(
                f"position ({p[0]:.1f}, {p[1]:.1f}) is more than {LOCATE_REACH} m from any "
                "driving lane of the map"
            )
        key = self.lanes[row]
        a = self._centres.start[row]
        xy = self._centres.xy
        heading = math.atan2(
            xy[a + seg + 1, 1] - xy[a + seg, 1], xy[a + seg + 1, 0] - xy[a + seg, 0]
        )
        siblings = self._siblings[key]
        return LanePosition(
            s=self._start[key] + u,
            offset=offset,
            lane=key,
            index=siblings.index(key),
            lanes=len(siblings),
            width=self._width_at(row, seg),
            heading=heading,
            end=self._end[key],
        )

    def _width_at(self, row: int, seg: int) -> float:
        rec = self.map.lanes[self.lanes[row]]
        rev, keep = self._lane_rev[row]
        width = rec.width[::-1] if rev else rec.width
        return float(width[keep][seg])

    def boundary_markings(
        self, lane: LaneKey, position: FloatArray | None = None
    ) -> dict[str, int | MarkingChain | None]:
        """The true lines around ``lane`` ahead of ``position`` (``None``: no such line).

        ``ego_left``/``ego_right`` bound the lane on the driver's left/right;
        ``left_adjacent``/``right_adjacent`` are the outer lines of the driving lanes
        beside it at ``position``. Each is a marking index, or the chain of marking
        indices that bound the lane one after another over the next
        :data:`BOUNDARY_REACH` metres along the lane and its successors, with where
        each takes over (:class:`~aldm_gym.roads.markings.MarkingChain`: a border
        changes marking where, e.g., a broken line becomes solid at an exit or a lane
        opens beside it), or ``None`` where the lane does not exist or the border is
        not painted.
        """
        if lane not in self._key_index:
            raise InputError(f"unknown driving lane {lane!r}")
        siblings = self._siblings[lane]
        i = siblings.index(lane)
        p = None if position is None else world_point("position", position)
        return {
            "left_adjacent": self._border(siblings[i - 1], "left", p) if i >= 1 else None,
            "ego_left": self._border(lane, "left", p),
            "ego_right": self._border(lane, "right", p),
            "right_adjacent": (
                self._border(siblings[i + 1], "right", p) if i + 1 < len(siblings) else None
            ),
        }

    def _border_marks(self, row: int, side: str) -> np.ndarray:
        """Per centre vertex of lane ``row`` (travel order), the index of the road's
        marking on its ``side`` (-1 where unpainted); computed once per lane and side."""
        cache = self.__dict__.setdefault("_border_cache", {})
        got = cache.get((row, side))
        if got is None:
            rev, keep = self._lane_rev[row]
            marks = np.asarray(getattr(self.map.lanes[self.lanes[row]], side))
            marks = (marks[::-1] if rev else marks)[keep]
            lookup = np.full(max(len(self.map.markings), 1), -1, dtype=np.int64)
            for theirs, ours in self._marking_of.items():
                lookup[theirs] = ours
            got = np.where(marks >= 0, lookup[np.maximum(marks, 0)], -1)
            cache[(row, side)] = got
        return got

    def _border(
        self, lane: LaneKey, side: str, position: FloatArray | None
    ) -> int | MarkingChain | None:
        """The markings along one border of ``lane`` from ``position`` on (see above)."""
        row = self._key_index[lane]
        seg = 0 if position is None else max(self._nearest_lane(position, only=row)[1], 0)
        chain: list[int] = []
        starts: list[FloatArray] = []
        covered = 0.0
        key: LaneKey | None = lane
        seen: set[LaneKey] = set()
        xy = self._centres.xy
        while key is not None and key not in seen and covered < BOUNDARY_REACH:
            seen.add(key)
            row = self._key_index[key]
            a, b = self._centres.start[row], self._centres.start[row + 1]
            marks = self._border_marks(row, side)[seg:]
            at = np.flatnonzero(marks >= 0)
            if len(at):
                # consecutive repeats collapse: the markings in the order they follow,
                # each from the centre vertex where it starts to bound the lane
                marks = marks[at]
                first = np.concatenate(([True], marks[1:] != marks[:-1]))
                for k, v in zip(marks[first].tolist(), at[first].tolist(), strict=True):
                    if not chain or chain[-1] != k:
                        chain.append(k)
                        starts.append(xy[a + seg + v])
            covered += float(self._centres.u[b - 1] - self._centres.u[a + min(seg, b - a - 1)])
            key, seg = self._succ.get(key), 0
        if not chain:
            return None
        if len(chain) == 1:
            return chain[0]
        if position is not None:
            starts[0] = position
        return MarkingChain(chain, np.array(starts))

    def lane_pose(self, road_id: str, lane_id: int, s: float) -> tuple[float, float, float]:
        """World pose (highway-env's frame) on the centre of a lane at reference ``s``.

        :param road_id: the OpenDRIVE road id.
        :param lane_id: the OpenDRIVE lane id (> 0 left of the reference line).
        :param s: arc length along the road's reference line [m].
        :return: ``(x [m], y [m], heading [rad])`` facing the lane's direction of travel,
            ready for :meth:`LineSensor.measure <aldm_gym.sensor.LineSensor.measure>`.
        :raises MapError: no such road or lane at ``s``.
        """
        if not math.isfinite(float(s)):
            raise InputError(f"s must be finite, got {s!r}")
        x, y, h = self.map.lane_pose(str(road_id), int(lane_id), float(s))
        return (x, -y, -h)

    def _lane_s(self, lane: LaneKey) -> tuple[FloatArray, FloatArray]:
        """Per centre vertex of ``lane`` (travel order): its arc length ``u`` along the
        lane [m] and the reference line's ``s`` there [m]; computed once per lane."""
        cache = self.__dict__.setdefault("_lane_s_cache", {})
        got = cache.get(lane)
        if got is None:
            row = self._key_index[lane]
            rev, keep = self._lane_rev[row]
            s = np.asarray(self.map.lanes[lane].s, dtype=np.float64)
            s = (s[::-1] if rev else s)[keep]
            c = self._centres
            u = np.asarray(c.u[c.start[row] : c.start[row + 1]], dtype=np.float64)
            got = cache[lane] = (u, s)
        return got

    def reference_s(self, lane: LaneKey, u: float) -> float:
        """The reference line's ``s`` [m] where a point ``u`` [m] along ``lane``'s centre
        lies (OpenDRIVE's road coordinate; on a curve the lane centre is longer or
        shorter than the reference line). ``u`` beyond the lane is clamped to its ends."""
        lane_u, s = self._lane_s(lane)
        return float(np.interp(u, lane_u, s))

    def lane_u(self, lane: LaneKey, s: float) -> float:
        """The arc length ``u`` [m] along ``lane``'s centre where the reference line is at
        ``s`` [m] (the inverse of :meth:`reference_s`; clamped to the lane)."""
        lane_u, ref = self._lane_s(lane)
        if ref[-1] < ref[0]:  # a lane driven against the reference line
            return float(np.interp(s, ref[::-1], lane_u[::-1]))
        return float(np.interp(s, ref, lane_u))

    def lane_key(self, road_id: str, lane_id: int, s: float) -> LaneKey:
        """The driving lane of OpenDRIVE road ``road_id`` with id ``lane_id`` in the lane
        section that holds reference ``s`` [m].

        :raises MapError: no such road, or that lane is not a driving lane there.
        """
        sections = sorted(
            (rec.s0, rec.s1, key)
            for key, rec in self.map.lanes.items()
            if rec.road_id == str(road_id) and rec.lane_id == int(lane_id)
        )
        if not sections:
            raise MapError(f"{self.map.path}: road {road_id!r} has no lane {lane_id}")
        for s0, s1, key in sections:
            if s0 - 1e-9 <= s <= s1 + 1e-9:
                if key not in self._key_index:
                    raise NotDrivenError(
                        f"{self.map.path}: lane {lane_id} of road {road_id!r} at s = {s:g} m "
                        f"is of type {self.map.lanes[key].type!r}, not a driving lane"
                    )
                return key
        raise MapError(
            f"{self.map.path}: s = {s:g} m is beyond road {road_id!r} "
            f"(its lane {lane_id} spans s = {sections[0][0]:g}..{sections[-1][1]:g} m)"
        )

    def lane_record(self, lane: LaneKey) -> LaneRecord:
        """The map's record of a lane (OpenDRIVE's frame)."""
        return self.map.lanes[lane]


def _nearest_centre_py(
    xy: FloatArray,
    u: FloatArray,
    rows: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    px: float,
    py: float,
) -> tuple[int, int, float, float]:
    """Nearest point on the polylines ``rows`` (vertex ranges ``[lo, hi)``) to ``(px, py)``.

    :return: ``(polyline index, index in ``xy`` of the segment's first vertex, signed
        offset [m] (> 0 left of the direction of travel; in highway-env's world the left
        of heading h is (sin h, -cos h)), arc length along the polyline [m])``.
    """
    best_d = np.inf
    best = (-1, -1, np.nan, np.nan)
    for r in range(len(rows)):
        for i in range(lo[r], hi[r] - 1):
            ax = xy[i, 0]
            ay = xy[i, 1]
            dx = xy[i + 1, 0] - ax
            dy = xy[i + 1, 1] - ay
            ll = dx * dx + dy * dy
            t = ((px - ax) * dx + (py - ay) * dy) / ll
            t = min(max(t, 0.0), 1.0)
            qx = ax + t * dx - px
            qy = ay + t * dy - py
            d = qx * qx + qy * qy
            if d < best_d:
                best_d = d
                length = math.sqrt(ll)
                offset = ((px - ax) * dy - (py - ay) * dx) / length
                best = (rows[r], i, offset, u[i] + t * (u[i + 1] - u[i]))
    return best


_nearest_centre = numba.njit(cache=True)(_nearest_centre_py)
