"""Scripted actors in SUMO: each holds its catalog speed and lane and does its events.

An :class:`~suite.catalog.ActorSpec` starts at its speed; its events run in order, each
armed once the one before it started, and start at the first SUMO step where they are
due (:mod:`suite.catalog.actors`): run time ``t_s`` [s] or later and, with ``when``,
``delay_s`` after its conditions (the ego's gap, time headway and time to collision to
the actor ahead of it, or the ego's route position: :class:`EgoAndActor`) first all held.
An event changes ``lane_change`` lanes (``changeLaneRelative``: SUMO's continuous
change over ``--lanechange.duration``, without regard for other drivers, i.e. a real
cut-in) and/or ramps its speed linearly to ``speed_mps`` at ``accel_mps2`` and holds it.
The commanded speed v(t) is pushed with ``setSpeed`` every step; SUMO's safe-speed rule
still applies (speed mode 31): an actor brakes for what is ahead of it, the ego included,
and never drives into it. Its own strategic lane changes stay on (lane-change mode 1) so
that it follows its route where its lane ends; no speed-gain, keep-right or cooperative
change ever moves it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from suite.catalog import ActorEventSpec, ActorSpec, ActorWhenSpec

ACTOR_LANE_CHANGE_MODE = 1  # strategic only; TraCI requests without regard for others
_REQUEST_S = 10.0  # how long a lane-change request stays active [s]


@dataclass
class _Ramp:
    """Speed command v(t) = v0 + slope (t - t0) until v1 is reached, then v1."""

    t0_s: float
    v0_mps: float
    v1_mps: float
    accel_mps2: float

    def speed(self, t_s: float) -> float:
        dv = self.v1_mps - self.v0_mps
        step = self.accel_mps2 * max(t_s - self.t0_s, 0.0)
        return self.v1_mps if step >= abs(dv) else self.v0_mps + (step if dv > 0 else -step)


@dataclass(frozen=True)
class EgoAndActor:
    """The ego and an actor at one SUMO step: front bumper route positions [m], speeds
    [m/s], the actor's length [m]. ``gap_m``: bumper to bumper along the route from the
    ego's front to the actor's rear (> 0: the actor ahead; NaN where unknown)."""

    ego_pos_m: float
    ego_speed_mps: float
    actor_pos_m: float
    actor_speed_mps: float
    actor_length_m: float

    @property
    def gap_m(self) -> float:
        return self.actor_pos_m - self.actor_length_m - self.ego_pos_m

    def holds(self, when: ActorWhenSpec) -> bool:
        """Whether every condition of ``when`` holds (module docstring of
        :mod:`suite.catalog.actors`); an unknown position holds none."""
        gap = self.gap_m
        checks: list[bool] = []
        if when.ego_pos_m is not None:
            checks.append(self.ego_pos_m >= when.ego_pos_m)
        ahead = math.isfinite(gap) and gap >= 0.0
        if when.ahead_gap_m is not None:
            checks.append(ahead and gap <= when.ahead_gap_m)
        if when.time_headway_s is not None:
            checks.append(ahead and self.ego_speed_mps > 0.0
                          and gap / self.ego_speed_mps <= when.time_headway_s)
        if when.ttc_s is not None:
            closing = self.ego_speed_mps - self.actor_speed_mps
            checks.append(ahead and closing > 0.0 and gap / closing <= when.ttc_s)
        return all(checks)


RoutePosition = Callable[[Any, str], float]  # (libsumo, vehicle id) -> route position [m]


@dataclass
class ActorScript:
    """Drives the scenario's actors in a running libsumo (``ls``); ``start`` once after
    they are inserted, ``apply(t_s)`` before every simulation step. ``route_pos``: a
    vehicle's front bumper route position [m] (NaN off the route), for the ``when``
    conditions; ``ego_id``: the ego's SUMO id."""

    actors: tuple[ActorSpec, ...]
    route_pos: RoutePosition | None = None
    ego_id: str = "ego"
    _next: dict[str, int] = field(default_factory=dict)
    _ramp: dict[str, _Ramp] = field(default_factory=dict)
    _held_since: dict[str, float] = field(default_factory=dict)

    def start(self, ls: Any) -> None:
        present = set(ls.vehicle.getIDList())
        missing = [a.id for a in self.actors if a.sumo_id not in present]
        if missing:
            raise RuntimeError(f"SUMO could not insert the actor(s) {missing} at their "
                               "positions and speeds (a vehicle too close ahead, or an "
                               "invalid lane)")
        for a in self.actors:
            ls.vehicle.setLaneChangeMode(a.sumo_id, ACTOR_LANE_CHANGE_MODE)
            ls.vehicle.setSpeed(a.sumo_id, a.speed_mps)
            self._next[a.id] = 0
            self._ramp[a.id] = _Ramp(0.0, a.speed_mps, a.speed_mps, 1.0)

    def _view(self, ls: Any, actor: ActorSpec, present: set[str]) -> EgoAndActor:
        nan = math.nan
        if self.route_pos is None or self.ego_id not in present:
            return EgoAndActor(nan, nan, nan, nan, actor.length_m)
        v = ls.vehicle
        return EgoAndActor(self.route_pos(ls, self.ego_id), float(v.getSpeed(self.ego_id)),
                           self.route_pos(ls, actor.sumo_id),
                           float(v.getSpeed(actor.sumo_id)), actor.length_m)

    def _due(self, ls: Any, actor: ActorSpec, ev: ActorEventSpec, t_s: float,
             present: set[str]) -> bool:
        """Whether ``ev`` starts now (its time reached and its conditions held for its
        delay; the clock of the delay starts when they first all held)."""
        if ev.earliest_s > t_s + 1e-9:
            return False
        if ev.when is None:
            return True
        since = self._held_since.get(actor.id)
        if since is None:
            if not self._view(ls, actor, present).holds(ev.when):
                return False
            since = self._held_since[actor.id] = t_s
        return t_s - since >= ev.when.delay_s - 1e-9

    def apply(self, ls: Any, t_s: float) -> None:
        """Start the events due at run time ``t_s`` [s] and push every speed command."""
        if not self.actors:
            return
        present = set(ls.vehicle.getIDList())
        for a in self.actors:
            vid = a.sumo_id
            if vid not in present:
                continue  # left the network
            k = self._next[a.id]
            while k < len(a.events) and self._due(ls, a, a.events[k], t_s, present):
                ev = a.events[k]
                if ev.lane_change:
                    ls.vehicle.changeLaneRelative(vid, ev.lane_change, _REQUEST_S)
                if ev.speed_mps is not None:
                    now = float(ls.vehicle.getSpeed(vid))
                    self._ramp[a.id] = _Ramp(t_s, now, ev.speed_mps, ev.accel_mps2)
                self._held_since.pop(a.id, None)
                k += 1
            self._next[a.id] = k
            ls.vehicle.setSpeed(vid, self._ramp[a.id].speed(t_s))


__all__ = ["ACTOR_LANE_CHANGE_MODE", "ActorScript", "EgoAndActor"]
