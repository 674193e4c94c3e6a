"""The conditions of triggers: their values from the world's state.

Each function here returns ``evaluate(runner) -> bool`` for a
:class:`~aldm_gym.scenario.storyboard.Condition`; ``runner`` is the
:class:`~aldm_gym.scenario.runner.ScenarioRunner` (its ``world`` and ``storyboard``).

Distances (``RelativeDistanceCondition``, ``TimeHeadwayCondition``,
``DistanceCondition``, ``TimeToCollisionCondition``) follow the standard's coordinate
systems:

- ``entity``: in the triggering entity's frame (x forward, y left): longitudinal
  along its x, lateral along its y, euclidean in the plane. With ``freespace`` the
  distance is between the bounding boxes (0 where they overlap along that axis),
  else between the reference points.
- ``road``: longitudinal as the difference of the reference line's ``s``, lateral as
  the difference of the road's ``t``; ``lane``: along and across the source's lane
  (the target's reference point projected on its centre line). With ``freespace`` the
  distance is between the bounding boxes: every corner projected into the system, the
  gap between the two intervals (0 where they overlap), so a box's extent is its own
  (a pedestrian crossing the road spans its width along ``s``) and the box centre need
  not be the reference point. Euclidean distances are the same in every system.

Speeds are the entities' speeds now (:attr:`~aldm_gym.scenario.world.Entity.current_speed`:
a scripted entity's script's, so a step ``SpeedAction`` that started earlier in the
same update shows at once, as in esmini).

A distance is a magnitude (>= 0). ``TimeHeadwayCondition`` divides the distance from
the triggering entity to the referenced one by the triggering entity's speed (inf when
it stands still), and counts only a referenced entity ahead; ``TimeToCollision``
divides the distance by the closing speed along the line of sight (inf when the two
do not close). An inf value is undefined: the condition holds for no rule (as esmini).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from aldm_gym.errors import OffRoadError
from aldm_gym.scenario.world import Entity, World, wrap_angle

__all__ = [
    "RULES",
    "ByEntity",
    "angle",
    "angle_within",
    "distance",
    "relative_angle",
    "relative_distance",
    "rule",
]

RULES: dict[str, Callable[[Any, Any], bool]] = {
    "greaterThan": operator.gt,
    "lessThan": operator.lt,
    "equalTo": lambda a, b: abs(a - b) < 1e-9 if _numbers(a, b) else a == b,
    "greaterOrEqual": operator.ge,
    "lessOrEqual": operator.le,
    "notEqualTo": lambda a, b: abs(a - b) >= 1e-9 if _numbers(a, b) else a != b,
}
"""OpenSCENARIO's comparison rules."""


def _numbers(a: Any, b: Any) -> bool:
    return isinstance(a, int | float) and isinstance(b, int | float)


def rule(name: str) -> Callable[[Any, Any], bool]:
    """The comparison of a ``rule`` attribute (KeyError for an unknown one)."""
    return RULES[name]


class ByEntity:
    """A ``ByEntityCondition``'s value: its condition on each triggering entity,
    combined by ``triggeringEntitiesRule``.

    Every triggering entity is evaluated (no short cut), so that :attr:`fulfilled`
    names those the condition holds on: ``selectTriggeringEntities`` makes them actors.
    An entity on no lane (:class:`~aldm_gym.errors.OffRoadError`) does not fulfil it.

    :param names: the triggering entities, in document order.
    :param every: ``triggeringEntitiesRule="all"`` (else ``any``).
    :param holds: ``holds(runner, name) -> bool``, the condition on one entity.
    """

    def __init__(
        self, names: Sequence[str], every: bool, holds: Callable[[Any, str], bool]
    ) -> None:
        """See the class docstring."""
        self.names = tuple(names)
        self.every = every
        self.holds = holds
        self.fulfilled: tuple[str, ...] = ()
        """The triggering entities the condition held on at the last evaluation."""

    def _one(self, runner: Any, name: str) -> bool:
        try:
            return bool(self.holds(runner, name))
        except OffRoadError:
            return False

    def __call__(self, runner: Any) -> bool:
        """The condition's value now (and :attr:`fulfilled` updated)."""
        self.fulfilled = tuple(n for n in self.names if self._one(runner, n))
        if self.every:
            return len(self.fulfilled) == len(self.names)
        return bool(self.fulfilled)


def _extent(entity: Entity, axis: np.ndarray) -> tuple[float, float]:
    """The box's (min, max) projection on a unit axis [m]."""
    p = entity.corners() @ axis
    return float(p.min()), float(p.max())


def _gap(a: tuple[float, float], b: tuple[float, float]) -> float:
    """The distance between two intervals (0 where they overlap)."""
    return max(0.0, b[0] - a[1], a[0] - b[1])


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    denom = float(ab @ ab)
    k = 0.0 if denom == 0.0 else min(1.0, max(0.0, float((p - a) @ ab) / denom))
    return float(np.hypot(*(p - (a + k * ab))))


def box_distance(a: Entity, b: Entity) -> float:
    """The shortest distance between two boxes [m] (0 where they overlap)."""
    ca, cb = a.corners(), b.corners()
    if _overlap(ca, cb):
        return 0.0
    best = math.inf
    for poly, other in ((ca, cb), (cb, ca)):
        for i in range(4):
            for p in other:
                best = min(best, _segment_distance(p, poly[i], poly[(i + 1) % 4]))
    return best


def _overlap(ca: np.ndarray, cb: np.ndarray) -> bool:
    """Separating-axis test of two rectangles."""
    for poly in (ca, cb):
        for i in range(2):
            edge = poly[i + 1] - poly[i]
            axis = np.array([-edge[1], edge[0]])
            pa, pb = ca @ axis, cb @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def relative_distance(
    world: World,
    source: Entity,
    target: Entity,
    kind: str,
    freespace: bool,
    system: str = "entity",
) -> float:
    """The distance [m] from ``source`` to ``target`` of ``kind`` (``longitudinal``,
    ``lateral``, ``euclidianDistance``/``cartesianDistance``) in ``system``."""
    if system in ("road", "lane") and kind in ("longitudinal", "lateral"):
        if freespace:  # between the boxes, their corners projected
            if system == "road":
                a, b = world.road_box(source), world.road_box(target)
            else:
                key = world.coordinates(source).lane
                a, b = world.lane_box(source, key), world.lane_box(target, key)
            if kind == "longitudinal":
                return _gap((a[0], a[1]), (b[0], b[1]))
            return _gap((a[2], a[3]), (b[2], b[3]))
        if system == "road":
            ca, cb = world.coordinates(source), world.coordinates(target)
            ds, dt = abs(cb.s - ca.s), abs(world.road_t(target) - world.road_t(source))
        else:  # along and across the source's lane
            ds, dt = world.lane_offsets(source, target)
        return ds if kind == "longitudinal" else dt
    if system not in ("road", "lane", "entity"):
        raise ValueError(f"coordinate system {system!r}")
    if kind in ("euclidianDistance", "cartesianDistance"):
        if freespace:
            return box_distance(source, target)
        return float(np.hypot(*(target.reference_point() - source.reference_point())))
    axis = source.forward() if kind == "longitudinal" else source.left()
    if freespace:
        return _gap(_extent(source, axis), _extent(target, axis))
    return abs(float((target.reference_point() - source.reference_point()) @ axis))


def distance(world: World, source: Entity, point: np.ndarray, freespace: bool) -> float:
    """Euclidean distance [m] from an entity (its box with ``freespace``, else its
    reference point) to a world point."""
    if freespace:
        c = source.corners()
        inside = all(
            float(np.cross(c[(i + 1) % 4] - c[i], point - c[i])) <= 0 for i in range(4)
        ) or all(float(np.cross(c[(i + 1) % 4] - c[i], point - c[i])) >= 0 for i in range(4))
        if inside:
            return 0.0
        return min(_segment_distance(point, c[i], c[(i + 1) % 4]) for i in range(4))
    return float(np.hypot(*(point - source.reference_point())))


def headway(
    world: World,
    source: Entity,
    target: Entity,
    freespace: bool,
    system: str,
    kind: str = "euclidianDistance",
) -> float:
    """Time headway [s] from ``source`` to ``target`` ahead of it: the distance of
    ``kind`` over ``source``'s speed (inf when the target is behind or ``source``
    stands still)."""
    ahead = float((target.position - source.position) @ source.forward())
    if ahead <= 0.0:
        return math.inf
    d = relative_distance(world, source, target, kind, freespace, system)
    v = source.current_speed
    return math.inf if v <= 0.0 else d / v


def time_to_collision(
    world: World,
    source: Entity,
    target: Entity,
    freespace: bool,
    system: str = "entity",
    kind: str = "euclidianDistance",
) -> float:
    """Time to collision [s]: the distance of ``kind`` in ``system`` over the speed at
    which it closes (inf when it does not). Longitudinal and lateral distances close
    at the difference of the two velocities along the source's heading (``entity``)
    or its lane's direction (``road``, ``lane``), or across it; euclidean ones along
    the line of sight."""
    if kind in ("longitudinal", "lateral"):
        if system == "entity":
            axis = source.forward() if kind == "longitudinal" else source.left()
        else:
            c = world.coordinates(source)
            _, h = world.pose(c.lane, c.u, 0.0)
            forward = np.array([math.cos(h), math.sin(h)])
            axis = forward if kind == "longitudinal" else np.array([forward[1], -forward[0]])
        side = float((target.position - source.position) @ axis)
        relative = source.current_speed * source.forward() - target.current_speed * target.forward()
        closing = float(relative @ axis) * (1.0 if side >= 0 else -1.0)
        if closing <= 0.0:
            return math.inf
        return relative_distance(world, source, target, kind, freespace, system) / closing
    los = target.position - source.position
    norm = float(np.hypot(*los))
    if norm == 0.0:
        return 0.0
    los = los / norm
    vs = source.current_speed * source.forward()
    vt = target.current_speed * target.forward()
    closing = float((vs - vt) @ los)
    if closing <= 0.0:
        return math.inf
    d = box_distance(source, target) if freespace else norm
    return d / closing


def time_to_point(world: World, source: Entity, point: np.ndarray, freespace: bool) -> float:
    """Time to collision with a point [s]: the distance to it over the source's speed
    along the line of sight (inf when it does not close)."""
    los = point - source.position
    norm = float(np.hypot(*los))
    if norm == 0.0:
        return 0.0
    closing = float(source.current_speed * source.forward() @ (los / norm))
    if closing <= 0.0:
        return math.inf
    return distance(world, source, point, freespace) / closing


def boxes_overlap(a: Entity, b: Entity) -> bool:
    """Whether two entities' bounding boxes overlap (``CollisionCondition``; a
    tractor and the trailer it tows do not collide)."""
    if a is b or a.trailer is b or b.trailer is a:
        return False
    return _overlap(a.corners(), b.corners())


def stood_still(world: World, entity: Entity, duration: float) -> bool:
    """Whether the entity has stood still (speed below 1e-3 m/s) for longer than
    ``duration`` [s] (as esmini: a step after the duration)."""
    since = entity.still_since
    return since is not None and world.time - since > duration + 1e-9


def acceleration(world: World, entity: Entity) -> float:
    """The entity's longitudinal acceleration over the last step [m/s²]."""
    return entity.acceleration


def at_road_end(world: World, entity: Entity, duration: float) -> bool:
    """Whether the entity has been at the end of its lane chain for longer than
    ``duration`` [s]."""
    since = entity.road_end_since
    return since is not None and world.time - since > duration + 1e-9


def off_road(world: World, entity: Entity, duration: float) -> bool:
    """Whether the entity's reference point has been on no driving lane for longer
    than ``duration`` [s]."""
    since = entity.off_road_since
    return since is not None and world.time - since > duration + 1e-9


def _lane_index(lane_id: int) -> int:
    """Position of a lane along the road's t axis (lane 0 skipped)."""
    return lane_id if lane_id > 0 else lane_id + 1


def lanes_clear(
    world: World,
    entity: Entity,
    others: list[Entity],
    ranges: list[tuple[int, int]],
    backward: float,
    forward: float,
    freespace: bool,
    opposite: bool,
) -> bool:
    """``RelativeClearanceCondition``: no other entity on the lanes ``ranges`` (relative
    to the entity's, positive to its left; no range: its own lane) from ``backward``
    [m] behind to ``forward`` [m] ahead of it along the road (between the boxes with
    ``freespace``, else the reference points); lanes of the other driving direction
    count only with ``opposite``."""
    from aldm_gym.errors import OffRoadError

    try:
        c = world.coordinates(entity)
        box = world.road_box(entity)
    except OffRoadError:
        return True
    wanted = ranges or [(0, 0)]
    for other in others:
        if other is entity:
            continue
        try:
            o = world.coordinates(other)
        except OffRoadError:
            continue
        if o.road_id != c.road_id or (o.direction != c.direction and not opposite):
            continue
        rel = (_lane_index(o.lane_id) - _lane_index(c.lane_id)) * c.direction
        if not any(min(a, b) <= rel <= max(a, b) for a, b in wanted):
            continue
        if freespace:
            ob = world.road_box(other)
            ahead = (ob[0] - box[1]) if c.direction > 0 else (box[0] - ob[1])
            behind = (box[0] - ob[1]) if c.direction > 0 else (ob[0] - box[1])
            if ahead <= forward and behind <= backward:
                return False
        else:
            ds = (o.s - c.s) * c.direction
            if -backward <= ds <= forward:
                return False
    return True


def speed(entity: Entity, other: Entity | None, direction: str | None) -> float:
    """The entity's speed [m/s] (``other``: relative to that entity's), total or along
    the entity's ``longitudinal``, ``lateral`` or ``vertical`` axis (OpenSCENARIO 1.3's
    ``direction``); an entity moves along its heading, the world is planar.

    A scripted entity's speed is its script's now (:attr:`Entity.current_speed`): a
    step ``SpeedAction`` that started earlier in this update shows at once, as in
    esmini, where actions set an object's speed as they start."""
    if direction is None:  # the total speeds (their difference)
        return entity.current_speed - (0.0 if other is None else other.current_speed)
    velocity = entity.current_speed * entity.forward()
    if other is not None:
        velocity = velocity - other.current_speed * other.forward()
    if direction == "vertical":
        return 0.0
    axis = entity.forward() if direction == "longitudinal" else entity.left()
    return float(velocity @ axis)


def angle(world: World, entity: Entity, kind: str, system: str) -> float:
    """The entity's ``heading``, ``pitch`` or ``roll`` [rad] (``AngleCondition``) in
    OpenDRIVE's sense (counter-clockwise, from above): in ``world`` coordinates, or
    relative to the road's reference line (``road``: along increasing ``s``) or to its
    lane's driving direction (``lane``) where it is. The world is planar: pitch and
    roll are 0.

    :raises OffRoadError: ``road`` or ``lane`` and the entity is on no driving lane.
    """
    if kind != "heading":
        return 0.0
    heading = -entity.heading  # highway-env's y points down
    if system == "world":
        return wrap_angle(heading)
    c = world.coordinates(entity)
    _, lane_heading = world.pose(c.lane, c.u, 0.0)
    along = -lane_heading + (math.pi if system == "road" and c.direction < 0 else 0.0)
    return wrap_angle(heading - along)


def relative_angle(world: World, entity: Entity, other: Entity, kind: str, system: str) -> float:
    """The entity's ``heading``, ``pitch`` or ``roll`` relative to ``other``'s [rad]
    (``RelativeAngleCondition``): the difference of their angles, each in the same
    system (``entity``: the world's, as the difference is the angle in ``other``'s
    frame)."""
    system = "world" if system == "entity" else system
    return wrap_angle(angle(world, entity, kind, system) - angle(world, other, kind, system))


def angle_within(value: float, target: float, tolerance: float) -> bool:
    """Whether an angle is within ``tolerance`` [rad] of ``target`` (both wrapped)."""
    return abs(wrap_angle(value - target)) <= tolerance


class _Point:
    """A point as the vehicle of a zero-size entity (for distances to positions)."""

    def __init__(self, point: np.ndarray) -> None:
        self.position = np.asarray(point, dtype=float)
        self.heading = 0.0
        self.speed = 0.0


def at_point(point: np.ndarray) -> Entity:
    """A zero-size entity standing at a world point [m], to measure distances to it
    like to an entity (``DistanceCondition`` in road and lane coordinates)."""
    from aldm_gym.scenario.world import BoundingBox

    return Entity(
        name="<position>",
        kind="miscObject",
        category="point",
        box=BoundingBox(0.0, 0.0, 1e-9, 1e-9, 0.0),
        vehicle=_Point(point),
        scripted=False,
    )
