"""Minimal-risk manoeuvre: what drives when the outer planner fails.

When the planner reports a failure (C/GMRES residual above its bound or non-finite,
Ipopt unsuccessful) or a command is non-finite, the controller stops using the planner
and follows this manoeuvre instead, committed for at least ``hold_s``:

* speed: a jerk-limited ramp (:class:`TargetSpeedRamp`, deceleration ``decel_mps2``,
  jerk ``jerk_mps3``) starting at the *measured* speed and acceleration, toward the
  behaviour's speed target (which follows the lead car) but never above the speed at
  engagement: it brakes smoothly, it never speeds up. Unless that is too little: with
  an obstacle ellipse ahead covering the ego's lateral position (the followed lead's
  wall, a stopped car), at distance d from the ego's CG to the ellipse and closing at
  dv, the braking needed is b = dv² / (2 d) (d at least the bumper gap less
  ``standstill_m``: :func:`most_urgent_obstacle`); while 1.2 b exceeds ``decel_mps2`` the ramp
  brakes at up to 1.2 b, capped at ``emergency_decel_mps2``; its jerk bound
  (:func:`onset_jerk_mps3`) is ``jerk_mps3`` while 1.2 b is within
  ``comfort_decel_mps2`` and ``emergency_jerk_mps3`` beyond (a collision is worse than
  a hard stop, but a moderate need does not justify an emergency-rate brake onset);
* path: along the reference at the shaped lateral reference (the lane the behaviour
  holds), so the preview tracker keeps the car in its lane;
* its own limits hold at the wheels (:meth:`TwoLoopController._mrm_limits`): the
  tracker's corrections never brake harder than the ramp's current deceleration
  (``decel_mps2``, or the emergency's), never brake once the car is below the ramp's
  set-point, and the steering moves from the last command at a bounded rate
  (:mod:`controllers.two_loop.steer_rate`), never stepped.

Re-engagement: after ``hold_s`` the planner restarts at the measured state (its growing
horizon makes the first solution exact) and resumes. Hysteresis: a failure within
``rearm_s`` of re-engaging doubles the next hold (up to ``max_hold_s``); a clean
``rearm_s`` resets it. This replaces alternating full drive and full braking (a restart
that fails again at once) with one committed, comfortable braking manoeuvre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.behaviour.ellipses import box_half_length_m
from controllers.behaviour.types import ObstaclePolicy
from controllers.params import check_leaves, check_range, param
from controllers.path.frenet import FrenetPath
from controllers.protocol import Obstacles
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.outer.target_ramp import TargetSpeedRamp

NEED_MARGIN = 1.2  # braking is planned for this multiple of the obstacle's need b [-]
URGENT_WINDOW_S = 0.5  # the plan's deceleration is read over this much of its horizon [s]


@dataclass(frozen=True)
class Emergency:
    """Braking beyond comfort for an obstacle (the only reason for it), as the trace
    shows it: ``active``; ``decel_mps2`` the braking b the obstacle needs
    (:func:`most_urgent_obstacle`) [m/s²]; ``ds_m``, ``dy_m`` its ellipse centre from the
    ego's CG along and across the path [m]; ``jerk_mps3`` the braking onset's jerk bound
    it allows [m/s³] (NaN when not active)."""

    active: bool = False
    decel_mps2: float = math.nan
    ds_m: float = math.nan
    dy_m: float = math.nan
    jerk_mps3: float = math.nan


NO_EMERGENCY = Emergency()


@dataclass(frozen=True)
class FallbackParams:
    """Minimal-risk manoeuvre (module docstring)."""

    decel_mps2: float = param(3.0, "m/s²", "deceleration of the minimal-risk braking")
    jerk_mps3: float = param(3.0, "m/s³", "jerk bound of its braking onset")
    hold_s: float = param(2.0, "s", "shortest manoeuvre before the planner re-engages")
    max_hold_s: float = param(8.0, "s", "longest hold after repeated failures")
    rearm_s: float = param(4.0, "s", "a failure this soon after re-engaging doubles the hold")
    emergency_decel_mps2: float = param(8.0, "m/s²",
                                        "hardest braking when an obstacle ahead needs it")
    emergency_jerk_mps3: float = param(15.0, "m/s³", "jerk bound of that braking")
    comfort_decel_mps2: float = param(3.5, "m/s²", "needed braking up to which the onset "
                                      "keeps jerk_mps3")
    standstill_m: float = param(1.0, "m", "bumper gap kept when the CG is inside an ellipse")
    lat_jerk_mps3: float = param(5.0, "m/s³", "lateral jerk bounding the steering rate while "
                                 "the manoeuvre drives and blends out")
    blend_s: float = param(1.0, "s", "how long the steering rate stays bounded after the "
                           "hand-back to the planner")
    rate_speed_floor_mps: float = param(5.0, "m/s", "speed below which the steering-rate "
                                        "bound no longer grows")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("decel_mps2", "jerk_mps3", "hold_s", "max_hold_s", "rearm_s",
                     "emergency_decel_mps2", "emergency_jerk_mps3", "comfort_decel_mps2",
                     "standstill_m", "lat_jerk_mps3", "blend_s", "rate_speed_floor_mps"):
            check_range(self, name, gt=0.0)
        check_range(self, "max_hold_s", ge=self.hold_s)
        check_range(self, "emergency_decel_mps2", ge=self.decel_mps2)
        check_range(self, "emergency_jerk_mps3", ge=self.jerk_mps3)


class MinimalRiskManeuver:
    """``engage`` on a failure; while ``active``, :meth:`plan` is what the tracker
    follows; :meth:`due` says when the planner may take over again (then
    :meth:`release`)."""

    def __init__(self, params: FallbackParams, accel_mps2: float,
                 policy: ObstaclePolicy | None = None) -> None:
        self.params = params
        self.policy = policy
        self.ramp = TargetSpeedRamp(accel_mps2, params.decel_mps2, params.jerk_mps3)
        self.active = False
        self.count = 0
        self._since = -math.inf
        self._released = -math.inf
        self._hold = params.hold_s
        self._cap = 0.0
        self.set_point_mps = math.inf
        self.emergency = NO_EMERGENCY

    def reset(self) -> None:
        self.active = False
        self.emergency = NO_EMERGENCY
        self.count = 0
        self._since = -math.inf
        self._released = -math.inf
        self._hold = self.params.hold_s

    def engage(self, t_s: float, speed_mps: float, accel_mps2: float) -> None:
        """A failure at ``t_s``: brake from the measured speed and acceleration."""
        p = self.params
        if t_s - self._released < p.rearm_s:
            self._hold = min(2.0 * self._hold, p.max_hold_s)
        else:
            self._hold = p.hold_s
        self.active = True
        self.count += 1
        self._since = t_s
        self._cap = max(speed_mps, 0.0)
        self.ramp.reset(max(speed_mps, 0.0))
        self.ramp.ramp_accel_mps2 = min(max(accel_mps2, -p.decel_mps2), 0.0)

    def due(self, t_s: float) -> bool:
        return self.active and t_s - self._since >= self._hold

    def release(self, t_s: float) -> None:
        self.active = False
        self._released = t_s
        self.emergency = NO_EMERGENCY

    def _brace(self, x0: np.ndarray, obstacles: Obstacles | None) -> None:
        """Ramp limits for this step: the usual ones, or harder if an obstacle ahead needs
        it (module docstring); :attr:`emergency` says which obstacle, when that need is
        beyond ``comfort_decel_mps2``."""
        p = self.params
        need, j = most_urgent_obstacle(x0, self.ramp.speed_mps, obstacles, self.policy,
                                       p.standstill_m)
        self.emergency = NO_EMERGENCY
        if NEED_MARGIN * need > p.decel_mps2 and obstacles is not None and j >= 0:
            self.ramp.decel_mps2 = min(NEED_MARGIN * need, p.emergency_decel_mps2)
            self.ramp.jerk_mps3 = onset_jerk_mps3(p, NEED_MARGIN * need)
            if NEED_MARGIN * need > p.comfort_decel_mps2:  # beyond comfort: an emergency
                self.emergency = Emergency(True, need, float(obstacles.s_m[j] - x0[0]),
                                           float(obstacles.y_m[j] - x0[1]),
                                           self.ramp.jerk_mps3)
        else:
            self.ramp.decel_mps2 = p.decel_mps2
            self.ramp.jerk_mps3 = p.jerk_mps3

    @property
    def hold_s(self) -> float:
        """The current hold (doubled after repeated failures)."""
        return self._hold

    def plan(self, path: FrenetPath, x0: np.ndarray, lateral_m: float, target_mps: float,
             dt_s: float, horizon_s: float, n_stages: int,
             obstacles: Obstacles | None = None) -> OuterPlan:
        """Advance the ramp by ``dt_s`` toward min(target, speed at engagement) and give
        the manoeuvre over the horizon: (s, y = lateral_m, gamma(s)) at N + 1 nodes.
        ``obstacles`` (the ellipses of this step) set the emergency braking."""
        self._brace(x0, obstacles)
        set_point = min(target_mps if math.isfinite(target_mps) else 0.0, self._cap)
        self.set_point_mps = max(set_point, 0.0)
        v0 = self.ramp.update(max(set_point, 0.0), dt_s)
        a0 = self.ramp.ramp_accel_mps2
        tau = np.linspace(0.0, horizon_s, n_stages + 1)
        v = np.maximum(v0 + a0 * tau, 0.0)
        s = float(x0[0]) + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1])
                                                              * np.diff(tau))])
        y = np.full(n_stages + 1, lateral_m if math.isfinite(lateral_m) else float(x0[1]))
        states = np.column_stack([s, y, path.gamma(s)])
        return OuterPlan(stage_times_s=tau, states=states, speeds_mps=v[:-1].copy(),
                         headings_rad=states[:-1, 2].copy(), residual=math.nan,
                         fallback=True, guard_fired=0, solve_s=0.0, target_speed_mps=v0)


def onset_jerk_mps3(p: FallbackParams, decel_mps2: float) -> float:
    """Jerk bound [m/s³] of a braking onset toward ``decel_mps2``: ``jerk_mps3`` up to
    ``comfort_decel_mps2``, ``emergency_jerk_mps3`` beyond. A step, not a blend: once
    the braking needed is beyond comfort, comfort is lost anyway and a slower onset only
    spends the gap (graded linearly up to 8 m/s², a car stopping 15 m ahead at 11.5 m/s
    left a 2.1 m gap and a TTC of 0.76 s instead of 1.5 s; docs/two_loop.md)."""
    return p.jerk_mps3 if decel_mps2 <= p.comfort_decel_mps2 else p.emergency_jerk_mps3


def plan_decel_mps2(speed_mps: float, plan: OuterPlan,
                    window_s: float = URGENT_WINDOW_S) -> float:
    """The deceleration [m/s²] the plan asks of the car: (v - V_k) / max(tau_k, window_s),
    v the measured speed, V_k the plan's speed at its first node tau_k >= ``window_s``
    (the last if the horizon is shorter). The plan's V is an input of its point-mass
    model: a plan far below the car's speed wants it slower now. 0 for an empty plan."""
    tau = np.asarray(plan.stage_times_s, dtype=np.float64)
    v = np.asarray(plan.speeds_mps, dtype=np.float64)
    if v.size == 0:
        return 0.0
    k = min(int(np.searchsorted(tau, window_s)), v.size - 1)
    return (speed_mps - float(v[k])) / max(float(tau[k]), window_s)


def planner_emergency(p: FallbackParams, x0: np.ndarray, speed_mps: float, plan: OuterPlan,
                      obstacles: Obstacles | None, policy: ObstaclePolicy | None = None, *,
                      urgent: tuple[float, int] | None = None) -> Emergency:
    """Whether the planner's braking this step is an emergency: both the plan's own
    deceleration (:func:`plan_decel_mps2`) and ``NEED_MARGIN`` times an obstacle's need b
    (:func:`most_urgent_obstacle`, from the measured Frenet x0 and speed) exceed
    ``comfort_decel_mps2``. Then its braking onset may be as fast as
    :func:`onset_jerk_mps3` of the lesser of the two (``emergency_jerk_mps3``).

    The plan alone is not enough: a set-point below the car's speed (a lower set speed,
    a restart) is no emergency, however far below. Nor is the obstacle alone: a stopped
    car the ego evades "needs" an emergency stop all the while the plan goes round it.

    ``urgent``: :func:`most_urgent_obstacle` of these x0, speed, obstacles and policy
    (with ``p.standstill_m``) when the caller has it already (computed here otherwise)."""
    if obstacles is None or obstacles.count == 0:
        return NO_EMERGENCY
    want = plan_decel_mps2(speed_mps, plan)
    if not want > p.comfort_decel_mps2:
        return NO_EMERGENCY
    need, j = urgent if urgent is not None else most_urgent_obstacle(
        x0, speed_mps, obstacles, policy, p.standstill_m)
    if j < 0 or not NEED_MARGIN * need > p.comfort_decel_mps2:
        return NO_EMERGENCY
    return Emergency(True, need, float(obstacles.s_m[j] - x0[0]), float(obstacles.y_m[j] - x0[1]),
                     onset_jerk_mps3(p, min(want, NEED_MARGIN * need)))


def braking_need_mps2(speed_mps: float, lead_speed_mps: np.ndarray, d_m: np.ndarray,
                      lead_braking_mps2: np.ndarray) -> np.ndarray:
    """The constant deceleration b [m/s²] that keeps an ego at ``speed_mps`` (v) clear of
    each obstacle ahead at distance ``d_m`` (d) moving at ``lead_speed_mps`` (v_j >= 0)
    and braking at ``lead_braking_mps2`` (b_j >= 0, to a stop), all (K,):

    * the speeds match while the obstacle still moves (closing c = v - v_j > 0 and the
      match time 2d/c at b = b_j + c² / (2d) comes before its stop, v_j / b_j):
      b = b_j + c² / (2d) (with b_j = 0 the constant-speed law c² / (2d));
    * otherwise the ego must stop within the obstacle's stopping point:
      b = v² / (2 (d + v_j² / (2 b_j))) (0 when b_j = 0 and nothing closes).

    d <= 0 while closing (or with the obstacle braking) is inf; nothing closing and no
    braking is 0."""
    v = float(speed_mps)
    c = v - lead_speed_mps
    with np.errstate(divide="ignore", invalid="ignore"):
        d_pos = np.maximum(d_m, 1e-9)
        match = lead_braking_mps2 + np.maximum(c, 0.0) ** 2 / (2.0 * d_pos)
        stops = lead_braking_mps2 > 0.0
        t_stop = np.where(stops, lead_speed_mps / np.where(stops, lead_braking_mps2, 1.0),
                          np.inf)
        before_stop = (c > 0.0) & (2.0 * d_pos / np.maximum(c, 1e-12) <= t_stop)
        stop_within = np.where(
            stops, v * v / (2.0 * (d_pos + lead_speed_mps**2
                                   / (2.0 * np.where(stops, lead_braking_mps2, 1.0)))),
            0.0)
        b = np.where(before_stop, match, stop_within)
        b = np.where(d_m > 0.0, b, np.where((c > 0.0) | stops, np.inf, 0.0))
    return np.asarray(b, dtype=float)


def most_urgent_obstacle(x0: np.ndarray, speed_mps: float, obstacles: Obstacles | None,
                         policy: ObstaclePolicy | None = None, standstill_m: float = 1.0
                         ) -> tuple[float, int]:
    """(b [m/s²], j): the braking b that keeps the ego's CG (Frenet x0 = (s, y, ...),
    speed v) out of the nearest ellipse ahead covering its lateral offset:
    b = (v - v_j)² / (2 d_j), d_j = s_j - A_j - s the distance to the ellipse's rear point
    along s, v_j the ellipse's speed along s (0 if nothing is ahead or nothing closes);
    an ellipse whose vehicle brakes (``obstacles.accel_s_mps2`` < 0) needs
    :func:`braking_need_mps2` with that braking.

    Without ``policy``, inf once the CG is at or past that point (d_j <= 0) and closing.
    With the ``policy`` the ellipses were built with (a_j the box-sum half length:
    ``obstacles.half_length_m``, or where the obstacles do not carry it
    :func:`controllers.behaviour.ellipses.box_half_length_m` of the semi-axes, which a
    followed lead's wall or a shrunk ellipse would turn into a fraction of the car's
    length: a cut-in 4 m ahead read as 7 m away, its need as 1.5 m/s² instead of 6.9;
    g_j = s_j - a_j - s -
    ``standstill_m`` the bumper gap less the standstill distance):

        d_j <- max(d_j, min(g_j, A_j - a_j - standstill_m))

    i.e. the ellipse's distance while it exceeds the ellipse's own margin over the box
    sum, that margin on the ellipse's rear, and the bumper gap inside the ellipse
    (continuous, never increasing as the ego closes in; inf only when g_j <= 0). The
    ellipse's margins are the planner's, not the car's: a car merging in 5 m ahead at
    nearly the ego's speed needs little braking, not an emergency stop (with d_j near
    zero there it needed 8 m/s²); far out the ellipse's distance keeps its early,
    harder braking for a stopped car (the bumper gap alone braked later: TTC 1.5 s ->
    0.8 s behind a car stopping 15 m ahead at 11.5 m/s).

    j is the index into ``obstacles`` of the ellipse that needs b (the first of the
    largest; -1 with b = 0 when nothing ahead covers the ego or nothing closes)."""
    if obstacles is None or obstacles.count == 0:
        return 0.0, -1
    s, y = float(x0[0]), float(x0[1])
    ds = obstacles.s_m - s
    ahead = (ds > 0.0) & (np.abs(obstacles.y_m - y) < obstacles.semi_b_m)
    if not np.any(ahead):
        return 0.0, -1
    d = ds[ahead] - obstacles.semi_a_m[ahead]
    if policy is not None:
        half = (obstacles.half_length_m[ahead] if obstacles.half_length_m.shape[0]
                else box_half_length_m(obstacles.semi_a_m[ahead], obstacles.semi_b_m[ahead],
                                       policy))
        gap = ds[ahead] - half - standstill_m  # bumper gap less the standstill distance
        floor = obstacles.semi_a_m[ahead] - half - standstill_m  # = gap - d
        d = np.maximum(d, np.minimum(gap, floor))
    lead_braking = (np.maximum(-obstacles.accel_s_mps2[ahead], 0.0)
                    if obstacles.accel_s_mps2.shape[0] == obstacles.count
                    else np.zeros(int(np.count_nonzero(ahead))))
    b = braking_need_mps2(speed_mps, np.maximum(obstacles.speed_s_mps[ahead], 0.0), d,
                          lead_braking)
    k = int(np.argmax(b))
    if not b[k] > 0.0:
        return 0.0, -1
    return float(b[k]), int(np.flatnonzero(ahead)[k])
