"""The env's OSI trace (``config["osi"]``): each step as SensorView and SensorData.

:class:`OsiRecorder` opens one trace per episode (:meth:`OsiConfig.episode_path
<aldm_gym.osi.OsiConfig.episode_path>`), writes a message pair at reset and after each
env step (``every="step"``) or each simulation step (``every="frame"``), and closes the
file at the next reset or when the env closes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aldm_gym.osi.boundaries import sample_boundaries
from aldm_gym.osi.messages import BOUNDARY_ID, sensor_data, sensor_view
from aldm_gym.osi.settings import OsiConfig
from aldm_gym.osi.trace import TraceWriter

__all__ = ["OsiRecorder"]


class OsiRecorder:
    """Writes an episode's sensor frames as OSI messages.

    :param settings: the env's ``osi`` section.
    """

    def __init__(self, settings: OsiConfig) -> None:
        self.settings = settings
        self.episode = -1
        self.writer: TraceWriter | None = None
        self.cycle = 0

    def start(self) -> None:
        """A new episode: close the last trace, open the next. An episode that ended
        at its reset (highway-env resets once when the env is made) is overwritten."""
        empty = self.writer is not None and self.cycle <= 1
        self.close()
        if not empty:
            self.episode += 1
        self.cycle = 0
        self.writer = TraceWriter(self.settings.episode_path(self.episode))

    def record(self, env: Any) -> None:
        """Write the env's current sensor frame and detection."""
        if self.writer is None:
            return
        perception, road = env.perception, env.highway
        frame, det = perception.frame, perception.detection
        t = frame.timestamp
        # the sensor's own grid: where else a road is sampled can change how far it
        # follows a marking that bends away
        xs = perception.sensor.config.x_grid
        boundaries = sample_boundaries(road, frame.origin, frame.yaw, xs)
        lane = env.lane_position.lane
        lines = road.boundary_markings(lane, frame.origin)
        vehicles = env.road.vehicles
        ego = env.vehicle
        view = sensor_view(
            t=t,
            vehicles=vehicles,
            host=ego,
            frame=frame,
            boundaries=boundaries,
            table=road.marking_table,
            lines=lines,
            lane_index=_lane_index(lane),
        )
        ids = range(BOUNDARY_ID, BOUNDARY_ID + len(road.marking_table["type"]))
        data = sensor_data(
            t=t, host=ego, frame=frame, detection=det, boundary_ids=ids, cycle=self.cycle
        )
        self.writer.write(view)
        self.writer.write(data)
        self.cycle += 1

    def close(self) -> None:
        """Finish the current trace (if any)."""
        if self.writer is not None:
            self.writer.close()
            self.writer = None


def _lane_index(lane: Any) -> int | None:
    """An integer lane index of a lane id (a generated road's int; a map's last field)."""
    if isinstance(lane, int | np.integer):
        return int(lane)
    if isinstance(lane, tuple) and lane and isinstance(lane[-1], int | np.integer):
        return int(lane[-1])
    return None
