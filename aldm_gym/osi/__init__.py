"""ASAM OSI in and out: the line sensor and its detectors as an OSI sensor model.

* **Out**: the env writes, per step, an ``osi3.SensorView`` (ground truth: the host and
  the vehicles around it, the lane boundaries in view with their dash states, the host's
  lanes) and an ``osi3.SensorData`` (the detector's lines as ``DetectedLaneBoundary``)
  to an OSI trace (``config={"osi": {"trace": "run.mcap"}}``, :class:`OsiConfig`).
* **In**: :class:`ViewReader` turns a ``SensorView`` or ``GroundTruth`` into the
  CarMaker line sensor's frame; :class:`OsiLaneSensor` adds a detector and answers
  with a ``SensorData``; :func:`detect_trace` does it over a trace file
  (``aldm-gym osi detect``).

The messages are the official bindings' (``osi-python``), trace files go through
``asam-osi-utilities``: both are the ``[osi]`` extra (imported on first use, a clear
error without them). Field mapping, frames and ids: ``docs/osi.md``.
"""

from __future__ import annotations

from aldm_gym.osi.boundaries import BoundarySample, painted_intervals, sample_boundaries
from aldm_gym.osi.detect import TRACE_DETECTORS, DetectSummary, OsiLaneSensor, detect_trace
from aldm_gym.osi.messages import line_objects, sensor_data, sensor_view
from aldm_gym.osi.reader import HostPose, ViewReader
from aldm_gym.osi.settings import OsiConfig
from aldm_gym.osi.trace import TraceWriter, read_messages

__all__ = [
    "TRACE_DETECTORS",
    "BoundarySample",
    "DetectSummary",
    "HostPose",
    "OsiConfig",
    "OsiLaneSensor",
    "TraceWriter",
    "ViewReader",
    "detect_trace",
    "line_objects",
    "painted_intervals",
    "read_messages",
    "sample_boundaries",
    "sensor_data",
    "sensor_view",
]
