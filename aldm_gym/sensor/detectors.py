"""The detector registry: every lane detector by name, behind one signature.

A detector turns a :class:`~aldm_gym.sensor.frame.SensorFrame` into a
:class:`~aldm_gym.sensor.lane_detection.LaneDetection`. Everything that chooses a detector
by name — the environment's ``detector`` key, ``aldm-gym compare``/``train``
choices, the frame-level comparison — goes through :func:`make_detector`, so adding
a detector is one entry in :data:`REGISTRY`.

One signature for all: ``detector(frame, road, lane_id, motion=None) -> LaneDetection``.
Only ``ground_truth`` reads ``road`` and ``lane_id`` (the true lane); the others see the
frame alone. ``motion`` (:class:`~aldm_gym.sensor.tracking.EgoMotion`, the sensor's
motion since the previous frame) is read only by the tracking ALDM
(``{"tracking": True}``) and the lane-model filter (``{"tracking": "model"}``), the
stateful detectors: a fresh detector from :func:`make_detector` has no tracks.
Detectors are small picklable objects (no closures), so an environment holding one
can be copied and pickled.

Every detector takes ``path_range``: its :attr:`LaneDetection.trajectory` fits each
ego line on its points with x <= ``path_range`` (at least 4 points), through the one
trajectory function :func:`~aldm_gym.sensor.trajectory.driving_trajectory`;
``None`` fits the whole line.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

from aldm_gym.errors import ConfigError
from aldm_gym.sensor.aldm import ALDMParams, detect_lanes
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import ground_truth_detect
from aldm_gym.sensor.lane_detection import LaneDetection
from aldm_gym.sensor.lane_filter import FilterParams, LaneModelFilter, split_aldm_params
from aldm_gym.sensor.naive import naive_detect
from aldm_gym.sensor.tracking import EgoMotion, LaneTracker
from aldm_gym.sensor.trajectory import fit_reach


class Detector(Protocol):
    """``(frame, road, true lane id, motion) -> LaneDetection``; only ground truth uses
    ``road`` and the lane id, only the tracking ALDM ``motion``.

    A detector with a false ``uses_motion`` attribute is called with ``motion=None``
    (the env skips the odometry); without the attribute it gets the motion.
    """

    def __call__(
        self, frame: SensorFrame, road: Any, lane_id: int, motion: EgoMotion | None = None
    ) -> LaneDetection:
        """Detect the lanes of one frame."""
        ...


@dataclass(frozen=True)
class ALDMDetector:
    """The ALDM (:func:`~aldm_gym.sensor.aldm.detect_lanes`) with fixed parameters.

    :ivar params: validated :class:`~aldm_gym.sensor.aldm.ALDMParams`.
    :ivar path_range: the trajectory's fit range [m] (``None``: whole lines).
    """

    uses_motion: ClassVar[bool] = False
    """It ignores ``motion`` (the env then does not compute it)."""

    params: Any
    path_range: float | None = None

    def __call__(
        self,
        frame: SensorFrame,
        road: Any = None,
        lane_id: int = 0,
        motion: EgoMotion | None = None,
    ) -> LaneDetection:
        """Detect the lanes of ``frame`` (``road``, ``lane_id`` and ``motion`` unused)."""
        return detect_lanes(frame, self.params, path_range=self.path_range)


class _StatefulDetector:
    """A detector that carries state from frame to frame in ``self.tracker`` (an
    object with ``update(frame, motion) -> LaneDetection``)."""

    uses_motion: ClassVar[bool] = True
    """It reads ``motion``."""

    tracker: Any

    def __call__(
        self,
        frame: SensorFrame,
        road: Any = None,
        lane_id: int = 0,
        motion: EgoMotion | None = None,
    ) -> LaneDetection:
        """Detect the lanes of ``frame`` with the state carried by ``motion`` (``None``:
        the state starts again from this frame)."""
        return self.tracker.update(frame, motion)


class TrackingALDMDetector(_StatefulDetector):
    """The tracking ALDM (:class:`~aldm_gym.sensor.tracking.LaneTracker`): stateful;
    the tracks, moved by ``motion``, are the prior of each frame's detection.

    :param params: validated :class:`~aldm_gym.sensor.aldm.ALDMParams`.
    :param tracker: validated :class:`~aldm_gym.sensor.tracking.TrackerParams`.
    :param path_range: the trajectory's fit range [m] (``None``: whole lines).
    """

    def __init__(self, params: Any, tracker: Any, path_range: float | None = None) -> None:
        self.tracker = LaneTracker(params, tracker, path_range=path_range)


class ModelALDMDetector(_StatefulDetector):
    """The lane-model filter (:class:`~aldm_gym.sensor.lane_filter.LaneModelFilter`):
    stateful; the model, carried by ``motion``, is updated with each frame. Its
    detections are :class:`~aldm_gym.sensor.lane_filter.ModelLaneDetection` (with a
    confidence per line).

    :param params: validated :class:`~aldm_gym.sensor.aldm.ALDMParams` (the frame that
        starts the model).
    :param filt: validated :class:`~aldm_gym.sensor.lane_filter.FilterParams`.
    :param path_range: the trajectory's fit range [m] (``None``: whole lines).
    """

    def __init__(
        self, params: ALDMParams, filt: FilterParams, path_range: float | None = None
    ) -> None:
        self.tracker = LaneModelFilter(params, filt, path_range=path_range)


@dataclass(frozen=True)
class NaiveDetector:
    """CarMaker's default (:func:`~aldm_gym.sensor.naive.naive_detect`).

    :ivar lane_width: lane width for the one-line trajectory [m]; ``None`` takes the
        road's at each call.
    :ivar path_range: the trajectory's fit range [m] (``None``: whole lines).
    """

    uses_motion: ClassVar[bool] = False
    """It ignores ``motion`` (the env then does not compute it)."""

    lane_width: float | None = None
    path_range: float | None = None

    def __call__(
        self,
        frame: SensorFrame,
        road: Any = None,
        lane_id: int = 0,
        motion: EgoMotion | None = None,
    ) -> LaneDetection:
        """Detect the lanes of ``frame`` (``lane_id`` and ``motion`` unused)."""
        width = self.lane_width if self.lane_width is not None else road.lane_width
        return naive_detect(frame, lane_width=width, path_range=self.path_range)


@dataclass(frozen=True)
class GroundTruthDetector:
    """The true markings of the true lane (``ground_truth_detect``).

    :ivar path_range: the trajectory's fit range [m] (``None``: whole lines).
    """

    uses_motion: ClassVar[bool] = False
    """It ignores ``motion`` (the env then does not compute it)."""

    path_range: float | None = None

    def __call__(
        self, frame: SensorFrame, road: Any, lane_id: int, motion: EgoMotion | None = None
    ) -> LaneDetection:
        """The true lines of lane ``lane_id`` of ``road`` in ``frame``'s sensor frame
        (``motion`` unused)."""
        return ground_truth_detect(road, frame, lane_id, path_range=self.path_range)


def _make_aldm(params: Mapping[str, Any], path_range: float | None) -> Detector:
    _, tracker, filt, aldm = split_aldm_params(dict(params))
    if filt is not None:
        return ModelALDMDetector(aldm, filt, path_range)
    if tracker is not None:
        return TrackingALDMDetector(aldm, tracker, path_range)
    return ALDMDetector(aldm, path_range)


def _make_naive(params: Mapping[str, Any], path_range: float | None) -> Detector:
    return NaiveDetector(**params, path_range=path_range)


def _make_truth(params: Mapping[str, Any], path_range: float | None) -> Detector:
    return GroundTruthDetector(**params, path_range=path_range)


@dataclass(frozen=True)
class DetectorEntry:
    """One registered detector.

    :ivar factory: builds the detector from its parameters (a mapping) and
        ``path_range``.
    :ivar description: one line for ``--help`` and the docs.
    :ivar params: names of the parameters it takes (``None``: the factory validates).
    """

    factory: Callable[[Mapping[str, Any], float | None], Detector]
    description: str
    params: tuple[str, ...] | None = field(default=())


REGISTRY: dict[str, DetectorEntry] = {
    "naive": DetectorEntry(
        _make_naive, "CarMaker's default: the relevant line object per side", ("lane_width",)
    ),
    "aldm": DetectorEntry(
        _make_aldm,
        "the Advanced Lane Detection Model (detect_lanes): the robust mode by default, "
        "the paper's algorithm as published with mode='paper'",
        None,
    ),
    "ground_truth": DetectorEntry(_make_truth, "the true markings: the upper bound"),
}
"""Every detector by name. The order is the order of tables and figures."""

DETECTORS: tuple[str, ...] = tuple(REGISTRY)
"""Names accepted by :func:`make_detector` (and the env's ``detector`` key)."""


def make_detector(
    name: str, params: Mapping[str, Any] | None = None, *, path_range: float | None = None
) -> Detector:
    """The detector ``name`` (:data:`DETECTORS`) with ``params``.

    ``aldm`` takes :class:`~aldm_gym.sensor.aldm.ALDMParams` fields,
    ``tracking=True`` with :class:`~aldm_gym.sensor.tracking.TrackerParams` fields for
    the tracking ALDM, and ``tracking="model"`` with
    :class:`~aldm_gym.sensor.lane_filter.FilterParams` fields for the lane-model filter;
    ``naive`` takes ``lane_width``; ``ground_truth`` takes none.

    :param path_range: every detector's trajectory fits each ego line on its points
        with x <= this (at least 4 points) [m]; ``None``: the whole line. With 80 it is
        the path the environment's lane keeping follows.
    :raises ConfigError: unknown name, parameters the detector does not take (naming
        them and the allowed ones), or ``path_range`` not > 0.
    """
    entry = REGISTRY.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ConfigError(f"unknown detector {name!r}; allowed: {list(DETECTORS)}")
    params = dict(params or {})
    if entry.params is not None:
        unknown = sorted(str(k) for k in params if k not in entry.params)
        if unknown:
            raise ConfigError(
                f"detector {name!r} takes no parameter(s) {unknown}; allowed: {list(entry.params)}"
            )
    fit_reach(path_range)  # validates
    return entry.factory(params, path_range)
