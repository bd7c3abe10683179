"""The storyboard's state machine, one step at a time (docs/openscenario.md, "Runtime").

Every element (story, act, maneuver group, maneuver, event, action) is *standby*,
*running* or *complete*. The storyboard starts running at t = 0 with its stories; an act
starts when its start trigger fires (its groups and maneuvers start with it); an event
of a running maneuver starts when its start trigger fires (with priority override, the
maneuver's other running events stop) and starts its actions on every actor of its
group. An action completes when its motion does (:mod:`~suite.world.storyboard.motion`),
an event when all its actions have (it may run again up to its maximum execution
count), a maneuver, group, act or story when all its children have; an act's stop
trigger stops it. The storyboard's stop trigger stops everything (the scripted entities
then keep their speed and lane). Transitions (startTransition, endTransition,
stopTransition) are true at the step they happen, states while they last.

Each :meth:`StoryEngine.step` at run time t: (1) every trigger of an element that can
start (standby) or stop (running) samples its conditions with the entities' places
at t; (2) elements start and stop; (3) the scripted entities move to t + dt.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from suite.catalog import storyboard as sb
from suite.world.storyboard.conditions import test_condition
from suite.world.storyboard.motion import Motion, Running
from suite.world.storyboard.road import LaneRoad, lane_centre_y
from suite.world.storyboard.state import EntityView
from suite.world.storyboard.triggers import ConditionMemory

__all__ = ["StoryEngine", "Transition"]

STANDBY, RUNNING, COMPLETE = "standbyState", "runningState", "completeState"


@dataclass(frozen=True)
class Transition:
    """An element's transition at run time ``t_s`` [s]: its type, name, transition."""

    t_s: float
    element_type: str
    name: str
    transition: str


@dataclass
class _Node:
    kind: str
    name: str
    element: Any
    children: list[_Node] = field(default_factory=list)
    state: str = STANDBY
    runs: int = 0
    actors: tuple[str, ...] = ()
    running: list[Running] = field(default_factory=list)


def _tree(story: sb.Storyboard) -> list[_Node]:
    out = []
    for st in story.stories:
        acts = []
        for act in st.acts:
            groups = []
            for g in act.groups:
                mans = [_Node("maneuver", m.name, m, [
                    _Node("event", e.name, e, [_Node("action", n, a) for n, a in e.actions],
                          actors=g.actors) for e in m.events]) for m in g.maneuvers]
                groups.append(_Node("maneuverGroup", g.name, g, mans))
            acts.append(_Node("act", act.name, act, groups))
        out.append(_Node("story", st.name, st, acts))
    return out


@dataclass
class StoryEngine:
    """Runs ``story`` on ``road``: the scripted entities' motions, the element states
    and the transitions so far (``log``)."""

    story: sb.Storyboard
    road: LaneRoad
    motions: dict[str, Motion] = field(default_factory=dict)
    log: list[Transition] = field(default_factory=list)
    stopped_at_s: float | None = None
    _stories: list[_Node] = field(default_factory=list)
    _memory: ConditionMemory = field(default_factory=ConditionMemory)
    _now: set[tuple[str, str, str]] = field(default_factory=set)
    _views: dict[str, EntityView] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for init in self.story.inits:
            e = self.story.entity(init.entity)
            p = init.position
            self.motions[e.name] = Motion(
                e, p.pos_m, lane_centre_y(self.road, p.pos_m, p.lane) + p.lateral_m,
                init.speed_mps, heading_rad=p.heading_rad)
        self._stories = _tree(self.story)
        for node in self._stories:
            self._set(node, RUNNING, 0.0)

    # ------------------------------------------------------------------ views
    def views(self, ego: EntityView | None) -> dict[str, EntityView]:
        out = {n: m.view(self.road) for n, m in self.motions.items()}
        if ego is not None:
            out[self.story.ego.name] = ego
        return out

    def _set(self, node: _Node, state: str, t_s: float, how: str = "") -> None:
        transition = how or {RUNNING: "startTransition", COMPLETE: "endTransition"}[state]
        node.state = state
        self._now.add((node.kind, node.name, transition))
        self.log.append(Transition(t_s, node.kind, node.name, transition))

    def _state_test(self, c: sb.StateCondition) -> bool:
        if c.state.endswith("Transition"):
            return (c.element_type, c.ref, c.state) in self._now
        nodes = [n for n in self._walk() if n.kind == c.element_type and n.name == c.ref]
        return any(n.state == c.state for n in nodes)

    def _walk(self) -> list[_Node]:
        out, stack = [], list(self._stories)
        while stack:
            n = stack.pop()
            out.append(n)
            stack.extend(n.children)
        return out

    def _fires(self, trig: sb.Trigger, t_s: float, dt_s: float) -> bool:
        fired = False
        for g in trig.groups:
            ok = True
            for c in g.conditions:
                self._memory.record(c, t_s, test_condition(
                    c, t_s, self._views, self._state_test, self._place_y))
                ok = ok and self._memory.fires(c, t_s, dt_s)
            fired = fired or ok
        return fired

    def _place_y(self, p: sb.RoutePosition) -> float:
        return lane_centre_y(self.road, p.pos_m, p.lane) + p.lateral_m

    # ------------------------------------------------------------------ step
    def step(self, t_s: float, dt_s: float, ego: EntityView | None) -> None:
        """One step at run time ``t_s`` [s] (module docstring)."""
        self._views = self.views(ego)
        prev_now, self._now = self._now, set()
        self._now |= prev_now  # transitions of the last step's end are seen now
        if self.stopped_at_s is None:
            if self._fires(self.story.stop, t_s, dt_s):
                self.stopped_at_s = t_s
                for n in self._walk():
                    if n.state == RUNNING:
                        self._set(n, COMPLETE, t_s, "stopTransition")
                for m in self.motions.values():  # they keep their speed and place
                    m.longitudinal = m.lateral = None
            else:
                for story in self._stories:
                    self._story(story, t_s, dt_s)
        self._now -= prev_now
        for m in self.motions.values():
            m.advance(t_s, dt_s, self.road, self._views)
        if self.stopped_at_s is None:
            self._complete(t_s + dt_s)

    def _story(self, story: _Node, t_s: float, dt_s: float) -> None:
        for act in story.children:
            a: sb.Act = act.element
            if act.state == STANDBY and self._fires(a.start, t_s, dt_s):
                self._set(act, RUNNING, t_s)
                for g in act.children:
                    self._set(g, RUNNING, t_s)
                    for m in g.children:
                        self._set(m, RUNNING, t_s)
            elif act.state == RUNNING and self._fires(a.stop, t_s, dt_s):
                self._stop(act, t_s)
            if act.state == RUNNING:
                for g in act.children:
                    for m in g.children:
                        self._maneuver(m, t_s, dt_s)

    def _stop(self, node: _Node, t_s: float) -> None:
        for n in [node, *node.children]:
            if n.state == RUNNING:
                self._set(n, COMPLETE, t_s, "stopTransition")
            for k in n.children:
                self._stop(k, t_s)

    def _maneuver(self, man: _Node, t_s: float, dt_s: float) -> None:
        if man.state != RUNNING:
            return
        for ev in man.children:
            e: sb.Event = ev.element
            if ev.state == STANDBY and ev.runs < e.max_executions \
                    and self._fires(e.start, t_s, dt_s):
                if e.priority == "override":
                    for other in man.children:
                        if other is not ev and other.state == RUNNING:
                            self._stop(other, t_s)
                elif e.priority == "skip" and any(o.state == RUNNING for o in man.children):
                    continue
                self._start_event(ev, t_s)

    def _start_event(self, ev: _Node, t_s: float) -> None:
        ev.runs += 1
        self._set(ev, RUNNING, t_s)
        for act in ev.children:
            act.state = STANDBY
            self._set(act, RUNNING, t_s)
            act.running = [self.motions[name].start(act.element, t_s, self.road, self._views)
                           for name in ev.actors if name in self.motions]

    def _complete(self, t_s: float) -> None:
        """Bottom up: actions whose motions are done, then their parents."""
        for story in self._stories:
            self._complete_node(story, t_s)

    def _complete_node(self, node: _Node, t_s: float) -> bool:
        if node.kind == "action":
            if node.state == RUNNING and all(r.done for r in node.running):
                self._set(node, COMPLETE, t_s)
            return node.state == COMPLETE
        done = [self._complete_node(k, t_s) for k in node.children]
        if node.state == RUNNING and all(done):
            if node.kind == "event" and node.runs < node.element.max_executions:
                node.state = STANDBY
                self.log.append(Transition(t_s, node.kind, node.name, "endTransition"))
                self._now.add((node.kind, node.name, "endTransition"))
                return False
            if node.kind == "maneuverGroup" or node.kind in ("act", "story", "maneuver",
                                                            "event"):
                self._set(node, COMPLETE, t_s)
        return node.state == COMPLETE

    def time_of(self, element_type: str, name: str, transition: str) -> float:
        """The run time [s] of an element's first such transition (NaN: none)."""
        return next((x.t_s for x in self.log if (x.element_type, x.name, x.transition)
                     == (element_type, name, transition)), math.nan)

    def motion_views(self) -> Mapping[str, EntityView]:
        return {n: m.view(self.road) for n, m in self.motions.items()}
