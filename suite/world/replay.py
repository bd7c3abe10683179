"""Recorded traffic in SUMO: replayed vehicles, and their handover in reactive mode.

A scenario's ``replay`` (:class:`~suite.catalog.ReplaySpec`) names a tracks file
(:mod:`suite.catalog.tracks`). Every recorded vehicle is a SUMO vehicle whose id is its
track id (``rec_<id>``), of a vehicle type per box size (length x width as recorded).

Timing: SUMO step k of the run ends at run time t_k = k dt (dt = SUMO's step; run time
0 = the recording's initial step, the run's t = 0). A track with samples on [t0, t1] is
present at the steps with t0 <= t_k <= t1 (to 1 ns): it is inserted before the first of
them and removed before the first step after t1 ("appears at its first sample, leaves
after its last"). Its poses at every such t_k are interpolated once at the start
(:meth:`~suite.catalog.tracks.Track`'s linear interpolation, heading unwrapped): no
per-step file read or interpolation, only the TraCI calls.

Replayed: before step k the vehicle is put at its recorded pose at t_k with
``moveToXY(..., keepRoute=2)`` (free placement mapped to the nearest lane) at its
*front bumper*, (x_f, y_f) = (x_c, y_c) + L/2 (cos psi, sin psi), heading in SUMO's
navigation degrees (90 - deg(psi)) mod 360, and ``setSpeed`` gives SUMO its recorded
speed; speed mode 32 and lane-change mode 0: it ignores the ego and everyone else, as a
recording does. Collisions are judged on hwyeval's 2-D boxes (reports.metrics).

Reactive (``mode = "reactive"``, nuPlan's reactive agents): after each SUMO step the
replayed vehicles the ego can see are tested against the handover rule
(:func:`handover_due`); a vehicle that meets it is handed to SUMO's car-following
driver before the next step, for good: speed mode 31 (SUMO's default, safe speed),
lane-change mode from ``replay.lane_changes``, its speed command released
(``setSpeed(-1)``), speed factor 1 and maximum speed the highest speed of its recording
(at least 1 m/s), and a route along the edges its recording drives (resolved once at
the start with ``convertRoad`` every ~1 s of the track, joined with ``findRoute``, and
continued along the scenario's route when it ends on it). It then stays in the
simulation until SUMO removes it at its route's end.

Agent kinds per vehicle and step (:data:`reports.record.AGENT_SUMO` 0 = SUMO traffic
or actor, :data:`~reports.record.AGENT_REPLAYED` 1, :data:`~reports.record.AGENT_REACTIVE`
2) reach ``Traffic.agent`` and the ``agent`` column of neighbours.parquet: the kind
under which the vehicle's pose of that step was produced.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import Traffic
from reports.geometry import box_fronts, math_rad_to_nav_deg_array
from reports.record import AGENT_REACTIVE, AGENT_REPLAYED, AGENT_SUMO, ReplayHandover
from suite.catalog import ReplaySpec
from suite.catalog.tracks import Track, TrackSet

__all__ = ["REPLAY_SPEED_MODE", "HandoverEgo", "ReplayAgents", "handover_due"]

REPLAY_SPEED_MODE = 32  # no safe-speed, acceleration or deceleration checks: as recorded
REACTIVE_SPEED_MODE = 31  # SUMO's default
ROUTE_SAMPLE_S = 1.0  # a track's edges are looked up about this often [s]
_EPS_S = 1e-9
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class HandoverEgo:
    """The ego for the handover rule: box centre [m], heading [rad], speed [m/s], box
    length/width [m], SUMO road and lane index."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_mps: float
    length_m: float
    width_m: float
    road_id: str
    lane_index: int


def handover_due(ego: HandoverEgo, traffic: Traffic, time_gap_s: float) -> npt.NDArray[np.bool_]:
    """Which vehicles of ``traffic`` (n,) meet the handover rule against ``ego``.

    In the ego's frame at this instant (s along its heading, d to its left, from its
    centre) a vehicle at (s, d) with speed v, heading h, box L x W is *behind* when
    s < 0; its bumper gap is g = -s - (L_ego + L)/2 [m]; it *shares the ego's lane*
    when it has the ego's SUMO road and lane index, or (on another road: lane indices of
    two edges are not comparable) its box overlaps the ego's laterally,
    |d| < (W_ego + W)/2. It is *about to* when that lateral overlap holds now or at
    tau = ``time_gap_s`` ahead with both moving straight at their speeds,
    d(tau) = d + tau (v sin(h - psi) - 0) (the ego's own frame moves with it). Due:

        behind and shares the ego's lane                                   (rule 1)
        or behind and (shares or about to) and g < v * time_gap_s         (rule 2)

    i.e. rule 2 is the time gap g / v below ``time_gap_s``. Shapes (n,) -> (n,) bool.
    """
    n = traffic.count
    if n == 0:
        return np.zeros(0, dtype=bool)
    c, s_ = math.cos(ego.heading_rad), math.sin(ego.heading_rad)
    rx, ry = traffic.x_m - ego.x_m, traffic.y_m - ego.y_m
    s = rx * c + ry * s_
    d = -rx * s_ + ry * c
    behind = s < 0.0
    gap = -s - 0.5 * (ego.length_m + traffic.length_m)
    half = 0.5 * (ego.width_m + traffic.width_m)
    lateral_v = traffic.speed_mps * np.sin(traffic.heading_rad - ego.heading_rad)
    d_later = d + lateral_v * float(time_gap_s)
    same_road = np.array([r == ego.road_id for r in traffic.road_id], dtype=bool)
    shares = np.where(same_road, np.asarray(traffic.lane_index) == ego.lane_index,
                      np.abs(d) < half)
    about = shares | (np.abs(d) < half) | (np.abs(d_later) < half)
    rule_gap = behind & about & (gap < traffic.speed_mps * float(time_gap_s))
    due: npt.NDArray[np.bool_] = (behind & shares) | rule_gap
    return due


@dataclass
class _Grid:
    """One track's poses at the SUMO steps k0..k1 it is present at: front bumper
    (fx, fy) [m], navigation angle [deg], speed [m/s], arrays (k1 - k0 + 1,)."""

    k0: int
    k1: int
    fx: FloatArray
    fy: FloatArray
    nav_deg: FloatArray
    speed: FloatArray


def _grid(track: Track, dt_s: float, last_k: int) -> _Grid | None:
    """The track at the step times k dt inside its samples (None: none of them, or all
    after the run's last step ``last_k``)."""
    k0 = max(math.ceil(track.start_s / dt_s - 1e-6), 0)
    k1 = min(math.floor(track.end_s / dt_s + 1e-6), last_k)
    if k1 < k0:
        return None
    t = np.arange(k0, k1 + 1, dtype=np.float64) * dt_s
    t = np.clip(t, track.start_s, track.end_s)  # a step within 1 ns of an end
    x = np.interp(t, track.time_s, track.x_m)
    y = np.interp(t, track.time_s, track.y_m)
    h = np.interp(t, track.time_s, track.heading_rad)
    v = np.interp(t, track.time_s, track.speed_mps)
    fx, fy = box_fronts(x, y, h, track.length_m)
    return _Grid(k0, k1, fx, fy, math_rad_to_nav_deg_array(h), v)


@dataclass
class ReplayAgents:
    """The recorded vehicles of one run in a running libsumo (``ls``): :meth:`prepare`
    once after SUMO started, :meth:`apply` before every SUMO step, :meth:`observe`
    after it (reactive handovers), :meth:`agents` for a scene's vehicles.

    ``dt_s``: SUMO's step [s]; ``run_steps``: how many SUMO steps the run may take;
    ``route``: the scenario's route (a reactive vehicle's route continues along it)."""

    spec: ReplaySpec
    tracks: TrackSet
    dt_s: float
    run_steps: int
    route: tuple[str, ...]
    handovers: list[ReplayHandover] = field(default_factory=list)
    _grids: dict[str, _Grid] = field(default_factory=dict)
    _by_start: list[tuple[int, str]] = field(default_factory=list)
    _next_start: int = 0
    _active: list[str] = field(default_factory=list)  # replayed now, insertion order
    _kind: dict[str, int] = field(default_factory=dict)  # inserted id -> agent kind
    _routes: dict[str, tuple[str, ...]] = field(default_factory=dict)
    _max_speed: dict[str, float] = field(default_factory=dict)
    _type_of: dict[str, str] = field(default_factory=dict)
    seen: set[str] = field(default_factory=set)  # ids ever inserted

    def prepare(self, ls: Any) -> None:
        """Vehicle types per box size, each track's step grid and route."""
        types: dict[tuple[float, float], str] = {}
        for track in self.tracks.tracks:
            g = _grid(track, self.dt_s, self.run_steps)
            if g is None:
                continue
            tid = track.track_id
            self._grids[tid] = g
            self._by_start.append((g.k0, tid))
            size = (round(track.length_m, 3), round(track.width_m, 3))
            if size not in types:
                types[size] = f"rec_type_{len(types)}"
                ls.vehicletype.copy("DEFAULT_VEHTYPE", types[size])
                ls.vehicletype.setLength(types[size], size[0])
                ls.vehicletype.setWidth(types[size], size[1])
                ls.vehicletype.setMinGap(types[size], 2.0)
            self._type_of[tid] = types[size]
            self._max_speed[tid] = max(float(np.max(track.speed_mps)), 1.0)
            self._routes[tid] = self._track_route(ls, track)
            ls.route.add(f"{tid}__route", list(self._routes[tid]))
        self._by_start.sort()

    def _track_route(self, ls: Any, track: Track) -> tuple[str, ...]:
        """The edges the track drives (module doc), continued along the scenario route."""
        n = track.time_s.shape[0]
        stride = max(int(round(ROUTE_SAMPLE_S / max(self.tracks.dt_s, 1e-6))), 1)
        idx = sorted(set(range(0, n, stride)) | {n - 1})
        edges: list[str] = []
        for i in idx:
            edge = str(ls.simulation.convertRoad(float(track.x_m[i]), float(track.y_m[i]),
                                                 False, "passenger")[0])
            if edge and not edge.startswith(":") and (not edges or edges[-1] != edge):
                edges.append(edge)
        if not edges:
            return (self.route[0],)
        out = [edges[0]]
        for edge in edges[1:]:
            if edge in out:
                continue
            path = tuple(ls.simulation.findRoute(out[-1], edge, vType="DEFAULT_VEHTYPE").edges)
            if path:
                out.extend(e for e in path[1:] if e not in out)
        if out[-1] in self.route:
            out.extend(e for e in self.route[self.route.index(out[-1]) + 1:] if e not in out)
        return tuple(out)

    def apply(self, ls: Any, k: int) -> None:
        """Before SUMO step ``k`` (ending at run time k dt): insert the tracks starting
        then, remove those that ended, put every replayed vehicle at its pose."""
        v = ls.vehicle
        while self._next_start < len(self._by_start) and self._by_start[self._next_start][0] <= k:
            tid = self._by_start[self._next_start][1]
            self._next_start += 1
            g = self._grids[tid]
            if g.k0 < k:
                continue  # its steps are over before the replay began (cannot happen)
            v.add(tid, f"{tid}__route", self._type_of[tid], depart="now",
                  departSpeed=repr(float(g.speed[0])))
            v.setSpeedMode(tid, REPLAY_SPEED_MODE)
            v.setLaneChangeMode(tid, 0)
            self._active.append(tid)
            self._kind[tid] = AGENT_REPLAYED
            self.seen.add(tid)
        if not self._active:
            return
        keep = []
        present: set[str] | None = None
        for tid in self._active:
            g = self._grids[tid]
            if k > g.k1:
                present = set(v.getIDList()) if present is None else present
                if tid in present:
                    v.remove(tid)
                self._kind.pop(tid, None)
                continue
            j = k - g.k0
            v.moveToXY(tid, "", -1, float(g.fx[j]), float(g.fy[j]), float(g.nav_deg[j]),
                       keepRoute=2)
            v.setSpeed(tid, float(g.speed[j]))
            keep.append(tid)
        self._active = keep

    def agents(self, ids: tuple[str, ...]) -> npt.NDArray[np.int8]:
        """The agent kind of each vehicle of ``ids`` (module doc), shape (n,) int8."""
        kind = self._kind
        return np.fromiter((kind.get(vid, AGENT_SUMO) for vid in ids), dtype=np.int8,
                           count=len(ids))

    def observe(self, ls: Any, ego: HandoverEgo | None, traffic: Traffic, t_s: float) -> None:
        """After a SUMO step at run time ``t_s``: hand over the replayed vehicles of
        ``traffic`` that meet :func:`handover_due` (reactive mode only)."""
        if not self.spec.reactive or ego is None or traffic.count == 0 or not self._active:
            return
        mask = traffic.agent == AGENT_REPLAYED
        if not mask.any():
            return
        sub = traffic.take(mask)
        due = handover_due(ego, sub, self.spec.handover_time_gap_s)
        for i in np.flatnonzero(due).tolist():
            self._hand_over(ls, sub.ids[i], t_s)

    def _hand_over(self, ls: Any, tid: str, t_s: float) -> None:
        v = ls.vehicle
        v.setSpeedMode(tid, REACTIVE_SPEED_MODE)
        v.setLaneChangeMode(tid, self.spec.lane_change_mode)
        v.setSpeedFactor(tid, 1.0)
        v.setMaxSpeed(tid, self._max_speed[tid])
        road = str(v.getRoadID(tid))
        route = self._routes[tid]
        if road in route:
            v.setRoute(tid, list(route[route.index(road):]))
        v.setSpeed(tid, -1.0)
        self._active.remove(tid)
        self._kind[tid] = AGENT_REACTIVE
        self.handovers.append(ReplayHandover(tid, float(t_s)))
