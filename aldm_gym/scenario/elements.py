"""What the player does with every element of ASAM OpenSCENARIO XML 1.3.

:data:`ELEMENTS` names each element of the 1.3 schema with its status:

- ``played``: read and played (as the standard and esmini play it; docs/scenarios.md
  says where the standard leaves a choice and what the player chose);
- ``ignored``: accepted and without effect, with one
  :class:`~aldm_gym.errors.ScenarioWarning` per element kind and file (weather, traffic
  signals, light states: things the env does not model), or silently where the element
  only describes (a license, a 3D model file);
- ``refused``: a :class:`~aldm_gym.errors.ScenarioError` naming the file, the line and
  the element, never a silently wrong run.

docs/scenarios.md's element table is written from it (``python -m
aldm_gym.scenario.elements``) and a test checks the two agree, and that every element
of the schema is here.
"""

from __future__ import annotations

import sys

__all__ = ["ELEMENTS", "STATUSES", "counts", "markdown_table"]

STATUSES = ("played", "ignored", "refused")
"""The statuses, in the table's order."""


def _each(status: str, note: str, names: str) -> dict[str, tuple[str, str]]:
    return {name: (status, note) for name in names.split()}


ELEMENTS: dict[str, tuple[str, str]] = {
    # ---------------------------------------------------------------- file, parameters
    **_each("played", "the file", "OpenSCENARIO FileHeader"),
    **_each(
        "ignored",
        "describes the file, no effect",
        "License Properties Property File CustomContent",
    ),
    **_each(
        "played",
        "parameters and their constraints, at every place the schema allows them",
        "ParameterDeclarations ParameterDeclaration ConstraintGroup ValueConstraint "
        "ParameterAssignments ParameterAssignment",
    ),
    **_each(
        "played",
        "variables (1.2+): `VariableAction` changes them, `VariableCondition` reads them",
        "VariableDeclarations VariableDeclaration",
    ),
    **_each(
        "ignored",
        "monitors have no meaning on the env",
        "MonitorDeclarations MonitorDeclaration SetMonitorAction",
    ),
    **_each(
        "played",
        "catalogs: vehicles, pedestrians, misc objects, trajectories, routes, maneuvers",
        "CatalogLocations Catalog CatalogReference Directory VehicleCatalog "
        "PedestrianCatalog MiscObjectCatalog TrajectoryCatalog RouteCatalog ManeuverCatalog",
    ),
    **_each(
        "ignored",
        "the catalog location is accepted; controllers and environments have no meaning here",
        "ControllerCatalog EnvironmentCatalog",
    ),
    # ---------------------------------------------------------------- variations
    **_each(
        "played",
        "parameter variation files (`aldm-gym scenario suite`)",
        "ParameterValueDistribution ScenarioFile Deterministic "
        "DeterministicSingleParameterDistribution DeterministicMultiParameterDistribution "
        "DistributionSet DistributionRange ValueSetDistribution ParameterValueSet Element "
        "Stochastic StochasticDistribution ProbabilityDistributionSet NormalDistribution "
        "LogNormalDistribution UniformDistribution PoissonDistribution Histogram Bin Range",
    ),
    **_each(
        "refused",
        "a distribution defined by another tool cannot be sampled",
        "UserDefinedDistribution",
    ),
    # ---------------------------------------------------------------- road network
    **_each("played", "the OpenDRIVE map", "RoadNetwork LogicFile"),
    **_each(
        "ignored",
        "a 3D scene has no meaning on the env",
        "SceneGraphFile UsedArea",
    ),
    **_each(
        "ignored",
        "traffic signals have no meaning on the env",
        "TrafficSignals TrafficSignalController Phase TrafficSignalState "
        "TrafficSignalGroupState InfrastructureAction TrafficSignalAction "
        "TrafficSignalControllerAction TrafficSignalStateAction",
    ),
    # ---------------------------------------------------------------- entities
    **_each(
        "played",
        "entities: their boxes and performance limits",
        "Entities ScenarioObject Vehicle Pedestrian MiscObject BoundingBox Center "
        "Dimensions Performance",
    ),
    **_each(
        "ignored",
        "vehicle details the env does not model (axles, 3D models, animations)",
        "Axles FrontAxle RearAxle AdditionalAxle",
    ),
    **_each(
        "played",
        "marks the ego (the function under test); the controller itself is the env's",
        "ObjectController",
    ),
    **_each(
        "ignored",
        "another tool's controller: every entity but the ego follows the storyboard",
        "Controller",
    ),
    **_each(
        "played",
        "a selection of scenario objects (by name, by type, or other selections), as "
        "actors, triggering entities and `Init`'s actors",
        "EntitySelection Members",
    ),
    **_each(
        "refused",
        "an entity defined in another tool (its state is that tool's) is not played",
        "ExternalObjectReference",
    ),
    **_each(
        "played",
        "trailers: towed from the start or connected and disconnected at run time, the "
        "coupler following the hitch (not on the function under test's vehicle)",
        "Trailer TrailerHitch TrailerCoupler TrailerRef TrailerAction ConnectTrailerAction "
        "DisconnectTrailerAction",
    ),
    # ---------------------------------------------------------------- storyboard
    **_each(
        "played",
        "the storyboard and its life cycle",
        "Storyboard Init Actions Private Story Act ManeuverGroup Actors EntityRef Maneuver "
        "Event Action StartTrigger StopTrigger ConditionGroup Condition",
    ),
    # ---------------------------------------------------------------- conditions
    **_each(
        "played",
        "conditions (every coordinate system but `trajectory`, freespace or not)",
        "ByEntityCondition TriggeringEntities EntityCondition ByValueCondition "
        "SimulationTimeCondition StoryboardElementStateCondition ParameterCondition "
        "VariableCondition RelativeDistanceCondition TimeHeadwayCondition "
        "TimeToCollisionCondition TimeToCollisionConditionTarget SpeedCondition "
        "RelativeSpeedCondition ReachPositionCondition DistanceCondition "
        "TraveledDistanceCondition CollisionCondition StandStillCondition "
        "AccelerationCondition EndOfRoadCondition OffroadCondition "
        "RelativeClearanceCondition RelativeLaneRange",
    ),
    **_each(
        "played",
        "a `CollisionCondition` with any entity of a type, or the members of an "
        "`EntitySelection` of a type",
        "ByType",
    ),
    **_each(
        "ignored",
        "the env has none of these: the condition never holds",
        "TimeOfDayCondition UserDefinedValueCondition TrafficSignalCondition "
        "TrafficSignalControllerCondition",
    ),
    **_each(
        "played",
        "angle conditions (1.3): heading in world, road or lane coordinates, relative "
        "to another entity; pitch and roll are 0 on the planar world",
        "AngleCondition RelativeAngleCondition",
    ),
    # ---------------------------------------------------------------- positions
    **_each(
        "played",
        "positions",
        "Position WorldPosition RelativeWorldPosition RelativeObjectPosition RoadPosition "
        "RelativeRoadPosition LanePosition RelativeLanePosition Orientation",
    ),
    **_each(
        "played",
        "positions along a route or a trajectory",
        "RoutePosition InRoutePosition FromCurrentEntity FromRoadCoordinates "
        "FromLaneCoordinates RouteRef TrajectoryPosition",
    ),
    **_each(
        "played",
        "geographic positions, through the map's `<geoReference>` (pyproj); the altitude "
        "is not used",
        "GeoPosition",
    ),
    # ---------------------------------------------------------------- private actions
    **_each(
        "played",
        "private actions",
        "PrivateAction TeleportAction LongitudinalAction SpeedAction SpeedActionDynamics "
        "SpeedActionTarget AbsoluteTargetSpeed RelativeTargetSpeed SpeedProfileAction "
        "SpeedProfileEntry LongitudinalDistanceAction DynamicConstraints LateralAction "
        "LaneChangeAction LaneChangeActionDynamics LaneChangeTarget RelativeTargetLane "
        "AbsoluteTargetLane LaneOffsetAction LaneOffsetActionDynamics LaneOffsetTarget "
        "RelativeTargetLaneOffset AbsoluteTargetLaneOffset LateralDistanceAction "
        "RoutingAction AssignRouteAction Route Waypoint AcquirePositionAction "
        "FollowTrajectoryAction TrajectoryRef Trajectory Shape Polyline Vertex Clothoid "
        "ClothoidSpline ClothoidSplineSegment PositionStart Nurbs ControlPoint Knot "
        "TimeReference Timing None TrajectoryFollowingMode ControllerAction "
        "ActivateControllerAction",
    ),
    **_each(
        "ignored",
        "every entity but the ego follows the storyboard; the ego's pedals, gears and "
        "steering are the function's",
        "AssignControllerAction OverrideControllerValueAction Throttle Brake BrakePercent "
        "BrakeForce Clutch ParkingBrake SteeringWheel Gear ManualGear AutomaticGear",
    ),
    **_each(
        "ignored",
        "visibility, lights and animations have no meaning on the env",
        "VisibilityAction SensorReferenceSet SensorReference AppearanceAction "
        "LightStateAction LightType LightState VehicleLight UserDefinedLight Color "
        "ColorRgb ColorCmyk AnimationAction AnimationType AnimationState AnimationFile "
        "ComponentAnimation VehicleComponent UserDefinedComponent UserDefinedAnimation "
        "PedestrianAnimation PedestrianGesture",
    ),
    **_each(
        "played",
        "synchronisation: arrive when the master arrives, at a final speed",
        "SynchronizeAction TargetPositionMaster TargetPosition FinalSpeed AbsoluteSpeed "
        "RelativeSpeedToMaster TargetDistanceSteadyState TargetTimeSteadyState",
    ),
    **_each(
        "played",
        "a random branch at every split of the actor's lanes (the episode's seed)",
        "RandomRouteAction",
    ),
    # ---------------------------------------------------------------- global actions
    **_each(
        "played",
        "parameter and variable actions (set, add, multiply)",
        "GlobalAction ParameterAction VariableAction SetAction ModifyAction Rule AddValue "
        "MultiplyByValue",
    ),
    **_each(
        "ignored",
        "weather, time of day and road condition have no meaning on the env (the line "
        "sensor's conditions are its own settings)",
        "EnvironmentAction Environment TimeOfDay Weather Sun Fog Precipitation Wind "
        "DomeImage DomeFile RoadCondition",
    ),
    **_each(
        "ignored",
        "a command for another tool",
        "UserDefinedAction CustomCommandAction",
    ),
    **_each(
        "played",
        "deleting an entity and adding it back at a position (not the function under test)",
        "EntityAction AddEntityAction DeleteEntityAction",
    ),
    **_each(
        "played",
        "generated traffic: the env's map traffic (IDM/MOBIL) kept in a swarm's ring, "
        "placed by a source, removed by a sink, drawn from the episode's seed "
        "(aldm_gym.scenario.traffic)",
        "TrafficAction TrafficSwarmAction TrafficSourceAction TrafficSinkAction "
        "TrafficStopAction TrafficDefinition CentralObject InitialSpeedRange "
        "DirectionOfTravelDistribution VehicleCategoryDistribution "
        "VehicleCategoryDistributionEntry",
    ),
    **_each(
        "ignored",
        "generated vehicles drive as the env's map traffic: their controllers and roles "
        "are its own",
        "ControllerDistribution ControllerDistributionEntry VehicleRoleDistribution "
        "VehicleRoleDistributionEntry",
    ),
    **_each(
        "played",
        "generated traffic (1.3): a traffic area on road ranges or in a polygon, and "
        "vehicles drawn from entity templates (their category and bounding box)",
        "TrafficAreaAction TrafficArea TrafficDistribution TrafficDistributionEntry "
        "EntityDistribution EntityDistributionEntry ScenarioObjectTemplate RoadRange "
        "RoadCursor Lane Polygon",
    ),
    # 1.0 spelling of the root in some writers' schemas
    **_each("played", "the file", "OpenScenario"),
}
"""Element name -> (status, why)."""


def counts() -> dict[str, int]:
    """How many elements have each status."""
    out = dict.fromkeys(STATUSES, 0)
    for status, _ in ELEMENTS.values():
        out[status] += 1
    return out


def markdown_table() -> str:
    """docs/scenarios.md's element table: one row per status and reason."""
    rows: dict[tuple[str, str], list[str]] = {}
    for name, (status, note) in ELEMENTS.items():
        rows.setdefault((status, note), []).append(name)
    lines = ["| status | elements | why |", "|---|---|---|"]
    for status in STATUSES:
        for (s, note), names in rows.items():
            if s == status:
                listed = ", ".join(f"`{n}`" for n in sorted(names))
                lines.append(f"| {status} | {listed} | {note} |")
    c = counts()
    lines.append("")
    lines.append(
        f"{len(ELEMENTS)} elements: {c['played']} played, {c['ignored']} ignored, "
        f"{c['refused']} refused."
    )
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover - prints the docs table
    sys.stdout.write(markdown_table() + "\n")
