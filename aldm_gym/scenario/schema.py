"""What the OpenSCENARIO 1.3.1 schema asks of a file's structure, beyond what the
reader reads: which children an element may have at most once (``maxOccurs`` 1 in a
sequence, or one branch of a choice), which attributes it must have, and where text
may stand.

:data:`SINGLE_CHILDREN` and :data:`REQUIRED_ATTRIBUTES` are written from the schema
(tests/scenario/test_schema.py derives them again from the XSD that scenariogeneration
ships and checks they agree). :func:`check_structure` refuses a file that repeats one
of the single children, leaves out a required attribute (but those in
:data:`LENIENT`, which files written for esmini leave out), holds text where the
schema has none, or has an element the schema does not know: a second
``StartTrigger`` on an event, a second ``Position`` in a vertex would otherwise be
read as the first one alone, a misspelt element inside one the player reads only in
part would be skipped, and a missing attribute would take a default the author never
chose.
"""

from __future__ import annotations

import difflib
from typing import Any

from aldm_gym.errors import ScenarioError

__all__ = [
    "LENIENT",
    "RENAMED",
    "REQUIRED_ATTRIBUTES",
    "SINGLE_CHILDREN",
    "TEXT_ELEMENTS",
    "check_structure",
]

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

REQUIRED_ATTRIBUTES: dict[str, frozenset[str]] = {
    "AbsoluteSpeed": frozenset({"value"}),
    "AbsoluteTargetLane": frozenset({"value"}),
    "AbsoluteTargetLaneOffset": frozenset({"value"}),
    "AbsoluteTargetSpeed": frozenset({"value"}),
    "AccelerationCondition": frozenset({"rule", "value"}),
    "Act": frozenset({"name"}),
    "Action": frozenset({"name"}),
    "Actors": frozenset({"selectTriggeringEntities"}),
    "AddValue": frozenset({"value"}),
    "AdditionalAxle": frozenset(
        {
            "maxSteering",
            "positionX",
            "positionZ",
            "trackWidth",
            "wheelDiameter",
        }
    ),
    "AngleCondition": frozenset({"angle", "angleTolerance", "angleType"}),
    "AnimationState": frozenset({"state"}),
    "AutomaticGear": frozenset({"gear"}),
    "Bin": frozenset({"weight"}),
    "Brake": frozenset({"active"}),
    "BrakeForce": frozenset({"value"}),
    "BrakePercent": frozenset({"value"}),
    "Catalog": frozenset({"name"}),
    "CatalogReference": frozenset({"catalogName", "entryName"}),
    "Center": frozenset({"x", "y", "z"}),
    "CentralObject": frozenset({"entityRef"}),
    "Clothoid": frozenset({"curvature", "length"}),
    "ClothoidSplineSegment": frozenset({"curvatureEnd", "curvatureStart", "length"}),
    "Clutch": frozenset({"active", "value"}),
    "Color": frozenset({"colorType"}),
    "ColorCmyk": frozenset({"cyan", "key", "magenta", "yellow"}),
    "ColorRgb": frozenset({"blue", "green", "red"}),
    "Condition": frozenset({"conditionEdge", "delay", "name"}),
    "ConnectTrailerAction": frozenset({"trailerRef"}),
    "Controller": frozenset({"name"}),
    "ControllerDistributionEntry": frozenset({"weight"}),
    "CustomCommandAction": frozenset({"type"}),
    "DeterministicSingleParameterDistribution": frozenset({"parameterName"}),
    "Dimensions": frozenset({"height", "length", "width"}),
    "DirectionOfTravelDistribution": frozenset({"opposite", "same"}),
    "Directory": frozenset({"path"}),
    "DistanceCondition": frozenset({"freespace", "rule", "value"}),
    "DistributionRange": frozenset({"stepWidth"}),
    "DomeFile": frozenset({"filepath"}),
    "Element": frozenset({"value"}),
    "EndOfRoadCondition": frozenset({"duration"}),
    "EntityAction": frozenset({"entityRef"}),
    "EntityDistributionEntry": frozenset({"weight"}),
    "EntityRef": frozenset({"entityRef"}),
    "EntitySelection": frozenset({"name"}),
    "Environment": frozenset({"name"}),
    "Event": frozenset({"name", "priority"}),
    "ExternalObjectReference": frozenset({"name"}),
    "File": frozenset({"filepath"}),
    "FileHeader": frozenset({"author", "date", "description", "revMajor", "revMinor"}),
    "Fog": frozenset({"visualRange"}),
    "FromCurrentEntity": frozenset({"entityRef"}),
    "FromLaneCoordinates": frozenset({"laneId", "pathS"}),
    "FromRoadCoordinates": frozenset({"pathS", "t"}),
    "FrontAxle": frozenset(
        {
            "maxSteering",
            "positionX",
            "positionZ",
            "trackWidth",
            "wheelDiameter",
        }
    ),
    "Gear": frozenset({"active"}),
    "InitialSpeedRange": frozenset({"lowerLimit", "upperLimit"}),
    "Knot": frozenset({"value"}),
    "Lane": frozenset({"id"}),
    "LaneChangeActionDynamics": frozenset({"dynamicsDimension", "dynamicsShape", "value"}),
    "LaneOffsetAction": frozenset({"continuous"}),
    "LaneOffsetActionDynamics": frozenset({"dynamicsShape"}),
    "LanePosition": frozenset({"laneId", "roadId", "s"}),
    "LateralDistanceAction": frozenset({"continuous", "entityRef", "freespace"}),
    "License": frozenset({"name"}),
    "LightState": frozenset({"mode"}),
    "LogNormalDistribution": frozenset({"expectedValue", "variance"}),
    "LogicFile": frozenset({"filepath"}),
    "LongitudinalDistanceAction": frozenset({"continuous", "entityRef", "freespace"}),
    "Maneuver": frozenset({"name"}),
    "ManeuverGroup": frozenset({"maximumExecutionCount", "name"}),
    "ManualGear": frozenset({"number"}),
    "MiscObject": frozenset({"mass", "miscObjectCategory", "name"}),
    "MonitorDeclaration": frozenset({"name", "value"}),
    "MultiplyByValue": frozenset({"value"}),
    "NormalDistribution": frozenset({"expectedValue", "variance"}),
    "Nurbs": frozenset({"order"}),
    "OffroadCondition": frozenset({"duration"}),
    "ParameterAction": frozenset({"parameterRef"}),
    "ParameterAssignment": frozenset({"parameterRef", "value"}),
    "ParameterCondition": frozenset({"parameterRef", "rule", "value"}),
    "ParameterDeclaration": frozenset({"name", "parameterType", "value"}),
    "ParkingBrake": frozenset({"active"}),
    "Pedestrian": frozenset({"mass", "name", "pedestrianCategory"}),
    "PedestrianGesture": frozenset({"gesture"}),
    "Performance": frozenset({"maxAcceleration", "maxDeceleration", "maxSpeed"}),
    "Phase": frozenset({"duration", "name"}),
    "PoissonDistribution": frozenset({"expectedValue"}),
    "Precipitation": frozenset({"precipitationType"}),
    "Private": frozenset({"entityRef"}),
    "Property": frozenset({"name", "value"}),
    "Range": frozenset({"lowerLimit", "upperLimit"}),
    "ReachPositionCondition": frozenset({"tolerance"}),
    "RearAxle": frozenset({"maxSteering", "positionX", "positionZ", "trackWidth", "wheelDiameter"}),
    "RelativeAngleCondition": frozenset({"angle", "angleTolerance", "angleType", "entityRef"}),
    "RelativeClearanceCondition": frozenset({"freeSpace", "oppositeLanes"}),
    "RelativeDistanceCondition": frozenset(
        {
            "entityRef",
            "freespace",
            "relativeDistanceType",
            "rule",
            "value",
        }
    ),
    "RelativeLanePosition": frozenset({"dLane", "entityRef"}),
    "RelativeObjectPosition": frozenset({"dx", "dy", "entityRef"}),
    "RelativeRoadPosition": frozenset({"ds", "dt", "entityRef"}),
    "RelativeSpeedCondition": frozenset({"entityRef", "rule", "value"}),
    "RelativeSpeedToMaster": frozenset({"speedTargetValueType", "value"}),
    "RelativeTargetLane": frozenset({"entityRef", "value"}),
    "RelativeTargetLaneOffset": frozenset({"entityRef", "value"}),
    "RelativeTargetSpeed": frozenset({"continuous", "entityRef", "speedTargetValueType", "value"}),
    "RelativeWorldPosition": frozenset({"dx", "dy", "entityRef"}),
    "RoadCondition": frozenset({"frictionScaleFactor"}),
    "RoadCursor": frozenset({"roadId"}),
    "RoadPosition": frozenset({"roadId", "s", "t"}),
    "Route": frozenset({"closed", "name"}),
    "ScenarioFile": frozenset({"filepath"}),
    "ScenarioObject": frozenset({"name"}),
    "SceneGraphFile": frozenset({"filepath"}),
    "SensorReference": frozenset({"name"}),
    "SetAction": frozenset({"value"}),
    "SetMonitorAction": frozenset({"monitorRef", "value"}),
    "SimulationTimeCondition": frozenset({"rule", "value"}),
    "SpeedActionDynamics": frozenset({"dynamicsDimension", "dynamicsShape", "value"}),
    "SpeedCondition": frozenset({"rule", "value"}),
    "SpeedProfileAction": frozenset({"followingMode"}),
    "SpeedProfileEntry": frozenset({"speed"}),
    "StandStillCondition": frozenset({"duration"}),
    "SteeringWheel": frozenset({"active", "value"}),
    "Stochastic": frozenset({"numberOfTestRuns"}),
    "StochasticDistribution": frozenset({"parameterName"}),
    "Story": frozenset({"name"}),
    "StoryboardElementStateCondition": frozenset(
        {
            "state",
            "storyboardElementRef",
            "storyboardElementType",
        }
    ),
    "Sun": frozenset({"azimuth", "elevation"}),
    "SynchronizeAction": frozenset({"masterEntityRef"}),
    "TargetDistanceSteadyState": frozenset({"distance"}),
    "TargetTimeSteadyState": frozenset({"time"}),
    "Throttle": frozenset({"active", "value"}),
    "TimeHeadwayCondition": frozenset({"entityRef", "freespace", "rule", "value"}),
    "TimeOfDay": frozenset({"animation", "dateTime"}),
    "TimeOfDayCondition": frozenset({"dateTime", "rule"}),
    "TimeToCollisionCondition": frozenset({"freespace", "rule", "value"}),
    "Timing": frozenset({"domainAbsoluteRelative", "offset", "scale"}),
    "TrafficAreaAction": frozenset({"continuous", "numberOfEntities"}),
    "TrafficDefinition": frozenset({"name"}),
    "TrafficDistributionEntry": frozenset({"weight"}),
    "TrafficSignalCondition": frozenset({"name", "state"}),
    "TrafficSignalController": frozenset({"name"}),
    "TrafficSignalControllerAction": frozenset({"phase", "trafficSignalControllerRef"}),
    "TrafficSignalControllerCondition": frozenset({"phase", "trafficSignalControllerRef"}),
    "TrafficSignalGroupState": frozenset({"state"}),
    "TrafficSignalState": frozenset({"state", "trafficSignalId"}),
    "TrafficSignalStateAction": frozenset({"name", "state"}),
    "TrafficSinkAction": frozenset({"radius"}),
    "TrafficSourceAction": frozenset({"radius", "rate"}),
    "TrafficSwarmAction": frozenset(
        {
            "innerRadius",
            "numberOfVehicles",
            "offset",
            "semiMajorAxis",
            "semiMinorAxis",
        }
    ),
    "TrailerCoupler": frozenset({"dx"}),
    "TrailerHitch": frozenset({"dx"}),
    "TrailerRef": frozenset({"entityRef"}),
    "Trajectory": frozenset({"closed", "name"}),
    "TrajectoryFollowingMode": frozenset({"followingMode"}),
    "TrajectoryPosition": frozenset({"s"}),
    "TraveledDistanceCondition": frozenset({"value"}),
    "TriggeringEntities": frozenset({"triggeringEntitiesRule"}),
    "UserDefinedAnimation": frozenset({"userDefinedAnimationType"}),
    "UserDefinedComponent": frozenset({"userDefinedComponentType"}),
    "UserDefinedDistribution": frozenset({"type"}),
    "UserDefinedLight": frozenset({"userDefinedLightType"}),
    "UserDefinedValueCondition": frozenset({"name", "rule", "value"}),
    "ValueConstraint": frozenset({"rule", "value"}),
    "VariableAction": frozenset({"variableRef"}),
    "VariableCondition": frozenset({"rule", "value", "variableRef"}),
    "VariableDeclaration": frozenset({"name", "value", "variableType"}),
    "Vehicle": frozenset({"name", "vehicleCategory"}),
    "VehicleCategoryDistributionEntry": frozenset({"category", "weight"}),
    "VehicleComponent": frozenset({"vehicleComponentType"}),
    "VehicleLight": frozenset({"vehicleLightType"}),
    "VehicleRoleDistributionEntry": frozenset({"role", "weight"}),
    "VisibilityAction": frozenset({"graphics", "sensors", "traffic"}),
    "Waypoint": frozenset({"routeStrategy"}),
    "Wind": frozenset({"direction", "speed"}),
    "WorldPosition": frozenset({"x", "y"}),
}
"""Element tag -> the attributes the schema requires of it."""

LENIENT: dict[tuple[str, str], str] = {
    ("SpeedActionDynamics", "dynamicsDimension"): "time, for a step",
    ("SpeedActionDynamics", "value"): "0, for a step",
    ("RelativeObjectPosition", "dx"): "0",
    ("RelativeObjectPosition", "dy"): "0",
    ("RelativeTargetSpeed", "speedTargetValueType"): "delta",
    ("Condition", "conditionEdge"): "none",
    ("LaneOffsetAction", "continuous"): "false",
}
"""Required attributes that files written for esmini leave out (its own examples do),
with the value the player takes, as esmini does. Every other missing required
attribute is an error."""

TEXT_ELEMENTS = frozenset(
    {"CustomCommandAction", "CustomContent", "License", "UserDefinedDistribution"}
)
"""The elements whose content is text; anywhere else text is an error."""


RENAMED: dict[str, str] = {"CentralSwarmObject": "CentralObject"}
"""Elements of OpenSCENARIO 1.0 that later versions renamed, checked as the new name
(the player reads both)."""


def check_structure(root: Any, source: str) -> None:
    """Raise unless every element under ``root`` is an element of OpenSCENARIO 1.3 with
    the attributes the schema requires (but :data:`LENIENT`'s), no text where the
    schema has none, and no repeat of a child the schema allows once.

    :param source: the file's name, for the message.
    :raises ScenarioError: ``file.xosc:57 <Event>: a second <StartTrigger>; the schema
        allows one``, ``file.xosc:12 <SpeedActionDynamic>: not an element of
        OpenSCENARIO 1.3 (did you mean <SpeedActionDynamics>?)``, ``file.xosc:30
        <Event>: missing attribute 'priority' (the schema requires it)``,
        ``file.xosc:31 <Event>: text 'oops' where the schema has none``.
    """
    from aldm_gym.scenario.elements import ELEMENTS

    for el in root.iter():
        tag = el.tag
        if not isinstance(tag, str):
            continue  # comments, processing instructions
        tag = RENAMED.get(tag, tag)
        if tag not in ELEMENTS:
            near = difflib.get_close_matches(tag, list(ELEMENTS), n=1)
            hint = f" (did you mean <{near[0]}>?)" if near else ""
            parent = el.getparent()
            inside = f" inside <{parent.tag}>" if parent is not None else ""
            raise ScenarioError(
                f"{source}:{el.sourceline} <{tag}>: not an element of OpenSCENARIO "
                f"1.3{inside}{hint}"
            )
        for name in sorted(REQUIRED_ATTRIBUTES.get(tag, ())):
            if el.get(name) is None and (tag, name) not in LENIENT:
                raise ScenarioError(
                    f"{source}:{el.sourceline} <{tag}>: missing attribute {name!r} (the "
                    "schema requires it)"
                )
        if tag not in TEXT_ELEMENTS:
            _check_no_text(el, source)
        single = SINGLE_CHILDREN.get(tag)
        if not single:
            continue
        seen: set[str] = set()
        for child in el:
            kid = RENAMED.get(child.tag, child.tag) if isinstance(child.tag, str) else child.tag
            if not isinstance(kid, str) or kid not in single:
                continue
            if kid in seen:
                raise ScenarioError(
                    f"{source}:{child.sourceline} <{tag}>: a second <{kid}>; the schema allows one"
                )
            seen.add(kid)


def _check_no_text(el: Any, source: str) -> None:
    """Raise where an element holds text (between its children too)."""
    for text in (el.text, *(child.tail for child in el)):
        if text and text.strip():
            shown = text.strip()
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            raise ScenarioError(
                f"{source}:{el.sourceline} <{el.tag}>: text {shown!r} where the schema has none"
            )
