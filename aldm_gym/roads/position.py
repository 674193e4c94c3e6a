"""Ground truth of a vehicle's position on a road, the same for every road source.

The environment scores and ends episodes on ground truth: which lane the ego is in,
how far it is from that lane's centre, how wide the lane is there, which way the lane
runs, how much road is left. A generated highway answers from its one reference line;
a map answers from the lane that contains the position. Both hand back a
:class:`LanePosition`, so the env never asks which kind of road it drives on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from aldm_gym.errors import InputError
from aldm_gym.types import FloatArray


@dataclass(frozen=True)
class LanePosition:
    """Where a world position lies on a road (ground truth; a sensor never sees it).

    :ivar s: arc length along the road (its reference line or route) [m], growing in
        the driving direction; progress is measured with it.
    :ivar offset: lateral offset from the lane's centre [m], > 0 to the driver's left.
    :ivar lane: the road's key of the lane (an ``int`` on a generated highway, 0 =
        leftmost; a map's own key on a map), what ``road.boundary_markings`` takes.
    :ivar index: lane number from the left among the lanes of this driving direction
        at this point (0 = leftmost).
    :ivar lanes: number of such lanes at this point.
    :ivar width: the lane's width here [m].
    :ivar heading: the lane's direction of travel here (world heading [rad]).
    :ivar end: the arc length ``s`` where the road (route) ends [m].
    """

    s: float
    offset: float
    lane: Any
    index: int
    lanes: int
    width: float
    heading: float
    end: float

    @property
    def edge_lane(self) -> bool:
        """Whether the lane is the leftmost or the rightmost one here."""
        return self.index in (0, self.lanes - 1)


@dataclass(frozen=True)
class Pose:
    """A sampled vehicle pose on a road (:meth:`Road.sample_poses
    <aldm_gym.roads.protocol.Road.sample_poses>`).

    :ivar s: reference arc length [m] (on a map: along the lane's chain).
    :ivar lane_id: true lane (the road's lane key: an int on a generated highway, a
        ``(road id, section, lane id)`` on a map).
    :ivar shift: left offset from the lane centre [m].
    :ivar pose: world ``(x [m], y [m], heading [rad])``.
    :ivar index: the lane's number from the left among the lanes of its direction.
    :ivar lanes: how many such lanes there are.
    """

    s: float
    lane_id: Any
    shift: float
    pose: tuple[float, float, float]
    index: int = 0
    lanes: int = 1


#: Largest world coordinate accepted [m]: far beyond any map (UTM northings stay
#: below 1e7 m), small enough that projections stay exact in float64.
MAX_COORDINATE = 1e9


def world_point(name: str, value: Any) -> FloatArray:
    """``value`` as a float64 ``(2,)`` world point [m] (a 3rd coordinate is dropped).

    :raises InputError: naming ``name`` unless ``value`` holds 2 (or 3) finite numbers
        within :data:`MAX_COORDINATE` of the origin on each axis.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.shape not in ((2,), (3,)) or not (math.isfinite(arr[0]) and math.isfinite(arr[1])):
        raise InputError(f"{name} must be 2 finite numbers (x, y) [m], got {value!r}")
    check_within_world(name, float(arr[0]), float(arr[1]), value)
    return arr[:2]


def world_heading(name: str, value: float | None) -> float | None:
    """``value`` as a heading [rad] (highway-env's world frame), or None for None.

    :raises InputError: naming ``name`` unless ``value`` is a finite number.
    """
    if value is None:
        return None
    try:
        heading = float(value)
    except (TypeError, ValueError):
        heading = math.nan
    if not math.isfinite(heading):
        raise InputError(f"{name} must be a finite number [rad], got {value!r}")
    return heading


def check_within_world(name: str, x: float, y: float, value: Any) -> None:
    """Raise unless the world point ``(x, y)`` [m] lies within :data:`MAX_COORDINATE`
    of the origin on each axis.

    :raises InputError: naming ``name`` and quoting ``value`` (what the caller got).
    """
    if abs(x) > MAX_COORDINATE or abs(y) > MAX_COORDINATE:
        raise InputError(
            f"{name} must lie within ±{MAX_COORDINATE:g} m of the origin on each axis, "
            f"got {value!r}"
        )
