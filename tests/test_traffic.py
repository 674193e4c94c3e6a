"""FastRoad / FastIDMVehicle give highway-env's results: same neighbours, collisions, episodes."""

from __future__ import annotations

import copy
import math
from typing import Any

import gymnasium as gym
import highway_env  # noqa: F401  (registers the highway envs)
import numpy as np
import pytest
from highway_env.road.lane import CircularLane, SineLane, StraightLane
from highway_env.road.road import Road, RoadNetwork
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import Landmark, Obstacle

from aldm_gym.envs.traffic import (
    FastIDMVehicle,
    FastRoad,
    FastRoadNetwork,
    _clip,
    _power,
    use_fast_road,
)

FAST_IDM = "aldm_gym.envs.traffic.FastIDMVehicle"


def _make_env(env_id: str, vehicles: int, fast: bool, **config: Any) -> Any:
    cfg: dict[str, Any] = {
        "vehicles_count": vehicles,
        "lanes_count": 4,
        "simulation_frequency": 5,
        "policy_frequency": 1,
        "duration": 10**6,
        **config,
    }
    if fast:
        cfg["other_vehicles_type"] = FAST_IDM
    env = gym.make(env_id, config=cfg)
    if fast:
        use_fast_road(env)
    return env


def _state(env: Any) -> list[tuple[Any, ...]]:
    return [
        (
            v.position.tobytes(),
            float(v.heading),
            float(v.speed),
            v.lane_index,
            getattr(v, "target_lane_index", None),
            v.crashed,
        )
        for v in env.unwrapped.road.vehicles
    ]


def _check_neighbours(road: FastRoad) -> int:
    """Compare every vehicle's neighbours on its lane and side lanes with ``Road``'s."""
    checked = 0
    for vehicle in road.vehicles:
        lanes = [None, vehicle.lane_index, *road.network.side_lanes(vehicle.lane_index)]
        for lane_index in lanes:
            fast = road.neighbour_vehicles(vehicle, lane_index)
            base = Road.neighbour_vehicles(road, vehicle, lane_index)
            assert fast[0] is base[0] and fast[1] is base[1], (vehicle, lane_index)
            checked += 1
    return checked


# -- whole episodes -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("env_id", "vehicles", "seed"),
    [("highway-fast-v0", 20, 0), ("highway-fast-v0", 40, 1), ("highway-v0", 20, 2)],
)
def test_seeded_episodes_are_identical(env_id: str, vehicles: int, seed: int) -> None:
    """30 IDLE steps with Road+IDMVehicle and FastRoad+FastIDMVehicle match bit for bit."""
    runs = []
    for fast in (False, True):
        env = _make_env(env_id, vehicles, fast)
        obs, _ = env.reset(seed=seed)
        trace: list[tuple[Any, ...]] = [(obs.tobytes(), _state(env))]
        episode_seed = seed
        for _ in range(30):
            obs, reward, terminated, truncated, _ = env.step(1)
            trace.append((obs.tobytes(), reward, _state(env)))
            if terminated or truncated:
                episode_seed += 100
                obs, _ = env.reset(seed=episode_seed)
                trace.append((obs.tobytes(), _state(env)))
        assert isinstance(env.unwrapped.road, FastRoad) == fast
        runs.append(trace)
    assert runs[0] == runs[1]


@pytest.mark.parametrize("connected", [False, True])
def test_neighbours_match_base_every_step(connected: bool) -> None:
    """At every simulation step, before the vehicles act, neighbours equal Road's."""
    env = _make_env("highway-v0", 30, fast=True, neighbour_vehicles_connected_lanes=connected)
    env.reset(seed=3)
    base = env.unwrapped
    road = base.road
    assert isinstance(road, FastRoad)
    checked = 0
    act = road.act

    def checked_act() -> None:
        nonlocal checked
        checked += _check_neighbours(road)
        act()

    road.act = checked_act  # type: ignore[method-assign]
    for _ in range(6):
        _, _, terminated, _, _ = env.step(1)
        if terminated:
            break
    assert checked > 0


def test_close_objects_match_base() -> None:
    """close_objects_to / close_vehicles_to return the same objects in the same order."""
    env = _make_env("highway-v0", 30, fast=True)
    env.reset(seed=4)
    road = env.unwrapped.road
    road.objects.append(Obstacle(road, road.vehicles[3].position + np.array([12.0, 0.0])))
    for _ in range(3):
        env.step(1)
        for vehicle in road.vehicles[:10]:
            for kwargs in (
                {"distance": 60.0},
                {"distance": 100.0, "count": 5, "see_behind": False},
                {"distance": 80.0, "sort": False, "vehicles_only": True},
            ):
                fast = road.close_objects_to(vehicle, **kwargs)
                base = Road.close_objects_to(road, vehicle, **kwargs)
                assert [id(o) for o in fast] == [id(o) for o in base]


# -- synthetic scenes ------------------------------------------------------------------


def _dense_scene(seed: int, n: int = 40) -> Road:
    """Vehicles and objects packed on 3 lanes with random headings: many collisions."""
    rng = np.random.default_rng(seed)
    road = Road(network=RoadNetwork.straight_road_network(3, length=300.0))
    for _ in range(n):
        position = [rng.uniform(0, 80), rng.uniform(-1, 9)]
        v = Vehicle(road, position, heading=rng.normal(0, 0.3), speed=rng.uniform(-5, 30))
        v.check_collisions = bool(rng.random() < 0.7)
        v.collidable = bool(rng.random() < 0.9)
        road.vehicles.append(v)
    for k in range(6):
        cls = Obstacle if k % 2 else Landmark
        road.objects.append(cls(road, [rng.uniform(0, 80), rng.uniform(0, 8)]))
    return road


@pytest.mark.parametrize("seed", range(5))
def test_collisions_match_base(seed: int) -> None:
    """Crashed / hit flags and impacts after several steps equal the O(n²) loop's."""
    base = _dense_scene(seed)
    fast = FastRoad.from_road(copy.deepcopy(base))
    for _ in range(3):
        base.step(0.1)
        fast.step(0.1)
        for a, b in zip(base.vehicles + base.objects, fast.vehicles + fast.objects, strict=True):
            assert (a.crashed, a.hit) == (b.crashed, b.hit)
            assert np.array_equal(np.asarray(a.impact), np.asarray(b.impact))
            assert a.position.tobytes() == b.position.tobytes()
    assert any(v.crashed for v in fast.vehicles)


def test_neighbour_ties_follow_base_order() -> None:
    """Equal longitudinal coordinates: front = last in list order, rear = first."""
    road = FastRoad(network=RoadNetwork.straight_road_network(2, length=200.0))
    for x in (10.0, 50.0, 50.0, 50.0, 90.0, 90.0, 30.0, 30.0):
        road.vehicles.append(Vehicle(road, [x, 0.0], speed=20.0))
    road.objects.append(Obstacle(road, [50.0, 0.5]))  # off-centre: same s, on lane
    road.objects.append(Landmark(road, [60.0, 0.0]))  # landmarks are never neighbours
    for lane_index in (None, ("0", "1", 0), ("0", "1", 1)):
        for vehicle in road.vehicles:
            fast = road.neighbour_vehicles(vehicle, lane_index)
            base = Road.neighbour_vehicles(road, vehicle, lane_index)
            assert fast[0] is base[0] and fast[1] is base[1]
    outsider = Vehicle(road, [50.0, 0.0], speed=20.0)  # not in road.vehicles
    assert road.neighbour_vehicles(outsider) == Road.neighbour_vehicles(road, outsider)


class _ManyStraightLane(StraightLane):
    """A StraightLane subclass offering ``local_coordinates_many`` (generic lane path)."""

    def local_coordinates_many(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        delta = points - self.start
        return (
            delta[:, 0] * self.direction[0] + delta[:, 1] * self.direction[1],
            delta[:, 0] * self.direction_lateral[0] + delta[:, 1] * self.direction_lateral[1],
        )


def _mixed_network() -> RoadNetwork:
    net = RoadNetwork()
    for i in range(3):
        net.add_lane("a", "b", _ManyStraightLane([0, 4.0 * i], [200, 4.0 * i]))
    net.add_lane("b", "c", SineLane([200, 0], [400, 0], amplitude=2, pulsation=0.05, phase=0))
    net.add_lane("b", "c", StraightLane([200, 4], [400, 4]))
    net.add_lane("c", "d", CircularLane([400, 60], 60, -np.pi / 2, 0.0))
    return net


@pytest.mark.parametrize("connected", [False, True])
def test_generic_lanes_match_base(connected: bool) -> None:
    """local_coordinates_many lanes, lanes without it, and connected-lane search."""
    rng = np.random.default_rng(7)
    road = FastRoad(network=_mixed_network(), neighbour_vehicles_connected_lanes=connected)
    for _ in range(40):
        position = [rng.uniform(-10, 470), rng.uniform(-3, 12)]
        road.vehicles.append(IDMVehicle(road, position, heading=0.0, speed=20.0))
    for _ in range(5):
        _check_neighbours(road)
        road.act()
        road.step(0.2)


def test_closest_lane_matches_base() -> None:
    """FastRoadNetwork.get_closest_lane_index equals RoadNetwork's, NaN included."""
    rng = np.random.default_rng(11)
    for net in (_mixed_network(), RoadNetwork.straight_road_network(4, angle=0.3)):
        fast = FastRoadNetwork.from_network(net)
        points = rng.uniform([-20, -20], [480, 80], size=(300, 2))
        headings = [*rng.uniform(-4, 4, 299).tolist(), None]
        for point, heading in zip(points, headings, strict=True):
            assert fast.get_closest_lane_index(point, heading) == net.get_closest_lane_index(
                point, heading
            )
        nan = np.array([np.nan, 1.0])
        assert fast.get_closest_lane_index(nan, 0.0) == net.get_closest_lane_index(nan, 0.0)


def test_cache_follows_vehicles_moved_outside_road_step() -> None:
    """A vehicle stepped on its own, or appended, is seen by the next query."""
    road = FastRoad(network=RoadNetwork.straight_road_network(2, length=500.0))
    for x in (10.0, 40.0, 70.0):
        road.vehicles.append(IDMVehicle(road, [x, 0.0], speed=20.0))
    ego = road.vehicles[0]
    assert road.neighbour_vehicles(ego)[0] is road.vehicles[1]
    for _ in range(25):  # 50 m: overtakes vehicle 1 without road.step
        ego.speed = 20.0
        ego.step(0.1)
    assert road.neighbour_vehicles(ego) == Road.neighbour_vehicles(road, ego)
    road.vehicles.append(IDMVehicle(road, [ego.position[0] + 1.0, 0.0], speed=20.0))
    assert road.neighbour_vehicles(ego)[0] is road.vehicles[-1]


# -- float helpers ---------------------------------------------------------------------


def test_scalar_helpers_match_numpy() -> None:
    """_clip / _power reproduce np.clip / np.power bit for bit (signed zeros, NaN)."""
    values = [-0.0, 0.0, -2.0, 0.3, 1.0, 7.5, math.inf, -math.inf, math.nan]
    for x in values:
        for low, high in ((-1, 1), (0, 30), (-0.0, 0.0), (-math.pi / 4, math.pi / 4)):
            expected = float(np.clip(x, low, high))
            got = _clip(x, low, high)
            assert (math.isnan(expected) and math.isnan(got)) or (
                expected == got and math.copysign(1, expected) == math.copysign(1, got)
            )
    rng = np.random.default_rng(0)
    for base in rng.uniform(0, 3, 200).tolist():
        for exponent in (2, 2.0, 0.5, -1.0, 3.5, 4.0, 4.4):
            assert _power(base, exponent) == float(np.power(base, exponent))


def test_use_fast_road_is_idempotent_and_repoints_vehicles() -> None:
    """Every vehicle of the env queries the FastRoad, also after a reset."""
    env = gym.make("highway-fast-v0")
    base = use_fast_road(env)
    assert use_fast_road(env) is base
    for _ in range(2):
        assert isinstance(base.road, FastRoad)
        assert all(v.road is base.road for v in base.road.vehicles)
        env.reset(seed=0)
    assert not isinstance(base.road.vehicles[1], FastIDMVehicle)  # vehicles untouched
