"""The function interface and its driver on ``ALDMHighway-v0`` (generated roads)."""

from __future__ import annotations

import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import aldm_gym  # noqa: F401  (registers the env)
from aldm_gym.errors import InputError
from aldm_gym.function import (
    DOMAINS,
    BuiltinFunction,
    CallableFunction,
    FunctionDriver,
    FunctionInput,
    FunctionOutput,
    PerceivedLine,
    env_for,
    function_input,
)
from aldm_gym.function.interface import check_output

FAST = {"duration": 4, "vehicles_count": 6, "policy_frequency": 10}


def _env(**config: Any) -> Any:
    return gym.make("ALDMHighway-v0", config={**FAST, **config})


class Constant:
    """A function that requests the same thing every step."""

    def __init__(self, output: FunctionOutput, domains: frozenset[str]) -> None:
        self.output, self.domains = output, domains
        self.inputs: list[FunctionInput] = []

    def reset(self) -> None:
        self.inputs.clear()

    def step(self, inputs: FunctionInput) -> FunctionOutput:
        self.inputs.append(inputs)
        return self.output


def test_cubic_recovers_a_cubic_and_missing_lines_are_empty() -> None:
    x = np.linspace(5.0, 80.0, 20)
    c = np.array([1.6, 0.01, 2e-4, -1e-6])
    line = PerceivedLine("ego_left", np.column_stack([x, np.polynomial.polynomial.polyval(x, c)]))
    np.testing.assert_allclose(line.cubic(), c, rtol=1e-6, atol=1e-9)
    assert line.found and line.range == pytest.approx(80.0)
    empty = PerceivedLine("ego_right", np.zeros((0, 2)))
    assert not empty.found and empty.range == 0.0
    assert np.all(empty.cubic() == 0.0)


@pytest.mark.parametrize(
    ("output", "domains", "match"),
    [
        ("IDLE", frozenset(), "must return a FunctionOutput"),
        (FunctionOutput(acceleration=math.nan), frozenset({"longitudinal"}), "finite"),
        (FunctionOutput(steering=0.1, curvature=0.01), frozenset({"lateral"}), "not both|one"),
        (FunctionOutput(lane_change=2), frozenset(), "-1, 0 or 1"),
        (FunctionOutput(speed_step=True), frozenset(), "-1, 0 or 1"),
        (FunctionOutput(steering=0.1), frozenset({"longitudinal"}), "lateral domain"),
        (FunctionOutput(acceleration=1.0), frozenset({"lateral"}), "longitudinal"),
        (FunctionOutput(steering=0.0, lane_change=1), DOMAINS, "changes lanes itself"),
    ],
)
def test_bad_outputs_are_named(output: Any, domains: frozenset[str], match: str) -> None:
    with pytest.raises(InputError, match=match):
        check_output(output, domains)


def test_the_builtin_function_drives_exactly_as_the_idle_action() -> None:
    env_a, env_b = _env(), _env()
    try:
        obs_a, _ = env_a.reset(seed=5)
        driver = FunctionDriver(env_b, BuiltinFunction())
        obs_b, _ = driver.reset(seed=5)
        for _ in range(30):
            obs_a, _, term_a, trunc_a, info_a = env_a.step(1)
            obs_b, _, term_b, trunc_b, info_b = driver.step()
            for key in obs_a:
                assert np.array_equal(obs_a[key], obs_b[key]), key
            assert (term_a, trunc_a) == (term_b, trunc_b)
            assert info_a["speed"] == info_b["speed"]
            if term_a or trunc_a:
                break
    finally:
        env_a.close()
        env_b.close()


def test_inputs_are_the_env_perception() -> None:
    env = _env()
    try:
        env.reset(seed=2)
        u = env.unwrapped
        inputs = function_input(env)
        assert inputs.step == pytest.approx(0.1)
        assert inputs.time == 0.0
        assert [line.role for line in inputs.lines] == [
            "left_adjacent",
            "ego_left",
            "ego_right",
            "right_adjacent",
        ]
        np.testing.assert_array_equal(inputs.line("ego_left").points, u.detection.ego_left)
        assert inputs.ego.speed == pytest.approx(u.vehicle.speed)
        assert len(inputs.objects) == len(u.perception.objects) > 0
        assert {o.id for o in inputs.objects} == set(u.perception.objects.ids.tolist())
        with pytest.raises(InputError, match="no line role"):
            inputs.line("centre")
    finally:
        env.close()


def test_an_acceleration_request_replaces_the_acc_and_the_lka_still_steers() -> None:
    fn = Constant(FunctionOutput(acceleration=-2.0), frozenset({"longitudinal"}))
    env = _env()
    try:
        driver = FunctionDriver(env, fn)
        driver.reset(seed=1)
        v0 = env.unwrapped.vehicle.speed
        for _ in range(10):
            _, _, _, _, info = driver.step()
            assert env.unwrapped.vehicle.action["acceleration"] == pytest.approx(-2.0)
        assert env.unwrapped.vehicle.speed == pytest.approx(v0 - 2.0, abs=0.05)
        assert info["departures"] == 0  # the built-in LKA kept the lane
        assert len(fn.inputs) == 10 and fn.inputs[-1].time == pytest.approx(0.9)
    finally:
        env.close()


def test_a_curvature_request_steers_the_arc_and_the_acc_keeps_the_speed() -> None:
    fn = Constant(FunctionOutput(curvature=0.004), frozenset({"lateral"}))
    env = _env()
    try:
        driver = FunctionDriver(env, fn)
        driver.reset(seed=1)
        ego = env.unwrapped.vehicle
        acc = ego.acc_command  # the ACC's command on the reset's perception
        driver.step()
        assert ego.steering_iso == pytest.approx(math.atan(0.004 * env.unwrapped.lka.wheelbase))
        assert ego.action["acceleration"] == acc
    finally:
        env.close()


def test_a_lane_change_request_starts_the_builtin_lane_change() -> None:
    fn = Constant(FunctionOutput(lane_change=1), frozenset())
    env = _env(initial_lane_id=2, vehicles_count=1)
    try:
        driver = FunctionDriver(env, fn)
        driver.reset(seed=0)
        _, _, _, _, info = driver.step()
        assert info["lane_change"] == 1
    finally:
        env.close()


def test_request_refuses_bad_values() -> None:
    env = _env()
    try:
        env.reset(seed=0)
        u = env.unwrapped
        with pytest.raises(InputError, match="steering must be a finite"):
            u.request(steering=math.inf)
        with pytest.raises(InputError, match="not both"):
            u.request(steering=0.0, curvature=0.0)
        with pytest.raises(InputError, match="acceleration"):
            u.request(acceleration="fast")  # type: ignore[arg-type]
    finally:
        env.close()
    continuous = _env(action={"type": "ContinuousAction"})
    try:
        continuous.reset(seed=0)
        with pytest.raises(InputError, match="meta actions"):
            continuous.unwrapped.request(acceleration=1.0)
        with pytest.raises(InputError, match="meta actions"):
            FunctionDriver(continuous, BuiltinFunction())
    finally:
        continuous.close()


def test_a_function_returning_garbage_is_named() -> None:
    def bad(inputs: FunctionInput) -> Any:
        return 1

    env = _env()
    try:
        driver = FunctionDriver(env, CallableFunction(bad, domains=()))
        driver.reset(seed=0)
        with pytest.raises(InputError, match="CallableFunction must return a FunctionOutput"):
            driver.step()
    finally:
        env.close()


def test_an_object_without_the_protocol_is_refused() -> None:
    class NoStep:
        domains = frozenset()

        def reset(self) -> None: ...

    with pytest.raises(InputError, match="no step"):
        FunctionDriver(_env(), NoStep())  # type: ignore[arg-type]

    class WrongDomain(Constant):
        pass

    with pytest.raises(InputError, match="domains must be a set"):
        FunctionDriver(_env(), WrongDomain(FunctionOutput(), frozenset({"vertical"})))


def test_a_function_that_takes_a_domain_is_stepped_at_the_simulation_rate() -> None:
    lka = Constant(FunctionOutput(), frozenset({"lateral"}))
    assert env_for(lka, {})["policy_frequency"] == 10
    assert env_for(lka, {"simulation_frequency": 20})["policy_frequency"] == 20
    assert env_for(lka, {"policy_frequency": 5}, given={"policy_frequency"}) == {
        "policy_frequency": 5
    }
    assert "policy_frequency" not in env_for(BuiltinFunction(), {})
    lka.env_config = {"observation": {"line_confidence": True}}  # type: ignore[attr-defined]
    with pytest.raises(Exception, match="observation: the function under test needs"):
        env_for(lka, {"observation": {"line_confidence": False}}, given={"observation"})


def test_the_same_seed_gives_the_same_run_with_a_function() -> None:
    from examples.lane_centering import LaneCenteringChauffeur

    runs = []
    for _ in range(2):
        env = _env()
        try:
            driver = FunctionDriver(env, LaneCenteringChauffeur())
            driver.reset(seed=4)
            trace = []
            for _ in range(25):
                _, _, term, trunc, info = driver.step()
                trace.append((info["speed"], info["lateral_offset"]))
                if term or trunc:
                    break
            runs.append(trace)
        finally:
            env.close()
    assert runs[0] == runs[1]


def test_a_function_stepped_slower_than_the_simulation_is_warned_about() -> None:
    from aldm_gym.errors import AldmGymWarning

    lka = Constant(FunctionOutput(curvature=0.0), frozenset({"lateral"}))
    with pytest.warns(AldmGymWarning, match="policy_frequency=1 Hz.*env_for"):
        FunctionDriver(gym.make("ALDMHighway-v0"), lka)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        FunctionDriver(gym.make("ALDMHighway-v0", config=env_for(lka, {})), lka)
        FunctionDriver(gym.make("ALDMHighway-v0"), BuiltinFunction())  # takes no domain


def test_domains_that_are_not_a_set_are_refused() -> None:
    for domains in (None, 3, "lateral"):
        with pytest.raises(InputError, match="domains must be a set"):
            FunctionDriver(_env(), Constant(FunctionOutput(), domains))  # type: ignore[arg-type]
