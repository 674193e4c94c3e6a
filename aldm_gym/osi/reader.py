"""OSI ground truth -> the CarMaker line sensor's frame.

A ``SensorView`` (or a bare ``GroundTruth``) carries the road's paint as
``LaneBoundary`` polylines with dash states, and the host vehicle among the moving
objects. :class:`ViewReader` turns each into a
:class:`~aldm_gym.roads.PolylineRoad` (every boundary a marking, its painted
stretches from the dash states: :func:`~aldm_gym.osi.boundaries.painted_intervals`)
and measures it with the line sensor from the host's sensor pose, so everything
downstream (naive, ALDM, the tracker) runs unchanged: with ``marking_model="per_dash"``
each painted stretch is a line object, with ``"editor"`` each boundary.

Static ground truth: a message without lane boundaries reuses the last ones read
(simulators may send static data once); a message with the same boundaries as the
last reuses their road (no rebuild).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from aldm_gym.config import build_config
from aldm_gym.errors import ConfigError, InputError, TraceError
from aldm_gym.osi._bindings import osi3 as _osi3
from aldm_gym.osi.boundaries import _curve
from aldm_gym.osi.messages import BOUNDARY_TYPE
from aldm_gym.osi.wire import decode_points
from aldm_gym.roads.markings import MARKING_MODELS, MarkingType
from aldm_gym.roads.polyline import MarkingCurve, PolylineRoad
from aldm_gym.roads.position import MAX_COORDINATE
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.line_sensor import LineSensor, LineSensorConfig

_TYPE_FROM_OSI = {osi: cm for cm, osi in BOUNDARY_TYPE.items()}
_COLOUR_FROM_OSI = {3: 0, 4: 1, 6: 3, 7: 4, 5: 5, 9: 6, 8: 7, 1: 0}
_RAISED = {11: 0.75, 12: 0.15, 13: 1.0, 14: 0.75, 15: 3.0}
"""OSI boundary types that stand above the road (guard rail, curb, structure, barrier,
sound barrier) -> a continuous line object with this height [m] if the points give none."""
_NO_PAINT_COLOUR = 2  # COLOR_NONE: a logical boundary without paint

END_STUB = 1e-3
"""Length of the straight stub added at each end of a boundary [m]."""

_NOWHERE = MarkingCurve(xy=np.array([[1e9, 1e9], [1e9 + 1.0, 1e9]]), painted=np.zeros((0, 2)))
"""An unpainted marking far away: the road of a message with nothing painted."""


@dataclass(frozen=True)
class HostPose:
    """The host vehicle of one message.

    :ivar id: its OSI id.
    :ivar pose: ``(x [m], y [m], heading [rad])`` of its box centre in highway-env's
        world (OSI's y and yaw mirrored).
    :ivar mount: the sensor's position relative to the box centre, ``x`` forward and
        ``y`` left [m], its height above the road ``z`` [m] (the road at z = 0), and its
        yaw [rad], as the line sensor's ``mount_x/y/z/yaw``.
    """

    id: int
    pose: tuple[float, float, float]
    mount: tuple[float, float, float, float]


def _time(msg: Any) -> float:
    ts = msg.timestamp
    return float(ts.seconds) + 1e-9 * float(ts.nanos)


def _fail(where: str, what: str) -> TraceError:
    return TraceError(f"{where}: {what}")


def _boundary_curve(lb: Any, where: str, data: bytes | None = None) -> MarkingCurve | None:
    """One ``LaneBoundary`` as a marking curve (``None``: nothing painted); ``data``:
    its serialized bytes, if at hand."""
    c = lb.classification
    kind = int(c.type)
    height = 0.0
    if kind in _RAISED:
        ctype = int(MarkingType.CONTINUOUS)
        height = _RAISED[kind]
    elif kind in _TYPE_FROM_OSI:
        ctype = _TYPE_FROM_OSI[kind]
    else:
        return None  # no line, road or grass edge, unknown, other
    if int(c.color) == _NO_PAINT_COLOUR:
        return None
    pts = lb.boundary_line
    n = len(pts)
    ident = int(lb.id.value)
    if n < 2:
        raise _fail(where, f"lane boundary {ident} has {n} point(s); a boundary needs 2 or more")
    try:
        rows = decode_points(lb.SerializeToString() if data is None else data, 2, where)
    except InputError as exc:
        raise _fail(where, f"lane boundary {ident}: {exc}") from None
    if not np.isfinite(rows[:2]).all():
        raise _fail(where, f"lane boundary {ident} has a NaN or infinite point")
    if np.abs(rows[:2]).max() > MAX_COORDINATE:
        raise _fail(
            where,
            f"lane boundary {ident} has a point more than {MAX_COORDINATE:g} m from the origin",
        )
    first = pts[0]
    width = float(first.width) if first.HasField("width") and first.width > 0.0 else 0.15
    if first.HasField("height") and first.height > 0.0:
        height = float(first.height)
    # The sensor samples a polyline from its first vertex up to (not at) its last, in x
    # computed through the world frame (last bits differ): a short stub at each end,
    # painted as that end is, makes the end points inner points, measured like the rest.
    xy = np.empty((n + 2, 2))
    u = np.empty(n + 2)
    iv = np.empty((n + 1, 2))
    botts, dashed = ctype == int(MarkingType.DOTTED), ctype == int(MarkingType.DASHED)
    nv, ni = _curve(rows, botts, dashed, width, END_STUB, xy, u, iv)
    if nv == 0:
        raise _fail(where, f"lane boundary {ident} has all its points in one place")
    if ni == 0:
        return None
    xy, u, iv = xy[:nv], u[:nv], iv[:ni]
    return MarkingCurve(
        xy=xy,
        u=u,
        painted=iv,
        type=ctype,
        colour=_COLOUR_FROM_OSI.get(int(c.color), 0),
        width=width,
        height=height,
    )


def _unique_ids(gt: Any, where: str) -> None:
    """Raise unless the moving objects' ids, and the lane boundaries', are unique (OSI:
    an identifier names one object). Unset ids are not compared (some writers leave a
    boundary's id out)."""
    for kind, items in (("moving object", gt.moving_object), ("lane boundary", gt.lane_boundary)):
        seen: set[int] = set()
        for item in items:
            if not item.HasField("id"):
                continue
            ident = int(item.id.value)
            if ident in seen:
                raise _fail(where, f"two {kind} entries have the id {ident}")
            seen.add(ident)


class ViewReader:
    """Turns OSI ``SensorView`` or ``GroundTruth`` messages into line-sensor frames.

    :param sensor: the line sensor's settings (a :class:`LineSensorConfig` or its
        fields); its mount is used only when a message has no mounting position.
    :param marking_model: ``"per_dash"`` (each painted stretch a line object) or
        ``"editor"`` (each boundary one object).
    :param source: the file name, for error messages.
    :param seed: seed of the sensor's noise and dropout, if it has any: frame ``index``
        draws from ``default_rng([seed, index])``, so a trace gives the same frames
        however its frames are dealt out to processes.
    """

    def __init__(
        self,
        sensor: LineSensorConfig | Mapping[str, Any] | None = None,
        marking_model: str = "per_dash",
        source: str = "<message>",
        seed: int = 0,
    ) -> None:
        if marking_model not in MARKING_MODELS:
            raise InputError(
                f"marking_model must be one of {list(MARKING_MODELS)}, got {marking_model!r}"
            )
        self.config: LineSensorConfig = build_config(LineSensorConfig, sensor, where="sensor")
        self.marking_model = marking_model
        self.source = source
        self.seed = seed
        self._sensors: dict[tuple[float, ...], LineSensor] = {}
        self._key: tuple[bytes, ...] | None = None
        self._road: PolylineRoad | None = None
        self.road: PolylineRoad | None = None
        """The road of the last message read."""
        self.host: HostPose | None = None
        """The host of the last message read."""
        self.host_base: Any = None
        """The host's ``osi3.BaseMoving`` in the last message read."""
        self.boundary_ids: list[int] = []
        """OSI id of each marking of :attr:`road` (the painted boundaries, in order)."""
        self.mounting: Any = None
        """The sensor's ``osi3.MountingPosition`` in the host's vehicle frame (the
        message's own, or the line sensor's mount placed there)."""
        self.sensor_id: int | None = None
        """The message's ``sensor_id``, if it has one."""
        self._time: float | None = None

    def _sensor(self, mount: tuple[float, float, float, float], where: str = "") -> LineSensor:
        sensor = self._sensors.get(mount)
        if sensor is None:
            c = self.config
            mx, my, mz, myaw = mount
            try:
                cfg = replace(c, mount_x=mx, mount_y=my, mount_z=max(0.0, mz), mount_yaw=myaw)
                sensor = LineSensor(cfg, seed=self.seed)
            except ConfigError as exc:
                raise _fail(where or self.source, f"the sensor's mounting: {exc}") from None
            self._sensors[mount] = sensor
        return sensor

    def _host(self, msg: Any, gt: Any, where: str) -> HostPose:
        is_view = msg.DESCRIPTOR.name == "SensorView"
        host_id = None
        if is_view and msg.HasField("host_vehicle_id"):
            host_id = int(msg.host_vehicle_id.value)
        elif gt.HasField("host_vehicle_id"):
            host_id = int(gt.host_vehicle_id.value)
        if host_id is None:
            raise _fail(where, "no host vehicle (host_vehicle_id is not set)")
        host = next((o for o in gt.moving_object if int(o.id.value) == host_id), None)
        if host is None:
            raise _fail(where, f"no host vehicle: no moving object has the host's id {host_id}")
        base = host.base
        x, y, yaw = float(base.position.x), float(base.position.y), float(base.orientation.yaw)
        pose = (x, y, float(base.position.z), yaw, base.orientation.pitch, base.orientation.roll)
        if not all(math.isfinite(v) for v in pose):
            raise _fail(where, f"the host vehicle {host_id} has a NaN or infinite pose")
        if abs(x) > MAX_COORDINATE or abs(y) > MAX_COORDINATE:
            raise _fail(
                where,
                f"the host vehicle {host_id} is more than {MAX_COORDINATE:g} m from the origin",
            )
        dim = base.dimension
        if not all(math.isfinite(v) and v >= 0.0 for v in (dim.length, dim.width, dim.height)):
            raise _fail(
                where,
                f"the host vehicle {host_id}'s dimension must be finite and not negative, "
                f"got {dim.length} x {dim.width} x {dim.height} m",
            )
        b2r = host.vehicle_attributes.bbcenter_to_rear
        if not all(math.isfinite(v) for v in (b2r.x, b2r.y, b2r.z)):
            raise _fail(where, f"the host vehicle {host_id}'s bbcenter_to_rear is not finite")
        mounting = _osi3.MountingPosition()
        if is_view and msg.HasField("mounting_position"):
            mp = msg.mounting_position
            mounting.CopyFrom(mp)
            # from the box centre; the height above the road from the box's bottom
            mount = (
                float(b2r.x + mp.position.x),
                float(b2r.y + mp.position.y),
                float(0.5 * base.dimension.height + b2r.z + mp.position.z),
                float(mp.orientation.yaw),
            )
        else:  # the line sensor's own mount, from the box centre
            c = self.config
            mount = (c.mount_x, c.mount_y, c.mount_z, c.mount_yaw)
            # ... written in the host's vehicle frame (at bbcenter_to_rear)
            mounting.position.x = c.mount_x - b2r.x
            mounting.position.y = c.mount_y - b2r.y
            mounting.position.z = c.mount_z - 0.5 * base.dimension.height - b2r.z
            mounting.orientation.yaw = c.mount_yaw
        if not all(math.isfinite(v) for v in mount):
            raise _fail(where, f"the host vehicle {host_id}'s sensor mounting is not finite")
        # yaw: OSI's is left positive; the line sensor's mount yaw too
        self.host_base = base
        self.mounting = mounting
        self.sensor_id = int(msg.sensor_id.value) if is_view and msg.HasField("sensor_id") else None
        return HostPose(host_id, (x, -y, -yaw), mount)

    def _road_of(self, gt: Any, where: str) -> PolylineRoad:
        boundaries = gt.lane_boundary
        if len(boundaries) == 0 and len(gt.lane) == 0 and self._road is not None:
            return self._road  # static ground truth sent in an earlier frame
        key = tuple(lb.SerializeToString() for lb in boundaries)
        if key == self._key and self._road is not None:
            return self._road
        curves, ids = [], []
        for lb, data in zip(boundaries, key, strict=True):
            curve = _boundary_curve(lb, where, data)
            if curve is not None:
                curves.append(curve)
                ids.append(int(lb.id.value))
        # nothing painted in view: the sensor sees nothing (one far, unseen marking keeps
        # the road well formed)
        self._road = PolylineRoad(curves or [_NOWHERE], self.marking_model)
        self._key = key
        self.boundary_ids = ids
        return self._road

    def frame(self, msg: Any, index: int = 0) -> SensorFrame:
        """The line sensor's frame of one message.

        :param msg: an ``osi3.SensorView`` or ``osi3.GroundTruth``.
        :param index: the message's frame number (for error messages).
        :raises TraceError: naming the file and frame: another message type, no host
            vehicle, a host with a non-finite pose, dimension or ``bbcenter_to_rear``
            or outside the world, a mounting the line sensor cannot take, a boundary
            with fewer than two points, non-finite or far points, two objects or
            boundaries with one id, a time before the previous frame's. A message
            with nothing painted gives a frame without line objects; one with
            neither lane boundaries nor lanes keeps the last boundaries read (static
            ground truth sent once).
        """
        where = f"{self.source} frame {index}"
        name = getattr(getattr(msg, "DESCRIPTOR", None), "name", type(msg).__name__)
        if name == "SensorView":
            if not msg.HasField("global_ground_truth") and not msg.HasField("host_vehicle_id"):
                raise _fail(
                    where,
                    "a SensorView without ground truth or host vehicle: is this a trace of "
                    "another message type (e.g. SensorData)?",
                )
            gt = msg.global_ground_truth
            t = _time(msg) if msg.HasField("timestamp") else _time(gt)
        elif name == "GroundTruth":
            gt, t = msg, _time(msg)
        else:
            raise _fail(where, f"expected an osi3.SensorView or osi3.GroundTruth, got {name}")
        if self._time is not None and t < self._time:
            raise _fail(
                where,
                f"its time {t:.9g} s is before the previous frame's {self._time:.9g} s "
                "(OSI timestamps do not go back)",
            )
        _unique_ids(gt, where)
        host = self._host(msg, gt, where)
        try:
            road = self._road_of(gt, where)
        except TraceError:
            raise
        except InputError as exc:  # boundaries the road cannot be built from
            raise _fail(where, f"the lane boundaries: {exc}") from None
        self._time = t
        self.road, self.host = road, host
        sensor = self._sensor(host.mount, where)
        if self.config.noisy:
            sensor.seed([self.seed, index])
        return sensor.measure(road, host.pose, t)

    @property
    def sensor(self) -> LineSensor:
        """The line sensor at the last host's mount."""
        if self.host is None:
            raise InputError("no message read yet")
        return self._sensor(self.host.mount)

    def odometry_pose(self) -> tuple[float, float, float]:
        """The last frame's sensor position and the host's heading ``(x, y, heading)``
        in highway-env's world (what :func:`~aldm_gym.sensor.tracking.odometry` takes)."""
        if self.host is None:
            raise InputError("no message read yet")
        origin, _ = self.sensor.world_pose(self.host.pose)
        return float(origin[0]), float(origin[1]), float(self.host.pose[2])
