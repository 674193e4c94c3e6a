"""env -> OSI trace -> reader: the same frames, point for point; the written messages
parse with the official bindings and carry what OSI requires."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from aldm_gym.osi import ViewReader, detect_trace, read_messages
from aldm_gym.osi._bindings import osi3
from aldm_gym.osi.messages import (
    BOUNDARY_ID,
    TRACKING_ID,
    VEHICLE_ID,
    detection_from_data,
    sensor_data,
)
from aldm_gym.osi.trace import binary_path
from aldm_gym.roads import shipped_map
from aldm_gym.sensor.lane_detection import LINE_NAMES
from tests.osi.conftest import ROADS, record
from tests.scenario._build import with_geo_reference


def _objects(frame, dotted: bool) -> tuple[np.ndarray, list]:
    """The points and (type, colour, length) of the frame's dotted objects or of the rest."""
    keep = [n for n in range(frame.n_lines) if (frame.line_type[n] == 3) == dotted]
    pts = [frame.line_points(n) for n in keep]
    rows = [
        (int(frame.line_type[n]), int(frame.line_colour[n]), len(p))
        for n, p in zip(keep, pts, strict=True)
    ]
    return (np.concatenate(pts) if pts else np.zeros((0, 3))), rows


def _same(a, b) -> None:
    # Every object but Botts' dots: the same points, objects and order.
    pa, ra = _objects(a, dotted=False)
    pb, rb = _objects(b, dotted=False)
    assert ra == rb
    np.testing.assert_allclose(pa, pb, rtol=0.0, atol=1e-9)
    # Botts' dots travel as one point per dot (OSI's rule), so a dot's ends and the line
    # between dots (a chord of 1.2 m: 1.8 mm off the marking at R 100 m) are known to a
    # few millimetres: a grid point that grazes a dot's end may fall on either side
    da, _ = _objects(a, dotted=True)
    db, _ = _objects(b, dotted=True)
    assert abs(len(da) - len(db)) <= 2
    if len(da) and len(db):
        gap = np.abs(da[:, None, :2] - db[None, :, :2]).sum(axis=2).min(axis=1)
        assert np.sort(gap)[: min(len(da), len(db))].max() < 3e-3
    if not len(da) and not len(db):
        assert a.n_left == b.n_left
    # The relevant line: the object whose first point is nearest to the middle axis. On a
    # straight road the dashes of one marking tie up to the last bits, which differ after
    # a round trip through the world frame: compare the distance, not the index.
    for side in ("left", "right"):
        pa_, pb_ = a.relevant_line_points(side), b.relevant_line_points(side)
        assert len(pa_) > 0 and len(pb_) > 0
        assert abs(abs(pa_[0, 1] - a.axis_y) - abs(pb_[0, 1] - b.axis_y)) < 1e-9


@pytest.mark.parametrize("road", sorted(ROADS))
@pytest.mark.parametrize("suffix", [".mcap", ".osi"])
def test_env_trace_reads_back_to_the_same_frames(tmp_path: Path, road: str, suffix: str) -> None:
    path = tmp_path / f"run{suffix}"
    env, frames = record(path, ROADS[road], steps=2)
    source = path if suffix == ".mcap" else binary_path(path, "SensorView")
    reader = ViewReader(env.sensor.config, env.settings.marking_model, str(source))
    got = list(read_messages(source))
    assert len(got) == len(frames) == 21
    for (index, message), frame in zip(got, frames, strict=True):
        again = reader.frame(message, index)
        _same(again, frame)
        assert again.timestamp == pytest.approx(frame.timestamp, abs=1e-9)
        np.testing.assert_allclose(again.origin, frame.origin, atol=1e-9)


def test_written_messages_carry_the_required_fields(env_trace) -> None:
    path, env, _ = env_trace
    found = {TRACKING_ID[n] for n in TRACKING_ID if env.detection.found(n)}
    assert len(found) >= 3
    from osi_utilities import MultiTraceReader

    reader = MultiTraceReader()
    assert reader.open(path)
    meta = {m["name"]: m["data"] for m in reader.get_file_metadata()}
    trace_meta = meta["net.asam.osi.trace"]
    assert trace_meta["min_osi_version"] == trace_meta["max_osi_version"] == "3.8.0"
    assert sorted(reader.get_available_topics()) == ["SensorData", "SensorView"]
    for topic in ("SensorView", "SensorData"):
        channel = reader.get_channel_metadata(topic)
        assert channel["net.asam.osi.trace.channel.osi_version"] == "3.8.0"
    kinds: dict[str, int] = {}
    while (result := reader.read_message()) is not None:
        msg = result.message
        kinds[result.channel_name] = kinds.get(result.channel_name, 0) + 1
        assert (msg.version.version_major, msg.version.version_minor) == (3, 8)
        assert msg.HasField("timestamp")
        if result.channel_name == "SensorView":
            gt = msg.global_ground_truth
            ids = {o.id.value for o in gt.moving_object}
            assert msg.host_vehicle_id.value == gt.host_vehicle_id.value
            assert msg.host_vehicle_id.value in ids
            assert msg.HasField("mounting_position")
            for lb in gt.lane_boundary:
                assert lb.id.value >= BOUNDARY_ID
                assert lb.classification.type in (3, 4, 11)  # solid, dashed, guard rail
                assert lb.classification.color == 3  # white
                assert len(lb.boundary_line) >= 2
                states = {p.dash for p in lb.boundary_line}
                assert states <= {2, 3, 4, 5}  # START, CONTINUE, END, GAP
                assert all(p.HasField("width") and p.width > 0 for p in lb.boundary_line)
            host = next(o for o in gt.moving_object if o.id.value == gt.host_vehicle_id.value)
            assert host.base.dimension.length > 0 and host.type == 2  # TYPE_VEHICLE
            assert len(gt.lane) >= 2 and gt.lane[0].classification.is_host_vehicle_lane
            boundary_ids = {lb.id.value for lb in gt.lane_boundary}
        else:
            assert msg.lane_boundary_header.data_qualifier == 2  # AVAILABLE
            names = {db.header.tracking_id.value for db in msg.lane_boundary}
            assert names == found  # the lines the env's detector found (same every frame)
            for db in msg.lane_boundary:
                assert len(db.boundary_line) >= 2
                assert db.candidate[0].probability == 1.0
                (gt_id,) = [i.value for i in db.header.ground_truth_id]
                assert gt_id in boundary_ids
    reader.close()
    assert kinds == {"SensorView": 31, "SensorData": 31}
    assert VEHICLE_ID >= 1


def test_sensor_data_holds_the_env_detection(env_trace) -> None:
    path, env, _ = env_trace
    data = [m for _, m in _all(path, "SensorData")]
    lines = detection_from_data(data[-1])
    det = env.detection
    for name, line in lines.items():
        np.testing.assert_allclose(line, det.line(name), atol=1e-12)
    # ego lines on the true ego-lane boundaries: ids of the lane marked as the host's
    view = [m for _, m in _all(path, "SensorView")][-1]
    host_lane = view.global_ground_truth.lane[0].classification
    by_id = {
        db.header.tracking_id.value: db.header.ground_truth_id[0].value
        for db in data[-1].lane_boundary
    }
    assert by_id[TRACKING_ID["ego_left"]] == host_lane.left_lane_boundary_id[0].value
    assert by_id[TRACKING_ID["ego_right"]] == host_lane.right_lane_boundary_id[0].value


def test_sensor_data_carries_the_filter_confidence(env_trace, tmp_path: Path) -> None:
    """With the lane-model filter each written line's existence probability is its
    confidence; the single-frame ALDM's lines have none."""
    path = tmp_path / "filter.mcap"
    env, _ = record(path, {"detector_params": {"tracking": "model"}}, steps=1)
    data = [m for _, m in _all(path, "SensorData")]
    names = {v: k for k, v in TRACKING_ID.items()}
    conf = env.detection.confidence
    assert len(data[-1].lane_boundary) >= 2
    for db in data[-1].lane_boundary:
        assert db.header.HasField("existence_probability")
        name = names[db.header.tracking_id.value]
        role = LINE_NAMES.index(name)
        assert db.header.existence_probability == conf[role] > 0.0
        # measured in this frame, and each point's lateral RMSE from the covariance
        assert np.isfinite(env.detection.measured[role]).all()
        assert db.header.measurement_state == osi3.DetectedItemHeader.MEASUREMENT_STATE_MEASURED
        rmse = [p.position.y for p in db.boundary_line_rmse]
        assert len(rmse) == len(db.boundary_line)
        np.testing.assert_allclose(rmse, env.detection.lateral_std[role])
        assert all(p.position.x == 0.0 for p in db.boundary_line_rmse)
    # a line the frame did not measure is written as predicted (carried by the model)
    det = env.detection
    hidden = dataclasses.replace(det, measured=np.full((len(LINE_NAMES), 2), np.nan))
    sd = sensor_data(t=0.0, host=None, frame=env.frame, detection=hidden)
    assert sd.lane_boundary and all(
        db.header.measurement_state == osi3.DetectedItemHeader.MEASUREMENT_STATE_PREDICTED
        for db in sd.lane_boundary
    )
    plain = [m for _, m in _all(env_trace[0], "SensorData")]
    assert not any(db.header.HasField("existence_probability") for db in plain[-1].lane_boundary)
    assert not any(len(db.boundary_line_rmse) for db in plain[-1].lane_boundary)
    assert all(
        db.header.measurement_state == osi3.DetectedItemHeader.MEASUREMENT_STATE_MEASURED
        for db in plain[-1].lane_boundary
    )


def _all(path: Path, topic: str):
    from osi_utilities import MultiTraceReader

    reader = MultiTraceReader()
    reader.open(path)
    reader.set_topics([topic])
    i = 0
    while (r := reader.read_message()) is not None:
        yield i, r.message
        i += 1
    reader.close()


def test_detect_on_the_env_trace_reproduces_the_env(env_trace, tmp_path: Path) -> None:
    path, env, _ = env_trace
    out = tmp_path / "sd.osi"
    summary = detect_trace(path, out)
    assert summary.frames == 31
    assert summary.found == {n: float(env.detection.found(n)) for n in summary.found}
    from osi_utilities import SingleTraceReader
    from osi_utilities._types import MessageType

    reader = SingleTraceReader()
    reader.set_message_type(MessageType.SENSOR_DATA)
    assert reader.open(out)
    last = None
    n = 0
    while (r := reader.read_message()) is not None:
        last = r.message
        n += 1
    reader.close()
    assert n == 31
    # same sensor, same detector, same frame: the env's own detection (ALDM is stateless)
    lines = detection_from_data(last)
    for name, line in lines.items():
        np.testing.assert_allclose(line, env.detection.line(name), atol=1e-9)


def test_two_jobs_write_what_one_writes(env_trace, tmp_path: Path) -> None:
    path, _, _ = env_trace
    one, two = tmp_path / "one.mcap", tmp_path / "two.mcap"
    detect_trace(path, one, jobs=1)
    detect_trace(path, two, jobs=2)
    a = [m.SerializeToString() for _, m in _all(one, "SensorData")]
    b = [m.SerializeToString() for _, m in _all(two, "SensorData")]
    assert len(a) == 31 and a == b


@pytest.mark.parametrize("offset", [None, (120.0, -30.0, 0.25)])
def test_a_georeferenced_map_gives_the_ground_truth_its_projection(
    tmp_path: Path, offset: tuple[float, float, float] | None
) -> None:
    """The map's ``<geoReference>`` and ``<offset>`` are the ground truth's
    ``proj_string`` and ``proj_frame_offset``; a map without them sets neither."""
    proj = "+proj=utm +zone=32 +ellps=GRS80 +units=m +no_defs"
    xodr = with_geo_reference(shipped_map("motorway"), tmp_path / "geo.xodr", proj, offset)
    path = tmp_path / "geo.mcap"
    record(path, {"road": {"xodr": str(xodr)}}, steps=1)
    views = [m for _, m in read_messages(path, "SensorView")]
    assert views
    for view in views:
        gt = view.global_ground_truth
        assert gt.proj_string == proj
        assert gt.HasField("proj_frame_offset") == (offset is not None)
        if offset is not None:
            off = gt.proj_frame_offset
            assert (off.position.x, off.position.y, off.yaw) == offset


def test_a_map_without_a_geo_reference_sets_no_projection(env_trace) -> None:
    path, _, _ = env_trace
    for _, view in read_messages(path, "SensorView"):
        assert view.global_ground_truth.proj_string == ""
        assert not view.global_ground_truth.HasField("proj_frame_offset")
