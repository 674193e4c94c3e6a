"""The line sensor and the ALDM as an OSMP sensor-model FMU, loaded by a real FMI host
(fmpy): SensorView buffers passed by pointer, SensorData read back, equal message for
message to ``aldm-gym osi detect``."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import pytest
from lxml import etree

from aldm_gym.cli import main
from aldm_gym.errors import ConfigError
from aldm_gym.osi import detect_trace, read_messages
from aldm_gym.osi.osmp import (
    OSMPHost,
    OSMPSensorModel,
    build_sensor_fmu,
    pack_pointer,
    unpack_pointer,
)
from tests.osi.conftest import record
from tests.osi.test_roundtrip import _all

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

OSMP_NS = "http://xsd.pmsf.net/OSISensorModelPackaging"


@pytest.fixture(scope="module")
def trace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 21-frame SensorView trace of the env (vehicles, a generated road)."""
    path = tmp_path_factory.mktemp("osmp") / "run.mcap"
    record(path, {}, steps=2)
    return path


def _views(path: Path) -> list[bytes]:
    return [m.SerializeToString() for _, m in read_messages(path, "SensorView")]


@pytest.mark.parametrize("address", [0, 1, 0x7FFF_FFFF, 0x8000_0000, 0x7F12_3456_789A, 2**64 - 1])
def test_pointers_round_trip_through_two_signed_int32(address: int) -> None:
    lo, hi = pack_pointer(address)
    assert -(2**31) <= lo < 2**31 and -(2**31) <= hi < 2**31
    assert unpack_pointer(lo, hi) == address


@pytest.mark.parametrize(("tracking", "params"), [("none", {}), ("points", {"tracking": True})])
def test_the_fmu_gives_what_osi_detect_gives(
    trace: Path, tmp_path: Path, tracking: str, params: dict[str, Any]
) -> None:
    out = tmp_path / "sd.mcap"
    detect_trace(trace, out, detector_params=params)
    expected = [m.SerializeToString() for _, m in _all(out, "SensorData")]
    fmu = build_sensor_fmu(tmp_path / "sensor.fmu", tracking=tracking)
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu)) == []
    host = OSMPHost(fmu)
    try:
        views = _views(trace)
        assert [host.step(v) for v in views] == expected
        host.reset()  # fmi2Reset: the tracker starts afresh
        assert [host.step(v) for v in views] == expected
    finally:
        host.close()


def test_parameters_choose_the_setting_of_one_fmu(trace: Path, tmp_path: Path) -> None:
    out = tmp_path / "sd.mcap"
    detect_trace(trace, out, detector_params={"tracking": "model"}, sensor={"preset": "camera"})
    expected = [m.SerializeToString() for _, m in _all(out, "SensorData")]
    fmu = build_sensor_fmu(tmp_path / "plain.fmu")  # built single-frame, ideal sensor
    host = OSMPHost(fmu, {"tracking": "model", "settings": '{"sensor": {"preset": "camera"}}'})
    try:
        assert [host.step(v) for v in _views(trace)] == expected
    finally:
        host.close()


def test_a_ground_truth_only_view_works_as_a_ground_truth_input(
    trace: Path, tmp_path: Path
) -> None:
    """A SensorView holding only the global ground truth (how a host wraps esmini's
    GroundTruth) gives what ``osi detect`` gives on the GroundTruth messages."""
    from aldm_gym.osi import OsiLaneSensor
    from aldm_gym.osi._bindings import osi3

    reference = OsiLaneSensor()  # osi detect's model, frame by frame
    views, expected = [], []
    for index, sv in read_messages(trace, "SensorView"):
        expected.append(reference.step(sv.global_ground_truth, index).SerializeToString())
        only = osi3.SensorView()
        only.global_ground_truth.CopyFrom(sv.global_ground_truth)
        views.append(only.SerializeToString())
    host = OSMPHost(build_sensor_fmu(tmp_path / "gt.fmu"))
    try:
        assert [host.step(v) for v in views] == expected
    finally:
        host.close()


def test_bad_input_is_not_valid_and_the_next_good_one_is(trace: Path, tmp_path: Path) -> None:
    host = OSMPHost(build_sensor_fmu(tmp_path / "s.fmu"))
    try:
        good = _views(trace)[0]
        assert host.step(b"") is None
        assert host.step(b"\xff\xfe not protobuf") is None
        assert host.step(good) is not None
    finally:
        host.close()
    model = OSMPSensorModel()
    assert model.step(0, 0, 10) == (0, 0, 0) and "no SensorView" in model.error
    assert model.step(1, 0, -5) == (0, 0, 0)


def test_the_model_description_carries_the_osmp_annotations(tmp_path: Path) -> None:
    fmu = build_sensor_fmu(tmp_path / "s.fmu", tracking="model", sensor={"preset": "camera"})
    root = etree.fromstring(zipfile.ZipFile(fmu).read("modelDescription.xml"))
    package = root.find(f"VendorAnnotations/Tool[@name='net.pmsf.osmp']/{{{OSMP_NS}}}osmp")
    assert package is not None and package.get("version") == "1.5.0"
    assert package.get("osi-version", "").startswith("3.")
    binaries = root.findall(f".//ScalarVariable/Annotations/Tool/{{{OSMP_NS}}}osmp-binary-variable")
    roles = {(b.get("name"), b.get("role")) for b in binaries}
    assert roles == {
        (n, r)
        for n in ("OSMPSensorViewIn", "OSMPSensorDataOut")
        for r in ("base.lo", "base.hi", "size")
    }
    assert all("type=Sensor" in b.get("mime-type", "") for b in binaries)
    starts = {
        v.get("name"): v.find("String").get("start")
        for v in root.iter("ScalarVariable")
        if v.find("String") is not None
    }
    assert root.find("DefaultExperiment").get("stepSize") == "0.1"
    assert starts["tracking"] == "model"
    assert starts["settings"] == '{"sensor": {"preset": "camera"}}'


def test_bad_settings_are_refused_before_packaging(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="tracking must be one of"):
        build_sensor_fmu(tmp_path / "s.fmu", tracking="kalman")
    with pytest.raises(ConfigError, match="preset"):
        build_sensor_fmu(tmp_path / "s.fmu", sensor={"preset": "fog"})
    assert not (tmp_path / "s.fmu").exists()


def test_the_command_writes_an_fmu(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "aldm.fmu"
    argv = ["osi", "fmu", str(out), "--tracking", "points", "--env", "sensor.preset=camera"]
    assert main(argv) == 0
    assert "OSMP 1.5.0 sensor-model FMU" in capsys.readouterr().out
    text = zipfile.ZipFile(out).read("modelDescription.xml").decode()
    assert 'start="points"' in text and "camera" in text


def test_an_output_stays_valid_until_the_second_step_after_it(trace: Path) -> None:
    """OSMP: the SensorData of step k is readable until step k + 2 starts."""
    import ctypes

    model = OSMPSensorModel()
    views = _views(trace)[:2]
    buffers = [ctypes.create_string_buffer(v, len(v)) for v in views]

    def step(k: int) -> tuple[int, int, int]:
        lo, hi = pack_pointer(ctypes.addressof(buffers[k]))
        return model.step(lo, hi, len(views[k]))

    lo, hi, size = step(0)
    first = ctypes.string_at(unpack_pointer(lo, hi), size)
    step(1)
    assert model._previous is not None  # the first output, still held
    assert ctypes.addressof(model._previous) == unpack_pointer(lo, hi)
    assert ctypes.string_at(unpack_pointer(lo, hi), size) == first


def test_the_command_takes_tracking_from_env_or_config(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "c.yaml"
    config.write_text("detector_params:\n  tracking: model\nacc:\n  time_gap: 2.0\n")
    out = tmp_path / "from_config.fmu"
    assert main(["osi", "fmu", str(out), "--config", str(config)]) == 0
    captured = capsys.readouterr()
    assert "tracking model" in captured.out
    assert "sections of --config only" in captured.err  # acc is not the FMU's
    assert 'start="model"' in zipfile.ZipFile(out).read("modelDescription.xml").decode()
    out = tmp_path / "from_env.fmu"
    assert main(["osi", "fmu", str(out), "--env", "detector_params.tracking=true"]) == 0
    assert "tracking points" in capsys.readouterr().out


def test_a_bad_tracking_value_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests._cli import usage_error

    line = usage_error(
        ["osi", "fmu", str(tmp_path / "x.fmu"), "--env", "detector_params.tracking=kalman"],
        capsys,
    )
    assert "tracking must be one of [False, True, 'model']" in line
