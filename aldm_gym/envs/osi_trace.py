"""The env's OSI trace (``config["osi"]``): each step as SensorView and SensorData.

:class:`OsiRecorder` opens one trace per episode (:meth:`OsiConfig.episode_path
<aldm_gym.osi.OsiConfig.episode_path>`), writes a message pair at reset and after each
env step (``every="step"``) or each simulation step (``every="frame"``), and closes the
file at the next reset or when the env closes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from aldm_gym.osi.boundaries import sample_boundaries
from aldm_gym.osi.messages import BOUNDARY_ID, LANE_ID, sensor_data, sensor_view
from aldm_gym.osi.settings import OsiConfig
from aldm_gym.osi.trace import TraceWriter

__all__ = ["OsiRecorder"]

BEHIND = 10.0
"""The ground truth written reaches this far behind the sensor [m]."""


class OsiRecorder:
    """Writes an episode's sensor frames as OSI messages.

    :param settings: the env's ``osi`` section.
    """

    def __init__(self, settings: OsiConfig) -> None:
        self.settings = settings
        self.episode = -1
        self.writer: TraceWriter | None = None
        self.cycle = 0
        self._lanes: dict[Any, int] = {}
        self._vehicles: dict[int, tuple[Any, int]] = {}

    def start(self) -> None:
        """A new episode: close the last trace, open the next. An episode that ended
        at its reset (highway-env resets once when the env is made) is overwritten."""
        empty = self.writer is not None and self.cycle <= 1
        self.close()
        if not empty:
            self.episode += 1
        self.cycle = 0
        self._vehicles = {}
        self.writer = TraceWriter(self.settings.episode_path(self.episode))

    def record(self, env: Any) -> None:
        """Write the env's current sensor frame and detection."""
        if self.writer is None:
            return
        perception, road = env.perception, env.highway
        frame, det = perception.frame, perception.detection
        t = frame.timestamp
        config = perception.sensor.config
        # the sensor's own grid (a reader with the same sensor meets the same vertices),
        # and at its spacing back to BEHIND behind the sensor (the host's surroundings)
        steps = math.ceil((config.fov_start + BEHIND) / config.dx)
        back = config.fov_start - config.dx * np.arange(steps, 0, -1)
        xs = np.concatenate([back, config.x_grid])
        boundaries = sample_boundaries(road, frame.origin, frame.yaw, xs)
        lane = env.lane_position.lane
        lines = road.boundary_markings(lane, frame.origin)
        ego = env.vehicle
        view = sensor_view(
            t=t,
            vehicles=env.road.vehicles,
            host=ego,
            frame=frame,
            boundaries=boundaries,
            table=road.marking_table,
            lines=lines,
            lane_ids={name: self._lane_id(key) for name, key in _lane_keys(lane).items()},
            ids=[self._vehicle_number(v) for v in env.road.vehicles],
            map_header=getattr(getattr(road, "map", None), "header", None),
        )
        ids = range(BOUNDARY_ID, BOUNDARY_ID + len(road.marking_table["type"]))
        data = sensor_data(
            t=t, host=ego, frame=frame, detection=det, boundary_ids=ids, cycle=self.cycle
        )
        self.writer.write(view)
        self.writer.write(data)
        self.cycle += 1

    def _vehicle_number(self, vehicle: Any) -> int:
        """A vehicle's number for the episode: the next free one when it is first seen
        (its index in the traffic while no vehicle has left), kept while it is away (a
        scenario's deleted entity added back is the same object)."""
        entry = self._vehicles.get(id(vehicle))  # holding the vehicle keeps its id(·) unique
        if entry is None:
            entry = (vehicle, len(self._vehicles))
            self._vehicles[id(vehicle)] = entry
        return entry[1]

    def _lane_id(self, key: Any) -> int:
        """A lane's OSI id: ``LANE_ID`` + a generated road's lane id; on a map the next
        free number for each lane key (highway-env's ``(from, to, index)``), kept for
        the env's life."""
        if isinstance(key, int | np.integer):
            return LANE_ID + int(key)
        if key not in self._lanes:
            self._lanes[key] = LANE_ID + len(self._lanes)
        return self._lanes[key]

    def close(self) -> None:
        """Finish the current trace (if any)."""
        if self.writer is not None:
            self.writer.close()
            self.writer = None


def _lane_keys(lane: Any) -> dict[str, Any]:
    """The host lane's key and its neighbours' (highway-env numbers lanes from the
    left: index − 1 is the lane to the left)."""
    if isinstance(lane, int | np.integer):
        return {"host": int(lane), "left": int(lane) - 1, "right": int(lane) + 1}
    a, b, i = lane
    return {"host": lane, "left": (a, b, i - 1), "right": (a, b, i + 1)}
