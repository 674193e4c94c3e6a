"""The detector registry: every lane detector by name, behind one signature.

A detector turns a :class:`~aldm_gym.sensor.frame.SensorFrame` into a
:class:`~aldm_gym.sensor.detection.LaneDetection`. Everything that chooses a detector
by name — the environment's ``detector`` key, ``aldm-gym compare``/``train``
choices, the frame-level comparison — goes through :func:`make_detector`, so adding
a detector is one entry in :data:`REGISTRY`.

One signature for all: ``detector(frame, road, lane_id) -> LaneDetection``. Only
``ground_truth`` reads ``road`` and ``lane_id`` (the true lane); the others see the
frame alone. Detectors are small picklable objects (no closures), so an environment
holding one can be copied and pickled.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from aldm_gym.sensor.aldm import detect_lanes, make_params
from aldm_gym.sensor.detection import LaneDetection
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import ground_truth_detect
from aldm_gym.sensor.naive import naive_detect


class Detector(Protocol):
    """``(frame, road, true lane id) -> LaneDetection``; only ground truth uses the last two."""

    def __call__(self, frame: SensorFrame, road: Any, lane_id: int) -> LaneDetection:
        """Detect the lanes of one frame."""
        ...


@dataclass(frozen=True)
class ALDMDetector:
    """The ALDM (:func:`~aldm_gym.sensor.aldm.detect_lanes`) with fixed parameters.

    :ivar params: validated :class:`~aldm_gym.sensor.aldm.ALDMParams`.
    """

    params: Any

    def __call__(self, frame: SensorFrame, road: Any = None, lane_id: int = 0) -> LaneDetection:
        """Detect the lanes of ``frame`` (``road`` and ``lane_id`` unused)."""
        return detect_lanes(frame, self.params)


@dataclass(frozen=True)
class NaiveDetector:
    """CarMaker's default (:func:`~aldm_gym.sensor.naive.naive_detect`).

    :ivar lane_width: lane width for the one-line trajectory [m]; ``None`` takes the
        road's at each call.
    """

    lane_width: float | None = None

    def __call__(self, frame: SensorFrame, road: Any = None, lane_id: int = 0) -> LaneDetection:
        """Detect the lanes of ``frame`` (``lane_id`` unused)."""
        width = self.lane_width if self.lane_width is not None else road.lane_width
        return naive_detect(frame, lane_width=width)


@dataclass(frozen=True)
class GroundTruthDetector:
    """The true markings of the true lane (``ground_truth_detect``)."""

    def __call__(self, frame: SensorFrame, road: Any, lane_id: int) -> LaneDetection:
        """The true lines of lane ``lane_id`` of ``road`` in ``frame``'s sensor frame."""
        return ground_truth_detect(road, frame, lane_id)


def _make_aldm(params: Mapping[str, Any]) -> Detector:
    return ALDMDetector(make_params(None, **params))


def _make_naive(params: Mapping[str, Any]) -> Detector:
    return NaiveDetector(**params)


def _make_truth(params: Mapping[str, Any]) -> Detector:
    return GroundTruthDetector(**params)


@dataclass(frozen=True)
class DetectorEntry:
    """One registered detector.

    :ivar factory: builds the detector from its parameters (a mapping).
    :ivar description: one line for ``--help`` and the docs.
    :ivar params: names of the parameters it takes (``None``: the factory validates).
    """

    factory: Callable[[Mapping[str, Any]], Detector]
    description: str
    params: tuple[str, ...] | None = field(default=())


REGISTRY: dict[str, DetectorEntry] = {
    "naive": DetectorEntry(
        _make_naive, "CarMaker's default: the relevant line object per side", ("lane_width",)
    ),
    "aldm": DetectorEntry(
        _make_aldm, "the paper's Advanced Lane Detection Model (detect_lanes)", None
    ),
    "ground_truth": DetectorEntry(_make_truth, "the true markings: the upper bound"),
}
"""Every detector by name. The order is the order of tables and figures."""

DETECTORS: tuple[str, ...] = tuple(REGISTRY)
"""Names accepted by :func:`make_detector` (and the env's ``detector`` key)."""


def make_detector(name: str, params: Mapping[str, Any] | None = None) -> Detector:
    """The detector ``name`` (:data:`DETECTORS`) with ``params``.

    ``aldm`` takes :class:`~aldm_gym.sensor.aldm.ALDMParams` fields; ``naive`` takes
    ``lane_width``; ``ground_truth`` takes none.

    :raises ValueError: unknown name, or parameters the detector does not take (naming
        them and the allowed ones).
    """
    entry = REGISTRY.get(name) if isinstance(name, str) else None
    if entry is None:
        raise ValueError(f"unknown detector {name!r}; allowed: {list(DETECTORS)}")
    params = dict(params or {})
    if entry.params is not None:
        unknown = sorted(str(k) for k in params if k not in entry.params)
        if unknown:
            raise ValueError(
                f"detector {name!r} takes no parameter(s) {unknown}; allowed: {list(entry.params)}"
            )
    return entry.factory(params)
