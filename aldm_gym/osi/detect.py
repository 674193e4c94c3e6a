"""The line sensor and a detector behind any OSI-speaking simulator.

:class:`OsiLaneSensor` is the sensor model as a function of one message:
``SensorView`` (or ``GroundTruth``) in, ``SensorData`` out, with its state (the
tracker, the odometry) carried between calls. An OSMP (FMI) wrapper calls
:meth:`OsiLaneSensor.step` from its ``doStep`` with the decoded input and encodes the
result; :func:`detect_trace` runs it over a trace file (``aldm-gym osi detect``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aldm_gym.errors import ConfigError, TraceError
from aldm_gym.osi.messages import sensor_data
from aldm_gym.osi.reader import ViewReader
from aldm_gym.osi.trace import TraceWriter, read_messages
from aldm_gym.sensor.detectors import DETECTORS, Detector, make_detector
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection
from aldm_gym.sensor.line_sensor import LineSensorConfig
from aldm_gym.sensor.tracking import odometry

__all__ = ["TRACE_DETECTORS", "DetectSummary", "OsiLaneSensor", "detect_trace"]

TRACE_DETECTORS = tuple(d for d in DETECTORS if d != "ground_truth")
"""Detectors that work on a trace (``ground_truth`` needs the road's lanes)."""


class OsiLaneSensor:
    """The line sensor plus a detector, on OSI messages.

    :param detector: ``"aldm"`` (default) or ``"naive"``; ``detector_params`` as the
        env's (``{"tracking": True}`` for the tracking ALDM).
    :param marking_model: ``"per_dash"`` or ``"editor"`` (:class:`ViewReader`).
    :param sensor: the line sensor's settings.
    :param source: a name for error messages (the trace file).
    :param seed: seed of a noisy sensor's draws (per frame: :class:`ViewReader`).
    :raises ConfigError: an unknown detector, ``ground_truth``, or a seed that is not an
        integer >= 0.
    """

    def __init__(
        self,
        detector: str = "aldm",
        detector_params: Mapping[str, Any] | None = None,
        marking_model: str = "per_dash",
        sensor: LineSensorConfig | Mapping[str, Any] | None = None,
        source: str = "<message>",
        seed: int = 0,
    ) -> None:
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ConfigError(f"seed must be an integer >= 0, got {seed!r}")
        if detector == "ground_truth":
            raise ConfigError(
                "detector 'ground_truth' needs the road's lanes, which an OSI trace does not "
                f"give the line sensor; allowed: {list(TRACE_DETECTORS)}"
            )
        self.detector: Detector = make_detector(detector, detector_params)
        self.reader = ViewReader(sensor, marking_model, source, seed=seed)
        self.frame: SensorFrame | None = None
        """The line sensor's frame of the last message."""
        self.detection: LaneDetection | None = None
        """The detection of the last message."""
        self._last: tuple[float, float, float] | None = None
        self._last_t: float | None = None
        self._cycle = 0

    def step(self, message: Any, index: int | None = None) -> Any:
        """One ``osi3.SensorData`` from one ``SensorView`` or ``GroundTruth``.

        The tracker's motion comes from the host's poses and the messages' time stamps.

        :param index: the message's frame number (errors, the lane boundary header's
            ``cycle_counter``; default: the last one + 1).
        :raises TraceError: a message that cannot be used (:meth:`ViewReader.frame`).
        """
        reader = self.reader
        if index is not None:
            self._cycle = index
        frame = self.frame = reader.frame(message, self._cycle)
        pose = reader.odometry_pose()
        t = frame.timestamp
        last_t, self._last_t = self._last_t, t
        last, self._last = self._last, pose
        motion = None if last_t is None else odometry(last, pose, t - last_t)
        road = reader.road
        assert road is not None
        det = self.detection = self.detector(frame, road, None, motion=motion)
        sd = sensor_data(
            t=t,
            host=reader.host_base,
            frame=frame,
            detection=det,
            boundary_ids=reader.boundary_ids,
            cycle=self._cycle,
            mounting=reader.mounting,
            sensor_id=reader.sensor_id,
        )
        self._cycle += 1
        return sd


@dataclass(frozen=True)
class DetectSummary:
    """What :func:`detect_trace` did.

    :ivar frames: messages read and detected.
    :ivar found: per line name, the share of frames in which the line was found.
    :ivar out: the SensorData trace written.
    """

    frames: int
    found: dict[str, float]
    out: Path


def _ground_truth(message: Any) -> Any:
    return message.global_ground_truth if message.DESCRIPTOR.name == "SensorView" else message


def _frames(
    model: OsiLaneSensor,
    messages: Iterable[tuple[int, Any]],
    found: dict[str, int],
    part: int = 0,
    parts: int = 1,
) -> Iterator[tuple[int, Any]]:
    """``(index, SensorData)`` of the frames ``index % parts == part``, counting the
    lines found into ``found``. Skipped frames still hand their lane boundaries on
    (static ground truth sent once)."""
    static: Any = None
    for index, message in messages:
        if index % parts != part:
            if len(_ground_truth(message).lane_boundary):
                static = message
            continue
        if static is not None and not len(_ground_truth(message).lane_boundary):
            model.reader.frame(static, index)  # the boundaries this frame reuses
        static = None
        data = model.step(message, index)
        det = model.detection
        assert det is not None
        for name in LINE_NAMES:
            found[name] += int(det.found(name))
        yield index, data


def _detect_part(
    path: str, settings: dict[str, Any], part: int, parts: int
) -> tuple[list[tuple[int, bytes]], dict[str, int]]:
    """Frames ``index % parts == part`` of a trace (:func:`_frames`) in a worker:
    ``(index, SensorData bytes)`` and the found-line counts."""
    message_type, topic = settings.pop("message_type"), settings.pop("topic")
    model = OsiLaneSensor(**settings, source=path)
    found = dict.fromkeys(LINE_NAMES, 0)
    messages = read_messages(path, message_type, topic)
    out = [(i, sd.SerializeToString()) for i, sd in _frames(model, messages, found, part, parts)]
    return out, found


def detect_trace(
    path: str | Path,
    out: str | Path,
    *,
    detector: str = "aldm",
    detector_params: Mapping[str, Any] | None = None,
    marking_model: str = "per_dash",
    sensor: LineSensorConfig | Mapping[str, Any] | None = None,
    message_type: str | None = None,
    topic: str | None = None,
    jobs: int = 1,
    progress: Callable[[int], Any] | None = None,
    seed: int = 0,
) -> DetectSummary:
    """Run the line sensor and a detector over a trace: one ``SensorData`` per frame.

    :param path: the input trace (``.mcap`` or ``.osi``) of SensorView or GroundTruth
        (``message_type``, ``topic``: :func:`~aldm_gym.osi.trace.read_messages`).
    :param out: the output trace (``.mcap`` or ``.osi``) of SensorData.
    :param jobs: processes; frames are dealt out in turn, so only a detector without
        state between frames can take more than one (not the tracking ALDM).
    :param progress: called with the number of frames done (a progress bar's
        ``update``): after each frame, or with ``jobs > 1`` when a process ends.
    :param seed: seed of a noisy sensor's draws; frame ``i`` draws from
        ``[seed, i]``, so any ``jobs`` gives the same trace.
    :raises TraceError: naming the file and frame of a message that cannot be used.
    :raises ConfigError: ``jobs > 1`` with the tracking ALDM, or ``jobs < 1``.
    """
    if not isinstance(jobs, int) or jobs < 1:
        raise ConfigError(f"jobs must be an integer >= 1, got {jobs!r}")
    if jobs > 1 and (detector_params or {}).get("tracking"):
        raise ConfigError(
            "the tracking ALDM carries its lanes from frame to frame: it runs in one "
            "process (jobs=1)"
        )
    model = OsiLaneSensor(
        detector, detector_params, marking_model, sensor, source=str(path), seed=seed
    )
    found = dict.fromkeys(LINE_NAMES, 0)
    n = 0
    with TraceWriter(out, ("SensorData",), description=f"aldm-gym {detector}") as writer:
        if jobs == 1:
            for _, data in _frames(model, read_messages(path, message_type, topic), found):
                writer.write(data)
                n += 1
                if progress is not None:
                    progress(1)
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            from aldm_gym.osi._bindings import osi3

            settings = {
                "detector": detector,
                "detector_params": dict(detector_params or {}),
                "marking_model": marking_model,
                "sensor": model.reader.config,
                "message_type": message_type,
                "topic": topic,
                "seed": seed,
            }
            # fork: the workers start with the compiled kernels already loaded
            ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
            with ProcessPoolExecutor(jobs, mp_context=ctx) as pool:
                futures = [
                    pool.submit(_detect_part, str(path), dict(settings), k, jobs)
                    for k in range(jobs)
                ]
                parts = [f.result() for f in futures]
            rows = sorted((row for part, _ in parts for row in part), key=lambda r: r[0])
            for _, data in rows:
                sd = osi3.SensorData()
                sd.ParseFromString(data)
                writer.write(sd)
            for _, counts in parts:
                for name in LINE_NAMES:
                    found[name] += counts[name]
            n = len(rows)
            if progress is not None:
                progress(n)
    if n == 0:
        raise TraceError(f"{path}: no frames (an empty trace, or one that cannot be decoded)")
    share = {k: v / n for k, v in found.items()}
    return DetectSummary(n, share, Path(out))
