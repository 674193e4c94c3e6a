"""Traffic that scales: highway-env's road and vehicles, same results, about linear cost.

highway-env's ``Road`` answers neighbour queries, collisions and perception queries
with O(n²) Python-level work per simulation step, and its vehicle models spend most of
their time in numpy *scalar* calls (highway-env issues #36, #121, #223). This package
keeps the exact answers (checked bit for bit in
``tests/envs/traffic/test_fast_road.py``) and removes that work. One job per module:

- :mod:`~aldm_gym.envs.traffic.scalar` -- scalar float math with numpy's results
  (``clip_scalar``, ``power_scalar``, ``sin_scalar``, ...) and the probe of where numpy
  agrees with libm (``NUMPY_AGREES_WITH_LIBM``).
- :mod:`~aldm_gym.envs.traffic.straight_lanes` -- plain ``StraightLane`` constants as
  floats, cached per lane.
- :mod:`~aldm_gym.envs.traffic.network` -- :class:`FastRoadNetwork`, the closest-lane
  look-up.
- :mod:`~aldm_gym.envs.traffic.neighbours` -- the neighbour cache (sorted per-lane
  tables, bisection queries).
- :mod:`~aldm_gym.envs.traffic.collisions` -- broad and narrow phase selecting the
  pairs whose ``handle_collisions`` can have an effect.
- :mod:`~aldm_gym.envs.traffic.vehicles` -- :class:`BatchedLaneUpdate`,
  :class:`FastBicycleStep`, :class:`FastControlledVehicle`, :class:`FastIDMVehicle`.
- :mod:`~aldm_gym.envs.traffic.road` -- :class:`FastRoad`, composing the above.
- :mod:`~aldm_gym.envs.traffic.compiled` -- :class:`CompiledTraffic`, the optional
  engine of a ``FastRoad`` on a generated highway: the ``FastIDMVehicle`` traffic in
  compiled kernels (:mod:`~aldm_gym.envs.traffic.kernels`), same results.
- :mod:`~aldm_gym.envs.traffic.patch` -- :func:`use_fast_road` for any highway-env env.

Data flow of one simulation step on a :class:`FastRoad`: ``act`` ends the neighbour
cache's epoch and every vehicle decides its action, querying neighbours (the cache
projects all road objects once per queried lane edge and answers by bisection) and
lane geometry (``straight_lanes``, ``scalar``); ``step`` moves every vehicle
(``FastBicycleStep``), defers their closest-lane look-ups (``BatchedLaneUpdate``) and
runs them in one batch on the network, ends the epoch, then resolves collisions. With
an engine, ``act`` and ``step`` hand the compiled vehicles to it (state gathered into
arrays, one kernel call each, results written back) whenever it can.

Usage::

    road = FastRoad(network=..., np_random=self.np_random, ...)  # in _create_road
    use_fast_road(env)                                           # any highway-env env

or, for traffic alone, ``other_vehicles_type = "aldm_gym.envs.traffic.FastIDMVehicle"``.
"""

from __future__ import annotations

from aldm_gym.envs.traffic.network import FastRoadNetwork
from aldm_gym.envs.traffic.patch import use_fast_road
from aldm_gym.envs.traffic.road import FastRoad
from aldm_gym.envs.traffic.scalar import FAST_MATH_MATCHES_NUMPY, LIBM_MATCHES_NUMPY, clip_scalar
from aldm_gym.envs.traffic.vehicles import (
    BatchedLaneUpdate,
    FastBicycleStep,
    FastControlledVehicle,
    FastIDMVehicle,
)

__all__ = [
    "FAST_MATH_MATCHES_NUMPY",
    "LIBM_MATCHES_NUMPY",
    "BatchedLaneUpdate",
    "FastBicycleStep",
    "FastControlledVehicle",
    "FastIDMVehicle",
    "FastRoad",
    "FastRoadNetwork",
    "clip_scalar",
    "use_fast_road",
]
