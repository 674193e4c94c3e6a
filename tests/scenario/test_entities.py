"""Entities deleted and added at run time (``EntityAction``) and angle conditions,
played in the env: the road, the conditions and the errors; the agreement with esmini
is tests/scenario/test_esmini.py's (corpus ``entities_deleted_and_added``,
``angle_conditions``)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scenariogeneration import xosc

from aldm_gym.errors import ScenarioError
from aldm_gym.scenario import conditions as C
from tests.scenario._build import (
    STEP,
    at,
    at_time,
    cars_and_board,
    placed,
    play,
    save,
    step_speed,
    write,
)
from tests.scenario.corpus import CORPUS, _curved_road, _event


def _road_vehicles(env: object) -> int:
    return len(env.road.vehicles)  # type: ignore[attr-defined]


def test_a_deleted_entity_leaves_the_road_and_comes_back_where_it_is_added(
    tmp_path: Path,
) -> None:
    import gymnasium as gym

    import aldm_gym  # noqa: F401

    path = CORPUS["entities_deleted_and_added"](tmp_path)
    cfg = {"scenario": {"xosc": str(path)}, "policy_frequency": 10, "simulation_frequency": 10}
    env = gym.make("ALDMHighway-v0", config=cfg).unwrapped
    env.reset(seed=0)
    runner = env.scenario
    world = runner.world
    late, target = world.entities["Late"], world.entities["Target"]
    # Init deletes Late, which it does not place: only the ego and the target drive
    assert not late.present and _road_vehicles(env) == 2
    seen: dict[float, tuple[bool, bool, int]] = {}
    positions: dict[float, np.ndarray] = {}
    while world.time < 8.0 - 1e-9:
        env.step(1)
        t = round(world.time, 1)
        seen[t] = (target.present, runner.on_road(target), _road_vehicles(env))
        positions[t] = target.reference_point().copy()
    # deleted at 2.1 s: out for the conditions at once, off the road from the next step
    assert seen[2.0] == (True, True, 2)
    assert seen[2.1] == (False, True, 2)
    assert seen[2.2] == (False, False, 1)  # Late arrives at 3.2 s
    assert seen[3.2][2] == 2
    # added back at 5.1 s: in at once, on the road at 250 m on lane -3 at the next step
    assert seen[5.1][:2] == (True, False)
    assert seen[5.2] == (True, True, 3)
    c = world.coordinates(target)
    assert c.lane_id == -3 and c.s > 250.0
    # it moved on from 250 m at the speed it had (20 m/s) in the step that placed it
    assert world.coordinates(target).s == pytest.approx(250.0 + 20.0 * (8.0 - 5.1), abs=1e-6)
    # the ego's event on the target's speed waited while the target was gone
    assert runner.storyboard.starts("event")["on_target_speed"] == [pytest.approx(5.1)]
    env.close()


def _patched(folder: Path, action: str) -> Path:
    """A scenario whose target's event at 1 s is ``action`` (XML of a GlobalAction)."""
    path = write(folder, [("Target", [_event("e", step_speed(5.0), at_time(1.0))])])
    text = path.read_text()
    start = text.index("<PrivateAction>", text.index('<Event name="e"'))
    end = text.index("</PrivateAction>", start) + len("</PrivateAction>")
    path.write_text(text[:start] + action + text[end:])
    return path


def test_deleting_the_function_under_test_is_an_error_naming_the_action(tmp_path: Path) -> None:
    path = _patched(
        tmp_path, '<GlobalAction><EntityAction entityRef="Ego"><DeleteEntityAction/>'
        "</EntityAction></GlobalAction>"
    )  # fmt: skip
    with pytest.raises(ScenarioError, match=r"scenario\.xosc:\d+ <GlobalAction>.*deletes 'Ego'"):
        play(path, seconds=2.0)


def test_an_entity_init_does_not_place_is_still_an_error_unless_it_is_added(
    tmp_path: Path,
) -> None:
    path = write(tmp_path, [("Ego", [_event("e", step_speed(20.0), at_time(5.0))])], target=None)
    text = path.read_text().replace(
        "</Entities>",
        '<ScenarioObject name="Late"><CatalogReference catalogName="x" entryName="y"/>'
        "</ScenarioObject></Entities>",
    )
    # a vehicle the Init does not place: the car of the target, renamed
    ego = text[text.index('<ScenarioObject name="Ego">') : text.index("</ScenarioObject>") + 17]
    text = text.replace(
        '<ScenarioObject name="Late"><CatalogReference catalogName="x" entryName="y"/>'
        "</ScenarioObject>",
        ego.replace('name="Ego"', 'name="Late"'),
    )
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"Init places no position for \['Late'\]"):
        play(path, seconds=0.5)
    added = text.replace(
        "<Story ",
        '<Story name="arrive"><Act name="a"><ManeuverGroup name="g" maximumExecutionCount="1">'
        '<Actors selectTriggeringEntities="false"/><Maneuver name="m"><Event name="in" '
        'priority="override"><Action name="add"><GlobalAction><EntityAction entityRef="Late">'
        '<AddEntityAction><Position><LanePosition roadId="0" laneId="-1" s="120" offset="0"/>'
        "</Position></AddEntityAction></EntityAction></GlobalAction></Action><StartTrigger>"
        '<ConditionGroup><Condition name="t" delay="0" conditionEdge="none"><ByValueCondition>'
        '<SimulationTimeCondition value="1" rule="greaterThan"/></ByValueCondition></Condition>'
        "</ConditionGroup></StartTrigger></Event></Maneuver></ManeuverGroup><StartTrigger>"
        '<ConditionGroup><Condition name="go" delay="0" conditionEdge="none"><ByValueCondition>'
        '<SimulationTimeCondition value="0" rule="greaterOrEqual"/></ByValueCondition>'
        "</Condition></ConditionGroup></StartTrigger></Act></Story><Story ",
        1,
    )
    path.write_text(added)
    env, records = play(path, seconds=2.0)
    late = env.scenario.world.entities["Late"]
    assert late.present and env.scenario.on_road(late)
    c = env.scenario.world.coordinates(late)
    assert c.lane_id == -1 and c.s == pytest.approx(120.0)  # no speed: it stands there
    assert not records[0]["active"]


def test_angles_in_world_road_and_lane_coordinates(tmp_path: Path) -> None:
    from highway_env.road.road import Road

    from aldm_gym.roads.map_road import OpenDriveRoad
    from aldm_gym.scenario.reader import read_scenario
    from aldm_gym.scenario.runner import ScenarioRunner
    from aldm_gym.scenario.world import ScenarioVehicle

    path = write(
        tmp_path,
        [],
        road=_curved_road(tmp_path),
        ego_s=300.0,  # in the arc of R 250 m, 200 m in: the road turned 0.8 rad left
        lane_id=-1,
        target=(0, 0.0, 20.0),
    )
    scenario = read_scenario(path)
    road = OpenDriveRoad.from_file(str(scenario.map_path), marking_model="editor")
    runner = ScenarioRunner(scenario, road, "Ego")
    traffic = Road(network=road.network, vehicles=[])
    runner.populate(traffic, lambda tr, pos, h, v: ScenarioVehicle(tr, pos, h, v), STEP)
    world, ego = runner.world, runner.world.entities["Ego"]
    assert C.angle(world, ego, "heading", "world") == pytest.approx(0.8, abs=1e-4)
    assert C.angle(world, ego, "heading", "road") == pytest.approx(0.0, abs=1e-4)
    assert C.angle(world, ego, "heading", "lane") == pytest.approx(0.0, abs=1e-4)
    assert C.angle(world, ego, "pitch", "world") == 0.0
    ego.vehicle.heading -= 0.1  # turned 0.1 rad to the left (highway-env's y is down)
    assert C.angle(world, ego, "heading", "road") == pytest.approx(0.1, abs=1e-4)
    target = world.entities["Target"]
    assert C.relative_angle(world, ego, target, "heading", "entity") == pytest.approx(0.1, abs=1e-4)
    assert C.angle_within(math.pi - 0.01, -math.pi + 0.01, 0.03)  # across the wrap
    assert not C.angle_within(0.5, 0.3, 0.1)


def test_a_relative_angle_condition_fires_when_the_lane_change_turns_the_actor(
    tmp_path: Path,
) -> None:
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 3.0)
    turned = xosc.EntityTrigger(
        "turned",
        0,
        xosc.ConditionEdge.none,
        xosc.RelativeAngleCondition(
            0.03, 0.01, xosc.AngleType.heading, "Ego", xosc.CoordinateSystem.entity
        ),
        "Target",
    )
    path = write(
        tmp_path,
        [
            (
                "Target",
                [
                    _event("change", xosc.RelativeLaneChangeAction(1, "Target", dyn), at_time(1.0)),
                    _event("slow", step_speed(10.0), turned, xosc.Priority.parallel),
                ],
            )
        ],
        lane_id=-2,
        target=(0, 30.0, 20.0),
        stop=6.0,
    )
    env, _ = play(path, seconds=6.0)
    starts = env.scenario.storyboard.starts("event")
    # the target turns left (towards lane -1) relative to the ego within 0.3 s
    assert starts["change"] == [pytest.approx(1.1)]
    assert 1.2 <= starts["slow"][0] <= 1.6


def test_a_vehicle_keeps_its_osi_id_while_another_is_away(tmp_path: Path) -> None:
    import gymnasium as gym

    import aldm_gym  # noqa: F401
    from aldm_gym.osi.messages import VEHICLE_ID
    from aldm_gym.osi.trace import read_messages

    path = CORPUS["entities_deleted_and_added"](tmp_path)
    out = tmp_path / "run.mcap"
    cfg = {
        "scenario": {"xosc": str(path)},
        "policy_frequency": 10,
        "simulation_frequency": 10,
        "osi": {"trace": str(out)},
    }
    env = gym.make("ALDMHighway-v0", config=cfg).unwrapped
    env.reset(seed=0)
    for _ in range(60):
        env.step(1)
    env.close()
    views = [m for _, m in read_messages(out, "SensorView")]
    ids = [sorted(o.id.value for o in v.global_ground_truth.moving_object) for v in views]
    # ego 0 and target 1 at the start; the target gone from 2.2 s; Late (2) from 3.2 s;
    # the target back with its own id from 5.2 s
    assert ids[0] == [VEHICLE_ID, VEHICLE_ID + 1]
    assert ids[25] == [VEHICLE_ID]
    assert ids[40] == [VEHICLE_ID, VEHICLE_ID + 2]
    assert ids[55] == [VEHICLE_ID, VEHICLE_ID + 1, VEHICLE_ID + 2]


def _selections(folder: Path) -> Path:
    """``EntitySelection``s: the two other cars (by name) slow down together at 1 s;
    the ego changes lanes when all vehicles (by type) drive slower than 20.5 m/s; a
    selection of a selection and the ego is the actor of a speed change at 6 s."""
    init = placed([("Ego", -2, 50.0, 20.0), ("Left", -1, 90.0, 22.0), ("Right", -3, 70.0, 21.0)])
    entities, board = cars_and_board(("Ego", "Left", "Right"), init, 9.0)
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    slow = xosc.Maneuver("slow")
    slow.add_event(_event("slow_down", xosc.AbsoluteSpeedAction(15.0, dyn), at_time(1.0)))
    board.add_maneuver(slow, "others")
    all_slow = xosc.EntityTrigger(
        "all_slow", 0, xosc.ConditionEdge.none,
        xosc.SpeedCondition(20.5, xosc.Rule.lessThan), "vehicles",
        xosc.TriggeringEntitiesRule.all,
    )  # fmt: skip
    lane = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    ego = xosc.Maneuver("ego")
    ego.add_event(_event("change", xosc.RelativeLaneChangeAction(1, "Ego", lane), all_slow))
    board.add_maneuver(ego, "Ego")
    together = xosc.Maneuver("together")
    together.add_event(_event("speed_up", xosc.AbsoluteSpeedAction(25.0, dyn), at_time(6.0)))
    board.add_maneuver(together, "everyone")
    path = save(folder, "selections.xosc", entities, board)
    text = path.read_text().replace(
        "</Entities>",
        '<EntitySelection name="others"><Members><EntityRef entityRef="Left"/>'
        '<EntityRef entityRef="Right"/></Members></EntitySelection>'
        '<EntitySelection name="vehicles"><Members><ByType objectType="vehicle"/></Members>'
        "</EntitySelection>"
        '<EntitySelection name="everyone"><Members><EntityRef entityRef="others"/>'
        '<EntityRef entityRef="Ego"/></Members></EntitySelection></Entities>',
    )
    path.write_text(text)
    return path


def test_a_selection_plays_as_its_members_spelled_out(tmp_path: Path) -> None:
    """esmini 3.6 reads ``EntitySelection`` but finds no entity by its name, so the
    selection is checked against the same file with the members named one by one."""
    from aldm_gym.scenario.esmini import player_trace

    path = _selections(tmp_path)
    text = path.read_text()
    spelled = tmp_path / "spelled.xosc"

    def refs(*names: str) -> str:
        return "".join(f'<EntityRef entityRef="{n}"/>' for n in names)

    spelled.write_text(
        text.replace('<EntityRef entityRef="others"/>\n', refs("Left", "Right") + "\n")
        .replace('<EntityRef entityRef="vehicles"/>', refs("Ego", "Left", "Right"))
        .replace('<EntityRef entityRef="everyone"/>', refs("Left", "Right", "Ego"))
    )
    assert 'entityRef="others"/>\n' not in spelled.read_text()
    ours, theirs = player_trace(path), player_trace(spelled)
    assert set(ours.poses) == {"Ego", "Left", "Right"}
    for name in ours.poses:
        np.testing.assert_array_equal(ours.poses[name], theirs.poses[name])
    assert ours.starts == theirs.starts
    # the two others slow down together, the ego changes lanes once all are slow
    assert ours.starts["slow_down"] == [pytest.approx(1.1)]
    assert len(ours.starts["change"]) == 1 and ours.starts["change"][0] > 1.1
    assert ours.starts["speed_up"] == [pytest.approx(6.1)]
    end = ours.poses["Ego"][-1]
    assert end[3] > 20.0 and ours.poses["Left"][-1][3] > 15.0


@pytest.mark.parametrize(
    ("members", "message"),
    [
        ('<EntityRef entityRef="nobody"/>', "entityRef='nobody' names no scenario object"),
        ('<EntityRef entityRef="loop"/>', "the selection 'loop' contains itself"),
        ('<ByType objectType="external"/>', "external objects are not played"),
    ],
)
def test_a_bad_selection_is_named(tmp_path: Path, members: str, message: str) -> None:
    from aldm_gym.scenario import read_scenario

    path = write(tmp_path, [])
    text = path.read_text().replace(
        "</Entities>",
        f'<EntitySelection name="loop"><Members>{members}</Members></EntitySelection></Entities>',
    )
    path.write_text(text)
    with pytest.raises(ScenarioError, match=rf"scenario\.xosc:\d+ <\w+>: {message}"):
        read_scenario(path)


def test_a_selection_where_one_entity_is_needed_is_an_error(tmp_path: Path) -> None:
    from aldm_gym.scenario import read_scenario

    path = write(tmp_path, [])
    text = path.read_text().replace(
        "</Entities>",
        '<EntitySelection name="both"><Members><EntityRef entityRef="Ego"/>'
        '<EntityRef entityRef="Target"/></Members></EntitySelection></Entities>',
    )
    text = text.replace(
        '<RelativeLanePosition entityRef="Ego"', '<RelativeLanePosition entityRef="both"'
    )
    path.write_text(text)
    with pytest.raises(ScenarioError, match="'both' is an EntitySelection; one scenario object"):
        read_scenario(path)


def test_a_towed_trailer_follows_its_hitch_and_does_not_collide_with_its_tractor(
    tmp_path: Path,
) -> None:
    path = CORPUS["trailers"](tmp_path)
    env, records = play(path, seconds=12.0)
    world = env.scenario.world
    truck, towed = world.entities["Truck"], world.entities["Towed"]
    assert truck.trailer is towed and towed.tractor is truck
    hitch = truck.reference_point() + truck.hitch * truck.forward()
    coupler = towed.reference_point() + towed.coupler * towed.forward()
    assert np.hypot(*(hitch - coupler)) < 1e-9  # the coupler sits on the hitch
    # the trailer's box overlaps the tractor's (a fifth wheel): no collision for the
    # road nor for a CollisionCondition
    assert C.box_distance(truck, towed) == 0.0
    assert not C.boxes_overlap(truck, towed)
    assert not truck.vehicle.crashed and not towed.vehicle.crashed
    # the disconnected trailer goes on by itself along its lane at the hauler's speed
    loose, hauler = world.entities["Loose"], world.entities["Hauler"]
    assert loose.tractor is None and hauler.trailer is None
    assert at(records, 12.0)["Loose"][3] == pytest.approx(15.0)
    assert at(records, 11.0)["Loose"][1] < at(records, 12.0)["Loose"][1]


def _with_trailer(folder: Path, change: Callable[[str], str]) -> Path:
    path = CORPUS["trailers"](folder)
    path.write_text(change(path.read_text()))
    return path


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t.replace('<TrailerCoupler dx="8.0"/>', "", 1), "has no <TrailerCoupler>"),
        (lambda t: t.replace('<TrailerHitch dx="0.5"/>', "", 1), "has no <TrailerHitch>"),
        (
            lambda t: t.replace('trailerRef="Loose"', 'trailerRef="Towed"'),
            "'Towed' is towed by 'Truck' already",
        ),
    ],
)
def test_a_trailer_that_cannot_be_towed_is_named(
    tmp_path: Path, change: Callable[[str], str], message: str
) -> None:
    from aldm_gym.scenario import read_scenario

    path = _with_trailer(tmp_path, change)
    with pytest.raises(ScenarioError, match=message):
        read_scenario(path)
        play(path, seconds=2.0)


def test_the_function_under_test_does_not_tow(tmp_path: Path) -> None:
    activate = (
        '<Private entityRef="Truck"><PrivateAction><ActivateControllerAction '
        'lateral="true" longitudinal="true"/></PrivateAction></Private></Actions>'
    )
    path = _with_trailer(tmp_path, lambda t: t.replace("</Actions>", activate, 1))
    with pytest.raises(ScenarioError, match="takes 'Truck', which tows a trailer"):
        play(path, seconds=2.0, scenario={"xosc": str(path), "ego": "Truck"})


@pytest.mark.parametrize(("ref", "towed"), [("", False), ("Loose", True)])
def test_esmini_catalogs_name_a_trailer_by_entity_ref(
    tmp_path: Path, ref: str, towed: bool
) -> None:
    """esmini's own vehicle catalog writes ``<Trailer><EntityRef .../></Trailer>`` (for
    ``TrailerRef``), with an empty name for none."""
    from aldm_gym.scenario import read_scenario

    path = CORPUS["trailers"](tmp_path)
    text = path.read_text()
    hauler = text.index('<ScenarioObject name="Hauler">')
    hitch = text.index('<TrailerHitch dx="0.5"/>', hauler) + len('<TrailerHitch dx="0.5"/>')
    text = text[:hitch] + f'<Trailer><EntityRef entityRef="{ref}"/></Trailer>' + text[hitch:]
    text = text.replace('<ConnectTrailerAction trailerRef="Loose"/>', "<DisconnectTrailerAction/>")
    path.write_text(text)
    spec = read_scenario(path).entity("Hauler")
    assert spec.trailer == ("Loose" if towed else None)
