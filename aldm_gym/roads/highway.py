"""Seeded multi-lane highways on highway-env's ``RoadNetwork`` with painted markings.

A :class:`HighwayRoad` couples three things built from one curvature profile:

* a highway-env :class:`~highway_env.road.road.RoadNetwork` (one edge ``("a", "b")``
  holding ``lanes_count`` :class:`~aldm_gym.roads.lane.ReferenceLane` objects, lane 0
  leftmost, as in highway-env), used by vehicles, traffic and rendering;
* the painted markings (:class:`~aldm_gym.roads.markings.Marking`), left edge line,
  dashed lane lines, right edge line, optional guard rails, left to right;
* ground truth: which markings bound a lane, where a marking is at a given arc
  length, and where every marking lies in a sensor's frame.

Marking indices: marking ``j`` lies left of lane ``j`` and right of lane ``j - 1``,
so lane ``i`` is bounded by markings ``i`` (left) and ``i + 1`` (right). Guard
rails, when enabled, come after the painted markings in the list.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numba
import numpy as np
from highway_env.road.lane import LineType
from highway_env.road.road import RoadNetwork

from aldm_gym.config import build_config, check_choice, check_range, setting, validate
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.roads.lane import ReferenceLane
from aldm_gym.roads.markings import MARKING_MODELS, Marking, MarkingRole, MarkingType
from aldm_gym.roads.overpass import overpass_lines
from aldm_gym.roads.position import LanePosition, Pose, world_heading, world_point
from aldm_gym.roads.reference_line import ReferenceLine, Segment
from aldm_gym.types import FloatArray

MIN_RADIUS_BY_SPEED = {130: 800.0, 120: 600.0, 110: 500.0, 100: 400.0}
"""RVS 03.03.23 minimum curve radius [m] by design speed [km/h] (paper, Table II). The
paper's LKA assumes curves of at least the 110 km/h value, 500 m: the default
``min_radius`` of generated roads."""

MAX_HEADING = np.deg2rad(75.0)
"""Largest heading of a generated road relative to its start [rad]: it never turns back."""

EDGE = ("a", "b")
"""The highway-env edge (from, to) that holds every lane."""


@dataclass(frozen=True)
class RoadConfig:
    """Settings of the highway generator (all lengths in [m]).

    :ivar lanes_count: number of lanes, 1–6.
    :ivar lane_width: lane width [m].
    :ivar length: road length along the reference line [m].
    :ivar curved: whether to draw curves; ``False`` gives a straight road.
    :ivar min_radius: smallest curve radius [m]; 500 m is the paper's LKA assumption
        (RVS 03.03.23: 400–800 m by design speed), down to 100 m allowed.
    :ivar max_radius: largest curve radius [m].
    :ivar straight_length: (min, max) length of straights between curves [m].
    :ivar arc_length: (min, max) length of constant-radius arcs [m].
    :ivar transition_length: (min, max) length of clothoid transitions [m].
    :ivar segments: explicit curvature profile ``((length, kappa_start, kappa_end), ...)``
        [m, 1/m, 1/m] (kappa > 0 left curve); overrides the random generator.
    :ivar dash_length: dash length of lane lines [m] (6 m in AT/DE, 3 m in the US).
    :ivar gap_length: gap between dashes [m] (12 m in AT/DE, 9 m in the US).
    :ivar dash_phase: arc length along each lane line where its first dash starts [m].
    :ivar lane_line_type: CarMaker type of lane lines (2 dashed, 3 dotted, 1 continuous).
    :ivar lane_line_width: painted width of lane lines [m].
    :ivar edge_line_width: painted width of the edge lines [m].
    :ivar guard_rail: add a guard rail outside each edge line.
    :ivar guard_rail_offset: lateral distance of a guard rail outside its edge line [m].
    :ivar guard_rail_height: guard-rail height [m] (> 0).
    :ivar speed_limit: speed limit of every lane [m/s].
    :ivar seed: seed of the curvature profile (``None``: a fresh random one; the env
        draws it from its own generator at each reset, so seeded episodes repeat).
    :ivar overpasses: reference arc lengths where a bridge crosses above the road [m]
        (``None``: none); the sensor reports the bridge's markings at ``z > 0``
        (:mod:`aldm_gym.roads.overpass`).
    :ivar overpass_angle: angle between a bridge's road and this one [rad].
    :ivar overpass_height: height of a bridge's markings above the road [m].
    :ivar marking_model: how markings become line objects for the sensor:
        ``"per_dash"`` (every dash is its own object, as on roads converted from
        OpenDRIVE or measurements) or ``"editor"`` (a dashed line is one object, as
        drawn in CarMaker's road editor). The painted geometry is the same.
    """

    lanes_count: int = setting(4, lo=1, hi=6, integer=True)
    lane_width: float = setting(3.75, lo=2.5, hi=5.0)
    length: float = setting(6000.0, lo=200.0, hi=100_000.0)
    curved: bool = setting(True)
    min_radius: float = setting(MIN_RADIUS_BY_SPEED[110], lo=100.0, hi=1e6)
    max_radius: float = setting(3000.0, lo="min_radius", hi=1e6)
    straight_length: tuple[float, float] = setting((150.0, 600.0), kind="pair", lo=1.0, hi=1e5)
    arc_length: tuple[float, float] = setting((150.0, 600.0), kind="pair", lo=1.0, hi=1e5)
    transition_length: tuple[float, float] = setting((60.0, 150.0), kind="pair", lo=1.0, hi=1e5)
    segments: tuple[tuple[float, float, float], ...] | None = setting(None, kind="any")
    dash_length: float = setting(6.0, lo=0.0, lo_open=True, hi=1000.0)
    gap_length: float = setting(12.0, lo=0.0, lo_open=True, hi=1000.0)
    dash_phase: float = setting(0.0, lo=-1e5, hi=1e5)
    lane_line_type: int = setting(2, choices=(1, 2, 3))
    lane_line_width: float = setting(0.15, lo=0.0, lo_open=True, hi=1.0)
    edge_line_width: float = setting(0.30, lo=0.0, lo_open=True, hi=1.0)
    guard_rail: bool = setting(False)
    guard_rail_offset: float = setting(1.0, lo=0.0, hi=10.0)
    guard_rail_height: float = setting(0.75, lo=0.0, lo_open=True, hi=3.0)
    speed_limit: float = setting(36.0, lo=0.0, lo_open=True, hi=100.0)
    seed: int | None = setting(0, lo=0, hi=2**63 - 1, integer=True, optional=True)
    marking_model: str = setting("per_dash", choices=MARKING_MODELS)
    overpasses: tuple[float, ...] | None = setting(None, kind="numbers", lo=0.0, optional=True)
    overpass_angle: float = setting(math.radians(45.0), lo=math.radians(10.0), hi=math.pi / 2)
    overpass_height: float = setting(6.0, lo=0.5, hi=50.0)

    def __post_init__(self) -> None:
        validate(self, "road")
        if self.overpasses is not None:  # hashable: roads are cached by their config
            object.__setattr__(self, "overpasses", tuple(self.overpasses))
        if self.segments is not None:
            object.__setattr__(self, "segments", _segments(self.segments))


def _segments(value: Any) -> tuple[tuple[float, float, float], ...]:
    """``road.segments`` checked and normalised to a tuple of float triples."""
    if isinstance(value, str | bytes) or not hasattr(value, "__len__"):
        raise ConfigError(
            f"road.segments must be a sequence of (length, kappa_start, kappa_end), got {value!r}"
        )
    if len(value) == 0:
        raise ConfigError("road.segments must not be empty")
    out = []
    for k, seg in enumerate(value):
        if isinstance(seg, str | bytes) or not hasattr(seg, "__len__") or len(seg) != 3:
            raise ConfigError(f"road.segments[{k}] must be (length, kappa_start, kappa_end)")
        check_range("road", f"segments[{k}].length", seg[0], 0.0, 1e5, lo_open=True)
        for kk in seg[1:]:
            check_range("road", f"segments[{k}].kappa", kk, -1.0 / 100.0, 1.0 / 100.0)
        out.append((float(seg[0]), float(seg[1]), float(seg[2])))
    return tuple(out)


def curvature_profile(config: RoadConfig) -> list[Segment]:
    """The road's curvature profile: explicit ``segments`` or a seeded random sequence.

    The random sequence alternates straights and curves; each curve is a clothoid
    transition into a constant-radius arc (left or right, radius log-uniform in
    ``[min_radius, max_radius]``) and a transition back to straight.
    """
    if config.segments is not None:
        return [Segment(float(a), float(b), float(c)) for a, b, c in config.segments]
    if not config.curved:
        return [Segment(config.length)]
    rng = np.random.default_rng(config.seed)
    segs: list[Segment] = []
    total = 0.0
    heading = 0.0  # accumulated heading change [rad]

    def add(seg: Segment) -> None:
        nonlocal total, heading
        segs.append(seg)
        total += seg.length
        heading += 0.5 * (seg.kappa_start + seg.kappa_stop) * seg.length

    add(Segment(float(rng.uniform(*config.straight_length))))
    while total < config.length:
        radius = float(np.exp(rng.uniform(np.log(config.min_radius), np.log(config.max_radius))))
        sign = float(rng.choice([-1.0, 1.0]))
        l_in = float(rng.uniform(*config.transition_length))
        l_arc = float(rng.uniform(*config.arc_length))
        l_out = float(rng.uniform(*config.transition_length))
        # Keep the road advancing: the accumulated heading stays within
        # +-MAX_HEADING, so the road never turns back onto itself.
        if abs(heading + sign * (l_arc + 0.5 * (l_in + l_out)) / radius) > MAX_HEADING:
            sign = -sign
        turn = (l_arc + 0.5 * (l_in + l_out)) / radius
        room = MAX_HEADING - sign * heading
        if turn > room:
            l_arc = max(room * radius - 0.5 * (l_in + l_out), 1.0)
            if (l_arc + 0.5 * (l_in + l_out)) / radius > room:
                add(Segment(float(rng.uniform(*config.straight_length))))
                continue
        kappa = sign / radius
        add(Segment(l_in, 0.0, kappa))
        add(Segment(l_arc, kappa, kappa))
        add(Segment(l_out, kappa, 0.0))
        add(Segment(float(rng.uniform(*config.straight_length))))
    # Trim the last straight so the road has the requested length.
    excess = total - config.length
    last = segs[-1]
    if excess > 0 and last.kappa_start == 0 and last.kappa_stop == 0 and last.length > excess + 1:
        segs[-1] = Segment(last.length - excess)
    return segs


class HighwayRoad:
    """A generated highway: highway-env network, painted markings and ground truth.

    :param config: a :class:`RoadConfig`, a mapping of its fields, or ``None`` for defaults.
    """

    def __init__(self, config: RoadConfig | Mapping[str, Any] | None = None) -> None:
        self.config: RoadConfig = build_config(RoadConfig, config, where="road")
        cfg = self.config
        n, w = cfg.lanes_count, cfg.lane_width
        half = 0.5 * n * w
        outer = half + (cfg.guard_rail_offset if cfg.guard_rail else 0.0) + 5.0
        self.reference = ReferenceLine(curvature_profile(cfg), max_offset=outer + 30.0)
        self.length = self.reference.length
        self.lanes_count = n
        self.lane_width = w
        self.markings: tuple[Marking, ...] = self._make_markings()
        self._offsets = np.array([m.offset for m in self.markings])
        # Arc length along every marking at each reference sample: du = (1 - kappa d) ds.
        ref = self.reference
        stretch = 1.0 - ref.kappa[None, :] * self._offsets[:, None]
        du = 0.5 * (stretch[:, 1:] + stretch[:, :-1]) * np.diff(ref.s)[None, :]
        self._u = np.concatenate([np.zeros((len(self.markings), 1)), np.cumsum(du, axis=1)], axis=1)
        self.network = HighwayNetwork(self)
        for i in range(n):
            left = LineType.CONTINUOUS_LINE if i == 0 else LineType.STRIPED
            right = LineType.CONTINUOUS_LINE if i == n - 1 else LineType.NONE
            lane = ReferenceLane(ref, self.lane_offset(i), w, (left, right), cfg.speed_limit)
            self.network.add_lane(*EDGE, lane)

    # ------------------------------------------------------------ construction
    def _make_markings(self) -> tuple[Marking, ...]:
        cfg = self.config
        n, w = cfg.lanes_count, cfg.lane_width
        out: list[Marking] = []
        for j in range(n + 1):
            offset = (0.5 * n - j) * w
            if j in (0, n):
                role = MarkingRole.EDGE_LEFT if j == 0 else MarkingRole.EDGE_RIGHT
                out.append(Marking(j, offset, MarkingType.CONTINUOUS, role, 0, cfg.edge_line_width))
            else:
                out.append(
                    Marking(
                        j,
                        offset,
                        MarkingType(cfg.lane_line_type),
                        MarkingRole.LANE_LINE,
                        0,
                        cfg.lane_line_width,
                        0.0,
                        cfg.dash_length,
                        cfg.gap_length,
                        cfg.dash_phase,
                    )
                )
        if cfg.guard_rail:
            for side in (1.0, -1.0):
                off = side * (0.5 * n * w + cfg.guard_rail_offset)
                out.append(
                    Marking(
                        len(out),
                        off,
                        MarkingType.CONTINUOUS,
                        MarkingRole.GUARD_RAIL,
                        2,
                        0.1,
                        cfg.guard_rail_height,
                    )
                )
        return tuple(out)

    # ------------------------------------------------------------ ground truth
    @cached_property
    def marking_table(self) -> dict[str, np.ndarray]:
        """Marking attributes as arrays indexed by marking (for vectorised sensors).

        Keys: ``type``, ``colour`` (int64); ``height``, ``width``, ``dash``, ``period``,
        ``phase`` (float64, [m]); ``broken`` (bool); ``paint`` ``(0, 2)`` and
        ``paint_start`` (zeros): no explicit painted intervals, every marking's paint
        is its periodic pattern (see :mod:`aldm_gym.roads.polyline` for maps).
        """
        mk = self.markings
        return {
            "paint": np.zeros((0, 2)),
            "paint_start": np.zeros(len(mk) + 1, dtype=np.int64),
            "type": np.array([int(m.type) for m in mk], dtype=np.int64),
            "colour": np.array([m.colour for m in mk], dtype=np.int64),
            "height": np.array([m.height for m in mk], dtype=np.float64),
            "width": np.array([m.width for m in mk], dtype=np.float64),
            "dash": np.array([m.dash_length for m in mk], dtype=np.float64),
            "period": np.array([m.period for m in mk], dtype=np.float64),
            "phase": np.array([m.phase for m in mk], dtype=np.float64),
            "broken": np.array([m.broken for m in mk], dtype=bool),
        }

    @cached_property
    def overpass_lines(self) -> FloatArray:
        """``(B, 5)`` world segments ``(x0, y0, x1, y1, z)`` [m] of the markings of the
        bridges in ``config.overpasses`` (empty without bridges)."""
        cfg = self.config
        rows = []
        for s in cfg.overpasses or ():
            if s > self.length:
                raise ConfigError(f"road.overpasses: {s} is beyond the road ({self.length:.0f} m)")
            left = self.marking_position(0, s)
            right = self.marking_position(len(self.markings) - 1, s)
            half = 0.5 * float(np.hypot(*(np.asarray(left) - np.asarray(right))))
            centre = 0.5 * (np.asarray(left) + np.asarray(right))
            heading = float(self.reference.heading_at(s))
            rows.append(
                overpass_lines(centre, heading, half, cfg.overpass_angle, cfg.overpass_height)
            )
        return np.concatenate(rows) if rows else np.zeros((0, 5))

    @property
    def marking_model(self) -> str:
        """``"per_dash"`` or ``"editor"`` (see :class:`RoadConfig`)."""
        return self.config.marking_model

    def with_marking_model(self, marking_model: str) -> HighwayRoad:
        """The same road geometry with another marking model (shares the tables)."""
        check_choice("road", "marking_model", marking_model, MARKING_MODELS)
        twin = copy.copy(self)
        twin.config = dataclasses.replace(self.config, marking_model=marking_model)
        return twin

    def lane_offset(self, lane_id: int) -> float:
        """Left offset of lane ``lane_id``'s centre from the reference line [m]."""
        self._check_lane(lane_id)
        return (0.5 * self.lanes_count - lane_id - 0.5) * self.lane_width

    def lane_of_offset(self, d: float) -> int:
        """Lane whose centre is nearest to left offset ``d`` [m] (lower id at a boundary)."""
        i = math.ceil(0.5 * self.lanes_count - d / self.lane_width) - 1
        return min(max(i, 0), self.lanes_count - 1)

    def locate(self, position: FloatArray) -> tuple[float, float, int]:
        """Ground truth of a world position: ``(s [m], left offset d [m], lane id)``.

        :raises ValueError: naming ``position`` unless it is 2 finite numbers [m].
        """
        world_point("position", position)
        s, d = self.reference.project(position)
        return s, d, self.lane_of_offset(d)

    def lane_position(self, position: FloatArray, heading: float | None = None) -> LanePosition:
        """Ground truth of a world position as a :class:`~aldm_gym.roads.position.LanePosition`.

        The lane is the one whose centre is nearest (clipped to the road's lanes), the
        offset is from its centre, the direction of travel is the reference line's.
        ``heading`` [rad] changes nothing: every lane runs the reference line's way
        (see :meth:`OpenDriveRoad.lane_position
        <aldm_gym.roads.OpenDriveRoad.lane_position>`).

        :raises ValueError: naming ``position`` unless it is 2 finite numbers [m].
        """
        world_heading("heading", heading)
        s, d, lane_id = self.locate(position)
        s = float(s)
        return LanePosition(
            s=s,
            offset=float(d - self.lane_offset(lane_id)),
            lane=lane_id,
            index=lane_id,
            lanes=self.lanes_count,
            width=self.lane_width,
            heading=float(self.reference.heading_at(s)),
            end=self.length,
        )

    def lane_id_at(self, position: FloatArray) -> int:
        """Ground-truth lane id at a world position (clipped to the road's lanes)."""
        return self.locate(position)[2]

    def lane(self, lane_id: int) -> ReferenceLane:
        """The highway-env lane object of lane ``lane_id`` (0 = leftmost)."""
        self._check_lane(lane_id)
        return self.network.graph[EDGE[0]][EDGE[1]][lane_id]

    def lane_index(self, lane_id: int) -> tuple[str, str, int]:
        """highway-env lane index ``(from, to, id)`` of lane ``lane_id``."""
        self._check_lane(lane_id)
        return (EDGE[0], EDGE[1], lane_id)

    def lane_boundaries(self, lane_id: int) -> tuple[Marking, Marking]:
        """The (left, right) markings bounding lane ``lane_id``."""
        self._check_lane(lane_id)
        return self.markings[lane_id], self.markings[lane_id + 1]

    def _check_hint(self, origin: FloatArray, s_origin: float) -> None:
        """Reject an ``s_origin`` hint that does not belong to ``origin`` (never silent)."""
        if not math.isfinite(s_origin):
            raise InputError(f"s_origin (s_hint) must be finite, got {s_origin!r}")
        ref = self.reference
        k = min(max(int(s_origin / ref.step + 0.5), 0), len(ref.s) - 1)
        h = float(ref.heading[k])
        dx = origin[0] - float(ref.xy[k, 0])
        dy = origin[1] - float(ref.xy[k, 1])
        # The sensor may be anywhere sideways (off the road too), but along the road it
        # must lie near the hinted arc length: within the sampling step, 20 m of slack,
        # and the distance beyond either road end.
        along = abs(dx * math.cos(h) + dy * math.sin(h))
        allowed = 20.0 + ref.step + max(0.0, -s_origin, s_origin - self.length)
        if along > allowed:
            raise InputError(
                f"s_hint {s_origin:.1f} m is {along:.1f} m along the road from the sensor's "
                f"position ({origin[0]:.1f}, {origin[1]:.1f}); it must be the sensor's arc "
                "length along the road (or None)"
            )

    def boundary_markings(
        self, lane_id: int, position: FloatArray | None = None
    ) -> dict[str, int | None]:
        """Marking index of the four lines around lane ``lane_id`` (``None``: no such line).

        Keys ``left_adjacent``, ``ego_left``, ``ego_right``, ``right_adjacent``. The
        outer lines are the adjacent lanes' outer markings only where those lanes exist.
        ``position`` is not needed here (markings do not change along this road).
        """
        self._check_lane(lane_id)
        n = self.lanes_count
        return {
            "left_adjacent": lane_id - 1 if lane_id >= 1 else None,
            "ego_left": lane_id,
            "ego_right": lane_id + 1,
            "right_adjacent": lane_id + 2 if lane_id + 2 <= n else None,
        }

    def _check_lane(self, lane_id: int) -> None:
        ok = isinstance(lane_id, int | np.integer) and not isinstance(lane_id, bool)
        if not ok or not 0 <= int(lane_id) < self.lanes_count:
            raise InputError(
                f"lane_id must be an integer in [0, {self.lanes_count - 1}], got {lane_id!r}"
            )

    def _check_marking(self, j: int) -> None:
        if not 0 <= int(j) < len(self.markings):
            raise InputError(f"marking index must be in [0, {len(self.markings) - 1}], got {j}")

    def marking_position(self, j: int, s: FloatArray | float) -> FloatArray:
        """World position of marking ``j`` at reference arc length ``s`` [m], shape ``(..., 2)``."""
        self._check_marking(j)
        _check_finite("s", s)
        return self.reference.position(s, self.markings[j].offset)

    def marking_arc_length(self, j: int, s: FloatArray | float) -> FloatArray:
        """Arc length along marking ``j`` [m] at reference arc length ``s`` [m]."""
        self._check_marking(j)
        _check_finite("s", s)
        return np.interp(s, self.reference.s, self._u[j])

    def curvature_at(self, s: FloatArray | float) -> FloatArray:
        """Reference-line curvature at ``s`` [1/m], positive = left curve."""
        _check_finite("s", s)
        return self.reference.curvature_at(s)

    def lateral_offsets(self, xy: FloatArray, pos: LanePosition) -> FloatArray:
        """Lateral position [m] (> 0 left) of world points ``xy`` ``(N, 2)`` relative to
        the centre of lane ``pos.lane``, along the reference line (one compiled batch
        projection)."""
        _, d = self.reference.project_many(xy)
        return d - self.lane_offset(pos.lane)

    def ends_within(self, pos: LanePosition, distance: float) -> bool:
        """Whether the road ends within ``distance`` [m] ahead of ``pos``."""
        return pos.s > pos.end - distance

    def lane_ends_in(self, pos: LanePosition) -> None:
        """``None``: the lanes of a generated highway run to the road's end."""
        return None

    def lane_narrows_in(self, pos: LanePosition, width: float, closing: float = 0.0) -> float:
        """``inf``: the lanes of a generated highway keep their width."""
        return math.inf

    def lane_end_side(self, pos: LanePosition) -> int:
        """0: the lanes of a generated highway run to the road's end."""
        return 0

    def sample_poses(
        self,
        n: int,
        rng: np.random.Generator,
        max_shift: float = 0.875,
        heading_jitter: float = 0.01,
        margin: float = 250.0,
    ) -> list[Pose]:
        """``n`` seeded poses: arc length uniform in ``[margin, length - margin]``, a
        random lane, a lateral shift uniform in ``±max_shift`` [m], the heading with a
        normal jitter of ``heading_jitter`` [rad].

        :raises InputError: the road is not longer than ``2 margin``.
        """
        if self.length <= 2 * margin:
            raise InputError(f"road too short ({self.length:.0f} m) for a {margin} m margin")
        out = []
        for _ in range(n):
            s = float(rng.uniform(margin, self.length - margin))
            lane = int(rng.integers(self.lanes_count))
            shift = float(rng.uniform(-max_shift, max_shift))
            p = self.reference.position(s, self.lane_offset(lane) + shift)
            h = float(self.reference.heading_at(s)) + float(rng.normal(0.0, heading_jitter))
            out.append(Pose(s, lane, shift, (float(p[0]), float(p[1]), h), lane, self.lanes_count))
        return out

    def sample_visible(
        self,
        origin: FloatArray,
        yaw: float,
        xs: FloatArray,
        s_origin: float | None = None,
    ) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """:meth:`sample_markings` for the sensor: ``(rows, y, u)`` with rows = every marking.

        The road protocol of :class:`~aldm_gym.sensor.LineSensor`: maps return only
        the markings near the sensor; this road has few markings and returns them all.
        """
        y, u = self.sample_markings(origin, yaw, xs, s_origin)
        return self._all_rows, y, u

    @cached_property
    def _all_rows(self) -> np.ndarray:
        return np.arange(len(self.markings), dtype=np.int64)

    def sample_markings(
        self,
        origin: FloatArray,
        yaw: float,
        xs: FloatArray,
        s_origin: float | None = None,
        margin: float = 20.0,
    ) -> tuple[FloatArray, FloatArray]:
        """Where every marking crosses the lines ``x = xs`` of a planar sensor frame.

        The frame has its origin at world ``origin`` and its x axis along world
        heading ``yaw``; y is to the left (ISO 8855). Each marking is followed in
        the direction the frame looks, from ``margin`` metres behind the origin,
        up to the first point where it stops advancing in x (a marking is never
        reported twice at one x).

        :param origin: world position of the frame origin (2,) [m].
        :param yaw: world heading of the frame's x axis [rad].
        :param xs: ``(K,)`` increasing x positions [m].
        :param s_origin: the origin's reference arc length, if known [m].
        :return: ``(y, u)``, each ``(n_markings, K)``: lateral position [m] of
            marking ``j`` at ``xs[k]`` and its arc length along the marking [m];
            NaN where the marking does not reach that x.
        """
        ref = self.reference
        origin = world_point("origin", origin)
        if not math.isfinite(yaw):
            raise InputError(f"yaw must be finite, got {yaw!r}")
        if s_origin is None:
            s_origin, _ = ref.project(origin)
        else:
            self._check_hint(origin, s_origin)
        xs = np.asarray(xs, dtype=np.float64)
        x_max = float(xs[-1]) if len(xs) else 0.0
        forward = math.cos(yaw - float(np.interp(s_origin, ref.s, ref.heading))) >= 0.0
        reach = 1.2 * x_max + margin  # arc length needed to cover x_max, with slack
        if forward:
            lo, hi = s_origin - margin, s_origin + reach
        else:
            lo, hi = s_origin - reach, s_origin + margin
        # math.floor/ceil: int(np.floor(x)) without numpy's scalar dispatch (same
        # integers; NaN and inf raise as int() does).
        i0 = max(math.floor(lo / ref.step), 0)
        i1 = min(math.ceil(hi / ref.step) + 1, len(ref.s))
        m = len(self.markings)
        y_out = np.full((m, len(xs)), np.nan)
        u_out = np.full((m, len(xs)), np.nan)
        if i1 - i0 < 2:
            return y_out, u_out
        if not forward:
            i0, i1 = i1 - 1, i0 - 1  # walk the table backwards
        _sample_lines(
            ref.xy,
            ref.normal,
            self._u,
            self._offsets,
            i0,
            i1,
            -1 if not forward else 1,
            float(origin[0]),
            float(origin[1]),
            float(yaw),
            xs,
            y_out,
            u_out,
        )
        return y_out, u_out


def _check_finite(name: str, value: Any) -> None:
    """ValueError naming ``name`` unless ``value`` is finite (a number or an array)."""
    if isinstance(value, float | int):
        ok = math.isfinite(value)
    else:
        ok = bool(np.all(np.isfinite(np.asarray(value, dtype=np.float64))))
    if not ok:
        raise InputError(f"{name} must be finite, got {value!r}")


class HighwayNetwork(RoadNetwork):
    """highway-env's ``RoadNetwork`` for a :class:`HighwayRoad`, with a one-projection lane look-up.

    ``Vehicle.on_state_update`` asks for the closest lane at every simulation step. The
    base implementation projects the position on every lane; all lanes of a highway
    road share one reference line, arc length and heading, so the lane whose centre is
    nearest to the lateral offset is the answer (the base argmin's tie rule, first
    index, is kept). If lanes are added to the graph, the base look-up is used.
    """

    def __init__(self, road: HighwayRoad) -> None:
        """Create the (still empty) network of ``road``."""
        super().__init__()
        self._road = road
        self._prepared: dict[bytes, tuple[str, str, int]] = {}

    def get_closest_lane_index(
        self, position: np.ndarray, heading: float | None = None
    ) -> tuple[str, str, int]:
        """Index ``("a", "b", lane_id)`` of the lane closest to a world position [m]."""
        road = self._road
        lanes = self.graph.get(EDGE[0], {}).get(EDGE[1], [])
        if len(self.graph) != 1 or len(lanes) != road.lanes_count:
            return super().get_closest_lane_index(position, heading)
        if type(position) is np.ndarray and position.dtype == np.float64 and position.shape == (2,):
            prepared = self._prepared.get(position.tobytes())
            if prepared is not None:
                return prepared
        # Nearest lane centre; at an exact boundary the lower id wins, as np.argmin does.
        return (EDGE[0], EDGE[1], road.locate(position)[2])

    def prepare_closest_lanes(self, positions: FloatArray) -> None:
        """Project ``(N, 2)`` world positions [m] in one batch ahead of their look-ups.

        The projections are those :meth:`get_closest_lane_index` computes one at a time
        (:meth:`ReferenceLine.remember_projections`, bit for bit), so the lanes
        remembered here for the next look-ups are the lanes it would return. Only the
        latest batch is kept.
        """
        batch = self._road.reference.remember_projections(positions)
        lane_of_offset = self._road.lane_of_offset
        self._prepared = {
            key: (EDGE[0], EDGE[1], lane_of_offset(d)) for key, (_, d) in batch.items()
        }


def _sample_lines_py(
    xy: FloatArray,
    normal: FloatArray,
    u_tab: FloatArray,
    offsets: FloatArray,
    i_start: int,
    i_stop: int,
    direction: int,
    ox: float,
    oy: float,
    yaw: float,
    xs: FloatArray,
    y_out: FloatArray,
    u_out: FloatArray,
) -> None:
    """Fill ``y_out[j, k]``/``u_out[j, k]`` where marking ``j`` crosses ``x = xs[k]``.

    Walks the reference table from ``i_start`` towards ``i_stop`` (exclusive) in
    ``direction``; each marking is the reference offset by ``offsets[j]`` to the
    left. The walk of a marking stops where it no longer advances in the sensor's
    x, so each x is crossed at most once. Plain-Python reference of ``_sample_lines``.
    """
    cy, sy = math.cos(yaw), math.sin(yaw)
    nk = xs.shape[0]
    for j in range(offsets.shape[0]):
        off = offsets[j]
        k = 0
        have_prev = False
        x0 = y0 = u0 = 0.0
        i = i_start
        while i != i_stop and k < nk:
            wx = xy[i, 0] + off * normal[i, 0] - ox
            wy = xy[i, 1] + off * normal[i, 1] - oy
            x1 = wx * cy + wy * sy
            y1 = wx * sy - wy * cy  # left of the sensor's x axis
            u1 = u_tab[j, i]
            if have_prev:
                if x1 <= x0:
                    break
                while k < nk and xs[k] <= x1:
                    if xs[k] >= x0:
                        t = (xs[k] - x0) / (x1 - x0)
                        y_out[j, k] = y0 + t * (y1 - y0)
                        u_out[j, k] = u0 + t * (u1 - u0)
                    k += 1
            x0, y0, u0 = x1, y1, u1
            have_prev = True
            i += direction


_sample_lines = numba.njit(cache=True)(_sample_lines_py)


def generate_highway(**overrides: Any) -> HighwayRoad:
    """Build a :class:`HighwayRoad` from keyword overrides of :class:`RoadConfig`."""
    return HighwayRoad(overrides)
