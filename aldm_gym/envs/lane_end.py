"""Lanes that end: where the ego's lane ends ahead, and the chauffeur's answer to it.

A 2+1 road's overtaking lane, an on-ramp's acceleration lane and a lane drop end with
a taper: the lane narrows to nothing while the lane beside it goes on. A chauffeur
that only keeps its lane drives into the taper and off the road; a real one changes
lanes before the end, or stops at it when no gap comes.

Two sources say where the ego's lane ends, chosen by the ``lane_end`` section's
``source``:

* **The map horizon** (:func:`map_lane_end`), what ADASIS gives a production car from
  its navigation map: when the ego's lane chain ends before the road does, the
  distance along it to where the lane gets too narrow for the car (below ``end_width``
  and :data:`END_CLOSING` under its widest: the part of its taper the car cannot use),
  and the side of the neighbour that reaches farther. It reads the map at the ego's
  true position (a map-matched position, as ADASIS's).
* **Perception** (:func:`perceived_lane_end`): the ego's two detected lines converge.
  The lane ends where its width between them gets as narrow (against its width near
  the ego). The side to leave it by is across the line that stays: in a taper one line
  closes in on the other (a 2+1 road's centre line onto the lane line; an on-ramp's
  edge line onto the lane line), and the lane beyond the closing line widens as the
  ego's narrows, while the lane beyond the staying line keeps its width. Without a
  detected adjacent lane on the side to leave by, there is no side: the chauffeur then
  stops at the end.

:class:`LaneEndMonitor` combines them once per simulation step (the nearer end wins;
perception's end must be seen in ``confirm_steps`` consecutive frames, and is then held
until the ego has left the lane or passed it). The env then
(``docs/acc.md``, "Lanes that end"):

* starts a lane change to that side once the end is nearer than
  ``max(min_distance, lead_time · speed)``, under the built-in lateral control and any
  meta action but a lane change, as soon as the target lane has the gap the rule-based
  lane change asks for (:func:`gap_is_free`, the same check); and
* while no lane change is under way, brakes for the end as for a standing vehicle
  ``stop_margin`` before it (the ACC law), so the ego stops there if no gap comes.

The mirror case, a lane that opens beside the ego's with no line between them yet, is
:func:`opening_path`'s: the LKA keeps right instead of following the middle of the gap.

Sensor frame (ISO 8855: x forward, y left), SI units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from aldm_gym.config import setting, validate
from aldm_gym.envs.observation import VEHICLE_LENGTH, eval_line
from aldm_gym.envs.targets import Objects, corridor_overlaps, line_y
from aldm_gym.roads.position import LanePosition
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.types import FloatArray

SOURCES = ("both", "map", "perception", "off")
"""The values of ``lane_end.source``."""

GAP_BEHIND = 20.0
"""Free road the target lane needs behind the ego [m] (the rule-based LCA's)."""

GAP_AHEAD = 40.0
"""Free road the target lane needs ahead of the ego [m] (the rule-based LCA's)."""

CLOSING_TIME = 3.0
"""Time margin for a faster vehicle approaching from behind [s] (the rule-based LCA's)."""

SAMPLE_STEP = 2.0
"""x step at which the detected lane's width is read [m]."""

END_CLOSING = 0.5
"""A lane has ended where it is narrower than ``end_width`` and this much [m] narrower
than near the ego (than its widest, on the map): a 3.5 m lane at 3 m, a 3.1 m lane at
2.6 m. So that a narrow lane and a detector's noise on it make no end."""

NEAR_SAMPLES = 5
"""Perception: the lane's width near the ego is the median of its first this many
samples (every :data:`SAMPLE_STEP`)."""


@dataclass(frozen=True)
class LaneEndConfig:
    """The env's ``lane_end`` section: how the built-in chauffeur handles a lane that ends.

    :ivar source: what tells it that its lane ends: ``"both"`` (the map horizon and
        perception, the nearer end), ``"map"``, ``"perception"`` or ``"off"`` (the
        chauffeur keeps its lane to the end).
    :ivar lead_time: a lane change starts once the end is nearer than this times the
        ego's speed [s] ...
    :ivar min_distance: ... or than this [m], whichever is more.
    :ivar stop_margin: without a lane change under way the ego brakes to stop this far
        before the end [m].
    :ivar end_width: perception: the lane ends where its detected width falls below
        this [m].
    :ivar confirm_steps: perception: simulation steps in a row that must see the end.
    :ivar opening_factor: a detected ego lane wider than this many lane widths is
        opening into two: the LKA keeps a lane's width from the line that stays
        (:func:`opening_path`); 0: it keeps to the middle.
    """

    source: str = setting("both", choices=SOURCES)
    lead_time: float = setting(8.0, lo=0.0, hi=60.0)
    min_distance: float = setting(100.0, lo=0.0, hi=1000.0)
    stop_margin: float = setting(5.0, lo=0.0, hi=100.0)
    end_width: float = setting(3.0, lo=0.5, hi=5.0)
    confirm_steps: int = setting(3, lo=1, hi=50, integer=True)
    opening_factor: float = setting(1.25, lo=0.0, hi=3.0)

    def __post_init__(self) -> None:
        validate(self, "lane_end")


@dataclass(frozen=True)
class LaneEnd:
    """Where the ego's lane ends.

    :ivar distance: from the ego's centre to the end, along the lane [m].
    :ivar side: the side to leave the lane by: +1 left, -1 right, 0 unknown.
    :ivar source: ``"map"`` or ``"perception"``.
    """

    distance: float
    side: int
    source: str


def map_lane_end(road: Road, pos: LanePosition, end_width: float = 3.0) -> LaneEnd | None:
    """The map horizon's lane end: where the ego's lane chain, which ends before the road
    does (``road.lane_ends_in``), gets narrower than ``end_width`` [m] and
    :data:`END_CLOSING` narrower than its widest (its taper;
    ``road.lane_narrows_in``), and the side of the neighbour that reaches farther;
    ``None`` on a road whose lanes do not end (a generated highway).

    :param road: the env's road.
    :param pos: the ego's true lane position (map-matched).
    """
    distance = road.lane_ends_in(pos)
    if distance is None or not math.isfinite(distance):
        return None
    distance = min(distance, road.lane_narrows_in(pos, end_width, END_CLOSING))
    return LaneEnd(float(distance), int(road.lane_end_side(pos)), "map")


def _adjacent_width(detection: LaneDetection, side: int, xs: FloatArray) -> FloatArray | None:
    """Width [m] of the detected adjacent lane on ``side`` at ``xs``, or ``None`` when
    its outer line is not detected over ``xs``."""
    outer = detection.left_adjacent if side > 0 else detection.right_adjacent
    inner = detection.ego_left if side > 0 else detection.ego_right
    if len(outer) < 2 or outer[0, 0] > xs[0] + SAMPLE_STEP or outer[-1, 0] < xs[-1] - SAMPLE_STEP:
        return None
    yo = np.interp(xs, outer[:, 0], outer[:, 1])
    yi = np.interp(xs, inner[:, 0], inner[:, 1])
    return (yo - yi) * side


def perceived_lane_end(
    detection: LaneDetection | None, end_width: float, ego_x: float = -1.0
) -> LaneEnd | None:
    """The end of the ego's lane as its detected lines show it (the module docstring):
    the nearest x where the width between ``ego_left`` and ``ego_right`` falls below
    ``end_width`` and :data:`END_CLOSING` below its width near the ego,
    within the x range both lines cover; ``None`` if it does not. Where both adjacent
    lanes keep their width, the side is the right one (keep right).

    :param end_width: the width [m] below which the lane has ended.
    :param ego_x: x of the ego's centre in the sensor frame [m].
    """
    if detection is None:
        return None
    left, right = detection.ego_left, detection.ego_right
    if len(left) < 2 or len(right) < 2:
        return None
    x0, x1 = max(left[0, 0], right[0, 0]), min(left[-1, 0], right[-1, 0])
    if x1 - x0 < 2.0 * SAMPLE_STEP:
        return None
    if _width_range(left, right, float(x0), float(x1))[0] >= end_width:
        return None  # nowhere that narrow: most frames end here
    xs = np.arange(x0, x1 + 1e-9, SAMPLE_STEP)
    width = np.interp(xs, left[:, 0], left[:, 1]) - np.interp(xs, right[:, 0], right[:, 1])
    near = sorted(width[:NEAR_SAMPLES].tolist())  # the median, without numpy's overhead
    limit = min(end_width, near[len(near) // 2] - END_CLOSING)
    if width[0] < limit:
        return None  # narrow from the start: not a taper the ego is in
    narrow = np.flatnonzero(width < limit)
    if not len(narrow):
        return None
    k = int(narrow[0])
    closing = width[0] - width[k]
    side = 0
    grown = {}
    for s in (1, -1):
        adjacent = _adjacent_width(detection, s, xs[: k + 1])
        if adjacent is not None:
            grown[s] = adjacent[-1] - adjacent[0]
    # The lane beyond the staying line keeps its width; beyond the closing one it grows.
    staying = [s for s, g in grown.items() if abs(g) < 0.5 * closing]
    if len(staying) == 1:
        side = staying[0]
    elif len(staying) == 2:
        side = -1  # both look alike: keep right
    return LaneEnd(float(xs[k] - ego_x), side, "perception")


OPENING_BLEND = 0.2
"""Over this many lane widths beyond ``opening_factor`` the LKA's path blends from the
detection's trajectory to the staying line's offset (:func:`opening_path`)."""


def _width_range_py(
    left: FloatArray, right: FloatArray, x0: float, x1: float
) -> tuple[float, float]:
    """The smallest and the largest width [m] between two lines over ``[x0, x1]``,
    where both are detected (linear between their points: the width is piecewise
    linear with its corners at the points of either line, so both are at one of them)."""
    narrowest, widest = np.inf, -np.inf
    for i in range(left.shape[0]):
        if x0 <= left[i, 0] <= x1:
            w = left[i, 1] - line_y(right, 0.0, left[i, 0])
            narrowest, widest = min(narrowest, w), max(widest, w)
    for i in range(right.shape[0]):
        if x0 <= right[i, 0] <= x1:
            w = line_y(left, 0.0, right[i, 0]) - right[i, 1]
            narrowest, widest = min(narrowest, w), max(widest, w)
    return narrowest, widest


_width_range = numba.njit(cache=True)(_width_range_py)


def opening_path(
    path: FloatArray,
    detection: LaneDetection | None,
    lane_width: float,
    factor: float,
) -> FloatArray:
    """The LKA's path where the ego's lane opens into two: half a lane width left of its
    right line (the keep-right rule), instead of the middle of the widening gap.

    A lane that opens beside the ego (a 2+1 road's overtaking lane starting, often with
    no paint between the two lanes until the split is complete) makes the detected
    lane wider than any lane; midway between its lines the ego drifts onto the lane
    boundary the map has there. Where the detected width ``w`` exceeds
    ``factor · lane_width`` the path blends, over :data:`OPENING_BLEND` lane widths
    more, from the detection's trajectory to the right line offset by half
    ``lane_width``: the right lane of the two, as the keep-right rule of right-hand
    traffic asks (German StVO §2(2), Austrian StVO §7). Which of the two lines is the
    one that stays cannot be told from one frame's two lines alone (a curve bends both,
    the ego's own yaw turns both); keeping right is also what a driver does where the
    new lane is on the left (2+1 roads, lanes added on a climb). Where it opens on the
    right (a diverge towards an exit), the ego follows the right lane, a lane, not the
    boundary between two. The width is read where both lines are detected (linear
    between their points) and held beyond; the right line is followed as the
    observation reads it (linear beyond its ends too). Below the threshold the path is
    unchanged. A lane merging in from the right whose line the detector misses looks
    the same (wide near the ego, normal ahead, as in the middle of an opening): the ego
    then keeps to the right lane of the two, the merging one, whose end the lane-end
    logic sees.

    :param path: ``(M, 2)`` the detection's trajectory [m].
    :param lane_width: the lane width the ego keeps [m].
    :param factor: the width, in lane widths, above which the lane is opening.
    """
    if detection is None or len(path) < 2:
        return path
    left, right = detection.ego_left, detection.ego_right
    if len(left) < 2 or len(right) < 2:
        return path
    x0, x1 = max(left[0, 0], right[0, 0]), min(left[-1, 0], right[-1, 0])
    if x1 <= x0:
        return path
    # The width where both lines are detected, held beyond (never extrapolated: a
    # detector's short lines extrapolated far apart are not a lane opening). Its
    # largest value first: most frames end there.
    lo = factor * lane_width
    if _width_range(left, right, float(x0), float(x1))[1] <= lo:
        return path
    seen = np.clip(path[:, 0], x0, x1)
    width = np.interp(seen, left[:, 0], left[:, 1]) - np.interp(seen, right[:, 0], right[:, 1])
    weight = np.clip((width - lo) / (OPENING_BLEND * lane_width), 0.0, 1.0)
    if not np.any(weight > 0.0):
        return path
    out = path.copy()
    keep = eval_line(right, path[:, 0]) + 0.5 * lane_width
    out[:, 1] = (1.0 - weight) * path[:, 1] + weight * keep
    return out


def gap_is_free(
    x: FloatArray,
    vx: FloatArray,
    behind: float = GAP_BEHIND,
    ahead: float = GAP_AHEAD,
    closing_time: float = CLOSING_TIME,
) -> bool:
    """Whether the target lane has room for a lane change: no vehicle of it within
    ``behind`` / ``ahead`` of the ego (centre to centre, plus a vehicle length), and
    none behind approaching faster than it can within ``closing_time`` plus 5 m. The
    rule-based lane change's check (:class:`~aldm_gym.agents.policies.RuleBasedLCA`).

    :param x: ``(N,)`` the target lane's vehicles' x relative to the ego [m].
    :param vx: ``(N,)`` their speeds relative to the ego [m/s] (> 0: faster).
    """
    for xi, vi in zip(np.asarray(x, float), np.asarray(vx, float), strict=True):
        if -behind - VEHICLE_LENGTH <= xi <= ahead + VEHICLE_LENGTH:
            return False
        gap = abs(xi) - VEHICLE_LENGTH
        if xi < 0 and vi > 0 and gap < closing_time * vi + 5.0:
            return False  # approaching fast from behind
    return True


BEHIND = 100.0
"""How far behind the ego the target lane's lines are carried for the gap check [m]."""


def _carried_back(line: FloatArray, curvature: float) -> FloatArray:
    """``line`` with points behind its first one, to :data:`BEHIND` behind the ego,
    along the arc of the ego's ``curvature`` from the line's first point and slope
    (a straight extrapolation behind puts a car 60 m back in a curve of R 500 m 3.6 m
    off its lane)."""
    x0, y0 = float(line[0, 0]), float(line[0, 1])
    slope = float((line[1, 1] - line[0, 1]) / max(line[1, 0] - line[0, 0], 1e-9))
    dx = np.arange(-BEHIND - x0, 0.0, 10.0)
    back = np.column_stack([x0 + dx, y0 + slope * dx + 0.5 * curvature * dx * dx])
    return np.vstack([back, line])


def target_lane_free(
    detection: LaneDetection | None,
    objects: Objects,
    side: int,
    *,
    lane_width: float,
    ego_x: float = -1.0,
    ego_speed: float = 0.0,
    curvature: float = 0.0,
) -> bool:
    """Whether the adjacent lane on ``side`` may be changed into: :func:`gap_is_free`
    on the objects with any part in it (between the ego line and the adjacent line; a
    missing adjacent line: the ego line shifted by ``lane_width``; both carried behind
    the ego along the arc of its ``curvature``), x from the ego's centre; and no object
    in it drives against the ego's direction (moving backwards over the road: an
    oncoming lane, as beyond a 2+1 road's centre line).

    :param ego_speed: the ego's speed [m/s] (an object's speed over the road is its
        relative speed plus it).
    :param curvature: the ego's path curvature [1/m] (> 0 left).
    """
    if len(objects) == 0:
        return True
    ego_line = "ego_left" if side > 0 else "ego_right"
    if detection is None or not detection.found(ego_line):
        return False
    line = detection.ego_left if side > 0 else detection.ego_right
    outer_name = "left_adjacent" if side > 0 else "right_adjacent"
    outer = detection.line(outer_name) if detection.found(outer_name) else line
    shift = 0.0 if detection.found(outer_name) else side * lane_width
    line, outer = _carried_back(line, curvature), _carried_back(outer, curvature)
    if side > 0:
        overlap = corridor_overlaps(objects.x, objects.y, objects.width, outer, shift, line, 0.0)
    else:
        overlap = corridor_overlaps(objects.x, objects.y, objects.width, line, 0.0, outer, shift)
    inside = overlap > 0.0
    if np.any(objects.vx[inside] + ego_speed < 0.0):
        return False  # oncoming traffic
    return gap_is_free(objects.x[inside] - ego_x, objects.vx[inside])


CONSISTENT = 10.0
"""Perception: successive sightings of an end agree when they differ by less than this,
after the way travelled between them [m]."""

PASSED = 10.0
"""A held end is forgotten once the ego is this far past it [m]."""


class LaneEndMonitor:
    """One episode's view of where the ego's lane ends (the module docstring).

    Perception's end is **held** once confirmed: ``confirm_steps`` sightings in a row
    that agree (each within :data:`CONSISTENT` of the last one moved by the way
    travelled) make it the end the chauffeur acts on, and it is then carried along by
    odometry, whatever the detector says next, until the ego has completed a lane
    change or is :data:`PASSED` beyond it. In a taper the detector's lines are at their
    least reliable (the closing line and the one it closes in on meet, and a detector
    may take the lane beyond for the ego's); a chauffeur that forgot the end there
    would drive into it.

    :param config: the ``lane_end`` section.
    :param ego_x: x of the ego's centre in the sensor frame [m].
    """

    def __init__(self, config: LaneEndConfig, ego_x: float = -1.0) -> None:
        self.config = config
        self.ego_x = float(ego_x)
        self.lane_end: LaneEnd | None = None
        """The end the chauffeur acts on at this step, or ``None``."""
        self._seen = 0
        self._last: LaneEnd | None = None
        self._held: LaneEnd | None = None
        self._held_changes = 0

    def _perceive(
        self, detection: LaneDetection | None, travelled: float, lane_changes: int
    ) -> LaneEnd | None:
        """Perception's end: confirmed, then held (the class docstring)."""
        seen = perceived_lane_end(detection, self.config.end_width, self.ego_x)
        last = self._last
        if seen is None:
            self._seen = 0
        elif last is not None and abs(seen.distance - (last.distance - travelled)) < CONSISTENT:
            self._seen += 1
        else:
            self._seen = 1
        self._last = seen
        held = self._held
        if held is not None:
            held = LaneEnd(held.distance - travelled, held.side, held.source)
            if held.distance < -PASSED or lane_changes > self._held_changes:
                held = None
        if seen is not None and self._seen >= self.config.confirm_steps:
            side = seen.side or (held.side if held is not None else 0)
            held = LaneEnd(seen.distance, side, seen.source)
            self._held_changes = lane_changes
        self._held = held
        return held

    def update(
        self,
        road: Road,
        pos: LanePosition | None,
        detection: LaneDetection | None,
        travelled: float = 0.0,
        lane_changes: int = 0,
    ) -> LaneEnd | None:
        """This simulation step's lane end (:attr:`lane_end`).

        :param pos: the ego's true lane position (for the map horizon), or ``None``
            off the map.
        :param travelled: the way the ego travelled since the last update [m].
        :param lane_changes: lane changes the ego has completed this episode.
        """
        source = self.config.source
        found: list[LaneEnd] = []
        if source in ("both", "map") and pos is not None:
            horizon = map_lane_end(road, pos, self.config.end_width)
            if horizon is not None:
                found.append(horizon)
        if source in ("both", "perception"):
            seen = self._perceive(detection, travelled, lane_changes)
            if seen is not None:
                found.append(seen)
        self.lane_end = min(found, key=lambda e: e.distance) if found else None
        if self.lane_end is not None and self.lane_end.side == 0 and len(found) == 2:
            # The map knows the side where perception does not.
            other = found[0] if found[1] is self.lane_end else found[1]
            self.lane_end = LaneEnd(self.lane_end.distance, other.side, self.lane_end.source)
        return self.lane_end

    def zone(self, speed: float) -> float:
        """The distance [m] from the end within which a lane change starts."""
        return max(self.config.min_distance, self.config.lead_time * max(speed, 0.0))


__all__ = [
    "SOURCES",
    "LaneEnd",
    "LaneEndConfig",
    "LaneEndMonitor",
    "gap_is_free",
    "map_lane_end",
    "opening_path",
    "perceived_lane_end",
    "target_lane_free",
]
