"""Compile every numba kernel of the package once, before any real work.

The kernels are compiled on first use and cached on disk (``numba.njit(cache=True)``),
so the first run after an install pays the compile (about half a minute to a minute
on 2 cores) and later runs load machine code in well under a second. ``make demo`` and
``make test`` run this module right after installing, so no progress bar and no test
worker includes the compile, and two test workers do not compile the same kernels at
once.

numba compiles in one thread per process, and the robust ALDM alone takes over half
of the time. With two or more CPUs the warm-up therefore compiles in two processes:
a helper process takes the kernels the robust ALDM does not use (the sensor, paper
mode, the naive detector, the traffic, the env with the naive and ground-truth
detectors, the camera preset's conditions and a shipped OpenDRIVE map) while this
process compiles the robust ALDM and then the tracking ALDM; then this process runs
everything once more, now from the cache, and steps the env with the ALDM, with the
tracking ALDM under the camera preset and on a map (the documented examples). Both
write the same on-disk cache (numba replaces its index files atomically; a kernel both
happen to need is compiled twice, not corrupted).

With ``--store`` the same warm-up runs in child processes that compile for a generic
x86-64 CPU into the package's shipped kernels (:data:`aldm_gym._numba.STORE`, emptied
first, then its manifest), which every later process on any x86-64 CPU loads when
numba's cache misses (docs/reliability.md, "Shipped kernels"); it does nothing when
they match this install. Every Makefile setup runs it.

Run: ``python -m aldm_gym.warmup [--serial] [--store]`` (prints what it did and how
long it took).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time


def _robust_aldm() -> None:
    """The robust ALDM, on synthetic points (four straight markings, 3.75 m lanes) so
    that this process compiles nothing else."""
    import numpy as np

    from aldm_gym.sensor import detect_lanes

    x = np.arange(0.0, 150.0, 0.5)
    y = (1.5, 0.5, -0.5, -1.5)
    points = np.concatenate([np.column_stack([x, np.full_like(x, 3.75 * c)]) for c in y])
    detect_lanes(points, mode="robust")


def _tracking() -> None:
    """The tracking ALDM (``detector_params={"tracking": True}``) on the same synthetic
    points, three frames, and the lane-model filter, two, so their kernels compile
    beside the robust ALDM's."""
    import numpy as np

    from aldm_gym.sensor.tracking import EgoMotion, LaneTracker

    x = np.arange(0.0, 150.0, 0.5)
    lines = [np.column_stack([x, np.full_like(x, 3.75 * c)]) for c in (1.5, 0.5, -0.5, -1.5)]
    every = np.concatenate(lines)
    tracker = LaneTracker()
    for k in range(3):
        points = every[(every[:, 0] < 40.0 + 10.0 * k) | (every[:, 0] > 70.0 + 10.0 * k)]
        tracker.update(points, None if k == 0 else EgoMotion(25.0, 0.0, 0.1))
    # the lane-model filter's update kernel (``{"tracking": "model"}``)
    from aldm_gym.sensor.lane_filter import LaneModelFilter

    model = LaneModelFilter()
    for k in range(2):
        model.update(every, None if k == 0 else EgoMotion(25.0, 0.0, 0.1))


def _the_rest() -> None:
    """Every kernel the robust ALDM does not use: the sensor with noise on a generated
    and a polyline road, paper mode, the naive detector, the OSI point decoder, the env
    (traffic, observation, ACC) with the naive and ground-truth detectors, the camera
    preset and a map."""
    import numpy as np

    import aldm_gym  # noqa: F401  (registers the env)
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.roads.polyline import MarkingCurve, PolylineRoad
    from aldm_gym.sensor import LineSensor, detect_lanes, naive_detect

    road = HighwayRoad({"seed": 0, "length": 1000.0})
    pose = (*road.reference.position(500.0, road.lane_offset(1)), road.reference.heading_at(500.0))
    sensor = LineSensor({"lateral_noise": 0.05, "dropout": 0.1}, seed=0)
    frame = sensor.measure(road, tuple(float(v) for v in pose))
    detect_lanes(frame, mode="paper")
    naive_detect(frame)
    xy = np.column_stack([np.arange(0.0, 300.0, 1.0), np.zeros(300)])
    poly = PolylineRoad([MarkingCurve(xy, np.array([[0.0, 6.0], [18.0, 24.0]]))])
    LineSensor().measure(poly, (10.0, 0.0, 0.0))
    from aldm_gym.osi.boundaries import _curve, _run_points
    from aldm_gym.osi.wire import decode_points, encode_points

    _run_points(np.arange(3.0), np.zeros(3), np.arange(3.0), np.array([[0.5, 1.5]]))

    rows = decode_points(encode_points(2, np.arange(3.0), np.zeros(3), np.full(3, 3)))
    _curve(rows, False, False, 0.15, 1e-3, np.empty((5, 2)), np.empty(5), np.empty((4, 2)))
    _env_steps(_HELPER_ENVS)


_HELPER_ENVS: tuple[dict, ...] = (
    {"detector": "naive", "vehicles_count": 5},
    {"detector": "ground_truth", "vehicles_count": 5},
    {"detector": "naive", "vehicles_count": 5, "sensor": {"preset": "camera"}},
    {"detector": "naive", "vehicles_count": 5, "road": {"xodr": "motorway"}},
)
"""Envs the helper runs, with detectors that compile nothing the robust ALDM's process
does: the naive and the ground-truth detector, and with the naive one the documented
examples, the camera preset (occlusion, wear, noise, clutter) and a shipped map
(``"motorway"`` stands for its path)."""

_FINAL_ENVS: tuple[dict, ...] = (
    {"detector": "aldm", "vehicles_count": 5},
    {
        "detector": "aldm",
        "detector_params": {"tracking": True},
        "vehicles_count": 5,
        "sensor": {"preset": "camera"},
    },
    {"detector": "aldm", "vehicles_count": 5, "road": {"xodr": "motorway"}},
)
"""Envs the final pass runs: the default, the tracking ALDM under the camera preset,
and the ALDM on a shipped map."""


def _env_steps(configs: tuple[dict, ...]) -> int:
    """``gym.make`` + ``reset`` + one ``step`` of each config; the simulation steps the
    compiled traffic engine ran (its kernels compile on every CPU)."""
    import gymnasium as gym

    from aldm_gym.envs.traffic.compiled import COMPILED
    from aldm_gym.roads import shipped_map

    compiled = 0
    for config in configs:
        road = config.get("road")
        if road is not None:
            config = {**config, "road": {"xodr": str(shipped_map(road["xodr"]))}}
        env = gym.make("ALDMHighway-v0", config=config)
        env.reset(seed=0)
        env.step(1)
        engine = env.unwrapped.road.engine
        if engine is not None:
            compiled += engine.steps[COMPILED]
        env.close()
    return compiled


def warm_up(parallel: bool | None = None) -> float:
    """Run each kernel once on small inputs (both ALDM modes, the sensor with noise on a
    generated road and a polyline road, the trajectory fit, the env with each detector).

    :param parallel: compile in two processes (module docstring); ``None``: when the
        machine has two CPUs or more.
    :return: the wall time it took [s].
    """
    import aldm_gym  # noqa: F401  (registers the env)
    from aldm_gym._numba import notice_given

    if parallel is None:
        parallel = (os.cpu_count() or 1) >= 2
    start = time.perf_counter()
    helper = None
    if parallel:
        helper = subprocess.Popen(
            [sys.executable, "-c", "from aldm_gym.warmup import _the_rest; _the_rest()"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,  # its errors surface in the serial pass below
        )
    with notice_given():  # the warm-up says itself that it compiles
        try:
            _robust_aldm()
            _tracking()
        finally:
            if helper is not None:
                helper.wait()  # its failure is not fatal: the serial pass compiles it
        _the_rest()  # from the cache when the helper ran
        _env_steps(_FINAL_ENVS)
    return time.perf_counter() - start


def build_store(parallel: bool | None = None) -> float:
    """Compile the shipped kernels: the warm-up in a child process that compiles for a
    generic x86-64 CPU into :data:`aldm_gym._numba.STORE_BUILD`, then the manifest, then
    that folder replaces :data:`aldm_gym._numba.STORE`. A wheel built afterwards carries
    them (package data).

    The child runs with ``NUMBA_CPU_NAME=generic`` and Intel's SVML off (code that calls
    it would not load where it is missing), and without the settings that change the
    code numba makes (``NUMBA_CPU_FEATURES``, ``NUMBA_OPT``, ``NUMBA_BOUNDSCHECK``,
    ``NUMBA_DEBUGINFO``, ``NUMBA_DISABLE_JIT``).

    :param parallel: as :func:`warm_up`.
    :return: the wall time it took [s].
    :raise OSError: the package folder is not writable.
    :raise subprocess.CalledProcessError: the compile failed (the store is left as it
        was).
    """
    import json
    import shutil

    from aldm_gym._numba import MANIFEST, STORE, STORE_BUILD, STORE_ENV, store_manifest

    start = time.perf_counter()
    shutil.rmtree(STORE_BUILD, ignore_errors=True)
    STORE_BUILD.mkdir()
    env = {
        **os.environ,
        "NUMBA_CPU_NAME": "generic",
        "NUMBA_DISABLE_INTEL_SVML": "1",
        STORE_ENV: "build",
    }
    for name in (
        "NUMBA_CPU_FEATURES",
        "NUMBA_OPT",
        "NUMBA_BOUNDSCHECK",
        "NUMBA_DEBUGINFO",
        "NUMBA_DISABLE_JIT",
    ):
        env.pop(name, None)
    code = f"from aldm_gym.warmup import warm_up; warm_up(parallel={parallel!r})"
    try:
        subprocess.run([sys.executable, "-c", code], env=env, check=True)
        (STORE_BUILD / MANIFEST).write_text(json.dumps(store_manifest(), indent=1) + "\n")
        shutil.rmtree(STORE, ignore_errors=True)
        STORE_BUILD.rename(STORE)
    finally:
        shutil.rmtree(STORE_BUILD, ignore_errors=True)
    return time.perf_counter() - start


def main() -> None:
    """Warm up (or build the shipped kernels) with a one-line message before and after."""
    from aldm_gym._numba import store_status

    parser = argparse.ArgumentParser(prog="python -m aldm_gym.warmup", description=__doc__)
    parser.add_argument(
        "--serial", action="store_true", help="compile in this process only (no helper)"
    )
    parser.add_argument(
        "--store",
        action="store_true",
        help="compile the shipped kernels (generic x86-64, into the package folder) "
        "instead of this machine's numba cache; nothing to do when they are current",
    )
    args = parser.parse_args()
    parallel = False if args.serial else None
    if args.store:
        if store_status() == "current":
            print("aldm-gym: the shipped kernels are current", flush=True)
            return
        print("aldm-gym: compiling the shipped kernels (generic x86-64)...", flush=True)
        took = build_store(parallel)
    else:
        print(
            "aldm-gym: compiling the numba kernels (cached on disk; once per install)...",
            flush=True,
        )
        took = warm_up(parallel)
    print(f"aldm-gym: kernels ready in {took:.0f} s", file=sys.stdout, flush=True)


if __name__ == "__main__":
    main()
