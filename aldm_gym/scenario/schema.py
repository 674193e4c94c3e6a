"""Which children an OpenSCENARIO element may have at most once (ASAM OpenSCENARIO
XML 1.3.1's schema: ``maxOccurs`` 1 in a sequence, or one branch of a choice).

:data:`SINGLE_CHILDREN` is written from the schema (tests/scenario/test_schema.py derives
it again from the XSD that scenariogeneration ships and checks the two agree). The
reader refuses a file that repeats one of them, or has an element the schema does not
know (:func:`check_single_children`): a second ``StartTrigger`` on an event, a second
``Position`` in a vertex would otherwise be read as the first one alone, and a
misspelt element inside one the player reads only in part would be skipped.
"""

from __future__ import annotations

import difflib
from typing import Any

from aldm_gym.errors import ScenarioError

__all__ = ["SINGLE_CHILDREN", "check_single_children"]

SINGLE_CHILDREN: dict[str, frozenset[str]] = {
    "AbsoluteSpeed": frozenset({"TargetDistanceSteadyState", "TargetTimeSteadyState"}),
    "AcquirePositionAction": frozenset({"Position"}),
    "Act": frozenset({"StartTrigger", "StopTrigger"}),
    "Action": frozenset({"GlobalAction", "PrivateAction", "UserDefinedAction"}),
    "AddEntityAction": frozenset({"Position"}),
    "AnimationAction": frozenset({"AnimationState", "AnimationType"}),
    "AnimationFile": frozenset({"File"}),
    "AnimationType": frozenset(
        {
            "AnimationFile",
            "ComponentAnimation",
            "PedestrianAnimation",
            "UserDefinedAnimation",
        }
    ),
    "AppearanceAction": frozenset({"AnimationAction", "LightStateAction"}),
    "AssignControllerAction": frozenset({"CatalogReference", "Controller", "ObjectController"}),
    "AssignRouteAction": frozenset({"CatalogReference", "Route"}),
    "Axles": frozenset({"FrontAxle", "RearAxle"}),
    "Bin": frozenset({"Range"}),
    "BoundingBox": frozenset({"Center", "Dimensions"}),
    "Brake": frozenset({"BrakeForce", "BrakePercent"}),
    "ByEntityCondition": frozenset({"EntityCondition", "TriggeringEntities"}),
    "ByValueCondition": frozenset(
        {
            "ParameterCondition",
            "SimulationTimeCondition",
            "StoryboardElementStateCondition",
            "TimeOfDayCondition",
            "TrafficSignalCondition",
            "TrafficSignalControllerCondition",
            "UserDefinedValueCondition",
            "VariableCondition",
        }
    ),
    "CatalogLocations": frozenset(
        {
            "ControllerCatalog",
            "EnvironmentCatalog",
            "ManeuverCatalog",
            "MiscObjectCatalog",
            "PedestrianCatalog",
            "RouteCatalog",
            "TrajectoryCatalog",
            "VehicleCatalog",
        }
    ),
    "CatalogReference": frozenset({"ParameterAssignments"}),
    "Clothoid": frozenset({"Position"}),
    "ClothoidSplineSegment": frozenset({"PositionStart"}),
    "CollisionCondition": frozenset({"ByType", "EntityRef"}),
    "Color": frozenset({"ColorCmyk", "ColorRgb"}),
    "ComponentAnimation": frozenset({"UserDefinedComponent", "VehicleComponent"}),
    "Condition": frozenset({"ByEntityCondition", "ByValueCondition"}),
    "ControlPoint": frozenset({"Position"}),
    "Controller": frozenset({"ParameterDeclarations", "Properties"}),
    "ControllerAction": frozenset(
        {
            "ActivateControllerAction",
            "AssignControllerAction",
            "OverrideControllerValueAction",
        }
    ),
    "ControllerCatalog": frozenset({"Directory"}),
    "ControllerDistributionEntry": frozenset({"CatalogReference", "Controller"}),
    "DeterministicMultiParameterDistribution": frozenset({"ValueSetDistribution"}),
    "DeterministicSingleParameterDistribution": frozenset(
        {
            "DistributionRange",
            "DistributionSet",
            "UserDefinedDistribution",
        }
    ),
    "DistanceCondition": frozenset({"Position"}),
    "DistributionRange": frozenset({"Range"}),
    "DomeImage": frozenset({"DomeFile"}),
    "EntityAction": frozenset({"AddEntityAction", "DeleteEntityAction"}),
    "EntityCondition": frozenset(
        {
            "AccelerationCondition",
            "AngleCondition",
            "CollisionCondition",
            "DistanceCondition",
            "EndOfRoadCondition",
            "OffroadCondition",
            "ReachPositionCondition",
            "RelativeAngleCondition",
            "RelativeClearanceCondition",
            "RelativeDistanceCondition",
            "RelativeSpeedCondition",
            "SpeedCondition",
            "StandStillCondition",
            "TimeHeadwayCondition",
            "TimeToCollisionCondition",
            "TraveledDistanceCondition",
        }
    ),
    "EntityDistributionEntry": frozenset({"ScenarioObjectTemplate"}),
    "EntitySelection": frozenset({"Members"}),
    "Environment": frozenset({"ParameterDeclarations", "RoadCondition", "TimeOfDay", "Weather"}),
    "EnvironmentAction": frozenset({"CatalogReference", "Environment"}),
    "EnvironmentCatalog": frozenset({"Directory"}),
    "Event": frozenset({"StartTrigger"}),
    "FileHeader": frozenset({"License", "Properties"}),
    "FinalSpeed": frozenset({"AbsoluteSpeed", "RelativeSpeedToMaster"}),
    "Fog": frozenset({"BoundingBox"}),
    "FollowTrajectoryAction": frozenset(
        {
            "CatalogReference",
            "TimeReference",
            "Trajectory",
            "TrajectoryFollowingMode",
            "TrajectoryRef",
        }
    ),
    "Gear": frozenset({"AutomaticGear", "ManualGear"}),
    "GeoPosition": frozenset({"Orientation"}),
    "GlobalAction": frozenset(
        {
            "EntityAction",
            "EnvironmentAction",
            "InfrastructureAction",
            "ParameterAction",
            "SetMonitorAction",
            "TrafficAction",
            "VariableAction",
        }
    ),
    "InRoutePosition": frozenset(
        {
            "FromCurrentEntity",
            "FromLaneCoordinates",
            "FromRoadCoordinates",
        }
    ),
    "InfrastructureAction": frozenset({"TrafficSignalAction"}),
    "Init": frozenset({"Actions"}),
    "LaneChangeAction": frozenset({"LaneChangeActionDynamics", "LaneChangeTarget"}),
    "LaneChangeTarget": frozenset({"AbsoluteTargetLane", "RelativeTargetLane"}),
    "LaneOffsetAction": frozenset({"LaneOffsetActionDynamics", "LaneOffsetTarget"}),
    "LaneOffsetTarget": frozenset({"AbsoluteTargetLaneOffset", "RelativeTargetLaneOffset"}),
    "LanePosition": frozenset({"Orientation"}),
    "LateralAction": frozenset({"LaneChangeAction", "LaneOffsetAction", "LateralDistanceAction"}),
    "LateralDistanceAction": frozenset({"DynamicConstraints"}),
    "LightState": frozenset({"Color"}),
    "LightStateAction": frozenset({"LightState", "LightType"}),
    "LightType": frozenset({"UserDefinedLight", "VehicleLight"}),
    "LogNormalDistribution": frozenset({"Range"}),
    "LongitudinalAction": frozenset(
        {
            "LongitudinalDistanceAction",
            "SpeedAction",
            "SpeedProfileAction",
        }
    ),
    "LongitudinalDistanceAction": frozenset({"DynamicConstraints"}),
    "Maneuver": frozenset({"ParameterDeclarations"}),
    "ManeuverCatalog": frozenset({"Directory"}),
    "ManeuverGroup": frozenset({"Actors"}),
    "MiscObject": frozenset({"BoundingBox", "ParameterDeclarations", "Properties"}),
    "MiscObjectCatalog": frozenset({"Directory"}),
    "ModifyAction": frozenset({"Rule"}),
    "NormalDistribution": frozenset({"Range"}),
    "ObjectController": frozenset({"CatalogReference", "Controller"}),
    "OpenSCENARIO": frozenset(
        {
            "Catalog",
            "CatalogLocations",
            "Entities",
            "FileHeader",
            "MonitorDeclarations",
            "ParameterDeclarations",
            "ParameterValueDistribution",
            "RoadNetwork",
            "Storyboard",
            "VariableDeclarations",
        }
    ),
    "OpenScenario": frozenset(
        {
            "Catalog",
            "CatalogLocations",
            "Entities",
            "FileHeader",
            "MonitorDeclarations",
            "ParameterDeclarations",
            "ParameterValueDistribution",
            "RoadNetwork",
            "Storyboard",
            "VariableDeclarations",
        }
    ),
    "OverrideControllerValueAction": frozenset(
        {
            "Brake",
            "Clutch",
            "Gear",
            "ParkingBrake",
            "SteeringWheel",
            "Throttle",
        }
    ),
    "ParameterAction": frozenset({"ModifyAction", "SetAction"}),
    "ParameterValueDistribution": frozenset({"Deterministic", "ScenarioFile", "Stochastic"}),
    "ParkingBrake": frozenset({"BrakeForce", "BrakePercent"}),
    "Pedestrian": frozenset({"BoundingBox", "ParameterDeclarations", "Properties"}),
    "PedestrianCatalog": frozenset({"Directory"}),
    "Phase": frozenset({"TrafficSignalGroupState"}),
    "PoissonDistribution": frozenset({"Range"}),
    "Position": frozenset(
        {
            "GeoPosition",
            "LanePosition",
            "RelativeLanePosition",
            "RelativeObjectPosition",
            "RelativeRoadPosition",
            "RelativeWorldPosition",
            "RoadPosition",
            "RoutePosition",
            "TrajectoryPosition",
            "WorldPosition",
        }
    ),
    "PositionStart": frozenset(
        {
            "GeoPosition",
            "LanePosition",
            "RelativeLanePosition",
            "RelativeObjectPosition",
            "RelativeRoadPosition",
            "RelativeWorldPosition",
            "RoadPosition",
            "RoutePosition",
            "TrajectoryPosition",
            "WorldPosition",
        }
    ),
    "PrivateAction": frozenset(
        {
            "ActivateControllerAction",
            "AppearanceAction",
            "ControllerAction",
            "LateralAction",
            "LongitudinalAction",
            "RoutingAction",
            "SynchronizeAction",
            "TeleportAction",
            "TrailerAction",
            "VisibilityAction",
        }
    ),
    "ReachPositionCondition": frozenset({"Position"}),
    "RelativeLanePosition": frozenset({"Orientation"}),
    "RelativeObjectPosition": frozenset({"Orientation"}),
    "RelativeRoadPosition": frozenset({"Orientation"}),
    "RelativeSpeedToMaster": frozenset({"TargetDistanceSteadyState", "TargetTimeSteadyState"}),
    "RelativeWorldPosition": frozenset({"Orientation"}),
    "RoadCondition": frozenset({"Properties"}),
    "RoadNetwork": frozenset({"LogicFile", "SceneGraphFile", "TrafficSignals", "UsedArea"}),
    "RoadPosition": frozenset({"Orientation"}),
    "Route": frozenset({"ParameterDeclarations"}),
    "RouteCatalog": frozenset({"Directory"}),
    "RoutePosition": frozenset({"InRoutePosition", "Orientation", "RouteRef"}),
    "RouteRef": frozenset({"CatalogReference", "Route"}),
    "RoutingAction": frozenset(
        {
            "AcquirePositionAction",
            "AssignRouteAction",
            "FollowTrajectoryAction",
            "RandomRouteAction",
        }
    ),
    "Rule": frozenset({"AddValue", "MultiplyByValue"}),
    "ScenarioObject": frozenset(
        {
            "CatalogReference",
            "ExternalObjectReference",
            "MiscObject",
            "Pedestrian",
            "Vehicle",
        }
    ),
    "ScenarioObjectTemplate": frozenset(
        {
            "CatalogReference",
            "ExternalObjectReference",
            "MiscObject",
            "Pedestrian",
            "Vehicle",
        }
    ),
    "Shape": frozenset({"Clothoid", "ClothoidSpline", "Nurbs", "Polyline"}),
    "SpeedAction": frozenset({"SpeedActionDynamics", "SpeedActionTarget"}),
    "SpeedActionTarget": frozenset({"AbsoluteTargetSpeed", "RelativeTargetSpeed"}),
    "SpeedProfileAction": frozenset({"DynamicConstraints"}),
    "StochasticDistribution": frozenset(
        {
            "Histogram",
            "LogNormalDistribution",
            "NormalDistribution",
            "PoissonDistribution",
            "ProbabilityDistributionSet",
            "UniformDistribution",
            "UserDefinedDistribution",
        }
    ),
    "Story": frozenset({"ParameterDeclarations"}),
    "Storyboard": frozenset({"Init", "StopTrigger"}),
    "SynchronizeAction": frozenset({"FinalSpeed", "TargetPosition", "TargetPositionMaster"}),
    "TargetPosition": frozenset(
        {
            "GeoPosition",
            "LanePosition",
            "RelativeLanePosition",
            "RelativeObjectPosition",
            "RelativeRoadPosition",
            "RelativeWorldPosition",
            "RoadPosition",
            "RoutePosition",
            "TrajectoryPosition",
            "WorldPosition",
        }
    ),
    "TargetPositionMaster": frozenset(
        {
            "GeoPosition",
            "LanePosition",
            "RelativeLanePosition",
            "RelativeObjectPosition",
            "RelativeRoadPosition",
            "RelativeWorldPosition",
            "RoadPosition",
            "RoutePosition",
            "TrajectoryPosition",
            "WorldPosition",
        }
    ),
    "TeleportAction": frozenset({"Position"}),
    "TimeReference": frozenset({"None", "Timing"}),
    "TimeToCollisionCondition": frozenset({"TimeToCollisionConditionTarget"}),
    "TimeToCollisionConditionTarget": frozenset({"EntityRef", "Position"}),
    "TrafficAction": frozenset(
        {
            "TrafficAreaAction",
            "TrafficSinkAction",
            "TrafficSourceAction",
            "TrafficStopAction",
            "TrafficSwarmAction",
        }
    ),
    "TrafficArea": frozenset({"Polygon"}),
    "TrafficAreaAction": frozenset({"TrafficArea", "TrafficDistribution"}),
    "TrafficDefinition": frozenset(
        {
            "ControllerDistribution",
            "VehicleCategoryDistribution",
            "VehicleRoleDistribution",
        }
    ),
    "TrafficDistributionEntry": frozenset({"EntityDistribution", "Properties"}),
    "TrafficSignalAction": frozenset({"TrafficSignalControllerAction", "TrafficSignalStateAction"}),
    "TrafficSinkAction": frozenset({"Position", "TrafficDefinition"}),
    "TrafficSourceAction": frozenset({"Position", "TrafficDefinition", "TrafficDistribution"}),
    "TrafficSwarmAction": frozenset(
        {
            "CentralObject",
            "DirectionOfTravelDistribution",
            "InitialSpeedRange",
            "TrafficDefinition",
            "TrafficDistribution",
        }
    ),
    "TrailerAction": frozenset({"ConnectTrailerAction", "DisconnectTrailerAction"}),
    "Trajectory": frozenset({"ParameterDeclarations", "Shape"}),
    "TrajectoryCatalog": frozenset({"Directory"}),
    "TrajectoryPosition": frozenset({"Orientation", "TrajectoryRef"}),
    "TrajectoryRef": frozenset({"CatalogReference", "Trajectory"}),
    "UniformDistribution": frozenset({"Range"}),
    "UserDefinedAction": frozenset({"CustomCommandAction"}),
    "VariableAction": frozenset({"ModifyAction", "SetAction"}),
    "Vehicle": frozenset(
        {
            "Axles",
            "BoundingBox",
            "ParameterDeclarations",
            "Performance",
            "Properties",
            "Trailer",
            "TrailerCoupler",
            "TrailerHitch",
        }
    ),
    "VehicleCatalog": frozenset({"Directory"}),
    "Vertex": frozenset({"Position"}),
    "VisibilityAction": frozenset({"SensorReferenceSet"}),
    "Waypoint": frozenset({"Position"}),
    "Weather": frozenset({"DomeImage", "Fog", "Precipitation", "Sun", "Wind"}),
}
"""Element tag -> the child tags it may have at most once."""


def check_single_children(root: Any, source: str) -> None:
    """Raise unless every element under ``root`` is an element of OpenSCENARIO 1.3 and
    none repeats a child the schema allows once.

    :param source: the file's name, for the message.
    :raises ScenarioError: ``file.xosc:57 <Event>: a second <StartTrigger>; the schema
        allows one``, or ``file.xosc:12 <SpeedActionDynamic>: not an element of
        OpenSCENARIO 1.3 (did you mean <SpeedActionDynamics>?)``.
    """
    from aldm_gym.scenario.elements import ELEMENTS

    for el in root.iter():
        tag = el.tag
        if not isinstance(tag, str):
            continue  # comments, processing instructions
        if tag not in ELEMENTS:
            near = difflib.get_close_matches(tag, list(ELEMENTS), n=1)
            hint = f" (did you mean <{near[0]}>?)" if near else ""
            parent = el.getparent()
            inside = f" inside <{parent.tag}>" if parent is not None else ""
            raise ScenarioError(
                f"{source}:{el.sourceline} <{tag}>: not an element of OpenSCENARIO "
                f"1.3{inside}{hint}"
            )
        single = SINGLE_CHILDREN.get(tag)
        if not single:
            continue
        seen: set[str] = set()
        for child in el:
            kid = child.tag
            if not isinstance(kid, str) or kid not in single:
                continue
            if kid in seen:
                raise ScenarioError(
                    f"{source}:{child.sourceline} <{tag}>: a second <{kid}>; the schema allows one"
                )
            seen.add(kid)
