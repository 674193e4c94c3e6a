"""Generated traffic: swarms, sources, sinks and their stop (aldm_gym.scenario.traffic)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scenariogeneration import xosc

from aldm_gym.errors import ScenarioError
from aldm_gym.scenario import read_scenario
from tests.scenario._build import STEP, at_time, write


def _global(name: str, action: Any, t: float = 0.5) -> xosc.Event:
    ev = xosc.Event(name, xosc.Priority.override)
    ev.add_action(f"{name}_action", action)
    ev.add_trigger(at_time(t, name=f"{name}_t"))
    return ev


CARS_ONLY = (
    '<TrafficDefinition name="cars"><VehicleCategoryDistribution>'
    '<VehicleCategoryDistributionEntry category="car" weight="1"/>'
    "</VehicleCategoryDistribution><ControllerDistribution>"
    '<ControllerDistributionEntry weight="1"><Controller name="idm"><Properties/>'
    "</Controller></ControllerDistributionEntry></ControllerDistribution>"
    "</TrafficDefinition>"
)
"""Cars only."""

DEFINITION = (
    '<TrafficDefinition name="mix"><VehicleCategoryDistribution>'
    '<VehicleCategoryDistributionEntry category="car" weight="3"/>'
    '<VehicleCategoryDistributionEntry category="truck" weight="1"/>'
    "</VehicleCategoryDistribution><ControllerDistribution>"
    '<ControllerDistributionEntry weight="1"><Controller name="idm"><Properties/>'
    "</Controller></ControllerDistributionEntry></ControllerDistribution>"
    "</TrafficDefinition>"
)
"""A traffic definition as OpenSCENARIO 1.0-1.2 writes it (files written for esmini)."""


def _with_traffic(path: Path, bodies: dict[str, str]) -> Path:
    """Put each traffic action's body in place of the ``TrafficStopAction`` of its
    ``trafficName`` (scenariogeneration writes 1.3, where a TrafficDefinition is
    deprecated)."""
    text = path.read_text()
    for name, body in bodies.items():
        placeholder = f'<TrafficAction trafficName="{name}">\n'
        start = text.index(placeholder) + len(placeholder)
        end = text.index("<TrafficStopAction/>", start) + len("<TrafficStopAction/>")
        text = text[:start] + body + text[end:]
    path.write_text(text)
    return path


def _run(path: Path, seconds: float, seed: int = 0) -> tuple[Any, list[list[tuple]]]:
    """Play a scenario with the IDLE function; per step the generated vehicles as
    ``(generator, category, x, y, speed)``."""
    import warnings

    import gymnasium as gym

    import aldm_gym  # noqa: F401

    cfg = {"scenario": {"xosc": str(path)}, "policy_frequency": 10, "simulation_frequency": 10}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make("ALDMHighway-v0", config=cfg).unwrapped
        env.reset(seed=seed)
    frames = []
    while env.scenario.world.time < seconds - 1e-9:
        *_, terminated, truncated, _ = env.step(1)
        frames.append(
            [
                (v.generated_by, v.category, *map(float, v.position), float(v.speed))
                for v in env.road.vehicles
                if getattr(v, "generated_by", None) is not None
            ]
        )
        if terminated or truncated:
            break
    return env, frames


def test_a_swarm_keeps_its_vehicles_in_the_ring_and_follows_the_seed(tmp_path: Path) -> None:
    swarm = (
        '<TrafficSwarmAction semiMajorAxis="150" semiMinorAxis="12" innerRadius="30" '
        'offset="20" numberOfVehicles="6"><CentralObject entityRef="Ego"/>'
        f'{DEFINITION}<InitialSpeedRange lowerLimit="18" upperLimit="22"/>'
        "</TrafficSwarmAction>"
    )
    events = [_global("swarm", xosc.TrafficStopAction("swarm"))]
    path = write(tmp_path, [("Ego", events)], target=None, stop=20.0)
    _with_traffic(path, {"swarm": swarm})
    env, frames = _run(path, 12.0)
    ego = env.scenario.world.entities["Ego"].vehicle
    assert frames[2] == []  # it starts at 0.5 s
    kept = frames[-1]
    assert len(kept) == 6 and {g for g, *_ in kept} == {"swarm"}
    assert {c for _, c, *_ in kept} <= {"car", "truck"}
    h = float(ego.heading)
    for _, _, x, y, speed in kept:
        d = np.array([x, y]) - np.asarray(ego.position)
        along = d[0] * math.cos(h) + d[1] * math.sin(h) - 20.0
        across = -d[0] * math.sin(h) + d[1] * math.cos(h)
        assert (along / 150.0) ** 2 + (across / 12.0) ** 2 <= 1.0 + 1e-9
        assert 0.0 < speed < 30.0
    _, again = _run(path, 12.0)
    assert again == frames  # the same seed, the same traffic
    _, other = _run(path, 12.0, seed=1)
    assert other != frames


def test_a_source_places_at_its_rate_a_sink_removes_and_a_stop_ends_it(tmp_path: Path) -> None:
    # OpenSCENARIO 1.0-1.2 spelling (a TrafficDefinition), as files written for esmini
    source = (
        '<TrafficSourceAction rate="1" radius="0" velocity="15"><Position>'
        '<LanePosition roadId="0" laneId="-1" offset="0" s="150"/></Position>'
        f"{CARS_ONLY}</TrafficSourceAction>"
    )
    sink = (
        '<TrafficSinkAction radius="10"><Position>'
        '<LanePosition roadId="0" laneId="-1" offset="0" s="200"/></Position>'
        "</TrafficSinkAction>"
    )
    events = [
        _global("source", xosc.TrafficStopAction("ramp"), t=1.0),
        _global("sink", xosc.TrafficStopAction("exit"), t=0.0),
        _global("stop", xosc.TrafficStopAction("ramp"), t=3.95),
    ]
    # one maneuver each: an event of one maneuver would override the others
    path = write(tmp_path, [("Ego", [ev]) for ev in events], target=None, stop=15.0)
    _with_traffic(path, {"ramp": source, "exit": sink})
    env, frames = _run(path, 14.0)
    counts = [len([v for v in f if v[0] == "ramp"]) for f in frames]
    times = [round(STEP * (k + 1), 1) for k in range(len(frames))]
    # started once the time is past 1 s: placed at 1.1, 2.1 and 3.1 s (the one due
    # at 4.1 s is stopped at 4 s), each at 15 m/s
    assert counts[times.index(1.0)] == 0 and counts[times.index(1.1)] == 1
    assert counts[times.index(3.0)] == 2 and counts[times.index(3.1)] == 3
    assert max(counts) == 3
    # 40-60 m on at 15 m/s the sink takes them: from 1.1 + 40 / 15 ≈ 3.8 s for the first
    assert counts[-1] == 0
    gone = next(t for t, c in zip(times, counts, strict=True) if t > 3.1 and c < 3)
    assert 3.7 < gone < 4.9
    assert all(v.entity is not None for v in env.road.vehicles if hasattr(v, "entity"))


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (
            '<TrafficSwarmAction semiMajorAxis="100" semiMinorAxis="10" innerRadius="5" '
            f'offset="0" numberOfVehicles="500"><CentralObject entityRef="Ego"/>{DEFINITION}'
            "</TrafficSwarmAction>",
            r"numberOfVehicles must be in \[0, 200\], got 500",
        ),
        (
            '<TrafficSourceAction rate="0" radius="1"><Position><WorldPosition x="0" y="0"/>'
            f"</Position>{DEFINITION}</TrafficSourceAction>",
            r"rate must be > 0 \[vehicles/s\], got 0",
        ),
        (
            '<TrafficSourceAction rate="1" radius="1" velocity="1e9"><Position>'
            f'<WorldPosition x="0" y="0"/></Position>{DEFINITION}</TrafficSourceAction>',
            r"velocity must be in \[0, 100\] \[m/s\], got 1e\+09",
        ),
        (
            '<TrafficSwarmAction semiMajorAxis="100" semiMinorAxis="10" innerRadius="5" '
            'offset="0" numberOfVehicles="5"><CentralObject entityRef="Nobody"/>'
            f"{DEFINITION}</TrafficSwarmAction>",
            "entityRef='Nobody' names no scenario object",
        ),
        (
            '<TrafficSwarmAction semiMajorAxis="100" semiMinorAxis="10" innerRadius="5" '
            'offset="0" numberOfVehicles="5"><CentralObject entityRef="Ego"/>'
            '<TrafficDefinition name="d"><VehicleCategoryDistribution>'
            '<VehicleCategoryDistributionEntry category="spaceship" weight="1"/>'
            "</VehicleCategoryDistribution></TrafficDefinition></TrafficSwarmAction>",
            "category='spaceship' is not one of",
        ),
    ],
)
def test_bad_traffic_actions_are_refused_by_name(tmp_path: Path, body: str, message: str) -> None:
    path = write(tmp_path, [("Ego", [_global("bad", xosc.TrafficStopAction("t"))])], target=None)
    _with_traffic(path, {"t": body})
    with pytest.raises(ScenarioError, match=f"scenario.xosc:\\d+ <\\w+>: {message}"):
        read_scenario(path)


def test_a_stop_without_a_name_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, [("Ego", [_global("bad", xosc.TrafficStopAction())])], target=None)
    with pytest.raises(ScenarioError, match="needs the trafficName to stop"):
        read_scenario(path)


TEMPLATES = (
    "<TrafficDistribution>"
    '<TrafficDistributionEntry weight="3"><EntityDistribution>'
    '<EntityDistributionEntry weight="1"><ScenarioObjectTemplate>'
    '<Vehicle name="van" vehicleCategory="van"><BoundingBox><Center x="1.5" y="0" z="1"/>'
    '<Dimensions width="2.1" length="6.0" height="2.4"/></BoundingBox>'
    '<Performance maxSpeed="40" maxAcceleration="4" maxDeceleration="8"/>'
    '<Axles><FrontAxle maxSteering="0.5" wheelDiameter="0.7" trackWidth="1.8" positionX="3" '
    'positionZ="0.35"/><RearAxle maxSteering="0" wheelDiameter="0.7" trackWidth="1.8" '
    'positionX="0" positionZ="0.35"/></Axles><Properties/></Vehicle>'
    "</ScenarioObjectTemplate></EntityDistributionEntry>"
    "</EntityDistribution></TrafficDistributionEntry>"
    "</TrafficDistribution>"
)
"""1.3's spelling: vehicles drawn from an entity template (a 6 m x 2.1 m van)."""


def _area(shape: str, count: int = 4, continuous: bool = True) -> str:
    return (
        f'<TrafficAreaAction continuous="{str(continuous).lower()}" '
        f'numberOfEntities="{count}">{TEMPLATES}<TrafficArea>{shape}</TrafficArea>'
        "</TrafficAreaAction>"
    )


ROAD_RANGE = (
    '<RoadRange><RoadCursor roadId="0" s="150"><Lane id="-1"/><Lane id="-3"/></RoadCursor>'
    '<RoadCursor roadId="0" s="450"/></RoadRange>'
)
"""Lanes -1 and -3 of road 0 from s = 150 to 450 m."""


def test_a_traffic_area_keeps_its_count_on_its_road_range(tmp_path: Path) -> None:
    """``TrafficAreaAction`` (1.3), continuous: ``numberOfEntities`` vehicles from the
    distribution's template, on the range's lanes; those that leave are replaced."""
    events = [_global("area", xosc.TrafficStopAction("area"))]
    path = write(tmp_path, [("Ego", events)], target=None, stop=30.0)
    _with_traffic(path, {"area": _area(ROAD_RANGE)})
    env, frames = _run(path, 25.0)
    assert frames[2] == []  # it starts at 0.5 s
    assert len(frames[-1]) == 4
    road = env.scenario.world.road
    for _, category, x, y, _ in frames[-1]:
        assert category == "van"
        pos = road.lane_position(np.array([x, y]))
        assert road.lane_record(pos.lane).lane_id in (-1, -3)
        assert 150.0 - 1e-6 <= pos.s <= 450.0 + 1e-6
    vans = [v for v in env.road.vehicles if getattr(v, "generated_by", None) == "area"]
    assert {(v.LENGTH, v.WIDTH) for v in vans} == {(6.0, 2.1)}
    # at 70-80 % of the speed limit the first ones left the 300 m range long ago: these
    # replaced them
    _, again = _run(path, 25.0)
    assert again == frames  # the same seed, the same traffic


def test_a_traffic_area_in_a_polygon_placed_once(tmp_path: Path) -> None:
    """Not continuous: the vehicles are placed once in the polygon and drive on."""
    corners = "".join(
        f'<Position><WorldPosition x="{x}" y="{y}"/></Position>'
        for x, y in ((100, 0), (300, 0), (300, -11), (100, -11))
    )
    events = [_global("area", xosc.TrafficStopAction("area"))]
    path = write(tmp_path, [("Ego", events)], target=None, stop=30.0)
    _with_traffic(path, {"area": _area(f"<Polygon>{corners}</Polygon>", 3, False)})
    _, frames = _run(path, 20.0)
    first = next(f for f in frames if f)
    assert all(100.0 <= x <= 300.0 for _, _, x, _, _ in first)
    assert len(frames[-1]) == 3
    assert max(x for _, _, x, _, _ in frames[-1]) > 300.0  # they drove out, none new


@pytest.mark.parametrize(
    ("body", "message"),
    [
        (_area(ROAD_RANGE).replace("<Vehicle", "<Pedestrian").replace("</Vehicle>",
         "</Pedestrian>"), None),
        (_area('<RoadRange><RoadCursor roadId="0" s="10"/></RoadRange>'), "needs >= 2 road"),
        (_area(ROAD_RANGE, count=500), "numberOfEntities must be in"),
    ],
)  # fmt: skip
def test_bad_traffic_areas_are_refused_by_name(
    tmp_path: Path, body: str, message: str | None
) -> None:
    path = write(tmp_path, [("Ego", [_global("area", xosc.TrafficStopAction("area"))])])
    _with_traffic(path, {"area": body})
    with pytest.raises(ScenarioError, match=message or "Pedestrian"):
        read_scenario(path)


def test_a_1_3_swarm_draws_from_a_traffic_distribution(tmp_path: Path) -> None:
    swarm = (
        '<TrafficSwarmAction semiMajorAxis="150" semiMinorAxis="12" innerRadius="30" '
        f'offset="20" numberOfVehicles="3"><CentralObject entityRef="Ego"/>{TEMPLATES}'
        "</TrafficSwarmAction>"
    )
    events = [_global("swarm", xosc.TrafficStopAction("swarm"))]
    path = write(tmp_path, [("Ego", events)], target=None, stop=20.0)
    _with_traffic(path, {"swarm": swarm})
    _, frames = _run(path, 8.0)
    assert len(frames[-1]) == 3 and {c for _, c, *_ in frames[-1]} == {"van"}


def test_the_verdict_sees_a_generated_vehicle_ahead(tmp_path: Path) -> None:
    from aldm_gym.harness.criteria import run_scenario

    source = (
        '<TrafficSourceAction rate="0.1" radius="0" velocity="8"><Position>'
        '<LanePosition roadId="0" laneId="-2" offset="0" s="100"/></Position>'
        f"{CARS_ONLY}</TrafficSourceAction>"
    )
    events = [_global("source", xosc.TrafficStopAction("slow"), t=0.0)]
    path = write(tmp_path, [("Ego", events)], target=None, stop=8.0, activate_at=0.0)
    _with_traffic(path, {"slow": source})
    result = run_scenario(path, detector="ground_truth", marking_model="per_dash")
    # 50 m ahead of the ego's rear axle at 8 m/s against its 20 m/s: the ACC closes in
    assert result.min_time_gap_s < 3.0 and result.min_ttc_s < 10.0


def test_a_swarm_written_for_openscenario_1_0_plays(tmp_path: Path) -> None:
    """1.0 named the central object ``CentralSwarmObject`` and gave the speed as
    ``velocity``."""
    swarm = (
        '<TrafficSwarmAction semiMajorAxis="120" semiMinorAxis="10" innerRadius="25" '
        'offset="0" numberOfVehicles="3" velocity="21"><CentralSwarmObject entityRef="Ego"/>'
        f"{CARS_ONLY}</TrafficSwarmAction>"
    )
    path = write(tmp_path, [("Ego", [_global("swarm", xosc.TrafficStopAction("s"))])], target=None)
    _with_traffic(path, {"s": swarm})
    _, frames = _run(path, 3.0)
    assert len(frames[-1]) == 3
    first = next(f for f in frames if f)
    assert 21.0 in {v[-1] for v in first}  # placed at its velocity (IDM drives on)


def test_an_idle_sink_saves_nothing_up() -> None:
    """A sink removes at most ``rate`` vehicles a second, also after a long idle time."""
    from types import SimpleNamespace

    from aldm_gym.scenario.traffic import Sink, TrafficDefinition

    class Car:
        def __init__(self, x: float) -> None:
            self.position, self.generated_by = np.array([x, 0.0]), "src"

    road = SimpleNamespace(vehicles=[])
    runner = SimpleNamespace(traffic=road)
    sink = Sink(
        name="exit", definition=TrafficDefinition(), point=(0.0, 0.0), radius=10.0, rate=0.5
    )
    rng = np.random.default_rng(0)
    for _ in range(100):  # 10 s without a vehicle in reach
        sink.step(runner, rng, 0.1)
    road.vehicles.extend(Car(x) for x in (-2.0, 0.0, 2.0, 30.0))
    sink.step(runner, rng, 0.1)
    assert len(road.vehicles) == 3  # one removed, not all three in reach
    for _ in range(19):  # 1.9 s more at 0.5 a second: none due yet
        sink.step(runner, rng, 0.1)
    assert len(road.vehicles) == 3
    sink.step(runner, rng, 0.1)
    assert len(road.vehicles) == 2
