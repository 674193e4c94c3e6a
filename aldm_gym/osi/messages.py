"""aldm-gym's state as OSI messages: a ``SensorView`` (ground truth) and a ``SensorData``
(the detector's lanes).

Ids (``osi3.Identifier``), stable within an episode:

| what | id |
|---|---|
| a vehicle | ``VEHICLE_ID + its index in the traffic's vehicle list`` (the host's too) |
| a lane boundary | ``BOUNDARY_ID + its marking index on the road`` |
| a lane | ``LANE_ID + its lane index`` (the generated road's lane id, a map's lane index) |
| the sensor | ``SENSOR_ID + the sensor index m`` |
| a detected line | ``tracking_id``: 1 ``left_adjacent``, 2 ``ego_left``, 3 ``ego_right``, |
| | 4 ``right_adjacent`` |

Frames: OSI's world frame is right-handed (x east, y north, z up): a highway-env world
point ``(x, y)`` is ``(x, -y)`` there and a heading ``h`` is ``-h``; on a map this is
the OpenDRIVE file's own inertial frame. Vehicles have no axles in highway-env: their
vehicle frame is the centre of the box on the ground (``bbcenter_to_rear = (0, 0,
-h/2)``), so the sensor's mounting position is the line sensor's ``mount_x/y/z``.
Detected lines are in the sensor frame (ISO 8855: x forward, y left), as OSI's
``SensorData`` gives everything but feature data.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from aldm_gym.osi._bindings import interface_version, osi3
from aldm_gym.osi.boundaries import DASH_END, DASH_START, BoundarySample
from aldm_gym.osi.wire import encode_points
from aldm_gym.roads.markings import MarkingType
from aldm_gym.sensor.conditions import TRUCK_LENGTH, vehicle_height
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection
from aldm_gym.types import FloatArray

VEHICLE_ID = 1
"""Id of the first vehicle (the traffic's vehicle 0)."""
BOUNDARY_ID = 1_000_000
"""Id of marking 0's lane boundary."""
LANE_ID = 2_000_000
"""Id of lane 0."""
SENSOR_ID = 3_000_000
"""Id of sensor m = 0."""

TRACKING_ID = {name: i + 1 for i, name in enumerate(LINE_NAMES)}
"""``DetectedLaneBoundary.header.tracking_id`` of each detected line."""

BOUNDARY_TYPE = {
    int(MarkingType.CONTINUOUS): 3,  # TYPE_SOLID_LINE
    int(MarkingType.DASHED): 4,  # TYPE_DASHED_LINE
    int(MarkingType.DOTTED): 5,  # TYPE_BOTTS_DOTS
}
"""OSI ``LaneBoundary.Classification.Type`` of each CarMaker line type."""
GUARD_RAIL_TYPE = 11
"""``TYPE_GUARD_RAIL``: a line with height (the generated road's guard rails)."""

BOUNDARY_COLOUR = {0: 3, 1: 4, 2: 1, 3: 6, 4: 7, 5: 5, 6: 9, 7: 8, 8: 1}
"""OSI ``Color`` of each colour index (0 white, 1 yellow, 2 barrier: other, 3 blue,
4 green, 5 red, 6 orange, 7 violet, 8 black: other)."""


def _version(msg: Any) -> None:
    major, minor, patch = interface_version()
    msg.version_major, msg.version_minor, msg.version_patch = major, minor, patch


def _timestamp(msg: Any, t: float) -> None:
    ns = round(float(t) * 1e9)
    msg.seconds, msg.nanos = divmod(ns, 1_000_000_000)


def _base(base: Any, vehicle: Any) -> None:
    """``BaseMoving`` of a highway-env vehicle in OSI's world frame."""
    x, y = float(vehicle.position[0]), float(vehicle.position[1])
    h = float(vehicle.heading)
    height = vehicle_height(vehicle)
    speed = float(vehicle.speed)
    base.dimension.length = float(vehicle.LENGTH)
    base.dimension.width = float(vehicle.WIDTH)
    base.dimension.height = height
    base.position.x, base.position.y, base.position.z = x, -y, 0.5 * height
    yaw = math.remainder(-h, 2.0 * math.pi)  # OSI prefers [-pi, pi]
    base.orientation.roll, base.orientation.pitch, base.orientation.yaw = 0.0, 0.0, yaw
    base.velocity.x = speed * math.cos(h)
    base.velocity.y = -speed * math.sin(h)
    base.velocity.z = 0.0


def _moving_object(obj: Any, vehicle: Any, ident: int) -> None:
    obj.id.value = ident
    _base(obj.base, vehicle)
    obj.type = osi3.MovingObject.TYPE_VEHICLE
    truck = float(vehicle.LENGTH) >= TRUCK_LENGTH
    obj.vehicle_classification.type = (
        osi3.MovingObject.VehicleClassification.TYPE_HEAVY_TRUCK
        if truck
        else osi3.MovingObject.VehicleClassification.TYPE_CAR
    )
    b2r = obj.vehicle_attributes.bbcenter_to_rear
    b2r.x, b2r.y, b2r.z = 0.0, 0.0, -0.5 * vehicle_height(vehicle)


def _boundary(lb: Any, sample: BoundarySample, table: Mapping[str, np.ndarray]) -> bool:
    """Fill ``lb`` from a sample; False when it has fewer than two points (not kept)."""
    j = sample.marking
    lb.id.value = BOUNDARY_ID + j
    height = float(table["height"][j])
    width = float(table["width"][j])
    kind = int(table["type"][j])
    lb.classification.type = GUARD_RAIL_TYPE if height > 0.0 else BOUNDARY_TYPE.get(kind, 1)
    lb.classification.color = BOUNDARY_COLOUR.get(int(table["colour"][j]), 1)
    xy, dash = sample.xy, sample.dash
    if kind == int(MarkingType.DOTTED):
        # OSI: "one BoundaryPoint position has to define each Botts' dot": the centre
        # of each dot, its width the dot's length along the line (a round dot), no state
        starts = np.flatnonzero(dash == DASH_START)
        ends = np.flatnonzero(dash == DASH_END)
        ends = ends[np.searchsorted(ends, starts[0]) :] if len(starts) else ends
        pairs = min(len(starts), len(ends))
        if pairs < 2:
            return False  # a boundary needs two points
        a, b = xy[starts[:pairs]], xy[ends[:pairs]]
        centre = 0.5 * (a + b)
        size = np.hypot(*(b - a).T)
        rise = np.full(pairs, height)
        lb.MergeFromString(encode_points(2, centre[:, 0], -centre[:, 1], width=size, height=rise))
        return True
    # width and height on every point (OSI lets them carry over; viewers read each)
    lb.MergeFromString(encode_points(2, xy[:, 0], -xy[:, 1], dash, width=width, height=height))
    return True


def _merge_runs(samples: Sequence[BoundarySample]) -> list[BoundarySample]:
    """One sample per marking: the runs of a marking joined in x order."""
    by_marking: dict[int, list[BoundarySample]] = {}
    for s in samples:
        by_marking.setdefault(s.marking, []).append(s)
    out = []
    for j, runs in by_marking.items():
        if len(runs) == 1:
            out.append(runs[0])
            continue
        runs.sort(key=lambda r: float(r.x[0]))
        out.append(
            BoundarySample(
                j,
                np.concatenate([r.xy for r in runs]),
                np.concatenate([r.x for r in runs]),
                np.concatenate([r.dash for r in runs]),
            )
        )
    return out


def _lanes(gt: Any, lines: Mapping[str, Any], lane_ids: Mapping[str, int]) -> None:
    """The host's lane and the lanes beside it that exist, each with the ids of its
    boundaries that are in the message, and their adjacency both ways.

    :param lane_ids: OSI lane id of ``"host"``, ``"left"`` and ``"right"``.
    """
    present = {int(lb.id.value) for lb in gt.lane_boundary}

    def ids(line: Any) -> list[int]:
        if line is None:
            return []
        marks = [int(line)] if isinstance(line, int | np.integer) else [int(j) for j in line]
        return [BOUNDARY_ID + j for j in marks if BOUNDARY_ID + j in present]

    rows = [
        ("host", lines.get("ego_left"), lines.get("ego_right")),
        ("left", lines.get("left_adjacent"), lines.get("ego_left")),
        ("right", lines.get("ego_right"), lines.get("right_adjacent")),
    ]
    lanes = {}
    for name, left, right in rows:
        if name != "host" and (left is None or right is None):
            continue
        lane = gt.lane.add()
        lane.id.value = int(lane_ids[name])
        c = lane.classification
        c.type = osi3.Lane.Classification.TYPE_DRIVING
        c.is_host_vehicle_lane = name == "host"
        c.centerline_is_driving_direction = True
        for i in ids(left):
            c.left_lane_boundary_id.add().value = i
        for i in ids(right):
            c.right_lane_boundary_id.add().value = i
        lanes[name] = c
    host = lanes["host"]
    if "left" in lanes:
        host.left_adjacent_lane_id.add().value = int(lane_ids["left"])
        lanes["left"].right_adjacent_lane_id.add().value = int(lane_ids["host"])
    if "right" in lanes:
        host.right_adjacent_lane_id.add().value = int(lane_ids["right"])
        lanes["right"].left_adjacent_lane_id.add().value = int(lane_ids["host"])


def sensor_view(
    *,
    t: float,
    vehicles: Sequence[Any],
    host: Any,
    frame: SensorFrame,
    boundaries: Sequence[BoundarySample],
    table: Mapping[str, np.ndarray],
    lines: Mapping[str, Any] | None = None,
    lane_ids: Mapping[str, int] | None = None,
    reach: float = 300.0,
    ids: Sequence[int] | None = None,
    map_header: Any = None,
) -> Any:
    """One ``osi3.SensorView``: the host and the vehicles within ``reach`` [m], the lane
    boundaries in view (:func:`~aldm_gym.osi.boundaries.sample_boundaries`) and, when
    ``lines`` (the road's ``boundary_markings``) and ``lane_ids`` (OSI ids of the
    ``"host"``, ``"left"`` and ``"right"`` lanes) are given, the host's lane and its
    neighbours.

    :param t: simulation time [s].
    :param vehicles: every vehicle of the traffic.
    :param host: the ego (one of ``vehicles``).
    :param frame: the sensor frame measured at this step (mounting position, sensor id).
    :param table: the road's ``marking_table`` (type, colour, width, height).
    :param ids: each vehicle's number (its OSI id is ``VEHICLE_ID`` + it; default its
        index), so that a vehicle keeps its id when others leave the traffic.
    :param map_header: an OpenDRIVE map's header
        (:class:`~aldm_gym.roads.opendrive.parse.Header`): its ``<geoReference>`` is
        the ground truth's ``proj_string`` and its ``<offset>`` the
        ``proj_frame_offset`` (OSI's world frame is the map's inertial one), so that
        a consumer can put the world on the earth.
    """
    numbers = list(range(len(vehicles))) if ids is None else list(ids)
    if len(numbers) != len(vehicles):
        raise ValueError(f"{len(numbers)} ids for {len(vehicles)} vehicles")
    sv = osi3.SensorView()
    _version(sv.version)
    _timestamp(sv.timestamp, t)
    sv.sensor_id.value = SENSOR_ID + int(frame.sensor_index)
    _mounting(sv.mounting_position, frame)
    gt = sv.global_ground_truth
    _version(gt.version)
    _timestamp(gt.timestamp, t)
    if map_header is not None and map_header.geo_reference:
        gt.proj_string = map_header.geo_reference
        ox, oy, oz, hdg = map_header.offset
        if any(map_header.offset):
            off = gt.proj_frame_offset
            off.position.x, off.position.y, off.position.z = ox, oy, oz
            off.yaw = hdg
    hx, hy = float(host.position[0]), float(host.position[1])
    host_id = None
    for i, v in zip(numbers, vehicles, strict=True):
        if v is host:
            host_id = VEHICLE_ID + i
        elif math.hypot(float(v.position[0]) - hx, float(v.position[1]) - hy) > reach:
            continue
        _moving_object(gt.moving_object.add(), v, VEHICLE_ID + i)
    if host_id is None:  # a host outside the traffic list
        host_id = VEHICLE_ID + max(numbers, default=-1) + 1
        _moving_object(gt.moving_object.add(), host, host_id)
    gt.host_vehicle_id.value = host_id
    sv.host_vehicle_id.value = host_id
    for sample in _merge_runs(boundaries):
        if not _boundary(gt.lane_boundary.add(), sample, table):
            del gt.lane_boundary[-1]
    if lines is not None and lane_ids is not None:
        _lanes(gt, lines, lane_ids)
    return sv


def _mounting(mp: Any, frame: SensorFrame) -> None:
    """The sensor's mounting in the vehicle frame (centre of the box on the ground)."""
    pos, rot = frame.mount_position, frame.mount_rotation
    mp.position.x, mp.position.y, mp.position.z = (float(v) for v in pos)
    # the line sensor's mount yaw is left positive in the vehicle frame, as OSI's
    mp.orientation.roll = float(rot[0])
    mp.orientation.pitch = float(rot[1])
    mp.orientation.yaw = float(rot[2])


def line_objects(frame: SensorFrame, lines: Sequence[FloatArray]) -> list[tuple[int, int, int]]:
    """What each detected line runs through, read from the frame's line objects: the
    ``(type, colour, marking)`` of the object most of a few of its points lie on (within
    0.2 m of one of that object's points); ``(0, 0, -1)`` for a line on no object.

    ``marking`` is the object's *ground truth* (:attr:`SensorFrame.line_marking`): the
    road's marking the detected line lies on, -1 for clutter or a line on none (a
    ghost).
    """
    out = [(0, 0, -1)] * len(lines)
    pts = frame.all_points
    if len(pts) == 0:
        return out
    owner = np.repeat(np.arange(frame.n_lines), np.diff(frame.line_start))
    probes = [line[:: max(1, len(line) // 8)] for line in lines]
    which = np.repeat(np.arange(len(lines)), [len(p) for p in probes])
    if len(which) == 0:
        return out
    probe = np.concatenate(probes)
    d = np.abs(probe[:, None, 0] - pts[None, :, 0]) + np.abs(probe[:, None, 1] - pts[None, :, 1])
    nearest = np.argmin(d, axis=1)
    hit = d[np.arange(len(probe)), nearest] < 0.2
    for i in range(len(lines)):
        objects = owner[nearest[hit & (which == i)]]
        if len(objects):
            n = int(np.bincount(objects).argmax())
            out[i] = (
                int(frame.line_type[n]),
                int(frame.line_colour[n]),
                int(frame.line_marking[n]),
            )
    return out


def sensor_data(
    *,
    t: float,
    host: Any,
    frame: SensorFrame,
    detection: LaneDetection,
    boundary_ids: Sequence[int] | None = None,
    cycle: int = 0,
    mounting: Any = None,
    sensor_id: int | None = None,
) -> Any:
    """One ``osi3.SensorData``: the detector's four lines as ``DetectedLaneBoundary``.

    Each found line gives one boundary in the sensor frame (its points on the road,
    ``mount_z`` below the sensor), with
    ``tracking_id`` (:data:`TRACKING_ID`), the id of the true boundary it lies on (that
    of the line objects it runs through, :func:`line_objects`; unset for a line on no
    object: a ghost, or a stretch the tracking ALDM carries over from earlier frames), one
    candidate of probability 1 whose type and colour are those objects', and
    ``MEASUREMENT_STATE_MEASURED``. ``header.existence_probability`` is the line's
    confidence when the detection has one (the lane-model filter's
    :class:`~aldm_gym.sensor.lane_filter.ModelLaneDetection`), unset otherwise (naive
    detection and the ALDM do not estimate it). The filter's lines also carry
    ``MEASUREMENT_STATE_PREDICTED`` when no point of this frame measured them (drawn
    from the model alone: hidden, worn) and, per point, ``boundary_line_rmse``: the
    lateral standard deviation of its position from the filter's covariance (``y``;
    ``x`` and ``z`` 0). Per-point confidences are left unset.

    :param host: the host vehicle (``host_vehicle_location``): a highway-env vehicle,
        an ``osi3.BaseMoving`` to copy, or ``None``.
    :param boundary_ids: the OSI id of each marking index of the frame's road
        (``None``: no ground-truth ids).
    :param cycle: ``lane_boundary_header.cycle_counter``.
    :param mounting: an ``osi3.MountingPosition`` to copy (the input's, in the input's
        vehicle frame); ``None``: the frame's mount (aldm-gym's vehicle frame).
    :param sensor_id: the sensor's id (``None``: :data:`SENSOR_ID` + its index).
    """
    sd = osi3.SensorData()
    _version(sd.version)
    _timestamp(sd.timestamp, t)
    sensor = SENSOR_ID + int(frame.sensor_index) if sensor_id is None else int(sensor_id)
    sd.sensor_id.value = sensor
    if mounting is not None:
        sd.mounting_position.CopyFrom(mounting)
    else:
        _mounting(sd.mounting_position, frame)
    # the sensor frame's origin is the mounting position: the road lies mount_z below it
    road_z = -float(frame.mount_position[2])
    if host is not None:
        if getattr(getattr(host, "DESCRIPTOR", None), "name", "") == "BaseMoving":
            sd.host_vehicle_location.CopyFrom(host)
        else:
            _base(sd.host_vehicle_location, host)
    header = sd.lane_boundary_header
    _timestamp(header.measurement_time, t)
    header.cycle_counter = int(cycle)
    header.data_qualifier = osi3.DetectedEntityHeader.DATA_QUALIFIER_AVAILABLE
    found = [(name, detection.line(name)) for name in LINE_NAMES]
    found = [(name, line) for name, line in found if len(line)]
    confidence = getattr(detection, "confidence", None)
    measured = getattr(detection, "measured", None)
    lateral_std = getattr(detection, "lateral_std", None)
    objects = line_objects(frame, [line for _, line in found])
    for (name, line), (kind, colour, marking) in zip(found, objects, strict=True):
        db = sd.lane_boundary.add()
        db.header.tracking_id.value = TRACKING_ID[name]
        if marking >= 0 and boundary_ids is not None:
            db.header.ground_truth_id.add().value = int(boundary_ids[marking])
        role = LINE_NAMES.index(name)
        carried = measured is not None and not np.isfinite(measured[role]).all()
        db.header.measurement_state = (
            osi3.DetectedItemHeader.MEASUREMENT_STATE_PREDICTED
            if carried
            else osi3.DetectedItemHeader.MEASUREMENT_STATE_MEASURED
        )
        if confidence is not None:
            db.header.existence_probability = float(confidence[role])
        db.header.sensor_id.add().value = sensor
        cand = db.candidate.add()
        cand.probability = 1.0
        cand.classification.type = BOUNDARY_TYPE.get(kind, 0)
        cand.classification.color = BOUNDARY_COLOUR.get(colour, 0) if kind else 0
        db.MergeFromString(encode_points(3, line[:, 0], line[:, 1], z=road_z))
        if lateral_std is not None and lateral_std.shape[1] == len(line):
            # the RMSE of each point: lateral only (the filter's covariance)
            std = lateral_std[role]
            db.MergeFromString(encode_points(4, np.zeros(len(line)), std))
    return sd


def detection_from_data(sd: Any) -> dict[str, FloatArray]:
    """The detected lines of an ``osi3.SensorData`` by name (sensor frame, ``(K, 2)``
    [m]): the inverse of :func:`sensor_data` for the lines it wrote."""
    names = {v: k for k, v in TRACKING_ID.items()}
    out = {name: np.zeros((0, 2)) for name in LINE_NAMES}
    for db in sd.lane_boundary:
        name = names.get(int(db.header.tracking_id.value))
        if name is None:
            continue
        pts = [(p.position.x, p.position.y) for p in db.boundary_line]
        out[name] = np.array(pts, dtype=np.float64).reshape(-1, 2)
    return out
