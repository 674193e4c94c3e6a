"""The OSMP sensor-model FMU against ``aldm-gym osi detect``, per frame, in one process.

A trace of the default env (every frame) is written once and its SensorViews are kept
in memory as serialized bytes. Per round, each path detects every frame:

* **detect**: what ``osi detect`` does per frame without the file I/O: parse the
  SensorView, :class:`~aldm_gym.osi.detect.OsiLaneSensor` ``step``, serialize the
  SensorData;
* **fmu**: an OSMP host (fmpy) passes the same bytes by pointer to the FMU that
  ``aldm-gym osi fmu`` writes and reads its SensorData back (set three integers,
  ``fmi2DoStep``, get three integers and ``OSMPValid``, copy the buffer).

Rounds alternate which path goes first; the ratio of the medians is the FMU path's
cost. Usage::

    .venv/bin/python -m benchmarks.bench_osmp [--rounds 7] [--steps 30] [--tracking none]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
from pathlib import Path


def _trace(path: Path, steps: int) -> list[bytes]:
    import gymnasium as gym

    import aldm_gym  # noqa: F401
    from aldm_gym.osi import read_messages

    env = gym.make("ALDMHighway-v0", config={"osi": {"trace": str(path), "every": "frame"}})
    env.reset(seed=5)
    for _ in range(steps):
        env.step(1)
    env.close()
    return [m.SerializeToString() for _, m in read_messages(path, "SensorView")]


def _detect(views: list[bytes], tracking: str) -> float:
    from aldm_gym.osi import OsiLaneSensor
    from aldm_gym.osi._bindings import osi3
    from aldm_gym.osi.osmp import detector_params_for

    model = OsiLaneSensor(detector_params=detector_params_for(tracking))
    start = time.perf_counter()
    for i, raw in enumerate(views):
        sv = osi3.SensorView()
        sv.ParseFromString(raw)
        model.step(sv, i).SerializeToString()
    return (time.perf_counter() - start) / len(views)


def _fmu(host: object, views: list[bytes]) -> float:
    host.reset()  # type: ignore[attr-defined]
    start = time.perf_counter()
    for raw in views:
        host.step(raw)  # type: ignore[attr-defined]
    return (time.perf_counter() - start) / len(views)


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and print per-frame times and their ratio."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--steps", type=int, default=30, help="env steps (10 frames each)")
    parser.add_argument("--tracking", choices=("none", "points", "model"), default="none")
    args = parser.parse_args(argv)
    from aldm_gym.osi.osmp import OSMPHost, build_sensor_fmu

    with tempfile.TemporaryDirectory() as tmp:
        views = _trace(Path(tmp) / "run.mcap", args.steps)
        fmu = build_sensor_fmu(Path(tmp) / "sensor.fmu", tracking=args.tracking)
        host = OSMPHost(fmu)
        _detect(views[:20], args.tracking)  # kernels loaded
        _fmu(host, views[:20])
        detect, through_fmu = [], []
        for r in range(args.rounds):
            order = (0, 1) if r % 2 == 0 else (1, 0)
            for which in order:
                if which == 0:
                    detect.append(_detect(views, args.tracking))
                else:
                    through_fmu.append(_fmu(host, views))
        host.close()
    d, f = statistics.median(detect), statistics.median(through_fmu)
    print(
        f"{len(views)} frames, tracking {args.tracking}, {args.rounds} rounds; "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"Python {platform.python_version()}"
    )
    print(f"osi detect per frame: {1e3 * d:.3f} ms (median)")
    print(f"OSMP FMU per frame:   {1e3 * f:.3f} ms (median)")
    print(f"FMU / detect: {f / d:.3f}")


if __name__ == "__main__":
    main()
