"""The road: :class:`FastRoad`, a drop-in ``Road`` whose per-step cost is about linear.

highway-env's :class:`~highway_env.road.road.Road` projects every vehicle onto the
queried lane for every neighbour query, checks collisions for every pair of vehicles
and computes a norm per vehicle for every perception query. :class:`FastRoad` keeps
the exact answers and delegates the work:

- **Neighbours** -- :class:`~aldm_gym.envs.traffic.neighbours.NeighbourCache`.
- **Collisions** -- :func:`~aldm_gym.envs.traffic.collisions.resolve_collisions`.
- **Perception** -- ``close_objects_to`` filters by distance with one vectorised norm.
- **Lane look-up** -- a plain ``RoadNetwork`` is wrapped in a
  :class:`~aldm_gym.envs.traffic.network.FastRoadNetwork`.

The neighbour cache is invalidated at the two places positions can change in a
highway-env simulation step: at the start of :meth:`FastRoad.act` and after the
vehicles moved in :meth:`FastRoad.step`. It is also invalidated whenever a vehicle
steps on its own (``Vehicle.on_state_update`` reads ``road.record_history``, which is
a property here), and when ``vehicles``/``objects`` change membership. Code that
moves vehicles by assigning ``position`` directly must call :meth:`FastRoad.invalidate`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from highway_env.road.road import LaneIndex, Road, RoadNetwork
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import RoadObject

from aldm_gym.envs.traffic.collisions import resolve_collisions
from aldm_gym.envs.traffic.compiled import CompiledTraffic
from aldm_gym.envs.traffic.neighbours import NeighbourCache
from aldm_gym.envs.traffic.network import FastRoadNetwork
from aldm_gym.envs.traffic.scalar import PLAIN_DOT_MATCHES_NUMPY
from aldm_gym.envs.traffic.vehicles import STEPS_ENDING_WITH_UPDATE
from aldm_gym.types import FloatArray

__all__ = ["FastRoad"]


class FastRoad(Road):
    """A :class:`highway_env.road.road.Road` with O(n log n) neighbours and collisions.

    Results are those of the base class: same neighbours (including tie-breaking), same
    collision outcomes (pairs handled in the base loop's order), same
    ``close_objects_to`` lists. See the module docstring for how the per-step cache is
    kept valid.

    :param network: the road network; a plain ``RoadNetwork`` is wrapped in a
        :class:`FastRoadNetwork` sharing its graph.
    :param vehicles: the vehicles driving on the road.
    :param road_objects: obstacles and landmarks.
    :param np_random: random generator for vehicle behaviour.
    :param record_history: whether vehicles record their trajectories (display only).
    :param neighbour_vehicles_connected_lanes: also search connected lane segments.
    """

    def __init__(
        self,
        network: RoadNetwork | None = None,
        vehicles: list[RoadObject] | None = None,
        road_objects: list[RoadObject] | None = None,
        np_random: np.random.RandomState | np.random.Generator | None = None,
        record_history: bool = False,
        neighbour_vehicles_connected_lanes: bool = False,
    ) -> None:
        """Create a road; see the class docstring for the parameters."""
        if network is not None and type(network) is RoadNetwork:
            network = FastRoadNetwork.from_network(network)
        self._record_history = bool(record_history)
        self._neighbours = NeighbourCache(self)
        self._deferred_updates: list[Vehicle] | None = None
        self.engine: CompiledTraffic | None = None
        """The compiled traffic engine, if any (set by the owner; see :meth:`act`)."""
        super().__init__(
            network=network,
            vehicles=vehicles,
            road_objects=road_objects,
            np_random=np_random,
            record_history=record_history,
            neighbour_vehicles_connected_lanes=neighbour_vehicles_connected_lanes,
        )

    @classmethod
    def from_road(cls, road: Road) -> FastRoad:
        """Rewrap an existing road, keeping its network, vehicles, objects and settings.

        The ``vehicles`` and ``objects`` lists are shared (not copied) and every object
        whose ``road`` is the old road is re-pointed to the new one, so vehicles created
        before the swap query the fast road.

        :param road: a ``Road`` (or ``FastRoad``, returned unchanged).
        :return: the fast road.
        """
        if isinstance(road, FastRoad):
            return road
        fast = cls(
            network=road.network,
            np_random=road.np_random,
            record_history=road.record_history,
            neighbour_vehicles_connected_lanes=road.neighbour_vehicles_connected_lanes,
        )
        fast.vehicles = road.vehicles
        fast.objects = road.objects
        for obj in [*road.vehicles, *road.objects]:
            if getattr(obj, "road", None) is road:
                obj.road = fast
        return fast

    def release(self) -> None:
        """Forget every vehicle and object, and the neighbour tables built from them.

        Vehicles hold their road and the road holds them (in its lists and its
        neighbour cache): a road dropped without this call is freed only by Python's
        next full garbage collection, with all its vehicles (docs/reliability.md).
        """
        self.vehicles.clear()
        self.objects.clear()
        self._neighbours._reset()
        self._deferred_updates = None
        if self.engine is not None:
            self.engine.forget()  # it may hold the vehicle list between act and step

    @property
    def record_history(self) -> bool:
        """Whether vehicles record their trajectories (display only).

        ``Vehicle.on_state_update`` reads this flag right after a vehicle moved, so
        reading it also invalidates the neighbour cache: a vehicle stepped outside
        :meth:`step` (e.g. ``predict_trajectory`` on a deep copy) cannot leave it stale.
        """
        self._neighbours.valid = False
        return self._record_history

    @record_history.setter
    def record_history(self, value: bool) -> None:
        self._record_history = bool(value)

    def invalidate(self) -> None:
        """Drop the per-step neighbour cache and the compiled engine's gathered state
        (call after moving vehicles by hand)."""
        self._neighbours.valid = False
        if self.engine is not None:
            self.engine.forget()

    # -- Road API -------------------------------------------------------------------

    def neighbour_vehicles(
        self, vehicle: RoadObject, lane_index: LaneIndex | None = None
    ) -> tuple[RoadObject | None, RoadObject | None]:
        """Preceding and following objects of ``vehicle`` on a lane (base-class result).

        :param vehicle: the vehicle whose neighbours must be found.
        :param lane_index: the lane to search (default: the vehicle's lane); the vehicle
            is projected onto it.
        :return: ``(front, rear)``, either of which may be None.
        """
        lane_index = lane_index or vehicle.lane_index
        if not lane_index:
            return None, None
        return self._neighbours.neighbours(vehicle, lane_index)

    def close_objects_to(
        self,
        vehicle: RoadObject,
        distance: float,
        count: int | None = None,
        see_behind: bool = True,
        sort: bool = True,
        vehicles_only: bool = False,
    ) -> list[RoadObject]:
        """Objects within ``distance`` [m] of ``vehicle`` (base-class result and order).

        The Euclidean pre-filter is one vectorised norm; the lane-distance conditions
        and sorting then run on the few remaining objects exactly as in the base class.

        :param vehicle: the reference vehicle.
        :param distance: the search radius [m].
        :param count: keep at most this many objects (after sorting).
        :param see_behind: include vehicles behind the reference vehicle.
        :param sort: sort by absolute lane distance.
        :param vehicles_only: skip road objects.
        :return: the selected objects.
        """
        origin = np.asarray(vehicle.position, dtype=np.float64)

        def near(population: list[RoadObject]) -> list[RoadObject]:
            if not population:
                return []
            positions = np.array([o.position for o in population], dtype=np.float64)
            delta = positions.reshape(-1, 2) - origin
            # np.linalg.norm of a length-2 vector is sqrt(x*x + y*y) where the BLAS dot
            # is not fused; where it is, the two differ by rounding only, so the few
            # distances that close to the radius are taken from np.linalg.norm itself.
            dist = np.sqrt(delta[:, 0] * delta[:, 0] + delta[:, 1] * delta[:, 1])
            if not PLAIN_DOT_MATCHES_NUMPY:
                close = np.flatnonzero(np.abs(dist - distance) <= 1e-9 * (1.0 + distance))
                for i in close.tolist():
                    dist[i] = np.linalg.norm(delta[i])
            return [population[i] for i in np.flatnonzero(dist < distance).tolist()]

        vehicles = [
            v
            for v in near(self.vehicles)
            if v is not vehicle
            and (see_behind or -2 * vehicle.LENGTH < vehicle.lane_distance_to(v))
        ]
        obstacles = [
            o for o in near(self.objects) if -2 * vehicle.LENGTH < vehicle.lane_distance_to(o)
        ]
        objects_ = vehicles if vehicles_only else vehicles + obstacles
        if sort:
            objects_ = sorted(objects_, key=lambda o: abs(vehicle.lane_distance_to(o)))
        if count:
            objects_ = objects_[:count]
        return objects_

    def act(self) -> None:
        """Decide the actions of every vehicle (positions are fixed from here to ``step``).

        With an :attr:`engine`, it decides the compiled vehicles' actions in one call
        (same results) whenever it can, else every vehicle acts here in Python.
        """
        self._neighbours.valid = False  # (the engine keeps its own state: see holding())
        engine = self.engine
        if engine is not None and engine.act(self):
            return
        for vehicle in self.vehicles:
            vehicle.act()

    def step(self, dt: float) -> None:
        """Move every vehicle by ``dt`` [s], then resolve collisions (base-class result).

        Vehicles whose ``step`` ends with ``on_state_update`` (see
        :class:`~aldm_gym.envs.traffic.vehicles.BatchedLaneUpdate`) have their
        closest-lane look-up deferred until all have moved: the look-up depends only on
        the vehicle's own pose, so the order does not matter, and the network may then
        prepare every position in one batch (``prepare_closest_lanes``, e.g. one
        compiled projection of all vehicles; ``prepare_closest_lane_poses`` with the
        headings too, for a network whose look-up weighs them).

        With an :attr:`engine`, it moves the compiled vehicles (and sets their lanes) in
        one call whenever it can; the vehicles before them move here.

        :param dt: timestep [s].
        """
        engine = self.engine
        first = engine.step(self, dt) if engine is not None else None
        movers = self.vehicles if first is None else self.vehicles[:first]
        deferred: list[Vehicle] = []
        try:
            for vehicle in movers:
                self._deferred_updates = (
                    deferred if type(vehicle).step in STEPS_ENDING_WITH_UPDATE else None
                )
                vehicle.step(dt)
        finally:
            self._deferred_updates = None
        if len(deferred) > 1:  # a single look-up gains nothing from a batch
            prepare_poses: Callable[[FloatArray, FloatArray], None] | None = getattr(
                self.network, "prepare_closest_lane_poses", None
            )
            prepare: Callable[[FloatArray], None] | None = getattr(
                self.network, "prepare_closest_lanes", None
            )
            if prepare_poses is not None:
                # A network whose look-up weighs the heading (a map's) needs the poses.
                prepare_poses(
                    np.array([v.position for v in deferred], dtype=np.float64).reshape(-1, 2),
                    np.array([v.heading for v in deferred], dtype=np.float64),
                )
            elif prepare is not None:
                # Built like NeighbourCache's position array: when every object is a
                # deferred vehicle (a highway), the next act's batch projection is a memo hit.
                prepare(np.array([v.position for v in deferred], dtype=np.float64).reshape(-1, 2))
        for vehicle in deferred:
            # The vehicle's own on_state_update (its class may extend the end of a
            # step, e.g. MapIDMVehicle); outside the deferral it runs Vehicle's.
            vehicle.on_state_update()
        self._neighbours.valid = False
        if first is None:
            resolve_collisions(self.vehicles, self.objects, dt)
        else:
            assert engine is not None
            engine.collide(self, dt, first)
