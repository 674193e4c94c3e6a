"""Emulation of IPG CarMaker's line sensor on any marked road (:class:`~aldm_gym.roads.MarkedRoad`).

The sensor samples every painted marking (and barrier) at fixed x positions of its
own frame, from the field-of-view start (5.52 m) every ``dx`` (2 m) up to the range
of view (200 m): point ``p`` lies at ``x = fov_start + p * dx`` (paper §"Line Sensor
Model": "every increment of p means an increment of approximately 2 m in
x-direction"). A sampled point is seen when it lies inside the horizontal angle of
view, ``|y| <= x tan(fov_half_angle)`` (paper Fig. 1: "position, orientation and
angle of view"). Points are grouped into line objects according to the road's
marking model: one object per marking (``"editor"``) or one per dash
(``"per_dash"``), then assigned to a side by their first point, as CarMaker does:
right when it lies right of the car's middle axis, otherwise left.

Sampling the markings is a numba kernel of the road (``road.sample_visible``);
everything after it (paint pattern, noise, objects, sides, order, caps) is one numba
kernel here, ``_assemble`` (plain-Python reference ``_assemble_py``, umap habit). The
noise and dropout draws come from the generator as whole-grid arrays and enter the
kernel as data, so a seeded run repeats exactly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from aldm_gym.config import build_config, setting, validate
from aldm_gym.errors import ConfigError, InputError
from aldm_gym.roads.position import check_within_world
from aldm_gym.roads.protocol import MarkedRoad
from aldm_gym.sensor import conditions as cond
from aldm_gym.sensor.conditions import CELL, MAX_STRETCH
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.types import FloatArray

_NO_TURN = (0.0, 0.0, 0.0)
"""Default external rotation and travel (recognised by identity: no validation needed)."""
_NO_NOISE = np.zeros((3, 0, 0))
_NO_DRAW = np.zeros((0, 0))


CONDITIONS_OFF: dict[str, Any] = {
    "lateral_noise": 0.0,
    "longitudinal_noise": 0.0,
    "occlusion": False,
    "worn_dash_rate": 0.0,
    "worn_stretch_rate": 0.0,
    "worn_stretch_length": (20.0, 80.0),
    "lateral_noise_growth": 0.0,
    "visibility": None,
    "sight_clearance": None,
    "seam_rate": 0.0,
    "old_marking_rate": 0.0,
    "speck_rate": 0.0,
}
"""The preset-able fields of :class:`LineSensorConfig` and their values without a
preset: CarMaker's ideal sensor."""

PRESETS: dict[str, dict[str, Any]] = {
    "camera": {
        "occlusion": True,
        "worn_dash_rate": 0.05,
        "worn_stretch_rate": 1.0,
        "worn_stretch_length": (20.0, 60.0),
        "lateral_noise": 0.02,
        "lateral_noise_growth": 0.0005,
        "longitudinal_noise": 0.1,
        "visibility": 150.0,
        "seam_rate": 1.0,
        "old_marking_rate": 0.3,
        "speck_rate": 2.0,
    },
}
"""Named sets of values for the preset-able fields (``sensor={"preset": "camera"}``):
a camera-like sensor (``docs/sensor.md`` explains each value)."""


@dataclass(frozen=True)
class LineSensorConfig:
    """Line-sensor settings (defaults: the paper's CarMaker sensor).

    The field of view is the part of the road plane with ``fov_start <= x <= range``
    (x along the sensor's axis, the paper's "range of view in driving direction")
    and ``|y| <= x tan(fov_half_angle)`` (the horizontal angle of view of the paper's
    Fig. 1), optionally also ``|y| <= max_lateral``. The paper gives no value for the
    angle. The default half angle, 80°, sees 31 m to either side already at the
    field-of-view start and widens from there, so the markings of a curve stay in
    view out to the full range: in the paper's worst case (R = 500 m right curve) the
    ego lines are ~42 m to the right at x = 200 m. A fixed 30 m lateral band
    (``{"fov_half_angle": math.pi / 2, "max_lateral": 30.0}``) would cut those lines
    off at x ~ 170 m, where paper mode, having no gate, jumps to other markings.
    Visibility is decided on the noiseless position.

    Point ``p`` of a line lies at ``x = fov_start + p dx``, so ``p`` runs
    ``0 … ⌊(range − fov_start) / dx⌋`` (97 for the defaults; at most
    ``max_points_per_line − 1``). The paper writes ``0 … ⌊ld_range / 2⌋`` (100), counting
    x from the sensor; its ``p = 0`` is "the start of the sensor's field of view", so
    the grid here starts at ``fov_start`` = 5.52 m and the last point that still lies
    within the 200 m range is ``p = 97`` (x = 199.52 m).

    :ivar range: range of view ahead of the sensor, along its x axis [m] (``ld_range``,
        200 m).
    :ivar fov_start: x of the nearest detectable point [m] (5.52 m).
    :ivar dx: x spacing of the points of a line [m] (about 2 m).
    :ivar fov_half_angle: half the horizontal angle of view [rad] (default 80°); a point
        is seen when ``|y| <= x tan(fov_half_angle)``; pi/2 sets no angular limit.
    :ivar max_lateral: optional extra limit: largest |y| at which a point is seen [m];
        ``None`` (default): no lateral limit beyond the angle of view.
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
    :ivar lateral_noise: standard deviation of Gaussian noise on y [m] (σ₀ of the
        range-dependent noise; preset-able).
    :ivar longitudinal_noise: standard deviation of Gaussian noise on x [m]
        (longitudinal jitter; preset-able).
    :ivar height_noise: standard deviation of Gaussian noise on z [m].
    :ivar dropout: probability that a point is missing, independently per point.

    Sensor conditions beyond CarMaker (``docs/sensor.md``; all off by default). A
    preset-able field left ``None`` takes the preset's value, or its "off" value
    (:data:`CONDITIONS_OFF`) without a preset; a value given explicitly always wins.

    :ivar preset: ``None`` or ``"camera"`` (:data:`PRESETS`): a set of values for the
        preset-able fields.
    :ivar occlusion: hide points behind the vehicles passed to :meth:`LineSensor.measure`.
    :ivar worn_dash_rate: share of the dashes of broken markings that are worn away
        [-] (fixed per road).
    :ivar worn_stretch_rate: worn stretches per km of each painted marking [1/km]
        (fixed per road; at most 10).
    :ivar worn_stretch_length: (min, max) length of a worn stretch [m].
    :ivar wear_seed: another seed wears other dashes and stretches, and places other
        seams and old markings, on the same road.
    :ivar lateral_noise_growth: growth of the lateral noise with range: σ_y(x) =
        ``lateral_noise + lateral_noise_growth * x`` [m/m].
    :ivar visibility: x beyond which nothing is seen [m] (fog, glare; ``None``:
        the range).
    :ivar sight_clearance: distance of sight obstructions (barriers, cuttings,
        vegetation) beyond the road's outermost markings [m]: a point whose sight line
        from the sensor leaves that clear zone is hidden, so the range shrinks in bends
        (about ``sqrt(8 R d)`` for radius R and the sensor d from the zone's inner
        edge; :func:`~aldm_gym.sensor.conditions.sight_hidden`); ``None``: an open
        roadside.
    :ivar seam_rate: tar seams per km of each painted marking [1/km] (fixed per road).
    :ivar old_marking_rate: old markings per km of each painted marking [1/km] (fixed
        per road).
    :ivar speck_rate: mean number of random specks per frame [-] (Poisson).
    """

    range: float = setting(200.0, lo=0.0, lo_open=True, hi=1000.0)
    fov_start: float = setting(5.52, lo=0.0, hi="range")
    dx: float = setting(2.0, lo=0.1, hi=50.0)
    fov_half_angle: float = setting(math.radians(80.0), lo=0.0, lo_open=True, hi=math.pi / 2)
    max_lateral: float | None = setting(None, lo=0.0, lo_open=True, hi=1000.0, optional=True)
    max_lines_per_side: int = setting(100, lo=1, hi=100, integer=True)
    max_points_per_line: int = setting(200, lo=1, hi=200, integer=True)
    relevant_points: int = setting(30, lo=1, hi=200, integer=True)
    sensor_index: int = setting(0, lo=0, hi=15, integer=True)
    mount_x: float = setting(1.0, lo=-20.0, hi=20.0)
    mount_y: float = setting(0.0, lo=-20.0, hi=20.0)
    mount_z: float = setting(1.3, lo=0.0, hi=10.0)
    mount_roll: float = setting(0.0, lo=-2 * np.pi, hi=2 * np.pi)
    mount_pitch: float = setting(0.0, lo=-2 * np.pi, hi=2 * np.pi)
    mount_yaw: float = setting(0.0, lo=-2 * np.pi, hi=2 * np.pi)
    lateral_noise: float = setting(None, lo=0.0, hi=5.0, optional=True)
    longitudinal_noise: float = setting(None, lo=0.0, hi=5.0, optional=True)
    height_noise: float = setting(0.0, lo=0.0, hi=5.0)
    dropout: float = setting(0.0, lo=0.0, hi=1.0)
    preset: str | None = setting(None, choices=tuple(PRESETS), optional=True)
    occlusion: bool = setting(None, kind="bool", optional=True)
    worn_dash_rate: float = setting(None, lo=0.0, hi=1.0, optional=True)
    worn_stretch_rate: float = setting(None, lo=0.0, hi=1000.0 / CELL, optional=True)
    worn_stretch_length: tuple[float, float] = setting(
        None, kind="pair", lo=0.0, lo_open=True, hi=MAX_STRETCH, optional=True
    )
    wear_seed: int = setting(0, lo=0, hi=2**31 - 1, integer=True)
    lateral_noise_growth: float = setting(None, lo=0.0, hi=0.05, optional=True)
    visibility: float | None = setting(None, lo=0.0, lo_open=True, hi=1000.0, optional=True)
    sight_clearance: float | None = setting(None, lo=0.0, hi=1000.0, optional=True)
    seam_rate: float = setting(None, lo=0.0, hi=1000.0 / CELL, optional=True)
    old_marking_rate: float = setting(None, lo=0.0, hi=1000.0 / CELL, optional=True)
    speck_rate: float = setting(None, lo=0.0, hi=100.0, optional=True)

    def __post_init__(self) -> None:
        preset = self.preset
        if preset is not None and (not isinstance(preset, str) or preset not in PRESETS):
            raise ConfigError(f"sensor.preset must be one of {list(PRESETS)}, got {preset!r}")
        values = PRESETS[preset] if preset is not None else {}
        for name, off in CONDITIONS_OFF.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, values.get(name, off))
        validate(self, "sensor")
        if self.fov_start >= self.range:
            raise ConfigError(f"sensor.fov_start ({self.fov_start}) must be < range ({self.range})")
        if self.dropout >= 1.0:
            raise ConfigError("sensor.dropout must be < 1 (1 would drop every point)")

    @property
    def x_grid(self) -> FloatArray:
        """The x positions sampled along each line [m], at most ``max_points_per_line``."""
        k = int(np.floor((self.range - self.fov_start) / self.dx + 1e-9)) + 1
        k = min(k, self.max_points_per_line)
        return np.asarray(self.fov_start + self.dx * np.arange(k), dtype=np.float64)

    @property
    def tan_half_angle(self) -> float:
        """``tan(fov_half_angle)``, ``inf`` for pi/2 (no angular limit) [-]."""
        if self.fov_half_angle >= 0.5 * math.pi:
            return math.inf
        return math.tan(self.fov_half_angle)

    @property
    def noisy(self) -> bool:
        """Whether measuring draws random numbers."""
        return bool(
            self.lateral_noise
            or self.longitudinal_noise
            or self.height_noise
            or self.dropout
            or self.lateral_noise_growth
            or self.speck_rate
        )

    @property
    def worn(self) -> bool:
        """Whether paint wears (road-fixed)."""
        return bool(self.worn_dash_rate or self.worn_stretch_rate)

    @property
    def conditions(self) -> bool:
        """Whether any condition beyond CarMaker's noise and dropout is on."""
        return bool(
            self.occlusion
            or self.worn
            or self.lateral_noise_growth
            or self.visibility is not None
            or self.sight_clearance is not None
            or self.seam_rate
            or self.old_marking_rate
            or self.speck_rate
        )


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _vec3(value: Any, name: str) -> FloatArray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be 3 finite numbers, got {value!r}") from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be 3 finite numbers, got {value!r}")
    return arr


def _pose(pose: Any) -> tuple[float, float, float]:
    """``(x, y, heading)`` from a tuple/array or a highway-env vehicle."""
    try:
        return _pose_numbers(pose)
    except (TypeError, ValueError) as exc:
        if str(exc).startswith("pose"):
            raise
        raise InputError(f"pose must be (x [m], y [m], heading [rad]), got {pose!r}") from None


def _pose_numbers(pose: Any) -> tuple[float, float, float]:
    if type(pose) is tuple and len(pose) == 3:
        x, y, h = float(pose[0]), float(pose[1]), float(pose[2])
    elif hasattr(pose, "position") and hasattr(pose, "heading"):
        x, y = np.asarray(pose.position, dtype=np.float64)[:2]
        h = float(pose.heading)
    else:
        arr = np.asarray(pose, dtype=np.float64)
        if arr.shape != (3,):
            raise InputError(f"pose must be (x [m], y [m], heading [rad]), got shape {arr.shape}")
        x, y, h = arr
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(h)):
        raise InputError(f"pose must be finite, got {(x, y, h)}")
    check_within_world("pose", x, y, (x, y, h))
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
        c = self.config
        self._xs = c.x_grid
        self._rng = np.random.default_rng(seed)
        self._noise_std = np.array([c.lateral_noise, c.longitudinal_noise, c.height_noise])
        self._mount_cos = float(np.cos(c.mount_yaw))
        self._mount_sin = float(np.sin(c.mount_yaw))
        self._tan_half = c.tan_half_angle
        self._max_lateral = math.inf if c.max_lateral is None else float(c.max_lateral)
        self._axis_y = self.middle_axis_y()

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
            cy, sy = self._mount_cos, self._mount_sin
            tx = cy * float(ext_travel[0]) - sy * float(ext_travel[1])
            ty = sy * float(ext_travel[0]) + cy * float(ext_travel[1])
        ch, sh = float(np.cos(h)), float(np.sin(h))
        a, b = c.mount_x + tx, c.mount_y + ty
        # Forward is (cos h, sin h); the driver's left in highway-env's world is
        # (sin h, -cos h). Scalar form of `(x, y) + a * fwd + b * left`, same operations.
        origin = np.array([(x + a * ch) + b * sh, (y + a * sh) + b * -ch])
        return origin, h - (c.mount_yaw + ext_yaw)

    def middle_axis_y(self, ext_travel: FloatArray | None = None, ext_yaw: float = 0.0) -> float:
        """y of the car's middle axis in the sensor frame, at the sensor [m].

        CarMaker judges sides against "the middle axis of the car" (paper §"Line Sensor
        Model"), not the sensor's own axis: a point's side offset is ``y - axis_y``.
        The sensor sits ``mount_y`` (plus any external travel) left of that axis, so
        ``axis_y = -mount_y`` for a forward sensor and ``+mount_y`` for a backward one
        (``mount_yaw = pi``: its y axis points to the car's right). For other yaw
        angles the axis is taken parallel to the sensor's x axis, at the sensor's
        lateral offset projected on its y axis (``-lateral cos(yaw)``).

        :param ext_travel: additional external travel (x, y, z) in the mount frame [m].
        :param ext_yaw: additional external yaw [rad].
        """
        c = self.config
        lateral = c.mount_y
        if ext_travel is not None:
            lateral = lateral + (
                self._mount_sin * float(ext_travel[0]) + self._mount_cos * float(ext_travel[1])
            )
        cos_yaw = self._mount_cos if ext_yaw == 0.0 else float(np.cos(c.mount_yaw + ext_yaw))
        return -lateral * cos_yaw

    def measure(
        self,
        road: MarkedRoad,
        pose: Any,
        t: float = 0.0,
        *,
        rng: np.random.Generator | None = None,
        ext_rotation: Any = _NO_TURN,
        ext_travel: Any = _NO_TURN,
        s_hint: float | None = None,
        occluders: Any = None,
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
        :param occluders: with ``occlusion`` on, the vehicles whose footprints hide
            markings: highway-env vehicles or an ``(V, 6)`` array of world ``(x, y,
            heading, length, width, height)`` (see
            :func:`~aldm_gym.sensor.conditions.occluder_array`); the ego may be among
            them (a footprint holding the sensor hides nothing).
        :return: the frame.
        """
        if not hasattr(road, "sample_visible"):
            raise TypeError(
                f"road must be a marked road (HighwayRoad, OpenDriveRoad, PolylineRoad), "
                f"got {type(road).__name__}"
            )
        if not (_is_number(t) and math.isfinite(t)):
            raise InputError(f"t must be a finite number [s], got {t!r}")
        if s_hint is not None and not _is_number(s_hint):
            raise InputError(f"s_hint must be a number [m] or None, got {s_hint!r}")
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy Generator or None, got {type(rng).__name__}")
        c = self.config
        rot = np.zeros(3) if ext_rotation is _NO_TURN else _vec3(ext_rotation, "ext_rotation")
        travel = np.zeros(3) if ext_travel is _NO_TURN else _vec3(ext_travel, "ext_travel")
        origin, yaw = self.world_pose(pose, travel, float(rot[2]))
        if ext_travel is _NO_TURN and ext_rotation is _NO_TURN:
            axis_y = self._axis_y
        else:
            axis_y = self.middle_axis_y(travel, float(rot[2]))
        xs = self._xs
        rows, ys, us = road.sample_visible(origin, yaw, xs, s_hint)
        gen = rng if rng is not None else self._rng
        if c.noisy:
            # Draw for the whole grid so the stream does not depend on what is visible.
            noise = gen.standard_normal((3, *ys.shape))
            draw = gen.random(ys.shape)
        else:
            noise, draw = _NO_NOISE, _NO_DRAW
        tab = road.marking_table
        noise_std = self._noise_std
        n_markings = len(tab["height"])
        bridges = getattr(road, "overpass_lines", None)
        if c.conditions or (bridges is not None and len(bridges)):
            rows, ys, us, tab, noise, draw, noise_std = self._conditions(
                road, tab, rows, ys, us, origin, yaw, occluders, gen, noise, draw, bridges
            )
        points, line_start, mk, piece, n_left, rel_left, rel_right = _assemble(
            xs,
            ys,
            us,
            tab["height"],
            tab["phase"],
            tab["period"],
            tab["dash"],
            tab["broken"],
            tab["paint"],
            tab["paint_start"],
            rows,
            road.marking_model == "per_dash",
            self._tan_half,
            self._max_lateral,
            axis_y,
            noise,
            draw,
            noise_std,
            c.dropout,
            c.max_lines_per_side,
        )
        if len(tab["height"]) > n_markings:
            # Clutter, specks and bridge markings are no marking of this road.
            mk_truth = np.where(mk < n_markings, mk, -1)
        else:
            mk_truth = mk
        return SensorFrame(
            timestamp=float(t),
            sensor_index=c.sensor_index,
            all_points=points,
            line_start=line_start,
            line_type=tab["type"][mk],
            line_colour=tab["colour"][mk],
            line_height=tab["height"][mk],
            line_width=tab["width"][mk],
            line_marking=mk_truth,
            line_piece=piece,
            n_left=n_left,
            relevant_left=rel_left,
            relevant_right=rel_right,
            relevant_points=c.relevant_points,
            mount_position=np.array([c.mount_x, c.mount_y, c.mount_z]),
            mount_rotation=np.array([c.mount_roll, c.mount_pitch, c.mount_yaw]),
            ext_rotation=rot,
            ext_travel=travel,
            origin=origin,
            yaw=float(yaw),
            range=c.range,
            fov_start=c.fov_start,
            fov_half_angle=c.fov_half_angle,
            max_lateral=self._max_lateral,
            axis_y=axis_y,
            occluders=(
                cond.occluder_array(occluders).copy()
                if c.occlusion and occluders is not None
                else np.zeros((0, 6))
            ),
        )

    def _conditions(
        self,
        road: Any,
        tab: dict[str, np.ndarray],
        rows: np.ndarray,
        ys: FloatArray,
        us: FloatArray,
        origin: FloatArray,
        yaw: float,
        occluders: Any,
        gen: np.random.Generator,
        noise: FloatArray,
        draw: FloatArray,
        bridges: FloatArray | None,
    ) -> tuple[
        np.ndarray,
        FloatArray,
        FloatArray,
        dict[str, np.ndarray],
        FloatArray,
        FloatArray,
        FloatArray,
    ]:
        """The sensor conditions on the sampled grid (``docs/sensor.md``).

        Extra rows (seams, old markings, bridge markings, specks) become virtual
        markings appended to the marking table (continuous, one object each); masks
        (worn paint, visibility, occlusion) set hidden points' y to NaN, on the
        noiseless positions. Generator draws, after the grid's noise: specks, then the
        extra rows' noise.

        :return: ``(rows, ys, us, table, noise, draw, noise_std)`` for ``_assemble``.
        """
        c = self.config
        xs = self._xs
        k = len(xs)
        height = tab["height"]
        road_ys = ys  # the markings' own positions, before wear (the roadside's bounds)
        ys = ys.copy()
        key = 0
        if c.worn or c.seam_rate or c.old_marking_rate:
            key = cond.road_key(road, c.wear_seed)
        extra_y: list[FloatArray] = []
        extra_z: list[FloatArray] = []
        if c.seam_rate or c.old_marking_rate:
            cy, _ = cond._clutter(
                ys, us, rows, height, key, c.seam_rate / 1000.0, c.old_marking_rate / 1000.0
            )
            extra_y.append(cy)
            extra_z.append(np.zeros(len(cy)))
        if bridges is not None and len(bridges):
            by, bz = cond.overpass_rows(np.asarray(bridges, dtype=np.float64), origin, yaw, xs)
            extra_y.append(by)
            extra_z.append(bz)
        if c.speck_rate:
            n = int(gen.poisson(c.speck_rate))
            at = gen.integers(0, k, n)
            sy = np.full((n, k), np.nan)
            sy[np.arange(n), at] = gen.uniform(-cond.SPECK_BAND, cond.SPECK_BAND, n)
            extra_y.append(sy)
            extra_z.append(np.zeros(n))
        if c.worn:
            cond._wear(
                ys,
                us,
                rows,
                height,
                tab["phase"],
                tab["period"],
                tab["broken"],
                tab["paint"],
                tab["paint_start"],
                key,
                c.worn_dash_rate,
                c.worn_stretch_rate / 1000.0,
                c.worn_stretch_length[0],
                c.worn_stretch_length[1],
            )
        n_extra = sum(len(e) for e in extra_y)
        m = len(height)
        if n_extra:
            ys = np.vstack([ys, *extra_y])
            us = np.vstack([us, np.zeros((n_extra, k))])
            rows = np.concatenate([rows, m + np.arange(n_extra, dtype=np.int64)])
            z_extra = np.concatenate(extra_z)
            tab = _with_virtual(tab, z_extra)
            if c.noisy:
                noise = np.concatenate([noise, gen.standard_normal((3, n_extra, k))], axis=1)
                draw = np.vstack([draw, gen.random((n_extra, k))])
        if c.visibility is not None:
            ys[:, xs > c.visibility] = np.nan
        if c.sight_clearance is not None:
            # The road's own markings set the clear zone; everything on the road (not
            # a bridge) behind the roadside is hidden, on the noiseless positions.
            ground = tab["height"][rows] <= cond.GROUND_BAND
            hidden = cond.sight_hidden(xs, ys, road_ys, c.sight_clearance)
            ys[hidden & ground[:, None]] = np.nan
        if c.occlusion and occluders is not None:
            world = cond.occluder_array(occluders)
            if len(world):
                reach = c.range + 10.0  # a point in range, behind half an 18 m truck
                z = tab["height"][rows]
                cond._occlude(xs, ys, z, world, origin[0], origin[1], yaw, reach, c.mount_z)
        noise_std = self._noise_std
        if c.lateral_noise_growth and noise.shape[1]:
            # sigma_y(x) = sigma_0 + k x: scale the draws, unit weight in the kernel.
            noise = noise.copy()
            noise[0] *= c.lateral_noise + c.lateral_noise_growth * xs
            noise_std = np.array([1.0, noise_std[1], noise_std[2]])
        return rows, ys, us, tab, noise, draw, noise_std


def _with_virtual(tab: dict[str, np.ndarray], z: FloatArray) -> dict[str, np.ndarray]:
    """The marking table with ``len(z)`` virtual markings appended: continuous, white,
    0.15 m wide, at height ``z`` [m], no explicit paint (clutter, specks, bridges)."""
    n = len(z)
    ps = tab["paint_start"]
    return {
        "type": np.concatenate([tab["type"], np.ones(n, dtype=np.int64)]),
        "colour": np.concatenate([tab["colour"], np.zeros(n, dtype=np.int64)]),
        "height": np.concatenate([tab["height"], z]),
        "width": np.concatenate([tab["width"], np.full(n, 0.15)]),
        "dash": np.concatenate([tab["dash"], np.zeros(n)]),
        "period": np.concatenate([tab["period"], np.ones(n)]),
        "phase": np.concatenate([tab["phase"], np.zeros(n)]),
        "broken": np.concatenate([tab["broken"], np.zeros(n, dtype=bool)]),
        "paint": tab["paint"],
        "paint_start": np.concatenate([ps, np.full(n, ps[-1], dtype=ps.dtype)]),
    }


def _assemble_py(
    xs: FloatArray,
    ys: FloatArray,
    us: FloatArray,
    height: FloatArray,
    phase: FloatArray,
    period: FloatArray,
    dash: FloatArray,
    broken: np.ndarray,
    paint: FloatArray,
    paint_start: np.ndarray,
    rows: np.ndarray,
    per_dash: bool,
    tan_half: float,
    max_lateral: float,
    axis_y: float,
    noise: FloatArray,
    draw: FloatArray,
    noise_std: FloatArray,
    dropout: float,
    max_lines: int,
) -> tuple[FloatArray, np.ndarray, np.ndarray, np.ndarray, int, int, int]:
    """One frame from the sampled markings: paint, noise, objects, sides, order, caps.

    Plain-Python reference of ``_assemble`` (umap habit: same code, compiled once).

    :param xs: ``(K,)`` x grid of the sensor [m].
    :param ys: ``(R, K)`` noiseless y of marking ``rows[r]`` at ``xs[p]`` [m], NaN where
        absent.
    :param us: ``(R, K)`` arc length along that marking there [m].
    :param height: ``(M,)`` marking heights [m]; ``phase``, ``period``, ``dash``
        ``(M,)`` its dash pattern [m]; ``broken`` ``(M,)`` whether it is dashed.
    :param paint: ``(P, 2)`` explicit painted intervals of arc length [m];
        ``paint_start`` ``(M + 1,)``: marking ``j`` owns rows
        ``paint_start[j]:paint_start[j + 1]``. A marking with explicit intervals is
        painted exactly there (each interval a piece); else by its periodic pattern.
    :param rows: ``(R,)`` the marking index of each row of ``ys``/``us``.
    :param per_dash: one object per painted piece of a broken marking, or of a
        marking with explicit intervals (else one per marking).
    :param tan_half: tangent of the half angle of view; a point is seen where the
        noiseless ``|y| <= x tan_half`` (``inf``: no angular limit).
    :param max_lateral: largest noiseless |y| seen [m] (``inf``: no limit).
    :param axis_y: y of the car's middle axis [m]: an object is left when its first
        point has ``y - axis_y >= 0`` ("right of the middle axis ... right side,
        otherwise left"), and the relevant line is the one nearest to that axis.
    :param noise: ``(3, M, K)`` standard normal draws for (y, x, z), or ``(3, 0, 0)``
        for a noiseless sensor.
    :param draw: ``(M, K)`` uniform draws, a point is kept when ``draw >= dropout``; or
        ``(0, 0)`` for a noiseless sensor.
    :param noise_std: ``(3,)`` standard deviations of the noise on (y, x, z) [m].
    :param dropout: dropout probability.
    :param max_lines: cap on objects per side.
    :return: ``(all_points (N, 3), line_start (L + 1,), marking (L,), piece (L,),
        n_left, relevant_left, relevant_right)`` as in :class:`SensorFrame`.
    """
    m, k = ys.shape
    noisy = draw.shape[0] > 0
    # Pass 1, marking-major with x increasing: visible points, and a new object
    # wherever the marking, or for per-dash roads the dash, changes.
    px = np.empty(m * k)
    py = np.empty(m * k)
    pz = np.empty(m * k)
    obj_first = np.empty(m * k + 1, dtype=np.int64)
    obj_mark = np.empty(m * k, dtype=np.int64)
    obj_piece = np.empty(m * k)
    n = 0
    n_obj = 0
    last_j = -1
    last_pid = 0.0
    for r in range(m):
        j = rows[r]
        a = paint_start[j]
        b = paint_start[j + 1]
        explicit = b > a
        split = per_dash and (broken[j] or explicit)
        for p in range(k):
            # Paint along the marking (arc length u): piece index and on/off.
            piece = -1.0
            if explicit:
                uq = us[r, p]
                if not (uq == uq):  # NaN: the marking does not reach xs[p]
                    continue
                lo = a
                hi = b
                while lo < hi:  # the last interval starting at or before u
                    mid = (lo + hi) // 2
                    if paint[mid, 0] <= uq:
                        lo = mid + 1
                    else:
                        hi = mid
                q = lo - 1
                if q < a or not (uq < paint[q, 1]):
                    continue
                piece = float(q - a)
            elif broken[j]:
                rel_u = (us[r, p] - phase[j]) / period[j]
                piece = np.floor(rel_u)
                if not ((rel_u - piece) * period[j] < dash[j]):  # NaN: not painted
                    continue
            y = ys[r, p]
            if not (abs(y) <= max_lateral):  # NaN: the marking does not reach xs[p]
                continue
            x = xs[p]
            # Angle of view (paper Fig. 1); inf * 0 would be NaN at x = 0, so no test.
            if tan_half < np.inf and not (abs(y) <= x * tan_half):
                continue
            z = height[j]
            if noisy:
                if not (draw[r, p] >= dropout):
                    continue
                y = y + noise_std[0] * noise[0, r, p]
                x = x + noise_std[1] * noise[1, r, p]
                z = z + noise_std[2] * noise[2, r, p]
            pid = piece if split else -1.0
            if j != last_j or pid - last_pid != 0.0:
                obj_first[n_obj] = n
                obj_mark[n_obj] = j
                obj_piece[n_obj] = pid
                n_obj += 1
                last_j = j
                last_pid = pid
            px[n] = x
            py[n] = y
            pz[n] = z
            n += 1
    obj_first[n_obj] = n
    # Order: left side first (first point on or left of the middle axis: the paper's
    # "right of the middle axis ... right side, otherwise to the left"); within a
    # side by first x, then by the first point's distance to the axis; ties keep the
    # pass-1 order (a stable insertion sort; tens of objects).
    order = np.arange(n_obj)
    for i in range(1, n_obj):
        b = order[i]
        fb = obj_first[b]
        left_b = py[fb] - axis_y >= 0.0
        q = i - 1
        while q >= 0:
            fa = obj_first[order[q]]
            left_a = py[fa] - axis_y >= 0.0
            if left_a != left_b:
                after = left_b
            elif px[fa] != px[fb]:
                after = px[fa] > px[fb]
            else:
                after = abs(py[fa] - axis_y) > abs(py[fb] - axis_y)
            if not after:
                break
            order[q + 1] = order[q]
            q -= 1
        order[q + 1] = b
    n_left_all = 0
    for i in range(n_obj):
        if py[obj_first[i]] - axis_y >= 0.0:
            n_left_all += 1
    # Caps: the first max_lines objects of each side.
    n_left = min(n_left_all, max_lines)
    n_right = min(n_obj - n_left_all, max_lines)
    n_keep = n_left + n_right
    keep = np.empty(n_keep, dtype=np.int64)
    keep[:n_left] = order[:n_left]
    keep[n_left:] = order[n_left_all : n_left_all + n_right]
    line_start = np.empty(n_keep + 1, dtype=np.int64)
    line_start[0] = 0
    for i in range(n_keep):
        o = keep[i]
        line_start[i + 1] = line_start[i] + obj_first[o + 1] - obj_first[o]
    points = np.empty((line_start[n_keep], 3))
    marking = np.empty(n_keep, dtype=np.int64)
    pieces = np.empty(n_keep, dtype=np.int64)
    for i in range(n_keep):
        o = keep[i]
        marking[i] = obj_mark[o]
        pieces[i] = np.int64(obj_piece[o])
        dst = line_start[i]
        for src in range(obj_first[o], obj_first[o + 1]):
            points[dst, 0] = px[src]
            points[dst, 1] = py[src]
            points[dst, 2] = pz[src]
            dst += 1
    # Relevant line of a side: its first point nearest to the middle axis (the first
    # one on ties).
    rel_left = -1
    rel_right = -1
    for i in range(n_keep):
        ay = abs(points[line_start[i], 1] - axis_y)
        if i < n_left:
            if rel_left < 0 or ay < abs(points[line_start[rel_left], 1] - axis_y):
                rel_left = i
        elif rel_right < 0 or ay < abs(points[line_start[n_left + rel_right], 1] - axis_y):
            rel_right = i - n_left
    return points, line_start, marking, pieces, n_left, rel_left, rel_right


_assemble = numba.njit(cache=True)(_assemble_py)
