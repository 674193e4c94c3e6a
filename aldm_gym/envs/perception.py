"""What the ego perceives at each simulation step: the line sensor's frame, the lanes
the detector rebuilds from it, and the other vehicles (an ideal object sensor).

:class:`Perception` is one episode's sensing: the env builds one at every reset (a
fresh detector: the tracking ALDM starts without a prior) and calls :meth:`measure`,
:meth:`detect` and :meth:`sense_objects` at every simulation step. Nothing here reads
ground truth except the detector ``"ground_truth"`` itself (the upper bound).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from aldm_gym.envs.config import EnvConfig
from aldm_gym.envs.targets import Objects, objects_from_world
from aldm_gym.envs.traffic import FastRoad
from aldm_gym.envs.traffic import kernels as K
from aldm_gym.envs.traffic.vehicles import velocity
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.detectors import Detector, make_detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.sensor.line_sensor import LineSensor
from aldm_gym.sensor.tracking import EgoMotion, odometry

__all__ = ["Perception"]


class Perception:
    """The ego's sensing in one episode: line sensor, detector, objects, odometry.

    :param settings: the env's settings (``sensor``, ``detector``, ``detector_params``,
        ``simulation_frequency``).
    :param path_range: the detectors fit the trajectory up to this x [m] (``None``:
        whole lines).

    :ivar frame: the last sensor frame (``None`` before the first :meth:`measure`).
    :ivar detection: the last detection.
    :ivar objects: the other vehicles in the sensor frame at the last
        :meth:`sense_objects` (ids: their index in ``road.vehicles``).
    :ivar objects_xy: their world positions ``(N, 2)`` [m] (for ground truth).
    """

    def __init__(self, settings: EnvConfig, path_range: float | None) -> None:
        """Build the sensor and a fresh detector."""
        self.sensor = LineSensor(settings.sensor)
        self.detector: Detector = make_detector(
            settings.detector, dict(settings.detector_params), path_range=path_range
        )
        self.dt = 1.0 / settings.simulation_frequency
        self.frame: SensorFrame | None = None
        self.detection: LaneDetection | None = None
        self.objects = Objects()
        self.objects_xy = np.zeros((0, 2))
        self._motion = (np.zeros(0), np.zeros(0))  # speed [m/s], heading [rad]
        self._odometry: tuple[float, float, float] | None = None

    def measure(
        self,
        road: Road,
        ego: Any,
        t: float,
        s_hint: float | None,
        rng: np.random.Generator,
        vehicles: list[Any],
    ) -> SensorFrame:
        """One sensor frame from the ego's pose.

        :param t: time stamp [s].
        :param s_hint: the ego's arc length along the road [m] (the sensor adds its
            mount offset); ``None``: the sensor projects its own position.
        :param rng: draws the noise when the sensor is noisy (the env's generator).
        :param vehicles: every vehicle (occluders, when the sensor has occlusion on).
        """
        config = self.sensor.config
        self.frame = self.sensor.measure(
            road,
            (ego.position[0], ego.position[1], ego.heading),
            t,
            rng=rng if config.noisy else None,
            s_hint=None if s_hint is None else s_hint + config.mount_x,
            occluders=vehicles if config.occlusion else None,
        )
        return self.frame

    def detect(self, road: Road, lane: Any, ego: Any) -> LaneDetection:
        """The detector's lanes on the last frame (``lane``: the true lane, which only
        the ground-truth detector reads); handed to the ego, whose lateral control
        follows nothing else."""
        assert self.frame is not None
        detector = self.detector
        motion = self.ego_motion(ego) if getattr(detector, "uses_motion", True) else None
        self.detection = det = detector(self.frame, road, lane, motion=motion)
        ego.detection = det
        ego.frame = self.frame  # what a lane change may cross: the paint under the lines
        ego.trajectory = det.trajectory  # fitted up to lka.path_range by the detector
        ego.sensor_pose = (self.frame.origin, self.frame.yaw)  # the frame of both
        return det

    def ego_motion(self, ego: Any) -> EgoMotion | None:
        """The sensor's motion since the previous frame, as odometry would give it: the
        distance its mount point travelled and its heading change over the simulation
        step (the tracking ALDM's input); ``None`` at the first frame of an episode or
        after an implausible jump."""
        heading = float(ego.heading)
        origin, _ = self.sensor.world_pose((ego.position[0], ego.position[1], heading))
        pose = (float(origin[0]), float(origin[1]), heading)
        last, self._odometry = self._odometry, pose
        return odometry(last, pose, self.dt)

    @property
    def objects_velocity(self) -> np.ndarray:
        """The world velocities ``(N, 2)`` [m/s] of :attr:`objects` (for ground truth;
        computed when asked: the truth reads them once per policy step)."""
        speed, heading = self._motion
        return speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])

    def sense_objects(self, traffic: FastRoad, ego: Any) -> Objects:
        """The other vehicles in the sensor frame (ids: their index in
        ``traffic.vehicles``).

        Positions and velocities are exact (an ideal object sensor): the comparison is
        about the lanes, not about object detection. Right after a step of the compiled
        traffic engine its arrays hold these very values: no second gather.
        """
        frame = self.frame
        assert frame is not None
        vehicles = traffic.vehicles
        n = len(vehicles)
        ego_row = next((i for i, v in enumerate(vehicles) if v is ego), n)
        rows = [*range(ego_row), *range(ego_row + 1, n)]
        if not rows:
            self.objects = Objects()
            self.objects_xy = np.zeros((0, 2))
            self._motion = (np.zeros(0), np.zeros(0))
            return self.objects
        engine = traffic.engine
        state = engine.moved_state(traffic) if engine is not None else None
        if state is not None:
            table = state[1:].copy() if ego_row == 0 else state[rows]
            xy = self.objects_xy = table[:, K.F_X : K.F_Y + 1]
            speed, heading = table[:, K.F_SPEED], table[:, K.F_HEADING]
            width, length = table[:, K.F_WIDTH], table[:, K.F_LENGTH]
        else:
            others = [vehicles[i] for i in rows]
            xy = self.objects_xy = np.array([v.position for v in others], dtype=np.float64)
            speed = np.array([v.speed for v in others], dtype=np.float64)
            heading = np.array([v.heading for v in others], dtype=np.float64)
            width = np.array([v.WIDTH for v in others], dtype=np.float64)
            length = np.array([v.LENGTH for v in others], dtype=np.float64)
        self._motion = (speed, heading)
        self.objects = objects_from_world(
            np.array(rows, dtype=np.int64),
            xy,
            speed,
            heading,
            width,
            length,
            frame.origin,
            frame.yaw,
            velocity(ego),
        )
        return self.objects
