"""Target selection where it is hard: curves with vehicles ahead in the ego and adjacent lanes.

The open-loop scenario set of ``aldm-gym compare`` for the ACC's target selection
(:mod:`aldm_gym.envs.targets`). On seeded generated roads with arcs of R 500–1500 m
the ego stands in a lane with a neighbour on both sides, and one vehicle is placed
ahead on the road:

* ``ego_lane``: in the ego lane, 60–150 m ahead (it is the target);
* ``adjacent``: in a neighbouring lane, 60–150 m ahead (it is not: in the curve it may
  well lie straight ahead of the car);
* ``cut_in``: in a neighbouring lane 20–60 m ahead, drifted towards the ego lane so
  that 0.6–1.2 m of its width is inside it (it is the target: ``enter_overlap`` is
  0.5 m).

Every detector sees the same frame; a fresh :class:`~aldm_gym.envs.targets.TargetSelector`
(no hysteresis history) selects on its lines; the truth is the same overlap rule on
the road's true lane (along its reference line). A scene is correct when the vehicle
is selected exactly when it is truly in the ego lane.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np

from aldm_gym.envs.longitudinal import ACCConfig, selector_for
from aldm_gym.envs.observation import to_sensor_frame
from aldm_gym.envs.targets import NO_TARGET, Objects
from aldm_gym.errors import ConfigError
from aldm_gym.roads.highway import MARKING_MODELS, HighwayRoad
from aldm_gym.sensor.detectors import DETECTORS, make_detector
from aldm_gym.sensor.line_sensor import LineSensor

SCENE_KINDS: tuple[str, ...] = ("ego_lane", "adjacent", "cut_in")
"""The scene kinds (module docstring)."""

CUT_IN_RANGE: tuple[float, float] = (20.0, 60.0)
"""Distance of a cutting-in vehicle ahead [m] (the other scene kinds: :data:`FAR_RANGE`)."""
FAR_RANGE: tuple[float, float] = (60.0, 150.0)
"""Distance of a vehicle in the ego or an adjacent lane [m]."""

DISTANCE_BINS: tuple[float, ...] = (20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 150.0)
"""Edges of the distance bins of :func:`accuracy_by_distance` [m]."""

TARGET_COLUMNS: tuple[str, ...] = (
    "marking_model",
    "detector",
    "mode",
    "scenes",
    "accuracy",
    "missed_rate",
    "false_rate",
    "ego_lane_accuracy",
    "adjacent_accuracy",
    "cut_in_accuracy",
)
"""Columns of ``compare_targets.csv`` (one row per marking model × detector)."""

MIN_RADIUS, MAX_RADIUS = 500.0, 1500.0
"""The curves of the scenario roads [m]."""

VEHICLE_WIDTH, VEHICLE_LENGTH = 2.0, 5.0
"""The placed vehicle's size [m] (highway-env's)."""


@dataclass(frozen=True)
class TargetScene:
    """One scene: the ego's pose, the vehicle ahead and whether it is the target.

    :ivar road: index of the road in the list given to :func:`make_scenes`.
    :ivar lane: the ego's lane id.
    :ivar pose: the ego's world pose ``(x [m], y [m], heading [rad])``.
    :ivar kind: one of :data:`SCENE_KINDS`.
    :ivar distance: the vehicle's distance ahead along the road [m].
    :ivar position: the vehicle's world position [m].
    :ivar heading: the vehicle's world heading [rad].
    :ivar in_lane: ground truth: the vehicle is in the ego lane (the target).
    """

    road: int
    lane: int
    pose: tuple[float, float, float]
    kind: str
    distance: float
    position: tuple[float, float]
    heading: float
    in_lane: bool


def scenario_road(seed: int, marking_model: str = "per_dash") -> HighwayRoad:
    """The generated road of the scenario set: curves of R 500–1500 m, 4 lanes."""
    return HighwayRoad(
        {
            "seed": seed,
            "min_radius": MIN_RADIUS,
            "max_radius": MAX_RADIUS,
            "marking_model": marking_model,
        }
    )


def make_scenes(
    roads: Sequence[HighwayRoad],
    per_road: int,
    seed: int = 0,
    enter_overlap: float = ACCConfig.enter_overlap,
) -> list[TargetScene]:
    """``per_road`` seeded scenes on each road, the ego on a curve (R <= 1500 m).

    :raises ValueError: a road with fewer than 3 lanes (a scene needs both neighbours).
    """
    scenes = []
    for k, road in enumerate(roads):
        if road.lanes_count < 3:
            raise ConfigError("target scenes need roads with at least 3 lanes")
        rng = np.random.default_rng([seed, k])
        w = road.lane_width
        while sum(sc.road == k for sc in scenes) < per_road:
            s = float(rng.uniform(250.0, road.length - 450.0))
            kind = SCENE_KINDS[int(rng.integers(len(SCENE_KINDS)))]
            near = kind == "cut_in"
            d = float(rng.uniform(*CUT_IN_RANGE) if near else rng.uniform(*FAR_RANGE))
            if abs(float(road.curvature_at(s + 0.5 * d))) < 1.0 / (MAX_RADIUS + 1.0):
                continue  # a straight: not a hard scene
            lane = int(rng.integers(1, road.lanes_count - 1))
            side = 1.0 if rng.uniform() < 0.5 else -1.0
            if kind == "ego_lane":
                y_rel = float(rng.uniform(-0.5, 0.5))
            elif kind == "adjacent":
                y_rel = side * (w + float(rng.uniform(-0.5, 0.5)))
            else:
                inside = float(rng.uniform(0.6, 1.2))  # of its width in the ego lane
                y_rel = side * (0.5 * w + 0.5 * VEHICLE_WIDTH - inside)
            overlap = min(y_rel + 1.0, 0.5 * w) - max(y_rel - 1.0, -0.5 * w)
            ego_xy = road.reference.position(s, road.lane_offset(lane))
            pos = road.reference.position(s + d, road.lane_offset(lane) + y_rel)
            heading = float(road.reference.heading_at(s))
            scenes.append(
                TargetScene(
                    road=k,
                    lane=lane,
                    pose=(float(ego_xy[0]), float(ego_xy[1]), heading),
                    kind=kind,
                    distance=d,
                    position=(float(pos[0]), float(pos[1])),
                    heading=float(road.reference.heading_at(s + d)),
                    in_lane=overlap >= enter_overlap,
                )
            )
    return scenes


def select_in_scenes(
    roads: Sequence[HighwayRoad],
    scenes: Iterable[TargetScene],
    detector: str,
    sensor: LineSensor | None = None,
    config: ACCConfig | None = None,
    progress: Callable[[int], None] | None = None,
    params: dict[str, Any] | None = None,
) -> list[bool]:
    """Whether ``detector``'s lines make the target selector pick each scene's vehicle.

    :param params: the detector's parameters (``{"mode": "paper"}`` for the ALDM's).
    """
    sensor = sensor or LineSensor()
    cfg = config or ACCConfig()
    det = make_detector(detector, params)
    ego_x = -float(sensor.config.mount_x)
    out = []
    for sc in scenes:
        road = roads[sc.road]
        frame = sensor.measure(road, sc.pose)
        detection = det(frame, road, sc.lane)
        rel = to_sensor_frame(np.array([sc.position]), np.zeros((1, 2)), frame.origin, frame.yaw)
        objects = Objects(
            ids=np.array([1]),
            x=rel[:, 0],
            y=rel[:, 1],
            vx=np.zeros(1),
            width=np.array([VEHICLE_WIDTH]),
            length=np.array([VEHICLE_LENGTH]),
        )
        selector = selector_for(cfg, ego_x=ego_x, lane_width=road.lane_width)
        out.append(selector.select(detection, objects) != NO_TARGET)
        if progress is not None:
            progress(1)
    return out


def _share(mask: np.ndarray) -> float:
    return float(mask.mean()) if len(mask) else float("nan")


def compare_target_selection(
    seeds: Sequence[int],
    per_road: int,
    *,
    marking_models: Iterable[str] = MARKING_MODELS,
    detectors: Iterable[str] = DETECTORS,
    aldm_mode: str = "robust",
    progress: Callable[[int], None] | None = None,
) -> tuple[list[dict[str, Any]], dict[tuple[str, str], list[float]]]:
    """The scenario set on the roads of ``seeds`` for every marking model × detector.

    :param aldm_mode: the ALDM's mode (``"robust"`` or ``"paper"``), named in the rows'
        ``mode`` column.

    :return: rows with the keys of :data:`TARGET_COLUMNS`, and per ``(marking model,
        detector)`` the accuracy in each distance bin of :data:`DISTANCE_BINS`
        (:func:`accuracy_by_distance`).
    """
    detectors = list(detectors)
    rows: list[dict[str, Any]] = []
    curves: dict[tuple[str, str], list[float]] = {}
    base = [scenario_road(s) for s in seeds]
    scenes = make_scenes(base, per_road, seed=int(seeds[0]) if len(seeds) else 0)
    truth = np.array([sc.in_lane for sc in scenes])
    kinds = np.array([sc.kind for sc in scenes])
    for model in marking_models:
        roads = [r.with_marking_model(model) for r in base]
        for det in detectors:
            mode = aldm_mode if det == "aldm" else ""
            params = {"mode": "paper"} if mode == "paper" else None
            picked = np.array(
                select_in_scenes(roads, scenes, det, progress=progress, params=params)
            )
            ok = picked == truth
            row: dict[str, Any] = {
                "marking_model": model,
                "detector": det,
                "mode": mode,
                "scenes": len(scenes),
                "accuracy": _share(ok),
                "missed_rate": _share(truth & ~picked),
                "false_rate": _share(~truth & picked),
            }
            for kind in SCENE_KINDS:
                row[f"{kind}_accuracy"] = _share(ok[kinds == kind])
            rows.append(row)
            curves[(model, det)] = accuracy_by_distance(scenes, ok)
    return rows, curves


def accuracy_by_distance(scenes: Sequence[TargetScene], ok: np.ndarray) -> list[float]:
    """Share of correct scenes per distance bin of :data:`DISTANCE_BINS` (NaN if empty)."""
    dist = np.array([sc.distance for sc in scenes])
    edges = DISTANCE_BINS
    return [_share(ok[(dist >= lo) & (dist < hi)]) for lo, hi in pairwise(edges)]
