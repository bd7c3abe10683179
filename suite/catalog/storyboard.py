"""The typed, resolved OpenSCENARIO storyboard a scenario runs (docs/openscenario.md).

``hwyeval import openscenario`` writes it (``<stem>.story.json``, every parameter and
expression already evaluated, every position already on the SUMO route); the world's
storyboard runtime (:mod:`suite.world.storyboard`) executes it each SUMO step. Both
import this module and nothing of each other.

Positions are on the scenario's route, in SUMO's terms: ``pos_m`` the route position
[m] of the entity's *front bumper* (as ``ego.pos_m``), ``lane`` the lane index of the
edge there (0 = rightmost), ``lateral_m`` [m, left +] the offset from that lane's
centre line. Times [s], speeds [m/s], accelerations [m/s²], distances [m].

:func:`story_from_json` / :func:`story_to_json` (de)serialise; every class checks its
fields in ``__post_init__`` and raises :class:`StoryError`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, fields, is_dataclass
from typing import Any

from suite.catalog.story_actions import (
    ACTION_TYPES,
    ActivateControllerAction,
    FollowTrajectoryAction,
    LaneChangeAction,
    LaneOffsetAction,
    LongitudinalDistanceAction,
    RelativeLaneTarget,
    SpeedAction,
    StopAction,
    TeleportAction,
    TrajectoryVertex,
)
from suite.catalog.story_conditions import (
    CONDITION_TYPES,
    DIMENSIONS,
    DISTANCE_TYPES,
    EDGES,
    ELEMENT_TYPES,
    ENTITY_CONDITIONS,
    ENTITY_KINDS,
    RULES,
    SHAPES,
    STATES,
    Condition,
    ConditionGroup,
    Entity,
    EntityInit,
    ReachPositionCondition,
    RelativeDistanceCondition,
    RelativeSpeedCondition,
    RoutePosition,
    SimulationTimeCondition,
    SpeedCondition,
    StateCondition,
    StoryError,
    TimeHeadwayCondition,
    TimeToCollisionCondition,
    TraveledDistanceCondition,
    Trigger,
    _one_of,
    compare,
)

__all__ = ["ACTION_TYPES", "Act", "ActivateControllerAction", "CONDITION_TYPES", "Condition",
           "ConditionGroup", "DIMENSIONS", "DISTANCE_TYPES", "EDGES", "ELEMENT_TYPES",
           "ENTITY_CONDITIONS", "ENTITY_KINDS", "Entity", "EntityInit", "Event",
           "FollowTrajectoryAction", "LaneChangeAction", "LaneOffsetAction",
           "LongitudinalDistanceAction", "Maneuver", "ManeuverGroup", "RULES",
           "ReachPositionCondition", "RelativeDistanceCondition", "RelativeLaneTarget",
           "RelativeSpeedCondition", "RoutePosition", "SHAPES", "STATES",
           "SimulationTimeCondition", "SpeedAction", "SpeedCondition", "StateCondition",
           "StopAction", "Story", "StoryError", "Storyboard", "TeleportAction",
           "TimeHeadwayCondition", "TimeToCollisionCondition", "TrajectoryVertex",
           "TraveledDistanceCondition", "Trigger", "compare", "story_from_json", "story_to_json"]

# ---------------------------------------------------------------- the storyboard tree

@dataclass(frozen=True)
class Event:
    """An event: its actions (``(name, action)``) on the maneuver group's actors, start
    ``trigger``, ``priority`` and how often it may run."""

    name: str
    actions: tuple[tuple[str, Any], ...]
    start: Trigger
    priority: str = "override"
    max_executions: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "actions", tuple((str(n), a) for n, a in self.actions))
        if not self.actions or any(not isinstance(a, ACTION_TYPES) for _, a in self.actions):
            raise StoryError(f"Event {self.name}: expected one known action or more")
        _one_of(self, "priority", ("override", "overwrite", "skip", "parallel"))


@dataclass(frozen=True)
class Maneuver:
    name: str
    events: tuple[Event, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "events", tuple(self.events))


@dataclass(frozen=True)
class ManeuverGroup:
    name: str
    actors: tuple[str, ...]
    maneuvers: tuple[Maneuver, ...]
    max_executions: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "actors", tuple(self.actors))
        object.__setattr__(self, "maneuvers", tuple(self.maneuvers))


@dataclass(frozen=True)
class Act:
    name: str
    groups: tuple[ManeuverGroup, ...]
    start: Trigger
    stop: Trigger = Trigger()

    def __post_init__(self) -> None:
        object.__setattr__(self, "groups", tuple(self.groups))


@dataclass(frozen=True)
class Story:
    name: str
    acts: tuple[Act, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "acts", tuple(self.acts))


@dataclass(frozen=True)
class Storyboard:
    """The whole resolved storyboard: entities (the ego among them), the non-ego
    entities' starts, the stories and the stop trigger; ``source`` names the file."""

    entities: tuple[Entity, ...]
    inits: tuple[EntityInit, ...]
    stories: tuple[Story, ...]
    stop: Trigger = Trigger()
    source: str = ""

    def __post_init__(self) -> None:
        for name in ("entities", "inits", "stories"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        names = [e.name for e in self.entities]
        if len(set(names)) != len(names) or sum(e.ego for e in self.entities) != 1:
            raise StoryError("Storyboard: expected distinct entity names and one ego")
        known = set(names)
        for init in self.inits:
            if init.entity not in known:
                raise StoryError(f"Storyboard: init of unknown entity {init.entity!r}")

    @property
    def ego(self) -> Entity:
        return next(e for e in self.entities if e.ego)

    def entity(self, name: str) -> Entity:
        for e in self.entities:
            if e.name == name:
                return e
        raise KeyError(name)


# ---------------------------------------------------------------- JSON

_CLASSES: dict[str, type] = {c.__name__: c for c in (
    RoutePosition, Entity, EntityInit, *CONDITION_TYPES, Condition, ConditionGroup, Trigger,
    *ACTION_TYPES, RelativeLaneTarget, TrajectoryVertex, Event, Maneuver, ManeuverGroup, Act,
    Story, Storyboard)}


def _encode(obj: Any) -> Any:
    if is_dataclass(obj) and not isinstance(obj, type):
        return {"type": type(obj).__name__,
                **{f.name: _encode(getattr(obj, f.name)) for f in fields(obj)}}
    if isinstance(obj, tuple | list):
        return [_encode(x) for x in obj]
    return obj


def _decode(data: Any) -> Any:
    if isinstance(data, list):
        return tuple(_decode(x) for x in data)
    if isinstance(data, dict):
        cls = _CLASSES.get(str(data.get("type")))
        if cls is None:
            raise StoryError(f"unknown storyboard element {data.get('type')!r}")
        kwargs = {k: _decode(v) for k, v in data.items() if k != "type"}
        try:
            return cls(**kwargs)
        except TypeError as exc:
            raise StoryError(f"{cls.__name__}: {exc}") from None
    return data


def story_to_json(story: Storyboard) -> str:
    """The storyboard as JSON text (deterministic: keys in field order)."""
    return json.dumps(_encode(story), indent=1) + "\n"


def story_from_json(text: str) -> Storyboard:
    """The storyboard of :func:`story_to_json`'s text; :class:`StoryError` if invalid."""
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise StoryError(f"not JSON: {exc}") from None
    story = _decode(data)
    if not isinstance(story, Storyboard):
        raise StoryError("expected a Storyboard at the top")
    return story
