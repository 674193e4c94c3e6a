"""The lane network: :class:`FastRoadNetwork`, a faster closest-lane look-up.

``Vehicle.on_state_update`` looks up the closest lane of every vehicle at every
simulation step; highway-env's ``RoadNetwork`` evaluates every lane through numpy
scalar calls. Here plain ``StraightLane`` lanes are evaluated with the same IEEE
operations on Python floats.
"""

from __future__ import annotations

import numpy as np
from highway_env.road.lane import AbstractLane
from highway_env.road.road import LaneIndex, RoadNetwork

from aldm_gym.envs.traffic.straight_lanes import straight_geometry
from aldm_gym.errors import InputError

__all__ = ["FastRoadNetwork"]


class FastRoadNetwork(RoadNetwork):
    """A :class:`RoadNetwork` with a faster, result-identical ``get_closest_lane_index``.

    ``Vehicle.on_state_update`` calls ``get_closest_lane_index`` for every vehicle at
    every simulation step; the base version loops over all lanes through numpy scalar
    calls (~6 µs per lane). Here ``StraightLane`` lanes are evaluated with plain float
    arithmetic performing the same IEEE operations in the same order (two-term dot
    products, ``wrap_to_pi``'s ``%``), and the argmin keeps ``np.argmin``'s rules (first
    minimum; the first NaN wins). Other lane classes fall back to their own
    ``distance_with_heading``.

    The flat lane list is cached; it is rebuilt when :meth:`add_lane` is called or the
    graph's shape (edges and lane counts) changes.
    """

    def __init__(self) -> None:
        """Create an empty network."""
        super().__init__()
        self._flat: list[tuple[LaneIndex, AbstractLane, tuple[float, ...] | None]] | None = None
        self._flat_shape: tuple[int, ...] = ()

    @classmethod
    def from_network(cls, network: RoadNetwork) -> FastRoadNetwork:
        """Wrap an existing network, sharing its graph (lanes are not copied).

        :param network: any ``RoadNetwork``.
        :return: a ``FastRoadNetwork`` whose ``graph`` is ``network.graph``.
        """
        fast = cls()
        fast.graph = network.graph
        return fast

    def add_lane(self, _from: str, _to: str, lane: AbstractLane) -> None:
        """Add a lane (see ``RoadNetwork.add_lane``) and drop the flat lane cache."""
        super().add_lane(_from, _to, lane)
        self._flat = None

    def _graph_shape(self) -> tuple[int, ...]:
        """Cheap fingerprint of the graph's structure: lane count of every edge."""
        return tuple(len(lanes) for to in self.graph.values() for lanes in to.values())

    def _flat_lanes(self) -> list[tuple[LaneIndex, AbstractLane, tuple[float, ...] | None]]:
        """All lanes in the base iteration order, with StraightLane constants unpacked."""
        shape = self._graph_shape()
        if self._flat is None or shape != self._flat_shape:
            flat: list[tuple[LaneIndex, AbstractLane, tuple[float, ...] | None]] = []
            for _from, to_dict in self.graph.items():
                for _to, lanes in to_dict.items():
                    for _id, lane in enumerate(lanes):
                        flat.append(((_from, _to, _id), lane, straight_geometry(lane)))
            self._flat = flat
            self._flat_shape = shape
        return self._flat

    def get_closest_lane_index(
        self, position: np.ndarray, heading: float | None = None
    ) -> LaneIndex:
        """Index of the lane closest to a world position (same result as the base class).

        :param position: a world position ``(2,)`` [m].
        :param heading: a heading angle [rad], or None to ignore headings.
        :return: the index of the closest lane.
        """
        px, py = (float(c) for c in position[:2])
        two_pi = 2 * np.pi
        best_index: LaneIndex | None = None
        best = 0.0
        angle_of: dict[float, float] = {}
        for index, lane, consts in self._flat_lanes():
            if consts is None:
                d = float(lane.distance_with_heading(position, heading))
            else:
                sx, sy, d0, d1, l0, l1, length, lane_heading = consts
                # Same operations as StraightLane.local_coordinates: delta = p - start,
                # then two-term dot products (np.dot of length 2 is a*b + c*d).
                dx = px - sx
                dy = py - sy
                s = dx * d0 + dy * d1
                r = dx * l0 + dy * l1
                # max(x, 0) returns x unless 0 > x (NaN stays NaN).
                beyond = s - length
                before = 0 - s
                d = abs(r) + (0 if 0 > beyond else beyond) + (0 if 0 > before else before)
                if heading is not None:
                    # AbstractLane.local_angle -> utils.wrap_to_pi; Python's float % and
                    # numpy's remainder share the fmod-and-fix-sign definition. Parallel
                    # lanes share a heading, so the angle is computed once per heading.
                    angle = angle_of.get(lane_heading)
                    if angle is None:
                        angle = abs(((heading - lane_heading) + np.pi) % two_pi - np.pi)
                        angle_of[lane_heading] = angle
                    d = d + 1.0 * angle
            if d != d:  # np.argmin returns the first NaN
                return index
            if best_index is None or d < best:
                best_index = index
                best = d
        if best_index is None:
            raise InputError("get_closest_lane_index called on a network without lanes")
        return best_index
