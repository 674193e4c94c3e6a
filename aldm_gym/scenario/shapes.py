"""Trajectory shapes: ``Polyline``, ``Clothoid``, ``ClothoidSpline`` and ``Nurbs``.

A shape resolves, when its ``FollowTrajectoryAction`` starts, into a :class:`Path`: a
polyline in highway-env's world with a heading and (for timed shapes) a time at each
point, which :class:`~aldm_gym.scenario.actions.FollowTrajectory` drives along. Curved
shapes are sampled every :data:`SAMPLE` metres or finer, with their exact headings; a
polyline keeps its vertices (a vertex without an orientation takes its segment's
direction).

Curvature and heading follow OpenDRIVE's sense (counter-clockwise positive); in
highway-env's world (y down the screen) a left turn decreases the heading, so the
heading there is ``h0 − ∫κ ds``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from aldm_gym.errors import ScenarioError

if TYPE_CHECKING:
    from aldm_gym.scenario.positions import Position
    from aldm_gym.scenario.world import Entity, World

__all__ = ["SAMPLE", "Clothoid", "ClothoidSpline", "Nurbs", "Path", "Polyline", "Shape"]

SAMPLE = 0.5
"""The longest step [m] between the points a curved shape is sampled at."""

MAX_POINTS = 200_000
"""The most points one shape may be sampled into (a 100 km clothoid at 0.5 m)."""


@dataclass(frozen=True)
class Path:
    """A resolved shape.

    :ivar points: ``(N, 2)`` reference-point positions, highway-env's world [m].
    :ivar headings: ``N`` headings [rad] (highway-env's world) or None where the
        segment's direction applies.
    :ivar times: ``(N,)`` times [s] of the points, or None (an untimed shape).
    """

    points: np.ndarray
    headings: list[float | None]
    times: np.ndarray | None
    smooth: bool = False
    """The headings are samples of a smooth curve: interpolate between them."""


class Shape:
    """A trajectory shape; :meth:`resolve` places it in the world now."""

    where: str = ""

    def resolve(self, world: World, entity: Entity | None = None) -> Path:
        """The shape's path in the world's current state (``entity``: the actor, where
        the shape starts when it names no start)."""
        raise NotImplementedError


def _pose(world: World, position: Position) -> tuple[np.ndarray, float, bool]:
    """World point [m], heading [rad] and whether the position gave an orientation."""
    w = position.resolve(world)
    if w.lane is not None:
        p, h = world.pose(w.lane, w.u, w.t)
        return np.asarray(p, dtype=float), h + w.heading_offset, w.heading_given
    assert w.point is not None
    return np.asarray(w.point, dtype=float), w.heading, w.heading_given


@dataclass(frozen=True)
class Polyline(Shape):
    """``Polyline``: vertices with optional times."""

    vertices: list[tuple[float | None, Position]]
    where: str = ""

    def resolve(self, world: World, entity: Entity | None = None) -> Path:
        """See :class:`Shape`."""
        points, headings = [], []
        for _, pos in self.vertices:
            p, h, given = _pose(world, pos)
            points.append(p)
            headings.append(h if given else None)
        times = [t for t, _ in self.vertices]
        timed = all(t is not None for t in times)
        return Path(np.array(points), headings, np.array(times, dtype=float) if timed else None)


def _sample(length: float, where: str) -> np.ndarray:
    """Arc lengths [m] from 0 to ``length`` at most :data:`SAMPLE` apart."""
    if not math.isfinite(length) or length <= 0.0:
        raise ScenarioError(f"{where}: length must be finite and > 0, got {length:g}")
    n = math.ceil(length / SAMPLE) + 1
    if n > MAX_POINTS:
        raise ScenarioError(f"{where}: a {length:g} m shape is longer than the player samples")
    return np.linspace(0.0, length, max(n, 2))


def _integrate(
    start: np.ndarray, heading: float, s: np.ndarray, turned: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Points and headings along arc lengths ``s`` from ``start``: ``turned`` is the
    OpenDRIVE heading change at each ``s`` (midpoint rule between samples)."""
    h = heading - turned  # highway-env's world turns the other way
    mid = 0.5 * (h[1:] + h[:-1])
    ds = np.diff(s)
    steps = np.stack([np.cos(mid) * ds, np.sin(mid) * ds], axis=1)
    points = start + np.vstack([np.zeros((1, 2)), np.cumsum(steps, axis=0)])
    return points, h


@dataclass(frozen=True)
class Clothoid(Shape):
    """``Clothoid``: from a start position (its heading), curvature [1/m] changing at
    ``curvature_prime`` [1/m²] over ``length`` [m]; times from ``start_time`` to
    ``stop_time`` [s] along the length if both are given."""

    start: Position
    curvature: float
    curvature_prime: float
    length: float
    start_time: float | None = None
    stop_time: float | None = None
    where: str = ""

    def resolve(self, world: World, entity: Entity | None = None) -> Path:
        """See :class:`Shape`."""
        p0, h0, _ = _pose(world, self.start)
        s = _sample(self.length, self.where)
        turned = self.curvature * s + 0.5 * self.curvature_prime * s * s
        points, h = _integrate(p0, h0, s, turned)
        times = None
        if self.start_time is not None and self.stop_time is not None:
            times = self.start_time + (self.stop_time - self.start_time) * s / self.length
        return Path(points, [float(x) for x in h], times, smooth=True)


@dataclass(frozen=True)
class ClothoidSpline(Shape):
    """``ClothoidSpline`` (1.3): segments, each from its start curvature to its end
    curvature over its length [m], continuing the previous one's heading (plus its
    ``h_offset`` [rad]); the first starts at its ``position_start``, or where the actor
    is. Times: each
    segment's ``time_start`` to the next's (the last to ``time_end``) along its length.

    :ivar segments: ``(curvature_start, curvature_end, length, h_offset, time_start,
        position_start)``.
    """

    segments: list[tuple[float, float, float, float, float | None, Position | None]]
    time_end: float | None = None
    where: str = ""

    def resolve(self, world: World, entity: Entity | None = None) -> Path:
        """See :class:`Shape`."""
        first = self.segments[0][5]
        if first is not None:
            point, heading, _ = _pose(world, first)
        elif entity is not None:  # from where the actor is, along its heading
            point, heading = entity.reference_point(), entity.heading
        else:
            raise ScenarioError(f"{self.where}: the first segment needs a positionStart")
        all_points, all_h, all_t = [point[None, :]], [heading], []
        starts = [seg[4] for seg in self.segments] + [self.time_end]
        timed = all(t is not None for t in starts)
        for k, (k0, k1, length, h_offset, t0, pos) in enumerate(self.segments):
            if k > 0 and pos is not None:
                point, heading, _ = _pose(world, pos)
            heading -= h_offset
            s = _sample(length, self.where)
            turned = k0 * s + 0.5 * (k1 - k0) / length * s * s
            points, h = _integrate(point, heading, s, turned)
            all_points.append(points[1:])
            all_h.extend(float(x) for x in h[1:])
            if timed:
                ta, tb = float(t0), float(starts[k + 1])  # type: ignore[arg-type]
                if k == 0:
                    all_t.append(ta)
                all_t.extend(list(ta + (tb - ta) * s[1:] / length))
            point, heading = points[-1], float(h[-1])
        return Path(
            np.vstack(all_points), list(all_h), np.array(all_t) if timed else None, smooth=True
        )


@dataclass(frozen=True)
class Nurbs(Shape):
    """``Nurbs``: a rational B-spline of ``order`` (degree + 1) through weighted control
    points; the control points' times, if every one has one, are interpolated by the
    same basis."""

    order: int
    control_points: list[tuple[Position, float | None, float]]
    knots: list[float]
    where: str = ""

    def resolve(self, world: World, entity: Entity | None = None) -> Path:
        """See :class:`Shape`."""
        from scipy.interpolate import BSpline

        degree = self.order - 1
        n = len(self.control_points)
        if degree < 1 or n < self.order:
            raise ScenarioError(
                f"{self.where}: order {self.order} needs at least {self.order} control points"
                f" (has {n}) and order >= 2"
            )
        if len(self.knots) != n + self.order:
            raise ScenarioError(
                f"{self.where}: {n} control points of order {self.order} need "
                f"{n + self.order} knots, got {len(self.knots)}"
            )
        knots = np.asarray(self.knots, dtype=float)
        if np.any(np.diff(knots) < 0) or not np.all(np.isfinite(knots)):
            raise ScenarioError(f"{self.where}: the knots must be finite and not decrease")
        points = np.array([_pose(world, pos)[0] for pos, _, _ in self.control_points])
        weights = np.array([w for _, _, w in self.control_points], dtype=float)
        if np.any(weights <= 0) or not np.all(np.isfinite(weights)):
            raise ScenarioError(f"{self.where}: the control points' weights must be > 0")
        times = [t for _, t, _ in self.control_points]
        timed = all(t is not None for t in times)
        columns = [points * weights[:, None], weights[:, None]]
        if timed:
            columns.append((np.array(times, dtype=float) * weights)[:, None])
        spline = BSpline(knots, np.hstack(columns), degree)
        lo, hi = knots[degree], knots[n]
        if not hi > lo:
            raise ScenarioError(f"{self.where}: the knots leave no span to evaluate")
        # sample finely enough: the control polygon's length bounds the curve's
        polygon = float(np.hypot(*np.diff(points, axis=0).T).sum())
        if not math.isfinite(polygon) or polygon / SAMPLE * 4 > MAX_POINTS:
            raise ScenarioError(f"{self.where}: the curve is longer than the player samples")
        u = np.linspace(lo, hi, max(math.ceil(polygon / SAMPLE) * 4 + 1, 2 * n + 1))
        values = spline(u)
        curve = values[:, :2] / values[:, 2:3]
        out_times = values[:, 3] / values[:, 2] if timed else None
        keep = np.concatenate(([True], np.hypot(*np.diff(curve, axis=0).T) > 1e-9))
        curve = curve[keep]
        return Path(curve, [None] * len(curve), None if out_times is None else out_times[keep])
