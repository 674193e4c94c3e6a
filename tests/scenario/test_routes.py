"""Routes where a lane splits: the straightest branch by default, a route's branch
towards its next waypoint, a random route's branch from the episode's seed."""

from __future__ import annotations

import warnings
from pathlib import Path

import gymnasium as gym
import pytest
from scenariogeneration import xosc

import aldm_gym  # noqa: F401
from aldm_gym.errors import ScenarioError, ScenarioWarning
from aldm_gym.roads.map_road import OpenDriveRoad, load_map
from aldm_gym.scenario.routes import RoutePlan, drive_to, next_lane
from tests.scenario._build import at_time
from tests.scenario.corpus import on_split_road, split_road

SPLIT = ("0", 0, -3)
"""The lane that splits: road 0's right lane."""
STRAIGHT, EXIT = ("4", 0, -3), ("3", 0, -1)


@pytest.fixture(scope="module")
def road(tmp_path_factory: pytest.TempPathFactory) -> OpenDriveRoad:
    return OpenDriveRoad(load_map(split_road(tmp_path_factory.mktemp("split"))))


def test_a_split_lane_has_both_successors_and_goes_straight_on_by_default(
    road: OpenDriveRoad,
) -> None:
    assert road.successors(SPLIT) == [EXIT, STRAIGHT]  # the map's order: exit first
    assert road.successor(SPLIT) == STRAIGHT  # the straightest, not the first
    assert road.successors(("0", 0, -2)) == [("4", 0, -2)]
    assert next_lane(road, None, SPLIT) == STRAIGHT


def test_a_route_plan_takes_the_branch_to_its_next_waypoint(road: OpenDriveRoad) -> None:
    # road 0, then the spiral (its lane is 40 m of reference line, shorter on the inside)
    assert drive_to(road, SPLIT, "2") == pytest.approx(300.0 + road.lane_length(EXIT))
    assert drive_to(road, STRAIGHT, "2") == float("inf")
    assert drive_to(road, SPLIT, "0") == 0.0
    plan = RoutePlan(["0", "2"])
    assert next_lane(road, plan, SPLIT) == EXIT
    assert plan.pending == ["2"]  # road 0 reached; the connecting road 3 is not road 2
    # once every waypoint is reached, the straightest again
    plan = RoutePlan(["0", "2"])
    plan.reached("0")
    plan.reached("2")
    assert plan.choose(road, SPLIT, road.successors(SPLIT)) == STRAIGHT
    # a waypoint no branch leads to is passed over for the next one
    plan = RoutePlan(["9", "2"])
    assert plan.choose(road, SPLIT, road.successors(SPLIT)) == EXIT
    assert RoutePlan(["9"]).choose(road, SPLIT, road.successors(SPLIT)) == STRAIGHT


def _random_route(folder: Path) -> Path:
    """The target on the splitting lane told to take random routes; the ego beside it."""
    event = _event("random", xosc.RandomRouteAction())
    rows = [("Ego", 0, -1, 200.0), ("Target", 0, -3, 200.0)]
    return on_split_road(folder, rows, [("Target", event)], 12.0, "random_route")


def _event(name: str, action: object) -> xosc.Event:
    ev = xosc.Event(name, xosc.Priority.override)
    ev.add_action(f"{name}_action", action)
    ev.add_trigger(at_time(0.5))
    return ev


def _target_road_after(path: Path, seed: int, seconds: float = 9.0) -> str:
    config = {"scenario": {"xosc": str(path)}, "policy_frequency": 10, "simulation_frequency": 10}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make("ALDMHighway-v0", config=config).unwrapped
        env.reset(seed=seed)
    world = env.scenario.world
    while world.time < seconds - 1e-9:
        env.step(1)
    return str(world.entities["Target"].lane[0])


def test_a_random_route_draws_its_branch_from_the_episode_seed(tmp_path: Path) -> None:
    path = _random_route(tmp_path)
    roads = {seed: _target_road_after(path, seed) for seed in range(6)}
    # 100 m to the split at 20 m/s, then 40 m of junction: on road 1 or 2 by 9 s
    assert set(roads.values()) == {"1", "2"}, roads
    for seed in (0, 1):
        assert _target_road_after(path, seed) == roads[seed]  # the same seed, the same branch


def _routed(
    folder: Path,
    name: str,
    rows: list[tuple[str, int, int, float]],
    *waypoints: tuple[float, int, int],
    stop: float = 3.0,
) -> Path:
    """The target given a route through ``(s, lane id, road id)`` waypoints at 0.5 s,
    on the split road with the cars of ``rows``."""
    route = xosc.Route(name)
    for s, lane, road_id in waypoints:
        route.add_waypoint(xosc.LanePosition(s, 0, lane, road_id), xosc.RouteStrategy.shortest)
    event = _event("route", xosc.AssignRouteAction(route))
    return on_split_road(folder, rows, [("Target", event)], stop, name)


def test_a_route_to_a_road_no_lane_reaches_is_an_error(tmp_path: Path) -> None:
    """A waypoint on the exit road seen from the through road's lanes: no branch, and
    no lane beside them, leads back there."""
    rows = [("Ego", 1, -1, 50.0), ("Target", 1, -3, 50.0)]
    path = _routed(tmp_path, "back", rows, (60.0, -3, 1), (100.0, -1, 2))
    with pytest.raises(ScenarioError, match=r"road '2' is on none of them"):
        _target_road_after(path, 0, 2.0)


def test_reaching_a_waypoint_passes_those_before_it() -> None:
    plan = RoutePlan(["0", "9", "2", "1"])
    plan.reached("2")  # "0" and "9" (one no branch led to) are behind it now
    assert plan.pending == ["1"]
    plan.reached("7")  # on no waypoint's road: nothing changes
    assert plan.pending == ["1"]


def test_a_route_checks_each_waypoint_from_the_lanes_it_can_be_on(tmp_path: Path) -> None:
    """A first waypoint on the actor's road but another lane, a second on the exit:
    the actor is on the splitting lane, so it reaches both (no warning) and exits."""
    rows = [("Ego", 0, -1, 200.0), ("Target", 0, -3, 200.0)]
    path = _routed(tmp_path, "exit", rows, (250.0, -1, 0), (100.0, -1, 2), stop=12.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ScenarioWarning)
        assert _target_road_after(path, 0) == "2"
