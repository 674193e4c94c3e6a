"""Lane-drop scenarios: the ego starts in a lane that ends, on the shipped maps.

The env's own start never puts the ego in a lane that ends within the episode (docs/
env.md, "Start"), so these OpenSCENARIO files do: the ego in the overtaking lane of the
2+1 road before its taper, or in the motorway's acceleration lane, handed to the
function under test from the start, and optionally traffic in the lane it must merge
into. :func:`run_lane_drops` plays them with :func:`~aldm_gym.harness.criteria.run_scenario`
(UN R157 criteria: no collision, in lane, time gap).

Written with scenariogeneration (the project's OpenSCENARIO writer; docs/scenarios.md).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aldm_gym.errors import InputError
from aldm_gym.roads.opendrive.parse import shipped_map


@dataclass(frozen=True)
class LaneDrop:
    """A lane that ends on a shipped map.

    :ivar map: the shipped map's name.
    :ivar road: the OpenDRIVE road id the ego starts on.
    :ivar lane: the lane id it starts in (the lane that ends).
    :ivar s: its start along the road [m].
    :ivar end: where the lane's taper ends along the road [m].
    :ivar target_lane: the lane id to merge into at the start (the one that goes on).
    """

    map: str
    road: str
    lane: int
    s: float
    end: float
    target_lane: int


LANE_DROPS: dict[str, LaneDrop] = {
    "two_plus_one": LaneDrop("two_plus_one", "1", -1, 50.0, 750.0, -2),
    "on_ramp": LaneDrop("motorway", "3", -4, 360.0, 750.0, -3),
}
"""The lane drops of the shipped maps: the 2+1 road's overtaking lane (the centre line
closes in from the left; merge right) and the motorway's acceleration lane (its edge
line closes in from the right; merge left)."""

TRAFFIC = ("none", "alongside", "platoon")
"""Traffic in the lane to merge into: none; one car beside the ego at its speed; five
cars 25 m apart from 25 m behind it to 75 m ahead, at its speed (no gap until the ego
has let them pass)."""


def car(name: str = "car") -> Any:
    """A 5 m x 2 m car (scenariogeneration's ``xosc.Vehicle``), reference point at the
    rear axle (box centre 1.4 m ahead)."""
    from scenariogeneration import xosc

    box = xosc.BoundingBox(2.0, 5.0, 1.8, 1.4, 0.0, 0.9)
    front = xosc.Axle(0.5, 0.8, 1.68, 2.98, 0.4)
    rear = xosc.Axle(0.0, 0.8, 1.68, 0.0, 0.4)
    return xosc.Vehicle(name, xosc.VehicleCategory.car, box, front, rear, 70, 10, 10)


def storyboard(init: Any, stop: float) -> Any:
    """A storyboard of ``init`` (an ``xosc.Init``) that stops at simulation time ``stop`` [s]."""
    from scenariogeneration import xosc

    return xosc.StoryBoard(
        init,
        xosc.ValueTrigger(
            "stop", 0, xosc.ConditionEdge.rising,
            xosc.SimulationTimeCondition(stop, xosc.Rule.greaterThan), "stop",
        ),
    )  # fmt: skip


def lane_drop_scenario(
    folder: str | Path, case: str, speed: float = 25.0, traffic: str = "none"
) -> Path:
    """Write one lane-drop scenario and return its path.

    :param folder: where to write the ``.xosc`` (the map is referenced where it lies).
    :param case: a key of :data:`LANE_DROPS`.
    :param speed: the ego's (and the traffic's) speed [m/s].
    :param traffic: one of :data:`TRAFFIC`.
    :raises InputError: an unknown case or traffic, or a speed outside (0, 70] m/s.
    """
    from scenariogeneration import xosc

    if case not in LANE_DROPS:
        raise InputError(f"unknown lane drop {case!r}; known: {sorted(LANE_DROPS)}")
    if traffic not in TRAFFIC:
        raise InputError(f"unknown traffic {traffic!r}; known: {list(TRAFFIC)}")
    if not 0.0 < speed <= 70.0:
        raise InputError(f"speed must be in (0, 70] m/s, got {speed!r}")
    drop = LANE_DROPS[case]
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)
    entities = xosc.Entities()
    entities.add_scenario_object("Ego", car("ego"))
    init = xosc.Init()
    init.add_init_action(
        "Ego", xosc.TeleportAction(xosc.LanePosition(drop.s, 0, drop.lane, drop.road))
    )
    init.add_init_action("Ego", xosc.AbsoluteSpeedAction(speed, step))
    init.add_init_action("Ego", xosc.ActivateControllerAction(True, True))
    offsets = {"none": (), "alongside": (0.0,), "platoon": (-25.0, 0.0, 25.0, 50.0, 75.0)}
    for k, ds in enumerate(offsets[traffic]):
        name = f"Car{k}"
        entities.add_scenario_object(name, car(name))
        start = xosc.LanePosition(drop.s + ds, 0, drop.target_lane, drop.road)
        init.add_init_action(name, xosc.TeleportAction(start))
        init.add_init_action(name, xosc.AbsoluteSpeedAction(speed, step))
    board = storyboard(init, (drop.end - drop.s) / speed + 20.0)
    scenario = xosc.Scenario(
        f"lane drop {case}",
        "aldm-gym",
        xosc.ParameterDeclarations(),
        entities,
        board,
        xosc.RoadNetwork(str(shipped_map(drop.map))),
        xosc.Catalog(),
    )
    path = Path(folder) / f"lane_drop_{case}_{traffic}_{speed:g}.xosc"
    scenario.write_xml(str(path))
    return path


def run_lane_drops(
    folder: str | Path,
    *,
    cases: Iterable[str] = tuple(LANE_DROPS),
    speeds: Iterable[float] = (15.0, 25.0),
    traffic: Iterable[str] = TRAFFIC,
    detectors: Iterable[str] = ("ground_truth", "aldm"),
    sources: Iterable[str] = ("map", "perception"),
    config: Mapping[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """Play every combination; one row per run: the case, speed, traffic, detector,
    ``lane_end.source`` and the :class:`~aldm_gym.harness.criteria.RunResult`'s row."""
    from aldm_gym.harness.criteria import run_scenario

    rows = []
    for case in cases:
        for speed in speeds:
            for kind in traffic:
                path = lane_drop_scenario(folder, case, speed, kind)
                for detector in detectors:
                    for source in sources:
                        cfg = dict(config or {})
                        cfg["lane_end"] = {**dict(cfg.get("lane_end", {})), "source": source}
                        result = run_scenario(path, detector=detector, config=cfg)
                        rows.append(
                            {
                                "case": case,
                                "speed": speed,
                                "traffic": kind,
                                "source": source,
                                **result.row(),
                            }
                        )
    return rows
