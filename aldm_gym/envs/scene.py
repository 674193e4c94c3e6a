"""Scene building of ``ALDMHighway-v0``: the road, the traffic's road and the vehicles.

One builder per road source, chosen by the settings (``road.xodr`` set or not), each
answering the same three questions (:class:`Scene`): the :class:`~aldm_gym.roads.Road`
the ego drives on, the highway-env road (:class:`~aldm_gym.envs.traffic.FastRoad`) over
its lanes, and the vehicles on it, the ego first and the traffic after it.

- :class:`GeneratedScene`: a seeded generated highway (cached across resets), traffic
  placed as in ``highway-v0``, run by the compiled engine (``traffic.engine``).
- :class:`MapScene`: an OpenDRIVE map; the ego starts on a seeded lane and position
  with enough lane chain ahead, traffic ahead of it along the chain (IDM/MOBIL with a
  mandatory merge out of ending lanes).
- :class:`ScenarioScene`: an OpenSCENARIO file on its map; its objects, placed and
  moved by its storyboard (:mod:`aldm_gym.scenario`).

The random draws keep their order (the road's seed, then the vehicles'), so a seed
gives the same scene bit for bit.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from highway_env import utils
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.envs.config import EnvConfig
from aldm_gym.envs.traffic import FastRoad
from aldm_gym.envs.traffic.compiled import CompiledTraffic
from aldm_gym.envs.traffic.mix import Spawner, make_truck
from aldm_gym.envs.vehicle import MapIDMVehicle, SensorVehicle
from aldm_gym.errors import ConfigError
from aldm_gym.roads.cache import cached_road
from aldm_gym.roads.highway import HighwayRoad
from aldm_gym.roads.map_road import OpenDriveRoad
from aldm_gym.roads.opendrive.map import LaneKey
from aldm_gym.roads.protocol import Road
from aldm_gym.types import FloatArray

__all__ = [
    "MAP_MIN_AHEAD",
    "MAP_START_WIDTH",
    "MAP_TRAFFIC_ROOM",
    "ROAD_END_MARGIN",
    "GeneratedScene",
    "MapScene",
    "ScenarioScene",
    "Scene",
    "make_scene",
]

ROAD_END_MARGIN = 250.0
"""The episode is truncated when the ego is this close to the end of the road [m]."""

MAP_MIN_AHEAD = 500.0
"""On a map the ego starts with at least ``max(this, initial_speed · duration)`` of its
lane chain ahead, plus :data:`ROAD_END_MARGIN` [m]."""

MAP_TRAFFIC_ROOM = 200.0
"""Traffic is not placed on a lane whose chain ends within this distance [m]."""

MAP_START_WIDTH = 2.5
"""On a map the ego starts where its lane is at least this wide [m] (the ALDM's
default ``min_lane_width``): not on the tip of a lane that opens from nothing."""

MakeEgo = Callable[[FastRoad, Any, float, float], SensorVehicle]
"""``make_ego(traffic_road, position [m], heading [rad], speed [m/s])``: the ego."""


class Scene:
    """A scene builder: the road, the traffic's road and the vehicles of an episode
    (:meth:`road`, :meth:`traffic_road`, :meth:`place_vehicles`, in that order)."""

    def __init__(self, settings: EnvConfig) -> None:
        """Hold the settings the scene is built from."""
        self.settings = settings

    def road(self, rng: np.random.Generator) -> Road:
        """The road of the next episode (draws from ``rng`` only where the road does)."""
        raise NotImplementedError

    def traffic_road(self, road: Road, rng: np.random.Generator) -> FastRoad:
        """highway-env's road over ``road``'s lane network, for the vehicles."""
        s = self.settings
        return FastRoad(
            network=road.network,
            np_random=rng,
            record_history=s.show_trajectories,
            # On a map the env sets it: its lanes end at every lane section.
            neighbour_vehicles_connected_lanes=s.neighbour_vehicles_connected_lanes,
        )

    def place_vehicles(
        self, road: Road, traffic: FastRoad, rng: np.random.Generator, make_ego: MakeEgo
    ) -> SensorVehicle:
        """Add the ego, then the traffic, to ``traffic.vehicles``; return the ego."""
        raise NotImplementedError


class GeneratedScene(Scene):
    """A generated highway (``road`` settings without ``xodr``)."""

    def road(self, rng: np.random.Generator) -> HighwayRoad:
        """The seeded highway of :meth:`EnvConfig.road_config` (a ``None`` seed drawn from
        ``rng`` at every episode), built once per process for each config."""
        seed = int(rng.integers(0, 2**31 - 1)) if self.settings.road.seed is None else 0
        return cached_road(self.settings.road_config(seed))

    def traffic_road(self, road: Road, rng: np.random.Generator) -> FastRoad:
        """highway-env's road; its traffic runs in the compiled engine unless
        ``traffic.engine = "python"``."""
        traffic = super().traffic_road(road, rng)
        if self.settings.traffic.engine == "compiled":
            traffic.engine = CompiledTraffic(road)  # this scene's generated highway
        return traffic

    def place_vehicles(
        self, road: Road, traffic: FastRoad, rng: np.random.Generator, make_ego: MakeEgo
    ) -> SensorVehicle:
        """Ego then ``vehicles_count`` IDM vehicles ahead of it, as in ``highway-v0``."""
        s = self.settings
        other_type = utils.class_from_path(s.other_vehicles_type)
        seed_vehicle = Vehicle.create_random(
            traffic,
            speed=float(s.initial_speed),
            lane_id=s.initial_lane_id,
            spacing=float(s.ego_spacing),
        )
        ego = make_ego(traffic, seed_vehicle.position, seed_vehicle.heading, seed_vehicle.speed)
        traffic.vehicles.append(ego)
        spawner = Spawner(s.traffic, rng)
        for _ in range(int(s.vehicles_count)):
            v = other_type.create_random(traffic, spacing=1.0 / float(s.vehicles_density))
            v.randomize_behavior()
            spawner.place(v, spawner.draw())
            traffic.vehicles.append(v)
        return ego


class MapScene(Scene):
    """An OpenDRIVE map (``road.xodr``), read when the env is configured.

    :param settings: the env's settings.
    :param road: the map, as :func:`~aldm_gym.envs.config.load_map` read it.
    """

    def __init__(self, settings: EnvConfig, road: OpenDriveRoad) -> None:
        """Hold the settings and the map."""
        super().__init__(settings)
        self.map = road

    def road(self, rng: np.random.Generator) -> OpenDriveRoad:
        """The map (the same every episode)."""
        return self.map

    def traffic_class(self) -> type:
        """The class of the map's traffic: ``other_vehicles_type``, where the default
        is :class:`~aldm_gym.envs.vehicle.MapIDMVehicle` (with the mandatory merge)."""
        s = self.settings
        other_type = utils.class_from_path(s.other_vehicles_type)
        if other_type.__name__ == "FastIDMVehicle" and s.other_vehicles_type == (
            EnvConfig.other_vehicles_type
        ):
            return MapIDMVehicle
        return other_type

    def place_vehicles(
        self, road: Road, traffic: FastRoad, rng: np.random.Generator, make_ego: MakeEgo
    ) -> SensorVehicle:
        """Ego on a seeded lane and position of the map, then IDM/MOBIL traffic ahead.

        The ego starts on a driving lane (of index ``initial_lane_id`` from the left, if
        set) at a position drawn uniformly among those with at least
        ``max(MAP_MIN_AHEAD, initial_speed · duration) + ROAD_END_MARGIN`` of lane chain
        ahead, where the lane is at least :data:`MAP_START_WIDTH` wide (on a short map,
        with a warning, the longest chain from where it is first that wide). Traffic is placed
        ahead of it along its lane chain, highway-env's way (gaps shrinking with the
        lane count and ``vehicles_density``), each vehicle on a random lane of the
        ego's direction there, never on a lane that ends within ``MAP_TRAFFIC_ROOM``,
        and on a ring (a chain that comes back to the ego's lane) no farther round
        than one spacing short of the ego.

        :raises ConfigError: ``initial_lane_id`` names no driving lane of the map.
        """
        s = self.settings
        road = self.map
        net = road.network
        speed = float(s.initial_speed)
        need = max(MAP_MIN_AHEAD, speed * float(s.duration)) + ROAD_END_MARGIN
        lanes = list(road.lanes)
        if s.initial_lane_id is not None:
            lanes = [k for k in lanes if road.siblings(k).index(k) == s.initial_lane_id]
            if not lanes:
                raise ConfigError(
                    f"config.initial_lane_id {s.initial_lane_id} : the map "
                    f"{road.map.path!r} has no driving lane with that index from the left"
                )
        i, u = _draw_start(road, lanes, need, rng)
        key = lanes[i]
        lane = net.get_lane(net.index_of[key])
        ego = make_ego(traffic, lane.position(u, 0.0), lane.heading_at(u), speed)
        traffic.vehicles.append(ego)
        other_type = self.traffic_class()
        spacing = 1.0 / float(s.vehicles_density)
        spawner = Spawner(s.traffic, rng)
        ring = _ring(road, key)
        cur, cur_u, ahead = key, u, 0.0
        for _ in range(int(s.vehicles_count)):
            siblings = road.siblings(cur)
            v_speed = float(rng.uniform(0.7 * lane.speed_limit, 0.8 * lane.speed_limit))
            offset = spacing * (12.0 + v_speed) * math.exp(-5.0 / 40.0 * len(siblings))
            step = offset * float(rng.uniform(0.9, 1.1))
            truck = spawner.draw()
            step += spawner.extra_shift(truck)
            cur_u += step
            ahead += step
            if ring is not None and u + ahead > max(u, ring[0]) + ring[1] - offset:
                # round a ring once: the next vehicle would come up behind the ego or
                # behind the first vehicle placed on the ring
                break
            while cur is not None and cur_u > road.lane_length(cur):
                cur_u -= road.lane_length(cur)
                cur = road.successor(cur)
            if cur is None:
                break  # the ego's lane chain ends: no more room ahead
            siblings = road.siblings(cur)
            target = siblings[int(rng.integers(len(siblings)))]
            point = net.get_lane(net.index_of[cur]).position(cur_u, 0.0)
            other = net.get_lane(net.index_of[target])
            s_other, _ = other.local_coordinates(point)
            left = road.chain_end(target) - road.chain_start(target) - s_other
            if not (0.0 <= s_other <= other.length) or left < MAP_TRAFFIC_ROOM:
                continue
            v = other_type(
                traffic, other.position(s_other, 0.0), other.heading_at(s_other), v_speed
            )
            v.randomize_behavior()
            if truck is not None:
                make_truck(v, truck, spawner.config)
            traffic.vehicles.append(v)
        return ego


def _draw_start(
    road: OpenDriveRoad, lanes: list[LaneKey], need: float, rng: np.random.Generator
) -> tuple[int, float]:
    """The ego's start: the index in ``lanes`` and the arc length [m] along that lane,
    drawn uniformly among the positions with ``need`` [m] of lane chain ahead where
    the lane is at least :data:`MAP_START_WIDTH` wide. Where no lane is that wide with
    that much ahead, uniformly among the positions with ``need`` ahead (with a
    warning); on a map too short for ``need``, where the lane with the longest chain
    ahead is first that wide (with a warning)."""
    path = road.map.path
    room = [min(road.lane_length(k), road.chain_end(k) - road.chain_start(k) - need) for k in lanes]
    spans = [_wide_spans(road, k, MAP_START_WIDTH, r) for k, r in zip(lanes, room, strict=True)]
    weights = np.array([float(np.sum(sp[:, 1] - sp[:, 0])) for sp in spans])
    if weights.sum() > 0.0:
        i = _draw_index(weights, rng)
        # uniform over the lane's wide spans
        sp = spans[i]
        v = float(rng.uniform(0.0, weights[i]))
        ends = np.cumsum(sp[:, 1] - sp[:, 0])
        j = min(int(np.searchsorted(ends, v, side="right")), len(sp) - 1)
        return i, float(min(sp[j, 0] + v - (ends[j] - (sp[j, 1] - sp[j, 0])), sp[j, 1]))
    if max(room) > 0.0:
        warnings.warn(
            f"{path}: no driving lane is {MAP_START_WIDTH} m wide where it has {need:.0f} m "
            "ahead; the ego starts on a narrower one",
            stacklevel=3,
        )
        weights = np.maximum(np.array(room), 0.0)
        i = _draw_index(weights, rng)
        return i, float(rng.uniform(0.0, weights[i]))
    first = [_first_wide(road, k, MAP_START_WIDTH) for k in lanes]
    chains = [road.chain_end(k) - road.chain_start(k) for k in lanes]
    ahead = np.array([c - u for c, (u, _) in zip(chains, first, strict=True)])
    wide = np.array([found for _, found in first])
    i = int(np.argmax(np.where(wide, ahead, -np.inf) if wide.any() else ahead))
    warnings.warn(
        f"{path}: no driving lane has {need:.0f} m ahead; the ego starts with the longest "
        f"({ahead[i]:.0f} m) and the episode may end early",
        stacklevel=3,
    )
    return i, first[i][0]


def _draw_index(weights: FloatArray, rng: np.random.Generator) -> int:
    """An index drawn with probability proportional to ``weights``."""
    cum = np.cumsum(weights)
    return min(int(np.searchsorted(cum, rng.uniform(0.0, cum[-1]), side="right")), len(cum) - 1)


def _wide_spans(road: OpenDriveRoad, key: LaneKey, width: float, room: float) -> FloatArray:
    """``(n, 2)`` the stretches ``[u0, u1]`` [m] of lane ``key`` within ``[0, room]``
    where it is at least ``width`` [m] wide (between vertices that both are)."""
    if room <= 0.0:
        return np.zeros((0, 2))
    u, w = road.lane_arc_lengths(key), road.lane_widths(key)
    wide = (w >= width).astype(np.int8)
    # runs of vertices that are all wide enough: one span each, cut at room
    edges = np.diff(np.concatenate(([0], wide, [0])))
    first, last = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    spans = np.stack((u[first], np.minimum(u[last], room)), axis=1)
    return spans[spans[:, 1] > spans[:, 0]]


def _first_wide(road: OpenDriveRoad, key: LaneKey, width: float) -> tuple[float, bool]:
    """The arc length [m] along lane ``key`` where it is first at least ``width`` [m]
    wide, and whether it ever is: 0 if it starts so wide, else the middle of the first
    stretch between two vertices that both are (not its first vertex: a position
    exactly on a vertex may take the width of the narrower stretch before it); its
    widest vertex, and False, when no such stretch exists."""
    u, w = road.lane_arc_lengths(key), road.lane_widths(key)
    wide = np.flatnonzero((w[:-1] >= width) & (w[1:] >= width))
    if not len(wide):
        return float(u[int(np.argmax(w))]), False
    i = int(wide[0])
    return (0.0 if i == 0 else float(0.5 * (u[i] + u[i + 1]))), True


def _ring(road: OpenDriveRoad, key: LaneKey) -> tuple[float, float] | None:
    """Where the chain of successors of lane ``key`` runs into a ring of lanes (a
    road that is its own successor, a test track): ``(entry, lap)``, the arc length
    [m] along the chain from the start of ``key`` to the ring's first lane (0 when
    ``key`` is on it) and the ring's length [m]; None when the chain ends."""
    total, cur = 0.0, key
    at: dict[LaneKey, float] = {}
    while cur is not None and cur not in at:
        at[cur] = total
        total += road.lane_length(cur)
        cur = road.successor(cur)
    if cur is None:
        return None
    return at[cur], total - at[cur]


class ScenarioScene(MapScene):
    """An OpenSCENARIO file (``scenario.xosc``) on its map: the scenario's objects are
    the vehicles, placed by its ``Init`` and moved by its storyboard
    (:class:`~aldm_gym.scenario.ScenarioRunner`, :attr:`runner` per episode).

    :param settings: the env's settings.
    :param road: the scenario's map.
    :param scenario: the scenario (:func:`~aldm_gym.scenario.read_scenario`).
    """

    def __init__(self, settings: EnvConfig, road: OpenDriveRoad, scenario: Any) -> None:
        """Hold the scenario (read once per configure, with the settings' parameters)."""
        from aldm_gym.scenario import choose_ego

        super().__init__(settings, road)
        self.scenario = scenario
        self.ego_name = choose_ego(self.scenario, settings.scenario.ego)
        self.runner: Any = None

    def place_vehicles(
        self, road: Road, traffic: FastRoad, rng: np.random.Generator, make_ego: MakeEgo
    ) -> SensorVehicle:
        """A fresh run of the scenario: its entities' vehicles, ``Init`` at time 0."""
        from aldm_gym.scenario import ScenarioRunner

        self.runner = ScenarioRunner(self.scenario, self.map, self.ego_name)
        dt = 1.0 / float(self.settings.simulation_frequency)
        ego = self.runner.populate(
            traffic, make_ego, dt, rng=rng, traffic_vehicle=self.traffic_class()
        )
        if self.settings.scenario.handover == "init" and not self.runner.active:
            self.runner.control(True, True)  # the function drives from the start
        return ego


def make_scene(settings: EnvConfig, map_road: OpenDriveRoad | None, scenario: Any = None) -> Scene:
    """The scene builder of ``settings``: a :class:`ScenarioScene` with ``scenario``, a
    :class:`MapScene` with the map read for ``road.xodr``, else a
    :class:`GeneratedScene`."""
    if map_road is not None and scenario is not None:
        return ScenarioScene(settings, map_road, scenario)
    if map_road is not None:
        return MapScene(settings, map_road)
    return GeneratedScene(settings)
