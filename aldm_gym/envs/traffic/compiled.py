"""The compiled traffic engine: IDM/MOBIL of a generated highway in three numba calls per step.

After :class:`~aldm_gym.envs.traffic.road.FastRoad` and
:class:`~aldm_gym.envs.traffic.vehicles.FastIDMVehicle`, the traffic was still about
60 % of an env step, spent in Python-level calls: every vehicle's MOBIL asks for
neighbours and IDM accelerations several times per simulation step. On a road whose
lanes all follow one reference line (a :class:`~aldm_gym.roads.highway.HighwayRoad`),
:class:`CompiledTraffic` gathers the vehicles' state into arrays, decides every
``FastIDMVehicle``'s action in one compiled call
(:func:`~aldm_gym.envs.traffic.kernels.traffic_act`), moves them and finds their lanes
in another (:func:`~aldm_gym.envs.traffic.kernels.traffic_step`), finds the pairs that
may collide in a third (:func:`~aldm_gym.envs.traffic.kernels.collision_pairs`; highway-env's
``handle_collisions`` then runs on those pairs), and writes the results back to the
vehicle objects, so everything else (the ego, the sensor, observations,
collisions, rendering) sees highway-env's vehicles as before.

The kernels repeat highway-env's operations in the same order with libm's elementary
functions, so the episode is the same bit for bit as with the Python path
(``traffic.engine = "python"``) wherever numpy's scalar math agrees with libm
(:data:`~aldm_gym.envs.traffic.scalar.LIBM_MATCHES_NUMPY`), and the same bit for bit
as the Python path computed with libm's functions on every CPU; where numpy differs by
last bits the two engines agree to rounding over short horizons and statistically
(docs/env.md, "The traffic engine"; ``tests/envs/traffic/test_compiled.py`` checks all
three). A step runs on the Python path whenever the engine cannot run it, decided per
simulation step (the reason is counted in :attr:`CompiledTraffic.steps`, and a whole
env step on the Python path is warned about once per reason):

- the network must be the road's own one-edge network, with no road objects, no
  trajectory recording and no search across connected lanes;
- the compiled vehicles are those of class ``FastIDMVehicle`` exactly (no planned
  route, an IDM exponent numpy does not special-case); every other vehicle (the ego)
  acts and moves in Python and must come before them in ``road.vehicles`` (vehicles
  act in list order and MOBIL reads the target lanes of those that acted before);
- every vehicle has highway-env's kinematics and lane distance, a lane of this network
  and a finite position.

Reading the vehicles into arrays is the engine's main Python cost. Within
:meth:`CompiledTraffic.holding` (the simulation steps of one env step, which nothing but
the simulation touches) the arrays are kept from one step to the next: they mirror the
compiled vehicles exactly (the kernels' results are written back as they are, and the
impacts and crash flags set by collisions are read back), so only the vehicles before
the compiled ones (the ego) are read again. Every block, and every step outside one,
starts by reading everything: behaviour constants (``DELTA``, ``TIME_WANTED``,
``LENGTH``, ...), speeds and poses a script changed between env steps take effect as on
the Python path. Code that changes vehicles *during* a block (between ``road.act`` and
``road.step`` of one simulation step, or in a render hook) must call
:meth:`FastRoad.invalidate <aldm_gym.envs.traffic.road.FastRoad.invalidate>`.
"""

from __future__ import annotations

import warnings
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from itertools import repeat
from operator import attrgetter, is_, is_not, itemgetter
from typing import Any

import numpy as np
from highway_env.road.road import Road
from highway_env.vehicle.controller import ControlledVehicle
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import RoadObject

from aldm_gym.envs.traffic import kernels as K
from aldm_gym.envs.traffic.collisions import resolve_collisions, uses_base_box
from aldm_gym.envs.traffic.scalar import NUMPY_POWER_SPECIAL
from aldm_gym.envs.traffic.vehicles import (
    STEPS_ENDING_WITH_UPDATE,
    BatchedLaneUpdate,
    FastControlledVehicle,
    FastIDMVehicle,
    uses_base_kinematics,
)
from aldm_gym.roads.reference_line import COORD_LIMIT

__all__ = ["COMPILED", "ENGINES", "CompiledTraffic"]

ENGINES = ("compiled", "python")
"""Values of the env's ``traffic.engine`` setting."""

COMPILED = "compiled"
"""The key of :attr:`CompiledTraffic.steps` counting the steps the kernels decided."""

_OFF_LANES = (
    "a vehicle is off the highway's lanes, its position is not a float64 pair or its "
    "IDM constants make the desired gap's square root fail"
)
_NOT_FINITE = "a vehicle's position is not finite"

_WARNED: set[str] = set()
"""Reasons already warned about in this process (:meth:`CompiledTraffic.holding`)."""

_BASE_LANE_DISTANCE = (RoadObject.lane_distance_to, FastControlledVehicle.lane_distance_to)

_POSITION = attrgetter("position")
_HEADING = attrgetter("heading")
_SPEED = attrgetter("speed")
_LENGTH = attrgetter("LENGTH")
_WIDTH = attrgetter("WIDTH")
_DIAGONAL = attrgetter("diagonal")
_LANE = attrgetter("lane")
_LANE_INDEX = attrgetter("lane_index")
_TARGET_INDEX = attrgetter("target_lane_index")
_TARGET_SPEED = attrgetter("target_speed")
_CRASHED = attrgetter("crashed")
_COLLIDABLE = attrgetter("collidable")
_CHECKS = attrgetter("check_collisions")
_ACTION = attrgetter("action")
_TIMER = attrgetter("timer")
_LANE_CHANGE = attrgetter("enable_lane_change")
_ROUTE = attrgetter("route")
_DELTA = attrgetter("DELTA")
_IMPACT = attrgetter("impact")
_DTYPE = attrgetter("dtype")
_FLOAT64 = {np.dtype(np.float64)}
_STEERING = itemgetter("steering")
_ACCELERATION = itemgetter("acceleration")


_PARAMS = attrgetter(
    "COMFORT_ACC_MAX",
    "COMFORT_ACC_MIN",
    "DISTANCE_WANTED",
    "TIME_WANTED",
    "DELTA",
    "POLITENESS",
    "LANE_CHANGE_MIN_ACC_GAIN",
    "LANE_CHANGE_MAX_BRAKING_IMPOSED",
    "LANE_CHANGE_DELAY",
    "ACC_MAX",
    "MAX_STEERING_ANGLE",
    "KP_LATERAL",
    "KP_HEADING",
    "TAU_PURSUIT",
    "MAX_SPEED",
    "MIN_SPEED",
)
"""Per compiled vehicle: the constants of the ``P_*`` columns, in order."""


_CLASS_OK: dict[frozenset[type], tuple[bool, bool]] = {}
"""Per set of vehicle classes on the road: :func:`_classes_ok`'s answer."""


def _classes_ok(kinds: frozenset[type]) -> tuple[bool, bool]:
    """Whether vehicles of these classes can share a compiled step (highway-env's
    kinematics, lane distance, vehicle base and bicycle step), and whether they all
    collide as highway-env's plain boxes."""
    ok = all(
        issubclass(cls, Vehicle)
        and uses_base_kinematics(cls)
        and cls.lane_distance_to in _BASE_LANE_DISTANCE
        # Moves that read only the vehicle itself: the compiled vehicles may then move
        # before the Python ones ahead of them in the list.
        and cls.step in STEPS_ENDING_WITH_UPDATE
        and cls.on_state_update in (Vehicle.on_state_update, BatchedLaneUpdate.on_state_update)
        for cls in kinds
    )
    return ok, all(uses_base_box(cls) for cls in kinds)


@cache
def _is_controlled(cls: type) -> bool:
    """Whether ``cls`` is a highway-env ``ControlledVehicle`` (it has a target lane)."""
    return issubclass(cls, ControlledVehicle)


class CompiledTraffic:
    """Runs the ``FastIDMVehicle`` traffic of one generated highway in compiled kernels.

    Attach it to a :class:`~aldm_gym.envs.traffic.road.FastRoad` (``road.engine``);
    ``FastRoad.act`` and ``FastRoad.step`` call :meth:`act` and :meth:`step`, which return
    False (doing nothing) when the step must run on the Python path (module docstring).

    :param highway: the generated road (a :class:`~aldm_gym.roads.highway.HighwayRoad`)
        whose ``network`` the traffic drives on.
    """

    def __init__(self, highway: Any) -> None:
        """Tabulate the road; see the class docstring."""
        from aldm_gym.roads.highway import EDGE

        ref = highway.reference
        self.network = highway.network
        self.edge: tuple[str, str] = EDGE
        lanes = list(self.network.graph[EDGE[0]][EDGE[1]])
        self.lanes = lanes
        self.lane_indices = [(EDGE[0], EDGE[1], i) for i in range(len(lanes))]
        self.lanes_count = int(highway.lanes_count)
        self.lane_width = float(highway.lane_width)
        self.lane_of_index = {index: i for i, index in enumerate(self.lane_indices)}
        self._lane_key: tuple[Any, ...] = ()
        self.s_tab = np.ascontiguousarray(ref.s, dtype=np.float64)
        self.line = ref.lookup
        self._tabulate_lanes()  # the lane arrays and the kernels' argument tuples
        self._memo = np.full((0, 4), np.nan)
        """``(x, y, s, d)`` [m] of the rows :func:`~aldm_gym.envs.traffic.kernels.traffic_step`
        projected last (see :func:`~aldm_gym.envs.traffic.kernels.traffic_act`)."""
        self._f: np.ndarray | None = None
        self._k: np.ndarray | None = None
        self._p: np.ndarray | None = None
        self._acted: tuple[list[Any], int] | None = None
        self._current: list[Any] | None = None
        self._held = False
        self._first = 0
        self._params: tuple[int, list[tuple[float, ...]]] | None = None
        self._boxes = False
        self.declined: str | None = None
        """Why the last declined step ran on the Python path."""
        self.steps: Counter[str] = Counter()
        """Simulation steps decided so far: ``steps[COMPILED]`` by the kernels, and per
        reason (a sentence) those that ran on the Python path."""

    def _tabulate_lanes(self) -> bool:
        """(Re)build the lane arrays when a lane's geometry, speed limit or
        ``forbidden`` flag changed (highway-env reads them at every use); True if
        they changed."""
        key = tuple(
            (
                lane.offset,
                lane.width,
                lane.length,
                bool(lane.forbidden),
                lane.speed_limit,
                lane.VEHICLE_LENGTH,
            )
            for lane in self.lanes
        )
        if key == self._lane_key:
            return False
        self._lane_key = key
        lanes = self.lanes
        self.lane_offset = np.array([lane.offset for lane in lanes], dtype=np.float64)
        self.lane_width_of = np.array([lane.width for lane in lanes], dtype=np.float64)
        self.lane_length = np.array([lane.length for lane in lanes], dtype=np.float64)
        self.lane_forbidden = np.array([bool(lane.forbidden) for lane in lanes], dtype=np.int64)
        self.lane_speed_limit = [
            np.nan if lane.speed_limit is None else float(lane.speed_limit) for lane in lanes
        ]
        self.lane_speed_limit_of = {
            id(lane): limit for lane, limit in zip(lanes, self.lane_speed_limit, strict=True)
        }
        self.lane_vehicle_length = float(lanes[0].VEHICLE_LENGTH) if lanes else 5.0
        self._build_tables()
        return True

    def _build_tables(self) -> None:
        """The kernels' argument tuples (lane arrays and the reference line)."""
        self.act_tables = (
            self.lane_offset,
            self.lane_width_of,
            self.lane_length,
            self.lane_forbidden,
            self.lane_vehicle_length,
            self.s_tab,
            self.line,
            COORD_LIMIT,
        )
        """The arguments of :func:`~aldm_gym.envs.traffic.kernels.traffic_act` after
        the state arrays ``f, k, p`` and the projection memo."""
        self.step_tables = (self.lanes_count, self.lane_width, self.line, COORD_LIMIT)
        """The arguments of :func:`~aldm_gym.envs.traffic.kernels.traffic_step` after
        ``f, k, p``, the projection memo and ``dt``."""

    # ----------------------------------------------------------------- eligibility
    def _road_ok(self, road: Road) -> str | None:
        """The road-level conditions of the module docstring: None when they hold, else
        the reason the step runs on the Python path."""
        graph = road.network.graph
        if road.network is not self.network:
            return "the road's network is not the generated highway's"
        if road.objects:
            return "road objects (obstacles, landmarks) are on the road"
        if getattr(road, "_record_history", True):
            return "the road records trajectories (record_history)"
        if road.neighbour_vehicles_connected_lanes:
            return "neighbours are searched across connected lanes"
        if not (
            len(graph) == 1
            and len(graph.get(self.edge[0], {})) == 1
            and len(graph[self.edge[0]].get(self.edge[1], ())) == len(self.lanes)
            and all(map(is_, graph[self.edge[0]][self.edge[1]], self.lanes))
        ):
            return "the network has lanes other than the generated highway's"
        return None

    def _split(self, road: Road) -> int | None:
        """Index of the first compiled vehicle in ``road.vehicles`` (every later one is
        compiled, every earlier one is not), or None if this step must run in Python
        (the reason is left in :attr:`declined`)."""
        reason = self._road_ok(road)
        if reason is not None:
            return self._decline(reason)
        vehicles = road.vehicles
        types = list(map(type, vehicles))
        try:
            first = types.index(FastIDMVehicle)
        except ValueError:
            return self._decline("no FastIDMVehicle on the road")
        if types.count(FastIDMVehicle) != len(types) - first:
            return self._decline("a vehicle of another class comes after a FastIDMVehicle")
        kinds = frozenset(types)
        ok = _CLASS_OK.get(kinds)
        if ok is None:
            ok = _CLASS_OK[kinds] = _classes_ok(kinds)
        if not ok[0]:
            return self._decline(
                "a vehicle class overrides highway-env's kinematics, lane distance or step"
            )
        compiled = vehicles[first:]
        if any(map(_ROUTE, compiled)):
            return self._decline("a FastIDMVehicle follows a planned route")
        if not NUMPY_POWER_SPECIAL.isdisjoint(map(_DELTA, compiled)):
            return self._decline("an IDM exponent (DELTA) that numpy special-cases")
        self._boxes = ok[1]
        return first

    def _decline(self, reason: str) -> None:
        """Record why a step runs on the Python path (for :meth:`act`'s report)."""
        self.declined = reason

    # ----------------------------------------------------------------- state
    def _gather(self, road: Road, first: int) -> bool:
        """Fill the state arrays from ``road.vehicles``; False if a vehicle is not on
        this network's edge, a position is not a float64 pair or the IDM constants make
        its square root fail (coordinates are checked by the kernels).

        Column by column (``map`` of attribute getters): several times cheaper than a
        Python loop over the vehicles.
        """
        vehicles = road.vehicles
        compiled = vehicles[first:]
        n = len(vehicles)
        self._tabulate_lanes()  # a script may have changed a lane's limit or flags
        lane_of = self.lane_of_index.__getitem__
        try:
            lane = list(map(lane_of, map(_LANE_INDEX, vehicles)))
            target = [-1] * first + list(map(lane_of, map(_TARGET_INDEX, compiled)))
            for row, v in enumerate(vehicles[:first]):
                if _is_controlled(type(v)):
                    target[row] = lane_of(v.target_lane_index)
            limit = list(map(self.lane_speed_limit_of.__getitem__, map(id, map(_LANE, vehicles))))
        except (KeyError, TypeError, AttributeError):
            return False  # a lane (or target) not of this network's edge
        impact = [getattr(v, "impact", None) for v in vehicles[:first]] + list(
            map(_IMPACT, compiled)
        )
        pending = list(map(is_not, impact, repeat(None, n)))
        impact_x = [0.0] * n
        impact_y = [0.0] * n
        if any(pending):
            for row, value in enumerate(impact):
                if value is not None:
                    impact_x[row], impact_y[row] = value.tolist()
        actions = list(map(_ACTION, compiled))
        positions = list(map(_POSITION, vehicles))
        if set(map(_DTYPE, positions)) != _FLOAT64:
            return False  # the kernels' write-back keeps float64 positions only
        xy = np.concatenate(positions).tolist()
        no = [0.0] * first
        columns = [
            xy[0::2],
            xy[1::2],
            list(map(_HEADING, vehicles)),
            list(map(_SPEED, vehicles)),
            list(map(_LENGTH, vehicles)),
            [getattr(v, "target_speed", 0) for v in vehicles[:first]]
            + list(map(_TARGET_SPEED, compiled)),
            limit,
            no + list(map(_TIMER, compiled)),
            no + list(map(_STEERING, actions)),
            no + list(map(_ACCELERATION, actions)),
            impact_x,
            impact_y,
            list(map(_WIDTH, vehicles)),
            list(map(_DIAGONAL, vehicles)),
            # The integer columns (small integers, exact as floats), in K_* order.
            lane,
            target,
            no + [1.0] * (n - first),
            list(map(_CRASHED, vehicles)),
            pending,
            no + list(map(_LANE_CHANGE, compiled)),
            list(map(_COLLIDABLE, vehicles)),
            list(map(_CHECKS, vehicles)),
        ]
        # One conversion of all columns (each list converted alone costs about as much).
        table = np.array(columns, dtype=np.float64)
        if table.shape != (K.F_COLUMNS + K.K_COLUMNS, n):
            return False  # a position that is not 2 numbers
        f = table[: K.F_COLUMNS].T.copy()
        k = table[K.F_COLUMNS :].T.astype(np.int64)
        self._f = f
        self._k = k
        params = list(map(_PARAMS, compiled))
        if (first, params) != self._params or self._p is None or len(self._p) != n:
            # Behaviour constants rarely change: rebuild their array only when they do.
            p = np.zeros((n, K.P_COLUMNS))
            p[first:] = params
            if not bool(
                np.all(-p[first:, K.P_COMFORT_ACC_MAX] * p[first:, K.P_COMFORT_ACC_MIN] >= 0.0)
            ):
                return False  # the IDM's sqrt fails: the Python path raises its error
            self._params = (first, params)
            self._p = p
        return True

    def _refresh(self, road: Road, first: int) -> str | None:
        """Read the Python vehicles (rows ``:first``) into the arrays again; the reason
        for the Python path if one is not on this network's lanes or its position is
        not finite, else ``None``.

        Row by row, the columns of :meth:`_gather`: for the one or two vehicles before
        the compiled ones this costs ~6 µs, :meth:`_gather`'s column reads ~20 µs.
        """
        f, k = self._f, self._k
        assert f is not None and k is not None
        lane_of = self.lane_of_index
        for row, v in enumerate(road.vehicles[:first]):
            lane = lane_of.get(v.lane_index)
            limit = self.lane_speed_limit_of.get(id(v.lane))
            target = -1
            if _is_controlled(type(v)):
                target = lane_of.get(v.target_lane_index, -2)
            if lane is None or limit is None or target == -2:
                return _OFF_LANES
            x, y = v.position.tolist()
            if not (abs(x) < COORD_LIMIT and abs(y) < COORD_LIMIT):
                return _NOT_FINITE
            impact = v.impact
            ix, iy = (0.0, 0.0) if impact is None else impact.tolist()
            f[row, : K.F_SPEED_LIMIT + 1] = (
                x,
                y,
                v.heading,
                v.speed,
                v.LENGTH,
                getattr(v, "target_speed", 0),
                limit,
            )
            f[row, K.F_IMPACT_X : K.F_DIAGONAL + 1] = (ix, iy, v.WIDTH, v.diagonal)
            k[row] = (
                lane,
                target,
                0,
                v.crashed,
                impact is not None,
                0,
                v.collidable,
                v.check_collisions,
            )
        return None

    @contextmanager
    def holding(self) -> Iterator[None]:
        """Within this block the steps run back to back: no code but the road's
        ``act``/``step`` and read-only perception touches the compiled vehicles.

        The engine then keeps their state in its arrays from one step to the next
        instead of reading every vehicle again (the env's ``_simulate`` holds it for
        the simulation steps of one env step; anything may happen between env steps,
        so the first step of a block reads everything).
        """
        self._held = True
        self._current = None
        before = self.steps.copy()
        try:
            yield
        finally:
            self._held = False
            self._current = None
            self._warn_if_declined(self.steps - before)

    @staticmethod
    def _warn_if_declined(block: Counter[str]) -> None:
        """Warn (once per reason and process) when a whole block ran on the Python path."""
        if block[COMPILED] or not block:
            return
        for reason in block:
            if reason not in _WARNED:
                _WARNED.add(reason)
                warnings.warn(
                    "traffic.engine='compiled': the traffic ran on the Python path for a "
                    f"whole env step because {reason} (same behaviour, slower; "
                    "docs/env.md, 'The traffic engine')",
                    RuntimeWarning,
                    stacklevel=4,
                )

    def forget(self) -> None:
        """Drop the state gathered by :meth:`act` (call after moving vehicles by hand;
        :meth:`FastRoad.invalidate <aldm_gym.envs.traffic.road.FastRoad.invalidate>`
        does)."""
        self._acted = None
        self._current = None

    # ----------------------------------------------------------------- the two calls
    def act(self, road: Road) -> bool:
        """Every vehicle decides its action (``Road.act``), or False for the Python path.

        The vehicles before the compiled ones act in Python first (list order), then
        one kernel call decides the rest; their ``action``, ``target_lane_index`` and
        ``timer`` are written back.
        """
        current, self._current = self._current, None
        self._acted = None
        vehicles = road.vehicles
        if self._held and current is not None and current == vehicles:
            # Back-to-back steps: the arrays mirror the compiled vehicles (module
            # docstring); only the Python vehicles are read again after they act.
            first = self._first
            for v in vehicles[:first]:
                v.act()
            failed = self._refresh(road, first)
        else:
            split = self._split(road)
            if split is None:
                self.steps[self.declined or "unknown"] += 1
                return False
            first = self._first = split
            for v in vehicles[:first]:
                v.act()
            failed = None if self._gather(road, first) else _OFF_LANES
        if failed is not None:
            # The Python vehicles have acted: the rest act in Python too (same order).
            self.steps[failed] += 1
            for v in vehicles[first:]:
                v.act()
            return True
        f, k, p = self._f, self._k, self._p
        assert f is not None and k is not None and p is not None
        if not K.traffic_act(f, k, p, self._memo, *self.act_tables):
            # A position not finite (or huge): the rest act in Python (same order).
            self.steps[_NOT_FINITE] += 1
            for v in vehicles[first:]:
                v.act()
            return True
        self.steps[COMPILED] += 1
        steer = f[first:, K.F_STEERING].tolist()
        accel = f[first:, K.F_ACCELERATION].tolist()
        timer = f[first:, K.F_TIMER].tolist()
        target = k[first:, K.K_TARGET].tolist()
        crashed = k[first:, K.K_CRASHED].tolist()
        indices = self.lane_indices
        # step() moves them from this state (positions do not change in between).
        self._acted = (list(vehicles), first)
        for v, hit, steering, acceleration, time, lane in zip(
            vehicles[first:], crashed, steer, accel, timer, target, strict=True
        ):
            if hit:
                continue  # IDMVehicle.act does nothing for a crashed vehicle
            v.action = {"steering": steering, "acceleration": acceleration}
            v.timer = time
            if v.target_lane_index[2] != lane:
                v.target_lane_index = indices[lane]
        return True

    def step(self, road: Road, dt: float) -> int | None:
        """Move the compiled vehicles by ``dt`` [s] and set their lanes.

        :return: the index of the first vehicle it moved (the caller steps the earlier
            ones), or None if it moved none (the Python path steps everyone).
        """
        acted, self._acted = self._acted, None
        self._current = None
        if acted is not None and acted[0] == road.vehicles:
            first = acted[1]  # the state act() gathered and updated
        else:
            first = self._split(road)
            if first is None or not self._gather(road, first):
                return None
            self._first = first
        f, k, p = self._f, self._k, self._p
        assert f is not None and k is not None and p is not None
        impact = k[first:, K.K_IMPACT].tolist()  # pending before the kernel applies them
        if len(self._memo) != len(f):
            self._memo = np.full((len(f), 4), np.nan)
        if not K.traffic_step(f, k, p, self._memo, float(dt), *self.step_tables):
            return None  # a position not finite: the Python path (and its errors)
        # Columns F_X .. F_ACCELERATION, one list per vehicle (a slice: no index array;
        # unpacked below in the kernels' column order F_X, F_Y, F_HEADING, F_SPEED,
        # three unused, F_TIMER, F_STEERING, F_ACCELERATION).
        rows = f[first:, : K.F_ACCELERATION + 1].tolist()
        lane = k[first:, K.K_LANE].tolist()
        crashed = k[first:, K.K_CRASHED].tolist()
        lanes = self.lanes
        indices = self.lane_indices
        limits = self.lane_speed_limit
        row_index = first
        for v, (x, y, heading, speed, *_, timer, steering, acceleration), hit, pending, new in zip(
            road.vehicles[first:], rows, crashed, impact, lane, strict=True
        ):
            position = v.position
            position[0] = x
            position[1] = y
            v.heading = heading
            v.speed = speed
            v.timer = timer
            action = v.action
            action["steering"] = steering
            action["acceleration"] = acceleration
            if hit and not v.crashed:
                v.crashed = True
            if pending:
                v.impact = None  # applied by the kernel
            if v.lane_index[2] != new:
                v.lane_index = indices[new]
                v.lane = lanes[new]
                f[row_index, K.F_SPEED_LIMIT] = limits[new]  # the new lane's
            row_index += 1
        return first

    def collide(self, road: Road, dt: float, first: int) -> None:
        """Resolve collisions after :meth:`step` moved vehicles ``first:`` and the
        caller moved the others: ``resolve_collisions``'s result, with the pairs that
        may collide found in one compiled call (plain boxes only; else its Python path).

        :param dt: timestep [s].
        :param first: what :meth:`step` returned.
        """
        f, k = self._f, self._k
        vehicles = road.vehicles
        if not self._boxes or f is None or k is None or len(f) != len(vehicles):
            resolve_collisions(vehicles, road.objects, dt)
            return
        if self._refresh(road, first) is not None:  # moved in Python since the gather
            resolve_collisions(vehicles, road.objects, dt)
            return
        ok, pairs = K.collision_pairs(f, k, float(dt))
        if not ok:
            resolve_collisions(vehicles, road.objects, dt)  # its all-pairs fallback
            return
        for i, j in pairs.tolist():
            vehicles[i].handle_collisions(vehicles[j], dt)  # impacts, crash flags only
            for row in (i, j):  # keep the arrays mirroring the vehicles
                v = vehicles[row]
                impact = v.impact
                k[row, K.K_CRASHED] = v.crashed
                k[row, K.K_IMPACT] = impact is not None
                if impact is not None:
                    f[row, K.F_IMPACT_X], f[row, K.F_IMPACT_Y] = impact.tolist()
        self._current = list(vehicles)

    def moved_state(self, road: Road) -> np.ndarray | None:
        """Every vehicle's state right after the last :meth:`collide`, or None.

        ``(N, F_COLUMNS)`` rows in ``road.vehicles`` order (see
        :mod:`~aldm_gym.envs.traffic.kernels`): the position, heading, speed, length and
        width columns are the vehicles' own values (the same floats), as long as no
        vehicle moved since; None after the next ``act``, :meth:`forget` or a step on
        the Python path. For the env's object list, built once per step this way. It
        is the engine's own array, changed by the next step: copy what you keep.
        """
        current = self._current
        if current is None or current != road.vehicles:
            return None
        return self._f
