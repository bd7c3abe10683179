"""Triggers and conditions of the XML storyboard -> the typed model
(:mod:`suite.catalog.storyboard`). Any other condition is an error naming it."""

from __future__ import annotations

from typing import Any

from suite.catalog import storyboard as sb
from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.position_xml import num, read_position
from suite.importers.openscenario.positions import Placer

__all__ = ["read_trigger"]


def _flag(el: Any, key: str, default: bool = False) -> bool:
    raw = el.get(key)
    return default if raw is None else raw.strip().lower() in ("true", "1")


def _rule(el: Any) -> str:
    rule = str(el.get("rule", ""))
    if rule not in sb.RULES:
        raise fail_at(el, f"rule {rule!r} is not one of {list(sb.RULES)}")
    return rule


def _value_condition(el: Any) -> Any:
    tag = str(el.tag)
    if tag == "SimulationTimeCondition":
        return sb.SimulationTimeCondition(num(el, "value"), _rule(el))
    if tag == "StoryboardElementStateCondition":
        kind, state = el.get("storyboardElementType", ""), el.get("state", "")
        if kind not in sb.ELEMENT_TYPES or state not in sb.STATES:
            raise fail_at(el, f"element type {kind!r} / state {state!r} unknown")
        return sb.StateCondition(kind, el.get("storyboardElementRef", ""), state)
    raise fail_at(el, f"condition {tag} is not supported")


def _distance_type(el: Any) -> str:
    """The distance type; the coordinate system must be one measured along the route
    (entity, road, lane: the route's lanes are the road's)."""
    if el.get("coordinateSystem", "entity") not in ("entity", "road", "lane"):
        raise fail_at(el, f"coordinateSystem {el.get('coordinateSystem')!r} is not "
                      "supported (entity, road, lane)")
    kind = el.get("relativeDistanceType", "longitudinal")
    if kind not in sb.DISTANCE_TYPES:
        raise fail_at(el, f"relativeDistanceType {kind!r} is not supported")
    return "cartesian" if kind == "euclidianDistance" else kind


def _entity_condition(el: Any, placer: Placer) -> Any:
    tag = str(el.tag)
    if tag in ("TraveledDistanceCondition", "SpeedCondition", "RelativeSpeedCondition",
               "ReachPositionCondition"):
        return _motion_condition(el, placer)
    if tag == "RelativeDistanceCondition":
        return sb.RelativeDistanceCondition(el.get("entityRef", ""), _distance_type(el),
                                            _flag(el, "freespace"), num(el, "value"), _rule(el))
    if tag == "TimeHeadwayCondition":
        if _distance_type(el) != "longitudinal":
            raise fail_at(el, "only a longitudinal time headway is supported")
        return sb.TimeHeadwayCondition(el.get("entityRef", ""), _flag(el, "freespace"),
                                       num(el, "value"), _rule(el))
    if tag == "TimeToCollisionCondition":
        ref = el.find("TimeToCollisionConditionTarget/EntityRef")
        if ref is None:
            raise fail_at(el, "only a time to collision with an entity is supported")
        return sb.TimeToCollisionCondition(ref.get("entityRef", ""), _flag(el, "freespace"),
                                           num(el, "value"), _rule(el))
    raise fail_at(el, f"condition {tag} is not supported")


def _motion_condition(el: Any, placer: Placer) -> Any:
    """Conditions on the triggering entity's own motion."""
    tag = str(el.tag)
    if tag == "ReachPositionCondition":
        pos = el.find("Position")
        if pos is None:
            raise fail_at(el, "a Position is required")
        return sb.ReachPositionCondition(read_position(pos, placer), num(el, "tolerance"))
    if tag == "TraveledDistanceCondition":
        return sb.TraveledDistanceCondition(num(el, "value"))
    if tag == "SpeedCondition":
        if el.get("direction") not in (None, "longitudinal"):
            raise fail_at(el, "only a longitudinal speed is supported")
        return sb.SpeedCondition(num(el, "value"), _rule(el))
    if el.get("direction") not in (None, "longitudinal"):
        raise fail_at(el, "only a longitudinal relative speed is supported")
    return sb.RelativeSpeedCondition(el.get("entityRef", ""), num(el, "value"), _rule(el))


def _condition(el: Any, placer: Placer, entities: set[str]) -> sb.Condition:
    name, delay = el.get("name", ""), num(el, "delay", 0.0)
    edge = el.get("conditionEdge", "none")
    if edge not in sb.EDGES:
        raise fail_at(el, f"conditionEdge {edge!r} unknown")
    by_value, by_entity = el.find("ByValueCondition"), el.find("ByEntityCondition")
    if by_value is not None:
        kid = _only_child(by_value)
        return sb.Condition(name, delay, edge, _value_condition(kid))
    if by_entity is None:
        raise fail_at(el, "a condition needs ByValueCondition or ByEntityCondition")
    trig = by_entity.find("TriggeringEntities")
    ec = by_entity.find("EntityCondition")
    if trig is None or ec is None:
        raise fail_at(by_entity, "TriggeringEntities and EntityCondition are required")
    refs = tuple(r.get("entityRef", "") for r in trig.iterfind("EntityRef"))
    for r, ref_el in zip(refs, trig.iterfind("EntityRef"), strict=True):
        if r not in entities:
            raise fail_at(ref_el, f"unknown entity {r!r}")
    check = _entity_condition(_only_child(ec), placer)
    target = getattr(check, "entity_ref", None)
    if target is not None and target not in entities:
        raise fail_at(ec, f"unknown entity {target!r}")
    return sb.Condition(name, delay, edge, check, refs,
                        trig.get("triggeringEntitiesRule", "any") == "any")


def _only_child(el: Any) -> Any:
    kids = [k for k in el if isinstance(k.tag, str)]
    if len(kids) != 1:
        raise fail_at(el, "expected exactly one child element")
    return kids[0]


def read_trigger(el: Any | None, placer: Placer, entities: set[str]) -> sb.Trigger:
    """A StartTrigger / StopTrigger (None: the empty trigger, never fires)."""
    if el is None:
        return sb.Trigger()
    groups = []
    for g in el:
        if not isinstance(g.tag, str):
            continue
        if g.tag != "ConditionGroup":
            raise fail_at(g, "a trigger holds ConditionGroups only")
        conds = [_condition(c, placer, entities) for c in g if isinstance(c.tag, str)]
        if conds:
            groups.append(sb.ConditionGroup(tuple(conds)))
    return sb.Trigger(tuple(groups))
