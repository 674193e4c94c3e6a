"""What the rest of aldm-gym asks of a road: two protocols, no road kinds.

The sensor, the detectors' ground truth, the env and the comparisons ask a road
questions; :class:`~aldm_gym.roads.HighwayRoad` (generated) and
:class:`~aldm_gym.roads.OpenDriveRoad` (a map) answer them, each in its own way, so
no code outside this package needs to know which kind it holds (highway-env's
``AbstractLane`` plays the same part for lanes).

- :class:`MarkedRoad`: painted markings the line sensor can measure
  (:class:`~aldm_gym.roads.PolylineRoad` is one without lanes).
- :class:`Road`: a marked road with lanes: ground truth of positions, the lane
  network traffic drives on, where the road ends, seeded poses for evaluations.

Both are ``runtime_checkable`` (``isinstance(x, Road)`` checks the members' presence,
not their signatures); type checkers check the signatures.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np
from highway_env.road.road import RoadNetwork

from aldm_gym.roads.position import LanePosition, Pose
from aldm_gym.types import FloatArray

__all__ = ["MarkedRoad", "Road"]


@runtime_checkable
class MarkedRoad(Protocol):
    """Painted markings in the world frame, as the line sensor measures them.

    Markings are rows of :attr:`marking_table` (type, colour, width, height, dash
    pattern per marking); :meth:`sample_visible` says where each marking near a sensor
    crosses its x grid.
    """

    @property
    def marking_model(self) -> str:
        """``"per_dash"`` (every dash a line object) or ``"editor"`` (a dashed line one
        object): how markings become the sensor's line objects."""
        ...

    @property
    def marking_table(self) -> Mapping[str, np.ndarray]:
        """Per marking: ``type``, ``colour``, ``width`` [m], ``height`` [m], and the
        dash pattern (``phase``, ``period``, ``dash`` [m], ``broken``, ``paint``,
        ``paint_start``) the sensor cuts line objects with."""
        ...

    @property
    def overpass_lines(self) -> FloatArray:
        """Markings of bridges crossing above the road, ``(B, 5)`` rows (may be empty)."""
        ...

    def sample_visible(
        self, origin: FloatArray, yaw: float, xs: FloatArray, s_origin: float | None = None
    ) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """Where the markings near a planar sensor frame cross its lines ``x = xs``.

        :param origin: the frame's world origin ``(2,)`` [m].
        :param yaw: world heading of its x axis [rad].
        :param xs: ``(K,)`` increasing x [m].
        :param s_origin: the origin's arc length along the road, if known [m].
        :return: ``(rows, y, u)``: the marking rows sampled, their lateral position
            ``(len(rows), K)`` [m] (y left, NaN where a marking does not reach that x)
            and their arc length along the marking [m].
        """
        ...

    def with_marking_model(self, marking_model: str) -> MarkedRoad:
        """The same paint with the other marking model."""
        ...


@runtime_checkable
class Road(MarkedRoad, Protocol):
    """A marked road with lanes: what the env, ground truth and evaluations ask."""

    @property
    def network(self) -> RoadNetwork:
        """highway-env's lane network the traffic drives on."""
        ...

    @property
    def lane_width(self) -> float:
        """A typical lane width [m] (a generated road's; a map's median)."""
        ...

    def lane_position(self, position: FloatArray, heading: float | None = None) -> LanePosition:
        """Ground truth of a world position ``(2,)`` [m]; with a vehicle's ``heading``
        [rad], on the lanes that run its way (a map's oncoming lanes do not count).

        :raises InputError: the position is not 2 finite numbers.
        :raises OffRoadError: it lies on no lane (off a map's lanes).
        """
        ...

    def sample_markings(
        self, origin: FloatArray, yaw: float, xs: FloatArray, s_origin: float | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`sample_visible` for every marking: ``(y, u)``, each
        ``(n_markings, K)`` [m]."""
        ...

    def boundary_markings(self, lane_id: Any, position: FloatArray | None = None) -> Any:
        """The markings that bound lane ``lane_id`` (and its neighbours) near
        ``position``: the ground truth the detectors are scored against
        (:func:`aldm_gym.sensor.ground_truth.line_markings`)."""
        ...

    def lateral_offsets(self, xy: FloatArray, pos: LanePosition) -> FloatArray:
        """Lateral position [m] (> 0 left) of world points ``xy`` ``(N, 2)`` relative to
        the centre of the lane at ``pos``; ``inf`` for a point on no lane."""
        ...

    def ends_within(self, pos: LanePosition, distance: float) -> bool:
        """Whether the road ahead of ``pos`` ends within ``distance`` [m]."""
        ...

    def lane_ends_in(self, pos: LanePosition) -> float | None:
        """Distance [m] to the end of the lane at ``pos`` when it ends before the road
        does (``inf`` when it does not), or ``None`` on a road whose lanes never end."""
        ...

    def lane_narrows_in(self, pos: LanePosition, width: float, closing: float = 0.0) -> float:
        """Distance [m] along the lane from ``pos`` to where it gets narrower than
        ``min(width, its widest − closing)`` before it ends (its taper); ``inf`` on a
        road whose lanes never end."""
        ...

    def lane_end_side(self, pos: LanePosition) -> int:
        """Where to leave the lane at ``pos`` before it ends: +1 by the left neighbour,
        -1 by the right one (the one whose lane chain reaches farther), 0 when the lane
        does not end or neither neighbour goes on."""
        ...

    def sample_poses(
        self,
        n: int,
        rng: np.random.Generator,
        max_shift: float = 0.875,
        heading_jitter: float = 0.01,
        margin: float = 250.0,
    ) -> list[Pose]:
        """``n`` seeded vehicle poses on the road's lanes (uniform along the lanes, a
        lateral shift within the lane, heading jitter).

        :param max_shift: largest lateral shift from the lane centre [m].
        :param heading_jitter: standard deviation of the heading error [rad].
        :param margin: distance kept from the road's ends [m] (generated roads).
        """
        ...
