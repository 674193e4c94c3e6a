"""The ground-truth referee of ``ALDMHighway-v0``: what truly happened, never seen by
the agent or the functions.

:class:`Referee` keeps, per episode, where the ego truly is on the road (a
:class:`~aldm_gym.roads.LanePosition` every simulation step), the lane departures, the
kind of a collision, the score of the detected ego lines against the true markings
(``info["detection"]``) and the truth about the ACC's target (``info["target"]``: the
target selector's own rule applied to the true corridor, and whether a hard braking was
for a vehicle truly in it). It asks the road (:class:`~aldm_gym.roads.Road`) and never
which kind of road it is.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from aldm_gym.envs.longitudinal import (
    ACCConfig,
    LongitudinalCommand,
    LongitudinalController,
    selector_for,
)
from aldm_gym.envs.targets import NO_TARGET, Objects, lane_overlap, predicted_overlaps
from aldm_gym.errors import OffRoadError
from aldm_gym.roads.position import LanePosition
from aldm_gym.roads.protocol import Road
from aldm_gym.sensor.frame import SensorFrame
from aldm_gym.sensor.ground_truth import score_detection
from aldm_gym.sensor.lane_detection import LINE_NAMES, LaneDetection
from aldm_gym.sensor.lane_metrics import NEAR, THRESHOLDS, frame_metrics

__all__ = ["NO_TARGET_INFO", "Referee", "collision_kind"]

NO_TARGET_INFO: dict[str, Any] = {
    "target": NO_TARGET,
    "leader": NO_TARGET,
    "correct": True,
    "missed": False,
    "false": False,
    "aeb": False,
    "aeb_activations": 0,
    "phantom_braking": False,
    "gap": math.inf,
    "time_gap": math.inf,
}
"""``info["target"]`` without an ACC (``acc.enabled = False`` or continuous actions)."""


def collision_kind(ego: Any, vehicles: list[Any]) -> str:
    """Where the other vehicle of the ego's collision was at the impact: ``"front"``
    (the ego ran into it: its centre more than half a car length ahead along the
    ego's axis), ``"rear"`` (it ran into the ego), else ``"side"``."""
    others = [v for v in vehicles if v is not ego and v.crashed]
    if not others:
        return "side"
    other = min(others, key=lambda v: float(np.hypot(*(v.position - ego.position))))
    d = other.position - ego.position
    ahead = float(d[0] * math.cos(ego.heading) + d[1] * math.sin(ego.heading))
    if ahead > 0.5 * ego.LENGTH:
        return "front"
    if ahead < -0.5 * ego.LENGTH:
        return "rear"
    return "side"


TRUTH_STEP = 0.1
"""The time step [s] over which ground truth differences a vehicle's lateral offset
(its lateral speed relative to the lanes, for the predicted true overlaps)."""


class Referee:
    """Ground truth of one episode (module docstring).

    :param road: the road of the episode.
    :param acc: the ``acc`` settings (the true target uses the selector's rule).
    :param ego_x: x of the ego's centre in the sensor frame [m].

    :ivar lane_position: where the ego truly is, updated every simulation step.
    :ivar off_map: the ego left a map's lanes (the episode terminates).
    :ivar departures: lane departures this episode (a wheel over a marking outside a
        lane change, counted once per departure).
    :ivar departed_step: a departure happened during this policy step.
    :ivar distance: distance the ego drove this episode [m]: the path length of its
        positions at the simulation steps.
    :ivar collision: ``""`` or the kind of the ego's collision (:func:`collision_kind`).
    """

    def __init__(self, road: Road, acc: ACCConfig, ego_x: float) -> None:
        """A fresh episode's referee."""
        self.road = road
        lane_width = float(road.lane_width)
        self.lane_position = LanePosition(0.0, 0.0, 0, 0, 1, 3.75, 0.0, 0.0)
        self.off_map = False
        self.departures = 0
        self.departed_step = False
        self.distance = 0.0
        self._last_xy: tuple[float, float] | None = None
        self.collision = ""
        self.acc_step: dict[str, bool] = {"aeb": False, "phantom_braking": False}
        self._lc_target_index: int | None = None
        self.truth = selector_for(acc, ego_x=ego_x, lane_width=lane_width)

    def begin_step(self) -> None:
        """A new policy step: its departure and ACC flags start clear."""
        self.departed_step = False
        self.acc_step = {"aeb": False, "phantom_braking": False}

    def locate(self, ego: Any) -> LanePosition:
        """The ego's true lane position (:attr:`lane_position`), on the lanes that run
        the ego's way (in a two-way road's oncoming lane it is off its own lane: a
        departure). Off a map's lanes the last lane is kept with an infinite offset (a
        departure) and :attr:`off_map` set.
        Adds the way from the last call to :attr:`distance`."""
        xy = (float(ego.position[0]), float(ego.position[1]))
        if self._last_xy is not None:
            self.distance += math.hypot(xy[0] - self._last_xy[0], xy[1] - self._last_xy[1])
        self._last_xy = xy
        try:
            self.lane_position = self.road.lane_position(ego.position, float(ego.heading))
        except OffRoadError:
            self.off_map = True
            last = self.lane_position
            self.lane_position = dataclasses.replace(
                last, offset=math.copysign(math.inf, last.offset)
            )
        return self.lane_position

    def judge(self, ego: Any, vehicles: list[Any]) -> None:
        """After a simulation step: the collision's kind at the impact, and a departure
        when a wheel is over a marking (``|offset| + width / 2 > lane width / 2``)
        outside a lane change."""
        if ego.crashed and not self.collision:
            # Classified at the step of the impact: the crashed ego slides on.
            self.collision = collision_kind(ego, vehicles)
        pos = self.lane_position
        over = abs(pos.offset) + 0.5 * ego.WIDTH > 0.5 * pos.width
        if over and ego.lane_change == 0:
            if not self.departed_step:
                self.departures += 1
            self.departed_step = True

    # ------------------------------------------------------------------ ACC truth
    def true_overlap(
        self,
        objects: Objects,
        objects_xy: np.ndarray,
        rows: np.ndarray,
        ego: Any,
        velocity: np.ndarray | None = None,
    ) -> np.ndarray:
        """Overlap [m] of ``objects`` ``rows`` (world positions ``objects_xy``) with the
        ego's true corridor: its lane, plus the lane it changes into while a lane
        change is under way; ``-inf`` for a vehicle on no lane.

        With their world velocities ``velocity`` ``(N, 2)`` [m/s] and a prediction
        horizon, the overlap is the predicted one, as the ACC's selection predicts
        (:meth:`~aldm_gym.envs.targets.TargetSelector.overlaps`), with each vehicle's
        true lateral speed relative to the lanes: the change of its lateral offset
        over :data:`TRUTH_STEP` at its velocity."""
        pos = self.lane_position
        if ego.lane_change == 0:
            self._lc_target_index = None
        elif self._lc_target_index is None:
            self._lc_target_index = pos.index - int(ego.lane_change)  # ids grow rightwards
        target = pos.index if self._lc_target_index is None else self._lc_target_index
        lo, hi = min(pos.index, target), max(pos.index, target)
        w = pos.width
        left, right = (pos.index - lo) * w + 0.5 * w, (pos.index - hi) * w - 0.5 * w
        xy = objects_xy[rows]
        y = self.road.lateral_offsets(xy, pos) if len(xy) else np.zeros(0)
        finite = np.isfinite(y)
        width = objects.width[rows]
        truth = self.truth
        if velocity is None or truth.horizon <= 0.0 or not len(xy):
            overlap = lane_overlap(y, width, left, right)
        else:
            ahead = self.road.lateral_offsets(xy + TRUTH_STEP * velocity[rows], pos)
            lateral = np.where(finite & np.isfinite(ahead), (ahead - y) / TRUTH_STEP, 0.0)
            shift = truth.shifts(objects.x[rows], objects.vx[rows], objects.length[rows], lateral)
            n = len(y)
            overlap = predicted_overlaps(
                np.where(finite, y, 0.0), width, shift, np.full(n, left), np.full(n, right)
            )
        overlap[~finite] = -math.inf
        return overlap

    def check_braking(
        self,
        cmd: LongitudinalCommand,
        ctrl: LongitudinalController,
        objects: Objects,
        objects_xy: np.ndarray,
        ego: Any,
        velocity: Callable[[], np.ndarray] | None = None,
    ) -> None:
        """After the ACC's command: note an AEB activation, and whether a hard braking
        for the target was for a vehicle truly in the ego's corridor (else a phantom
        braking), once per policy step."""
        self.acc_step["aeb"] |= cmd.aeb
        braking = (cmd.following or cmd.aeb) and (
            cmd.acceleration < -ctrl.config.phantom_deceleration
        )
        if braking and cmd.target != NO_TARGET and not self.acc_step["phantom_braking"]:
            row = np.array([objects.index_of(cmd.target)])
            moving = None if velocity is None else velocity()
            overlap = self.true_overlap(objects, objects_xy, row, ego, moving)[0]
            self.acc_step["phantom_braking"] = bool(overlap < ctrl.config.exit_overlap)

    def true_leader(
        self,
        objects: Objects,
        objects_xy: np.ndarray,
        ego: Any,
        velocity: np.ndarray | None = None,
    ) -> int:
        """The in-lane leader by ground truth: the target selector's rule and
        hysteresis (:class:`~aldm_gym.envs.targets.TargetSelector`) on the true
        corridor (:meth:`true_overlap`, predicted with the world ``velocity``).
        Evaluated once per policy step, for ``info``."""
        truth = self.truth
        x = objects.x - truth.ego_x
        near = np.flatnonzero((x > 0.0) & (x <= truth.max_range))
        overlap = self.true_overlap(objects, objects_xy, near, ego, velocity)
        return truth.select_overlaps(
            objects.ids[near], objects.x[near], overlap, objects.width[near]
        )

    def target_info(
        self,
        cmd: LongitudinalCommand | None,
        ctrl: LongitudinalController | None,
        objects: Objects,
        objects_xy: np.ndarray,
        ego: Any,
        velocity: np.ndarray | None = None,
    ) -> dict[str, Any]:
        """``info["target"]``: the ACC's target against ground truth (``docs/acc.md``)."""
        if cmd is None or ctrl is None:
            return dict(NO_TARGET_INFO)
        leader = self.true_leader(objects, objects_xy, ego, velocity)
        target = cmd.target
        time_gap = math.inf
        if leader != NO_TARGET:
            row = objects.index_of(leader)
            gap = float(ctrl.gaps(objects)[row])
            time_gap = max(gap, 0.0) / max(float(ego.speed), 0.1)
        return {
            "target": int(target),
            "leader": int(leader),
            "correct": target == leader,
            "missed": leader != NO_TARGET and target != leader,
            "false": target != NO_TARGET and target not in self.truth.inside,
            "aeb": bool(self.acc_step["aeb"]),
            "aeb_activations": int(ctrl.aeb.activations),
            "phantom_braking": bool(self.acc_step["phantom_braking"]),
            "gap": float(cmd.gap),
            "time_gap": time_gap,
        }

    # ------------------------------------------------------------------ lanes
    def lane_metrics(
        self, detection: LaneDetection | None, frame: SensorFrame, view: float | None = None
    ) -> dict[str, Any]:
        """``info["lane_metrics"]``: the frame's lane-detection metrics
        (:func:`~aldm_gym.sensor.lane_metrics.frame_metrics`): ``detected``, the lines
        detected; per threshold (``"strict"``, ``"loose"``) the counts ``tp`` (true
        lines recalled), ``fp`` (detected lines not precise), ``fn`` (true lines not
        recalled), and the mean |lateral error| of the lines precise at the loose threshold
        near (x <= 40 m) and far [m] (NaN without such points).

        :param view: the sensor's visibility [m] (``None``: its range)."""
        empty = LaneDetection()
        lane = self.lane_position.lane
        m = frame_metrics(detection or empty, self.road, frame, lane, view=view)
        out: dict[str, Any] = {"detected": len(m.detected)}
        for threshold in THRESHOLDS:
            tp, fp, fn = m.counts(threshold)
            out[threshold] = {"tp": tp, "fp": fp, "fn": fn}
        errors = [x.errors for x in m.matches if x.loose_precise]
        both = np.concatenate(errors) if errors else np.zeros((0, 2))
        near = both[both[:, 0] <= NEAR, 1]
        far = both[both[:, 0] > NEAR, 1]
        out["near_mean_m"] = float(near.mean()) if len(near) else math.nan
        out["far_mean_m"] = float(far.mean()) if len(far) else math.nan
        return out

    def score(
        self, detection: LaneDetection | None, frame: SensorFrame
    ) -> dict[str, dict[str, float]]:
        """Per ego line: mean |error| vs truth up to 60 m [m], preview [m], correct (1/0).

        ``correct`` is :class:`~aldm_gym.sensor.ground_truth.LineScore`'s: every point
        within 0.3 m of the true marking, starting <= 25 m, reaching >= 60 m. A
        detection with a per-line ``confidence`` (the lane-model filter's) adds it
        (in [0, 1]; 0 when no line has the role), and with ``measured`` (the filter's)
        ``measured_from`` / ``measured_to``: the x range [m] this frame's points
        measured the line in (NaN: carried by the model alone; beyond the range it is
        carried too).
        """
        nan = float("nan")
        if detection is None:
            return {
                n: {"mean_abs_error": nan, "preview": nan, "correct": 0.0}
                for n in ("ego_left", "ego_right")
            }
        scores = score_detection(
            detection, self.road, frame, self.lane_position.lane, names=("ego_left", "ego_right")
        )
        out: dict[str, dict[str, float]] = {}
        for name in ("ego_left", "ego_right"):
            sc = scores[name]
            if sc.found:
                out[name] = {
                    "mean_abs_error": float(sc.mean_abs_error),
                    "preview": sc.preview,
                    "correct": float(sc.correct),
                }
            else:
                out[name] = {"mean_abs_error": nan, "preview": nan, "correct": 0.0}
        confidence = getattr(detection, "confidence", None)
        if confidence is not None:  # the lane-model filter's existence confidence
            for name in ("ego_left", "ego_right"):
                out[name]["confidence"] = float(confidence[LINE_NAMES.index(name)])
        measured = getattr(detection, "measured", None)
        if measured is not None:  # the filter's: where this frame measured the line
            for name in ("ego_left", "ego_right"):
                lo, hi = measured[LINE_NAMES.index(name)]
                out[name]["measured_from"] = float(lo)
                out[name]["measured_to"] = float(hi)
        return out
