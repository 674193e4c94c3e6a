"""The compiled traffic engine (``traffic.engine = "compiled"``) against the Python path.

The contract (docs/env.md, "The traffic engine"):

1. the engine gives the same episodes bit for bit as the Python path computed with
   libm's elementary functions and plain arithmetic (its plain-Python twin), on every
   CPU: the ``libm_python_path`` fixture makes the Python path do that;
2. against the Python path as installed (numpy's functions, highway-env's results): bit
   for bit where numpy's scalar math agrees with libm (``LIBM_MATCHES_NUMPY``), else
   equal to rounding over short horizons and in the traffic's statistics. Both
   branches run on every CPU: the ``perturbed_python_path`` fixture moves numpy's
   results by one ulp on some inputs, as numpy's AVX-512 kernels do;
3. the engine hands a step back to the Python path whenever it cannot run it, says
   why (``engine.steps``), and warns once when a whole env step ran without it.
"""

from __future__ import annotations

import math
import struct
import warnings
from typing import Any

import gymnasium as gym
import numba
import numpy as np
import pytest
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.objects import Obstacle

import aldm_gym  # noqa: F401  (registers ALDMHighway-v0)
from aldm_gym.envs.traffic import compiled, kernels, scalar, straight_lanes, vehicles
from aldm_gym.envs.traffic import road as traffic_road
from aldm_gym.envs.traffic.compiled import COMPILED, CompiledTraffic
from aldm_gym.roads import reference_line

_LIBM = {
    "sin_scalar": math.sin,
    "cos_scalar": math.cos,
    "tan_scalar": math.tan,
    "atan_scalar": math.atan,
    "asin_scalar": math.asin,
}


def _plain_dot(monkeypatch: pytest.MonkeyPatch) -> None:
    """Plain dot products wherever the Python path chooses between them and numpy's."""
    for module in (vehicles, traffic_road, straight_lanes):
        monkeypatch.setattr(module, "PLAIN_DOT_MATCHES_NUMPY", True)


@pytest.fixture
def libm_python_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Python path computed with libm's functions and plain dot products: the
    engine's plain-Python twin (identical to the Python path as installed wherever
    numpy agrees with libm)."""
    for name, function in _LIBM.items():
        monkeypatch.setattr(vehicles, name, function)
    monkeypatch.setattr(scalar, "_POWER_FROM_LIBM", True)
    _plain_dot(monkeypatch)


def _off_by_one_ulp(function: Any) -> Any:
    """``function`` with its result moved by one ulp on about one input in eight (chosen
    by the input's bits, so the same input always gets the same result)."""

    def perturbed(x: float) -> float:
        y = function(x)
        bits = struct.unpack("<Q", struct.pack("<d", x))[0]
        if (bits * 0x9E3779B97F4A7C15 >> 61) & 7 == 0 and math.isfinite(y):
            return math.nextafter(y, math.inf if bits & 1 else -math.inf)
        return y

    return perturbed


@pytest.fixture
def perturbed_python_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The Python path with elementary functions that differ from libm's in the last bit
    on some inputs (what numpy's AVX-512 kernels do), on any CPU."""
    for name, function in _LIBM.items():
        monkeypatch.setattr(vehicles, name, _off_by_one_ulp(function))
    libm_power = scalar.power_scalar

    def power(x: float, exponent: float) -> float:
        return _off_by_one_ulp(lambda base: libm_power(base, exponent))(x)

    monkeypatch.setattr(scalar, "_POWER_FROM_LIBM", True)
    monkeypatch.setattr(vehicles, "power_scalar", power)
    _plain_dot(monkeypatch)


def _env(engine: str, **config: Any) -> Any:
    cfg: dict[str, Any] = {
        "vehicles_count": 20,
        "lanes_count": 4,
        "simulation_frequency": 10,
        "policy_frequency": 1,
        "duration": 1e4,
        **config,
    }
    cfg["traffic"] = {**cfg.get("traffic", {}), "engine": engine}
    return gym.make("ALDMHighway-v0", config=cfg)


def _vehicles(env: Any) -> list[tuple[Any, ...]]:
    return [
        (
            v.position.tobytes(),
            float(v.heading),
            float(v.speed),
            v.lane_index,
            getattr(v, "target_lane_index", None),
            bool(v.crashed),
            float(getattr(v, "timer", 0.0)),
            repr(sorted(v.action.items())),
        )
        for v in env.unwrapped.road.vehicles
    ]


@pytest.fixture
def kernel_calls(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts the compiled act and step calls that ran the traffic (returned True)."""
    counts = {"act": 0, "step": 0}
    for name in ("act", "step"):
        kernel = getattr(kernels, f"traffic_{name}")

        def counting(*args: Any, kernel: Any = kernel, name: str = name) -> bool:
            ok = kernel(*args)
            counts[name] += bool(ok)
            return ok

        monkeypatch.setattr(kernels, f"traffic_{name}", counting)
    return counts


def _rollout(
    engine: str, seed: int, steps: int, actions: str = "random", **config: Any
) -> list[Any]:
    env = _env(engine, **config)
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    trace: list[Any] = [sorted((k, v.tobytes()) for k, v in obs.items()), _vehicles(env)]
    for _ in range(steps):
        action = int(rng.integers(0, 5)) if actions == "random" else 1
        obs, reward, terminated, truncated, info = env.step(action)
        info.pop("action", None)
        trace.append((sorted((k, v.tobytes()) for k, v in obs.items()), reward, repr(info)))
        trace.append(_vehicles(env))
        if terminated or truncated:
            break
    env.close()
    return trace


def _crashes(trace: list[Any]) -> int:
    """Vehicles crashed at the end of a rollout."""
    return sum(row[5] for row in trace[-1])


_SCENES = [
    (0, {}),
    (1, {"traffic": {"truck_share": 0.3, "truck_lane_changes": True}}),
    (2, {"vehicles_count": 40, "lanes_count": 3}),
    (3, {"vehicles_density": 2.0, "lanes_count": 2}),
    (4, {"marking_model": "editor", "acc": {"enabled": False}}),
]


@pytest.mark.parametrize(("seed", "config"), _SCENES)
def test_episodes_are_bit_identical_to_the_libm_python_path(
    seed: int, config: dict, kernel_calls: dict[str, int], libm_python_path: None
) -> None:
    """Same seed, same episode, whichever engine runs the traffic, on every CPU."""
    python = _rollout("python", seed, 25, **config)
    assert kernel_calls["act"] == 0
    fast = _rollout("compiled", seed, 25, **config)
    assert fast == python
    steps = (len(fast) - 2) // 2  # env steps run
    assert kernel_calls["act"] == 10 * steps  # the engine decided every simulation step


def test_crashes_and_impacts_are_bit_identical(
    kernel_calls: dict[str, int], libm_python_path: None
) -> None:
    """Dense traffic with an aggressive ego: collisions happen, and match exactly."""
    crashed = 0
    for seed in range(3):
        config = {"vehicles_density": 3.0, "lanes_count": 2, "vehicles_count": 30}
        python = _rollout("python", seed, 30, actions="random", **config)
        fast = _rollout("compiled", seed, 30, actions="random", **config)
        assert fast == python
        crashed += _crashes(python)
    assert crashed > 0  # the scenes exercise impacts and crashed vehicles
    assert kernel_calls["act"] > 0


def _state(env: Any) -> tuple[np.ndarray, list[Any]]:
    """Every vehicle's ``(x, y, heading, speed)`` [m, m, rad, m/s] and its discrete state
    (lane, target lane, crashed)."""
    road_vehicles = env.unwrapped.road.vehicles
    floats = np.array([(*v.position, v.heading, v.speed) for v in road_vehicles])
    discrete = [
        (v.lane_index, getattr(v, "target_lane_index", None), bool(v.crashed))
        for v in road_vehicles
    ]
    return floats, discrete


_ROUNDING = 1e-6
"""Largest difference [m, rad, m/s, reward] between the engines over the short horizon
where numpy's functions differ from libm's by last bits (measured: below 1e-12 after
40 s on an AVX-512 CPU; a wrong operation in a kernel gives 1e-3 and more)."""


def _assert_equal_to_rounding(seed: int, steps: int, **config: Any) -> float:
    """Compiled and Python engine from the same seed: the same discrete states
    throughout, floats within :data:`_ROUNDING`; returns the largest float difference."""
    envs = [_env(engine, **config) for engine in ("python", "compiled")]
    for env in envs:
        env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    largest = 0.0
    for step in range(steps):
        action = int(rng.integers(0, 5))
        results = [env.step(action) for env in envs]
        (f_py, d_py), (f_c, d_c) = (_state(env) for env in envs)
        assert d_c == d_py, (seed, step)
        largest = max(largest, float(np.abs(f_c - f_py).max()))
        assert largest <= _ROUNDING, (seed, step)
        assert abs(results[1][1] - results[0][1]) <= _ROUNDING
        assert results[1][2:4] == results[0][2:4]  # terminated, truncated
        for key, value in results[0][0].items():
            np.testing.assert_allclose(results[1][0][key], value, atol=1e-4, err_msg=key)
        if results[0][2] or results[0][3]:
            break
    return largest


def _statistics(engine: str, seeds: range, steps: int) -> dict[str, float]:
    """The traffic's statistics over seeded IDLE episodes: mean speed [m/s] of the
    traffic, lane changes and crashed vehicles."""
    speeds: list[float] = []
    changes = crashed = 0
    for seed in seeds:
        env = _env(engine, vehicles_density=1.5)
        env.reset(seed=seed)
        road = env.unwrapped.road
        lanes = {id(v): v.lane_index for v in road.vehicles}
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(1)
            for v in road.vehicles[1:]:
                speeds.append(v.speed)
                changes += lanes.get(id(v)) != v.lane_index
                lanes[id(v)] = v.lane_index
            if terminated or truncated:
                break
        crashed += sum(v.crashed for v in road.vehicles)
        env.close()
    return {"speed": float(np.mean(speeds)), "lane_changes": changes, "crashed": crashed}


def _assert_same_statistics(seeds: range, steps: int) -> None:
    """Mean traffic speed within 0.05 m/s, lane changes within 10 % (or 2), crashed
    vehicles within 1, over the same seeded episodes on either engine."""
    python = _statistics("python", seeds, steps)
    fast = _statistics("compiled", seeds, steps)
    assert python["lane_changes"] >= 10  # the episodes exercise MOBIL
    assert abs(fast["speed"] - python["speed"]) <= 0.05
    assert abs(fast["lane_changes"] - python["lane_changes"]) <= max(
        2, 0.1 * python["lane_changes"]
    )
    assert abs(fast["crashed"] - python["crashed"]) <= 1


@pytest.mark.parametrize(("seed", "config"), _SCENES[:3])
def test_episodes_match_the_installed_python_path(seed: int, config: dict) -> None:
    """Against the Python path as installed: bit for bit where numpy's scalar math
    agrees with libm on this CPU, else to rounding (the branch this CPU takes; CI runs
    the suite again under numpy's AVX2 dispatch to take the other)."""
    if scalar.LIBM_MATCHES_NUMPY:
        assert _rollout("compiled", seed, 15, **config) == _rollout("python", seed, 15, **config)
    else:
        _assert_equal_to_rounding(seed, 15, **config)


def test_engines_agree_to_rounding_where_the_math_differs(perturbed_python_path: None) -> None:
    """Elementary functions one ulp off libm's on some inputs (numpy's AVX-512 kernels,
    emulated on any CPU): the engines still agree to rounding over the short horizon."""
    largest = max(_assert_equal_to_rounding(seed, 10, **config) for seed, config in _SCENES[:3])
    assert largest > 0.0  # the perturbation reached the Python path


def test_engines_agree_statistically_where_the_math_differs(
    perturbed_python_path: None,
) -> None:
    """... and in the traffic's statistics over many seeded episodes."""
    _assert_same_statistics(range(8), 20)


def test_engines_agree_statistically_on_this_cpu() -> None:
    """The same with the Python path as installed (identical where numpy agrees)."""
    _assert_same_statistics(range(8), 20)


def test_the_probe_and_the_python_path_agree() -> None:
    """The Python path uses libm's function exactly where the probe found numpy's equal
    to it, and numpy's elsewhere."""
    agrees = scalar.NUMPY_AGREES_WITH_LIBM
    assert set(agrees) == {"sin", "cos", "tan", "arctan", "arcsin", "power", "dot"}
    for name, function in (
        ("sin", math.sin),
        ("cos", math.cos),
        ("tan", math.tan),
        ("arctan", math.atan),
        ("arcsin", math.asin),
    ):
        chosen = getattr(scalar, {"arctan": "atan", "arcsin": "asin"}.get(name, name) + "_scalar")
        assert (chosen is function) == agrees[name]
    assert scalar.LIBM_MATCHES_NUMPY == all(agrees.values())
    assert scalar.FAST_MATH_MATCHES_NUMPY == scalar.LIBM_MATCHES_NUMPY
    assert scalar.PLAIN_DOT_MATCHES_NUMPY == agrees["dot"]
    features = scalar.numpy_simd_features()
    assert set(features) == {"baseline", "found", "disabled"}
    assert not set(features["found"]) & set(features["disabled"])


def _plain_python_kernels(monkeypatch: pytest.MonkeyPatch) -> int:
    """Replace every numba kernel of the engine (and of the reference line it projects
    on) by its plain-Python twin; the number replaced."""
    replaced = 0
    for module in (kernels, reference_line):
        for name, value in list(vars(module).items()):
            if isinstance(value, numba.core.registry.CPUDispatcher):
                monkeypatch.setattr(module, name, value.py_func)
                replaced += 1
    return replaced


def test_the_engine_equals_its_plain_python_twin(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled kernels and their plain-Python twins give the same episode, bit
    for bit, on every CPU (numba calls libm's functions, as ``math`` does)."""
    compiled_run = _rollout("compiled", 5, 3)
    assert _plain_python_kernels(monkeypatch) >= 15
    assert not isinstance(kernels.traffic_act, numba.core.registry.CPUDispatcher)
    assert _rollout("compiled", 5, 3) == compiled_run


def test_the_engine_runs_every_step_of_a_default_episode(kernel_calls: dict[str, int]) -> None:
    """With the default config no step falls back to the Python path."""
    env = _env("compiled")
    env.reset(seed=0)
    for _ in range(3):
        env.step(1)
    assert kernel_calls == {"act": 30, "step": 30}
    assert isinstance(env.unwrapped.road.engine, CompiledTraffic)
    assert env.unwrapped.road.engine.steps == {COMPILED: 30}
    env_py = _env("python")
    env_py.reset(seed=0)
    assert env_py.unwrapped.road.engine is None


def _split_after(env: Any) -> int | None:
    road = env.unwrapped.road
    return road.engine._split(road)


def test_unsupported_scenes_fall_back_to_the_python_path() -> None:
    """Road objects, trajectory recording, a Python vehicle after the compiled ones or a
    planned route: the engine declines, and the episode still runs."""
    env = _env("compiled")
    env.reset(seed=1)
    road = env.unwrapped.road
    assert _split_after(env) == 1  # the ego, then the compiled traffic

    engine = road.engine
    road.objects.append(Obstacle(road, road.vehicles[3].position + np.array([30.0, 0.0])))
    assert _split_after(env) is None
    assert engine.declined is not None and "road objects" in engine.declined
    road.objects.clear()

    road.record_history = True
    assert _split_after(env) is None
    assert "record_history" in engine.declined
    road.record_history = False

    last = road.vehicles[-1]
    road.vehicles.append(IDMVehicle.create_from(last))
    assert _split_after(env) is None
    assert "another class comes after" in engine.declined
    road.vehicles.pop()

    last.route = [("a", "b", 0)]
    assert _split_after(env) is None
    assert "planned route" in engine.declined
    last.route = None
    assert _split_after(env) == 1
    env.step(1)


def test_a_whole_env_step_on_the_python_path_is_warned_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The engine never switches off silently: the reason is counted per simulation
    step and warned once per process when a whole env step ran without the engine."""
    monkeypatch.setattr(compiled, "_WARNED", set())
    env = _env("compiled")
    env.reset(seed=1)
    road = env.unwrapped.road
    road.objects.append(Obstacle(road, road.vehicles[3].position + np.array([300.0, 0.0])))
    with pytest.warns(RuntimeWarning, match=r"ran on the Python path.*road objects"):
        env.step(1)
    reason = road.engine.declined
    assert road.engine.steps == {reason: 10}
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.step(1)  # the same reason again: no second warning
    road.objects.clear()
    env.step(1)
    assert road.engine.steps == {reason: 20, COMPILED: 10}


def test_steps_after_a_fallback_match_the_python_path(
    kernel_calls: dict[str, int], libm_python_path: None
) -> None:
    """A scene the engine declines for two env steps (an extra highway-env IDM vehicle
    at the end), then takes again once the vehicle is gone, runs the same with either
    engine setting."""

    def run(engine: str) -> list[Any]:
        env = _env(engine)
        env.reset(seed=6)
        road = env.unwrapped.road
        extra = IDMVehicle.create_from(road.vehicles[-1])
        extra.position = extra.position + np.array([60.0, 0.0])
        road.vehicles.append(extra)
        trace = []
        for t in range(5):
            env.step(1)
            if t == 1:
                road.vehicles.remove(extra)
            trace.append(_vehicles(env))
        return trace

    assert run("compiled") == run("python")
    assert kernel_calls["act"] == 30  # declined for 2 env steps, then 3 compiled ones


def test_lane_changes_of_the_road_between_env_steps_are_followed(libm_python_path: None) -> None:
    """A script that lowers a lane's speed limit and closes a lane to lane changes
    (highway-env reads both at every use) is followed from the next env step."""

    def run(engine: str) -> list[Any]:
        env = _env(engine)
        env.reset(seed=3)
        highway = env.unwrapped.highway
        saved = [(lane.speed_limit, lane.forbidden) for lane in highway.network.lanes_list()]
        trace = []
        try:
            for t in range(6):
                env.step(1)
                if t == 1:
                    highway.lane(1).speed_limit = 15.0
                    highway.lane(2).forbidden = True
                trace.append(_vehicles(env))
        finally:  # the road is cached and shared by later envs
            for lane, (limit, forbidden) in zip(highway.network.lanes_list(), saved, strict=True):
                lane.speed_limit, lane.forbidden = limit, forbidden
        return trace

    assert run("compiled") == run("python")


def test_non_finite_positions_take_the_python_path_and_its_error() -> None:
    """A NaN position is not given to the kernels: the step fails as on the Python path."""
    errors = []
    for engine in ("python", "compiled"):
        env = _env(engine)
        env.reset(seed=0)
        env.unwrapped.road.vehicles[5].position[0] = np.nan
        with pytest.raises(ValueError) as info:
            for _ in range(3):
                env.step(1)
        errors.append(str(info.value))
    assert errors[0] == errors[1]


def test_a_python_vehicle_gone_non_finite_within_a_block_is_counted_as_such() -> None:
    """Within ``holding`` the vehicles before the compiled ones are read again before
    each act: one whose position left the finite range sends the step to the Python
    path under that reason (not "off the lanes")."""
    env = _env("compiled")
    env.reset(seed=0)
    road = env.unwrapped.road
    engine: CompiledTraffic = road.engine
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with engine.holding():
            road.act()
            road.step(0.1)
            ego = road.vehicles[0]  # before the compiled ones: it acts first, in Python
            ego_act = ego.act

            def act_then_fly_off(*args: Any) -> None:
                ego_act(*args)
                ego.position[1] = 1e13  # beyond any coordinate the kernels take

            ego.act = act_then_fly_off
            assert engine.act(road)
    assert engine.steps[COMPILED] == 1
    assert engine.steps["a vehicle's position is not finite"] == 1
    assert sum(engine.steps.values()) == 2


def test_kernels_match_their_plain_python_twins() -> None:
    """Each compiled kernel computes what its plain-Python twin computes."""
    env = _env("compiled", vehicles_density=2.0)
    env.reset(seed=3)
    road = env.unwrapped.road
    engine: CompiledTraffic = road.engine
    for _ in range(3):
        env.step(1)
    first = engine._split(road)
    assert first is not None and engine._gather(road, first)
    f, k, p = engine._f, engine._k, engine._p
    tables = engine.act_tables
    f1, k1, f2, k2 = f.copy(), k.copy(), f.copy(), k.copy()
    empty = np.full((0, 4), np.nan)
    assert kernels.traffic_act(f1, k1, p, empty, *tables) is True
    assert kernels._traffic_act_py(f2, k2, p, empty, *tables) is True
    assert f1.tobytes() == f2.tobytes() and np.array_equal(k1, k2)
    step_tables = (0.1, *engine.step_tables)
    memo1, memo2 = np.full((len(f), 4), np.nan), np.full((len(f), 4), np.nan)
    assert kernels.traffic_step(f1, k1, p, memo1, *step_tables) is True
    assert kernels._traffic_step_py(f2, k2, p, memo2, *step_tables) is True
    assert f1.tobytes() == f2.tobytes() and np.array_equal(k1, k2)
    assert memo1.tobytes() == memo2.tobytes()
    assert np.isnan(memo1[:first]).all() and np.isfinite(memo1[first:]).all()
    # The next act with the memo gives the act without it, bit for bit.
    f3, k3, f4, k4 = f1.copy(), k1.copy(), f1.copy(), k1.copy()
    assert kernels.traffic_act(f3, k3, p, memo1, *tables) is True
    assert kernels.traffic_act(f4, k4, p, empty, *tables) is True
    assert f3.tobytes() == f4.tobytes() and np.array_equal(k3, k4)
    # Push two vehicles together so that the pair search has something to find.
    f1[2, kernels.F_X] = f1[1, kernels.F_X] + 1.0
    f1[2, kernels.F_Y] = f1[1, kernels.F_Y]
    ok, pairs = kernels.collision_pairs(f1, k1, 0.1)
    ok_py, pairs_py = kernels._collision_pairs_py(f1, k1, 0.1)
    assert ok and ok_py and np.array_equal(pairs, pairs_py)
    assert [1, 2] in pairs.tolist()
    f1[4, kernels.F_Y] = np.nan  # not finite: no pairs, the caller checks them all
    ok, pairs = kernels.collision_pairs(f1, k1, 0.1)
    assert not ok and len(pairs) == 0


def test_collision_pairs_include_every_colliding_pair() -> None:
    """Every pair highway-env's polygon test finds colliding is among the kernel's pairs."""
    from highway_env import utils

    rng = np.random.default_rng(0)
    found = 0
    for _ in range(200):
        n = 12
        f = np.zeros((n, kernels.F_COLUMNS))
        k = np.ones((n, kernels.K_COLUMNS), dtype=np.int64)
        f[:, kernels.F_X] = rng.uniform(0.0, 40.0, n)
        f[:, kernels.F_Y] = rng.uniform(-4.0, 4.0, n)
        f[:, kernels.F_HEADING] = rng.uniform(-0.3, 0.3, n)
        f[:, kernels.F_SPEED] = rng.uniform(0.0, 30.0, n)
        f[:, kernels.F_LENGTH] = rng.choice([5.0, 15.0], n)
        f[:, kernels.F_WIDTH] = 2.0
        f[:, kernels.F_DIAGONAL] = np.hypot(f[:, kernels.F_LENGTH], 2.0)
        ok, found_pairs = kernels.collision_pairs(f, k, 0.1)
        assert ok
        pairs = {tuple(p) for p in found_pairs.tolist()}
        for i in range(n):
            for j in range(i + 1, n):
                boxes = []
                for r in (i, j):
                    c, s = np.cos(f[r, kernels.F_HEADING]), np.sin(f[r, kernels.F_HEADING])
                    half = np.array([f[r, kernels.F_LENGTH], f[r, kernels.F_WIDTH]]) / 2
                    corners = np.array([[-1, -1], [-1, 1], [1, 1], [1, -1], [-1, -1]]) * half
                    rot = np.array([[c, -s], [s, c]])
                    boxes.append(corners @ rot.T + f[r, kernels.F_X : kernels.F_Y + 1])
                v_i = f[i, kernels.F_SPEED] * np.array([np.cos(f[i, 2]), np.sin(f[i, 2])])
                v_j = f[j, kernels.F_SPEED] * np.array([np.cos(f[j, 2]), np.sin(f[j, 2])])
                hit, will, _ = utils.are_polygons_intersecting(
                    boxes[0], boxes[1], v_i * 0.1, v_j * 0.1
                )
                if hit or will:
                    found += 1
                    assert (i, j) in pairs
    assert found > 50


def test_engine_setting_is_validated() -> None:
    """An unknown engine names the setting and the allowed values."""
    with pytest.raises(ValueError, match=r"traffic\.engine.*compiled.*python"):
        _env("numba").reset(seed=0)
    assert compiled.ENGINES == ("compiled", "python")


def test_vehicles_changed_between_env_steps_are_read_again(libm_python_path: None) -> None:
    """The engine keeps its arrays only within one env step (``holding``): a script
    that moves, slows or re-parameterises a vehicle between env steps is followed."""

    def run(engine: str) -> list[Any]:
        env = _env(engine)
        env.reset(seed=2)
        road = env.unwrapped.road
        trace = []
        for t in range(6):
            env.step(1)
            v = road.vehicles[3 + t]
            v.speed = v.speed - 4.0
            v.position[1] += 0.7
            v.DELTA = 3.7
            v.target_speed = 18.0
            trace.append(_vehicles(env))
        env.step(1)
        trace.append(_vehicles(env))
        return trace

    assert run("compiled") == run("python")


def test_holding_keeps_state_only_within_the_block() -> None:
    """Inside ``holding`` the engine reads the compiled vehicles once; a new block (the
    next env step) reads them all again."""
    env = _env("compiled")
    env.reset(seed=0)
    road = env.unwrapped.road
    engine: CompiledTraffic = road.engine
    reads = {"gather": 0, "refresh": 0}
    gather, refresh = engine._gather, engine._refresh

    def counting_gather(*args: Any) -> bool:
        reads["gather"] += 1
        return gather(*args)

    def counting_refresh(*args: Any) -> str | None:
        reads["refresh"] += 1
        return refresh(*args)

    engine._gather = counting_gather  # type: ignore[method-assign]
    engine._refresh = counting_refresh  # type: ignore[method-assign]
    env.step(1)
    env.step(1)
    # Per env step: one full read, then the ego alone before each of the 9 later acts
    # and after each of the 10 moves (for the collision pairs).
    assert reads == {"gather": 2, "refresh": 38}
    road.act()  # outside a block: everything is read
    road.step(0.1)
    assert reads["gather"] == 3
