"""The storyboard's vocabulary, positions, entities and conditions
(:mod:`suite.catalog.storyboard`, docs/openscenario.md): the checks every class runs in
``__post_init__``, the comparison rules, and the conditions and triggers that start and
stop the storyboard's elements."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

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
