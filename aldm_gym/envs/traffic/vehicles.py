"""Vehicle classes: highway-env's kinematics and IDM/MOBIL, numpy-free, same floats.

After :class:`~aldm_gym.envs.traffic.road.FastRoad`, the per-step cost is dominated by
numpy *scalar* calls in the vehicle models (``np.clip``, ``np.dot``, ``np.array``,
properties building 2-vectors). The classes here redo the same IEEE operations on
Python floats (:mod:`aldm_gym.envs.traffic.scalar`), so trajectories are identical
bit for bit (checked in ``tests/envs/traffic/test_fast_road.py``):

- :class:`BatchedLaneUpdate` -- mixin: lets ``FastRoad.step`` defer the closest-lane
  look-up that ends a vehicle's ``step``.
- :class:`FastBicycleStep` -- mixin: ``Vehicle.step``'s kinematic bicycle model.
- :class:`FastControlledVehicle` -- ``ControlledVehicle`` (lane following).
- :class:`FastIDMVehicle` -- ``IDMVehicle`` (IDM + MOBIL).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from highway_env import utils
from highway_env.road.lane import AbstractLane
from highway_env.road.road import LaneIndex
from highway_env.vehicle.behavior import IDMVehicle
from highway_env.vehicle.controller import ControlledVehicle
from highway_env.vehicle.kinematics import Vehicle
from highway_env.vehicle.objects import RoadObject

from aldm_gym.envs.traffic.scalar import (
    PLAIN_DOT_MATCHES_NUMPY,
    asin_scalar,
    atan_scalar,
    clip_scalar,
    cos_scalar,
    not_zero_scalar,
    power_scalar,
    sin_scalar,
    tan_scalar,
)
from aldm_gym.envs.traffic.straight_lanes import straight_geometry

__all__ = [
    "STEPS_ENDING_WITH_UPDATE",
    "BatchedLaneUpdate",
    "FastBicycleStep",
    "FastControlledVehicle",
    "FastIDMVehicle",
    "uses_base_kinematics",
    "velocity",
]


@cache
def uses_base_kinematics(cls: type) -> bool:
    """Whether ``cls.velocity`` / ``cls.direction`` are highway-env's own properties."""
    return getattr(cls, "direction", None) is RoadObject.direction and (
        getattr(cls, "velocity", None) in (Vehicle.velocity, RoadObject.velocity)
    )


def velocity(vehicle: RoadObject) -> tuple[float, float] | np.ndarray:
    """``vehicle.velocity`` [m/s] (world frame): for highway-env's own kinematics the
    same floats (``speed * cos``, ``speed * sin``, numpy's functions) without building
    two arrays; otherwise the vehicle's own property."""
    if uses_base_kinematics(type(vehicle)):
        speed, heading = vehicle.speed, vehicle.heading
        return (speed * cos_scalar(heading), speed * sin_scalar(heading))
    return vehicle.velocity


def _extra_length(obj: RoadObject) -> float:
    """Half of what ``obj`` is longer than highway-env's vehicle [m] (0 if not longer).

    highway-env's IDM measures centre to centre and its ``DISTANCE_WANTED`` includes one
    vehicle length, which is right only between two 5 m vehicles. A truck
    (:mod:`aldm_gym.envs.traffic.mix`) shortens the gap by this much at each end;
    objects no longer than a car keep highway-env's gap exactly.
    """
    length = obj.LENGTH
    return 0.5 * (length - Vehicle.LENGTH) if length > Vehicle.LENGTH else 0.0


class BatchedLaneUpdate(Vehicle):
    """Mixin: lets :meth:`FastRoad.step` defer this vehicle's closest-lane look-up.

    ``Vehicle.on_state_update`` (called at the end of ``step``) looks up the closest
    lane of the new position. Inside :meth:`FastRoad.step` the call is queued and run,
    unchanged, once every vehicle has moved, after the network has had the chance to
    project all positions in one batch. Anywhere else it runs at once.
    """

    def on_state_update(self) -> None:
        """Update the lane (now, or after all vehicles moved in ``FastRoad.step``)."""
        deferred: list[Vehicle] | None = getattr(self.road, "_deferred_updates", None)
        if deferred is not None:
            deferred.append(self)
            return
        Vehicle.on_state_update(self)


class FastBicycleStep(Vehicle):
    """Mixin: ``Vehicle.step`` (the kinematic bicycle model) without numpy scalar calls.

    Put it before ``Vehicle`` (or any class defining ``step``) in the bases; it only
    defines :meth:`step`. Its last action is ``self.on_state_update()``, so
    :meth:`FastRoad.step` may defer that call (see :data:`STEPS_ENDING_WITH_UPDATE`).
    """

    def step(self, dt: float) -> None:
        """Propagate the state by ``dt`` [s] exactly as ``Vehicle.step`` does.

        :param dt: integration timestep [s].
        """
        self.clip_actions()
        beta = atan_scalar(1 / 2 * tan_scalar(self.action["steering"]))
        speed = self.speed
        course = self.heading + beta
        position = self.position
        # Vehicle.step: position += (speed * [cos, sin]) * dt, element by element.
        position[0] = position[0] + speed * cos_scalar(course) * dt
        position[1] = position[1] + speed * sin_scalar(course) * dt
        impact: np.ndarray | None = getattr(self, "impact", None)
        if impact is not None:
            self.position += impact
            self.crashed = True
            self.impact = None
        self.heading += speed * sin_scalar(beta) / (self.LENGTH / 2) * dt
        self.speed += self.action["acceleration"] * dt
        self.on_state_update()


class FastControlledVehicle(FastBicycleStep, BatchedLaneUpdate, ControlledVehicle):
    """A ``ControlledVehicle`` whose hot paths avoid numpy scalar overhead.

    ``step`` (:class:`FastBicycleStep`), ``steering_control``, ``follow_road`` and
    ``lane_distance_to`` perform the same floating-point operations as highway-env's
    versions, so trajectories are identical bit for bit. Lanes other than plain
    ``StraightLane`` use the lane's own methods.
    """

    def lane_distance_to(self, other: RoadObject, lane: AbstractLane | None = None) -> float:
        """Signed distance [m] to ``other`` along ``lane`` (default: own lane).

        :param other: the other object (None gives NaN).
        :param lane: the lane to measure along.
        :return: ``s_other - s_self`` [m].
        """
        if not other:
            return np.nan
        if not lane:
            lane = self.lane
        geometry = straight_geometry(lane)
        if geometry is None:
            return super().lane_distance_to(other, lane)
        sx, sy, d0, d1 = geometry[0], geometry[1], geometry[2], geometry[3]
        ox, oy = other.position.tolist()
        px, py = self.position.tolist()
        return ((ox - sx) * d0 + (oy - sy) * d1) - ((px - sx) * d0 + (py - sy) * d1)

    def follow_road(self) -> None:
        """At the end of the target lane, switch to the next one (as the base class)."""
        target_lane_index: LaneIndex = getattr(self, "target_lane_index")  # noqa: B009 (typed)
        lane = self.road.network.get_lane(target_lane_index)
        geometry = straight_geometry(lane)
        if geometry is None:
            after_end = lane.after_end(self.position)
        else:
            px, py = self.position.tolist()
            s = (px - geometry[0]) * geometry[2] + (py - geometry[1]) * geometry[3]
            after_end = s > geometry[6] - lane.VEHICLE_LENGTH / 2
        if after_end:
            self.target_lane_index = self.road.network.next_lane(
                target_lane_index,
                route=self.route,
                position=self.position,
                np_random=self.road.np_random,
            )

    def steering_control(self, target_lane_index: LaneIndex) -> float:
        """Steering angle [rad] to follow the centre of a lane (base-class result).

        :param target_lane_index: index of the lane to follow.
        :return: the steering wheel angle command [rad].
        """
        target_lane = self.road.network.get_lane(target_lane_index)
        geometry = straight_geometry(target_lane)
        if geometry is None:
            s, r = target_lane.local_coordinates(self.position)
        else:
            px, py = self.position.tolist()
            dx = px - geometry[0]
            dy = py - geometry[1]
            s = dx * geometry[2] + dy * geometry[3]
            r = dx * geometry[4] + dy * geometry[5]
        speed = self.speed
        lane_future_heading = target_lane.heading_at(s + speed * self.TAU_PURSUIT)
        lateral_speed_command = -self.KP_LATERAL * r
        heading_command = asin_scalar(
            clip_scalar(lateral_speed_command / not_zero_scalar(speed), -1, 1)
        )
        heading_ref = lane_future_heading + clip_scalar(heading_command, -np.pi / 4, np.pi / 4)
        heading_rate_command = self.KP_HEADING * utils.wrap_to_pi(heading_ref - self.heading)
        slip_angle = asin_scalar(
            clip_scalar(self.LENGTH / 2 / not_zero_scalar(speed) * heading_rate_command, -1, 1)
        )
        steering_angle = atan_scalar(2 * tan_scalar(slip_angle))
        return float(clip_scalar(steering_angle, -self.MAX_STEERING_ANGLE, self.MAX_STEERING_ANGLE))


class FastIDMVehicle(FastControlledVehicle, IDMVehicle):
    """highway-env's ``IDMVehicle`` (IDM + MOBIL) with identical results, computed faster.

    Use it as ``other_vehicles_type = "aldm_gym.envs.traffic.FastIDMVehicle"``.
    ``act``, ``acceleration`` and ``desired_gap`` are the base code with numpy scalar
    calls replaced by the same float operations; MOBIL (``change_lane_policy``,
    ``mobil``) is inherited unchanged and benefits through these methods. One
    extension: gaps to and from vehicles longer than 5 m (trucks) are bumper to bumper
    (:func:`_extra_length`); between cars the results are highway-env's.
    """

    def step(self, dt: float) -> None:
        """Advance the lane-change timer, then the dynamics (``IDMVehicle.step``).

        :param dt: integration timestep [s].
        """
        self.timer += dt
        FastBicycleStep.step(self, dt)

    def act(self, action: dict[str, float] | str | None = None) -> None:
        """Decide steering (MOBIL + lane following) and acceleration (IDM).

        :param action: ignored, as in ``IDMVehicle.act``.
        """
        if self.crashed:
            return
        command: dict[str, float] = {}
        self.follow_road()
        if self.enable_lane_change:
            self.change_lane_policy()
        steering = self.steering_control(self.target_lane_index)
        command["steering"] = clip_scalar(
            steering, -self.MAX_STEERING_ANGLE, self.MAX_STEERING_ANGLE
        )
        front_vehicle, rear_vehicle = self.road.neighbour_vehicles(self, self.lane_index)
        acceleration = self.acceleration(
            ego_vehicle=self, front_vehicle=front_vehicle, rear_vehicle=rear_vehicle
        )
        # When changing lane, check both current and target lanes.
        if self.lane_index != self.target_lane_index:
            front_vehicle, rear_vehicle = self.road.neighbour_vehicles(self, self.target_lane_index)
            target_acceleration = self.acceleration(
                ego_vehicle=self, front_vehicle=front_vehicle, rear_vehicle=rear_vehicle
            )
            acceleration = min(acceleration, target_acceleration)
        command["acceleration"] = clip_scalar(acceleration, -self.ACC_MAX, self.ACC_MAX)
        Vehicle.act(self, command)

    def acceleration(
        self,
        ego_vehicle: ControlledVehicle | None,
        front_vehicle: RoadObject | None = None,
        rear_vehicle: RoadObject | None = None,
    ) -> float:
        """IDM acceleration [m/s²] of ``ego_vehicle`` behind ``front_vehicle`` (base result).

        :param ego_vehicle: the vehicle whose acceleration is computed (any vehicle).
        :param front_vehicle: its leader, if any.
        :param rear_vehicle: unused, as in the base class.
        :return: the acceleration command [m/s²].
        """
        if not ego_vehicle or not isinstance(ego_vehicle, Vehicle):
            return 0
        ego_target_speed = getattr(ego_vehicle, "target_speed", 0)
        if ego_vehicle.lane and ego_vehicle.lane.speed_limit is not None:
            ego_target_speed = clip_scalar(ego_target_speed, 0, ego_vehicle.lane.speed_limit)
        acceleration = self.COMFORT_ACC_MAX * (
            1
            - power_scalar(
                max(ego_vehicle.speed, 0) / abs(not_zero_scalar(ego_target_speed)), self.DELTA
            )
        )
        if front_vehicle:
            d = ego_vehicle.lane_distance_to(front_vehicle)
            extra = _extra_length(ego_vehicle) + _extra_length(front_vehicle)
            if extra:
                d -= extra  # bumper to bumper as between two cars (trucks)
            ratio = self.desired_gap(ego_vehicle, front_vehicle) / not_zero_scalar(d)
            # np.power(x, 2) is computed as x * x.
            acceleration -= self.COMFORT_ACC_MAX * (ratio * ratio)
        return acceleration

    def desired_gap(
        self,
        ego_vehicle: Vehicle,
        front_vehicle: RoadObject | None = None,
        projected: bool = True,
    ) -> float:
        """Desired distance [m] to the leader (IDM ``s*``, base-class result).

        :param ego_vehicle: the following vehicle.
        :param front_vehicle: its leader.
        :param projected: project the velocity difference on the ego heading.
        :return: the desired gap [m].
        """
        assert front_vehicle is not None
        # Annotated: mypy does not see type[Any] as Hashable (the cache's argument).
        ego_cls: type = type(ego_vehicle)
        front_cls: type = type(front_vehicle)
        if projected and not (
            PLAIN_DOT_MATCHES_NUMPY
            and uses_base_kinematics(ego_cls)
            and uses_base_kinematics(front_cls)
        ):
            # highway-env's np.dot, where plain arithmetic would not give its result.
            return float(super().desired_gap(ego_vehicle, front_vehicle, projected))
        d0 = self.DISTANCE_WANTED
        tau = self.TIME_WANTED
        ab = -self.COMFORT_ACC_MAX * self.COMFORT_ACC_MIN
        ego_speed = ego_vehicle.speed
        if projected:
            # np.dot(ego.velocity - front.velocity, ego.direction), term by term.
            cos_e = cos_scalar(ego_vehicle.heading)
            sin_e = sin_scalar(ego_vehicle.heading)
            front_speed = front_vehicle.speed
            dvx = ego_speed * cos_e - front_speed * cos_scalar(front_vehicle.heading)
            dvy = ego_speed * sin_e - front_speed * sin_scalar(front_vehicle.heading)
            dv = dvx * cos_e + dvy * sin_e
        else:
            dv = ego_speed - front_vehicle.speed
        return d0 + ego_speed * tau + ego_speed * dv / (2 * math.sqrt(ab))


STEPS_ENDING_WITH_UPDATE = frozenset({Vehicle.step, FastBicycleStep.step, FastIDMVehicle.step})
"""``step`` methods whose last action is ``self.on_state_update()`` (nothing after it
reads the lane), so :meth:`FastRoad.step` may defer that call."""
