"""Why the tracking ALDM's ego lines fail: every failing line of seeded IDLE episodes,
classified.

Runs ``ALDMHighway-v0`` with the tracking ALDM (``detector_params={"tracking":
True}``) under the camera preset with trucks (the setting of the tracking goal in
``docs/results.md``), IDLE (lane keeping only), and scores each step's ego lines as
``info["detection"]`` does (:func:`aldm_gym.sensor.ground_truth.score_line`: every
point within 0.3 m of the true marking, starting within 25 m, a preview of 60 m). Each
failing line is put in one class, checked in this order:

* ``missing``: fewer than two points;
* ``late start``: its first point is beyond 25 m;
* ``short``: its preview (:func:`~aldm_gym.sensor.lane_detection.line_preview`: the far
  end of its part without a gap over 36 m) is under 60 m;
* ``error < 90 m`` / ``error >= 90 m``: a point more than 0.3 m off, by the x of the
  first such point; each split into ``seen`` (this frame has points of the true
  marking within 10 m of that x: the line left a measured marking, e.g. for clutter)
  and ``unseen`` (nothing measured there: the line there is carried or extrapolated).

``--tracking model`` runs the lane-model filter (``detector_params={"tracking":
"model"}``) instead, ``--tracking none`` the single-frame ALDM.

``--sensor`` adds sensor settings (JSON), e.g. ``--preset none --trucks 0 --sensor
'{"worn_dash_rate": 0.3}'`` for worn paint alone; ``--road`` road settings, e.g.
``--road '{"min_radius": 100}'`` for the generator's tightest curves; ``--params``
more ``detector_params`` (e.g. the filter's settings). ``--policy
lca`` drives with the rule-based lane-change policy instead of IDLE. The lane departures
(``info["departures"]``) and lane changes of all episodes are printed too.

Run: ``.venv/bin/python -m benchmarks.tracking_failures [--seeds 20] [--tracking
tracker|model|none] [--policy idle|lca] [--list]`` (about 1.5 s per episode once
the kernels are compiled).
"""

from __future__ import annotations

import argparse
import collections
import json
from typing import Any

import numpy as np

FAR = 90.0
"""x [m] separating near from far errors."""
SEEN_DX = 10.0
"""A true marking point within this x distance [m] of the first bad point ..."""
SEEN_DY = 0.15
"""... and within this lateral distance [m] of the marking counts as measured."""
TRACKING: dict[str, bool | str] = {"tracker": True, "model": "model", "none": False}
"""``--tracking`` choices and their ``detector_params["tracking"]``."""


def classify(env: Any, name: str) -> tuple[str, float, float]:
    """The failure class of ego line ``name`` of the env's last step, the x of its
    first point off by more than 0.3 m [m] (NaN if none) and its largest error [m]."""
    from aldm_gym.sensor.ground_truth import line_markings, true_line
    from aldm_gym.sensor.lane_detection import line_preview

    u = env.unwrapped
    line = u.detection.line(name)
    if len(line) < 2:
        return "missing", float("nan"), float("nan")
    marking = line_markings(u.highway, u.lane_position.lane, u.frame.origin)[name]
    if marking is None:
        return "no such marking", float("nan"), float("nan")
    err = np.abs(line[:, 1] - true_line(u.highway, u.frame, marking, line[:, 0]))
    bad = np.flatnonzero(~(err <= 0.3))
    worst = float(np.nanmax(err)) if np.isfinite(err).any() else float("inf")
    if line[0, 0] > 25.0:
        return "late start", float("nan"), worst
    if line_preview(line) < 60.0:
        return "short", float("nan"), worst
    if len(bad) == 0:
        return "other", float("nan"), worst
    x_bad = float(line[bad[0], 0])
    pts = u.frame.all_points
    near = pts[np.abs(pts[:, 0] - x_bad) <= SEEN_DX]
    seen = len(near) > 0 and bool(
        np.any(np.abs(near[:, 1] - true_line(u.highway, u.frame, marking, near[:, 0])) < SEEN_DY)
    )
    where = "error < 90 m" if x_bad < FAR else "error >= 90 m"
    return f"{where}, {'seen' if seen else 'unseen'}", x_bad, worst


def main(argv: list[str] | None = None) -> None:
    """Run the episodes and print the rates and the classes."""
    import gymnasium as gym
    from tqdm import tqdm

    import aldm_gym  # noqa: F401  (registers the env)

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="episodes (seeds first, ...)")
    parser.add_argument("--first", type=int, default=0, help="first seed")
    parser.add_argument("--trucks", type=float, default=0.15, help="traffic.truck_share")
    parser.add_argument("--preset", default="camera", help="sensor preset ('none': ideal)")
    parser.add_argument(
        "--sensor",
        default="{}",
        help="more sensor settings as JSON, e.g. '{\"worn_dash_rate\": 0.3}'",
    )
    parser.add_argument(
        "--road",
        default="{}",
        help="road settings as JSON, e.g. '{\"min_radius\": 100}' for tight curves",
    )
    parser.add_argument(
        "--params",
        default="{}",
        help="more detector_params as JSON, e.g. '{\"q_curvature_rate\": 5e-6}'",
    )
    parser.add_argument(
        "--tracking",
        choices=tuple(TRACKING),
        default="tracker",
        help="the point-level tracker, the lane-model filter, or single frame",
    )
    parser.add_argument(
        "--policy",
        choices=("idle", "lca"),
        default="idle",
        help="IDLE (lane keeping only) or the rule-based lane-change policy",
    )
    parser.add_argument("--list", action="store_true", help="print every failing line")
    args = parser.parse_args(argv)
    config = {
        "marking_model": "per_dash",
        "detector": "aldm",
        "detector_params": {"tracking": TRACKING[args.tracking], **json.loads(args.params)},
        "sensor": {
            **({} if args.preset == "none" else {"preset": args.preset}),
            **json.loads(args.sensor),
        },
        "traffic": {"truck_share": args.trucks},
    }
    road = json.loads(args.road)
    if road:
        config["road"] = road
    from aldm_gym.agents.policies import RuleBasedLCA

    steps = both = lines = correct = departures = changes = restarts = 0
    classes: collections.Counter[str] = collections.Counter()
    failures = []
    for seed in tqdm(range(args.first, args.first + args.seeds), desc="episodes", unit="ep"):
        env = gym.make("ALDMHighway-v0", config=config)
        obs, _ = env.reset(seed=seed)
        policy = RuleBasedLCA() if args.policy == "lca" else None
        done = False
        k = 0
        lane = None
        while not done:
            action = 1 if policy is None else int(policy.predict(obs, deterministic=True)[0])
            obs, _, term, trunc, info = env.step(action)  # 1: IDLE
            done = term or trunc
            changes += lane is not None and info["lane_index"] != lane
            lane = info["lane_index"]
            k += 1
            steps += 1
            ok = [bool(info["detection"][n]["correct"]) for n in ("ego_left", "ego_right")]
            both += all(ok)
            for name, good in zip(("ego_left", "ego_right"), ok, strict=True):
                lines += 1
                correct += good
                if not good:
                    kind, x_bad, worst = classify(env, name)
                    classes[kind] += 1
                    failures.append((seed, k, name, kind, x_bad, worst))
        departures += int(info["departures"])
        model = getattr(env.unwrapped.perception.detector, "tracker", None)
        restarts += int(getattr(model, "n_restarts", 0))
        env.close()
    print(f"steps with both ego lines correct: {both / steps:.3f} ({both} of {steps})")
    print(f"ego lines correct: {correct / lines:.3f} ({correct} of {lines})")
    print(f"lane departures: {departures}; lane changes: {changes}")
    if args.tracking == "model":
        print(f"filter restarts (a receded model replaced by a fresh start): {restarts}")
    print("failing lines by class:")
    for kind, n in sorted(classes.items(), key=lambda kv: -kv[1]):
        print(f"  {n:4d}  {kind}")
    if args.list:
        print("seed step line class x_bad[m] max_error[m]")
        for seed, k, name, kind, x_bad, worst in failures:
            print(f"{seed:4d} {k:4d} {name:9s} {kind:24s} {x_bad:6.0f} {worst:6.2f}")


if __name__ == "__main__":
    main()
