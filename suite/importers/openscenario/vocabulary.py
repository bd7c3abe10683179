"""The element names the importer reads, and those it knowingly leaves aside; any other
element of a scenario is an error naming it and its line (nothing is dropped
silently). Where an element may appear is checked by the readers themselves."""

from __future__ import annotations

from typing import Any

from suite.importers.openscenario.errors import fail_at

__all__ = ["IGNORED", "READ", "check_vocabulary"]

READ = frozenset({
    "OpenSCENARIO", "FileHeader", "ParameterDeclarations", "ParameterDeclaration",
    "ConstraintGroup", "ValueConstraint", "CatalogLocations", "VehicleCatalog",
    "PedestrianCatalog", "MiscObjectCatalog", "ControllerCatalog", "ManeuverCatalog",
    "TrajectoryCatalog", "EnvironmentCatalog", "RouteCatalog", "Directory", "RoadNetwork",
    "LogicFile", "Entities", "ScenarioObject", "Vehicle", "Pedestrian", "MiscObject",
    "BoundingBox", "Center", "Dimensions", "Storyboard", "Init", "Actions", "Private",
    "PrivateAction", "GlobalAction", "Story", "Act", "ManeuverGroup", "Actors", "EntityRef",
    "Maneuver", "Event", "Action", "StartTrigger", "StopTrigger", "ConditionGroup",
    "Condition", "ByValueCondition", "ByEntityCondition", "TriggeringEntities",
    "EntityCondition", "SimulationTimeCondition", "StoryboardElementStateCondition",
    "RelativeDistanceCondition", "TimeHeadwayCondition", "TimeToCollisionCondition",
    "TimeToCollisionConditionTarget", "ReachPositionCondition", "TraveledDistanceCondition",
    "SpeedCondition", "RelativeSpeedCondition", "LongitudinalAction", "SpeedAction",
    "SpeedActionDynamics", "SpeedActionTarget", "AbsoluteTargetSpeed", "RelativeTargetSpeed",
    "LongitudinalDistanceAction", "LateralAction", "LaneChangeAction",
    "LaneChangeActionDynamics", "LaneChangeTarget", "RelativeTargetLane",
    "AbsoluteTargetLane", "LaneOffsetAction", "LaneOffsetActionDynamics", "LaneOffsetTarget",
    "AbsoluteTargetLaneOffset", "RelativeTargetLaneOffset", "TeleportAction", "Position",
    "WorldPosition", "LanePosition", "RoadPosition", "RelativeLanePosition",
    "RelativeRoadPosition", "RelativeObjectPosition", "RelativeWorldPosition", "Orientation",
    "ControllerAction", "ActivateControllerAction", "RoutingAction",
    "FollowTrajectoryAction", "TrajectoryRef", "Trajectory", "Shape", "Polyline", "Vertex",
    "TimeReference", "Timing", "TrajectoryFollowingMode", "ParameterAssignments",
    "ParameterAssignment", "CatalogReference",
})
"""Elements whose content the import reads (where the readers expect them)."""

IGNORED = frozenset({
    "License", "Properties", "Property", "File", "Performance", "Axles", "FrontAxle",
    "RearAxle", "AdditionalAxle", "ObjectController", "Controller", "EnvironmentAction",
    "Environment", "TimeOfDay", "Weather", "RoadCondition", "Sun", "Fog", "Precipitation",
    "Wind", "DomeImage", "SceneGraphFile", "DynamicConstraints",
})
"""Elements knowingly left aside: metadata (License, Properties, File), vehicle
dynamics the run does not use (Performance, Axles: hwyeval's vehicle model drives the
ego, scripted entities follow their actions), controllers (the ego's is the one under
test), the environment and its action (weather, light: no sensors are simulated), a
scene graph, and a distance action's dynamic constraints (the gap is taken at once)."""


def check_vocabulary(root: Any) -> None:
    """Every element of ``root`` is read or knowingly ignored (with all it holds), else
    an error naming it."""
    stack = [root]
    while stack:
        el = stack.pop()
        if not isinstance(el.tag, str) or el.tag in IGNORED:
            continue
        if el.tag not in READ:
            raise fail_at(el, f"{el.tag} is not supported")
        if el.tag == "ParameterDeclarations" and el.getparent() is not None \
                and el.getparent().getparent() is not None:
            raise fail_at(el, "parameter declarations inside the storyboard or the "
                          "entities are not supported (declare them at the top)")
        stack.extend(reversed(list(el)))
