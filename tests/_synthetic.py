"""Small synthetic line-sensor point clouds for ALDM tests and the accuracy report.

A road is a reference line of constant curvature through the sensor (x forward, y
left) with markings at lateral offsets ``d(s)`` (piecewise linear in arc length s,
so lanes can open, close or end). Each marking is sampled about every 2 m along s
(CarMaker's point spacing, with a random phase per marking so that x values of
different markings differ), clipped to the field of view
x in [5.52, 200] m, painted 6 m / gap 12 m when dashed, then lateral noise and
dropout are applied. Object ids follow the two road models: ``"editor"`` (one object
per marking) and ``"per_dash"`` (one per dash). :func:`grid_frame` is the other
sampling, CarMaker's own: every line at the sensor's x grid, so x values tie exactly.
:func:`lane_change_drive` drives a stateful detector through a lane change.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from aldm_gym.sensor.tracking import EgoMotion

FOV_START = 5.52
RANGE = 200.0


@dataclass
class SynthMarking:
    """One marking: offsets ``d`` [m] at knots ``s`` [m] (linear between), dash pattern."""

    offset: float
    dashed: bool = False
    taper_s: tuple[float, ...] = ()
    taper_d: tuple[float, ...] = ()
    end_s: float = np.inf  # paint stops at this arc length (exit, lane drop)
    start_s: float = -np.inf
    z: float = 0.0
    dash: float = 6.0
    gap: float = 12.0
    phase: float = 0.0

    def d(self, s: np.ndarray) -> np.ndarray:
        if not self.taper_s:
            return np.full_like(s, self.offset)
        return np.interp(s, self.taper_s, self.taper_d)


@dataclass
class SynthRoad:
    """Markings around the car plus the road's signed curvature [1/m] (left > 0)."""

    markings: list[SynthMarking]
    curvature: float = 0.0
    yaw: float = 0.0  # sensor heading relative to the road [rad]
    ego_left: int | None = None  # index of the true ego-left marking
    ego_right: int | None = None
    left_adjacent: int | None = None
    right_adjacent: int | None = None
    extra: dict[str, object] = field(default_factory=dict)

    def curve(self, j: int, s: np.ndarray) -> np.ndarray:
        """Sensor-frame (x, y) of marking j at arc lengths s, shape (len(s), 2)."""
        k = self.curvature
        d = self.markings[j].d(s)
        if abs(k) < 1e-12:
            ref = np.column_stack([s, np.zeros_like(s)])
            th = np.zeros_like(s)
        else:
            th = k * s
            ref = np.column_stack([np.sin(th) / k, (1.0 - np.cos(th)) / k])
        normal = np.column_stack([-np.sin(th), np.cos(th)])
        p = ref + d[:, None] * normal
        c, sn = np.cos(-self.yaw), np.sin(-self.yaw)
        return np.column_stack([c * p[:, 0] - sn * p[:, 1], sn * p[:, 0] + c * p[:, 1]])

    def truth(self, j: int, step: float = 0.25) -> np.ndarray:
        """Dense visible polyline of marking j (monotone in x) [m], painted or not."""
        s = np.arange(-10.0, 320.0, step)
        p = self.curve(j, s)
        stop = np.nonzero(np.diff(p[:, 0]) <= 0)[0]
        if len(stop):
            p = p[: stop[0] + 1]
        return p

    def lateral_error(self, j: int, line: np.ndarray) -> np.ndarray:
        """|y - y_j(x)| of each point of ``line`` (K, 2) against marking j [m]."""
        t = self.truth(j)
        inside = (line[:, 0] >= t[0, 0]) & (line[:, 0] <= t[-1, 0])
        err = np.full(len(line), np.inf)
        err[inside] = np.abs(line[inside, 1] - np.interp(line[inside, 0], t[:, 0], t[:, 1]))
        return err


def sample(
    road: SynthRoad,
    *,
    noise: float = 0.0,
    dropout: float = 0.0,
    seed: int = 0,
    model: str = "per_dash",
    spacing: float = 2.0,
    x_range: float = RANGE,
) -> tuple[np.ndarray, np.ndarray]:
    """Points of the road as the line sensor would see them.

    :return: ``(points, object_id)``: ``(N, 3)`` (x, y, z) [m] and ``(N,)`` ids
        (per marking for ``"editor"``, per dash for ``"per_dash"``).
    """
    rng = np.random.default_rng(seed)
    pts: list[np.ndarray] = []
    ids: list[np.ndarray] = []
    next_id = 0
    for j, mk in enumerate(road.markings):
        phase = rng.uniform(0.0, spacing)
        s = np.arange(-20.0 + phase, 400.0, spacing)
        p = road.curve(j, s)
        stop = np.nonzero(np.diff(p[:, 0]) <= 0)[0]
        keep = np.ones(len(s), dtype=bool)
        if len(stop):
            keep[stop[0] + 1 :] = False
        keep &= (p[:, 0] >= FOV_START) & (p[:, 0] <= x_range)
        keep &= (s <= mk.end_s) & (s >= mk.start_s)
        piece = np.zeros(len(s), dtype=np.int64)
        if mk.dashed:
            u = s - mk.phase
            period = mk.dash + mk.gap
            keep &= np.mod(u, period) < mk.dash
            piece = np.floor(u / period).astype(np.int64)
        p, piece = p[keep], piece[keep]
        if len(p) == 0:
            continue
        if model == "per_dash":
            _, inv = np.unique(piece, return_inverse=True)
            oid = next_id + inv
        else:
            oid = np.full(len(p), next_id)
        next_id = int(oid.max()) + 1
        z = np.full(len(p), mk.z)
        pts.append(np.column_stack([p, z]))
        ids.append(oid)
    if not pts:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    points = np.concatenate(pts)
    oid = np.concatenate(ids)
    if noise > 0:
        points[:, 1] += rng.normal(0.0, noise, len(points))
    if dropout > 0:
        keep = rng.random(len(points)) >= dropout
        points, oid = points[keep], oid[keep]
    perm = rng.permutation(len(points))
    return points[perm], oid[perm]


def highway(
    *,
    lanes: int = 3,
    ego_lane: int = 1,
    lane_width: float = 3.75,
    radius: float = np.inf,
    lateral: float = 0.0,
    yaw: float = 0.0,
    phase: float = 0.0,
) -> SynthRoad:
    """A multi-lane highway, lane 0 leftmost; the car in ``ego_lane``.

    :param radius: signed curve radius [m], > 0 left curve, inf straight.
    :param lateral: the car's offset from its lane centre, left positive [m].
    :param phase: dash phase [m] (shifts where the dashes lie).
    """
    n = lanes
    marks = []
    for j in range(n + 1):
        off = (ego_lane + 0.5 - j) * lane_width - lateral
        marks.append(SynthMarking(off, dashed=0 < j < n, phase=phase))
    road = SynthRoad(marks, 0.0 if np.isinf(radius) or abs(radius) > 1e8 else 1.0 / radius, yaw)
    road.ego_left, road.ego_right = ego_lane, ego_lane + 1
    road.left_adjacent = ego_lane - 1 if ego_lane >= 1 else None
    road.right_adjacent = ego_lane + 2 if ego_lane + 2 <= n else None
    return road


def worst_case_fig45(radius: float = -500.0, lane_width: float = 3.75) -> SynthRoad:
    """The paper's worst case (§ALDM, Fig. 4–5): strongest allowed right curve, car at
    the leftmost position of its lane (tyres touching the left line), the nearest dash
    of the left (dashed) line just outside the field of view, so the nearest visible
    dash starts 12 m later. Two lanes, the car in the right one.
    """
    half_car = 0.9
    lateral = 0.5 * lane_width - half_car
    # dash ends at x = 5.5 (just before the field of view): start of next dash at 17.5
    road = highway(lanes=2, ego_lane=1, lane_width=lane_width, radius=radius, lateral=lateral)
    for mk in road.markings:
        mk.phase = 5.5 - 6.0
    return road


def grid_frame(
    n_lines: int,
    *,
    spacing: float = 3.5,
    radius: float = np.inf,
    seed: int = 0,
) -> np.ndarray:
    """Solid lines as CarMaker's line sensor samples them: every line at the sensor's x
    grid (``x = 5.52 + 2 p``, :attr:`~aldm_gym.sensor.line_sensor.LineSensorConfig.x_grid`),
    so the frame's x values tie exactly across lines, and on a straight road each
    line's y values tie too. No noise, no dropout; rows shuffled (seeded).

    :param n_lines: parallel lines, ``spacing`` [m] apart, centred on the sensor (an
        even count puts the sensor mid-lane).
    :param radius: signed curve radius [m], > 0 left; ``inf`` straight. A curved line
        is ``y = offset + x^2 / (2 radius)`` on the same x grid.
    :return: ``(n_lines * 98, 3)`` points (x, y, z = 0) [m].
    """
    from aldm_gym.sensor.line_sensor import LineSensorConfig

    x = LineSensorConfig().x_grid
    bend = np.zeros_like(x) if np.isinf(radius) else x * x / (2.0 * radius)
    lines = [
        np.column_stack([x, (j - 0.5 * (n_lines - 1)) * spacing + bend, np.zeros_like(x)])
        for j in range(n_lines)
    ]
    pts = np.concatenate(lines) if lines else np.zeros((0, 3))
    return pts[np.random.default_rng(seed).permutation(len(pts))]


def line_error(road: SynthRoad, j: int, line: np.ndarray) -> float:
    """Largest |y - y_true| of ``line`` against marking ``j`` [m]; inf when missing."""
    return float(road.lateral_error(j, line).max()) if len(line) >= 2 else math.inf


def lane_change_drive(
    update: Callable[[np.ndarray, EgoMotion | None], Any],
    *,
    frames: int = 70,
    speed: float = 25.0,
    dt: float = 0.1,
) -> Iterator[tuple[int, float, SynthRoad, np.ndarray, Any]]:
    """Straight 4-lane road; from frame 10 the car changes one lane to the left in 4 s
    (a sine yaw rate), with odometry from the same constant-turn model. ``update(points,
    motion)`` is a stateful detector's step; yields ``(k, lateral [m], road, points,
    detection)`` per frame."""
    width, duration = 3.75, 4.0
    amp = width * 2.0 * math.pi / (speed * duration**2)
    s0 = lateral = yaw = 0.0
    motion = None
    for k in range(frames):
        road = highway(lanes=4, ego_lane=2, lateral=lateral, yaw=yaw, phase=-s0)
        pts, _ = sample(road, noise=0.02, seed=k)
        yield k, lateral, road, pts, update(pts, motion)
        t = (k - 10) * dt
        rate = amp * math.sin(2.0 * math.pi * t / duration) if 0.0 <= t < duration else 0.0
        motion = EgoMotion(speed, rate, dt)
        dx, dy, dpsi = motion.displacement()
        s0 += dx * math.cos(yaw) - dy * math.sin(yaw)
        lateral += dx * math.sin(yaw) + dy * math.cos(yaw)
        yaw += dpsi
