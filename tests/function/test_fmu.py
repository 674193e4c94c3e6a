"""A function under test in an FMU: built with pythonfmu (FMI 2.0 co-simulation), run
with fmpy, on a generated highway and on the OSC-ALKS cut-in from the command line."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.errors import InputError
from aldm_gym.function import FunctionDriver, FunctionInput, env_for, load_function
from aldm_gym.function.fmu import FMUFunction

pytest.importorskip("fmpy")
pythonfmu = pytest.importorskip("pythonfmu")

SOURCE = Path(__file__).with_name("fmu_lane_centering.py")

BAD_SOURCE = """
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class {name}(Fmi2Slave):
    author = "aldm-gym tests"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.speed = 0.0
        self.out = 0.0
        self.register_variable(Real("{input}", causality=Fmi2Causality.input,
            getter=lambda: self.speed, setter=lambda v: setattr(self, "speed", v)))
        {output}

    def do_step(self, current_time, step_size):
        return True
"""


def _build(script: Path, folder: Path) -> Path:
    from pythonfmu import FmuBuilder

    return Path(FmuBuilder.build_FMU(script, dest=folder))


@pytest.fixture(scope="module")
def fmu(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The lane-centering FMU of ``fmu_lane_centering.py``."""
    return _build(SOURCE, tmp_path_factory.mktemp("fmu"))


def _bad(tmp_path: Path, name: str, input_name: str, with_output: bool) -> Path:
    output = (
        'self.register_variable(Real("out", causality=Fmi2Causality.output, '
        "getter=lambda: self.out))"
        if with_output
        else ""
    )
    script = tmp_path / f"{name}.py"
    script.write_text(BAD_SOURCE.format(name=name, input=input_name, output=output))
    return _build(script, tmp_path)


def test_the_fmu_passes_fmpy_validation_and_declares_both_domains(fmu: Path) -> None:
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(fmu)) == []
    function = FMUFunction(fmu)
    try:
        assert function.domains == frozenset({"lateral", "longitudinal"})
        assert function.slots == [0, 1, 2, 3]
        assert set(function.outputs) == {"curvature", "acceleration"}
    finally:
        function.close()


def test_the_fmu_keeps_its_lane_and_resets_between_episodes(fmu: Path) -> None:
    function = load_function(str(fmu))
    env = gym.make("ALDMHighway-v0", config=env_for(function, {"duration": 6, "vehicles_count": 6}))
    try:
        driver = FunctionDriver(env, function)
        traces = []
        for _ in range(2):
            driver.reset(seed=3)
            trace = []
            for _ in range(60):
                _, _, term, trunc, info = driver.step()
                trace.append((info["speed"], info["lateral_offset"]))
                if term or trunc:
                    break
            assert info["departures"] == 0 and not info["crashed"]
            assert all(abs(offset) < 0.5 for _, offset in trace)
            traces.append(trace)
        assert traces[0] == traces[1]  # fmi2Reset: the second episode starts afresh
    finally:
        function.close()  # type: ignore[attr-defined]
        env.close()


def test_the_inputs_follow_the_convention(fmu: Path) -> None:
    env = gym.make("ALDMHighway-v0", config={"vehicles_count": 6})
    function = FMUFunction(fmu)
    try:
        env.reset(seed=1)
        from aldm_gym.function import function_input

        inputs: FunctionInput = function_input(env)
        values = function.values(inputs)
        assert set(values) == set(function.inputs)
        left = inputs.line("ego_left")
        assert values["line.ego_left.c0"] == pytest.approx(left.cubic()[0])
        assert values["line.ego_left.valid"] == 1.0
        nearest = min(inputs.objects, key=lambda o: o.x**2 + o.y**2)
        assert values["object[0].x"] == pytest.approx(nearest.x)
        assert values["object[0].valid"] == 1.0
    finally:
        function.close()
        env.close()


def test_a_mistyped_input_is_named_with_the_nearest(tmp_path: Path) -> None:
    path = _bad(tmp_path, "Mistyped", "ego.sped", with_output=True)
    with pytest.raises(InputError, match=r"input 'ego\.sped'.*did you mean 'ego\.speed'") as info:
        FMUFunction(path)
    assert "the FMU has inputs ['ego.sped'] and outputs ['out']" in str(info.value)


def test_an_unknown_output_is_named(tmp_path: Path) -> None:
    path = _bad(tmp_path, "OddOutput", "ego.speed", with_output=True)
    with pytest.raises(InputError, match=r"output 'out' is not in .*outputs: acceleration"):
        FMUFunction(path)


def test_an_fmu_without_outputs_is_refused(tmp_path: Path) -> None:
    path = _bad(tmp_path, "Silent", "ego.speed", with_output=False)
    with pytest.raises(InputError, match=r"has no output.*outputs none"):
        FMUFunction(path)


@pytest.mark.parametrize("content", [b"", b"not a zip", None])
def test_a_broken_fmu_is_a_clear_error(tmp_path: Path, content: Any) -> None:
    path = tmp_path / "broken.fmu"
    if content is None:
        with zipfile.ZipFile(path, "w") as z:
            z.writestr("modelDescription.xml", "<fmiModelDescription")
    else:
        path.write_bytes(content)
    with pytest.raises(InputError, match=r"broken\.fmu is not a readable FMU"):
        FMUFunction(path)
    with pytest.raises(InputError, match="no FMU at"):
        FMUFunction(tmp_path / "missing.fmu")


def test_an_fmi3_fmu_brakes_and_asks_for_a_lane_change(tmp_path: Path) -> None:
    pythonfmu3 = pytest.importorskip("pythonfmu3")
    path = Path(pythonfmu3.FmuBuilder.build_FMU(SOURCE.with_name("fmu3_brake.py"), dest=tmp_path))
    function = FMUFunction(path)
    env = gym.make(
        "ALDMHighway-v0", config={"policy_frequency": 10, "duration": 5, "initial_lane_id": 2}
    )
    try:
        assert function.fmi_version == "3.0"
        assert function.domains == frozenset({"longitudinal"})
        driver = FunctionDriver(env, function)
        for _ in range(2):  # fmi3Reset between the episodes
            driver.reset(seed=0)
            speeds, changes = [], []
            for _ in range(30):
                _, _, _, _, info = driver.step()
                speeds.append(info["speed"])
                changes.append(info["lane_change"])
            # the request of the step at 1 s starts the change at the next one
            assert changes[:10] == [0] * 10 and changes[10] == 1
            assert speeds[-1] < speeds[0] - 2.0  # braking towards 15 m/s
    finally:
        function.close()
        env.close()
