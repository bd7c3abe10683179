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
import math
from dataclasses import dataclass, fields, is_dataclass
from typing import Any

__all__ = [
    "ACTION_TYPES", "CONDITION_TYPES", "Act", "ActivateControllerAction", "Condition",
    "ConditionGroup", "Entity", "EntityInit", "Event", "FollowTrajectoryAction",
    "LaneChangeAction", "LaneOffsetAction", "LongitudinalDistanceAction", "Maneuver",
    "ManeuverGroup", "RelativeDistanceCondition", "RelativeLaneTarget",
    "RelativeSpeedCondition", "ReachPositionCondition", "RoutePosition",
    "SimulationTimeCondition", "SpeedAction", "SpeedCondition", "StateCondition",
    "StopAction", "Story", "StoryError", "Storyboard", "TeleportAction",
    "TimeHeadwayCondition", "TimeToCollisionCondition", "TrajectoryVertex",
    "TraveledDistanceCondition", "Trigger", "story_from_json", "story_to_json",
]

RULES = ("greaterThan", "lessThan", "equalTo", "greaterOrEqual", "lessOrEqual", "notEqualTo")
EDGES = ("rising", "falling", "risingOrFalling", "none")
SHAPES = ("step", "linear", "cubic", "sinusoidal")
DIMENSIONS = ("time", "distance", "rate")
ENTITY_KINDS = ("vehicle", "pedestrian", "misc")
ELEMENT_TYPES = ("story", "act", "maneuverGroup", "maneuver", "event", "action")
STATES = ("startTransition", "endTransition", "stopTransition", "skipTransition",
          "completeState", "runningState", "standbyState")
DISTANCE_TYPES = ("longitudinal", "lateral", "cartesian", "euclidianDistance")


class StoryError(ValueError):
    """A storyboard value that is not what the model allows: ``where`` and why."""


def _finite(owner: object, *names: str) -> None:
    for name in names:
        v = getattr(owner, name)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise StoryError(f"{type(owner).__name__}.{name}: expected a finite number, "
                             f"got {v!r}")
        object.__setattr__(owner, name, float(v))


def _one_of(owner: object, name: str, options: tuple[str, ...]) -> None:
    v = getattr(owner, name)
    if v not in options:
        raise StoryError(f"{type(owner).__name__}.{name}: expected one of {list(options)}, "
                         f"got {v!r}")


def _non_negative(owner: object, *names: str) -> None:
    _finite(owner, *names)
    for name in names:
        if getattr(owner, name) < 0.0:
            raise StoryError(f"{type(owner).__name__}.{name}: expected >= 0, got "
                             f"{getattr(owner, name)!r}")


def compare(value: float, rule: str, threshold: float) -> bool:
    """OpenSCENARIO's Rule: ``value <rule> threshold`` (equalTo within 1e-9)."""
    if rule == "greaterThan":
        return value > threshold
    if rule == "lessThan":
        return value < threshold
    if rule == "greaterOrEqual":
        return value >= threshold
    if rule == "lessOrEqual":
        return value <= threshold
    if rule == "equalTo":
        return abs(value - threshold) <= 1e-9
    return abs(value - threshold) > 1e-9


# ---------------------------------------------------------------- positions, entities

@dataclass(frozen=True)
class RoutePosition:
    """A place on the route: front bumper route position ``pos_m`` [m], ``lane`` index,
    ``lateral_m`` [m, left +] from its centre, ``heading_rad`` [rad] from its direction."""

    pos_m: float
    lane: int
    lateral_m: float = 0.0
    heading_rad: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "pos_m", "lateral_m", "heading_rad")
        if isinstance(self.lane, bool) or not isinstance(self.lane, int) or self.lane < 0:
            raise StoryError(f"RoutePosition.lane: expected an int >= 0, got {self.lane!r}")


@dataclass(frozen=True)
class Entity:
    """A scenario object: ``name``, ``kind`` (vehicle, pedestrian, misc), box
    ``length_m`` x ``width_m`` [m], ``front_m`` [m]: the front bumper's distance ahead of
    the OpenSCENARIO reference point (bounding box centre x + length / 2), ``ego``."""

    name: str
    kind: str
    length_m: float
    width_m: float
    front_m: float
    ego: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise StoryError(f"Entity.name: expected a non-empty string, got {self.name!r}")
        _one_of(self, "kind", ENTITY_KINDS)
        _finite(self, "length_m", "width_m", "front_m")
        if self.length_m <= 0.0 or self.width_m <= 0.0:
            raise StoryError(f"Entity {self.name}: box sizes must be > 0")


@dataclass(frozen=True)
class EntityInit:
    """Where a non-ego entity starts (t = 0) and at what speed [m/s]."""

    entity: str
    position: RoutePosition
    speed_mps: float = 0.0

    def __post_init__(self) -> None:
        _non_negative(self, "speed_mps")
        if not isinstance(self.position, RoutePosition):
            raise StoryError("EntityInit.position: expected a RoutePosition")


# ---------------------------------------------------------------- conditions

@dataclass(frozen=True)
class SimulationTimeCondition:
    """Run time [s] ``rule`` ``value_s``."""

    value_s: float
    rule: str

    def __post_init__(self) -> None:
        _finite(self, "value_s")
        _one_of(self, "rule", RULES)


@dataclass(frozen=True)
class StateCondition:
    """StoryboardElementStateCondition: the element ``ref`` of ``element_type`` is in
    (or has just taken) ``state``."""

    element_type: str
    ref: str
    state: str

    def __post_init__(self) -> None:
        _one_of(self, "element_type", ELEMENT_TYPES)
        _one_of(self, "state", STATES)


@dataclass(frozen=True)
class RelativeDistanceCondition:
    """The distance [m] of type ``distance_type`` (longitudinal and lateral along the
    road, cartesian straight) from a triggering entity to ``entity_ref``, between the
    boxes (``freespace``) or the reference points, ``rule`` ``value_m``."""

    entity_ref: str
    distance_type: str
    freespace: bool
    value_m: float
    rule: str

    def __post_init__(self) -> None:
        _finite(self, "value_m")
        _one_of(self, "rule", RULES)
        _one_of(self, "distance_type", DISTANCE_TYPES)


@dataclass(frozen=True)
class TimeHeadwayCondition:
    """Headway [s] of a triggering entity to ``entity_ref`` ahead of it: longitudinal gap
    (freespace: bumper to bumper) / the triggering entity's speed; inf when the
    reference is not ahead or the speed is 0."""

    entity_ref: str
    freespace: bool
    value_s: float
    rule: str

    def __post_init__(self) -> None:
        _finite(self, "value_s")
        _one_of(self, "rule", RULES)


@dataclass(frozen=True)
class TimeToCollisionCondition:
    """Time to collision [s] of a triggering entity with ``entity_ref`` ahead: gap /
    closing speed (inf when not closing)."""

    entity_ref: str
    freespace: bool
    value_s: float
    rule: str

    def __post_init__(self) -> None:
        _finite(self, "value_s")
        _one_of(self, "rule", RULES)


@dataclass(frozen=True)
class ReachPositionCondition:
    """A triggering entity's front bumper is within ``tolerance_m`` [m] of ``position``
    (route position and lateral place)."""

    position: RoutePosition
    tolerance_m: float

    def __post_init__(self) -> None:
        _non_negative(self, "tolerance_m")


@dataclass(frozen=True)
class TraveledDistanceCondition:
    """A triggering entity has travelled at least ``value_m`` [m] since t = 0."""

    value_m: float

    def __post_init__(self) -> None:
        _non_negative(self, "value_m")


@dataclass(frozen=True)
class SpeedCondition:
    """A triggering entity's speed [m/s] ``rule`` ``value_mps``."""

    value_mps: float
    rule: str

    def __post_init__(self) -> None:
        _finite(self, "value_mps")
        _one_of(self, "rule", RULES)


@dataclass(frozen=True)
class RelativeSpeedCondition:
    """A triggering entity's speed minus ``entity_ref``'s [m/s] ``rule`` ``value_mps``."""

    entity_ref: str
    value_mps: float
    rule: str

    def __post_init__(self) -> None:
        _finite(self, "value_mps")
        _one_of(self, "rule", RULES)


CONDITION_TYPES: tuple[type, ...] = (
    SimulationTimeCondition, StateCondition, RelativeDistanceCondition,
    TimeHeadwayCondition, TimeToCollisionCondition, ReachPositionCondition,
    TraveledDistanceCondition, SpeedCondition, RelativeSpeedCondition)
ENTITY_CONDITIONS: tuple[type, ...] = CONDITION_TYPES[2:]


@dataclass(frozen=True)
class Condition:
    """One condition: ``name``, ``delay_s`` [s] (it becomes true that long after its
    test did), ``edge`` (rising, falling, risingOrFalling, none), the test ``check``;
    for entity conditions the ``triggering`` entities and whether ``any`` or all must
    meet it."""

    name: str
    delay_s: float
    edge: str
    check: Any
    triggering: tuple[str, ...] = ()
    any_entity: bool = True

    def __post_init__(self) -> None:
        _non_negative(self, "delay_s")
        _one_of(self, "edge", EDGES)
        if not isinstance(self.check, CONDITION_TYPES):
            raise StoryError(f"Condition {self.name}: unknown check {self.check!r}")
        object.__setattr__(self, "triggering", tuple(self.triggering))
        if isinstance(self.check, ENTITY_CONDITIONS) and not self.triggering:
            raise StoryError(f"Condition {self.name}: an entity condition needs triggering "
                             "entities")


@dataclass(frozen=True)
class ConditionGroup:
    """Conditions that must all be true (AND)."""

    conditions: tuple[Condition, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "conditions", tuple(self.conditions))
        if not self.conditions:
            raise StoryError("ConditionGroup: expected at least one condition")


@dataclass(frozen=True)
class Trigger:
    """Condition groups of which one must be true (OR); no group: never fires."""

    groups: tuple[ConditionGroup, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "groups", tuple(self.groups))


# ---------------------------------------------------------------- actions

@dataclass(frozen=True)
class SpeedAction:
    """To a speed target: absolute ``target_mps``, or relative to ``relative_to``
    (``relative_kind`` delta: its speed + target, factor: its speed x target;
    ``continuous``: keep following it), along ``shape`` over ``dimension`` (time [s],
    distance [m] or rate [m/s²]) of ``value``."""

    target: float
    shape: str
    dimension: str
    value: float
    relative_to: str | None = None
    relative_kind: str = "delta"
    continuous: bool = False

    def __post_init__(self) -> None:
        _finite(self, "target", "value")
        _one_of(self, "shape", SHAPES)
        _one_of(self, "dimension", DIMENSIONS)
        _one_of(self, "relative_kind", ("delta", "factor"))
        if self.value < 0.0:
            raise StoryError(f"SpeedAction.value: expected >= 0, got {self.value}")


@dataclass(frozen=True)
class RelativeLaneTarget:
    """A lane ``value`` lanes left (+) of ``entity``'s lane."""

    entity: str
    value: int


@dataclass(frozen=True)
class LaneChangeAction:
    """Into ``lane`` (absolute index) or ``relative`` lane, ending ``target_offset_m``
    [m] off its centre, along ``shape`` over ``dimension`` (time [s], distance [m],
    rate: mean lateral speed [m/s], duration = lateral distance / rate)."""

    shape: str
    dimension: str
    value: float
    lane: int | None = None
    relative: RelativeLaneTarget | None = None
    target_offset_m: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "value", "target_offset_m")
        _one_of(self, "shape", SHAPES)
        _one_of(self, "dimension", DIMENSIONS)
        if (self.lane is None) == (self.relative is None):
            raise StoryError("LaneChangeAction: expected exactly one of lane, relative")
        if self.value < 0.0 or (self.value == 0.0 and self.shape != "step"):
            raise StoryError(f"LaneChangeAction.value: expected > 0, got {self.value}")


@dataclass(frozen=True)
class LaneOffsetAction:
    """To ``offset_m`` [m, left +] from the lane's centre (``relative_to``: from that
    entity's offset), along ``shape`` with at most ``max_lateral_acc_mps2`` [m/s²]."""

    offset_m: float
    shape: str
    max_lateral_acc_mps2: float
    relative_to: str | None = None
    continuous: bool = False

    def __post_init__(self) -> None:
        _finite(self, "offset_m", "max_lateral_acc_mps2")
        _one_of(self, "shape", SHAPES)
        if self.max_lateral_acc_mps2 <= 0.0:
            raise StoryError("LaneOffsetAction.max_lateral_acc_mps2: expected > 0")


@dataclass(frozen=True)
class TeleportAction:
    """To ``position`` (absolute) or relative to ``relative_to``: ``ds_m`` [m] along the
    route, ``dlane`` lanes left, ``lateral_m`` [m] off that lane's centre."""

    position: RoutePosition | None = None
    relative_to: str | None = None
    ds_m: float = 0.0
    dlane: int = 0
    lateral_m: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "ds_m", "lateral_m")
        if (self.position is None) == (self.relative_to is None):
            raise StoryError("TeleportAction: expected exactly one of position, relative_to")


@dataclass(frozen=True)
class ActivateControllerAction:
    """The ego's controller takes over (it drives the ego from t = 0 in hwyeval: the
    action is recorded as done, nothing else changes)."""

    lateral: bool = True
    longitudinal: bool = True


@dataclass(frozen=True)
class LongitudinalDistanceAction:
    """Keep (``continuous``) or take once the gap [m] (``distance_m``, or ``time_gap_s``
    x the reference's speed) to ``entity_ref``, ahead of it (``ahead``) or behind;
    ``freespace``: bumper to bumper, else reference points."""

    entity_ref: str
    freespace: bool
    ahead: bool
    continuous: bool
    distance_m: float | None = None
    time_gap_s: float | None = None

    def __post_init__(self) -> None:
        if (self.distance_m is None) == (self.time_gap_s is None):
            raise StoryError("LongitudinalDistanceAction: expected one of distance_m, "
                             "time_gap_s")


@dataclass(frozen=True)
class TrajectoryVertex:
    """A polyline vertex: time ``t_s`` [s] from the action's start and a place."""

    t_s: float
    position: RoutePosition

    def __post_init__(self) -> None:
        _finite(self, "t_s")


@dataclass(frozen=True)
class FollowTrajectoryAction:
    """Follow a polyline in time (following mode position): ``vertices`` in time order,
    linear between them, ``scale`` x (vertex time) + ``offset_s`` [s]."""

    vertices: tuple[TrajectoryVertex, ...]
    scale: float = 1.0
    offset_s: float = 0.0

    def __post_init__(self) -> None:
        _finite(self, "scale", "offset_s")
        object.__setattr__(self, "vertices", tuple(self.vertices))
        times = [v.t_s for v in self.vertices]
        if len(times) < 2 or times != sorted(times) or self.scale <= 0.0:
            raise StoryError("FollowTrajectoryAction: expected two vertices or more in time "
                             "order and a scale > 0")


@dataclass(frozen=True)
class StopAction:
    """The storyboard's own end (its stop trigger fired): nothing moves any more by the
    story; kept for the record."""


ACTION_TYPES: tuple[type, ...] = (
    SpeedAction, LaneChangeAction, LaneOffsetAction, TeleportAction,
    ActivateControllerAction, LongitudinalDistanceAction, FollowTrajectoryAction)


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
