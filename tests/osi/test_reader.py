"""OSI in: ground truth built here with the official bindings (not the project's
writer), written with asam-osi-utilities, read and detected; bad traces."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from osi3.osi_groundtruth_pb2 import GroundTruth
from osi3.osi_lane_pb2 import LaneBoundary
from osi3.osi_sensordata_pb2 import SensorData
from osi_utilities import MultiTraceWriter, SingleTraceWriter

from aldm_gym.errors import ConfigError, TraceError
from aldm_gym.osi import OsiLaneSensor, ViewReader, detect_trace, read_messages
from aldm_gym.osi.messages import TRACKING_ID, detection_from_data
from tests._cli import usage_error

HOST = 7
SOLID, DASHED = (
    LaneBoundary.Classification.TYPE_SOLID_LINE,
    LaneBoundary.Classification.TYPE_DASHED_LINE,
)
D = LaneBoundary.BoundaryPoint


def _circle(y0: float, radius: float | None, s: np.ndarray) -> np.ndarray:
    """Points at arc length s of a line y0 left of a road along +x that turns left with
    ``radius`` (None: straight); OSI world frame."""
    if radius is None:
        return np.stack([s, np.full_like(s, y0)], axis=1)
    r = radius - y0
    phi = s / radius
    return np.stack([r * np.sin(phi), radius - r * np.cos(phi)], axis=1)


def ground_truth(
    t: float = 0.0,
    host_x: float = 50.0,
    radius: float | None = None,
    gaps: bool = False,
    host: bool = True,
) -> GroundTruth:
    """A 4-lane-boundary road along +x (3.5 m lanes), the host in the lane between
    y = 1.75 and y = -1.75; dashed lines 6 m dash / 12 m gap with START/END points
    (and GAP points mid-gap with ``gaps``), solid lines without dash states."""
    gt = GroundTruth()
    gt.version.version_major, gt.version.version_minor = 3, 8
    gt.timestamp.seconds, gt.timestamp.nanos = int(t), round((t % 1) * 1e9)
    if host:
        gt.host_vehicle_id.value = HOST
    car = gt.moving_object.add()
    car.id.value = HOST
    s_host = host_x
    (pos,) = _circle(0.0, radius, np.array([s_host]))
    car.base.position.x, car.base.position.y, car.base.position.z = pos[0], pos[1], 0.75
    car.base.orientation.yaw = 0.0 if radius is None else s_host / radius
    car.base.dimension.length, car.base.dimension.width, car.base.dimension.height = 4.5, 1.8, 1.5
    car.vehicle_attributes.bbcenter_to_rear.x = -1.4
    car.vehicle_attributes.bbcenter_to_rear.z = -0.3
    for ident, y0, kind in (
        (1, 5.25, SOLID),
        (2, 1.75, DASHED),
        (3, -1.75, DASHED),
        (4, -5.25, SOLID),
    ):
        lb = gt.lane_boundary.add()
        lb.id.value = ident
        lb.classification.type = kind
        lb.classification.color = LaneBoundary.Classification.COLOR_WHITE
        if kind == SOLID:
            s = np.arange(0.0, 400.0, 2.0)
            for x, y in _circle(y0, radius, s):
                p = lb.boundary_line.add()
                p.position.x, p.position.y = x, y
                p.width = 0.3
        else:
            for k in range(23):
                a = 18.0 * k
                stations = [(a, D.DASH_START), (a + 3.0, D.DASH_CONTINUE), (a + 6.0, D.DASH_END)]
                if gaps:
                    stations.append((a + 12.0, D.DASH_GAP))
                for si, state in stations:
                    (xy,) = _circle(y0, radius, np.array([si]))
                    p = lb.boundary_line.add()
                    p.position.x, p.position.y = xy
                    p.width = 0.15
                    p.dash = state
    return gt


def _write_osi(path: Path, messages: list) -> Path:
    writer = SingleTraceWriter()
    assert writer.open(path)
    for m in messages:
        assert writer.write_message(m)
    writer.close()
    return path


def _sensor_data(path: Path) -> list[SensorData]:
    return [m for _, m in _read_sd(path)]


def _read_sd(path: Path):
    from osi_utilities import SingleTraceReader
    from osi_utilities._types import MessageType

    reader = SingleTraceReader()
    reader.set_message_type(MessageType.SENSOR_DATA)
    assert reader.open(path)
    i = 0
    while (r := reader.read_message()) is not None:
        yield i, r.message
        i += 1
    reader.close()


@pytest.mark.parametrize("radius", [None, 500.0])
@pytest.mark.parametrize("gaps", [False, True])
def test_a_hand_built_trace_is_detected(tmp_path: Path, radius: float | None, gaps: bool) -> None:
    frames = [ground_truth(0.1 * i, 50.0 + 2.5 * i, radius, gaps) for i in range(5)]
    src = _write_osi(tmp_path / "hand_gt.osi", frames)
    out = tmp_path / "hand_sd.osi"
    summary = detect_trace(src, out)
    assert summary.frames == 5 and all(v == 1.0 for v in summary.found.values())
    data = _sensor_data(out)
    assert len(data) == 5
    last = data[-1]
    truth = {
        db.header.tracking_id.value: db.header.ground_truth_id[0].value for db in last.lane_boundary
    }
    assert truth == {
        TRACKING_ID["left_adjacent"]: 1,
        TRACKING_ID["ego_left"]: 2,
        TRACKING_ID["ego_right"]: 3,
        TRACKING_ID["right_adjacent"]: 4,
    }
    lines = detection_from_data(last)
    for name, y0 in (("ego_left", 1.75), ("ego_right", -1.75), ("left_adjacent", 5.25)):
        line = lines[name]
        assert line[-1, 0] > 150.0  # traced through the dashes, not one dash
        x = line[:, 0]
        if radius is None:
            np.testing.assert_allclose(line[:, 1], y0, atol=1e-6)
        else:  # the true line in the sensor frame (the reader's sensor pose)
            frame = ViewReader().frame(frames[-1])
            s_true = np.arange(0.0, 400.0, 0.5)
            world = _circle(y0, radius, s_true) * [1.0, -1.0]  # OSI -> highway-env
            c, sn = math.cos(frame.yaw), math.sin(frame.yaw)
            rel = world - frame.origin
            xt = rel[:, 0] * c + rel[:, 1] * sn
            yt = rel[:, 0] * sn - rel[:, 1] * c
            ahead = xt > 0
            expect = np.interp(x, xt[ahead], yt[ahead])
            np.testing.assert_allclose(line[:, 1], expect, atol=0.02)
    kinds = {
        db.header.tracking_id.value: db.candidate[0].classification.type
        for db in last.lane_boundary
    }
    assert kinds[TRACKING_ID["ego_left"]] == DASHED and kinds[TRACKING_ID["left_adjacent"]] == SOLID


def test_per_dash_objects_break_the_naive_detector_not_the_aldm() -> None:
    """The paper's problem, through OSI: each dash of a dashed boundary is its own line
    object; CarMaker's default keeps one dash per side, the ALDM the whole marking."""
    gt = ground_truth()
    naive = OsiLaneSensor("naive").step(gt, 0)
    aldm = OsiLaneSensor("aldm").step(gt, 0)
    n_left = detection_from_data(naive)["ego_left"]
    a_left = detection_from_data(aldm)["ego_left"]
    assert n_left[-1, 0] - n_left[0, 0] < 7.0  # one 6 m dash
    assert a_left[-1, 0] - a_left[0, 0] > 150.0
    editor = OsiLaneSensor("naive", marking_model="editor").step(gt, 0)
    e_left = detection_from_data(editor)["ego_left"]
    assert e_left[-1, 0] - e_left[0, 0] > 150.0  # one object per boundary: naive works


def test_reader_frames_are_in_the_sensor_frame() -> None:
    reader = ViewReader()
    frame = reader.frame(ground_truth(host_x=50.0))
    # without a mounting position (a GroundTruth), the line sensor's own mount_x (1 m
    # ahead of the box centre, aldm-gym's vehicle reference) places the sensor
    assert frame.origin[0] == pytest.approx(50.0 + 1.0)
    assert frame.origin[1] == pytest.approx(0.0)
    ys = np.unique(np.round(frame.all_points[:, 1], 6))
    assert set(ys) == {5.25, 1.75, -1.75, -5.25}
    assert frame.n_lines > 4  # per dash: every dash its own object
    assert ViewReader(marking_model="editor").frame(ground_truth()).n_lines == 4


def test_static_ground_truth_sent_once_is_kept() -> None:
    reader = ViewReader()
    first = reader.frame(ground_truth(host_x=50.0), 0)
    later = ground_truth(host_x=60.0)
    del later.lane_boundary[:]  # no boundaries and no lanes: sent in an earlier frame
    second = reader.frame(later, 1)
    assert second.n_lines == first.n_lines
    assert second.origin[0] == pytest.approx(first.origin[0] + 10.0)
    # with lanes but no boundary in view (an env trace on a bare stretch): nothing seen
    later.lane.add().id.value = 1
    assert reader.frame(later, 2).n_lines == 0
    # the first frame without boundaries: nothing to see, not an error
    bare = ground_truth()
    del bare.lane_boundary[:]
    assert ViewReader().frame(bare, 0).n_lines == 0


def test_nothing_painted_gives_no_lines() -> None:
    gt = ground_truth()
    for lb in gt.lane_boundary:
        lb.classification.type = LaneBoundary.Classification.TYPE_NO_LINE
    model = OsiLaneSensor()
    data = model.step(gt, 0)
    assert model.frame is not None and model.frame.n_lines == 0
    assert len(data.lane_boundary) == 0


def test_esmini_style_dashes_without_states() -> None:
    """esmini writes a broken line as start/end point pairs and no dash states (OSI: a
    point at the start and one at the end of each dash): each pair is a dash."""
    gt = ground_truth()
    for lb in gt.lane_boundary:
        if lb.classification.type == DASHED:
            kept = [p for p in lb.boundary_line if p.dash != D.DASH_CONTINUE]
            del lb.boundary_line[:]
            for p in kept:
                q = lb.boundary_line.add()
                q.position.CopyFrom(p.position)
    stated = ViewReader().frame(ground_truth())
    bare = ViewReader().frame(gt)
    assert bare.n_lines == stated.n_lines > 20  # every dash its own object
    np.testing.assert_allclose(bare.all_points, stated.all_points, atol=1e-9)


def test_sensor_data_is_in_the_input_sensor_frame() -> None:
    from osi3.osi_sensorview_pb2 import SensorView

    view = SensorView()
    view.global_ground_truth.CopyFrom(ground_truth())
    view.host_vehicle_id.value = HOST
    view.sensor_id.value = 42
    mp = view.mounting_position
    mp.position.x, mp.position.y, mp.position.z = 3.5, 0.0, 1.1  # from the rear axle
    data = OsiLaneSensor().step(view, 0)
    assert data.sensor_id.value == 42 and data.mounting_position == mp
    frame = OsiLaneSensor().reader.frame(view)
    # box centre 50 + (rear axle −1.4 + 3.5)
    assert frame.origin[0] == pytest.approx(52.1)
    for db in data.lane_boundary:
        zs = np.array([p.position.z for p in db.boundary_line])
        # the road lies below the sensor: axle 0.75 − 0.3 above it, plus the mount's 1.1
        np.testing.assert_allclose(zs, -(0.75 - 0.3 + 1.1))


def test_a_road_with_elevation_and_a_bad_mount() -> None:
    high = ground_truth()
    high.moving_object[0].base.position.z = 50.75  # a road 50 m up
    assert ViewReader().frame(high).n_lines > 4
    from osi3.osi_sensorview_pb2 import SensorView

    view = SensorView()
    view.global_ground_truth.CopyFrom(ground_truth())
    view.host_vehicle_id.value = HOST
    view.mounting_position.position.x = 500.0
    with pytest.raises(TraceError, match=r"frame 3: the sensor's mounting: .*mount_x"):
        ViewReader().frame(view, 3)
    view.mounting_position.position.x = math.nan
    with pytest.raises(TraceError, match=r"frame 3: .*mounting is not finite"):
        ViewReader().frame(view, 3)


def _errors() -> dict:
    no_host = ground_truth(host=False)
    wrong_host = ground_truth()
    wrong_host.host_vehicle_id.value = 99
    one_point = ground_truth()
    del one_point.lane_boundary[1].boundary_line[1:]
    nan_point = ground_truth()
    nan_point.lane_boundary[0].boundary_line[3].position.y = math.nan
    nan_rear = ground_truth()
    nan_rear.moving_object[0].vehicle_attributes.bbcenter_to_rear.x = math.nan
    negative = ground_truth()
    negative.moving_object[0].base.dimension.width = -1.8
    far_host = ground_truth()
    far_host.moving_object[0].base.position.x = 1e300
    far_point = ground_truth()
    far_point.lane_boundary[0].boundary_line[3].position.x = -1e300
    twin_object = ground_truth()
    twin_object.moving_object.add().CopyFrom(twin_object.moving_object[0])
    twin_boundary = ground_truth()
    twin_boundary.lane_boundary[1].id.value = 1
    return {
        "bbcenter_to_rear is not finite": nan_rear,
        "dimension must be finite and not negative": negative,
        "host vehicle 7 is more than 1e\\+09 m": far_host,
        "lane boundary 1 has a point more than": far_point,
        "two moving object entries have the id 7": twin_object,
        "two lane boundary entries have the id 1": twin_boundary,
        "its time -1 s is before the previous frame's 0 s": ground_truth(t=-1.0),
        "no host vehicle \\(host_vehicle_id": no_host,
        "no moving object has the host's id 99": wrong_host,
        "lane boundary 2 has 1 point": one_point,
        "lane boundary 1 has a NaN": nan_point,
    }


@pytest.mark.parametrize("message", sorted(_errors()))
def test_bad_frames_name_the_file_and_frame(tmp_path: Path, message: str) -> None:
    good = ground_truth()
    src = _write_osi(tmp_path / "bad_gt.osi", [good, _errors()[message]])
    with pytest.raises(TraceError, match=rf"bad_gt.osi frame 1: .*{message}"):
        detect_trace(src, tmp_path / "out.osi")


def test_an_empty_trace_is_an_error(tmp_path: Path) -> None:
    src = tmp_path / "empty_gt.osi"
    src.write_bytes(b"")
    with pytest.raises(TraceError, match=r"empty_gt.osi: no frames"):
        detect_trace(src, tmp_path / "out.osi")


def test_a_truncated_binary_trace_names_the_frame(tmp_path: Path) -> None:
    src = _write_osi(tmp_path / "cut_gt.osi", [ground_truth(), ground_truth(0.1, 52.5)])
    data = src.read_bytes()
    src.write_bytes(data[:-20])
    with pytest.raises(TraceError, match=r"cut_gt.osi frame 1: Truncated message body"):
        detect_trace(src, tmp_path / "out.osi")


def test_a_truncated_mcap_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "cut.mcap"
    writer = MultiTraceWriter()
    assert writer.open(path)
    writer.add_channel("GroundTruth", GroundTruth, {})
    for i in range(3):
        assert writer.write_message(ground_truth(0.1 * i), "GroundTruth")
    writer.close()
    path.write_bytes(path.read_bytes()[:-200])
    with pytest.raises(TraceError, match=r"cut.mcap"):
        detect_trace(path, tmp_path / "out.mcap")


def test_the_wrong_message_type_is_named(tmp_path: Path) -> None:
    sd = OsiLaneSensor().step(ground_truth(), 0)
    src = _write_osi(tmp_path / "data_sv.osi", [sd])  # SensorData under a SensorView name
    with pytest.raises(TraceError, match=r"data_sv.osi frame 0: .*another message type"):
        detect_trace(src, tmp_path / "out.osi")
    named = _write_osi(tmp_path / "data_sd.osi", [sd])
    with pytest.raises(TraceError, match=r"data_sd.osi: the name says it holds SensorData"):
        list(read_messages(named))
    mcap = tmp_path / "data.mcap"
    writer = MultiTraceWriter()
    assert writer.open(mcap)
    writer.add_channel("SensorData", SensorData, {})
    assert writer.write_message(sd, "SensorData")
    writer.close()
    with pytest.raises(TraceError, match=r"no SensorView or GroundTruth channel"):
        detect_trace(mcap, tmp_path / "out.mcap")


def test_ground_truth_detector_and_tracking_jobs_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="ground_truth"):
        OsiLaneSensor("ground_truth")
    src = _write_osi(tmp_path / "x_gt.osi", [ground_truth()])
    with pytest.raises(ConfigError, match="one process"):
        detect_trace(src, tmp_path / "o.osi", detector_params={"tracking": True}, jobs=2)


def test_the_tracking_aldm_runs_on_a_trace(tmp_path: Path) -> None:
    frames = [ground_truth(0.1 * i, 50.0 + 2.5 * i) for i in range(8)]
    src = _write_osi(tmp_path / "t_gt.osi", frames)
    summary = detect_trace(src, tmp_path / "t_sd.osi", detector_params={"tracking": True})
    assert summary.frames == 8 and summary.found["ego_left"] == 1.0


def test_cli_detect(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from aldm_gym.cli import main

    src = _write_osi(tmp_path / "c_gt.osi", [ground_truth(0.1 * i, 50 + 2.5 * i) for i in range(3)])
    out = tmp_path / "c_sd.mcap"
    assert main(["osi", "detect", str(src), "--out", str(out), "--no-progress"]) == 0
    assert "3 frames" in capsys.readouterr().out
    assert [i for i, _ in read_messages(src)] == [0, 1, 2]
    assert out.exists()
    err = usage_error(["osi", "detect", str(tmp_path / "none.osi"), "--out", str(out)], capsys)
    assert "does not exist" in err
    err = usage_error(["osi", "detect", str(src), "--out", str(tmp_path / "x.txt")], capsys)
    assert ".mcap or .osi" in err
    err = usage_error(
        ["osi", "detect", str(src), "--out", str(out), "--tracking", "--jobs", "2"], capsys
    )
    assert "--jobs" in err
    err = usage_error(["osi", "detect", str(src), "--out", str(out), "--sensor", "bogus=1"], capsys)
    assert "--sensor" in err and "bogus" in err
    args = ["osi", "detect", str(src), "--out", str(out), "--no-progress"]
    assert main([*args, "--sensor", "preset=camera", "--sensor", "mount_x=2.0"]) == 0
    # --env: the sensor's and the detector's settings, as the env takes them
    env = ["--env", "sensor.preset=camera", "--env", "detector_params.tracking=model"]
    assert main([*args, *env]) == 0
    for extra, words in (
        (["--env", "road.xodr=motorway"], "sensor's and the detector's settings only"),
        (["--env", "detector_params.trackin=model"], "'tracking'"),
        (["--env", "sensor.preset=camera", "--sensor", "preset=camera"], "give one"),
        (["--env", "detector_params.tracking=model", "--jobs", "2"], "--jobs"),
        (["--env", "detector=naive"], "has its own flag: --detector"),
    ):
        assert words in usage_error([*args, *extra], capsys)
    src.write_bytes(src.read_bytes()[:-5])
    err = usage_error(["osi", "detect", str(src), "--out", str(out), "--no-progress"], capsys)
    assert "c_gt.osi frame 2" in err


def test_boundaries_without_ids_are_read() -> None:
    """Unset ids are not duplicates: a writer that leaves boundary ids out is read."""
    gt = ground_truth()
    for lb in gt.lane_boundary:
        lb.ClearField("id")
    frame = ViewReader().frame(gt, 0)
    assert len(frame.line_type) > 0 and len(frame.all_points) > 0


def test_a_noisy_sensor_gives_the_same_trace_every_time_and_with_any_jobs(
    env_trace, tmp_path: Path
) -> None:
    """The camera preset draws noise per frame from (seed, frame): the same trace on
    every run, with one process or two, and another with another seed."""
    from tests.osi.test_roundtrip import _all

    path = env_trace[0]

    def run(name: str, **kwargs) -> list[bytes]:
        out = tmp_path / name
        detect_trace(path, out, sensor={"preset": "camera"}, **kwargs)
        return [m.SerializeToString() for _, m in _all(out, "SensorData")]

    first = run("a.mcap")
    assert run("b.mcap") == first
    assert run("c.mcap", jobs=2) == first
    assert run("d.mcap", seed=1) != first
    with pytest.raises(ConfigError, match="seed must be an integer >= 0"):
        OsiLaneSensor(seed=-1)
