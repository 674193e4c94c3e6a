"""Emulation of IPG CarMaker's line sensor on a :class:`~aldm_gym.roads.HighwayRoad`.

The sensor samples every painted marking (and barrier) at fixed x positions of its
own frame, from the field-of-view start (5.52 m) every ``dx`` (2 m) up to the range
of view (200 m): point ``p`` lies at ``x = fov_start + p * dx`` (paper §"Line Sensor
Model": "every increment of p means an increment of approximately 2 m in
x-direction"). Points are grouped into line objects according to the road's
marking model: one object per marking (``"editor"``) or one per dash
(``"per_dash"``), then assigned to a side by their first point, as CarMaker does.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.config import build_config, check_range
from aldm_gym.roads.highway import HighwayRoad
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.types import FloatArray


@dataclass(frozen=True)
class LineSensorConfig:
    """Line-sensor settings (defaults: the paper's CarMaker sensor).

    :ivar range: range of view ahead of the sensor [m] (``ld_range``, 200 m).
    :ivar fov_start: x of the nearest detectable point [m] (5.52 m).
    :ivar dx: x spacing of the points of a line [m] (about 2 m).
    :ivar max_lateral: largest |y| at which a point is seen [m].
    :ivar max_lines_per_side: cap on objects per side (CarMaker: 100).
    :ivar max_points_per_line: cap on points per object (CarMaker: 200).
    :ivar relevant_points: length of the relevant-line point list (CarMaker: 30).
    :ivar sensor_index: ``m``: 0 forward sensor, 1 backward sensor.
    :ivar mount_x: sensor position ahead of the vehicle centre [m].
    :ivar mount_y: sensor position left of the vehicle centre [m].
    :ivar mount_z: sensor height above the road [m].
    :ivar mount_roll: mount roll [rad] (recorded; the road is flat).
    :ivar mount_pitch: mount pitch [rad] (recorded; the road is flat).
    :ivar mount_yaw: mount yaw [rad]; pi for a backward-looking sensor.
    :ivar lateral_noise: standard deviation of Gaussian noise on y [m].
    :ivar longitudinal_noise: standard deviation of Gaussian noise on x [m].
    :ivar height_noise: standard deviation of Gaussian noise on z [m].
    :ivar dropout: probability that a point is missing, independently per point.
    """

    range: float = 200.0
    fov_start: float = 5.52
    dx: float = 2.0
    max_lateral: float = 30.0
    max_lines_per_side: int = 100
    max_points_per_line: int = 200
    relevant_points: int = 30
    sensor_index: int = 0
    mount_x: float = 1.0
    mount_y: float = 0.0
    mount_z: float = 1.3
    mount_roll: float = 0.0
    mount_pitch: float = 0.0
    mount_yaw: float = 0.0
    lateral_noise: float = 0.0
    longitudinal_noise: float = 0.0
    height_noise: float = 0.0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        w = "sensor"
        check_range(w, "range", self.range, 0.0, 1000.0, lo_open=True)
        check_range(w, "fov_start", self.fov_start, 0.0, self.range)
        if self.fov_start >= self.range:
            raise ValueError(f"sensor.fov_start ({self.fov_start}) must be < range ({self.range})")
        check_range(w, "dx", self.dx, 0.1, 50.0)
        check_range(w, "max_lateral", self.max_lateral, 0.0, 200.0, lo_open=True)
        check_range(w, "max_lines_per_side", self.max_lines_per_side, 1, 100, integer=True)
        check_range(w, "max_points_per_line", self.max_points_per_line, 1, 200, integer=True)
        check_range(w, "relevant_points", self.relevant_points, 1, 200, integer=True)
        check_range(w, "sensor_index", self.sensor_index, 0, 15, integer=True)
        for name in ("mount_x", "mount_y"):
            check_range(w, name, getattr(self, name), -20.0, 20.0)
        check_range(w, "mount_z", self.mount_z, 0.0, 10.0)
        for name in ("mount_roll", "mount_pitch", "mount_yaw"):
            check_range(w, name, getattr(self, name), -2 * np.pi, 2 * np.pi)
        for name in ("lateral_noise", "longitudinal_noise", "height_noise"):
            check_range(w, name, getattr(self, name), 0.0, 5.0)
        check_range(w, "dropout", self.dropout, 0.0, 1.0)
        if self.dropout >= 1.0:
            raise ValueError("sensor.dropout must be < 1 (1 would drop every point)")

    @property
    def x_grid(self) -> FloatArray:
        """The x positions sampled along each line [m], at most ``max_points_per_line``."""
        k = int(np.floor((self.range - self.fov_start) / self.dx + 1e-9)) + 1
        k = min(k, self.max_points_per_line)
        return np.asarray(self.fov_start + self.dx * np.arange(k), dtype=np.float64)

    @property
    def noisy(self) -> bool:
        """Whether measuring draws random numbers."""
        return bool(
            self.lateral_noise or self.longitudinal_noise or self.height_noise or self.dropout
        )


def _vec3(value: Any, name: str) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return arr


def _pose(pose: Any) -> tuple[float, float, float]:
    """``(x, y, heading)`` from a tuple/array or a highway-env vehicle."""
    if hasattr(pose, "position") and hasattr(pose, "heading"):
        x, y = np.asarray(pose.position, dtype=np.float64)[:2]
        h = float(pose.heading)
    else:
        arr = np.asarray(pose, dtype=np.float64)
        if arr.shape != (3,):
            raise ValueError(f"pose must be (x [m], y [m], heading [rad]), got shape {arr.shape}")
        x, y, h = arr
    if not np.all(np.isfinite([x, y, h])):
        raise ValueError(f"pose must be finite, got {(x, y, h)}")
    return float(x), float(y), float(h)


class LineSensor:
    """A CarMaker-like line sensor.

    :param config: a :class:`LineSensorConfig`, a mapping of its fields, or ``None``.
    :param seed: seed of the sensor's own random generator (noise, dropout); pass
        ``rng`` to :meth:`measure` instead to draw from an environment's generator.

    Example::

        road = HighwayRoad({"marking_model": "per_dash"})
        sensor = LineSensor({"lateral_noise": 0.05})
        frame = sensor.measure(road, (x, y, heading), t=0.0)
        frame.left.n_lines, frame.points().shape
    """

    def __init__(
        self, config: LineSensorConfig | Mapping[str, Any] | None = None, seed: int | None = None
    ) -> None:
        self.config: LineSensorConfig = build_config(LineSensorConfig, config, where="sensor")
        self._xs = self.config.x_grid
        self._rng = np.random.default_rng(seed)

    def seed(self, seed: int | None) -> None:
        """Reseed the sensor's own random generator."""
        self._rng = np.random.default_rng(seed)

    def world_pose(
        self, pose: Any, ext_travel: FloatArray | None = None, ext_yaw: float = 0.0
    ) -> tuple[FloatArray, float]:
        """World position (2,) [m] and heading [rad] of the sensor on a vehicle at ``pose``."""
        c = self.config
        x, y, h = _pose(pose)
        tx = ty = 0.0
        if ext_travel is not None:
            # External travel is expressed in the mount frame: rotate by the mount yaw.
            cy, sy = np.cos(c.mount_yaw), np.sin(c.mount_yaw)
            tx = cy * ext_travel[0] - sy * ext_travel[1]
            ty = sy * ext_travel[0] + cy * ext_travel[1]
        fwd = np.array([np.cos(h), np.sin(h)])
        left = np.array([np.sin(h), -np.cos(h)])  # driver's left in highway-env's world
        origin = np.array([x, y]) + (c.mount_x + tx) * fwd + (c.mount_y + ty) * left
        # Yaw to the left is a negative world heading change (see roads.geometry).
        return origin, h - (c.mount_yaw + ext_yaw)

    def measure(
        self,
        road: HighwayRoad,
        pose: Any,
        t: float = 0.0,
        *,
        rng: np.random.Generator | None = None,
        ext_rotation: Any = (0.0, 0.0, 0.0),
        ext_travel: Any = (0.0, 0.0, 0.0),
        s_hint: float | None = None,
    ) -> SensorFrame:
        """Measure the road's markings from a vehicle at ``pose``.

        :param road: the road.
        :param pose: vehicle ``(x [m], y [m], heading [rad])`` in the world frame, or a
            highway-env vehicle.
        :param t: time stamp [s].
        :param rng: random generator for noise and dropout (default: the sensor's own).
        :param ext_rotation: additional external rotation (roll, pitch, yaw) in the mount
            frame [rad]; yaw turns the sensor, roll and pitch are recorded only.
        :param ext_travel: additional external travel (x, y, z) in the mount frame [m].
        :param s_hint: the sensor's reference arc length, if already known [m].
        :return: the frame.
        """
        if not isinstance(road, HighwayRoad):
            raise TypeError(f"road must be a HighwayRoad, got {type(road).__name__}")
        if not np.isfinite(t):
            raise ValueError(f"t must be finite, got {t}")
        c = self.config
        rot = _vec3(ext_rotation, "ext_rotation")
        travel = _vec3(ext_travel, "ext_travel")
        origin, yaw = self.world_pose(pose, travel, float(rot[2]))
        xs = self._xs
        ys, us = road.sample_markings(origin, yaw, xs, s_hint)
        tab = road.marking_table
        m, k = ys.shape
        # Paint pattern along each marking (arc length u): dash index and on/off.
        with np.errstate(invalid="ignore"):
            rel_u = (us - tab["phase"][:, None]) / tab["period"][:, None]
            piece = np.floor(rel_u)
            on = ~tab["broken"][:, None] | (
                (rel_u - piece) * tab["period"][:, None] < tab["dash"][:, None]
            )
            visible = on & (np.abs(ys) <= c.max_lateral)  # NaN compares False
        px = np.broadcast_to(xs, (m, k)).copy()
        pz = np.broadcast_to(tab["height"][:, None], (m, k)).copy()
        if c.noisy:
            gen = rng if rng is not None else self._rng
            # Draw for the whole grid so the stream does not depend on what is visible.
            noise = gen.standard_normal((3, m, k))
            keep = gen.random((m, k)) >= c.dropout
            ys = ys + c.lateral_noise * noise[0]
            px = px + c.longitudinal_noise * noise[1]
            pz = pz + c.height_noise * noise[2]
            visible &= keep
        return self._assemble(
            road, visible, px, ys, pz, piece, float(t), rot, travel, origin, float(yaw)
        )

    def _assemble(
        self,
        road: HighwayRoad,
        visible: np.ndarray,
        px: FloatArray,
        py: FloatArray,
        pz: FloatArray,
        piece: FloatArray,
        t: float,
        rot: FloatArray,
        travel: FloatArray,
        origin: FloatArray,
        yaw: float,
    ) -> SensorFrame:
        """Group visible points into objects, assign sides, order and cap them."""
        c = self.config
        k = visible.shape[1]
        per_dash = road.marking_model == "per_dash"
        tab = road.marking_table
        broken = tab["broken"]
        flat = np.flatnonzero(visible.ravel())  # marking-major, x increasing
        j_of = flat // k
        # Object key: the marking, and for per-dash roads also the dash.
        pc = piece.ravel()[flat]
        split_piece = per_dash & broken[j_of]
        pid = np.where(split_piece, pc, -1.0)
        if len(flat):
            new = np.concatenate([[True], (np.diff(j_of) != 0) | (np.diff(pid) != 0)])
        else:
            new = np.zeros(0, dtype=bool)
        starts = np.flatnonzero(new)
        counts = np.diff(np.append(starts, len(flat)))
        obj_j = j_of[starts]
        pts = np.column_stack([px.ravel()[flat], py.ravel()[flat], pz.ravel()[flat]])
        first = pts[starts] if len(starts) else np.zeros((0, 3))
        is_left = first[:, 1] > 0.0
        # Order: left side first; within a side by first x, then by |first y|.
        order = np.lexsort((np.abs(first[:, 1]), first[:, 0], ~is_left))
        n_left_all = int(is_left.sum())
        cap = c.max_lines_per_side
        keep = np.concatenate([order[: min(n_left_all, cap)], order[n_left_all:][:cap]])
        n_left = min(n_left_all, cap)
        counts_k = counts[keep]
        line_start = np.concatenate([[0], np.cumsum(counts_k)]).astype(np.int64)
        # Gather the points of the kept objects in their new order.
        idx = np.repeat(starts[keep] - line_start[:-1], counts_k) + np.arange(line_start[-1])
        all_points = pts[idx]
        first_k = first[keep]
        rel = [-1, -1]
        for side, (lo, hi) in enumerate(((0, n_left), (n_left, len(keep)))):
            if hi > lo:
                rel[side] = int(np.argmin(np.abs(first_k[lo:hi, 1])))
        mk_j = obj_j[keep]
        return SensorFrame(
            timestamp=t,
            sensor_index=c.sensor_index,
            all_points=all_points,
            line_start=line_start,
            line_type=tab["type"][mk_j],
            line_colour=tab["colour"][mk_j],
            line_height=tab["height"][mk_j],
            line_width=tab["width"][mk_j],
            line_marking=mk_j.astype(np.int64),
            line_piece=pid[starts][keep].astype(np.int64),
            n_left=n_left,
            relevant_left=rel[0],
            relevant_right=rel[1],
            relevant_points=c.relevant_points,
            mount_position=np.array([c.mount_x, c.mount_y, c.mount_z]),
            mount_rotation=np.array([c.mount_roll, c.mount_pitch, c.mount_yaw]),
            ext_rotation=rot,
            ext_travel=travel,
            origin=origin,
            yaw=yaw,
            range=c.range,
            fov_start=c.fov_start,
        )
