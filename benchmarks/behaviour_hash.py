"""Fingerprints of the project's behaviour, to prove a refactoring changed nothing.

Three sha256 digests:

* ``env``: seeded ``ALDMHighway-v0`` rollouts (20 and 40 vehicles; IDLE and seeded
  mixed meta actions; the three detectors; both marking models; the continuous
  action; several episodes each) — every observation array, reward, termination flag
  and info value, floats hashed by their exact bits;
* ``detect``: ``detect_lanes`` (robust and paper mode), ``naive_detect`` and
  ``ground_truth_detect`` on a few hundred seeded sensor frames (clean and noisy,
  per-dash and editor, straight and curved roads) — the four lines, and separately
  the trajectories.

Run it before and after a change; equal digests mean bit-identical behaviour. The
digests are defined per kind of CPU: numpy's scalar math (and so the env's Python paths)
differs from libm's in last bits on AVX-512 CPUs, so compare digests printed under the
same first line (the functions that differ; docs/env.md, "The traffic engine").

Run: ``.venv/bin/python -m benchmarks.behaviour_hash [--quick]``
"""

from __future__ import annotations

import argparse
import hashlib
import math
from collections.abc import Mapping
from typing import Any

import numpy as np


def _feed(h: Any, value: Any) -> None:
    """Feed ``value`` into hash ``h``, exact for floats and arrays, order-stable for dicts."""
    if isinstance(value, Mapping):
        for key in sorted(value, key=str):
            h.update(f"<{key}>".encode())
            _feed(h, value[key])
    elif isinstance(value, np.ndarray):
        arr = np.ascontiguousarray(value)
        h.update(f"{arr.dtype.str}{arr.shape}".encode())
        h.update(arr.tobytes())
    elif isinstance(value, bool | np.bool_):
        h.update(b"T" if value else b"F")
    elif isinstance(value, float | np.floating):
        f = float(value)
        h.update(b"nan" if math.isnan(f) else f.hex().encode())
    elif isinstance(value, int | np.integer):
        h.update(str(int(value)).encode())
    elif isinstance(value, list | tuple):
        h.update(b"[")
        for v in value:
            _feed(h, v)
        h.update(b"]")
    elif value is None:
        h.update(b"None")
    else:
        h.update(repr(value).encode())


ENV_CASES: tuple[dict[str, Any], ...] = (
    {"vehicles_count": 20},
    {"vehicles_count": 40},
    {"vehicles_count": 20, "detector": "naive"},
    {"vehicles_count": 20, "detector": "ground_truth"},
    {"vehicles_count": 20, "marking_model": "editor", "detector": "naive"},
    {"vehicles_count": 20, "sensor": {"lateral_noise": 0.05, "dropout": 0.1}},
    {"vehicles_count": 20, "action": {"type": "ContinuousAction"}},
)


def env_digest(episodes: int, steps: int) -> str:
    """sha256 over seeded rollouts of every case in :data:`ENV_CASES`."""
    import gymnasium as gym

    import aldm_gym  # noqa: F401  (registers the env)

    h = hashlib.sha256()
    for ci, case in enumerate(ENV_CASES):
        env = gym.make("ALDMHighway-v0", config=case)
        continuous = case.get("action", {}).get("type") == "ContinuousAction"
        for policy in ("idle", "mixed"):
            rng = np.random.default_rng(1000 + ci)
            for ep in range(episodes):
                obs, info = env.reset(seed=100 * ci + ep)
                _feed(h, obs)
                # reset's info["action"] (and the rewards computed from it) is
                # highway-env's unseeded action_space.sample(): not part of the episode.
                _feed(h, {k: v for k, v in info.items() if k not in ("action", "rewards")})
                for _ in range(steps):
                    if continuous:
                        action = (
                            np.zeros(2, np.float32)
                            if policy == "idle"
                            else (rng.uniform(-1, 1, 2) * [0.02, 2.0]).astype(np.float32)
                        )
                    else:
                        action = 1 if policy == "idle" else int(rng.integers(0, 5))
                    obs, reward, terminated, truncated, info = env.step(action)
                    _feed(h, (obs, reward, terminated, truncated, info))
                    if terminated or truncated:
                        break
        env.close()
    return h.hexdigest()


def detect_digest(frames_per_road: int) -> tuple[str, str]:
    """sha256 over every detector's lines, and over their trajectories, on seeded frames."""
    from aldm_gym.roads import HighwayRoad
    from aldm_gym.sensor import LineSensor, detect_lanes, ground_truth_detect, naive_detect
    from aldm_gym.sensor.open_loop import sample_poses

    h = hashlib.sha256()
    ht = hashlib.sha256()
    roads = (
        {"curved": False, "seed": 1},
        {"min_radius": 500.0, "max_radius": 1500.0, "seed": 2},
        {"min_radius": 100.0, "max_radius": 250.0, "seed": 3},
    )
    noises = ((0.0, 0.0), (0.05, 0.1), (0.10, 0.2))
    for ri, rcfg in enumerate(roads):
        base = HighwayRoad({**rcfg, "length": 3000.0})
        poses = sample_poses(base, frames_per_road, np.random.default_rng(ri))
        for model in ("per_dash", "editor"):
            road = base.with_marking_model(model)
            for noise, drop in noises:
                sensor = LineSensor({"lateral_noise": noise, "dropout": drop}, seed=ri)
                for p in poses:
                    frame = sensor.measure(road, p.pose)
                    dets = (
                        detect_lanes(frame),
                        detect_lanes(frame, mode="paper"),
                        naive_detect(frame, lane_width=road.lane_width),
                        ground_truth_detect(road, frame, p.lane_id),
                    )
                    for det in dets:
                        lines = (det.ego_left, det.ego_right, det.left_adjacent)
                        _feed(h, (*lines, det.right_adjacent))
                        _feed(ht, det.trajectory)
    return h.hexdigest(), ht.hexdigest()


def main(argv: list[str] | None = None) -> None:
    """Print the two digests."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer episodes and frames")
    args = parser.parse_args(argv)
    episodes, steps, frames = (1, 10, 10) if args.quick else (3, 40, 40)
    from aldm_gym.envs.traffic import scalar

    differ = [name for name, same in scalar.NUMPY_AGREES_WITH_LIBM.items() if not same]
    print(f"numpy differs from libm in: {', '.join(differ) or 'nothing'}")
    lines, trajectories = detect_digest(frames)
    print(f"lines  {lines}  ({frames} poses x 3 roads x 2 models x 3 noises x 4 detectors)")
    print(f"paths  {trajectories}  (the same detections' trajectories)")
    print(f"env    {env_digest(episodes, steps)}  ({episodes} episodes x {steps} steps per case)")


if __name__ == "__main__":
    main()
