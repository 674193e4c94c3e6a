"""The traffic mix: trucks in the env (``traffic`` section), their gaps and placement."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from highway_env.road.road import Road, RoadNetwork

import aldm_gym
from aldm_gym.envs.observation import lane_gaps
from aldm_gym.envs.traffic import FastIDMVehicle
from aldm_gym.envs.traffic.mix import Spawner, TrafficConfig, TruckSpec, make_truck

MAPS = Path(aldm_gym.__file__).parent / "roads" / "maps"


def _env(**config: Any) -> Any:
    return gym.make("ALDMHighway-v0", config={"detector": "ground_truth", **config})


def _others(env: Any) -> list[Any]:
    u = env.unwrapped
    return [v for v in u.road.vehicles if v is not u.vehicle]


def test_no_trucks_by_default_and_nothing_drawn() -> None:
    rng = np.random.default_rng(5)
    state = rng.bit_generator.state
    spawner = Spawner(TrafficConfig(), rng)
    assert spawner.draw() is None
    assert spawner.extra_shift(None) == 0.0
    assert rng.bit_generator.state == state  # a car-only env's episodes stay as they were
    env = _env()
    env.reset(seed=1)
    assert {v.LENGTH for v in _others(env)} == {5.0}


def test_trucks_have_their_size_speed_and_keep_their_lane() -> None:
    env = _env(traffic={"truck_share": 1.0, "truck_length": [14.0, 16.0]})
    env.reset(seed=2)
    others = _others(env)
    assert others
    for v in others:
        assert 14.0 <= v.LENGTH <= 16.0
        assert v.WIDTH == 2.5 and v.HEIGHT == 4.0
        assert 21.0 <= v.target_speed <= 24.0 and v.speed <= v.target_speed
        assert not v.enable_lane_change
        assert v.diagonal == pytest.approx(np.hypot(v.LENGTH, v.WIDTH))


@pytest.mark.parametrize("share", [0.3, 1.0])
def test_trucks_start_with_the_gaps_of_cars(share: float) -> None:
    """Every vehicle after a truck moves on by the truck's extra length: no overlap."""
    for seed in range(4):
        env = _env(traffic={"truck_share": share}, vehicles_density=1.5)
        env.reset(seed=seed)
        vehicles = env.unwrapped.road.vehicles
        by_lane: dict[Any, list[tuple[float, float]]] = {}
        for v in vehicles:
            s, _ = v.lane.local_coordinates(v.position)
            by_lane.setdefault(v.lane_index, []).append((s, v.LENGTH))
        for row in by_lane.values():
            row.sort()
            for (s0, l0), (s1, l1) in itertools.pairwise(row):
                assert s1 - s0 - 0.5 * (l0 + l1) > 2.0


def test_a_car_keeps_the_same_bumper_gap_behind_a_truck_as_behind_a_car() -> None:
    road = Road(network=RoadNetwork.straight_road_network(1), np_random=np.random.default_rng(0))
    lane = road.network.get_lane(("0", "1", 0))
    car = FastIDMVehicle(road, lane.position(100.0, 0.0), 0.0, 25.0)
    truck = FastIDMVehicle(road, lane.position(140.0, 0.0), 0.0, 22.0)
    make_truck(truck, TruckSpec(length=15.0, speed=22.0), TrafficConfig())
    # The truck's centre 40 m ahead: its rear 32.5 m ahead, as a car's 35 m ahead.
    leader = FastIDMVehicle(road, lane.position(135.0, 0.0), 0.0, 22.0)
    behind_truck = car.acceleration(car, truck)
    assert behind_truck == pytest.approx(car.acceleration(car, leader), rel=1e-12)
    # ... and is not what highway-env's centre-to-centre gap gives (the test can fail).
    plain = FastIDMVehicle(road, lane.position(140.0, 0.0), 0.0, 22.0)
    assert car.acceleration(car, plain) > behind_truck + 0.01


def test_truck_gaps_in_the_lanes_observation() -> None:
    codes = np.array([1.0, 1.0])
    x = np.array([30.0, -20.0])
    vx = np.zeros(2)
    cars = lane_gaps(codes, x, vx, 150.0)
    trucks = lane_gaps(codes, x, vx, 150.0, lengths=np.array([15.0, 17.0]))
    assert cars[1, 0] == 25.0 and cars[1, 2] == 15.0
    assert trucks[1, 0] == 20.0 and trucks[1, 2] == 9.0
    with pytest.raises(ValueError, match="lengths"):
        lane_gaps(codes, x, vx, 150.0, lengths=np.array([15.0]))


def test_traffic_with_trucks_is_deterministic_and_does_not_crash() -> None:
    def run() -> list[Any]:
        env = _env(traffic={"truck_share": 0.4})
        env.reset(seed=7)
        for _ in range(15):
            env.step(1)
        return [(v.position.tobytes(), v.LENGTH, v.crashed) for v in env.unwrapped.road.vehicles]

    first = run()
    assert first == run()
    assert any(length > 5.0 for _, length, _ in first)
    assert not any(crashed for *_, crashed in first)


def test_trucks_on_an_opendrive_map() -> None:
    env = _env(road={"xodr": str(MAPS / "motorway.xodr")}, traffic={"truck_share": 1.0})
    env.reset(seed=0)
    others = _others(env)
    assert others and all(v.LENGTH >= 12.0 for v in others)
    for _ in range(10):
        env.step(1)
    assert not any(v.crashed for v in env.unwrapped.road.vehicles)


@pytest.mark.parametrize(
    ("traffic", "match"),
    [
        ({"truck_share": 1.5}, "traffic.truck_share"),
        ({"truck_length": [18.0, 12.0]}, "traffic.truck_length"),
        ({"truck_width": 0.2}, "traffic.truck_width"),
        ({"trucks": 0.1}, r"unknown traffic key.*'truck_share'"),
    ],
)
def test_bad_traffic_settings_name_the_key(traffic: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _env(traffic=traffic)
