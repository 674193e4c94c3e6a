"""UN R157 (ALKS) pass criteria of a scenario run, judged on ground truth.

:func:`run_scenario` plays one concrete scenario in ``ALDMHighway-v0`` with a function
under test (:mod:`aldm_gym.function`; by default the env's own: LKA on the detected
lanes, ACC and AEB, no lane change) and a :class:`Judge` watches every policy step
after the ego's controller is active. The
criteria, each with the regulation's paragraph (UN R157, ECE/TRANS/WP.29/2020/81):

``no_collision`` (5.1.1)
    The ego collides with nothing. Not required where the suite marks the collision
    unavoidable (a file whose name contains ``unavoidable``, as OSC-ALKS's 4.4_2):
    there it is reported, not judged.
``in_lane`` (5.2.1)
    No wheel of the ego crosses a marking of its lane (the env's departure count:
    ``info["lane_departure"]``; ground truth).
``time_gap`` (5.2.3.3)
    Behind a vehicle in its lane the ego keeps at least the regulation's minimum time
    gap (its table: 1.0 s at 7.2 km/h, 1.1 s at 10, 1.2 at 20, ... 1.6 s at 60 km/h,
    interpolated between rows; 1.0 s below, 1.6 s above). The vehicle in front is the
    nearest scenario *vehicle* (not a pedestrian or an object) wholly ahead of the
    ego's front whose box overlaps the ego's lane, measured along that lane (so a lead
    in a curve is found; a vehicle beside the ego is not in front of it). The
    regulation lets the gap fall short "temporarily because of other road users (e.g.
    vehicle is cutting in, decelerating lead vehicle)" and asks that it be restored
    "at the next available opportunity": the criterion fails when the gap is short for
    more than :data:`GAP_RESTORE_TIME` in one stretch (our reading; the regulation
    gives no number). Standing still (< 0.5 m/s) never fails it.

Only what happens after the ego's ``ActivateControllerAction`` is judged; a collision
before it is the scenario's own and marks the run as an error, not a failure. The
numbers reported beside them: ``min_ttc_s`` (time to collision with the vehicle
ahead in the ego's lane, freespace), ``min_time_gap_s``, ``departures``, the simulation
time and whether the stop trigger ended the run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from aldm_gym.errors import OffRoadError
from aldm_gym.function import Function, FunctionDriver, close_function, env_for, load_function
from aldm_gym.scenario.world import Entity

__all__ = ["GAP_RESTORE_TIME", "Judge", "RunResult", "min_time_gap", "run_scenario"]

GAP_RESTORE_TIME = 3.0
"""The longest stretch [s] the time gap may stay below the regulation's minimum."""


R157_GAP_TABLE = (
    (7.2, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0),
    (1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6),
)
"""UN R157 5.2.3.3's table: speed [km/h] and minimum time gap [s]."""


def min_time_gap(speed: float) -> float:
    """UN R157 5.2.3.3's minimum time gap [s] at ``speed`` [m/s] (its table,
    interpolated between rows)."""
    return float(np.interp(speed * 3.6, *R157_GAP_TABLE))


@dataclass
class RunResult:
    """The outcome of one scenario run (one row of the suite's CSV)."""

    scenario: str
    detector: str
    marking_model: str
    parameters: dict[str, Any] = field(default_factory=dict)
    function: str = "builtin"
    """The function under test (its ``--function`` SPEC)."""
    passed: bool = False
    no_collision: bool = True
    in_lane: bool = True
    time_gap: bool = True
    collision: bool = False
    collision_before: bool = False
    collision_required: bool = True
    departures: int = 0
    min_ttc_s: float = math.inf
    min_time_gap_s: float = math.inf
    time_s: float = 0.0
    finished: bool = False
    error: str = ""
    judged: bool = True
    """False where the function under test never drove the ego (``error`` says so):
    the run says nothing of the function."""

    def row(self) -> dict[str, Any]:
        """A flat dict for a CSV (parameters as ``NAME=VALUE;...``)."""
        out = asdict(self)
        out["parameters"] = ";".join(f"{k}={v}" for k, v in self.parameters.items())
        return out


@dataclass(frozen=True)
class _Box:
    """A generated vehicle's box, around its reference point (its centre)."""

    cx: float
    length: float
    width: float


class _Generated:
    """A generated vehicle (a swarm's, a source's) as :func:`_lead` reads an entity."""

    kind = "vehicle"

    def __init__(self, vehicle: Any) -> None:
        self.vehicle = vehicle
        self.box = _Box(0.0, float(vehicle.LENGTH), float(vehicle.WIDTH))
        self.velocity = float(vehicle.speed)

    def reference_point(self) -> np.ndarray:
        """The box centre [m] (highway-env's frame)."""
        return np.asarray(self.vehicle.position, dtype=float)

    def forward(self) -> np.ndarray:
        """The unit vector of the heading."""
        h = float(self.vehicle.heading)
        return np.array([math.cos(h), math.sin(h)])


def _lead(world: Any, ego: Entity, others: list[Any]) -> tuple[Any, float] | None:
    """The vehicle in front in the ego's lane, and the freespace gap to it [m]: the
    nearest scenario or generated vehicle wholly ahead of the ego's front whose box
    overlaps the lane, with distances along the lane's centre (reference points
    projected on it)."""
    try:
        c = world.coordinates(ego)
    except OffRoadError:
        return None
    lane = world._lane(c.lane)
    half_lane = 0.5 * float(lane.width_at(c.u))
    u_ego, _ = lane.local_coordinates(ego.reference_point())
    ego_front = float(u_ego) + ego.box.cx + 0.5 * ego.box.length
    best: tuple[Entity, float] | None = None
    for e in others:
        if e.kind != "vehicle":
            continue
        u, lateral = lane.local_coordinates(e.reference_point())
        if abs(float(lateral)) >= half_lane + 0.5 * e.box.width:
            continue  # no part of it in the lane
        rear = float(u) + e.box.cx - 0.5 * e.box.length
        if rear < ego_front:
            continue  # beside or behind the ego, not in front of it
        gap = rear - ego_front
        if best is None or gap < best[1]:
            best = (e, gap)
    return best


class Judge:
    """Watches a run step by step (after the ego's activation) and fills a :class:`RunResult`."""

    def __init__(self, result: RunResult) -> None:
        """Start with every criterion met."""
        self.result = result
        self.short_since: float | None = None
        self.activated = False
        """Whether the function under test drove the ego at any step."""

    def observe(self, runner: Any, info: Mapping[str, Any], dt: float) -> None:
        """One step: ``info`` is the env's, ``runner`` the scenario's runtime."""
        r = self.result
        world = runner.world
        r.time_s = world.time
        r.finished = runner.finished
        if not runner.active:
            if info.get("crashed"):
                r.collision_before = True
            return
        self.activated = True
        if info.get("crashed") and not r.collision_before:
            r.collision = True
        if info.get("lane_departure"):
            r.departures += 1
        ego = runner.ego
        others: list[Any] = [e for e in world.entities.values() if e is not ego]
        others += [_Generated(v) for v in runner.generated()]
        lead = _lead(world, ego, others)
        v = ego.velocity
        if lead is None or v < 0.5:
            self.short_since = None
            return
        other, gap = lead
        time_gap = gap / v
        r.min_time_gap_s = min(r.min_time_gap_s, time_gap)
        closing = v - other.velocity * float(other.forward() @ ego.forward())
        if closing > 0.0:
            r.min_ttc_s = min(r.min_ttc_s, gap / closing)
        if time_gap < min_time_gap(v):
            if self.short_since is None:
                self.short_since = world.time
            elif world.time - self.short_since > GAP_RESTORE_TIME:
                r.time_gap = False
        else:
            self.short_since = None

    def verdict(self) -> RunResult:
        """The result with the criteria decided."""
        r = self.result
        r.no_collision = not r.collision or not r.collision_required
        r.in_lane = r.departures == 0
        if r.collision_before:
            r.error = "a collision before the function was activated (the scenario's own)"
        elif not self.activated:
            r.judged = False
            r.error = (
                "the function under test never drove the ego (no ActivateControllerAction "
                "handed it over before the run ended): not judged"
            )
        r.passed = bool(r.no_collision and r.in_lane and r.time_gap and not r.error)
        return r


def run_scenario(
    xosc: str | Path,
    parameters: Mapping[str, Any] | None = None,
    detector: str = "aldm",
    marking_model: str = "per_dash",
    config: Mapping[str, Any] | None = None,
    seed: int = 0,
    frames: list[Any] | None = None,
    function: Function | str = "builtin",
) -> RunResult:
    """Play one concrete scenario with a function under test and judge it.

    :param xosc: the scenario file.
    :param parameters: values for its parameter declarations.
    :param detector: the env's ``detector`` (``naive``, ``aldm``, ``ground_truth``).
    :param marking_model: ``per_dash`` or ``editor``.
    :param config: more env settings (merged last).
    :param seed: the env's seed (the sensor's noise, if any).
    :param frames: if a list, the rendered frames are appended (``rgb_array``).
    :param function: a :class:`~aldm_gym.function.Function`, or a ``--function`` SPEC
        (:func:`~aldm_gym.function.load_function`; closed after the run).
    :raises ScenarioError: the scenario cannot be played (before the run starts).
    :raises ConfigError: ``config`` sets what the function needs otherwise (the
        observation a policy was trained on).
    """
    import gymnasium as gym

    import aldm_gym  # noqa: F401  (registers the env)

    owned = isinstance(function, str)
    fn = load_function(function) if isinstance(function, str) else function
    params = dict(parameters or {})
    cfg: dict[str, Any] = {
        "scenario": {"xosc": str(xosc), "parameters": params},
        "detector": detector,
        "marking_model": marking_model,
        "policy_frequency": 10,
        "simulation_frequency": 10,
    }
    extra = dict(config or {})
    section = extra.pop("scenario", None)  # its other settings (the hand-over, ...)
    cfg.update(extra)
    if section:
        cfg["scenario"] = {**dict(section), "xosc": str(xosc), "parameters": params}
    cfg = env_for(fn, cfg, given=set(config or {}))
    name = Path(xosc).name
    result = RunResult(
        scenario=name,
        detector=detector,
        marking_model=marking_model,
        parameters=params,
        function=function if isinstance(function, str) else type(function).__name__,
        collision_required="unavoidable" not in name,
    )
    env: Any = None
    try:
        env = gym.make(
            "ALDMHighway-v0", config=cfg, render_mode="rgb_array" if frames is not None else None
        ).unwrapped
        driver = FunctionDriver(env, fn)
        _, info = driver.reset(seed=seed)
        judge = Judge(result)
        dt = 1.0 / float(env.settings.simulation_frequency)
        while True:
            _, _, terminated, truncated, info = driver.step()
            judge.observe(env.scenario, info, dt)
            if frames is not None:
                frames.append(env.render())
            if terminated or truncated:
                break
        return judge.verdict()
    finally:
        if env is not None:
            env.close()
        if owned:
            close_function(fn)
