"""Collisions: call ``handle_collisions`` on exactly the pairs where it can have an effect.

highway-env's ``Road.step`` checks every pair of road objects. A sort-and-sweep broad
phase on ``x`` (radius = the base spherical pre-check's radius) and a separating-axis
test on the boxes' edge normals (with a margin far above rounding) select the only
pairs whose :meth:`~highway_env.vehicle.objects.RoadObject.handle_collisions` can do
anything; they are handled in the base loop's order, so impacts are identical.
"""

from __future__ import annotations

import math
from functools import cache

import numba
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import RoadObject

__all__ = ["resolve_collisions"]

BROAD_PHASE_SLACK = 1e-6
"""Absolute slack [m] added to collision radii so that float rounding in the base
``np.linalg.norm`` pre-check can never make the broad phase drop a pair it keeps."""

SEPARATION_MARGIN = 1e-4
"""Gap [m] a box pair must clear on a separating axis before its exact check is skipped.

highway-env's polygon test computes the same projections with rounding errors of
order ``1e-16 × |position|`` (well below 1e-8 m on any road); the margin dwarfs them,
so a pair skipped here is one where that test returns "not intersecting, will not
intersect"."""

_BoxShape = tuple[float, float, float, float, float, float, float, float]
"""``(x, y, cos h, sin h, length / 2, width / 2, vx dt, vy dt)`` of a box road object
(positions, half sizes and displacements [m])."""


@cache
def _has_custom_collisions(cls: type) -> bool:
    """Whether ``cls`` overrides highway-env's collision check (cached per class)."""
    return (
        getattr(cls, "handle_collisions", None) is not RoadObject.handle_collisions
        or getattr(cls, "_is_colliding", None) is not RoadObject._is_colliding
    )


@cache
def uses_base_box(cls: type) -> bool:
    """Whether ``cls`` collides as highway-env's box: base polygon, velocity and checks."""
    return (
        not _has_custom_collisions(cls)
        and getattr(cls, "polygon", None) is RoadObject.polygon
        and getattr(cls, "direction", None) is RoadObject.direction
        and getattr(cls, "velocity", None) in (Vehicle.velocity, RoadObject.velocity)
    )


def boxes_separated_py(
    ax: float,
    ay: float,
    ac: float,
    as_: float,
    al: float,
    aw: float,
    adx: float,
    ady: float,
    bx: float,
    by: float,
    bc: float,
    bs: float,
    bl: float,
    bw: float,
    bdx: float,
    bdy: float,
) -> bool:
    """Whether box ``a`` (swept by its displacement relative to ``b``) and box ``b`` are
    apart by more than :data:`SEPARATION_MARGIN` on one of their four edge normals.

    A box is its centre ``(x, y)``, heading cosine and sine ``(c, s)``, half length
    ``l``, half width ``w`` and displacement over the step ``(dx, dy)`` [m] (the
    :data:`_BoxShape` fields). Those normals are among the axes of
    ``utils.are_polygons_intersecting``, so then it reports neither a current nor a
    future intersection, and ``handle_collisions`` has no effect. NaN never passes (the
    pair is then checked). Plain Python for :func:`resolve_collisions`, compiled
    (:func:`boxes_separated`) for the traffic kernels.
    """
    dx = bx - ax
    dy = by - ay
    wx = adx - bdx
    wy = ady - bdy
    for nx, ny in ((ac, as_), (-as_, ac), (bc, bs), (-bs, bc)):
        gap = (
            abs(dx * nx + dy * ny)
            - al * abs(ac * nx + as_ * ny)
            - aw * abs(ac * ny - as_ * nx)
            - bl * abs(bc * nx + bs * ny)
            - bw * abs(bc * ny - bs * nx)
            - abs(wx * nx + wy * ny)
        )
        if gap > SEPARATION_MARGIN:
            return True
    return False


boxes_separated = numba.njit(cache=True)(boxes_separated_py)


def resolve_collisions(vehicles: list[RoadObject], objects: list[RoadObject], dt: float) -> None:
    """Handle collisions as ``Road.step`` does, visiting only the pairs that can collide.

    The base loop calls ``vehicles[i].handle_collisions(other)`` for every later
    vehicle, then every object. That call is a no-op unless one side checks
    collisions, both are collidable and the centres are within
    ``(diag_i + diag_j) / 2 + speed_i * dt`` (its spherical pre-check). A
    sort-and-sweep on ``x`` with radius ``diag / 2 + max(speed * dt, 0)`` keeps a
    superset of those pairs. Pairs of plain boxes that are apart on one of their
    edge normals (:func:`boxes_separated_py`; vehicles side by side in adjacent
    lanes are the common case) are dropped too: the base polygon test would report
    no intersection for them. The rest are handled in the base loop's order, so the
    last write to each ``impact`` is the same. (Plain Python: for a few dozen
    objects it is several times cheaper than the same sweep in numpy calls.)

    :param vehicles: the road's vehicles (they call ``handle_collisions``).
    :param objects: the road's other objects (obstacles, landmarks).
    :param dt: timestep [s].
    """
    n_vehicles = len(vehicles)
    if n_vehicles == 0:
        return
    population = [*vehicles, *objects]
    entries: list[tuple[float, float, float, float, int, bool]] = []
    boxes: dict[int, _BoxShape] = {}
    for index, obj in enumerate(population):
        if not obj.collidable:
            continue  # both sides must be collidable
        px, py = obj.position.tolist()
        cls: type = type(obj)  # annotated: mypy does not see type[Any] as Hashable
        if _has_custom_collisions(cls):
            radius = math.inf  # its own collision logic: pair it with everything
        else:
            radius = obj.diagonal / 2 + max(obj.speed * dt, 0.0)
            radius = radius * (1 + 1e-9) + BROAD_PHASE_SLACK
        if not (math.isfinite(px) and math.isfinite(py)) or radius != radius:
            _resolve_all_collisions(vehicles, objects, dt)
            return
        if uses_base_box(cls):
            c = math.cos(obj.heading)
            s = math.sin(obj.heading)
            step = obj.speed * dt
            boxes[index] = (px, py, c, s, obj.LENGTH / 2, obj.WIDTH / 2, step * c, step * s)
        entries.append((px - radius, px + radius, py, radius, index, bool(obj.check_collisions)))
    entries.sort()
    pairs: list[tuple[int, int]] = []
    active: list[tuple[float, float, float, float, int, bool]] = []
    for entry in entries:
        low, _, y, radius, index, checks = entry
        if active:
            # Sorted by `low`, an earlier interval overlaps this one iff it ends after `low`.
            active = [a for a in active if a[1] >= low]
            for other in active:
                if (checks or other[5]) and abs(y - other[2]) <= radius + other[3]:
                    i, j = (index, other[4]) if index < other[4] else (other[4], index)
                    if i >= n_vehicles:  # objects never call handle_collisions themselves
                        continue
                    # Narrow phase: boxes clearly apart (side by side in adjacent
                    # lanes, or following at a distance) cannot collide this step.
                    box_i = boxes.get(i)
                    box_j = boxes.get(j)
                    if box_i is not None and box_j is not None:
                        if boxes_separated_py(*box_i, *box_j):
                            continue
                    pairs.append((i, j))
        active.append(entry)
    pairs.sort()
    for i, j in pairs:
        population[i].handle_collisions(population[j], dt)


def _resolve_all_collisions(
    vehicles: list[RoadObject], objects: list[RoadObject], dt: float
) -> None:
    """The base O(n²) collision loop (used when positions are not finite)."""
    for i, vehicle in enumerate(vehicles):
        for other in vehicles[i + 1 :]:
            vehicle.handle_collisions(other, dt)
        for other in objects:
            vehicle.handle_collisions(other, dt)
