"""A corpus of small scenarios, one per behaviour the player must share with esmini.

Each function writes one scenario with scenariogeneration (every entity scripted) into
a folder and returns its path; :data:`CORPUS` names them all. tests/scenario/test_esmini.py
plays each in both players and compares them step by step.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from pathlib import Path

from scenariogeneration import xodr, xosc

from tests.scenario._build import (
    at_time,
    car,
    cars_and_board,
    placed,
    save,
    step_speed,
    straight_road,
    write,
)


def _event(name: str, action: object, trigger: object, priority: object = None) -> xosc.Event:
    ev = xosc.Event(name, priority or xosc.Priority.override)
    ev.add_action(f"{name}_action", action)
    ev.add_trigger(trigger)
    return ev


def _curved_road(folder: Path, radius: float = 250.0) -> Path:
    """100 m straight, a 600 m arc of ``radius`` to the left, 500 m straight; three
    lanes right of the reference line."""
    path = folder / f"curve_{radius:g}.xodr"
    if not path.exists():
        plan = [xodr.Line(100.0), xodr.Arc(1.0 / radius, 600.0), xodr.Line(500.0)]
        road = xodr.create_road(plan, id=0, left_lanes=0, right_lanes=3, lane_width=3.5)
        odr = xodr.OpenDrive("curve")
        odr.add_road(road)
        odr.adjust_roads_and_lanes()
        odr.write_xml(str(path))
    return path


def lane_change_relative(folder: Path) -> Path:
    """A sinusoidal lane change by rate to the right, into the ego's lane ahead of it."""
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.rate, 1.5)
    ev = _event("change", xosc.RelativeLaneChangeAction(-1, "Target", dyn), at_time(1.0))
    return write(folder, [("Target", [ev])], name="lane_change.xosc")


def lane_change_into_oncoming_lane(folder: Path) -> Path:
    """A lane change across the centre line onto a lane driven the other way: the
    vehicle keeps its direction of travel."""
    road = straight_road(folder, left_lanes=2)
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.cubic, xosc.DynamicsDimension.time, 3.0)
    ev = _event("overtake", xosc.AbsoluteLaneChangeAction(1, dyn), at_time(1.0))
    return write(
        folder,
        [("Target", [ev])],
        road=road,
        lane_id=-1,
        target=(0, 30.0, 15.0),
        name="oncoming_lane_change.xosc",
    )


def lane_offset_in_a_curve(folder: Path) -> Path:
    """An entity 1.2 m left of its lane centre through an arc of R 250 m keeps its own
    speed along its own path."""
    ev = _event(
        "offset",
        xosc.AbsoluteLaneOffsetAction(1.2, xosc.DynamicsShapes.sinusoidal, 1.0),
        at_time(0.5),
    )
    return write(
        folder,
        [("Target", [ev])],
        road=_curved_road(folder),
        ego_s=20.0,
        target=(0, 20.0, 20.0),
        stop=40.0,
        name="offset_curve.xosc",
    )


def speed_linear_to_its_own_speed(folder: Path) -> Path:
    """A linear speed change by rate to a target equal to the speed (in the last bits):
    it completes at once, and the next event waits for its end."""
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 0.0)
    same = _event("same", xosc.AbsoluteSpeedAction(20.000000000000004, dyn), at_time(1.0))
    after = xosc.Event("after", xosc.Priority.parallel)
    after.add_action("after_action", step_speed(10.0))
    after.add_trigger(
        xosc.ValueTrigger(
            "same_ended",
            0.0,
            xosc.ConditionEdge.none,
            xosc.StoryboardElementStateCondition(
                xosc.StoryboardElementType.action,
                "same_action",
                xosc.StoryboardElementState.endTransition,
            ),
        )
    )
    return write(folder, [("Target", [same, after])], name="speed_same.xosc")


def trajectory_without_timing(folder: Path) -> Path:
    """A polyline without timing (vertices without ``h``), driven at the entity's own
    speed, which a later speed action changes without ending the path."""
    poly = xosc.Polyline(
        [],
        [
            xosc.WorldPosition(110.0, -5.25),
            xosc.WorldPosition(160.0, -5.25),
            xosc.WorldPosition(220.0, -8.75),
            xosc.WorldPosition(300.0, -8.75),
        ],
    )
    traj = xosc.Trajectory("path", False)
    traj.add_shape(poly)
    follow = xosc.FollowTrajectoryAction(
        traj, xosc.FollowingMode.position, xosc.ReferenceContext.relative, 1, 0
    )
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.time, 2.0)
    go = _event("path", follow, at_time(0.5), xosc.Priority.parallel)
    slow = _event("slow", xosc.AbsoluteSpeedAction(12.0, dyn), at_time(2.0), xosc.Priority.parallel)
    return write(folder, [("Target", [go, slow])], stop=12.0, name="trajectory_none.xosc")


def _entity_trigger(name: str, condition: object, entity: str = "Ego") -> xosc.EntityTrigger:
    return xosc.EntityTrigger(name, 0.0, xosc.ConditionEdge.none, condition, entity)


def ttc_in_road_coordinates_and_collision(folder: Path) -> Path:
    """A slower car ahead in the ego's lane: at a road-coordinate time to collision
    below 4 s (freespace, longitudinal) it brakes harder; when the boxes touch the ego
    stops (``CollisionCondition``)."""
    ttc = xosc.TimeToCollisionCondition(
        4.0,
        xosc.Rule.lessThan,
        alongroute=False,
        freespace=True,
        entity="Target",
        distance_type=xosc.RelativeDistanceType.longitudinal,
        coordinate_system=xosc.CoordinateSystem.road,
    )
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    brake = _event("brake", xosc.AbsoluteSpeedAction(2.0, dyn), _entity_trigger("ttc", ttc))
    crash = _event(
        "crash",
        step_speed(0.0),
        _entity_trigger("touch", xosc.CollisionCondition("Target")),
    )
    return write(
        folder,
        [("Target", [brake]), ("Ego", [crash])],
        target=(0, 40.0, 10.0),
        stop=15.0,
        name="ttc_collision.xosc",
    )


def story_parameters_and_relative_road_position(folder: Path) -> Path:
    """A story declares its own parameter; a teleport to a ``RelativeRoadPosition``
    from the ego uses it; an ``EndOfRoad`` of the target ends the scenario."""
    params = xosc.ParameterDeclarations()
    params.add_parameter(xosc.Parameter("Ahead", xosc.ParameterType.double, "25.0"))
    story = xosc.Story("jump", params)
    act = xosc.Act("jump_act", at_time(0.0))
    group = xosc.ManeuverGroup("jump_group")
    group.add_actor("Target")
    man = xosc.Maneuver("jump_maneuver")
    man.add_event(
        _event(
            "jump",
            xosc.TeleportAction(xosc.RelativeRoadPosition("$Ahead", -3.5, "Ego")),
            at_time(2.0),
        )
    )
    group.add_maneuver(man)
    act.add_maneuver_group(group)
    story.add_act(act)
    return write(folder, stories=[story], target=(1, 60.0, 25.0), name="story_params.xosc")


def stand_still_and_acquire_position(folder: Path) -> Path:
    """The target brakes to a stop; once it has stood still for 1 s it drives on to a
    position along its lane (``AcquirePositionAction``)."""
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 5.0)
    stop = _event("stop", xosc.AbsoluteSpeedAction(0.0, dyn), at_time(1.0))
    still = _entity_trigger("still", xosc.StandStillCondition(1.0), "Target")
    go = _event("go", xosc.AbsoluteSpeedAction(8.0, dyn), still, xosc.Priority.parallel)
    acquire = _event(
        "acquire",
        xosc.AcquirePositionAction(xosc.LanePosition(400.0, 0, -1, 0)),
        at_time(0.5),
        xosc.Priority.parallel,
    )
    return write(folder, [("Target", [stop, go, acquire])], stop=12.0, name="standstill.xosc")


def distance_rigid_before_its_reference(folder: Path) -> Path:
    """A rigid continuous ``LongitudinalDistanceAction`` (no ``DynamicConstraints``)
    behind the ego, which is written after it in the file and changes its speed: the
    actor keeps the gap, whatever the entities' order."""
    follow = _event(
        "follow",
        xosc.LongitudinalDistanceAction("Ego", freespace=True, continuous=True, distance=15.0),
        at_time(0.5),
    )
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 3.0)
    slow = _event("slow", xosc.AbsoluteSpeedAction(12.0, dyn), at_time(2.0))
    return write(
        folder,
        [("Target", [follow]), ("Ego", [slow])],
        target=(0, -40.0, 20.0),
        target_first=True,
        name="distance_rigid.xosc",
    )


def distance_with_dynamic_constraints(folder: Path) -> Path:
    """A ``LongitudinalDistanceAction`` by time gap with ``DynamicConstraints`` (limits
    on acceleration, deceleration, their rates, and speed) closing on the ego."""
    follow = _event(
        "close",
        xosc.LongitudinalDistanceAction(
            "Ego",
            freespace=False,
            continuous=True,
            max_acceleration=3.0,
            max_deceleration=4.0,
            max_speed=30.0,
            timeGap=1.5,
            max_acceleration_rate=2.0,
            max_deceleration_rate=3.0,
        ),
        at_time(0.5),
    )
    return write(
        folder,
        [("Target", [follow])],
        ego_s=150.0,
        target=(0, -80.0, 20.0),
        stop=20.0,
        name="distance_dyn.xosc",
    )


def parameter_and_variable_actions(folder: Path) -> Path:
    """A variable counted up by a repeated event; at 3 another is set, and its new
    value starts the target's speed change."""
    variables = xosc.VariableDeclarations()
    variables.add_variable(xosc.Variable("Count", xosc.ParameterType.int, "0"))
    variables.add_variable(xosc.Variable("Go", xosc.ParameterType.double, "0"))
    bump = xosc.Event("bump", xosc.Priority.parallel, maxexecution=3)
    bump.add_action("bump_action", xosc.VariableAddAction("Count", 1))
    bump.add_trigger(at_time(1.0))
    go = _event(
        "go",
        xosc.VariableSetAction("Go", 1.5),
        xosc.ValueTrigger(
            "counted", 0.0, xosc.ConditionEdge.none,
            xosc.VariableCondition("Count", 3, xosc.Rule.equalTo),
        ),
        xosc.Priority.parallel,
    )  # fmt: skip
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    slow = _event(
        "slow",
        xosc.AbsoluteSpeedAction(10.0, dyn),
        xosc.ValueTrigger(
            "set", 0.0, xosc.ConditionEdge.none,
            xosc.VariableCondition("Go", 1.0, xosc.Rule.greaterThan),
        ),
        xosc.Priority.parallel,
    )  # fmt: skip
    return write(
        folder,
        [("Target", [bump, go, slow])],
        variables=variables,
        name="parameters_variables.xosc",
    )


def speed_profile(folder: Path) -> Path:
    """A ``SpeedProfileAction``: three speeds, two with a time, one as fast as the
    dynamic constraints allow."""
    profile = xosc.SpeedProfileAction(
        [25.0, 15.0, 18.0],
        xosc.FollowingMode.position,
        times=[2.0, 3.0, None],  # type: ignore[list-item]
        dynamics_constraint=xosc.DynamicsConstraints(2.0, 3.0, 40.0),
    )
    path = write(
        folder,
        [("Target", [_event("profile", profile, at_time(1.0))])],
        stop=12.0,
        name="speed_profile.xosc",
    )
    path.write_text(path.read_text().replace(' time="None"', ""))  # the third has no time
    return path


def _follow(shape: object, timed: bool) -> xosc.FollowTrajectoryAction:
    traj = xosc.Trajectory("shape", False)
    traj.add_shape(shape)
    if timed:
        return xosc.FollowTrajectoryAction(
            traj, xosc.FollowingMode.position, xosc.ReferenceContext.relative, 1, 0
        )
    return xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.position)


def clothoid_trajectories(folder: Path) -> Path:
    """A clothoid without timing (the target, at its speed) and a timed one (the ego)."""
    untimed = xosc.Clothoid(0.0, -0.00002, 120.0, xosc.WorldPosition(112.0, -1.75, 0, 0))
    timed = xosc.Clothoid(0.001, -0.00002, 80.0, xosc.WorldPosition(70.0, -5.25, 0, 0), 0.0, 5.0)
    return write(
        folder,
        [
            ("Target", [_event("curl", _follow(untimed, False), at_time(0.5))]),
            ("Ego", [_event("timed", _follow(timed, True), at_time(0.9))]),
        ],
        stop=9.0,
        name="clothoids.xosc",
    )


def nurbs_trajectory(folder: Path) -> Path:
    """Rational B-splines without timing: order 3 with one weight above 1, and order 4."""
    weighted = xosc.Nurbs(3)
    for x, y, w in ((112, -1.75, 1), (140, -1.75, 1), (160, -5.0, 2), (200, -5.25, 1)):
        weighted.add_control_point(xosc.ControlPoint(xosc.WorldPosition(x, y), weight=w))
    weighted.add_knots([0, 0, 0, 1, 2, 2, 2])
    untimed = xosc.Nurbs(4)
    for x, y in ((70, -5.25), (100, -5.25), (120, -8.75), (160, -8.75)):
        untimed.add_control_point(xosc.ControlPoint(xosc.WorldPosition(x, y)))
    untimed.add_knots([0, 0, 0, 0, 1, 1, 1, 1])
    return write(
        folder,
        [
            ("Target", [_event("bend", _follow(weighted, False), at_time(0.5))]),
            ("Ego", [_event("swerve", _follow(untimed, False), at_time(0.9))]),
        ],
        stop=8.0,
        name="nurbs.xosc",
    )  # fmt: skip


def state_conditions(folder: Path) -> Path:
    """Conditions on an entity's state: the target's acceleration, the clearance of
    the lane left of the ego, the ego's distance to a position in road coordinates."""
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    speed_up = _event("speed_up", xosc.AbsoluteSpeedAction(30.0, dyn), at_time(1.0))
    accelerating = _entity_trigger(
        "accelerating", xosc.AccelerationCondition(1.5, xosc.Rule.greaterThan), "Target"
    )
    shift = xosc.AbsoluteLaneOffsetAction(-0.5, xosc.DynamicsShapes.sinusoidal, 1.0)
    clearance = xosc.RelativeClearanceCondition(False, 10.0, 20.0, True)
    clearance.add_relative_lane_range(1, 1)
    faster = _event(
        "faster", step_speed(25.0), _entity_trigger("clear", clearance), xosc.Priority.parallel
    )
    near = xosc.DistanceCondition(
        40.0,
        xosc.Rule.lessThan,
        xosc.LanePosition(400.0, 0, -2, 0),
        alongroute=False,
        freespace=False,
        distance_type=xosc.RelativeDistanceType.longitudinal,
        coordinate_system=xosc.CoordinateSystem.road,
    )
    slow = _event("slow", step_speed(10.0), _entity_trigger("near", near), xosc.Priority.parallel)
    return write(
        folder,
        [
            ("Target", [speed_up]),
            ("Ego", [_event("shift", shift, accelerating), faster, slow]),
        ],
        target=(1, 5.0, 20.0),
        stop=16.0,
        name="state_conditions.xosc",
    )


def synchronize(folder: Path) -> Path:
    """The target arrives at s = 300 m of its lane when the ego arrives at s = 300 m of
    its own, at 15 m/s held over the last 20 m."""
    sync = xosc.SynchronizeAction(
        "Ego",
        xosc.LanePosition(300.0, 0, -2, 0),
        xosc.LanePosition(300.0, 0, -1, 0),
        1.0,
        1.0,
        xosc.AbsoluteSpeed(15.0, xosc.TargetDistanceSteadyState(20.0)),
    )
    return write(
        folder,
        [("Target", [_event("sync", sync, at_time(0.5))])],
        target=(1, 60.0, 20.0),
        stop=14.0,
        name="synchronize.xosc",
    )


def turned_round_and_braking_in_a_lane_change(folder: Path) -> Path:
    """On a lane driven the other way, the target faces and drives along ``s`` (turned
    round on its lane) and changes lanes; a brake starts during its lane change."""
    road = straight_road(folder, left_lanes=2)
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 3.0)
    change = _event("change", xosc.AbsoluteLaneChangeAction(-1, dyn), at_time(1.0))
    brake_dyn = xosc.TransitionDynamics(
        xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 4.0
    )
    brake = _event(
        "brake", xosc.AbsoluteSpeedAction(8.0, brake_dyn), at_time(2.0), xosc.Priority.parallel
    )
    path = write(
        folder,
        [("Target", [change, brake])],
        road=road,
        lane_id=-1,
        target=(0, 30.0, 15.0),
        name="turned_round.xosc",
    )
    # the target on lane 1 (driven against s), turned round: it faces along s
    text = path.read_text()
    marker = '<RelativeLanePosition entityRef="Ego" ds="30.0" offset="0.0" dLane="0"/>'
    assert marker in text
    text = text.replace(
        marker,
        '<LanePosition roadId="0" laneId="1" s="80.0" offset="0.0">'
        '<Orientation type="relative" h="3.141592653589793"/></LanePosition>',
    )
    path.write_text(text)
    return path


def trajectory_and_route_positions(folder: Path) -> Path:
    """Teleports to a ``TrajectoryPosition`` (30 m along a polyline, 0.5 m to its
    left) and to a ``RoutePosition`` (100 m along a route, on another lane)."""
    poly = xosc.Polyline([], [xosc.WorldPosition(100.0, -1.75), xosc.WorldPosition(200.0, -5.25)])
    traj = xosc.Trajectory("path", False)
    traj.add_shape(poly)
    jump = xosc.TeleportAction(xosc.TrajectoryPosition(traj, 30.0, 0.5))
    route = xosc.Route("route")
    route.add_waypoint(xosc.LanePosition(60.0, 0, -2, 0), xosc.RouteStrategy.shortest)
    route.add_waypoint(xosc.LanePosition(900.0, 0, -2, 0), xosc.RouteStrategy.shortest)
    hop = xosc.TeleportAction(xosc.RoutePositionInLaneCoordinates(route, 100.0, -3, 0.5))
    return write(
        folder,
        [
            ("Target", [_event("jump", jump, at_time(1.0))]),
            ("Ego", [_event("hop", hop, at_time(2.0))]),
        ],
        name="trajectory_route_positions.xosc",
    )


def speed_shapes_and_priorities(folder: Path) -> Path:
    """Speed changes of every shape and dimension, and event priorities: a cubic by
    rate, a step skipped while it runs, a sinusoid by time in parallel once the target
    has travelled 60 m, a linear by distance overriding it when the target is 2 m/s
    faster than the ego."""
    cubic = xosc.TransitionDynamics(xosc.DynamicsShapes.cubic, xosc.DynamicsDimension.rate, 2.0)
    sine = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    by_distance = xosc.TransitionDynamics(
        xosc.DynamicsShapes.linear, xosc.DynamicsDimension.distance, 40.0
    )
    first = _event("cubic", xosc.AbsoluteSpeedAction(25.0, cubic), at_time(1.0))
    skipped = _event("skipped", step_speed(5.0), at_time(1.5), xosc.Priority.skip)
    travelled = _entity_trigger("travelled", xosc.TraveledDistanceCondition(60.0), "Target")
    sinus = _event("sinus", xosc.AbsoluteSpeedAction(15.0, sine), travelled, xosc.Priority.parallel)
    faster = _entity_trigger(
        "faster", xosc.RelativeSpeedCondition(2.0, xosc.Rule.greaterThan, "Ego"), "Target"
    )
    last = _event("distance", xosc.AbsoluteSpeedAction(20.0, by_distance), faster)
    return write(
        folder,
        [("Target", [first, skipped, sinus, last])],
        stop=12.0,
        name="speed_shapes.xosc",
    )


def reach_headway_and_route(folder: Path) -> Path:
    """The ego shifts in its lane when it comes within 2 m of a world position
    (``DistanceCondition``, euclidean, between reference points); the target speeds
    up once its time headway to the ego (entity coordinates, longitudinal, freespace)
    falls below 2.5 s; the target's route along its lane is assigned; a teleport to a
    position relative to the ego (RelativeObjectPosition) and one to a RoadPosition."""
    reach = _entity_trigger(
        "reach",
        xosc.DistanceCondition(
            2.0, xosc.Rule.lessThan, xosc.WorldPosition(150.0, -5.25), False, False
        ),
    )
    shift = xosc.AbsoluteLaneOffsetAction(0.6, xosc.DynamicsShapes.step, 1.0)
    headway = _entity_trigger(
        "close",
        xosc.TimeHeadwayCondition(
            "Target",
            2.5,
            xosc.Rule.lessThan,
            alongroute=False,
            freespace=True,
            distance_type=xosc.RelativeDistanceType.longitudinal,
            coordinate_system=xosc.CoordinateSystem.entity,
        ),
    )
    route = xosc.Route("along")
    route.add_waypoint(xosc.LanePosition(60.0, 0, -1, 0), xosc.RouteStrategy.shortest)
    route.add_waypoint(xosc.LanePosition(600.0, 0, -1, 0), xosc.RouteStrategy.shortest)
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 3.0)
    beside = xosc.TeleportAction(xosc.RelativeObjectPosition("Ego", 12.0, 3.5))
    on_road = xosc.TeleportAction(xosc.RoadPosition(400.0, -8.75, 0))
    return write(
        folder,
        [
            ("Ego", [_event("shift", shift, reach)]),
            (
                "Target",
                [
                    _event("route", xosc.AssignRouteAction(route), at_time(0.2)),
                    _event("away", xosc.AbsoluteSpeedAction(12.0, dyn), at_time(0.5),
                           xosc.Priority.parallel),
                    _event("speed_up", xosc.AbsoluteSpeedAction(30.0, dyn), headway,
                           xosc.Priority.parallel),
                    _event("beside", beside, at_time(6.0), xosc.Priority.parallel),
                    _event("on_road", on_road, at_time(8.0), xosc.Priority.parallel),
                ],
            ),
        ],
        target=(1, 30.0, 20.0),
        stop=10.0,
        name="reach_headway_route.xosc",
    )  # fmt: skip


def entities_deleted_and_added(folder: Path) -> Path:
    """``EntityAction``: the target is deleted at 2 s and added back at 5 s on
    another lane (at the speed it had); a third car that ``Init`` deletes and does
    not place is added 40 m ahead of the ego at 3 s, given a speed in the same step;
    an event on the target's speed waits while it is gone and starts once it is back."""
    init = xosc.Init()
    init.add_init_action("Ego", xosc.TeleportAction(xosc.LanePosition(50.0, 0, -2, 0)))
    init.add_init_action("Ego", step_speed(20.0))
    init.add_init_action(
        "Target", xosc.TeleportAction(xosc.RelativeLanePosition(lane_id=1, entity="Ego", ds=60.0))
    )
    init.add_init_action("Target", step_speed(20.0))
    init.add_global_action(xosc.DeleteEntityAction("Late"))
    entities, board = cars_and_board(("Ego", "Target", "Late"), init, 9.0)
    target = xosc.Maneuver("target")
    target.add_event(_event("delete", xosc.DeleteEntityAction("Target"), at_time(2.0)))
    back = xosc.AddEntityAction("Target", xosc.LanePosition(250.0, 0, -3, 0))
    target.add_event(_event("add_back", back, at_time(5.0), xosc.Priority.parallel))
    late = xosc.Maneuver("late")
    ahead = xosc.RelativeLanePosition(lane_id=-1, entity="Ego", ds=40.0)
    arrive = xosc.AddEntityAction("Late", ahead)
    late.add_event(_event("arrive", arrive, at_time(3.0)))
    late.add_event(_event("late_speed", step_speed(15.0), at_time(3.0), xosc.Priority.parallel))
    waiting = xosc.ConditionGroup()
    waiting.add_condition(at_time(4.0))
    waiting.add_condition(
        _entity_trigger("target_fast", xosc.SpeedCondition(10.0, xosc.Rule.greaterThan), "Target")
    )
    ego = xosc.Maneuver("ego")
    ego.add_event(_event("on_target_speed", step_speed(25.0), waiting))
    board.add_maneuver(target, "Target")
    board.add_maneuver(late, "Late")
    board.add_maneuver(ego, "Ego")
    return save(folder, "entities.xosc", entities, board)


def angle_conditions(folder: Path) -> Path:
    """``AngleCondition`` (1.3) on an arc of R 250 m: the target speeds up when its
    world heading (no coordinate system given) is within 0.02 rad of 0.3; the ego
    changes lanes at 4 s, in the arc, and slows down when its heading leaves the road's
    direction (road coordinates, falling edge) and again when it is 0.03 rad right of
    its lane's direction (lane coordinates)."""

    def heading(angle: float, tolerance: float, system: object) -> object:
        return xosc.AngleCondition(angle, tolerance, xosc.AngleType.heading, system)

    def trig(name: str, condition: object, entity: str, edge: object = None) -> object:
        return xosc.EntityTrigger(name, 0, edge or xosc.ConditionEdge.none, condition, entity)

    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 3.0)
    turning = trig("turning", heading(0.3, 0.02, xosc.CoordinateSystem.world), "Target")
    leaves = trig(
        "leaves", heading(0.0, 0.005, xosc.CoordinateSystem.road), "Ego", xosc.ConditionEdge.falling
    )
    askew = trig("askew", heading(-0.03, 0.01, xosc.CoordinateSystem.lane), "Ego")
    path = write(
        folder,
        [
            ("Target", [_event("world", step_speed(25.0), turning)]),
            (
                "Ego",
                [
                    _event("change", xosc.RelativeLaneChangeAction(-1, "Ego", dyn), at_time(4.0)),
                    _event("road", step_speed(18.0), leaves, xosc.Priority.parallel),
                    _event("lane", step_speed(16.0), askew, xosc.Priority.parallel),
                ],
            ),
        ],
        road=_curved_road(folder),
        ego_s=20.0,
        lane_id=-1,
        target=(0, 30.0, 20.0),
        stop=12.0,
        name="angles.xosc",
    )
    # the world's is the standard's default coordinate system: leave it out
    path.write_text(path.read_text().replace(' coordinateSystem="world"', ""))
    return path


def road_end_off_road_and_relative_world(folder: Path) -> Path:
    """A third car is teleported 60 m ahead of and 3.5 m right of the ego
    (``RelativeWorldPosition``) and pushed off the road by a lane offset; the ego
    slows down once it has been off road for 0.5 s (``OffroadCondition``); the target,
    40 m before the road's end, stops there and the ego speeds up once it has been at
    the end for 1 s (``EndOfRoadCondition``)."""
    init = xosc.Init()
    init.add_init_action("Ego", xosc.TeleportAction(xosc.LanePosition(1850.0, 0, -2, 0)))
    init.add_init_action("Ego", step_speed(10.0))
    init.add_init_action("Target", xosc.TeleportAction(xosc.LanePosition(1960.0, 0, -1, 0)))
    init.add_init_action("Target", step_speed(20.0))
    init.add_init_action("Side", xosc.TeleportAction(xosc.LanePosition(1800.0, 0, -3, 0)))
    init.add_init_action("Side", step_speed(10.0))
    entities, board = cars_and_board(("Ego", "Target", "Side"), init, 8.0)
    side = xosc.Maneuver("side")
    beside = xosc.TeleportAction(xosc.RelativeWorldPosition("Ego", 60.0, -3.5, 0.0))
    side.add_event(_event("beside", beside, at_time(0.5)))
    push = xosc.AbsoluteLaneOffsetAction(-3.0, xosc.DynamicsShapes.linear, 1.0)
    side.add_event(_event("push", push, at_time(1.0), xosc.Priority.parallel))
    board.add_maneuver(side, "Side")
    ego = xosc.Maneuver("ego")
    off = _entity_trigger("off", xosc.OffroadCondition(0.5), "Side")
    ego.add_event(_event("slow", step_speed(8.0), off))
    at_end = _entity_trigger("at_end", xosc.EndOfRoadCondition(1.0), "Target")
    ego.add_event(_event("fast", step_speed(14.0), at_end, xosc.Priority.parallel))
    board.add_maneuver(ego, "Ego")
    return save(folder, "road_end.xosc", entities, board)


def lateral_distances(folder: Path) -> Path:
    """``LateralDistanceAction`` in road coordinates beside an ego that shifts in its
    lane: the target 1 m left of it between the boxes, put there at every step
    (continuous); a third car 4 m right of it (reference points) with a spring of
    3 m/s² and 1.5 m/s, ending once there; a fourth car 3.5 m left of the target at
    1 m/s alone (continuous)."""
    init = placed((
        ("Ego", -2, 50.0, 20.0), ("Target", -1, 60.0, 20.0),
        ("Side", -3, 70.0, 20.0), ("Far", -1, 40.0, 20.0),
    ))  # fmt: skip
    entities, board = cars_and_board(("Ego", "Target", "Side", "Far"), init, 10.0)
    left = xosc.LateralDisplacement.leftToReferencedEntity
    right = xosc.LateralDisplacement.rightToReferencedEntity

    def keep(ref: str, d: float, free: bool, side: object, cont: bool, **dc: float) -> object:
        return xosc.LateralDistanceAction(
            ref, d, freespace=free, continuous=cont, displacement=side,
            coordinate_system=xosc.CoordinateSystem.road, **dc,
        )  # fmt: skip

    events = [
        ("Target", _event("rigid", keep("Ego", 1.0, True, left, True), at_time(1.0))),
        (
            "Side",
            _event(
                "spring",
                keep("Ego", 4.0, False, right, False, max_acceleration=3.0, max_speed=1.5),
                at_time(1.0),
            ),
        ),
        (
            "Far",
            _event("speed", keep("Target", 3.5, False, left, True, max_speed=1.0), at_time(2.0)),
        ),
    ]
    for name, ev in events:
        man = xosc.Maneuver(f"m_{name}")
        man.add_event(ev)
        board.add_maneuver(man, name)
    shift = xosc.Maneuver("shift")
    offset = xosc.AbsoluteLaneOffsetAction(-0.6, xosc.DynamicsShapes.sinusoidal, 0.5)
    shift.add_event(_event("shift", offset, at_time(4.0)))
    board.add_maneuver(shift, "Ego")
    return save(folder, "lateral_distances.xosc", entities, board)


def jerk_limited_speed_profiles(folder: Path) -> Path:
    """``SpeedProfileAction`` with ``followingMode="follow"`` and jerk limits, as esmini
    plans it: the target from 20 to 12 m/s in 4 s (on time, a held deceleration); the
    ego to 30 m/s in 2 s (too short for the jerks and past the acceleration limit:
    later); a third car through three timed speeds (the corners cut by the jerks) and
    an untimed one."""
    init = placed((("Ego", -2, 50.0, 20.0), ("Target", -1, 80.0, 20.0),
                             ("Third", -3, 30.0, 15.0)))  # fmt: skip
    entities, board = cars_and_board(("Ego", "Target", "Third"), init, 16.0)

    def follow(speeds: list[float], times: list[float | None], *dc: float) -> object:
        return xosc.SpeedProfileAction(
            speeds, xosc.FollowingMode.follow, times=times,  # type: ignore[arg-type]
            dynamics_constraint=xosc.DynamicsConstraints(*dc),
        )  # fmt: skip

    plans = [
        ("Target", follow([12.0], [4.0], 5.0, 4.0, 50.0, 2.0, 3.0)),
        ("Ego", follow([30.0], [2.0], 3.0, 6.0, 50.0, 1.5, 2.0)),
        (
            "Third",
            follow([25.0, 18.0, 22.0, 10.0], [3.0, 3.0, 2.0, None], 4.0, 3.0, 50.0, 4.0, 3.0),
        ),
    ]
    for name, profile in plans:
        man = xosc.Maneuver(f"m_{name}")
        man.add_event(_event(f"profile_{name}", profile, at_time(1.0)))
        board.add_maneuver(man, name)
    path = save(folder, "jerk_profiles.xosc", entities, board)
    path.write_text(path.read_text().replace(' time="None"', ""))  # the last has no time
    return path


def _truck(trailer: object = None) -> xosc.Vehicle:
    """A 7 m tractor with its hitch (a fifth wheel) 0.5 m ahead of its rear axle: a
    trailer coupled to it overlaps its box."""
    bb = xosc.BoundingBox(2.5, 7.0, 3.0, 2.5, 0.0, 1.5)
    front, rear = xosc.Axle(0.5, 0.8, 2.3, 5.0, 0.5), xosc.Axle(0.0, 0.8, 2.3, 0.0, 0.5)
    return xosc.Vehicle(
        "truck", xosc.VehicleCategory.truck, bb, front, rear, 40, 3, 6,
        trailer_hitch=xosc.HitchCoupler(0.5), trailer=trailer,
    )  # fmt: skip


def _trailer(name: str) -> xosc.Vehicle:
    """A 10 m trailer with its coupler 8 m ahead of its axle."""
    bb = xosc.BoundingBox(2.5, 10.0, 3.0, 3.0, 0.0, 1.5)
    front, rear = xosc.Axle(0.0, 0.8, 2.3, 8.0, 0.5), xosc.Axle(0.0, 0.8, 2.3, 0.0, 0.5)
    return xosc.Vehicle(
        name, xosc.VehicleCategory.trailer, bb, front, rear, 40, 3, 6,
        trailer_coupler=xosc.HitchCoupler(8.0),
    )  # fmt: skip


def trailers(folder: Path) -> Path:
    """Trailers on an arc of R 250 m: a truck towing a trailer defined inside it
    changes lanes in the arc; another connects a trailer driving on the next lane at
    1 s (it swings in behind it) and disconnects it at 6 s (it goes on by itself)."""
    entities = xosc.Entities()
    entities.add_scenario_object("Ego", car())
    entities.add_scenario_object("Loose", _trailer("loose"))
    inline = xosc.ScenarioObject("Towed", _trailer("towed"))
    entities.add_scenario_object("Truck", _truck(inline))
    entities.add_scenario_object("Hauler", _truck())
    init = placed((
        ("Ego", -1, 20.0, 15.0), ("Truck", -2, 60.0, 15.0),
        ("Hauler", -3, 120.0, 15.0), ("Loose", -2, 95.0, 12.0),
    ))  # fmt: skip
    board = xosc.StoryBoard(
        init,
        xosc.ValueTrigger(
            "stop", 0, xosc.ConditionEdge.rising,
            xosc.SimulationTimeCondition(12.0, xosc.Rule.greaterThan), "stop",
        ),
    )  # fmt: skip
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 4.0)
    truck = xosc.Maneuver("truck")
    truck.add_event(_event("change", xosc.AbsoluteLaneChangeAction(-1, dyn), at_time(4.0)))
    board.add_maneuver(truck, "Truck")
    hauler = xosc.Maneuver("hauler")
    hauler.add_event(_event("connect", xosc.ConnectTrailerAction("Loose"), at_time(1.0)))
    hauler.add_event(
        _event("disconnect", xosc.DisconnectTrailerAction(), at_time(6.0), xosc.Priority.parallel)
    )
    board.add_maneuver(hauler, "Hauler")
    scenario = xosc.Scenario(
        "trailers", "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(_curved_road(folder))), xosc.Catalog(),
    )  # fmt: skip
    path = folder / "trailers.xosc"
    scenario.write_xml(str(path))
    return path


def actions_in_document_order(folder: Path) -> Path:
    """esmini steps actions in document order, then moves the entities no action moves:
    ``Over`` keeps 0.5 m left of ``Ego`` (continuous ``LateralDistanceAction``, written
    before ``Ego``'s lane change, so it sees ``Ego`` where it was at the start of the
    step), ``Tail`` rides 15 m behind ``Ego`` (rigid ``LongitudinalDistanceAction``,
    written after the lane change, so it is placed from where ``Ego`` already is)."""
    init = placed((
        ("Ego", -3, 50.0, 30.0), ("Over", -2, 60.0, 30.0), ("Tail", -3, 35.0, 30.0),
    ))  # fmt: skip
    entities, board = cars_and_board(("Ego", "Over", "Tail"), init, 12.0)
    keep = xosc.LateralDistanceAction(
        "Ego", 0.5, freespace=True, continuous=True, max_speed=2.0,
        displacement=xosc.LateralDisplacement.leftToReferencedEntity,
        coordinate_system=xosc.CoordinateSystem.road,
    )  # fmt: skip
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    tail = xosc.LongitudinalDistanceAction(
        "Ego", freespace=False, continuous=True, distance=15.0,
        coordinate_system=xosc.CoordinateSystem.road,
        displacement=xosc.LongitudinalDisplacement.trailingReferencedEntity,
    )  # fmt: skip
    for actor, event in (
        ("Over", _event("keep", keep, at_time(1.0))),
        ("Ego", _event("change", xosc.RelativeLaneChangeAction(1, "Ego", dyn), at_time(2.0))),
        ("Tail", _event("tail", tail, at_time(1.0))),
    ):
        man = xosc.Maneuver(f"m_{actor}")
        man.add_event(event)
        board.add_maneuver(man, actor)
    return save(folder, "actions_in_document_order.xosc", entities, board)


def relative_speed_before_its_reference(folder: Path) -> Path:
    """The target keeps 2 m/s below the ego (continuous ``RelativeTargetSpeed``),
    written before the ego's linear slowdown: esmini steps it first, on the ego's
    speed of the step before."""
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0)
    follow = xosc.RelativeSpeedAction(-2.0, "Ego", dyn, continuous=True)
    linear = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 1.0)
    events = [
        ("Target", [_event("follow", follow, at_time(0.5))]),
        ("Ego", [_event("slow", xosc.AbsoluteSpeedAction(14.0, linear), at_time(1.0))]),
    ]
    return write(folder, events, target=(1, 30.0, 25.0), name="relative_speed.xosc")


def _story(name: str, actor: str, event: xosc.Event, start: object = None) -> xosc.Story:
    """A story of one act (started by ``start``, at once without) of one event."""
    man = xosc.Maneuver(f"{name}_maneuver")
    man.add_event(event)
    group = xosc.ManeuverGroup(f"{name}_group")
    group.add_actor(actor)
    group.add_maneuver(man)
    act = xosc.Act(f"{name}_act", start)
    act.add_maneuver_group(group)
    story = xosc.Story(name)
    story.add_act(act)
    return story


def _around_a_step(
    trigger: Callable[[str], xosc.EntityTrigger], watcher: str, stepper: str, speed: float
) -> list[xosc.Story]:
    """Stories around a step ``SpeedAction`` of ``stepper`` (to ``speed`` [m/s] at 1 s):
    one before it, whose act (started by ``trigger(name)``) shifts ``watcher`` 0.5 m
    in its lane, and one after it, whose act sets ``watcher`` to 10 m/s."""
    shift = _event(
        "shift",
        xosc.AbsoluteLaneOffsetAction(0.5, xosc.DynamicsShapes.sinusoidal, 1.0),
        at_time(0.0, name="now"),
    )
    slow = _event("slow_down", step_speed(10.0), at_time(0.0, name="now"))
    return [
        _story("before", watcher, shift, trigger("c_before")),
        _story("speed_up", stepper, _event("speed_up", step_speed(speed), at_time(1.0))),
        _story("after", watcher, slow, trigger("c_after")),
    ]


def speed_condition_in_the_update_of_a_step(folder: Path) -> Path:
    """A ``SpeedCondition`` on the target, whose step ``SpeedAction`` starts at 1 s: an
    act in a story before the target's sees the new speed one update later (its
    condition was evaluated before the action started), an act in a story after it
    in the same update (esmini sets the speed as the action starts)."""

    def fast(name: str) -> xosc.EntityTrigger:
        rule = xosc.Rule.greaterThan
        return xosc.EntityTrigger(
            name, 0, xosc.ConditionEdge.none, xosc.SpeedCondition(25.0, rule), "Target"
        )

    stories = _around_a_step(fast, "Ego", "Target", 30.0)
    return write(folder, stories=stories, stop=6.0, name="speed_condition_in_the_update.xosc")


def headway_condition_in_the_update_of_a_step(folder: Path) -> Path:
    """A ``TimeHeadwayCondition`` (< 2 s) from the ego to the target 60 m ahead, whose
    speed a step ``SpeedAction`` raises from 20 to 40 m/s at 1 s: an act in a story
    after it starts in the same update, one in a story before it an update later."""

    def close(name: str) -> xosc.EntityTrigger:
        headway = xosc.TimeHeadwayCondition("Target", 2.0, xosc.Rule.lessThan, freespace=False)
        return xosc.EntityTrigger(name, 0, xosc.ConditionEdge.none, headway, "Ego")

    stories = _around_a_step(close, "Target", "Ego", 40.0)
    return write(folder, stories=stories, stop=6.0, target=(0, 60.0, 20.0), name="headway.xosc")


def clothoid_spline(folder: Path) -> Path:
    """``ClothoidSpline`` (1.3): the target, untimed, along three segments from a start
    position (a bend left and back, the second segment turned by ``hOffset``); the
    ego, timed, along three segments with a start time each and an end time."""
    untimed = xosc.ClothoidSpline([
        xosc.ClothoidSplineSegment(
            0.0, 0.004, 40.0, position_start=[xosc.WorldPosition(112.0, -1.75, 0, 0)]
        ),
        xosc.ClothoidSplineSegment(0.004, -0.004, 40.0, h_offset=0.05),
        xosc.ClothoidSplineSegment(-0.004, 0.0, 40.0),
    ])  # fmt: skip
    timed = xosc.ClothoidSpline([
        xosc.ClothoidSplineSegment(
            0.0, -0.003, 50.0, time_start=0.0,
            position_start=[xosc.WorldPosition(70.0, -5.25, 0, 0)],
        ),
        xosc.ClothoidSplineSegment(-0.003, 0.003, 50.0, time_start=2.5),
        xosc.ClothoidSplineSegment(0.003, 0.0, 50.0, time_start=5.0),
    ], time_end=7.5)  # fmt: skip
    return write(
        folder,
        [
            ("Target", [_event("bend", _follow(untimed, False), at_time(0.5))]),
            ("Ego", [_event("timed", _follow(timed, True), at_time(0.9))]),
        ],
        stop=11.0,
        name="clothoid_spline.xosc",
    )


def object_kinds_and_collision_by_type(folder: Path) -> Path:
    """A ``MiscObject`` (an obstacle in the left lane) and a ``Pedestrian`` (on the
    right edge, walking along the road once the ego is within 60 m of it); the ego
    changes lanes when the target hits any miscellaneous object (``CollisionCondition``
    ``ByType``)."""
    init = placed((("Ego", -2, 50.0, 20.0), ("Target", -1, 80.0, 20.0),
                   ("Third", -3, 60.0, 18.0)))  # fmt: skip
    init.add_init_action("Cone", xosc.TeleportAction(xosc.LanePosition(260.0, 0, -1, 0)))
    init.add_init_action("Walker", xosc.TeleportAction(xosc.LanePosition(280.0, -1.0, -3, 0)))
    entities, board = cars_and_board(("Ego", "Target", "Third"), init, 14.0)
    cone = xosc.MiscObject(
        "cone", 50.0, xosc.MiscObjectCategory.obstacle,
        xosc.BoundingBox(1.0, 1.0, 1.0, 0.0, 0.0, 0.5),
    )  # fmt: skip
    entities.add_scenario_object("Cone", cone)
    walker = xosc.Pedestrian(
        "walker", 80.0, xosc.PedestrianCategory.pedestrian,
        xosc.BoundingBox(0.5, 0.6, 1.8, 0.0, 0.0, 0.9),
    )  # fmt: skip
    entities.add_scenario_object("Walker", walker)
    for name in ("Ego", "Target", "Third"):
        slow = xosc.Maneuver(f"slow_{name}")
        slow.add_event(_event("slow", step_speed(15.0), at_time(1.0)))
        board.add_maneuver(slow, name)
    hit = xosc.EntityTrigger(
        "hit", 0, xosc.ConditionEdge.rising,
        xosc.CollisionCondition(xosc.ObjectType.miscellaneous), "Target",
    )  # fmt: skip
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 2.0)
    dodge = xosc.Maneuver("dodge")
    dodge.add_event(_event("right", xosc.RelativeLaneChangeAction(-1, "Ego", dyn), hit))
    board.add_maneuver(dodge, "Ego")
    close = _entity_trigger(
        "close",
        xosc.RelativeDistanceCondition(
            60.0, xosc.Rule.lessThan, xosc.RelativeDistanceType.euclidianDistance, "Walker",
            freespace=False,
        ),
    )  # fmt: skip
    walk = xosc.Maneuver("walk")
    walk.add_event(_event("walk", step_speed(1.5), close))
    board.add_maneuver(walk, "Walker")
    return save(folder, "object_kinds.xosc", entities, board)


def parameter_rules_and_reach_position(folder: Path) -> Path:
    """OpenSCENARIO 1.0's forms: a ``ParameterAction`` sets a parameter and a
    ``ParameterCondition`` on it starts a brake; a ``ReachPositionCondition`` starts a
    lane change. A ``VariableAction`` multiplies a variable (``MultiplyByValue``) and a
    condition on it starts the ego's speed change. The parameter has constraints."""
    params = xosc.ParameterDeclarations()
    params.add_parameter(xosc.Parameter("Gain", xosc.ParameterType.double, "2.0"))
    variables = xosc.VariableDeclarations()
    variables.add_variable(xosc.Variable("Scale", xosc.ParameterType.double, "1.5"))
    # written as a variable action, then turned into the 1.0 parameter action below
    set_gain = _event("set_gain", xosc.VariableSetAction("Gain", 6.0), at_time(1.0))
    double = _event(
        "double", xosc.VariableMultiplyAction("Scale", 2.0), at_time(1.5), xosc.Priority.parallel
    )
    gained = xosc.ValueTrigger(
        "gained", 0.0, xosc.ConditionEdge.none,
        xosc.ParameterCondition("Gain", 5, xosc.Rule.greaterThan),
    )  # fmt: skip
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    slow = _event("slow", xosc.AbsoluteSpeedAction(14.0, dyn), gained, xosc.Priority.parallel)
    # written as a distance condition, then turned into the 1.0 reach condition below
    reach = _entity_trigger(
        "reach",
        xosc.DistanceCondition(
            2.0, xosc.Rule.lessThan, xosc.WorldPosition(150.0, -5.25), False, False
        ),
    )
    lc = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 3.0)
    change = _event("change", xosc.RelativeLaneChangeAction(-1, "Target", lc), reach)
    scaled = xosc.ValueTrigger(
        "scaled", 0.0, xosc.ConditionEdge.none,
        xosc.VariableCondition("Scale", 2.5, xosc.Rule.greaterThan),
    )  # fmt: skip
    faster = _event("faster", step_speed(24.0), scaled)
    path = write(
        folder,
        [("Target", [set_gain, double, slow, change]), ("Ego", [faster])],
        parameters=params,
        variables=variables,
        stop=12.0,
        name="parameter_rules.xosc",
    )
    text, n = re.subn(
        r'<VariableAction variableRef="Gain">(.*?)</VariableAction>',
        r'<ParameterAction parameterRef="Gain">\1</ParameterAction>', path.read_text(), flags=re.S,
    )  # fmt: skip
    assert n == 1
    text, n = re.subn(
        r'<DistanceCondition value="2.0"[^>]*>(.*?)</DistanceCondition>',
        r'<ReachPositionCondition tolerance="2.0">\1</ReachPositionCondition>', text, flags=re.S,
    )  # fmt: skip
    assert n == 1
    # the parameter's constraints (checked when the file is read)
    plain = '<ParameterDeclaration name="Gain" parameterType="double" value="2.0"/>'
    assert plain in text
    text = text.replace(
        plain,
        plain[:-2] + '><ConstraintGroup><ValueConstraint rule="greaterThan" value="0"/>'
        '<ValueConstraint rule="lessThan" value="10"/></ConstraintGroup></ParameterDeclaration>',
    )
    path.write_text(text)
    return path


def synchronize_relative_to_master(folder: Path) -> Path:
    """The target arrives at s = 320 m of its lane when the ego arrives at s = 320 m
    of its own, 2 m/s faster than the ego (``RelativeSpeedToMaster``, a delta), held
    for the last 2 s (``TargetTimeSteadyState``)."""
    sync = xosc.SynchronizeAction(
        "Ego",
        xosc.LanePosition(320.0, 0, -2, 0),
        xosc.LanePosition(320.0, 0, -1, 0),
        1.0,
        1.0,
        final_speed=xosc.RelativeSpeedToMaster(
            2.0, xosc.SpeedTargetValueType.delta, xosc.TargetTimeSteadyState(2.0)
        ),
    )
    return write(
        folder,
        [("Target", [_event("sync", sync, at_time(0.5))])],
        target=(1, 50.0, 20.0),
        stop=15.0,
        name="sync_relative.xosc",
    )


def synchronize_from_standstill(folder: Path) -> Path:
    """The target, standing 30 m behind the ego in the next lane, arrives at s = 230 m
    of its lane at the ego's speed when the ego arrives at s = 250 m of its own: it
    rushes (accelerates, then brakes to the ego's speed). Without
    ``targetToleranceMaster`` and ``targetTolerance`` (optional, no default in the
    standard; esmini plays them as 0 m)."""
    sync = xosc.SynchronizeAction(
        "Ego",
        xosc.LanePosition(250.0, 0, -2, 0),
        xosc.LanePosition(230.0, 0, -1, 0),
        1.0,
        1.0,
        final_speed=xosc.RelativeSpeedToMaster(0.0, xosc.SpeedTargetValueType.delta),
    )
    path = write(
        folder,
        [("Target", [_event("sync", sync, at_time(0.0))])],
        target=(1, -30.0, 0.0),
        stop=14.0,
        name="sync_standstill.xosc",
    )
    text = path.read_text()
    attributes = 'targetToleranceMaster="1.0" targetTolerance="1.0"'
    assert attributes in text
    path.write_text(text.replace(attributes, ""))
    return path


def trailer_by_reference(folder: Path) -> Path:
    """A truck towing a trailer that is an entity of its own (``TrailerRef``), from the
    start (``Init`` places the truck only), through a lane change in an arc of
    R 250 m. esmini finds a referenced trailer only when it is declared first."""
    entities = xosc.Entities()
    entities.add_scenario_object("Ego", car())
    entities.add_scenario_object("Box", _trailer("box"))
    entities.add_scenario_object("Rig", _truck("Box"))  # a name: a TrailerRef
    init = placed((("Ego", -1, 20.0, 15.0), ("Rig", -2, 60.0, 15.0)))
    board = xosc.StoryBoard(
        init,
        xosc.ValueTrigger(
            "stop", 0, xosc.ConditionEdge.rising,
            xosc.SimulationTimeCondition(12.0, xosc.Rule.greaterThan), "stop",
        ),
    )  # fmt: skip
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.sinusoidal, xosc.DynamicsDimension.time, 4.0)
    rig = xosc.Maneuver("rig")
    rig.add_event(_event("change", xosc.AbsoluteLaneChangeAction(-3, dyn), at_time(3.0)))
    board.add_maneuver(rig, "Rig")
    scenario = xosc.Scenario(
        "trailer_ref", "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(_curved_road(folder))), xosc.Catalog(),
    )  # fmt: skip
    path = folder / "trailer_ref.xosc"
    scenario.write_xml(str(path))
    assert '<TrailerRef entityRef="Box"/>' in path.read_text()
    return path


def _catalog_file(name: str, entries: str) -> str:
    """An OpenSCENARIO catalog file: ``entries`` (XML) in a catalog called ``name``."""
    return (
        '<?xml version="1.0" encoding="utf-8"?>\n<OpenSCENARIO>\n'
        '  <FileHeader revMajor="1" revMinor="3" date="2026-01-01T00:00:00" '
        f'description="{name}" author="aldm-gym tests"/>\n'
        f'  <Catalog name="{name}">\n{entries}  </Catalog>\n</OpenSCENARIO>\n'
    )


_VEHICLE_CATALOG = _catalog_file(
    "cars",
    """\
    <Vehicle name="car" vehicleCategory="car">
      <ParameterDeclarations>
        <ParameterDeclaration name="MaxSpeed" parameterType="double" value="70"/>
        <ParameterDeclaration name="Length" parameterType="double" value="5.0"/>
      </ParameterDeclarations>
      <BoundingBox>
        <Center x="1.4" y="0.0" z="0.75"/>
        <Dimensions width="2.0" length="$Length" height="1.5"/>
      </BoundingBox>
      <Performance maxSpeed="$MaxSpeed" maxAcceleration="10" maxDeceleration="10"/>
      <Axles>
        <FrontAxle maxSteering="0.5" wheelDiameter="0.6" trackWidth="1.8" positionX="2.8"
                   positionZ="0.3"/>
        <RearAxle maxSteering="0.0" wheelDiameter="0.6" trackWidth="1.8" positionX="0.0"
                  positionZ="0.3"/>
      </Axles>
      <Properties/>
    </Vehicle>
""",
)

_TRAJECTORY_CATALOG = _catalog_file(
    "paths",
    """\
    <Trajectory name="swerve" closed="false">
      <ParameterDeclarations>
        <ParameterDeclaration name="Dy" parameterType="double" value="1.0"/>
      </ParameterDeclarations>
      <Shape>
        <Polyline>
          <Vertex><Position><WorldPosition x="70" y="-5.25"/></Position></Vertex>
          <Vertex><Position><WorldPosition x="110" y="${-5.25 + $Dy}"/></Position></Vertex>
          <Vertex><Position><WorldPosition x="150" y="-5.25"/></Position></Vertex>
        </Polyline>
      </Shape>
    </Trajectory>
""",
)

_OBJECT_CATALOG = _catalog_file(
    "objects",
    """\
    <MiscObject name="cone" miscObjectCategory="obstacle" mass="5">
      <BoundingBox><Center x="0" y="0" z="0.4"/><Dimensions width="0.4" length="0.4" height="0.8"/>
      </BoundingBox>
      <Properties/>
    </MiscObject>
""",
)

_PEDESTRIAN_CATALOG = _catalog_file(
    "people",
    """\
    <Pedestrian name="walker" pedestrianCategory="pedestrian" mass="80" model3d="walker">
      <BoundingBox><Center x="0" y="0" z="0.9"/><Dimensions width="0.6" length="0.5" height="1.8"/>
      </BoundingBox>
      <Properties/>
    </Pedestrian>
""",
)

_ROUTE_CATALOG = _catalog_file(
    "routes",
    """\
    <Route name="along" closed="false">
      <ParameterDeclarations>
        <ParameterDeclaration name="LaneId" parameterType="int" value="-2"/>
      </ParameterDeclarations>
      <Waypoint routeStrategy="shortest">
        <Position><LanePosition roadId="0" laneId="$LaneId" s="60"/></Position>
      </Waypoint>
      <Waypoint routeStrategy="shortest">
        <Position><LanePosition roadId="0" laneId="$LaneId" s="900"/></Position>
      </Waypoint>
    </Route>
""",
)

_MANEUVER_CATALOG = _catalog_file(
    "maneuvers",
    """\
    <Maneuver name="slow_down">
      <ParameterDeclarations>
        <ParameterDeclaration name="Speed" parameterType="double" value="5"/>
        <ParameterDeclaration name="At" parameterType="double" value="1"/>
      </ParameterDeclarations>
      <Event name="slow" priority="override">
        <Action name="slow_action">
          <PrivateAction><LongitudinalAction><SpeedAction>
            <SpeedActionDynamics dynamicsShape="linear" value="2" dynamicsDimension="rate"/>
            <SpeedActionTarget><AbsoluteTargetSpeed value="$Speed"/></SpeedActionTarget>
          </SpeedAction></LongitudinalAction></PrivateAction>
        </Action>
        <StartTrigger><ConditionGroup>
          <Condition name="at" delay="0" conditionEdge="none"><ByValueCondition>
            <SimulationTimeCondition value="$At" rule="greaterThan"/>
          </ByValueCondition></Condition>
        </ConditionGroup></StartTrigger>
      </Event>
    </Maneuver>
""",
)


def catalogs_and_relative_lane_offset(folder: Path) -> Path:
    """Entries from catalogs with parameters assigned: the target is a catalog car
    whose ``Performance`` caps the speed it is asked for (``maxSpeed`` 24 m/s of 30)
    and is assigned a catalog route along its lane, a cone and a walker on the right
    edge are a misc object's and a pedestrian's entry, the third car slows down by a
    catalog maneuver,
    the ego follows a catalog trajectory (untimed) swerving 1.5 m left; a third car,
    two lanes right of the target, moves to 0.5 m left of where the target is
    (``RelativeTargetLaneOffset``, not continuous; esmini's reading: beside the
    referenced entity, whichever lane it is in)."""
    cat = folder / "catalogs"
    cat.mkdir(exist_ok=True)
    (cat / "cars.xosc").write_text(_VEHICLE_CATALOG)  # esmini: the file by the name
    (cat / "paths.xosc").write_text(_TRAJECTORY_CATALOG)
    (cat / "routes.xosc").write_text(_ROUTE_CATALOG)
    (cat / "objects.xosc").write_text(_OBJECT_CATALOG)
    (cat / "people.xosc").write_text(_PEDESTRIAN_CATALOG)
    (cat / "maneuvers.xosc").write_text(_MANEUVER_CATALOG)
    init = placed((("Ego", -2, 50.0, 20.0), ("Target", -1, 80.0, 20.0),
                   ("Third", -3, 90.0, 20.0)))  # fmt: skip
    entities = xosc.Entities()
    entities.add_scenario_object("Ego", car())
    target = xosc.CatalogReference("cars", "car")
    target.add_parameter_assignment("MaxSpeed", 24.0)
    target.add_parameter_assignment("Length", 4.5)
    entities.add_scenario_object("Target", target)
    entities.add_scenario_object("Third", car())
    entities.add_scenario_object("Cone", xosc.CatalogReference("objects", "cone"))
    entities.add_scenario_object("Walker", xosc.CatalogReference("people", "walker"))
    init.add_init_action("Cone", xosc.TeleportAction(xosc.LanePosition(300.0, -1.2, -3, 0)))
    init.add_init_action("Walker", xosc.TeleportAction(xosc.LanePosition(320.0, -1.5, -3, 0)))
    init.add_init_action("Walker", step_speed(1.0))
    board = xosc.StoryBoard(
        init,
        xosc.ValueTrigger(
            "stop", 0, xosc.ConditionEdge.rising,
            xosc.SimulationTimeCondition(10.0, xosc.Rule.greaterThan), "stop",
        ),
    )  # fmt: skip
    fast = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 3.0)
    shift = xosc.AbsoluteLaneOffsetAction(0.8, xosc.DynamicsShapes.sinusoidal, 1.0)
    tgt = xosc.Maneuver("target")
    tgt.add_event(_event("faster", xosc.AbsoluteSpeedAction(30.0, fast), at_time(0.5)))
    tgt.add_event(_event("shift", shift, at_time(3.0), xosc.Priority.parallel))
    route = xosc.CatalogReference("routes", "along")
    route.add_parameter_assignment("LaneId", -1)
    tgt.add_event(
        _event("route", xosc.AssignRouteAction(route), at_time(0.2), xosc.Priority.parallel)
    )
    board.add_maneuver(tgt, "Target")
    keep = xosc.RelativeLaneOffsetAction(
        0.5, "Target", xosc.DynamicsShapes.sinusoidal, 2.0, continuous=False
    )
    third = xosc.Maneuver("third")
    third.add_event(_event("keep", keep, at_time(1.0)))
    board.add_maneuver(third, "Third")
    swerve = (
        "<PrivateAction><RoutingAction><FollowTrajectoryAction><TrajectoryRef>"
        '<CatalogReference catalogName="paths" entryName="swerve"><ParameterAssignments>'
        '<ParameterAssignment parameterRef="Dy" value="1.5"/></ParameterAssignments>'
        "</CatalogReference></TrajectoryRef><TimeReference><None/></TimeReference>"
        '<TrajectoryFollowingMode followingMode="position"/></FollowTrajectoryAction>'
        "</RoutingAction></PrivateAction>"
    )
    ego = xosc.Maneuver("ego")
    ego.add_event(_event("swerve", step_speed(20.0), at_time(0.5)))
    board.add_maneuver(ego, "Ego")
    catalog = xosc.Catalog()
    catalog.add_catalog("VehicleCatalog", str(cat))
    catalog.add_catalog("TrajectoryCatalog", str(cat))
    catalog.add_catalog("RouteCatalog", str(cat))
    catalog.add_catalog("MiscObjectCatalog", str(cat))
    catalog.add_catalog("PedestrianCatalog", str(cat))
    catalog.add_catalog("ManeuverCatalog", str(cat))
    scenario = xosc.Scenario(
        "catalogs", "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(straight_road(folder))), catalog,
    )  # fmt: skip
    path = folder / "catalogs.xosc"
    scenario.write_xml(str(path))
    text = "".join(line.strip() for line in path.read_text().splitlines())
    # the ego's event carries the catalog trajectory in place of its placeholder speed
    start = text.index('<Event name="swerve"')
    a = text.index("<PrivateAction>", start)
    b = text.index("</PrivateAction>", a) + len("</PrivateAction>")
    text = text[:a] + swerve + text[b:]
    # the third car's maneuver group also plays a catalog maneuver, 15 m/s at 6 s
    group = '<ManeuverGroup name="maneuvuergroup_third"'  # scenariogeneration's name
    a = text.index("</Actors>", text.index(group)) + len("</Actors>")
    slow = (
        '<CatalogReference catalogName="maneuvers" entryName="slow_down"><ParameterAssignments>'
        '<ParameterAssignment parameterRef="Speed" value="15"/>'
        '<ParameterAssignment parameterRef="At" value="6"/></ParameterAssignments>'
        "</CatalogReference>"
    )
    path.write_text(text[:a] + slow + text[a:])
    return path


def init_relative_to_a_later_entity(folder: Path) -> Path:
    """``Init`` puts the ego 30 m behind the target, one lane right, before the
    target's own teleport (the order of ASAM's SlowPrecedingVehicle example); the ego
    then speeds up."""
    init = xosc.Init()
    behind = xosc.RelativeLanePosition(lane_id=-1, entity="Target", ds=-30.0)
    init.add_init_action("Ego", xosc.TeleportAction(behind))
    init.add_init_action("Ego", step_speed(20.0))
    init.add_init_action("Target", xosc.TeleportAction(xosc.LanePosition(120.0, 0, -1, 0)))
    init.add_init_action("Target", step_speed(15.0))
    entities, board = cars_and_board(("Ego", "Target"), init, 8.0)
    ego = xosc.Maneuver("ego")
    dyn = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 2.0)
    ego.add_event(_event("faster", xosc.AbsoluteSpeedAction(26.0, dyn), at_time(1.0)))
    board.add_maneuver(ego, "Ego")
    return save(folder, "init_order.xosc", entities, board)


def braking_during_a_lane_offset(folder: Path) -> Path:
    """A continuous lane offset towards the ego's lane (relative to the ego, esmini's
    cut-in_simple) and a brake written after it that starts while it runs: the
    offset sets the offset only, and the target travels at the braked speed."""
    offset = xosc.RelativeLaneOffsetAction(
        0.0, "Ego", xosc.DynamicsShapes.sinusoidal, 1.0, continuous=True
    )
    brake = xosc.TransitionDynamics(xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, 5.0)
    return write(
        folder,
        [
            (
                "Target",
                [
                    _event("cut_in", offset, at_time(1.0)),
                    _event(
                        "brake", xosc.AbsoluteSpeedAction(0.0, brake), at_time(2.0),
                        xosc.Priority.parallel,
                    ),
                ],
            )
        ],
        target=(1, 20.0, 25.0),
        stop=8.0,
        name="brake_in_offset.xosc",
    )  # fmt: skip


def lane_offset_relative_to_an_oncoming_entity(folder: Path) -> Path:
    """``RelativeTargetLaneOffset`` to an oncoming car: the target, in the ego's lane
    ahead, moves to 3 m left of where the car on the lane driven the other way is, as
    that car faces (its left is towards the target's lane), so 0.5 m left of its own
    lane's centre."""
    road = straight_road(folder, left_lanes=2)
    init = placed(
        (("Ego", -1, 50.0, 20.0), ("Target", -1, 90.0, 20.0), ("Oncoming", 1, 400.0, 15.0))
    )
    entities, board = cars_and_board(("Ego", "Target", "Oncoming"), init, 8.0)
    offset = xosc.RelativeLaneOffsetAction(3.0, "Oncoming", xosc.DynamicsShapes.sinusoidal, 1.0)
    man = xosc.Maneuver("m_target")
    man.add_event(_event("beside", offset, at_time(1.0)))
    board.add_maneuver(man, "Target")
    scenario = xosc.Scenario(
        "oncoming_offset", "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(road)), xosc.Catalog(),
    )  # fmt: skip
    path = folder / "oncoming_offset.xosc"
    scenario.write_xml(str(path))
    return path


def route_to_an_exit_from_a_through_lane(folder: Path) -> Path:
    """On the shipped motorway, the target drives the rightmost through lane (road 5,
    lane -3) with a route whose second waypoint is on the exit ramp (road 7), which
    only lane -4 leads onto: a route makes no lane change, so the target follows its
    lane past the exit (as esmini plays it; the player warns)."""
    from aldm_gym.roads import shipped_map

    init = xosc.Init()
    for name, lane, s in (("Ego", -1, 100.0), ("Target", -3, 150.0)):
        init.add_init_action(name, xosc.TeleportAction(xosc.LanePosition(s, 0, lane, 5)))
        init.add_init_action(name, step_speed(25.0))
    entities, board = cars_and_board(("Ego", "Target"), init, 30.0)
    route = xosc.Route("exit")
    route.add_waypoint(xosc.LanePosition(160.0, 0, -3, 5), xosc.RouteStrategy.shortest)
    route.add_waypoint(xosc.LanePosition(100.0, 0, -1, 7), xosc.RouteStrategy.shortest)
    man = xosc.Maneuver("m_target")
    man.add_event(_event("route", xosc.AssignRouteAction(route), at_time(0.5)))
    board.add_maneuver(man, "Target")
    scenario = xosc.Scenario(
        "exit_route", "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(shipped_map("motorway"))), xosc.Catalog(),
    )  # fmt: skip
    path = folder / "exit_route.xosc"
    scenario.write_xml(str(path))
    return path


def timed_polylines_follow_and_position(folder: Path) -> Path:
    """Timed polylines, relative timing: the target brakes along its lane by one
    written for 10 then 6 m/s² (``followingMode="follow"``: the speed changes at a
    constant acceleration along each segment, from the target's speed on); the ego
    swerves by one in ``position`` mode (each segment at its mean speed). Both go on
    at their last speed after the last vertex."""

    def timed(actor: str, points: list[tuple[float, float, float]], mode: object) -> object:
        poly = xosc.Polyline(
            [t for t, _, _ in points],
            [xosc.RelativeLanePosition(lane_id=0, entity=actor, ds=ds, offset=off)
             for _, ds, off in points],
        )  # fmt: skip
        traj = xosc.Trajectory(f"{actor}_path", False)
        traj.add_shape(poly)
        return xosc.FollowTrajectoryAction(traj, mode, xosc.ReferenceContext.relative, 1, 0)

    v1, v2, a1, a2 = 25.0, 12.0, -10.0, -6.0
    t1, t2 = (v2 - v1) / a1, (0.0 - v2) / a2
    d1, d2 = v1 * t1 + 0.5 * a1 * t1 * t1, v2 * t2 + 0.5 * a2 * t2 * t2
    brake = timed(
        "Target", [(0.0, 0.0, 0.0), (t1, d1, 0.0), (t1 + t2, d1 + d2, 0.0)],
        xosc.FollowingMode.follow,
    )  # fmt: skip
    swerve = timed(
        "Ego", [(0.0, 0.0, 0.0), (1.0, 21.0, 0.8), (2.0, 40.0, 0.0), (3.0, 60.0, -0.5)],
        xosc.FollowingMode.position,
    )  # fmt: skip
    path = write(
        folder,
        [
            ("Target", [_event("brake", brake, at_time(1.0))]),
            ("Ego", [_event("swerve", swerve, at_time(2.0))]),
        ],
        target=(1, 40.0, 25.0),
        stop=9.0,
        name="timed_polylines.xosc",
    )
    assert path.read_text().count("followingMode=") == 2
    return path


def split_road(folder: Path) -> Path:
    """A motorway whose right lane splits: road 0 (300 m, three lanes) ends in
    junction 1, where lane -3 continues both straight on (connecting road 4, 40 m, to
    road 1: 1000 m, three lanes) and onto an exit (connecting road 3, a 40 m spiral to
    the right, to road 2: one lane bending away on R 400 m). The exit's connection
    comes first in the file, so the first successor is not the straightest."""
    path = folder / "split.xodr"
    if not path.exists():

        def lanes(plan: object, road_id: int, n: int, kind: int = -1) -> xodr.Road:
            return xodr.create_road(
                plan, id=road_id, left_lanes=0, right_lanes=n, lane_width=3.5, road_type=kind
            )

        main = lanes(xodr.Line(300.0), 0, 3)
        on = lanes(xodr.Line(1000.0), 1, 3)
        off = lanes([xodr.Arc(-1 / 400, 100.0), xodr.Line(300.0)], 2, 1)
        to_off = lanes(xodr.Spiral(-1e-5, -1 / 400, 40.0), 3, 1, kind=1)
        to_on = lanes(xodr.Line(40.0), 4, 3, kind=1)
        main.add_successor(xodr.ElementType.junction, 1)
        on.add_predecessor(xodr.ElementType.junction, 1)
        off.add_predecessor(xodr.ElementType.junction, 1)
        to_off.add_predecessor(xodr.ElementType.road, 0, xodr.ContactPoint.end, lane_offset=-2)
        to_off.add_successor(xodr.ElementType.road, 2, xodr.ContactPoint.start)
        to_on.add_predecessor(xodr.ElementType.road, 0, xodr.ContactPoint.end)
        to_on.add_successor(xodr.ElementType.road, 1, xodr.ContactPoint.start)
        junction = xodr.create_junction([to_off, to_on], 1, [main, on, off])
        odr = xodr.OpenDrive("split")
        for r in (main, on, off, to_off, to_on):
            odr.add_road(r)
        odr.adjust_roads_and_lanes()
        odr.add_junction(junction)
        odr.write_xml(str(path))
    return path


def on_split_road(
    folder: Path,
    rows: Sequence[tuple[str, int, int, float]],
    events: Sequence[tuple[str, xosc.Event]],
    stop: float,
    name: str,
) -> Path:
    """A scenario on :func:`split_road`: a car per ``(name, road id, lane id, s [m])``
    at 20 m/s, each ``(actor, event)`` in a maneuver of its own; it stops at ``stop``
    [s]."""
    init = xosc.Init()
    for car_name, road_id, lane, s in rows:
        init.add_init_action(car_name, xosc.TeleportAction(xosc.LanePosition(s, 0, lane, road_id)))
        init.add_init_action(car_name, step_speed(20.0))
    entities, board = cars_and_board([r[0] for r in rows], init, stop)
    for k, (actor, ev) in enumerate(events):
        man = xosc.Maneuver(f"m{k}_{actor}")
        man.add_event(ev)
        board.add_maneuver(man, actor)
    scenario = xosc.Scenario(
        name, "aldm-gym tests", xosc.ParameterDeclarations(), entities, board,
        xosc.RoadNetwork(str(split_road(folder))), xosc.Catalog(),
    )  # fmt: skip
    path = folder / f"{name}.xosc"
    scenario.write_xml(str(path))
    return path


def routes_at_a_lane_split(folder: Path) -> Path:
    """Four cars on the right lane of :func:`split_road` and the ego beside them: one
    routed onto the exit, one routed straight on, one without a route (the
    straightest branch), one told to acquire a position on the exit road; and a
    teleport to a ``RoutePosition`` 250 m along a route onto the exit (10 m onto the
    exit road, past the split)."""
    names = ("Ego", "Exit", "Through", "Free", "Acquire")
    rows = [(n, 0, -1 if n == "Ego" else -3, 200.0 - 25 * k) for k, n in enumerate(names)]

    def route(name: str, road_id: int, lane: int) -> xosc.Route:
        r = xosc.Route(name)
        r.add_waypoint(xosc.LanePosition(100.0, 0, -3, 0), xosc.RouteStrategy.shortest)
        r.add_waypoint(xosc.LanePosition(100.0, 0, lane, road_id), xosc.RouteStrategy.shortest)
        return r

    acquire = xosc.AcquirePositionAction(xosc.LanePosition(200.0, 0, -1, 2))
    past = xosc.RoutePositionInLaneCoordinates(route("hop", 2, -1), 250.0, -1, 0.0)
    events = [
        ("Exit", _event("to_exit", xosc.AssignRouteAction(route("exit", 2, -1)), at_time(0.5))),
        ("Through", _event("on", xosc.AssignRouteAction(route("on", 1, -3)), at_time(0.5))),
        ("Acquire", _event("acquire", acquire, at_time(0.5))),
        ("Ego", _event("hop", xosc.TeleportAction(past), at_time(12.0))),
    ]
    return on_split_road(folder, rows, events, 15.0, "routes_at_a_split")


CORPUS: dict[str, Callable[[Path], Path]] = {
    f.__name__: f
    for f in (
        lane_change_relative,
        lane_change_into_oncoming_lane,
        lane_offset_in_a_curve,
        speed_linear_to_its_own_speed,
        trajectory_without_timing,
        ttc_in_road_coordinates_and_collision,
        story_parameters_and_relative_road_position,
        stand_still_and_acquire_position,
        distance_rigid_before_its_reference,
        distance_with_dynamic_constraints,
        parameter_and_variable_actions,
        speed_profile,
        clothoid_trajectories,
        nurbs_trajectory,
        state_conditions,
        synchronize,
        turned_round_and_braking_in_a_lane_change,
        trajectory_and_route_positions,
        speed_shapes_and_priorities,
        reach_headway_and_route,
        entities_deleted_and_added,
        angle_conditions,
        road_end_off_road_and_relative_world,
        lateral_distances,
        jerk_limited_speed_profiles,
        trailers,
        actions_in_document_order,
        relative_speed_before_its_reference,
        speed_condition_in_the_update_of_a_step,
        headway_condition_in_the_update_of_a_step,
        clothoid_spline,
        object_kinds_and_collision_by_type,
        parameter_rules_and_reach_position,
        synchronize_relative_to_master,
        synchronize_from_standstill,
        trailer_by_reference,
        catalogs_and_relative_lane_offset,
        init_relative_to_a_later_entity,
        braking_during_a_lane_offset,
        lane_offset_relative_to_an_oncoming_entity,
        route_to_an_exit_from_a_through_lane,
        timed_polylines_follow_and_position,
        routes_at_a_lane_split,
    )
}
"""The corpus by name."""

__all__ = ["CORPUS", "car"]
