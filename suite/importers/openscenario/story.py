"""The XML ``Storyboard`` -> the typed :class:`~suite.catalog.storyboard.Storyboard`:
the Init (teleports, speeds and distance actions resolved to start places and speeds;
other Init actions of scripted entities become a story started at t = 0) and the
stories. The ego's Init gives the catalog's ego start; in the stories the ego may only
be handed to its controller (ActivateControllerAction): hwyeval's controller drives it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from suite.catalog import storyboard as sb
from suite.importers.openscenario.actions_xml import ActionReader
from suite.importers.openscenario.conditions_xml import _only_child, read_trigger
from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.position_xml import read_position

__all__ = ["InitResult", "read_init", "read_stories"]

INIT_STORY = "__init__"
IGNORED_GLOBAL = ("EnvironmentAction",)


@dataclass
class InitResult:
    """The Init: each entity's reference-point place and speed [m/s], the actions that
    run from t = 0 (entity, name, action) and notes."""

    places: dict[str, sb.RoutePosition] = field(default_factory=dict)
    speeds: dict[str, float] = field(default_factory=dict)
    later: list[tuple[str, str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def _private_actions(init: Any) -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for el in init.iterfind("Actions/*"):
        if not isinstance(el.tag, str):
            continue
        if el.tag == "GlobalAction":
            kid = _only_child(el)
            if kid.tag not in IGNORED_GLOBAL:
                raise fail_at(kid, f"global action {kid.tag} is not supported")
            continue
        if el.tag != "Private":
            raise fail_at(el, f"Init action {el.tag} is not supported")
        out.extend((str(el.get("entityRef", "")), pa) for pa in el.iterfind("PrivateAction"))
    return out


def _place_all(acts: list[tuple[str, Any]], reader: ActionReader, res: InitResult,
               ego: str) -> None:
    """Teleports, the ego's first, then repeatedly those whose reference is placed."""
    todo = [(n, a) for n, a in acts if a.find("TeleportAction") is not None]
    todo.sort(key=lambda x: x[0] != ego)
    while todo:
        left = []
        for name, pa in todo:
            kid = _only_child(pa.find("TeleportAction/Position"))
            ref = kid.get("entityRef")
            if ref is not None and ref not in reader.placer.places:
                left.append((name, pa))
                continue
            place = read_position(pa.find("TeleportAction/Position"), reader.placer)
            reader.placer.places[name] = place
            res.places[name] = place
        if len(left) == len(todo):
            raise fail_at(left[0][1], f"entity {left[0][0]}: its position refers to an "
                          "entity that is never placed")
        todo = left


def _speed(name: str, action: sb.SpeedAction, res: InitResult, pa: Any) -> None:
    if action.relative_to is None:
        res.speeds[name] = max(action.target, 0.0)
        return
    if action.relative_to not in res.speeds:
        raise fail_at(pa, f"entity {name}: its speed refers to {action.relative_to}, "
                      "whose speed is not set before it")
    ref = res.speeds[action.relative_to]
    res.speeds[name] = max(ref + action.target if action.relative_kind == "delta"
                           else ref * action.target, 0.0)


def _distance(name: str, a: sb.LongitudinalDistanceAction, res: InitResult,
              entities: dict[str, sb.Entity], pa: Any) -> None:
    ref = res.places.get(a.entity_ref)
    if ref is None or name not in res.places:
        raise fail_at(pa, f"entity {name}: a distance to an entity not placed")
    gap = a.distance_m if a.distance_m is not None else \
        float(a.time_gap_s or 0.0) * res.speeds.get(a.entity_ref, 0.0)
    me, other = entities[name], entities[a.entity_ref]
    if a.freespace:  # bumper to bumper: reference points further apart by the boxes
        gap += (me.length_m - me.front_m) + other.front_m if a.ahead else \
            me.front_m + (other.length_m - other.front_m)
    own = res.places[name]
    res.places[name] = sb.RoutePosition(ref.pos_m + (gap if a.ahead else -gap), own.lane,
                                        own.lateral_m, own.heading_rad)
    res.speeds.setdefault(name, res.speeds.get(a.entity_ref, 0.0))


def read_init(board: Any, reader: ActionReader, entities: dict[str, sb.Entity],
              ego: str) -> InitResult:
    """The Init (module docstring)."""
    res = InitResult()
    init = board.find("Init")
    acts = [] if init is None else _private_actions(init)
    for name, pa in acts:
        if name not in entities:
            raise fail_at(pa.getparent(), f"unknown entity {name!r}")
    _place_all(acts, reader, res, ego)
    for name in entities:
        if name not in res.places:
            raise fail_at(board, f"entity {name} is never placed (no TeleportAction in Init)")
    for name, pa in acts:
        if pa.find("TeleportAction") is None:
            _init_action(name, pa, reader, res, entities, ego)
    return res


def _init_action(name: str, pa: Any, reader: ActionReader, res: InitResult,
                 entities: dict[str, sb.Entity], ego: str) -> None:
    """One Init action other than a teleport (module docstring)."""
    action = reader.private(pa)
    step_speed = isinstance(action, sb.SpeedAction) and (
        action.shape == "step" or action.value == 0.0) and not action.continuous
    if step_speed:
        _speed(name, action, res, pa)
    elif isinstance(action, sb.LongitudinalDistanceAction) and not action.continuous:
        _distance(name, action, res, entities, pa)
    elif isinstance(action, sb.ActivateControllerAction) and name == ego:
        res.notes.append("the ego's controller drives from t = 0 (Init "
                         "ActivateControllerAction)")
    elif name == ego:
        raise fail_at(pa, "this Init action on the ego is not supported: the ego is "
                      "driven by the controller under test")
    else:
        res.later.append((name, f"{INIT_STORY}{len(res.later)}", action))


def _check_actor(action: Any, actors: tuple[str, ...], ego: str, el: Any) -> None:
    if ego in actors and not isinstance(action, sb.ActivateControllerAction):
        raise fail_at(el, "an action on the ego other than ActivateControllerAction is not "
                      "supported: the ego is driven by the controller under test")


def _event(el: Any, reader: ActionReader, actors: tuple[str, ...], ego: str) -> sb.Event:
    actions = []
    for a in el.iterfind("Action"):
        pa = _only_child(a)
        if pa.tag != "PrivateAction":
            raise fail_at(pa, "only private actions are supported in events")
        action = reader.private(pa)
        _check_actor(action, actors, ego, pa)
        actions.append((str(a.get("name", "")), action))
    trig = read_trigger(el.find("StartTrigger"), reader.placer, reader.entities)
    return sb.Event(str(el.get("name", "")), tuple(actions), trig,
                    el.get("priority", "override").replace("overwrite", "override"),
                    int(el.get("maximumExecutionCount", "1")))


def _group(el: Any, reader: ActionReader, ego: str) -> sb.ManeuverGroup:
    act_el = el.find("Actors")
    if act_el is None:
        raise fail_at(el, "Actors are required")
    actors = tuple(reader.entity(r) for r in act_el.iterfind("EntityRef"))
    mans = []
    for m in el.iterfind("Maneuver"):
        mans.append(sb.Maneuver(str(m.get("name", "")),
                                tuple(_event(e, reader, actors, ego)
                                      for e in m.iterfind("Event"))))
    for kid in el:
        if isinstance(kid.tag, str) and kid.tag not in ("Actors", "Maneuver"):
            raise fail_at(kid, f"{kid.tag} in a ManeuverGroup is not supported")
    return sb.ManeuverGroup(str(el.get("name", "")), actors, tuple(mans),
                            int(el.get("maximumExecutionCount", "1")))


def _init_story(res: InitResult) -> sb.Story:
    at_zero = sb.Trigger((sb.ConditionGroup((sb.Condition(
        "t0", 0.0, "none", sb.SimulationTimeCondition(0.0, "greaterOrEqual")),)),))
    groups = tuple(sb.ManeuverGroup(f"{aname}_group", (entity,), (sb.Maneuver(
        f"{aname}_maneuver", (sb.Event(f"{aname}_event", ((aname, action),), at_zero),)),))
        for entity, aname, action in res.later)
    return sb.Story(INIT_STORY, (sb.Act(f"{INIT_STORY}_act", groups, at_zero),))


def read_stories(board: Any, reader: ActionReader, ego: str,
                 res: InitResult) -> tuple[sb.Story, ...]:
    """The stories (the Init's later actions first, as a story of their own)."""
    stories = [_init_story(res)] if res.later else []
    for st in board.iterfind("Story"):
        acts = []
        for a in st.iterfind("Act"):
            groups = tuple(_group(g, reader, ego) for g in a.iterfind("ManeuverGroup"))
            acts.append(sb.Act(str(a.get("name", "")), groups,
                               read_trigger(a.find("StartTrigger"), reader.placer,
                                            reader.entities),
                               read_trigger(a.find("StopTrigger"), reader.placer,
                                            reader.entities)))
        stories.append(sb.Story(str(st.get("name", "")), tuple(acts)))
    for kid in board:
        if isinstance(kid.tag, str) and kid.tag not in ("Init", "Story", "StopTrigger"):
            raise fail_at(kid, f"{kid.tag} in the Storyboard is not supported")
    return tuple(stories)
