"""Fuzzing the files users give the command line: scenarios, maps, OSI traces, env
settings files.

Hypothesis draws mutations (:mod:`tests.fuzz.mutate`) of seed files the tests already
write (small scenarios, the player's corpus, the shipped maps, a trace the env
records; the OSC-ALKS suite too under ``-m slow``); the mutants are then played through
``aldm-gym scenario run``, ``aldm-gym plot --xodr``, ``aldm-gym osi detect`` and
``aldm-gym osi fmu --config`` in a
child process with a memory cap and a time limit per case (:mod:`tests.fuzz.harness`).
Every outcome must be a refusal naming the file (exit 2) or a run that plays to an end
with finite numbers; anything else fails the test with the mutation that caused it.

The default run (a few hundred mutants) stays within a minute or two; the long run
(``ALDM_GYM_FUZZ=long pytest -m slow tests/fuzz``) plays ten times as many, on more
seeds.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from lxml import etree

from tests.fuzz.harness import run_cases
from tests.fuzz.mutate import (
    apply_bytes,
    apply_osi,
    apply_xml,
    bytes_mutation,
    describe,
    elements,
    osi_mutation,
    xml_mutation,
)

ALKS = Path(os.environ.get("OSC_ALKS_DIR", Path(__file__).resolve().parents[3] / "shared/osc-alks"))
ALKS_FILES = ALKS / "logical_scenarios/concrete_scenarios"


LONG = [
    pytest.mark.slow,
    pytest.mark.skipif(
        os.environ.get("ALDM_GYM_FUZZ") != "long",
        reason="the long fuzz run: ALDM_GYM_FUZZ=long pytest -m slow tests/fuzz",
    ),
]
"""Marks of the long runs: ``-m slow`` with ``ALDM_GYM_FUZZ=long`` (``make test`` runs the
slow tests, and the long fuzz alone would take it past its ten minutes)."""


def _draw(examples: int, strategy: st.SearchStrategy[Any], key: str) -> list[Any]:
    """``examples`` values Hypothesis draws from ``strategy`` (derandomized per ``key``:
    the same list on every run)."""
    drawn: list[Any] = []

    @settings(
        max_examples=examples,
        derandomize=True,
        database=None,
        deadline=None,
        phases=[Phase.explicit, Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(strategy)
    def collect(value: Any) -> None:
        drawn.append(value)

    collect.hypothesis.inner_test.__qualname__ = key  # type: ignore[attr-defined]
    collect()
    return drawn


# ------------------------------------------------------------------------------ seeds
def _scenario_seeds(folder: Path, slow: bool) -> list[Path]:
    from scenariogeneration import xosc

    from tests.scenario import corpus
    from tests.scenario._build import at_time, write

    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    change = xosc.Event("change", xosc.Priority.override)
    change.add_action("change_action", xosc.RelativeLaneChangeAction(-1, "Target", dyn))
    change.add_trigger(at_time(1.0))
    slower = xosc.Event("slower", xosc.Priority.override)
    slower.add_action(
        "slower_action",
        xosc.AbsoluteSpeedAction(
            "$TargetSpeed",
            xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0),
        ),
    )
    slower.add_trigger(at_time(2.0))
    params = xosc.ParameterDeclarations()
    params.add_parameter(xosc.Parameter("TargetSpeed", xosc.ParameterType.double, "15.0"))
    seeds = [
        write(
            folder,
            [("Target", [change, slower])],
            stop=4.0,
            activate_at=0.0,
            parameters=params,
            name="cut_in.xosc",
        )
    ]
    makers: list[Callable[[Path], Path]] = [
        corpus.trajectory_and_route_positions,
        corpus.state_conditions,
        corpus.parameter_and_variable_actions,
        corpus.synchronize,
        corpus.distance_with_dynamic_constraints,
        corpus.ttc_in_road_coordinates_and_collision,
        corpus.entities_deleted_and_added,
        corpus.trailers,
    ]
    if slow:
        makers = [getattr(corpus, name) for name in corpus.CORPUS]
    seeds += [make(folder) for make in makers]
    if slow and ALKS_FILES.is_dir():
        seeds += sorted(ALKS_FILES.glob("*4_[2345]_*.xosc"))
    return seeds


def _cases_of_xml(
    seed: Path,
    folder: Path,
    count: int,
    argv: Callable[[Path], list[str]],
    names: Callable[[Path], list[str]],
    key: str,
) -> list[dict[str, Any]]:
    """``count`` mutants of the XML file ``seed`` (three in four tree mutations, one in
    four byte mutations) as harness cases."""
    source = seed.read_bytes()
    size = len(elements(etree.fromstring(source)))
    either = st.one_of(xml_mutation(size), xml_mutation(size), xml_mutation(size), bytes_mutation())
    cases = []
    for k, mutation in enumerate(_draw(count, either, key)):
        if mutation["op"] in ("truncate", "flip", "bad_utf8", "empty"):
            data, where = apply_bytes(source, mutation), "bytes"
        else:
            data, where = apply_xml(source, mutation)
        path = folder / f"{seed.stem}_m{k}{seed.suffix}"
        path.write_bytes(data)
        cases.append(
            {
                "label": f"{seed.name} #{k} {describe(mutation)} at {where}",
                "argv": argv(path),
                "names": names(path),
            }
        )
    return cases


def _judge(results: list[dict[str, Any]], cases: list[dict[str, Any]]) -> None:
    defects = [r for r in results if r["outcome"] == "defect"]
    assert not defects, "\n".join(f"{r['label']}: {r['why']}" for r in defects)
    assert len(results) == len(cases)
    outcomes = {r["outcome"] for r in results}
    assert outcomes == {"refused", "played"}, f"a fuzz that only {outcomes} tests little"


def _scale(slow: bool) -> int:
    return 10 if slow else 1


# ------------------------------------------------------------------------ scenarios
def _scenario_cases(folder: Path, slow: bool) -> list[dict[str, Any]]:
    seeds = _scenario_seeds(folder, slow)
    mutants = folder / "mutants"
    mutants.mkdir()
    cases: list[dict[str, Any]] = []
    for seed in seeds:
        if seed.parent == folder:  # maps named by absolute paths: mutants anywhere
            home, count = mutants, (40 if seed.name == "cut_in.xosc" else 12) * _scale(slow)
        else:  # OSC-ALKS: mutants beside the copy's relative maps and catalogs; long runs
            home, count = _copy_tree(seed.parent, folder / "alks"), 15
            seed = home / seed.name
        cases += _cases_of_xml(
            seed,
            home,
            count,
            lambda p: ["scenario", "run", str(p), "--detector", "ground_truth"],
            lambda p: [p.name],
            f"scenario-{seed.stem}-{slow}",
        )
    # parameters from the command line: garbage, non-finite, huge, unknown
    seed = seeds[0]
    for value in ["nan", "inf", "1e308", "-1e308", "abc", "${1/0}", "9" * 400, ""]:
        cases.append(
            {
                "label": f"{seed.name} --param TargetSpeed={value[:20]!r}",
                "argv": ["scenario", "run", str(seed), "--param", f"TargetSpeed={value}"],
                "names": [seed.name, "TargetSpeed"],
            }
        )
    cases.append(
        {
            "label": f"{seed.name} --param Unknown=1",
            "argv": ["scenario", "run", str(seed), "--param", "Unknown=1"],
            "names": [seed.name, "Unknown"],
        }
    )
    return cases


def _copy_tree(source: Path, target: Path) -> Path:
    import shutil

    if not target.exists():
        shutil.copytree(source, target)
    return target


# ------------------------------------------------------------------------------ maps
def _map_cases(folder: Path, slow: bool) -> list[dict[str, Any]]:
    from aldm_gym.roads import shipped_map
    from tests.scenario._build import straight_road, write

    road = straight_road(folder)
    scenario = write(folder, stop=3.0, activate_at=0.0, name="on_map.xosc")
    text = scenario.read_text()
    mutants = folder / "mutants"
    mutants.mkdir()
    cases: list[dict[str, Any]] = []

    def on_scenario(p: Path) -> list[str]:
        xosc = p.with_suffix(".xosc")
        xosc.write_text(text.replace(str(road), str(p)))
        return ["scenario", "run", str(xosc), "--detector", "ground_truth"]

    cases += _cases_of_xml(
        road,
        mutants,
        30 * _scale(slow),
        on_scenario,
        lambda p: [p.name, p.with_suffix(".xosc").name],
        f"map-straight-{slow}",
    )
    for name in ["features", "two_plus_one"] + (["motorway", "bridges"] if slow else []):
        cases += _cases_of_xml(
            shipped_map(name),
            mutants,
            10 * _scale(slow),
            lambda p: ["plot", "--xodr", str(p), "--out", str(p.with_suffix(".png"))],
            lambda p: [p.name],
            f"map-{name}-{slow}",
        )
    return cases


# ---------------------------------------------------------------------------- traces
def _trace_cases(folder: Path, slow: bool) -> list[dict[str, Any]]:
    pytest.importorskip("osi3")
    pytest.importorskip("osi_utilities")
    import gymnasium as gym

    import aldm_gym  # noqa: F401
    from aldm_gym.osi.trace import TraceWriter, read_messages

    cases: list[dict[str, Any]] = []
    seeds = []
    for suffix in (".osi", ".mcap"):
        path = folder / f"run{suffix}"
        env = gym.make("ALDMHighway-v0", config={"osi": {"trace": str(path)}})
        env.reset(seed=4)
        for _ in range(4):
            env.step(1)
        env.close()
        seeds.append(path if suffix == ".mcap" else folder / "run_sv.osi")
    messages = [m for _, m in read_messages(seeds[0])]
    mutants = folder / "mutants"
    mutants.mkdir()

    def detect(p: Path) -> list[str]:
        return [
            "osi",
            "detect",
            str(p),
            "--out",
            str(p.with_name(p.stem + "_out" + p.suffix)),
            "--no-progress",
        ]

    for k, mutation in enumerate(
        _draw(30 * _scale(slow), osi_mutation(len(messages)), f"osi-{slow}")
    ):
        path = mutants / f"msg_{k}.osi"
        with TraceWriter(path, ["SensorView"]) as writer:
            for message in apply_osi(messages, mutation):
                writer.write(message)
        cases.append(
            {
                "label": f"{path.name} {describe(mutation)}",
                "argv": detect(path),
                "names": [path.name],
            }
        )
    for seed in seeds:
        source = seed.read_bytes()
        drawn = _draw(15 * _scale(slow), bytes_mutation(), f"trace-bytes-{seed.suffix}-{slow}")
        for k, mutation in enumerate(drawn):
            path = mutants / f"bytes_{k}{seed.suffix}"
            path.write_bytes(apply_bytes(source, mutation))
            cases.append(
                {
                    "label": f"{path.name} {describe(mutation)}",
                    "argv": detect(path),
                    "names": [path.name],
                }
            )
    return cases


# ---------------------------------------------------------------------------- configs
CONFIG_SEED = """\
# an env settings file, as --config takes it
detector: aldm
marking_model: per_dash
sensor:
  preset: camera
  lateral_noise: 0.02
detector_params:
  tracking: model
acc:
  time_gap: 1.8
observation:
  line_confidence: true
policy_frequency: 10
"""


def _config_cases(folder: Path, slow: bool) -> list[dict[str, Any]]:
    """Byte mutants of a YAML and a JSON env settings file, given to ``osi fmu
    --config`` (which reads the whole file and uses its sensor and detector sections)."""
    pytest.importorskip("pythonfmu")
    import json

    import yaml

    seeds = {".yaml": CONFIG_SEED, ".json": json.dumps(yaml.safe_load(CONFIG_SEED), indent=1)}
    mutants = folder / "mutants"
    mutants.mkdir()
    cases: list[dict[str, Any]] = []
    for suffix, text in seeds.items():
        drawn = _draw(20 * _scale(slow), bytes_mutation(), f"config-{suffix}-{slow}")
        for k, mutation in enumerate(drawn):
            path = mutants / f"config_{k}{suffix}"
            path.write_bytes(apply_bytes(text.encode(), mutation))
            out = folder / f"fmu_{k}.fmu"
            cases.append(
                {
                    "label": f"{path.name} {describe(mutation)}",
                    "argv": ["osi", "fmu", str(out), "--config", str(path)],
                    "names": [path.name],
                }
            )
    return cases


KINDS: dict[str, Callable[[Path, bool], list[dict[str, Any]]]] = {
    "scenario": _scenario_cases,
    "map": _map_cases,
    "trace": _trace_cases,
    "config": _config_cases,
}
"""The files fuzzed, each with the cases of its mutants."""


@pytest.mark.parametrize("slow", [pytest.param(False), pytest.param(True, marks=LONG)])
@pytest.mark.parametrize("kind", list(KINDS))
def test_mutants_are_refused_by_name_or_played(tmp_path: Path, kind: str, slow: bool) -> None:
    cases = KINDS[kind](tmp_path, slow)
    results = run_cases(cases, tmp_path, timeout=240 if not slow else 3600)
    _judge(results, cases)


def test_the_harness_sees_a_traceback_a_silent_refusal_and_nan(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The classification itself: what a defect looks like is reported as one."""
    import sys

    import aldm_gym.cli
    from tests.fuzz.harness import classify

    missing = tmp_path / "missing.xosc"
    refused = classify({"argv": ["scenario", "run", str(missing)], "names": ["missing.xosc"]})
    assert refused["outcome"] == "refused"
    unnamed = classify({"argv": ["scenario", "run", str(missing)], "names": ["other.xosc"]})
    assert unnamed["outcome"] == "defect" and "names no file" in unnamed["why"]

    def crash(argv: list[str]) -> int:
        raise OverflowError("int too large")

    def nan(argv: list[str]) -> int:
        print("run.xosc: PASS\n  min TTC nan s")
        return 0

    def two_lines(argv: list[str]) -> int:
        print("run.xosc: error: one\nrun.xosc: error: two", file=sys.stderr)
        return 2

    for fake, why in [
        (crash, "OverflowError"),
        (nan, "NaN printed"),
        (two_lines, "one error line"),
    ]:
        monkeypatch.setattr(aldm_gym.cli, "main", fake)
        outcome = classify({"argv": [], "names": ["run.xosc"]})
        assert outcome["outcome"] == "defect" and why in outcome["why"], outcome
