"""Fuzzing what a user passes: each input works or raises an error naming it.

Seeded random cases for the env config (keys and values drawn from the declared rules
of :mod:`aldm_gym.config`, then out of range, of the wrong type, numpy scalars,
NaN/inf, huge and tiny), actions, :meth:`LineSensor.measure` inputs, road methods,
:func:`detect_lanes` points and its parameters (:class:`ALDMParams`). A case passes
when it runs, or raises ``ValueError``/``TypeError`` whose message names the key or
argument at fault. Each group runs in a subprocess (this file run as a script), so a
segmentation fault fails its test instead of killing the test runner.

Inputs known to fail are listed in :data:`KNOWN_FAILURES` and tested one by one as
strict xfails: once fixed, the xfail passes, the test fails, and the entry goes.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

SEED = 12
"""Seed of every group's cases (a run repeats exactly)."""

CASES = {
    "config": 250,
    "action": 60,
    "sensor": 80,
    "road": 80,
    "points": 80,
    "params": 160,
}
"""Cases per group (bounded: a few seconds to half a minute each)."""

KNOWN_FAILURES: dict[str, str] = {}
"""``"group:case label" -> reason`` of inputs that still crash or raise an unnamed error
(each a strict xfail). Empty: the 24 found when the suite was written are fixed."""

Case = tuple[str, tuple[str, ...], Callable[[], Any]]
"""A case: its label, the names an error must mention (any one), and the call."""


# --- values --------------------------------------------------------------------------


def _bad_values(rng: random.Random) -> list[Any]:
    """Values no number/bool/choice rule should take silently."""
    return [
        float("nan"),
        float("inf"),
        -float("inf"),
        1e20,
        -1e20,
        1e-300,
        "abc",
        None,
        [1.0, 2.0],
        {"a": 1},
        True,
        object(),
        np.float32(rng.uniform(-1e6, 1e6)),
        np.int64(rng.randint(-(10**6), 10**6)),
        np.array([1.0]),
        2**70,
    ]


def _rule_values(rule: Any, default: Any, rng: random.Random, bound: Callable) -> list[Any]:
    """Values for one field: valid ones from its rule, then edge and bad ones."""
    out: list[Any] = []
    lo, hi = bound(rule.lo), bound(rule.hi)
    if rule.kind == "number":
        a = lo if lo is not None else -1e3
        b = hi if hi is not None else 1e3
        v = rng.uniform(a, b)
        out += [round(v) if rule.integer else v, np.float64(v), np.int64(int(v))]
        out += [a, b, b * 10 + 1, a - 1]
    elif rule.kind == "bool":
        out += [True, False, np.bool_(True), 1, "yes"]
    elif rule.kind in ("choice",):
        out += [*rule.choices, "nope", 3]
    elif rule.kind == "str":
        out += ["", "x", "os.path", "highway_env.vehicle.kinematics.Vehicle", 5]
    elif rule.kind in ("pair", "numbers"):
        a = lo if lo is not None else 0.0
        b = hi if hi is not None else 100.0
        x, y = sorted(rng.uniform(a, b) for _ in range(2))
        out += [[x, y], (np.float32(x), np.float32(y)), [y + 1, x], [x], [], [x, y, y]]
        out += [[x, float("nan")], np.array([x, y]), [[x, y]], "ab"]
    out += rng.sample(_bad_values(rng), 4)
    if default is not None and not isinstance(default, str | bool):
        out.append(default)
    return out


def _field_cases(cls: Any, rng: random.Random) -> Iterator[tuple[str, Any]]:
    """(field, value) pairs of a config dataclass, from its declared rules."""
    from aldm_gym.config import defaults, rules

    base = defaults(cls)

    def bound(b: Any) -> Any:
        return base.get(b) if isinstance(b, str) else b

    for name, rule in rules(cls).items():
        if rule.kind == "any":
            continue
        for value in _rule_values(rule, base.get(name), rng, bound):
            yield name, value


def _names(cls: Any, name: str) -> tuple[str, ...]:
    """``name`` and the fields of ``cls`` it bounds (an error may name either)."""
    from aldm_gym.config import rules

    return (name, *(f for f, r in rules(cls).items() if name in (r.lo, r.hi)))


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


# --- case groups ---------------------------------------------------------------------


def _config_cases(rng: random.Random) -> list[Case]:
    import gymnasium as gym

    from aldm_gym import ENV_ID
    from aldm_gym.envs.config import SECTIONS, EnvConfig
    from aldm_gym.sensor.aldm import ALDMParams

    pool: list[tuple[str, dict[str, Any], tuple[str, ...]]] = []
    for name, value in _field_cases(EnvConfig, rng):
        pool.append((f"config {name}={_short(value)}", {name: value}, _names(EnvConfig, name)))
    for section, cls in SECTIONS.items():
        for name, value in _field_cases(cls, rng):
            cfg = {section: {name: value}}
            pool.append((f"config {section}.{name}={_short(value)}", cfg, _names(cls, name)))
    for name, value in _field_cases(ALDMParams, rng):
        cfg = {"detector": "aldm", "detector_params": {name: value}}
        label = f"config detector_params.{name}={_short(value)}"
        pool.append((label, cfg, _names(ALDMParams, name)))
    for value in (5, "abc", [("duration", 5)], {1: 2}, {"nope": 1}, {"road": 3}):
        pool.append((f"config={_short(value)}", value, ("config", "road", "nope")))
    for value in ({1: 2}, {None: 1}, {"search_lenght": 3.0}):
        pool.append(
            (f"config detector_params={_short(value)}", {"detector_params": value}, ("key",))
        )
    chosen = rng.sample(pool, min(CASES["config"], len(pool)))

    def run(cfg: Any) -> Callable[[], Any]:
        def call() -> None:
            env = gym.make(ENV_ID, config=cfg)
            try:
                env.reset(seed=0)
                for _ in range(2):
                    env.step(env.action_space.sample())
            finally:
                env.close()

        return call

    return [(label, names, run(cfg)) for label, cfg, names in chosen]


def _action_cases(rng: random.Random) -> list[Case]:
    import gymnasium as gym

    from aldm_gym import ENV_ID

    envs = {
        kind: gym.make(
            ENV_ID,
            config={"action": {"type": kind}, "vehicles_count": 3, "detector": "naive"},
        )
        for kind in ("DiscreteMetaAction", "ContinuousAction")
    }
    for env in envs.values():
        env.reset(seed=0)
    discrete = [0, 4, np.int64(2), np.array(1), np.array([3]), 1.5, 4.99, "1", True]
    discrete += [None, float("nan"), float("inf"), [], [1, 2], np.array([1, 2]), -1, 5]
    discrete += [2**70, np.float32(1.0), object()]
    continuous = [np.zeros(2), [0.1, -0.2], np.zeros((2, 1)), np.zeros((1, 2)), np.zeros(3)]
    continuous += [np.array([np.nan, 0.0]), np.array([np.inf, 0.0]), [1e20, 1e20], "ab"]
    continuous += [None, 0.5, np.zeros(2, dtype=np.float32), np.array(["a", "b"]), []]
    pool = [("DiscreteMetaAction", a) for a in discrete]
    pool += [("ContinuousAction", a) for a in continuous]
    pool += [(k, [rng.uniform(-2, 2) for _ in range(2)]) for k in envs]
    chosen = pool[: CASES["action"]]

    def run(kind: str, action: Any) -> Callable[[], Any]:
        def call() -> None:
            env = envs[kind]
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset(seed=1)

        return call

    return [(f"{k} action={_short(a)}", ("action",), run(k, a)) for k, a in chosen]


def _pose_values(rng: random.Random) -> list[Any]:
    x, y, h = rng.uniform(0, 5000), rng.uniform(-5, 10), rng.uniform(-0.3, 0.3)
    return [
        (x, y, h),
        np.array([x, y, h]),
        (float("nan"), y, h),
        (x, float("inf"), h),
        (x, y, float("nan")),
        (x, y),
        (x, y, h, 0.0),
        np.zeros((3, 1)),
        [],
        "abc",
        None,
        (1e20, 0.0, 0.0),
        (x, 1e6, h),
        (np.float32(x), np.int64(2), h),
    ]


def _sensor_cases(rng: random.Random) -> list[Case]:
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor

    road = HighwayRoad({"length": 2000.0})
    sensor = LineSensor(seed=0)
    pool: list[Case] = []
    for pose in _pose_values(rng):
        pool.append(
            (f"measure pose={_short(pose)}", ("pose",), lambda p=pose: sensor.measure(road, p))
        )
    good = (100.0, 1.8, 0.0)
    extra = {
        "t": [float("nan"), float("inf"), -1.0, "abc", None, 1e20],
        "s_hint": [float("nan"), float("inf"), -50.0, 1e20, 1500.0, 100.0, "x", np.float32(100)],
        "ext_rotation": [(0.0, 0.0), (np.nan, 0, 0), (0, 0, 0.1), "abc", None, np.zeros(4)],
        "ext_travel": [(0.0, 0.0), (np.inf, 0, 0), (0, 0.5, 0), "abc", None],
        "rng": ["abc", 3, None],
    }
    for name, values in extra.items():
        for value in values:
            kwargs = {name: value}
            pool.append(
                (
                    f"measure pose={good} {name}={_short(value)}",
                    (name,),
                    lambda kw=kwargs: sensor.measure(road, good, **kw),
                )
            )
    pool.append(("measure road='abc'", ("road",), lambda: sensor.measure("abc", good)))
    return rng.sample(pool, min(CASES["sensor"], len(pool)))


def _road_cases(rng: random.Random) -> list[Case]:
    from aldm_gym.roads import HighwayRoad

    road = HighwayRoad({"length": 2000.0})
    pool: list[Case] = []
    positions = [(100.0, 2.0), (np.nan, 0.0), (0.0, np.inf), (1.0,), (1.0, 2.0, 3.0), "ab"]
    positions += [None, np.zeros((2, 2)), (1e20, 0.0), (-500.0, 0.0), (5000.0, 0.0)]
    for method in ("locate", "lane_position", "lane_id_at"):
        for pos in positions:
            pool.append(
                (
                    f"road.{method}({_short(pos)})",
                    ("position",),
                    lambda m=method, p=pos: getattr(road, m)(p),
                )
            )
    lane_ids = [0, 3, -1, 4, 99, 1.5, "a", None, np.int64(1), True, float("nan")]
    for method in ("lane_offset", "lane", "lane_boundaries", "boundary_markings"):
        for lane_id in lane_ids:
            pool.append(
                (
                    f"road.{method}({_short(lane_id)})",
                    ("lane_id",),
                    lambda m=method, i=lane_id: getattr(road, m)(i),
                )
            )
    for d in (0.0, 5.0, -100.0, float("nan"), float("inf"), "x", None):
        pool.append(
            (f"road.lane_of_offset({_short(d)})", ("d",), lambda v=d: road.lane_of_offset(v))
        )
    arcs = [10.0, np.array([1.0, 2.0]), float("nan"), float("inf"), -10.0, 1e20, "s", None]
    arcs += [np.array([1.0, np.nan]), np.zeros((2, 2))]
    for s in arcs:
        pool.append((f"road.curvature_at({_short(s)})", ("s",), lambda v=s: road.curvature_at(v)))
        for j in (0, 4, 5, -1, 1.5):
            pool.append(
                (
                    f"road.marking_position({j}, {_short(s)})",
                    ("s", "j"),
                    lambda i=j, v=s: road.marking_position(i, v),
                )
            )
    xs = np.arange(0.0, 100.0, 2.0)
    bad_xs = np.array([np.nan, 1.0])
    visible_args = [
        ("origin=(100,1.8) yaw=0 xs=0..98", ((100.0, 1.8), 0.0, xs, None)),
        ("origin=(nan,1.8)", ((np.nan, 1.8), 0.0, xs, None)),
        ("yaw=nan", ((100.0, 1.8), float("nan"), xs, None)),
        ("xs=[nan,1]", ((100.0, 1.8), 0.0, bad_xs, None)),
        ("s_origin=inf", ((100.0, 1.8), 0.0, xs, float("inf"))),
        ("s_origin=1500 (far from origin)", ((100.0, 1.8), 0.0, xs, 1500.0)),
        ("origin=(100,)", ((100.0,), 0.0, xs, None)),
        ("xs of shape (2,2)", ((100.0, 1.8), 0.0, np.zeros((2, 2)), None)),
        ("yaw='a'", ((100.0, 1.8), "a", xs, None)),
    ]
    for label, args in visible_args:
        for method in ("sample_visible", "sample_markings"):
            pool.append(
                (
                    f"road.{method}({label})",
                    ("origin", "yaw", "xs", "s_origin"),
                    lambda m=method, a=args: getattr(road, m)(*a),
                )
            )
    return rng.sample(pool, min(CASES["road"], len(pool)))


def _points_values(rng: random.Random) -> list[tuple[str, Any]]:
    """Named point clouds: valid, with NaN/inf, empty, of wrong shape or dtype, huge."""
    nprng = np.random.default_rng(rng.randrange(2**32))
    n = rng.randint(5, 300)
    cloud = np.column_stack([nprng.uniform(0, 100, n), nprng.uniform(-6, 6, n)])
    with_z = np.column_stack([cloud, nprng.uniform(-1, 1, n)])
    some_nan = cloud.copy()
    some_nan[nprng.integers(0, n, 3), nprng.integers(0, 2, 3)] = np.nan
    some_inf = with_z.copy()
    some_inf[0, 0] = np.inf
    return [
        (f"({n},2)", cloud),
        (f"({n},3)", with_z),
        (f"({n},2) some NaN", some_nan),
        (f"({n},3) one inf", some_inf),
        (f"({n},2) all NaN", np.full((n, 2), np.nan)),
        ("(0,2)", np.zeros((0, 2))),
        ("(0,3)", np.zeros((0, 3))),
        (f"({n},4)", np.zeros((n, 4))),
        (f"({n},)", np.zeros(n)),
        (f"(2,{n})", cloud.T),
        (f"({n},2) list", cloud.tolist()),
        (f"({n},2) float32", cloud.astype(np.float32)),
        (f"({n},2) int64", cloud.astype(np.int64)),
        (f"({n},2) bool", cloud > 1),
        (f"({n},2) complex", cloud.astype(complex)),
        ("(1,2) str", np.array([["a", "b"]])),
        ("None", None),
        ("'abc'", "abc"),
        (f"({n},2) x1e20", cloud * 1e20),
        (f"({n + 1},2) one 1e300", np.vstack([cloud, [[1e300, 1e300]]])),
        ("(1,2)", cloud[:1]),
        ("(500,2) one point repeated", np.repeat(cloud[:1], 500, axis=0)),
    ]


def _points_cases(rng: random.Random) -> list[Case]:
    from aldm_gym.sensor import detect_lanes, naive_detect

    pool: list[Case] = []
    for name, points in _points_values(rng) + _points_values(rng):
        for mode in ("robust", "paper"):
            pool.append(
                (
                    f"detect_lanes(points {name}, mode={mode})",
                    ("points",),
                    lambda p=points, m=mode: detect_lanes(p, mode=m),
                )
            )
    for name, points in _points_values(rng)[:3]:
        # naive_detect reads a sensor frame (its left/right grouping), not a cloud.
        pool.append(
            (f"naive_detect(points {name})", ("SensorFrame",), lambda p=points: naive_detect(p))
        )
    return rng.sample(pool, min(CASES["points"], len(pool)))


def _params_cases(rng: random.Random) -> list[Case]:
    from aldm_gym.config import rules
    from aldm_gym.sensor import detect_lanes
    from aldm_gym.sensor.aldm import ALDMParams

    nprng = np.random.default_rng(rng.randrange(2**32))
    # Three straight dashed-looking lines: enough for every stage of the detector.
    xs = np.arange(6.0, 120.0, 1.0)
    cloud = np.vstack([np.column_stack([xs, np.full_like(xs, y)]) for y in (-1.8, 1.8, 5.6)])
    cloud += nprng.normal(0, 0.03, cloud.shape)
    declared = rules(ALDMParams)
    pool: list[Case] = []
    for name, value in _field_cases(ALDMParams, rng):
        mode = rng.choice(("robust", "paper"))
        kwargs = {name: value} if name == "mode" else {name: value, "mode": mode}
        # A bound of another field (gate_min of gate_max) may be reported by that one.
        bounded = tuple(f for f, r in declared.items() if name in (r.lo, r.hi))
        pool.append(
            (
                f"detect_lanes(mode={mode}, {name}={_short(value)})",
                (name, *bounded),
                lambda kw=kwargs: detect_lanes(cloud, **kw),
            )
        )
    for value in (1e20, 1e-300):
        for name in ("search_length", "gap_search_length", "curvature_prior_std"):
            pool.append(
                (
                    f"detect_lanes({name}={value})",
                    (name,),
                    lambda kw={name: value}: detect_lanes(cloud, **kw),
                )
            )
    return rng.sample(pool, min(CASES["params"], len(pool)))


GROUPS: dict[str, Callable[[random.Random], list[Case]]] = {
    "config": _config_cases,
    "action": _action_cases,
    "sensor": _sensor_cases,
    "road": _road_cases,
    "points": _points_cases,
    "params": _params_cases,
}


# --- the subprocess side -------------------------------------------------------------


def _outcome(names: tuple[str, ...], call: Callable[[], Any]) -> dict[str, str]:
    """Run one case: ``ok``, ``named`` (a ValueError/TypeError naming an input) or
    ``unnamed`` (any other error, or a message naming none of ``names``)."""
    import warnings

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            call()
    except (ValueError, TypeError) as exc:
        message = str(exc)
        if any(name in message for name in names):
            return {"outcome": "named"}
        return {"outcome": "unnamed", "error": f"{type(exc).__name__}: {message}"[:300]}
    except Exception as exc:  # anything else is a finding
        where = traceback.extract_tb(exc.__traceback__)[-1]
        return {
            "outcome": "unnamed",
            "error": f"{type(exc).__name__}: {exc}"[:300]
            + f" (at {Path(where.filename).name}:{where.lineno})",
        }
    return {"outcome": "ok"}


def _run_group(group: str, only: str | None = None) -> None:
    """Run a group's cases (or the one labelled ``only``); print one JSON list."""
    cases = GROUPS[group](random.Random(f"{SEED}-{group}"))
    results = []
    for label, names, call in cases:
        if only is not None and label != only:
            continue
        print(f"CASE {label}", file=sys.stderr, flush=True)  # the last one names a crash
        results.append({"case": label, **_outcome(names, call)})
    print(json.dumps(results))


def _in_subprocess(group: str, only: str | None = None) -> list[dict[str, str]]:
    """Run a group in a fresh interpreter; a crash fails naming the case it died in."""
    argv = [sys.executable, __file__, group, *([only] if only else [])]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        last = [line for line in proc.stderr.splitlines() if line.startswith("CASE ")]
        pytest.fail(
            f"{group}: the process died (exit {proc.returncode}) in "
            f"{last[-1][5:] if last else 'setup'}:\n{proc.stderr[-1500:]}"
        )
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("group", list(GROUPS))
def test_fuzz_group_works_or_names_the_input(group: str) -> None:
    results = _in_subprocess(group)
    assert len(results) >= min(20, CASES[group])
    known = {k.split(":", 1)[1] for k in KNOWN_FAILURES if k.startswith(f"{group}:")}
    bad = [r for r in results if r["outcome"] == "unnamed" and r["case"] not in known]
    assert not bad, "\n".join(f"{r['case']}: {r['error']}" for r in bad)
    # Not everything is rejected: the valid draws run.
    assert any(r["outcome"] == "ok" for r in results)


@pytest.mark.parametrize(
    ("group", "label"),
    [
        pytest.param(
            label.split(":", 1)[0],
            label.split(":", 1)[1],
            marks=pytest.mark.xfail(strict=True, reason=reason),
        )
        for label, reason in KNOWN_FAILURES.items()
    ]
    or [pytest.param("none", "none", marks=pytest.mark.skip(reason="no known failures"))],
)
def test_known_failure(group: str, label: str) -> None:
    results = _in_subprocess(group, label)
    assert results, f"no case labelled {label!r} in {group}"
    assert all(r["outcome"] != "unnamed" for r in results), results


if __name__ == "__main__":
    _run_group(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else None)
