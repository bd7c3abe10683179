"""Scripted actors in SUMO: each holds its catalog speed and lane and does its events.

An :class:`~suite.catalog.ActorSpec` starts at its speed; from each event's ``t_s`` (run
time [s]) on it changes ``lane_change`` lanes (``changeLaneRelative``: SUMO's continuous
change over ``--lanechange.duration``, without regard for other drivers, i.e. a real
cut-in) and/or ramps its speed linearly to ``speed_mps`` at ``accel_mps2`` and holds it.
The commanded speed v(t) is pushed with ``setSpeed`` every step; SUMO's safe-speed rule
still applies (speed mode 31): an actor brakes for what is ahead of it, the ego included,
and never drives into it. Its own strategic lane changes stay on (lane-change mode 1) so
that it follows its route where its lane ends; no speed-gain, keep-right or cooperative
change ever moves it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from suite.catalog import ActorSpec

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


@dataclass
class ActorScript:
    """Drives the scenario's actors in a running libsumo (``ls``); ``start`` once after
    they are inserted, ``apply(t_s)`` before every simulation step."""

    actors: tuple[ActorSpec, ...]
    _next: dict[str, int] = field(default_factory=dict)
    _ramp: dict[str, _Ramp] = field(default_factory=dict)

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
            while k < len(a.events) and a.events[k].t_s <= t_s + 1e-9:
                ev = a.events[k]
                if ev.lane_change:
                    ls.vehicle.changeLaneRelative(vid, ev.lane_change, _REQUEST_S)
                if ev.speed_mps is not None:
                    now = float(ls.vehicle.getSpeed(vid))
                    self._ramp[a.id] = _Ramp(t_s, now, ev.speed_mps, ev.accel_mps2)
                k += 1
            self._next[a.id] = k
            ls.vehicle.setSpeed(vid, self._ramp[a.id].speed(t_s))


__all__ = ["ACTOR_LANE_CHANGE_MODE", "ActorScript"]
