"""The traffic mix: cars and trucks (the env's ``traffic`` section).

highway-env's traffic is one kind of vehicle, 5 m long. Trucks matter for a lane
sensor (they hide markings far ahead, :mod:`aldm_gym.sensor.conditions`) and for the
ACC (a 15 m target). With ``truck_share`` > 0 each other vehicle becomes a truck with
that probability, drawn from the env's generator when the vehicle is created:

- its ``LENGTH``, ``WIDTH`` and ``HEIGHT`` [m] are set on the instance (highway-env
  reads the class attributes through the instance everywhere: collisions, rendering,
  the bicycle model; the occlusion reads ``HEIGHT``);
- its desired speed is drawn from ``truck_speed`` (it starts at most that fast);
- it keeps its lane unless ``truck_lane_changes`` (MOBIL stays off);
- it is placed so that the gaps before and after it are those a car would have had:
  the vehicles ahead of it move forward by the extra length (:class:`Spawner`).

The car-following model (:class:`~aldm_gym.envs.traffic.FastIDMVehicle`) measures
gaps bumper to bumper with each vehicle's own length, so a car keeps the same
distance behind a truck as behind a car. With ``truck_share`` = 0 (the default) no
number is drawn and the episode is the one of a car-only env, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from highway_env.vehicle.kinematics import Vehicle

from aldm_gym.config import setting, validate
from aldm_gym.envs.traffic.compiled import ENGINES
from aldm_gym.errors import ConfigError
from aldm_gym.sensor.conditions import TRUCK_HEIGHT

__all__ = ["CAR_LENGTH", "Spawner", "TrafficConfig", "TruckSpec", "make_truck"]

CAR_LENGTH: float = float(Vehicle.LENGTH)
"""highway-env's vehicle length [m] (every car's)."""


@dataclass(frozen=True)
class TrafficConfig:
    """The env's ``traffic`` section: the share and the kind of trucks.

    :ivar truck_share: probability that an other vehicle is a truck, in [0, 1].
    :ivar truck_length: (min, max) length of a truck [m], drawn uniformly.
    :ivar truck_width: width of a truck [m].
    :ivar truck_speed: (min, max) desired speed of a truck [m/s], drawn uniformly
        (cars: highway-env's 23-25 m/s).
    :ivar truck_lane_changes: trucks change lanes by MOBIL as cars do (False: they
        keep the lane they start in).
    :ivar engine: ``"compiled"`` runs the IDM/MOBIL vehicles of a generated highway in
        compiled kernels (:mod:`aldm_gym.envs.traffic.compiled`; the same episode bit
        for bit, about 5x cheaper traffic); ``"python"`` runs highway-env's vehicle
        code (through :class:`~aldm_gym.envs.traffic.FastIDMVehicle`). OpenDRIVE maps
        always use the Python path.
    """

    truck_share: float = setting(0.0, lo=0.0, hi=1.0)
    truck_length: tuple[float, float] = setting((12.0, 18.0), kind="pair", lo=6.0, hi=25.0)
    truck_width: float = setting(2.5, lo=1.5, hi=3.0)
    truck_speed: tuple[float, float] = setting((21.0, 24.0), kind="pair", lo=0.0, hi=40.0)
    truck_lane_changes: bool = setting(False)
    engine: str = setting("compiled", choices=ENGINES)

    def __post_init__(self) -> None:
        validate(self, "traffic")
        for name in ("truck_length", "truck_speed"):
            lo, hi = getattr(self, name)
            if hi < lo:
                raise ConfigError(
                    f"traffic.{name} must be (min, max) with min <= max, got {(lo, hi)}"
                )


@dataclass(frozen=True)
class TruckSpec:
    """One drawn truck: length [m] and desired speed [m/s]."""

    length: float
    speed: float


def make_truck(vehicle: Any, spec: TruckSpec, config: TrafficConfig) -> None:
    """Turn ``vehicle`` (a highway-env vehicle) into the truck ``spec``, in place.

    :param vehicle: the vehicle; its speed is capped at the truck's desired speed.
    :param spec: the drawn length and desired speed.
    :param config: the traffic section (width, lane changes).
    """
    vehicle.LENGTH = spec.length
    vehicle.WIDTH = config.truck_width
    vehicle.HEIGHT = TRUCK_HEIGHT  # the occlusion's height of long vehicles
    vehicle.diagonal = math.hypot(spec.length, config.truck_width)
    vehicle.target_speed = spec.speed
    vehicle.speed = min(float(vehicle.speed), spec.speed)
    if hasattr(vehicle, "enable_lane_change"):
        vehicle.enable_lane_change = bool(config.truck_lane_changes)


class Spawner:
    """Draws which vehicles are trucks and keeps car-sized gaps around them.

    Call :meth:`draw` before placing a vehicle, then :meth:`extra_shift` for how far
    [m] to move it forward along its lane (half its own extra length, plus half the
    extra length of the truck placed before it, so that every vehicle after a truck
    starts further on by the truck's extra length).

    :param config: the traffic section.
    :param rng: the env's generator (nothing is drawn when ``truck_share`` is 0).
    """

    def __init__(self, config: TrafficConfig, rng: np.random.Generator):
        self.config = config
        self.rng = rng
        self._carried = 0.0

    def draw(self) -> TruckSpec | None:
        """The next vehicle's truck spec, or ``None`` for a car."""
        c = self.config
        if c.truck_share <= 0.0 or float(self.rng.uniform()) >= c.truck_share:
            return None
        return TruckSpec(
            length=float(self.rng.uniform(*c.truck_length)),
            speed=float(self.rng.uniform(*c.truck_speed)),
        )

    def extra_shift(self, spec: TruckSpec | None) -> float:
        """How far [m] to move the vehicle just drawn forward from a car's place."""
        half = 0.0 if spec is None else 0.5 * max(spec.length - CAR_LENGTH, 0.0)
        shift = self._carried + half
        self._carried += 2.0 * half
        return shift

    def place(self, vehicle: Any, spec: TruckSpec | None) -> None:
        """Make ``vehicle`` the drawn kind and move it forward along its lane.

        For lanes long enough to hold the shift (a generated highway's lanes run the
        whole road); the shift is along the lane, keeping its lateral offset.
        """
        shift = self.extra_shift(spec)
        if spec is not None:
            make_truck(vehicle, spec, self.config)
        if shift > 0.0:
            lane = vehicle.lane
            s, r = lane.local_coordinates(vehicle.position)
            vehicle.position = np.asarray(lane.position(s + shift, r), dtype=np.float64)
            vehicle.heading = float(lane.heading_at(s + shift))
