"""What the ``r157_reference`` driver reads of a step's obstacles: leads, cut-ins, braking.

The driver keeps its lane, the reference lane: its centre is the reference path (y = 0),
the lanes beside it have their centres at y = +-w (w the lane width of the scenario's
context). From the behaviour's obstacles (their centres (s, y) and velocities along and
across the path, exact for the driver's policy, whose ``offset_m`` is 0) it reads:

* the **lead**: the nearest vehicle ahead whose centre is in the ego's lane (|y| < w/2);
* **cut-in candidates**: vehicles ahead whose centre is in a lane beside it (w/2 <= |y|
  < 3w/2), moving towards the ego's lane, with the *deviation* of their centre from their
  own lane's centre towards the ego's lane, w - |y| [m] (R157's risk perception point
  for a lane change is this deviation passing 0.375 m; docs/baselines.md);
* each vehicle's **deceleration**, estimated from its speed along the path by
  :class:`DecelerationTracker`.

Bumper gaps use the obstacles' box-sum half lengths (``half_length_m``, the centre
distance at which the boxes touch), or ``(DEFAULT_LENGTH_M + ego length) / 2`` when the
obstacles do not carry them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from controllers.behaviour.types import Obstacles

DEFAULT_LENGTH_M = 4.5  # a vehicle's length when the obstacles do not carry it
SPEED_CHANGE_MPS = 1e-6  # a speed sample that differs by more is a new one


@dataclass(frozen=True)
class Other:
    """A vehicle as the driver sees it: its key (vehicle id, or ``#k`` for the k-th
    obstacle), bumper gap ahead of the ego [m] (front of the ego to its rear; < 0 when
    the boxes overlap along the path), its lateral offset from the reference path
    [m, left +], its velocity along and across the path [m/s] and its deceleration
    (> 0 braking) [m/s²]."""

    key: str
    gap_m: float
    y_m: float
    speed_mps: float
    lateral_speed_mps: float
    decel_mps2: float


@dataclass
class DecelerationTracker:
    """Deceleration of each vehicle from its speed samples, (v_prev - v) / interval,
    between its last two *different* speed samples, so that a world that moves its
    vehicles less often than the control period (SUMO's step, the positions extrapolated
    in between at constant speed) gives the deceleration over its own step, not a spike
    and zeros. The interval is the time between the two samples when it is at most
    ``max_interval_s`` [s] (the vehicle's speed changes at every world step); a vehicle
    whose speed was constant for longer than that and now changes gets the world's
    period, the last such interval seen of any vehicle (the control period until one is
    seen): its first change is then read as one world step's, not spread over the time it
    held its speed. An estimate is held for ``hold_s`` [s] after its sample; with no new
    sample since, the vehicle holds its speed (0)."""

    period_s: float = 0.02
    hold_s: float = 0.5
    max_interval_s: float = 0.25
    _last: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    def reset(self, period_s: float) -> None:
        self._last.clear()
        self.period_s = period_s

    def update(self, t_s: float, speeds: dict[str, float]) -> dict[str, float]:
        """The deceleration [m/s², > 0 braking] of every vehicle in ``speeds`` (key ->
        speed [m/s] at ``t_s``); vehicles no longer seen are forgotten."""
        out: dict[str, float] = {}
        for key, v in speeds.items():
            out[key] = self._one(key, t_s, v)
        for gone in set(self._last) - set(speeds):
            del self._last[gone]
        return out

    def _one(self, key: str, t_s: float, v: float) -> float:
        prev = self._last.get(key)
        if prev is None:
            self._last[key] = (t_s, v, 0.0)
            return 0.0
        t0, v0, decel = prev
        if abs(v - v0) > SPEED_CHANGE_MPS and t_s > t0:
            interval = t_s - t0
            if interval <= self.max_interval_s:
                self.period_s = interval
            else:
                interval = self.period_s
            decel = (v0 - v) / interval
            self._last[key] = (t_s, v, decel)
            return decel
        return decel if t_s - t0 <= self.hold_s else 0.0


def obstacle_keys(obstacles: Obstacles) -> list[str]:
    """Each obstacle's key: its vehicle id, or ``#k`` when the ids are not known."""
    if obstacles.vehicle_ids:
        return list(obstacles.vehicle_ids)
    return [f"#{k}" for k in range(obstacles.count)]


def read_others(obstacles: Obstacles, ego_s_m: float, ego_length_m: float,
                decel: dict[str, float]) -> list[Other]:
    """Every obstacle as an :class:`Other`, in the obstacles' order."""
    keys = obstacle_keys(obstacles)
    halves = obstacles.half_length_m
    default_half = 0.5 * (DEFAULT_LENGTH_M + ego_length_m)
    out: list[Other] = []
    for k, key in enumerate(keys):
        half = float(halves[k]) if halves.shape[0] == obstacles.count else default_half
        out.append(Other(key=key, gap_m=float(obstacles.s_m[k]) - ego_s_m - half,
                         y_m=float(obstacles.y_m[k]),
                         speed_mps=float(obstacles.speed_s_mps[k]),
                         lateral_speed_mps=float(obstacles.speed_y_mps[k]),
                         decel_mps2=decel.get(key, 0.0)))
    return out


def in_ego_lane(other: Other, lane_width_m: float) -> bool:
    """Its centre is in the ego's lane (|y| < w/2)."""
    return abs(other.y_m) < 0.5 * lane_width_m


def lead(others: list[Other], lane_width_m: float) -> Other | None:
    """The nearest vehicle ahead (bumper gap > -1 m: not yet beside the ego) whose
    centre is in the ego's lane; None when there is none."""
    ahead = [o for o in others if in_ego_lane(o, lane_width_m) and o.gap_m > -1.0]
    return min(ahead, key=lambda o: o.gap_m) if ahead else None


def deviation_towards_ego_m(other: Other, lane_width_m: float) -> float:
    """How far the centre of a vehicle in a lane beside the ego's has moved from its own
    lane's centre towards the ego's lane, w - |y| [m]; NaN for a vehicle in no lane beside
    it or moving away from the ego's lane."""
    w = lane_width_m
    beside = 0.5 * w <= abs(other.y_m) < 1.5 * w
    towards = other.y_m * other.lateral_speed_mps < 0.0
    return w - abs(other.y_m) if beside and towards else math.nan


def time_to_collision_s(gap_m: float, ego_speed_mps: float, other_speed_mps: float) -> float:
    """gap / closing speed [s]; inf when not closing (0 at a gap <= 0 while closing)."""
    closing = ego_speed_mps - other_speed_mps
    if closing <= 0.0:
        return math.inf
    return max(gap_m, 0.0) / closing
