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

from aldm_gym.envs.traffic import FastIDMVehicle, FastRoad, FastRoadNetwork, use_fast_road
from aldm_gym.envs.traffic.scalar import clip_scalar, not_zero_scalar, power_scalar

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


def _neighbours_checked_while_stepping(env: Any, seed: int, steps: int) -> int:
    """Step with IDLE, comparing neighbours with Road's before every ``act``; checks made."""
    env.reset(seed=seed)
    road = env.unwrapped.road
    assert isinstance(road, FastRoad)
    checked = 0
    act = road.act

    def checked_act() -> None:
        nonlocal checked
        checked += _check_neighbours(road)
        act()

    road.act = checked_act  # type: ignore[method-assign]
    for _ in range(steps):
        _, _, terminated, _, _ = env.step(1)
        if terminated:
            break
    return checked


@pytest.mark.parametrize("connected", [False, True])
def test_neighbours_match_base_every_step(connected: bool) -> None:
    """At every simulation step, before the vehicles act, neighbours equal Road's."""
    env = _make_env("highway-v0", 30, fast=True, neighbour_vehicles_connected_lanes=connected)
    assert _neighbours_checked_while_stepping(env, seed=3, steps=6) > 0


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
    """clip_scalar / power_scalar reproduce np.clip / np.power bit for bit (signed zeros, NaN)."""
    values = [-0.0, 0.0, -2.0, 0.3, 1.0, 7.5, math.inf, -math.inf, math.nan]
    for x in values:
        for low, high in ((-1, 1), (0, 30), (-0.0, 0.0), (-math.pi / 4, math.pi / 4)):
            expected = float(np.clip(x, low, high))
            got = clip_scalar(x, low, high)
            assert (math.isnan(expected) and math.isnan(got)) or (
                expected == got and math.copysign(1, expected) == math.copysign(1, got)
            )
    rng = np.random.default_rng(0)
    for base in rng.uniform(0, 3, 200).tolist():
        for exponent in (2, 2.0, 0.5, -1.0, 3.5, 4.0, 4.4):
            assert power_scalar(base, exponent) == float(np.power(base, exponent))


def test_not_zero_matches_highway_env() -> None:
    """``not_zero_scalar`` returns highway-env's ``not_zero``, signed zeros and NaN included."""
    from highway_env import utils

    for x in [0.0, -0.0, 0.01, -0.01, 0.005, -0.005, 0.0100001, -3.0, 25.0, math.nan, math.inf]:
        assert np.array(not_zero_scalar(x)).tobytes() == np.array(utils.not_zero(x)).tobytes(), x


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


def test_box_separation_implies_no_collision() -> None:
    """Wherever the narrow-phase filter skips a pair, highway-env's polygon test is a no-op."""
    from aldm_gym.envs.traffic.collisions import boxes_separated, boxes_separated_py

    rng = np.random.default_rng(7)
    road = Road(network=RoadNetwork.straight_road_network(4, length=1e4))
    dt = 0.1
    skipped = kept = 0
    for _ in range(3000):
        base = rng.uniform(-5e3, 5e3, size=2)
        a = Vehicle(road, base, heading=rng.normal(0, 0.4), speed=rng.uniform(-5, 40))
        offset = rng.uniform([-12.0, -6.0], [12.0, 6.0])
        b = Vehicle(road, base + offset, heading=rng.normal(0, 0.4), speed=rng.uniform(-5, 40))
        boxes = []
        for v in (a, b):
            c, s = math.cos(v.heading), math.sin(v.heading)
            step = v.speed * dt
            boxes.append(
                (*v.position.tolist(), c, s, v.LENGTH / 2, v.WIDTH / 2, step * c, step * s)
            )
        separated = boxes_separated_py(*boxes[0], *boxes[1])
        assert boxes_separated(*boxes[0], *boxes[1]) is separated
        if separated:
            skipped += 1
            intersecting, will_intersect, _ = a._is_colliding(b, dt)
            assert not intersecting and not will_intersect
        else:
            kept += 1
    assert skipped > 500 and kept > 500


# -- aldm-gym roads (ReferenceLane) ----------------------------------------------------


def _aldm_env(vehicles: int = 25) -> Any:
    import aldm_gym  # noqa: F401  (registers ALDMHighway-v0)

    config = {"vehicles_count": vehicles, "simulation_frequency": 10, "policy_frequency": 1}
    return gym.make("ALDMHighway-v0", config={**config, "duration": 1e4})


def test_reference_edge_neighbours_match_base_every_step() -> None:
    """On an aldm-gym highway (one shared reference line), neighbours equal Road's."""
    assert _neighbours_checked_while_stepping(_aldm_env(), seed=5, steps=4) > 300


def test_project_many_kernel_matches_plain_python_and_project() -> None:
    """The batch projection equals its plain-Python reference and the scalar projection."""
    from aldm_gym.roads.highway import HighwayRoad
    from aldm_gym.roads.reference_line import _project_many, _project_many_py

    ref = HighwayRoad({"min_radius": 100.0, "max_radius": 400.0, "seed": 11}).reference
    rng = np.random.default_rng(3)
    s = rng.uniform(-60.0, ref.length + 60.0, 300)
    d = rng.uniform(-50.0, 50.0, 300)
    points = np.vstack([ref.position(s, d), [[1e5, -3e4], [0.0, -0.0]]])
    args = (ref.lookup, points)
    fast, plain = _project_many(*args), _project_many_py(*args)
    many = ref.project_many(points)
    scalar = np.array([ref.project(p) for p in points])
    for got in (plain, many):
        assert got[0].tobytes() == fast[0].tobytes() and got[1].tobytes() == fast[1].tobytes()
    assert scalar[:, 0].tobytes() == fast[0].tobytes()
    assert scalar[:, 1].tobytes() == fast[1].tobytes()
    # Memo hits return the same floats as a fresh projection.
    again = np.array([ref.project(p) for p in points])
    assert again.tobytes() == scalar.tobytes()


def test_remembered_projections_equal_fresh_ones() -> None:
    """Batch-memoised positions (FastRoad.step's lane look-up) project as a fresh call does."""
    from aldm_gym.roads.highway import HighwayRoad

    road = HighwayRoad({"min_radius": 100.0, "max_radius": 400.0, "seed": 2})
    ref = road.reference
    rng = np.random.default_rng(8)
    s = rng.uniform(-30.0, ref.length + 30.0, 200)
    d = rng.uniform(-12.0, 12.0, 200)
    points = np.vstack([ref.position(s, d), [[0.0, -0.0], [1e5, -3e4]]])
    fresh = [ref.project(p) for p in points]
    ref._point_memo.clear()
    road.network.prepare_closest_lanes(points)
    assert len(ref._point_memo) == len(points)
    for p, expected in zip(points, fresh, strict=True):
        got = ref.project(p.copy())
        assert np.array(got).tobytes() == np.array(expected).tobytes()
        assert road.network.get_closest_lane_index(p.copy()) == (
            RoadNetwork.get_closest_lane_index(road.network, p.copy())
        )


def test_deferred_lane_updates_match_immediate_ones() -> None:
    """FastRoad.step's batched closest-lane look-up leaves the lanes of per-vehicle updates."""
    env = _aldm_env(30)
    env.reset(seed=4)
    road = env.unwrapped.road
    for _ in range(3):
        env.step(1)
        for v in road.vehicles:
            lane_index = v.lane_index
            Vehicle.on_state_update(v)
            assert v.lane_index == lane_index


def test_scalar_pose_matches_interp() -> None:
    """The scalar pose (fast path of lane.heading_at / position) equals ``_interp``."""
    from aldm_gym.roads.highway import HighwayRoad

    road = HighwayRoad({"seed": 4})
    ref = road.reference
    rng = np.random.default_rng(0)
    s = np.concatenate([rng.uniform(-100, ref.length + 100, 500), [0.0, -0.0, ref.length]])
    position, heading = ref._interp(s)
    for si, p, h in zip(s.tolist(), position, heading, strict=True):
        assert ref.pose_at(si) == (float(p[0]), float(p[1]), float(h))
        assert road.lane(1).heading_at(si) == float(h)


def test_aldm_env_fast_paths_change_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """A seeded ALDMHighway-v0 rollout is bit-identical with every fast path switched off.

    Off: the projection memo and batch kernel, the shared-reference neighbour tables,
    the scalar lane heading, the collision narrow phase, the inlined path fit and the
    deferred (batch-projected) lane look-up after the vehicles move, the ego's
    numpy-free bicycle step.
    """
    from aldm_gym.envs.traffic import collisions, neighbours
    from aldm_gym.envs.traffic import road as road_module
    from aldm_gym.envs.vehicle import SensorVehicle
    from aldm_gym.roads import reference_line
    from aldm_gym.roads.lane import ReferenceLane

    actions = [1, 0, 1, 3, 2, 1, 4, 1, 1, 2, 1, 0]

    def rollout() -> list[Any]:
        env = _aldm_env(30)
        obs, _ = env.reset(seed=9)
        trace: list[Any] = [sorted((k, v.tobytes()) for k, v in obs.items())]
        for a in actions:
            obs, reward, terminated, truncated, info = env.step(a)
            info.pop("action")
            trace.append((sorted((k, v.tobytes()) for k, v in obs.items()), reward, repr(info)))
            trace.append(_state(env))
            if terminated or truncated:
                break
        return trace

    fast = rollout()

    def plain_project(self: Any, point: Any) -> tuple[float, float]:
        px, py = float(point[0]), float(point[1])
        return reference_line.project_on_py(self.lookup, px, py)

    def plain_project_many(self: Any, points: Any) -> tuple[Any, Any]:
        out = np.array([plain_project(self, p) for p in np.reshape(points, (-1, 2))])
        return out[:, 0].copy(), out[:, 1].copy()

    monkeypatch.setattr(reference_line.ReferenceLine, "project", plain_project)
    monkeypatch.setattr(reference_line.ReferenceLine, "project_many", plain_project_many)
    monkeypatch.setattr(
        neighbours.NeighbourCache, "_build_reference_edge", lambda self, index: False
    )
    monkeypatch.setattr(
        ReferenceLane, "heading_at", lambda self, s: float(self.reference.heading_at(s))
    )
    monkeypatch.setattr(collisions, "boxes_separated_py", lambda *boxes: False)
    monkeypatch.setattr(road_module, "STEPS_ENDING_WITH_UPDATE", frozenset())
    monkeypatch.setattr(SensorVehicle, "step", Vehicle.step)
    assert rollout() == fast
