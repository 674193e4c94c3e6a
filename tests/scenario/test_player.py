"""The OpenSCENARIO player against the standard's definitions, on small scenarios.

Each scenario is written with scenariogeneration (tests/scenario/_build.py) on a
straight road, so every expected value follows from the definition by hand: positions
at 0.1 s steps, speeds and offsets along the dynamics' shapes, the step at which a
condition first holds.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scenariogeneration import xosc

from aldm_gym.errors import ScenarioError, ScenarioWarning
from aldm_gym.scenario import read_scenario
from tests.scenario._build import at, at_time, play, step_speed, write

MOTORWAY = Path(__file__).resolve().parents[2] / "aldm_gym" / "roads" / "maps" / "motorway.xodr"


def _event(name: str, action: object, trigger: object, priority: object = None) -> xosc.Event:
    ev = xosc.Event(name, priority or xosc.Priority.override)
    ev.add_action(f"{name}_action", action)
    ev.add_trigger(trigger)
    return ev


def test_init_places_by_lane_and_relative_lane_position(tmp_path: Path) -> None:
    path = write(tmp_path, target=(1, 60.0, 15.0))
    _, rec = play(path, 1.0)
    first, later = rec[0], at(rec, 1.0)
    assert first["Ego"][:3] == (-2, pytest.approx(50.0), pytest.approx(0.0))
    # dLane +1: the next lane towards +t (left), ds along s
    assert first["Target"][:3] == (-1, pytest.approx(110.0), pytest.approx(0.0))
    assert later["Ego"][1] == pytest.approx(70.0) and later["Target"][1] == pytest.approx(125.0)
    assert later["Target"][3] == 15.0


def test_speed_action_linear_rate(tmp_path: Path) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    ev = _event("accelerate", xosc.AbsoluteSpeedAction(30.0, dyn), at_time(1.0))
    path = write(tmp_path, [("Target", [ev])], target=(1, 60.0, 20.0))
    _, rec = play(path, 8.0)
    # starts at the first step after 1 s (1.1 s): +2 m/s per second until 30 m/s
    assert at(rec, 1.1)["Target"][3] == pytest.approx(20.0)
    assert at(rec, 3.1)["Target"][3] == pytest.approx(24.0)
    assert at(rec, 7.0)["Target"][3] == pytest.approx(30.0)


def test_speed_action_sinusoidal_time_is_half_way_at_half_time(tmp_path: Path) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 4.0)
    ev = _event("slow", xosc.AbsoluteSpeedAction(10.0, dyn), at_time(1.0))
    path = write(tmp_path, [("Target", [ev])])
    _, rec = play(path, 6.0)
    assert at(rec, 3.1)["Target"][3] == pytest.approx(15.0)
    assert at(rec, 2.1)["Target"][3] == pytest.approx(
        20.0 - 10.0 * 0.5 * (1 - math.cos(math.pi / 4))
    )
    assert at(rec, 5.1)["Target"][3] == pytest.approx(10.0)


def test_lane_change_sinusoidal_then_state_condition_with_delay(tmp_path: Path) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 4.0)
    change = _event("change", xosc.AbsoluteLaneChangeAction(-2, dyn), at_time(1.0))
    after = _event(
        "after",
        step_speed(10.0),
        xosc.ValueTrigger(
            "done",
            1.0,
            xosc.ConditionEdge.rising,
            xosc.StoryboardElementStateCondition(
                xosc.StoryboardElementType.action,
                "change_action",
                xosc.StoryboardElementState.endTransition,
            ),
        ),
    )
    path = write(tmp_path, [("Target", [change, after])], target=(1, 60.0, 20.0))
    _, rec = play(path, 8.0)
    # the offset from the target lane (-2) runs from +3.5 m to 0 along the shape; the
    # lane reported is the one that holds the car (-1 until half way)
    assert at(rec, 1.1)["Target"][:3] == (-1, pytest.approx(132.0), pytest.approx(0.0))
    quarter = 3.5 * 0.5 * (1 - math.cos(math.pi / 4))  # the shape at a quarter of 4 s
    assert at(rec, 2.1)["Target"][0::2] == (-1, pytest.approx(-quarter))
    assert at(rec, 3.1)["Target"][0::2] == (-2, pytest.approx(1.75))
    # the speed is along the heading: the lateral motion takes its share of 20 m/s
    s_quarter, s_half = at(rec, 2.1)["Target"][1], at(rec, 3.1)["Target"][1]
    assert 151.9 < s_quarter < 152.0 and 171.8 < s_half < s_quarter + 20.0
    assert at(rec, 5.1)["Target"][2] == pytest.approx(0.0, abs=1e-9)
    # ended at 5.1 s; the next event fires 1 s later
    assert at(rec, 6.0)["Target"][3] == 20.0 and at(rec, 6.1)["Target"][3] == 10.0


def test_lane_offset_duration_from_max_lateral_acceleration(tmp_path: Path) -> None:
    action = xosc.AbsoluteLaneOffsetAction(
        1.0, xosc.DynamicsShapes.sinusoidal, 0.5, continuous=False
    )
    ev = _event("offset", action, at_time(1.0))
    path = write(tmp_path, [("Target", [ev])])
    _, rec = play(path, 6.0)
    duration = math.pi * math.sqrt(1.0 / (2 * 0.5))  # pi s
    # the offset follows the shape a step late (the first step keeps it, as esmini)
    mid = round(1.2 + duration / 2, 1)
    assert at(rec, mid)["Target"][2] == pytest.approx(
        0.5 * (1 - math.cos(math.pi * (mid - 1.2) / duration)), abs=1e-9
    )
    assert at(rec, 4.3)["Target"][2] < 1.0
    assert at(rec, 4.4)["Target"][2] == pytest.approx(1.0)


def test_relative_distance_freespace_fires_at_the_step_it_holds(tmp_path: Path) -> None:
    # same lane, 60 m between reference points = 55 m between boxes, closing at 10 m/s:
    # below 25 m after 3 s, i.e. first at 3.1 s
    cond = xosc.EntityTrigger(
        "close",
        0,
        xosc.ConditionEdge.none,
        xosc.RelativeDistanceCondition(
            25.0,
            xosc.Rule.lessThan,
            xosc.RelativeDistanceType.longitudinal,
            "Target",
            freespace=True,
        ),
        "Ego",
    )
    ev = _event("flee", step_speed(20.0), cond)
    path = write(tmp_path, [("Target", [ev])], target=(0, 60.0, 10.0))
    _, rec = play(path, 5.0)
    assert at(rec, 3.0)["Target"][3] == 10.0
    assert at(rec, 3.1)["Target"][3] == 20.0


def test_rising_edge_and_delay(tmp_path: Path) -> None:
    ev = _event("late", step_speed(5.0), at_time(2.0, edge=xosc.ConditionEdge.rising, delay=1.5))
    path = write(tmp_path, [("Target", [ev])])
    _, rec = play(path, 5.0)
    assert at(rec, 3.5)["Target"][3] == 20.0
    assert at(rec, 3.6)["Target"][3] == 5.0


def test_override_priority_stops_the_running_event(tmp_path: Path) -> None:
    slow = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time, 20.0)
    first = _event("long", xosc.AbsoluteSpeedAction(0.0, slow), at_time(1.0))
    second = _event("short", step_speed(25.0), at_time(2.0), xosc.Priority.override)
    path = write(tmp_path, [("Target", [first, second])])
    env, rec = play(path, 4.0)
    assert 19.0 < at(rec, 2.0)["Target"][3] < 20.0
    assert at(rec, 2.1)["Target"][3] == 25.0 and at(rec, 3.0)["Target"][3] == 25.0
    board = env.scenario.storyboard
    assert board.element("event", "long").transition == "stopTransition"
    assert board.element("action", "long_action").state == "completeState"


def test_stop_trigger_ends_the_episode(tmp_path: Path) -> None:
    path = write(tmp_path, stop=3.0)
    _, rec = play(path, 10.0)
    assert rec[-1]["done"] and rec[-1]["time"] == pytest.approx(3.1)
    assert not any(r["done"] for r in rec[:-1])


def test_controller_activation_hands_the_ego_over(tmp_path: Path) -> None:
    path = write(tmp_path, activate_at=2.0, target=None, stop=8.0)
    env, rec = play(path, 8.0)
    assert not at(rec, 2.0)["active"] and at(rec, 2.1)["active"]
    # the function keeps the lane and the set speed it took over
    end = rec[-1]["Ego"]
    assert end[0] == -2 and abs(end[2]) < 0.2 and end[3] == pytest.approx(20.0, abs=0.5)
    assert env.vehicle.target_speed == pytest.approx(20.0)


def test_acc_only_activation_keeps_the_lane_change_scripted(tmp_path: Path) -> None:
    # the function drives the speed (ACC behind a slower car), the storyboard the lane
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 3.0)
    change = _event("change", xosc.AbsoluteLaneChangeAction(-3, dyn), at_time(2.0))
    path = write(
        tmp_path,
        [("Ego", [change])],
        activate_at=0.0,
        domains=(False, True),
        target=(0, 40.0, 12.0),
        stop=10.0,
    )
    env, rec = play(path, 10.0)
    assert env.scenario.domains == {"longitudinal"}
    assert at(rec, 1.9)["Ego"][0] == -2 and rec[-1]["Ego"][0] == -3
    assert abs(rec[-1]["Ego"][2]) < 1e-6  # on the target lane's centre, as scripted
    # the ACC slowed down behind the slower car before the change
    assert at(rec, 1.9)["Ego"][3] < 19.5


def test_lka_only_activation_keeps_the_speed_scripted(tmp_path: Path) -> None:
    # the function steers (LKA on the detected lanes), the storyboard sets the speed
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    slow = _event("slow", xosc.AbsoluteSpeedAction(10.0, dyn), at_time(1.0))
    path = write(tmp_path, [("Ego", [slow])], activate_at=0.0, domains=(True, False), target=None)
    env, rec = play(path, 10.0)
    assert env.scenario.domains == {"lateral"}
    speeds = [r["Ego"][3] for r in rec]
    assert at(rec, 1.0)["Ego"][3] == pytest.approx(20.0)
    assert at(rec, 3.5)["Ego"][3] == pytest.approx(15.0, abs=0.25)
    assert speeds[-1] == pytest.approx(10.0)
    assert all(r["Ego"][0] == -2 for r in rec)  # the LKA keeps its lane


def test_an_action_on_the_functions_domain_is_refused(tmp_path: Path) -> None:
    slow = _event("slow", step_speed(10.0), at_time(1.0))
    path = write(tmp_path, [("Ego", [slow])], activate_at=0.0, domains=(False, True), target=None)
    with pytest.raises(ScenarioError, match="longitudinal domain its controller drives"):
        play(path, 2.0)


def test_distance_with_dynamic_constraints_keeps_its_limits_and_rates(tmp_path: Path) -> None:
    from tests.scenario.corpus import distance_with_dynamic_constraints

    _, rec = play(distance_with_dynamic_constraints(tmp_path), 20.0)
    v = np.array([r["Target"][3] for r in rec])
    acc = np.diff(v) / 0.1
    jerk = np.diff(acc) / 0.1
    assert acc.max() <= 3.0 + 1e-9 and acc.min() >= -4.0 - 1e-9
    assert v.max() <= 30.0 + 1e-9
    # the rates bound how fast the acceleration grows away from 0
    growing = np.sign(acc[1:]) * jerk > 0
    assert np.all(jerk[growing & (acc[1:] > 0)] <= 2.0 + 1e-6)
    assert np.all(jerk[growing & (acc[1:] < 0)] >= -3.0 - 1e-6)
    # it settles at the time gap behind the ego (1.5 s at 20 m/s between the rear axles)
    gap = rec[-1]["Ego"][1] - rec[-1]["Target"][1]
    assert gap == pytest.approx(30.0, abs=0.5) and v[-1] == pytest.approx(20.0, abs=0.1)


def test_a_parameter_action_changes_what_a_parameter_condition_sees(tmp_path: Path) -> None:
    # OpenSCENARIO 1.0/1.1: ParameterAction and ParameterCondition at run time
    from tests.scenario.corpus import parameter_and_variable_actions

    text = parameter_and_variable_actions(tmp_path).read_text()
    start, end = text.index("<VariableDeclarations>"), text.index("</VariableDeclarations>")
    declarations = text[start : end + len("</VariableDeclarations>")]
    params = declarations.replace("Variable", "Parameter")
    text = text.replace(declarations, params).replace('revMinor="3"', 'revMinor="1"')
    for old, new in (
        ("VariableAction variableRef", "ParameterAction parameterRef"),
        ("</VariableAction>", "</ParameterAction>"),
        ("VariableCondition variableRef", "ParameterCondition parameterRef"),
        ("variableType", "parameterType"),
    ):
        text = text.replace(old, new)
    path = tmp_path / "parameters.xosc"
    path.write_text(text)
    env, rec = play(path, 10.0)
    assert env.scenario.parameters == {"Count": 3, "Go": 1.5}
    assert at(rec, 1.3)["Target"][3] == 20.0 and rec[-1]["Target"][3] == 10.0


def test_a_variable_set_to_a_value_of_another_type_is_named(tmp_path: Path) -> None:
    from tests.scenario.corpus import parameter_and_variable_actions

    path = parameter_and_variable_actions(tmp_path)
    path.write_text(path.read_text().replace('value="1.5"', 'value="fast"'))
    with pytest.raises(ScenarioError, match="'fast' is not a float"):
        play(path, 3.0)


@pytest.mark.parametrize("limits", [None, (1.0, 1.0, 1.0)])
def test_lateral_distance_holds_the_gap_beside_the_ego(
    tmp_path: Path, limits: tuple[float, float, float] | None
) -> None:
    # 2 m between the boxes (2 m wide): the target's centre 4 m left of the ego's
    kwargs = {}
    if limits is not None:
        names = ("max_acceleration", "max_deceleration", "max_speed")
        kwargs = dict(zip(names, limits, strict=True))
    act = xosc.LateralDistanceAction(
        "Ego",
        distance=2.0,
        freespace=True,
        continuous=True,
        displacement=xosc.LateralDisplacement.leftToReferencedEntity,
        **kwargs,
    )
    ev = _event("lat", act, at_time(1.0))
    path = write(tmp_path, [("Target", [ev])], target=(1, 10.0, 20.0), stop=14.0)
    _, rec = play(path, 14.0)
    offsets = [r["Target"][2] for r in rec]
    if limits is None:  # measured in the next step, put there in the one after, and kept
        assert at(rec, 1.2)["Target"][2] == 0.0 and at(rec, 1.3)["Target"][2] == 0.5
        assert rec[-1]["Target"][2] == pytest.approx(0.5)
    else:  # moved there within the lateral speed limit
        steps = np.abs(np.diff(offsets)) / 0.1
        assert steps.max() <= 1.0 + 1e-9
        assert rec[-1]["Target"][2] == pytest.approx(0.5, abs=0.02)


def test_a_trajectory_from_a_catalog_plays_as_the_inline_one(tmp_path: Path) -> None:
    from tests.scenario.corpus import trajectory_without_timing

    inline = trajectory_without_timing(tmp_path)
    text = inline.read_text()
    start, end = text.index("<Trajectory "), text.index("</Trajectory>") + len("</Trajectory>")
    catalogs = tmp_path / "catalogs"
    catalogs.mkdir()
    (catalogs / "trajectories.xosc").write_text(
        '<?xml version="1.0"?><OpenSCENARIO><FileHeader revMajor="1" revMinor="3" '
        'date="2026-01-01T00:00:00" description="" author=""/>'
        f'<Catalog name="paths">{text[start:end]}</Catalog></OpenSCENARIO>'
    )
    text = text[:start] + '<CatalogReference catalogName="paths" entryName="path"/>' + text[end:]
    text = text.replace(
        "<CatalogLocations/>",
        '<CatalogLocations><TrajectoryCatalog><Directory path="catalogs"/>'
        "</TrajectoryCatalog></CatalogLocations>",
    )
    from_catalog = tmp_path / "from_catalog.xosc"
    from_catalog.write_text(text)
    _, a = play(inline, 6.0)
    _, b = play(from_catalog, 6.0)
    assert [r["Target"] for r in a] == [r["Target"] for r in b]
    assert a[-1]["Target"][0] == -3  # it left its lane along the path


def test_a_run_the_function_never_drove_is_not_judged(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from aldm_gym.cli import main
    from aldm_gym.harness.criteria import run_scenario

    path = write(tmp_path, activate_at=None, stop=3.0)
    result = run_scenario(path, detector="ground_truth")
    assert not result.passed and "never drove the ego" in result.error
    assert main(["scenario", "run", str(path), "--detector", "ground_truth"]) == 1
    out = capsys.readouterr().out
    assert "NOT JUDGED" in out and "PASS" not in out


@pytest.mark.parametrize(
    "performance", ['maxSpeed="-1.0"', 'maxAcceleration="0"', 'maxDeceleration="-3"']
)
def test_impossible_performance_limits_are_refused(tmp_path: Path, performance: str) -> None:
    name = performance.split("=")[0]
    path = write(tmp_path)
    text = path.read_text()
    start = text.index("<Performance ")
    end = text.index("/>", start)
    attrs = {a.split("=")[0]: a for a in text[start + 13 : end].split()}
    attrs[name] = performance
    path.write_text(text[:start] + "<Performance " + " ".join(attrs.values()) + text[end:])
    with pytest.raises(ScenarioError, match="maxSpeed must be >= 0"):
        read_scenario(path)


def test_synchronizing_to_a_stop_arrives_without_error(tmp_path: Path) -> None:
    sync = xosc.SynchronizeAction(
        "Ego",
        xosc.LanePosition(300.0, 0, -2, 0),
        xosc.LanePosition(250.0, 0, -1, 0),
        1.0,
        1.0,
        xosc.AbsoluteSpeed(0.0),
    )
    path = write(tmp_path, [("Target", [_event("sync", sync, at_time(0.5))])], stop=14.0)
    _, rec = play(path, 14.0)
    assert rec[-1]["Target"][3] == pytest.approx(0.0, abs=1e-6)
    assert rec[-1]["Target"][1] == pytest.approx(250.0, abs=2.0)


def test_same_seed_same_run(tmp_path: Path) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.cubic, xosc.DynamicsDimension.rate, 1.0)
    ev = _event("change", xosc.AbsoluteLaneChangeAction(-2, dyn), at_time(1.0))
    path = write(tmp_path, [("Target", [ev])], activate_at=0.5, target=(1, 40.0, 15.0))
    _, a = play(path, 6.0, sensor={"preset": "camera"})
    _, b = play(path, 6.0, sensor={"preset": "camera"})
    assert a == b


def test_a_scenario_on_a_shipped_map(tmp_path: Path) -> None:
    path = write(
        tmp_path, road=MOTORWAY, road_id=1, ego_s=100.0, lane_id=-2, activate_at=1.0, stop=6.0
    )
    env, rec = play(path, 7.0)
    assert rec[0]["Ego"][:2] == (-2, pytest.approx(100.0))
    assert rec[-1]["done"] and not rec[-1]["crashed"]
    assert env.highway.map.path.endswith("motorway.xodr")


# ---------------------------------------------------------------------- bad input
def _patched(tmp_path: Path, old: str, new: str, **kwargs: object) -> Path:
    path = write(tmp_path, **kwargs)  # type: ignore[arg-type]
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    return path


def _line_of(path: Path, needle: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def test_unsupported_element_names_file_line_and_element(tmp_path: Path) -> None:
    path = write(tmp_path)
    text = path.read_text()
    start = text.index("<Vehicle", text.index('<ScenarioObject name="Target"'))
    end = text.index("</Vehicle>", start) + len("</Vehicle>")
    path.write_text(text[:start] + '<ExternalObjectReference name="elsewhere"/>' + text[end:])
    line = _line_of(path, "ExternalObjectReference")
    with pytest.raises(
        ScenarioError, match=rf"scenario\.xosc:{line} <ExternalObjectReference>.*not supported"
    ):
        read_scenario(path)


def test_an_element_with_no_meaning_here_is_ignored_with_one_warning(tmp_path: Path) -> None:
    from aldm_gym.errors import ScenarioWarning

    visibility = '<VisibilityAction graphics="true" traffic="true" sensors="true"/>'
    path = _patched(
        tmp_path,
        "<TeleportAction>",
        f"{visibility}</PrivateAction><PrivateAction>{visibility}</PrivateAction>"
        "<PrivateAction><TeleportAction>",
    )
    with pytest.warns(ScenarioWarning) as caught:
        scenario = read_scenario(path)
    texts = [str(w.message) for w in caught if issubclass(w.category, ScenarioWarning)]
    assert len(texts) == 1 and "<VisibilityAction> ignored" in texts[0]
    assert "lines" in scenario.ignored["VisibilityAction"]


def test_unknown_parameter_reference_is_named(tmp_path: Path) -> None:
    path = _patched(tmp_path, 'value="20.0"', 'value="$Nope"')
    with pytest.raises(ScenarioError, match=r"Nope"):
        read_scenario(path)


def test_a_missing_scenario_in_the_env_config_names_the_key(tmp_path: Path) -> None:
    import gymnasium as gym

    from aldm_gym import ENV_ID

    missing = tmp_path / "nope.xosc"
    with pytest.raises(ScenarioError, match=r"scenario\.xosc=.*nope\.xosc.*no such scenario"):
        gym.make(ENV_ID, config={"scenario": {"xosc": str(missing)}}).reset(seed=0)


def test_missing_catalog_entry_is_named(tmp_path: Path) -> None:
    catalog = tmp_path / "catalogs"
    catalog.mkdir()
    (catalog / "vehicles.xosc").write_text(
        '<OpenSCENARIO><FileHeader revMajor="1" revMinor="1" author="" date="" description=""/>'
        '<Catalog name="vehicle_catalog"/></OpenSCENARIO>'
    )
    path = write(tmp_path)
    text = path.read_text().replace(
        "<CatalogLocations/>",
        "<CatalogLocations><VehicleCatalog>"
        '<Directory path="./catalogs"/></VehicleCatalog></CatalogLocations>',
    )
    start = text.index("<Vehicle name")
    end = text.index("</Vehicle>") + len("</Vehicle>")
    text = (
        text[:start]
        + '<CatalogReference catalogName="vehicle_catalog" entryName="lorry"/>'
        + text[end:]
    )
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"<CatalogReference>.*no entry 'lorry'"):
        read_scenario(path)


def test_position_off_the_map_is_an_error_naming_the_position(tmp_path: Path) -> None:
    path = write(tmp_path, ego_s=5000.0)
    with pytest.raises(ScenarioError, match=r"<LanePosition>: the position is not on the map"):
        play(path, 1.0)


def test_state_condition_naming_no_element(tmp_path: Path) -> None:
    cond = xosc.ValueTrigger(
        "x",
        0,
        xosc.ConditionEdge.none,
        xosc.StoryboardElementStateCondition(
            xosc.StoryboardElementType.action, "nothing", xosc.StoryboardElementState.endTransition
        ),
    )
    path = write(tmp_path, [("Target", [_event("e", step_speed(1.0), cond)])])
    with pytest.raises(ScenarioError, match=r"storyboardElementRef='nothing' names no action"):
        read_scenario(path)


def test_unknown_override_and_variation_file(tmp_path: Path) -> None:
    path = write(tmp_path)
    with pytest.raises(ScenarioError, match=r"undeclared parameter Speed"):
        read_scenario(path, {"Speed": 3})
    variation = tmp_path / "variation.xosc"
    variation.write_text(
        '<OpenSCENARIO><FileHeader revMajor="1" revMinor="1" author="" date="" description=""/>'
        '<ParameterValueDistribution><ScenarioFile filepath="scenario.xosc"/>'
        "</ParameterValueDistribution></OpenSCENARIO>"
    )
    with pytest.raises(ScenarioError, match=r"a parameter variation file, not a scenario"):
        read_scenario(variation)


def test_both_a_map_and_a_scenario_is_a_config_error(tmp_path: Path) -> None:
    import gymnasium as gym

    from aldm_gym.errors import ConfigError

    path = write(tmp_path)
    with pytest.raises(ConfigError, match=r"road\.xodr and scenario\.xosc are both set"):
        gym.make(
            "ALDMHighway-v0",
            config={"scenario": {"xosc": str(path)}, "road": {"xodr": str(MOTORWAY)}},
        )
    with pytest.raises(ConfigError, match=r"scenario"):
        gym.make("ALDMHighway-v0", config={"scenario": {"xosc": str(path), "paramters": {}}})


def test_longitudinal_distance_places_the_actor_at_the_time_gap(tmp_path: Path) -> None:
    # leading the ego by 2 s freespace at 20 m/s: 40 m between the ego's front and the
    # target's rear, 45 m between the reference points of two 5 m cars
    action = xosc.LongitudinalDistanceAction(
        "Ego",
        freespace=True,
        continuous=False,
        timeGap=2.0,
        displacement=xosc.LongitudinalDisplacement.leadingReferencedEntity,
    )
    ev = _event("gap", action, at_time(0.5))
    path = write(tmp_path, [("Target", [ev])], target=(0, 90.0, 12.0))
    _, rec = play(path, 2.0)
    # started at 0.6 s, placed by the next step (as esmini), where everyone has moved
    assert at(rec, 0.6)["Target"][3] == 12.0
    placed = at(rec, 0.7)
    assert placed["Target"][1] - placed["Ego"][1] == pytest.approx(45.0)
    assert placed["Target"][3] == pytest.approx(20.0)


@pytest.mark.parametrize("attr", ["distance", "timeGap"])
def test_a_negative_longitudinal_distance_warns_and_plays_as_its_magnitude(
    tmp_path: Path, attr: str
) -> None:
    """The schema's range is 0 and up; scenariogeneration's one_action_example writes
    ``distance="-4.0"`` and esmini plays it as 4 m (the side is ``displacement``'s)."""
    traces = []
    for sign in (1.0, -1.0):
        action = xosc.LongitudinalDistanceAction(
            "Ego",
            freespace=True,
            continuous=False,
            displacement=xosc.LongitudinalDisplacement.leadingReferencedEntity,
            **{attr: sign * (12.0 if attr == "distance" else 1.5)},
        )
        ev = _event("gap", action, at_time(0.5))
        folder = tmp_path / f"s{sign:+.0f}"
        folder.mkdir()
        path = write(folder, [("Target", [ev])], target=(0, 90.0, 12.0))
        if sign < 0:
            with pytest.warns(ScenarioWarning, match=rf"{attr}: -1?[0-9.]+ .* read as "):
                read_scenario(path)
        traces.append(play(path, 2.0)[1])
    for t in (0.7, 1.5, 2.0):
        assert at(traces[1], t)["Target"] == at(traces[0], t)["Target"]
    placed = at(traces[0], 0.7)
    assert placed["Target"][1] > placed["Ego"][1] + 5.0


def test_a_synchronize_action_without_tolerances_plays_them_as_zero(tmp_path: Path) -> None:
    """``targetToleranceMaster`` and ``targetTolerance`` are optional without a default
    in the standard; esmini 3.6 plays them as 0 m. The target, from standing, rushes to
    its position at the master's speed: without the attributes it moves as with both
    written as 0, and not as with both 1 m (a plan for 1 m short of both targets)."""
    from tests.scenario.corpus import synchronize_from_standstill

    path = synchronize_from_standstill(tmp_path)
    text = path.read_text()
    tag = '<SynchronizeAction masterEntityRef="Ego" '
    assert tag in text
    runs = {}
    for tol in (None, "0.0", "1.0"):
        variant = (
            text
            if tol is None
            else text.replace(tag, f'{tag}targetToleranceMaster="{tol}" targetTolerance="{tol}" ')
        )
        file = tmp_path / f"sync_{tol}.xosc"
        file.write_text(variant)
        runs[tol] = play(file, 10.5)[1]
    times = np.arange(0.1, 10.45, 0.1)
    target = {k: np.array([at(r, t)["Target"][1] for t in times]) for k, r in runs.items()}
    np.testing.assert_array_equal(target[None], target["0.0"])
    assert np.max(np.abs(target[None] - target["1.0"])) > 0.3
    lane, s, _t, v = at(runs[None], 10.0)["Target"]
    assert (lane, s, v) == (-1, pytest.approx(230.0, abs=0.05), pytest.approx(20.0))


def _selecting_story(
    refs: tuple[str, ...], rule: object, delay: float = 0.0, edge: object = None
) -> xosc.Story:
    """An act that starts when the ego or the target drives faster than 25 m/s (with
    ``edge``), with a maneuver group (``selectTriggeringEntities``, actors ``refs``)
    that sets 10 m/s."""
    trigger = xosc.EntityTrigger(
        "fast",
        delay,
        edge or xosc.ConditionEdge.none,
        xosc.SpeedCondition(25.0, xosc.Rule.greaterThan),
        "Ego",
        triggeringrule=rule,
    )
    trigger.add_triggering_entity("Target")
    man = xosc.Maneuver("m")
    man.add_event(_event("slow", step_speed(10.0), at_time(0.0, name="now")))
    group = xosc.ManeuverGroup("g", selecttriggeringentities=True)
    for ref in refs:
        group.add_actor(ref)
    group.add_maneuver(man)
    act = xosc.Act("act_fast", trigger)
    act.add_maneuver_group(group)
    story = xosc.Story("selecting")
    story.add_act(act)
    return story


@pytest.mark.parametrize(
    ("refs", "rule", "delay", "slowed", "at_s"),
    [
        ((), xosc.TriggeringEntitiesRule.any, 0.0, {"Target"}, 1.1),
        (("Ego",), xosc.TriggeringEntitiesRule.any, 0.0, {"Ego", "Target"}, 1.1),
        ((), xosc.TriggeringEntitiesRule.any, 0.5, {"Target"}, 1.6),
        ((), xosc.TriggeringEntitiesRule.all, 0.0, {"Ego", "Target"}, 2.1),
    ],
)
def test_select_triggering_entities_adds_those_that_started_the_act(
    tmp_path: Path, refs: tuple[str, ...], rule: object, delay: float, slowed: set, at_s: float
) -> None:
    """OpenSCENARIO 1.3 §7.3.1: with ``selectTriggeringEntities`` the entities whose
    states fulfilled the conditions of a condition group that held in the act's start
    trigger become actors, in union with the ``EntityRef`` ones. The target speeds up
    at 1.1 s, the ego at 2.1 s (time conditions ``greaterThan``); the act starts in the
    same update when any (or all) of them is faster than 25 m/s (after ``delay``), and
    sets 10 m/s on its actors."""
    events = [
        ("Target", [_event("speed_up", step_speed(30.0), at_time(1.0))]),
        ("Ego", [_event("ego_up", step_speed(30.0), at_time(2.0))]),
    ]
    story = _selecting_story(refs, rule, delay)
    path = write(tmp_path, events, stories=[story], target=(1, 60.0, 20.0))
    runner, rec = play(path, 4.0)
    starts = runner.scenario.storyboard.starts("act")["act_fast"]
    assert starts == [pytest.approx(at_s)]
    after = at(rec, at_s + 0.2)
    unslowed = {"Target": 30.0, "Ego": 30.0 if at_s > 2.0 else 20.0}
    for name in ("Ego", "Target"):
        assert after[name][3] == (10.0 if name in slowed else unslowed[name]), name


def test_select_triggering_entities_of_a_falling_edge_are_those_that_fulfilled_it(
    tmp_path: Path,
) -> None:
    """A falling edge is made by the entities that fulfilled the condition until then:
    the target, faster than 25 m/s from 1.1 s, slows to 20 m/s at 3.1 s; the act
    starts then and slows it to 10 m/s; the ego, never that fast, is no actor."""
    events = [
        (
            "Target",
            [
                _event("speed_up", step_speed(30.0), at_time(1.0)),
                _event(
                    "ease", step_speed(20.0), at_time(3.0, name="later"), xosc.Priority.parallel
                ),
            ],
        ),
    ]
    story = _selecting_story((), xosc.TriggeringEntitiesRule.any, edge=xosc.ConditionEdge.falling)
    path = write(tmp_path, events, stories=[story], target=(1, 60.0, 20.0))
    env, rec = play(path, 4.0)
    assert env.scenario.storyboard.starts("act")["act_fast"] == [pytest.approx(3.1)]
    after = at(rec, 3.5)
    assert after["Target"][3] == 10.0 and after["Ego"][3] == 20.0


def test_select_triggering_entities_without_any_actor_is_a_clear_error(tmp_path: Path) -> None:
    """An act started by a time condition has no triggering entities: a private action
    of a group with neither ``EntityRef`` nor triggering entities has no actor."""
    man = xosc.Maneuver("m")
    man.add_event(_event("slow", step_speed(10.0), at_time(0.0, name="now")))
    group = xosc.ManeuverGroup("g", selecttriggeringentities=True)
    group.add_maneuver(man)
    act = xosc.Act("timed", at_time(1.0))
    act.add_maneuver_group(group)
    story = xosc.Story("selecting")
    story.add_act(act)
    path = write(tmp_path, stories=[story])
    with pytest.raises(ScenarioError, match="needs an actor"):
        play(path, 2.0)


def test_relative_speed_continuous_follows_its_entity(tmp_path: Path) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)
    follow = _event(
        "follow", xosc.RelativeSpeedAction(-2.0, "Ego", dyn, continuous=True), at_time(0.5)
    )
    linear = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 1.0)
    ego_slows = _event("slow", xosc.AbsoluteSpeedAction(14.0, linear), at_time(1.0))
    path = write(tmp_path, [("Target", [follow]), ("Ego", [ego_slows])], target=(1, 30.0, 25.0))
    _, rec = play(path, 8.0)
    # the follower's action is written before the ego's: esmini steps it first, on
    # the ego's speed of the step before (the corpus checks the same file against it)
    for t in (1.0, 3.0, 6.0, 8.0):
        assert at(rec, t)["Target"][3] == pytest.approx(at(rec, t - 0.1)["Ego"][3] - 2.0)


def test_follow_trajectory_polyline_by_time(tmp_path: Path) -> None:
    poly = xosc.Polyline(
        [0.0, 2.0, 4.0],
        [
            xosc.LanePosition(200.0, 0.0, -1, 0),
            xosc.LanePosition(210.0, 0.0, -1, 0),
            xosc.LanePosition(210.0, -3.5, -1, 0),
        ],
    )
    traj = xosc.Trajectory("walk", False)
    traj.add_shape(poly)
    action = xosc.FollowTrajectoryAction(
        traj, xosc.FollowingMode.position, xosc.ReferenceContext.relative, 1.0, 0.0
    )
    ev = _event("walk", action, at_time(1.0))
    path = write(tmp_path, [("Target", [ev])], target=(1, 150.0, 0.0))
    _, rec = play(path, 7.0)
    # started at 1.1 s: half way along the first leg at 2.1 s, at its end at 3.1 s,
    # a quarter of the way across to the next lane at 3.6 s, there from 5.1 s on
    assert at(rec, 2.1)["Target"][1] == pytest.approx(205.0)
    assert at(rec, 3.1)["Target"][1] == pytest.approx(210.0)
    assert at(rec, 3.6)["Target"][:3] == (-1, pytest.approx(210.0), pytest.approx(-0.875))
    assert at(rec, 5.1)["Target"][:3] == (-2, pytest.approx(210.0), pytest.approx(0.0, abs=1e-9))
    assert at(rec, 6.0)["Target"][2] == pytest.approx(0.0, abs=1e-9)


def test_time_headway_condition(tmp_path: Path) -> None:
    # the ego at 20 m/s behind a standing target 100 m ahead (95 m between the boxes):
    # the headway falls below 2 s once the gap is under 40 m, after 2.75 s: at 2.8 s
    cond = xosc.EntityTrigger(
        "headway",
        0,
        xosc.ConditionEdge.none,
        xosc.TimeHeadwayCondition("Target", 2.0, xosc.Rule.lessThan, freespace=True),
        "Ego",
    )
    ev = _event("go", step_speed(30.0), cond)
    path = write(tmp_path, [("Target", [ev])], target=(0, 100.0, 0.0))
    _, rec = play(path, 4.0)
    assert at(rec, 2.7)["Target"][3] == 0.0
    assert at(rec, 2.8)["Target"][3] == 30.0


def test_reset_replays_the_same_run(tmp_path: Path) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.rate, 1.0)
    ev = _event("change", xosc.AbsoluteLaneChangeAction(-2, dyn), at_time(1.0))
    path = write(tmp_path, [("Target", [ev])], activate_at=0.5, target=(1, 30.0, 18.0), stop=6.0)
    env, first = play(path, 7.0)
    env.reset(seed=0)
    again = [r["Target"] for r in _replay(env, len(first) - 1)]
    assert again == [r["Target"] for r in first[1:]]


def _replay(env: object, steps: int) -> list[dict[str, object]]:
    from tests.scenario._build import _snapshot

    out = []
    for _ in range(steps):
        *_, terminated, truncated, info = env.step(1)  # type: ignore[attr-defined]
        out.append(_snapshot(env.scenario, terminated or truncated, info))  # type: ignore[attr-defined]
    return out


def test_execution_count_repeats_an_event_and_instant_actions_show_transitions(
    tmp_path: Path,
) -> None:
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)
    slower = xosc.Event("slower", xosc.Priority.parallel, maxexecution=3)
    slower.add_action(
        "slower_action", xosc.RelativeSpeedAction(-1.0, "Target", step, continuous=False)
    )
    slower.add_trigger(at_time(1.0))
    # an action that starts and ends in one update still shows its startTransition
    seen = _event(
        "seen",
        xosc.AbsoluteLaneOffsetAction(0.5, xosc.DynamicsShapes.step, 1.0),
        xosc.ValueTrigger(
            "started",
            0,
            xosc.ConditionEdge.none,
            xosc.StoryboardElementStateCondition(
                xosc.StoryboardElementType.action,
                "slower_action",
                xosc.StoryboardElementState.startTransition,
            ),
        ),
    )
    path = write(tmp_path, [("Target", [slower, seen])])
    env, rec = play(path, 3.0)
    assert [at(rec, t)["Target"][3] for t in (1.0, 1.1, 1.2, 1.3, 2.0)] == [20, 19, 18, 17, 17]
    # the step-shaped offset moves the car at the next step (as esmini)
    assert at(rec, 1.1)["Target"][2] == 0.0 and at(rec, 1.2)["Target"][2] == pytest.approx(0.5)
    assert env.scenario.storyboard.element("event", "slower").state == "completeState"


def test_skip_priority_does_not_start_while_another_event_runs(tmp_path: Path) -> None:
    slow = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time, 5.0)
    first = _event("long", xosc.AbsoluteSpeedAction(10.0, slow), at_time(1.0))
    second = _event("skipped", step_speed(30.0), at_time(2.0), xosc.Priority.skip)
    path = write(tmp_path, [("Target", [first, second])])
    env, rec = play(path, 8.0)
    assert at(rec, 3.0)["Target"][3] == pytest.approx(20.0 - 10.0 * 1.9 / 5.0)
    event = env.scenario.storyboard.element("event", "skipped")
    # skipped in standby while "long" runs (to 6.1 s), then started (as esmini)
    skips = [t for t in event.transitions if t == "skipTransition"]
    assert len(skips) == 41 and event.transitions[41:] == ["startTransition", "endTransition"]
    assert at(rec, 6.2)["Target"][3] == 30.0


def test_an_action_of_the_same_domain_overrides_a_running_one(tmp_path: Path) -> None:
    slow = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time, 20.0)
    long = _event("long", xosc.AbsoluteSpeedAction(0.0, slow), at_time(1.0))
    jump = _event("jump", step_speed(25.0), at_time(2.0))
    # two maneuvers: priorities do not apply, the domain does
    path = write(tmp_path, [("Target", [long]), ("Target", [jump])])
    env, rec = play(path, 4.0)
    assert at(rec, 2.1)["Target"][3] == 25.0 and at(rec, 4.0)["Target"][3] == 25.0
    action = env.scenario.storyboard.element("action", "long_action")
    assert action.state == "completeState" and action.transitions[-1] == "stopTransition"


def test_an_acts_stop_trigger_stops_its_actions(tmp_path: Path) -> None:
    slow = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time, 10.0)
    man = xosc.Maneuver("brake")
    man.add_event(_event("brake", xosc.AbsoluteSpeedAction(0.0, slow), at_time(1.0)))
    group = xosc.ManeuverGroup("brakers")
    group.add_actor("Target")
    group.add_maneuver(man)
    stop = xosc.ValueTrigger(
        "halt",
        0,
        xosc.ConditionEdge.none,
        xosc.SimulationTimeCondition(2.0, xosc.Rule.greaterThan),
        "stop",
    )
    act = xosc.Act("braking", at_time(0.0, edge=xosc.ConditionEdge.rising), stop)
    act.add_maneuver_group(group)
    story = xosc.Story("story")
    story.add_act(act)
    path = write(tmp_path, stories=[story])
    env, rec = play(path, 4.0)
    held = at(rec, 2.1)["Target"][3]
    assert held == pytest.approx(20.0 - 2.0 * 1.0) and at(rec, 4.0)["Target"][3] == held
    assert env.scenario.storyboard.element("act", "braking").transitions[-1] == "stopTransition"


def test_activation_at_time_zero_sets_the_functions_speed(tmp_path: Path) -> None:
    path = write(tmp_path, activate_at=0.0, target=None, ego_speed=25.0, stop=3.0)
    env, rec = play(path, 3.0)
    assert rec[0]["active"] and env.vehicle.target_speed == 25.0
    assert rec[-1]["Ego"][3] == pytest.approx(25.0, abs=0.3)


def test_simulation_time_compares_exact_step_times(tmp_path: Path) -> None:
    ev = _event("late", step_speed(5.0), at_time(1.2))
    path = write(tmp_path, [("Target", [ev])])
    _, rec = play(path, 2.0)
    assert at(rec, 1.2)["Target"][3] == 20.0 and at(rec, 1.3)["Target"][3] == 5.0


def test_the_stop_trigger_ends_an_env_step_early(tmp_path: Path) -> None:
    import gymnasium as gym

    path = write(tmp_path, stop=3.0)
    env = gym.make("ALDMHighway-v0", config={"scenario": {"xosc": str(path)}}).unwrapped
    env.reset(seed=0)
    ends = [env.step(1)[3] for _ in range(4)]
    assert ends == [False, False, False, True]
    assert env.scenario.world.time == pytest.approx(3.1)


def test_a_misspelled_element_is_an_error(tmp_path: Path) -> None:
    ev = _event("e", step_speed(1.0), at_time(1.0))
    path = _patched(tmp_path, "<StartTrigger>", "<StartTriger>", events=[("Target", [ev])])
    text = path.read_text().replace(
        "</StartTrigger>\n                        </Event>",
        "</StartTriger>\n                        </Event>",
    )
    path.write_text(text)
    line = _line_of(path, "<StartTriger>")
    with pytest.raises(
        ScenarioError,
        match=rf"scenario\.xosc:{line} <StartTriger>: not an element of OpenSCENARIO 1.3 "
        r"inside <Event> \(did you mean <StartTrigger>\?\)",
    ):
        read_scenario(path)


def test_time_headway_defaults_to_the_euclidean_distance(tmp_path: Path) -> None:
    # a target 10 m to the left and 40 m ahead (boxes): the euclidean freespace distance
    # is under 2 s at 20 m/s only when both are close; longitudinally it would be 40 m
    cond = xosc.EntityTrigger(
        "h",
        0,
        xosc.ConditionEdge.none,
        xosc.TimeHeadwayCondition(
            "Target", 2.01, xosc.Rule.lessThan, freespace=False, alongroute=False
        ),
        "Ego",
    )
    path = write(
        tmp_path, [("Target", [_event("go", step_speed(5.0), cond)])], target=(1, 40.0, 20.0)
    )
    condition = path.read_text().split("<TimeHeadwayCondition")[1].split("/>")[0]
    path.write_text(
        path.read_text().replace(
            condition,
            condition.replace(' relativeDistanceType="longitudinal"', "").replace(
                ' relativeDistanceType="euclidianDistance"', ""
            ),
        )
    )
    _, rec = play(path, 1.0)
    # reference points 40 m ahead and 3.5 m across: 40.15 m, 2.008 s at 20 m/s
    assert rec[1]["Target"][3] == 5.0


def test_relative_target_lane_counts_from_the_entitys_left(tmp_path: Path) -> None:
    road = _two_way(tmp_path)
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    ev = _event("left", xosc.RelativeLaneChangeAction(1, "Target", dyn), at_time(0.5))
    path = write(
        tmp_path, [("Target", [ev])], road=road, lane_id=2, ego_s=1500.0, target=(0, -30.0, 20.0)
    )
    _, rec = play(path, 4.0)
    # lane 2 is driven against s; its driver's left is lane 1 (towards the reference line)
    assert rec[0]["Target"][0] == 2 and rec[-1]["Target"][0] == 1


def _two_way(folder: Path) -> Path:
    from tests.scenario._build import straight_road

    return straight_road(folder, left_lanes=2)


def test_subset_covers_every_value_it_can() -> None:
    from aldm_gym.harness.suite import _subset
    from aldm_gym.scenario.distributions import ConcreteRun

    runs = [
        ConcreteRun(i, {"a": str(a), "b": str(b), "c": str(c)})
        for i, (a, b, c) in enumerate(
            (a, b, c) for a in range(7) for b in range(5) for c in range(3)
        )
    ]
    picked = _subset(runs, 7)
    for name, count in (("a", 7), ("b", 5), ("c", 3)):
        assert len({r.parameters[name] for r in picked}) == count
    assert [r.index for r in picked] == sorted(r.index for r in picked)


def test_a_route_along_the_lane_chain_is_played_and_a_ramp_is_passed_by(tmp_path: Path) -> None:
    route = xosc.Route("ahead")
    route.add_waypoint(xosc.LanePosition(200.0, 0.0, -1, 0), xosc.RouteStrategy.shortest)
    route.add_waypoint(xosc.LanePosition(900.0, 0.0, -2, 0), xosc.RouteStrategy.shortest)
    ev = _event("route", xosc.AssignRouteAction(route), at_time(0.5))
    path = write(tmp_path, [("Target", [ev])])
    env, _ = play(path, 2.0)
    assert env.scenario.storyboard.element("action", "route_action").transitions == [
        "startTransition",
        "endTransition",
    ]

    def on_motorway(name: str, road_id: int, *waypoints: tuple[float, int]) -> Path:
        """The target's route through lane -1 of ``(s, road)`` waypoints, on the
        motorway from road ``road_id``."""
        route = xosc.Route(name)
        for s, road in waypoints:
            route.add_waypoint(xosc.LanePosition(s, 0.0, -1, road), xosc.RouteStrategy.shortest)
        ev = _event("route", xosc.AssignRouteAction(route), at_time(0.5))
        return write(
            tmp_path, [("Target", [ev])], road=MOTORWAY, road_id=road_id, ego_s=100.0,
            name=f"{name}.xosc",
        )  # fmt: skip

    # on the motorway the target's lanes run through roads 1-6; road 7 is a ramp
    path = on_motorway("away", 1, (200.0, 1), (100.0, 7))
    # the ramp is reached only by a lane change, which a route does not make: the
    # target follows its lane, as esmini plays it (corpus file
    # route_to_an_exit_from_a_through_lane), and the player says so
    with pytest.warns(ScenarioWarning, match=r"'Target' cannot reach road '7' along its lanes"):
        env, rec = play(path, 2.0)
    assert at(rec, 2.0)["Target"][3] == pytest.approx(20.0)
    assert env.scenario.world.entities["Target"].lane[0] == "1"  # still on its road
    # a waypoint behind the target is on no road it can reach: an error, not a warning
    path = on_motorway("behind", 3, (300.0, 3), (100.0, 1))
    with pytest.raises(ScenarioError, match=r"the route leaves the roads 'Target' can reach"):
        play(path, 2.0)


# ------------------------------------------- elements esmini 3.6 does not play
def _one_event(name: str, action: object, trigger: object) -> xosc.Event:
    ev = xosc.Event(name, xosc.Priority.parallel)
    ev.add_action(f"{name}_action", action)
    ev.add_trigger(trigger)
    return ev


def test_route_positions_from_road_coordinates_and_from_an_entity(tmp_path: Path) -> None:
    """``FromRoadCoordinates``: ``pathS`` along the route from its first waypoint, ``t``
    from the reference line; ``FromCurrentEntity``: where that entity is when the
    action starts. (esmini 3.6 implements neither: it logs them as not implemented.)"""
    from aldm_gym.scenario.esmini import player_trace

    route = xosc.Route("lane1")
    route.add_waypoint(xosc.LanePosition(20.0, 0, -1, 0), xosc.RouteStrategy.shortest)
    route.add_waypoint(xosc.LanePosition(1500.0, 0, -1, 0), xosc.RouteStrategy.shortest)
    hop = xosc.TeleportAction(xosc.RoutePositionInRoadCoordinates(route, 140.0, -8.75))
    onto = xosc.TeleportAction(xosc.RoutePositionOfCurrentEntity(route, "Ego"))
    path = write(
        tmp_path,
        [
            (
                "Target",
                [_one_event("hop", hop, at_time(1.0)), _one_event("onto", onto, at_time(3.0))],
            )
        ],
        target=(1, 50.0, 20.0),
        stop=5.0,
    )
    trace = player_trace(path)
    k_hop = trace.starts["hop"][0]
    k_onto = trace.starts["onto"][0]
    i = int(np.argmin(abs(trace.times - (k_hop + 0.1))))
    np.testing.assert_allclose(trace.poses["Target"][i, :2], [160.0, -8.75], atol=1e-9)
    j = int(np.argmin(abs(trace.times - k_onto)))
    np.testing.assert_allclose(
        trace.poses["Target"][j + 1, :2], trace.poses["Ego"][j, :2], atol=1e-9
    )


@pytest.mark.parametrize(
    ("rule", "fires_at"),
    [('<AddValue value="4"/>', 2.1), ('<MultiplyByValue value="3"/>', 2.1),
     ('<MultiplyByValue value="2"/>', None)],
)  # fmt: skip
def test_a_1_0_parameter_modify_action_adds_or_multiplies(
    tmp_path: Path, rule: str, fires_at: float | None
) -> None:
    """OpenSCENARIO 1.0's ``ParameterAction``/``ModifyAction`` (deprecated, still in the
    1.3 schema; esmini 3.6 ignores it with a warning): 2 + 4 and 2 · 3 pass 5, 2 · 2
    does not."""
    from aldm_gym.scenario.esmini import player_trace

    params = xosc.ParameterDeclarations()
    params.add_parameter(xosc.Parameter("Gain", xosc.ParameterType.double, "2.0"))
    gained = xosc.ValueTrigger(
        "gained", 0.0, xosc.ConditionEdge.none,
        xosc.ParameterCondition("Gain", 5, xosc.Rule.greaterThan),
    )  # fmt: skip
    path = write(
        tmp_path,
        [("Target", [_one_event("modify", xosc.VariableSetAction("Gain", 0.0), at_time(2.0)),
                     _one_event("slow", step_speed(10.0), gained)])],
        parameters=params,
        stop=4.0,
    )  # fmt: skip
    text = path.read_text()
    old = '<VariableAction variableRef="Gain"><SetAction value="0.0"/></VariableAction>'
    compact = "".join(line.strip() for line in text.splitlines())
    assert old in compact
    new = (
        f'<ParameterAction parameterRef="Gain"><ModifyAction><Rule>{rule}</Rule>'
        "</ModifyAction></ParameterAction>"
    )
    path.write_text(compact.replace(old, new))
    starts = player_trace(path).starts
    assert starts["modify"] == pytest.approx([2.1])
    assert starts.get("slow", []) == ([] if fires_at is None else pytest.approx([fires_at]))


def test_a_continuous_relative_lane_offset_keeps_beside_its_reference(tmp_path: Path) -> None:
    """``RelativeTargetLaneOffset`` puts the actor ``value`` left of where the referenced
    entity is, whichever lane that is (esmini's reading), and a continuous one follows
    the reference when it shifts (esmini 3.6 keeps the first target)."""
    from aldm_gym.scenario.esmini import player_trace

    keep = xosc.RelativeLaneOffsetAction(
        0.5, "Target", xosc.DynamicsShapes.sinusoidal, 6.0, continuous=True
    )
    shift = xosc.AbsoluteLaneOffsetAction(0.8, xosc.DynamicsShapes.sinusoidal, 1.0)
    path = write(
        tmp_path,
        [
            ("Ego", [_one_event("keep", keep, at_time(0.5))]),
            ("Target", [_one_event("shift", shift, at_time(4.0))]),
        ],
        lane_id=-3,
        target=(2, 0.0, 20.0),  # two lanes left, beside the ego
        stop=10.0,
    )
    trace = player_trace(path)
    ego_y, target_y = trace.poses["Ego"][:, 1], trace.poses["Target"][:, 1]
    before = int(np.argmin(abs(trace.times - 3.9)))
    assert ego_y[before] == pytest.approx(target_y[before] + 0.5, abs=1e-6)  # OpenDRIVE y
    assert target_y[-1] == pytest.approx(-1.75 + 0.8, abs=1e-6)
    assert ego_y[-1] == pytest.approx(target_y[-1] + 0.5, abs=1e-6)


def test_a_catalog_maneuver_that_is_no_maneuver_is_named(tmp_path: Path) -> None:
    from tests.scenario.corpus import catalogs_and_relative_lane_offset

    path = catalogs_and_relative_lane_offset(tmp_path)
    text = path.read_text()
    good = (
        '<CatalogReference catalogName="maneuvers" entryName="slow_down"><ParameterAssignments>'
        '<ParameterAssignment parameterRef="Speed" value="15"/>'
        '<ParameterAssignment parameterRef="At" value="6"/></ParameterAssignments>'
        "</CatalogReference>"
    )
    assert good in text
    path.write_text(text.replace(good, '<CatalogReference catalogName="cars" entryName="car"/>'))
    with pytest.raises(ScenarioError, match=r"cars.xosc.*is a <Vehicle>, not a <Maneuver>"):
        read_scenario(path)


def test_init_positions_relative_to_each_other_in_a_cycle_are_named(tmp_path: Path) -> None:
    from tests.scenario.corpus import init_relative_to_a_later_entity

    path = init_relative_to_a_later_entity(tmp_path)
    text = path.read_text()
    placed_at = '<LanePosition roadId="0" laneId="-1" s="120.0" offset="0.0"/>'
    assert placed_at in text
    path.write_text(
        text.replace(placed_at, '<RelativeLanePosition entityRef="Ego" ds="30.0" dLane="1"/>')
    )
    with pytest.raises(ScenarioError, match=r"'Target', which the position is relative to.*circle"):
        play(path, seconds=1.0)


@pytest.mark.parametrize("rule", [xosc.Rule.greaterThan, xosc.Rule.lessThan])
def test_a_time_headway_to_an_entity_behind_holds_for_no_rule(tmp_path: Path, rule: object) -> None:
    """The headway to an entity behind is undefined, and so is a time to collision
    that does not close: the condition holds for no rule (esmini: ``greaterThan``
    does not fire for a car behind). Once the faster target is 10 m ahead of the ego
    (0.5 s at 20 m/s) a headway above 0.5 s holds."""
    from aldm_gym.scenario.esmini import player_trace

    headway = xosc.TimeHeadwayCondition(
        "Target", 0.5, rule, alongroute=False, freespace=False,
        distance_type=xosc.RelativeDistanceType.longitudinal,
        coordinate_system=xosc.CoordinateSystem.entity,
    )  # fmt: skip
    trigger = xosc.EntityTrigger("behind", 0, xosc.ConditionEdge.none, headway, "Ego")
    path = write(
        tmp_path,
        [("Ego", [_one_event("slow", step_speed(15.0), trigger)])],
        target=(1, -30.0, 30.0),  # one lane left, 30 m behind, 10 m/s faster
        stop=8.0,
    )
    starts = player_trace(path).starts.get("slow", [])
    if rule == xosc.Rule.lessThan:  # ahead by 0 to 10 m: 3.0 to 4.0 s
        assert len(starts) == 1 and 3.0 < starts[0] <= 4.1
    else:  # ahead by more than 10 m: after 4.0 s, never while it is behind
        assert len(starts) == 1 and 4.0 < starts[0] <= 4.2


def test_a_lane_position_on_a_lane_not_driven_is_a_point_there(tmp_path: Path) -> None:
    """A lane position on a lane that is not driven (a border lane here) is the point
    on its centre: a ``SynchronizeAction``'s target (scenariogeneration's own
    example), or where an entity is placed, which then moves beside the driving lanes."""
    import re

    from tests.scenario._build import straight_road

    road = straight_road(tmp_path)
    text = road.read_text()
    text, n = re.subn(r'(<lane id="-3" type=")driving(")', r"\1border\2", text)
    assert n == 1
    road.write_text(text)
    sync = xosc.SynchronizeAction(
        "Ego",
        xosc.LanePosition(300.0, 0, -3, 0),  # the border lane
        xosc.LanePosition(300.0, 0, -1, 0),
        1.0,
        1.0,
        xosc.AbsoluteSpeed(15.0),
    )
    path = write(
        tmp_path, [("Target", [_one_event("sync", sync, at_time(0.5))])], stop=14.0, road=road
    )
    from aldm_gym.scenario.esmini import player_trace

    trace = player_trace(path)
    ego_x, target_x = trace.poses["Ego"][:, 0], trace.poses["Target"][:, 0]
    k = int(np.argmax(ego_x >= 300.0))  # the ego (the master) arrives
    assert ego_x[k] >= 300.0 and abs(target_x[k] - 300.0) < 2.0
    # an entity placed on the border lane moves beside the driving lanes, on its centre
    text = path.read_text()
    placed = '<LanePosition roadId="0" laneId="-2" s="50.0" offset="0.0"/>'
    assert placed in text
    path.write_text(text.replace(placed, placed.replace('laneId="-2"', 'laneId="-3"')))
    ego = player_trace(path).poses["Ego"]
    np.testing.assert_allclose(ego[:, 1], -8.75, atol=1e-9)  # OpenDRIVE y: lane -3's centre
    assert ego[-1, 0] > ego[0, 0] + 100.0
    bad = path.read_text().replace('laneId="-3" s="300.0"', 'laneId="-3" s="3000.0"')
    path.write_text(bad)
    with pytest.raises(ScenarioError, match="not on the map"):
        player_trace(path)


def test_a_map_without_road_marks_plays_and_the_sensor_sees_nothing(tmp_path: Path) -> None:
    """Test-track maps often carry no road marks (Euro NCAP's straight road): the
    scenario plays, and the line sensor finds no line to measure."""
    import re

    from tests.scenario._build import straight_road

    road = straight_road(tmp_path)
    text, n = re.subn(
        r"<roadMark[^>]*/>|<roadMark[^>]*>.*?</roadMark>", "", road.read_text(), flags=re.S
    )
    assert n > 0 and "roadMark" not in text
    road.write_text(text)
    path = write(tmp_path, [], road=road, stop=2.0)
    env, records = play(path, seconds=1.0)
    assert len(records) == 11 and not records[-1]["done"]
    assert records[-1]["Target"][1] > records[0]["Target"][1] + 15.0  # it drove on
    frame = env.perception.frame
    assert frame is not None and len(frame.all_points) == 0 and len(frame.line_type) == 0


def test_a_lane_change_onto_a_lane_not_driven_ends_on_its_centre(tmp_path: Path) -> None:
    """A lane change onto a border lane (esmini's lane_change_variable) is a lateral
    move to that lane's centre; the entity keeps moving beside the driving lanes."""
    import re

    from aldm_gym.scenario.esmini import player_trace
    from tests.scenario._build import straight_road

    road = straight_road(tmp_path)
    text, n = re.subn(r'(<lane id="-3" type=")driving(")', r"\1border\2", road.read_text())
    assert n == 1
    road.write_text(text)
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    change = xosc.AbsoluteLaneChangeAction(-3, dyn)
    path = write(
        tmp_path, [("Ego", [_one_event("out", change, at_time(1.0))])], stop=6.0, road=road
    )
    ego = player_trace(path).poses["Ego"]
    assert ego[0, 1] == pytest.approx(-5.25)
    np.testing.assert_allclose(ego[-10:, 1], -8.75, atol=1e-6)


def test_handover_at_init_lets_the_function_drive_a_file_without_a_controller(
    tmp_path: Path,
) -> None:
    """Test protocols that name the vehicle under test and carry no controller (Euro
    NCAP's files): with ``scenario.handover="init"`` the function drives from the
    start; by default it never does, and the ego runs into the slower car as scripted."""
    from aldm_gym.cli.scenario import scenario_env
    from aldm_gym.harness.criteria import run_scenario

    path = write(tmp_path, [], target=(0, 40.0, 10.0), ego_speed=20.0, stop=8.0)
    scripted = run_scenario(path, detector="ground_truth")
    assert not scripted.passed and "before the function was activated" in scripted.error
    config = scenario_env([], "init")
    assert dict(config["scenario"]) == {"handover": "init"}
    driven = run_scenario(path, detector="ground_truth", config=config)
    assert driven.judged and driven.finished and not driven.collision
    assert driven.min_time_gap_s > 0.5  # the ACC followed the slower car


def test_files_as_esmini_and_asam_1_0_examples_write_them(tmp_path: Path) -> None:
    """What public files write and esmini accepts: a parameter declared and assigned
    with its ``$``, a ``LaneOffsetAction`` without ``continuous``, a trailer's
    ``<Vehicle>`` straight inside ``<Trailer>`` (named after its tractor and a ``+``),
    and an entity that ``Init`` puts on a trajectory without a teleport."""
    from aldm_gym.scenario.esmini import player_trace

    params = xosc.ParameterDeclarations()
    params.add_parameter(xosc.Parameter("Speed", xosc.ParameterType.double, "12.0"))
    shift = xosc.AbsoluteLaneOffsetAction(0.5, xosc.DynamicsShapes.step, 1.0)
    path = write(
        tmp_path,
        [("Target", [_one_event("fast", step_speed("$Speed"), at_time(0.5)),
                     _one_event("shift", shift, at_time(1.0))])],
        parameters=params,
        stop=3.0,
    )  # fmt: skip
    text = path.read_text()
    assert text.count('name="Speed"') == 1 and text.count('continuous="true"') == 1
    text = text.replace('name="Speed"', 'name="$Speed"').replace(' continuous="true"', "")
    path.write_text(text)
    read_scenario(path)
    trace = player_trace(path)
    assert trace.poses["Target"][-1, 3] == pytest.approx(12.0)
    # a trailer's Vehicle inside <Trailer>, as esmini's vehicle catalog writes it
    rig = write(tmp_path, [], name="rig.xosc", stop=2.0)
    text = rig.read_text()
    inner = (
        '<Trailer><Vehicle name="box" vehicleCategory="trailer"><BoundingBox>'
        '<Center x="3" y="0" z="1.5"/><Dimensions width="2.5" length="10" height="3"/>'
        '</BoundingBox><Performance maxSpeed="40" maxAcceleration="3" maxDeceleration="6"/>'
        '<Axles><FrontAxle maxSteering="0" wheelDiameter="0.8" trackWidth="2.3" '
        'positionX="8" positionZ="0.5"/><RearAxle maxSteering="0" wheelDiameter="0.8" '
        'trackWidth="2.3" positionX="0" positionZ="0.5"/></Axles><TrailerCoupler dx="8"/>'
        "<Properties/></Vehicle></Trailer>"
    )
    start = text.index('<ScenarioObject name="Target">')
    end = text.index("</Vehicle>", start)
    text = text[:end] + '<TrailerHitch dx="0.5"/>' + inner + text[end:]
    rig.write_text(text)
    names = [e.name for e in read_scenario(rig).entities]
    assert names == ["Ego", "Target", "Target+"]
    # an entity that Init puts on a trajectory, with no teleport, starts on it
    poly = xosc.Polyline([], [xosc.WorldPosition(150.0, -1.75), xosc.WorldPosition(250.0, -1.75)])
    traj = xosc.Trajectory("path", False)
    traj.add_shape(poly)
    onto = write(tmp_path, [], name="onto.xosc", stop=2.0)
    text = onto.read_text()
    teleport = text[text.index('<Private entityRef="Target">') :]
    teleport = teleport[teleport.index("<PrivateAction>") : teleport.index("</PrivateAction>") + 16]
    assert "TeleportAction" in teleport
    follow = xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.position)
    init = xosc.Init()
    init.add_init_action("Target", follow)
    element = init.get_element().find(".//PrivateAction")
    from xml.etree import ElementTree

    onto.write_text(text.replace(teleport, ElementTree.tostring(element, encoding="unicode")))
    first = player_trace(onto).poses["Target"][0]
    assert first[0] == pytest.approx(150.0) and first[1] == pytest.approx(-1.75)
