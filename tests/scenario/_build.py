"""Small scenarios for the player's tests, written with scenariogeneration.

A straight two-way-free road of three 3.5 m lanes (ids -1, -2, -3 from the left),
2 km long; an ``Ego`` and a ``Target`` car (5 m x 2 m, reference point 1.4 m behind
the box centre). :func:`play` runs a file in the env and records every entity's road
coordinates at every 0.1 s step.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from scenariogeneration import xodr, xosc

from aldm_gym.harness import lane_drop

STEP = 0.1
"""The tests' simulation step [s] (10 Hz, policy at 10 Hz)."""


def straight_road(folder: Path, length: float = 2000.0, left_lanes: int = 0) -> Path:
    """A straight road with three lanes to the right of its reference line (driven
    along ``s``) and ``left_lanes`` to its left (driven against it)."""
    path = folder / f"straight_{left_lanes}.xodr"
    if not path.exists():
        road = xodr.create_road(
            xodr.Line(length), id=0, left_lanes=left_lanes, right_lanes=3, lane_width=3.5
        )
        odr = xodr.OpenDrive("straight")
        odr.add_road(road)
        odr.adjust_roads_and_lanes()
        odr.write_xml(str(path))
    return path


def with_geo_reference(
    source: Path, target: Path, proj: str, offset: tuple[float, float, float] | None = None
) -> Path:
    """``source``'s map written to ``target`` with a header ``<geoReference>`` of
    ``proj`` and, if given, an ``<offset>`` ``(x [m], y [m], hdg [rad])``."""
    text = source.read_text()
    start = text.index("<header")
    head = text[start : text.index(">", start) + 1]
    extra = f"<geoReference><![CDATA[{proj}]]></geoReference>"
    if offset is not None:
        extra += f'<offset x="{offset[0]}" y="{offset[1]}" z="0" hdg="{offset[2]}"/>'
    new = head[:-2] + ">" + extra + "</header>" if head.endswith("/>") else head + extra
    target.write_text(text.replace(head, new, 1))
    return target


car = lane_drop.car
"""A 5 m x 2 m car, reference point at the rear axle (box centre 1.4 m ahead)."""


def step_speed(v: float) -> xosc.AbsoluteSpeedAction:
    """A speed set at once."""
    return xosc.AbsoluteSpeedAction(
        v, xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)
    )


def at_time(t: float, name: str = "t", edge: Any = None, delay: float = 0.0) -> xosc.ValueTrigger:
    """A trigger: simulation time > ``t``."""
    return xosc.ValueTrigger(
        name,
        delay,
        edge or xosc.ConditionEdge.none,
        xosc.SimulationTimeCondition(t, xosc.Rule.greaterThan),
    )


def placed(rows: Sequence[tuple[str, int, float, float]]) -> xosc.Init:
    """An ``Init`` that puts each ``(name, lane id, s [m], speed [m/s])`` on road 0."""
    init = xosc.Init()
    for name, lane, s, v in rows:
        init.add_init_action(name, xosc.TeleportAction(xosc.LanePosition(s, 0, lane, 0)))
        init.add_init_action(name, step_speed(v))
    return init


def cars_and_board(
    names: Sequence[str], init: xosc.Init, stop: float
) -> tuple[xosc.Entities, xosc.StoryBoard]:
    """Cars called ``names`` and a storyboard of ``init`` that stops at ``stop`` [s],
    for scenarios that :func:`write` does not cover (more than two cars)."""
    entities = xosc.Entities()
    for name in names:
        entities.add_scenario_object(name, car())
    return entities, lane_drop.storyboard(init, stop)


def save(folder: Path, name: str, entities: xosc.Entities, board: xosc.StoryBoard) -> Path:
    """Write ``entities`` and ``board`` on the straight road as ``folder/name``."""
    scenario = xosc.Scenario(
        name, "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(straight_road(folder))), xosc.Catalog(),
    )  # fmt: skip
    path = folder / name
    scenario.write_xml(str(path))
    return path


def write(
    folder: Path,
    events: Sequence[tuple[str, Sequence[xosc.Event]]] = (),
    *,
    ego_s: float = 50.0,
    ego_speed: float | str = 20.0,
    target: tuple[int, float, float] | None = (1, 60.0, 20.0),
    stop: float = 10.0,
    activate_at: float | None = None,
    parameters: xosc.ParameterDeclarations | None = None,
    stories: Sequence[xosc.Story] = (),
    road: Path | None = None,
    lane_id: int = -2,
    road_id: int = 0,
    name: str = "scenario.xosc",
    domains: tuple[bool, bool] = (True, True),
    target_first: bool = False,
    variables: xosc.VariableDeclarations | None = None,
) -> Path:
    """A scenario: the ego on lane ``lane_id`` at ``ego_s`` [m] and ``ego_speed`` [m/s];
    the target ``(dLane, ds [m], speed [m/s])`` from it; ``events`` as ``(actor, [Event])``
    maneuvers; the ego's controller activated at ``activate_at`` [s] (0: in ``Init``;
    never if None);
    the scenario stops at ``stop`` [s]; ``domains`` are the (lateral, longitudinal)
    domains the activation hands to the function; ``target_first`` puts the target
    before the ego in the file; ``variables`` are the file's variable declarations;
    the ego's road is ``road_id``; ``stories`` are added as they are."""
    ents = xosc.Entities()
    if target is not None and target_first:
        ents.add_scenario_object("Target", car())
    ents.add_scenario_object("Ego", car())
    if target is not None and not target_first:
        ents.add_scenario_object("Target", car())
    init = xosc.Init()
    init.add_init_action("Ego", xosc.TeleportAction(xosc.LanePosition(ego_s, 0, lane_id, road_id)))
    init.add_init_action("Ego", step_speed(ego_speed))
    if activate_at == 0.0:  # in Init: the function drives from the start
        init.add_init_action("Ego", xosc.ActivateControllerAction(*domains))
    if target is not None:
        d_lane, ds, v = target
        init.add_init_action(
            "Target",
            xosc.TeleportAction(xosc.RelativeLanePosition(lane_id=d_lane, entity="Ego", ds=ds)),
        )
        init.add_init_action("Target", step_speed(v))
    board = lane_drop.storyboard(init, stop)
    for k, (actor, evs) in enumerate(events):
        man = xosc.Maneuver(f"maneuver{k}")
        for ev in evs:
            man.add_event(ev)
        board.add_maneuver(man, actor)
    for story in stories:
        board.add_story(story)
    if activate_at is not None and activate_at != 0.0:
        ev = xosc.Event("activate", xosc.Priority.override)
        ev.add_action("activate_action", xosc.ActivateControllerAction(*domains))
        ev.add_trigger(at_time(activate_at))
        man = xosc.Maneuver("activation")
        man.add_event(ev)
        board.add_maneuver(man, "Ego")
    scenario = xosc.Scenario(
        "test",
        "aldm-gym tests",
        parameters or xosc.ParameterDeclarations(),
        ents,
        board,
        xosc.RoadNetwork(str(road or straight_road(folder))),
        xosc.Catalog(),
        variable_declaration=variables,
    )
    path = folder / name
    scenario.write_xml(str(path))
    return path


def play(path: Path, seconds: float = 30.0, **config: Any) -> tuple[Any, list[dict[str, Any]]]:
    """Run a scenario (IDLE function); per step: ``{"time", "<entity>": (lane_id, s,
    offset, speed), "active", "done"}``. Returns (the env, the records)."""
    import gymnasium as gym

    import aldm_gym  # noqa: F401

    cfg = {"scenario": {"xosc": str(path)}, "policy_frequency": 10, "simulation_frequency": 10}
    cfg.update(config)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make("ALDMHighway-v0", config=cfg).unwrapped
        env.reset(seed=0)
    runner = env.scenario
    records = [_snapshot(runner, False)]
    while runner.world.time < seconds - 1e-9:
        *_, terminated, truncated, info = env.step(1)
        records.append(_snapshot(runner, terminated or truncated, info))
        if terminated or truncated:
            break
    return env, records


def _snapshot(runner: Any, done: bool, info: Any = None) -> dict[str, Any]:
    world = runner.world
    out: dict[str, Any] = {"time": world.time, "active": runner.active, "done": done}
    for name, e in world.entities.items():
        c = world.coordinates(e)
        out[name] = (c.lane_id, c.s, c.offset, e.current_speed)
    out["crashed"] = bool(info and info.get("crashed"))
    return out


def at(records: list[dict[str, Any]], t: float) -> dict[str, Any]:
    """The record at time ``t`` [s]."""
    return min(records, key=lambda r: abs(r["time"] - t))
