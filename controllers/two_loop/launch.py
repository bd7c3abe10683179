"""Launch supervisor: low-speed / standstill launch and hand-over to the two-loop controller.

The SPMM's speed V multiplies every lateral term, so at V = 0 heading and lateral
motion are uncontrollable and C/GMRES's F_U is singular; stopped behind an obstacle
it planned negative speeds (docs/two_loop.md "Launch"). The outer plan is therefore
not used from standstill until the car moves and the lane ahead is clear:

* engage: speed < ``engage_speed_mps``, target > ``handover_speed_mps``, and the lane
  ahead free of ellipses for ``handover_free_m`` or the lateral reference asking for a
  pull-out (|r_raw - y| > 0.5 m). Stopped with the lane blocked and no side free, it
  stays off (the two-loop controller holds the car).
* law: a :class:`TargetSpeedRamp` (the OCP's acceleration, deceleration and jerk
  limits) toward min(target, ``max_speed_mps``, sqrt(2 ``guard_decel_mps2``
  (d - ``clearance_m``))), torque T = m R a_ramp + ``k_pv`` (V_ramp - V), with d the
  free distance along the steering direction to the nearest box-sum rectangle grown by
  ``clearance_m`` (recovered from the ellipse by inverting
  ``controllers.behaviour.ellipses.ellipse_semi_axes``), without a pull-out also to
  the OCP's ellipse. Steering: pure pursuit of r_raw at ``lookahead_m``, heading offset
  h clipped to ``max_heading_rad``, delta = (L + K_us V²) kappa + ``k_heading``
  (gamma + h - psi), scaled by min(V / ``steer_speed_mps``, 1). Target below
  ``hold_target_mps``: the ramp brakes to 0 and the brakes hold (T <= -m R
  ``hold_decel_mps2``).
* hand-over: speed >= ``handover_speed_mps`` and the lane ahead at the car's offset
  free for ``handover_free_m``: the controller restarts the planner, the lateral
  shaper and the preview integral, and blends the launch command into the two-loop one
  over ``blend_s`` with the weight 1 - (3 phi² - 2 phi³) (C¹).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.behaviour.types import ObstaclePolicy, Obstacles
from controllers.params import ParamError, check_leaves, check_range, param
from controllers.path.frenet import FrenetPath, path_gamma
from controllers.plant.vehicle_model import VehicleParams
from controllers.two_loop.outer.params import OcpParams
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.outer.target_ramp import TargetSpeedRamp

_PULL_OUT_M = 0.5  # |r_raw - y| above this [m]: the reference asks for a pull-out
_ON_LANE_M = 0.25  # |r_raw - y| up to this [m]: not pulling out, the OCP's ellipses count
_MOVING_MPS = 0.05  # engaged above this speed [m/s]: the ramp starts at the commanded accel


@dataclass(frozen=True)
class LaunchParams:
    """Standstill launch and hand-over (module docstring)."""

    enabled: bool = param(True, "-", "use the launch law below engage_speed_mps")
    handover_speed_mps: float = param(1.5, "m/s", "hand-over speed to the two-loop controller")
    engage_speed_mps: float = param(0.5, "m/s", "standstill threshold below which it engages")
    blend_s: float = param(0.6, "s", "blend from the launch command after the hand-over")
    k_pv: float = param(1500.0, "N m s/m", "speed-error gain of the launch torque")
    max_speed_mps: float = param(3.0, "m/s", "speed cap until the hand-over")
    k_heading: float = param(1.0, "rad/rad", "pure-pursuit heading gain")
    lookahead_m: float = param(6.0, "m", "pure-pursuit look-ahead distance")
    max_heading_rad: float = param(0.5, "rad", "largest heading offset toward the target")
    steer_speed_mps: float = param(1.0, "m/s", "steering fades in up to this speed")
    clearance_m: float = param(0.3, "m", "growth of the box-sum rectangle")
    guard_decel_mps2: float = param(1.0, "m/s²", "speed cap sqrt(2 a (d - clearance))")
    handover_free_m: float = param(20.0, "m", "free lane ahead to engage (no pull-out), hand over")
    hold_target_mps: float = param(0.3, "m/s", "a target below this means stop")
    hold_decel_mps2: float = param(1.0, "m/s²", "holding brake, as -m R times this")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("handover_speed_mps", "engage_speed_mps", "blend_s", "steer_speed_mps",
                     "max_speed_mps", "lookahead_m", "max_heading_rad", "guard_decel_mps2"):
            check_range(self, name, gt=0.0)
        for name in ("k_pv", "k_heading", "hold_target_mps", "hold_decel_mps2", "clearance_m",
                     "handover_free_m"):
            check_range(self, name, ge=0.0)
        v = self.handover_speed_mps
        if self.engage_speed_mps >= v:
            raise ParamError("engage_speed_mps", f"a number < handover_speed_mps = {v}",
                             self.engage_speed_mps)
        if self.max_speed_mps < v:
            raise ParamError("max_speed_mps", f"a number >= handover_speed_mps = {v}",
                             self.max_speed_mps)
        if self.hold_target_mps >= v:
            raise ParamError("hold_target_mps", f"a number < handover_speed_mps = {v}",
                             self.hold_target_mps)


def free_distance_m(s_m: float, y_m: float, obstacles: Obstacles) -> float:
    """Distance [m] along the lane, at the lateral offset y_m, from s_m to the nearest
    obstacle ellipse ahead (as the OCP sees it); 0 inside one, inf if none."""
    d = math.inf
    for j in range(obstacles.count):
        sj, yj = float(obstacles.s_m[j]), float(obstacles.y_m[j])
        a, b = float(obstacles.semi_a_m[j]), float(obstacles.semi_b_m[j])
        q = (y_m - yj) / b if b > 0.0 else math.inf
        if not (abs(q) < 1.0 and math.isfinite(sj) and math.isfinite(a)):
            continue
        half = a * math.sqrt(1.0 - q * q)
        if s_m > sj + half:
            continue  # behind us
        d = min(d, max(sj - half - s_m, 0.0))
    return d


def _ray_hits_box(lo_s: float, hi_s: float, lo_y: float, hi_y: float, ch: float,
                  sh: float) -> float:
    """Entry distance t0 >= 0 of the ray t (ch, sh) from the origin into the box
    [lo_s, hi_s] x [lo_y, hi_y] (slab test); inf if it misses."""
    t0, t1 = 0.0, math.inf
    for lo, hi, dirc in ((lo_s, hi_s, ch), (lo_y, hi_y, sh)):
        if abs(dirc) < 1e-12:
            if lo > 0.0 or hi < 0.0:
                return math.inf
            continue
        ta, tb = lo / dirc, hi / dirc
        if ta > tb:
            ta, tb = tb, ta
        t0, t1 = max(t0, ta), min(t1, tb)
    return t0 if t0 <= t1 else math.inf


def box_free_distance_m(s_m: float, y_m: float, heading_rad: float, obstacles: Obstacles,
                        pass_side: int, policy: ObstaclePolicy, clearance_m: float) -> float:
    """Distance [m] along the ray from (s_m, y_m) at ``heading_rad`` (Frenet, relative to
    the lane) to the nearest box-sum rectangle (the CG positions where the two boxes
    touch when aligned with the lane, recovered from the ellipse by inverting
    ``controllers.behaviour.ellipses.ellipse_semi_axes`` with ``policy``) grown by
    ``clearance_m``; 0 inside one, inf if the ray misses them all."""
    side = float(np.sign(pass_side)) if abs(pass_side) == 1 else 0.0
    ch, sh = math.cos(heading_rad), math.sin(heading_rad)
    best = math.inf
    for j in range(obstacles.count):
        a_e = float(obstacles.semi_a_m[j]) - policy.margin_long_m
        b0 = float(obstacles.semi_b_m[j]) - policy.offset_m
        b = b0 - max(policy.margin_lat_m, 0.05)
        if not (a_e > 0.0 and b0 > 0.0 and b > 0.0):
            continue
        a = a_e * math.sqrt(max(1.0 - (b / b0) ** 2, 0.0))
        sc = float(obstacles.s_m[j])
        yc = float(obstacles.y_m[j]) + side * policy.offset_m * (1.0 if b0 > 0 else 0.0)
        t0 = _ray_hits_box(sc - a - clearance_m - s_m, sc + a + clearance_m - s_m,
                           yc - b - clearance_m - y_m, yc + b + clearance_m - y_m, ch, sh)
        if not math.isfinite(t0):
            continue
        if t0 <= 0.0 and abs(y_m - yc) > b and sh * (y_m - yc) > 0.0:
            continue  # within the clearance band beside it and moving away
        best = min(best, t0)
    return best


class LaunchSupervisor:
    """Decides when the launch law drives, computes it, and reports the hand-over.

    ``reset`` with the run's path and vehicle; each step: :meth:`transition` (engage
    or hand over; True on a hand-over), :meth:`weight`, then :meth:`command` while the
    weight is positive, and :meth:`observe_torque` with the torque finally applied.
    """

    def __init__(self, params: LaunchParams, ocp: OcpParams, policy: ObstaclePolicy) -> None:
        self.params = params
        self.ocp = ocp
        self.policy = policy
        self.ramp = TargetSpeedRamp(ocp.target_accel_mps2, ocp.target_decel_mps2,
                                    ocp.target_jerk_mps3)
        self.active = False
        self.count = 0
        self._t_handover = -math.inf
        self._last_torque = 0.0
        self._path: FrenetPath | None = None
        self._vp = VehicleParams().as_array()
        self._vehicle = VehicleParams()

    def reset(self, path: FrenetPath, vehicle: VehicleParams) -> None:
        """Start of a run: not engaged, ramp at rest."""
        self._path = path
        self._vp = vehicle.as_array()
        self._vehicle = vehicle
        self.ramp = TargetSpeedRamp(self.ocp.target_accel_mps2, self.ocp.target_decel_mps2,
                                    self.ocp.target_jerk_mps3)
        self.active = False
        self._t_handover = -math.inf
        self._last_torque = 0.0
        self.count = 0

    def watching(self, speed_mps: float) -> bool:
        """Whether this step may engage or hand over (at speed nothing of this runs)."""
        return self.params.enabled and (self.active or speed_mps < self.params.engage_speed_mps)

    def transition(self, t_s: float, x0: np.ndarray, speed_mps: float, target_mps: float,
                   obstacles: Obstacles, raw_reference_m: float) -> bool:
        """Engage, or hand over (returns True then); x0 = (s, y, theta) measured."""
        p = self.params
        free_m = free_distance_m(float(x0[0]), float(x0[1]), obstacles)
        if not self.active:
            pull_out = (math.isfinite(raw_reference_m)
                        and abs(raw_reference_m - float(x0[1])) > _PULL_OUT_M)
            if (speed_mps < p.engage_speed_mps and target_mps > p.handover_speed_mps
                    and (free_m >= p.handover_free_m or pull_out)):
                self.active = True
                self._t_handover = -math.inf
                self.ramp.reset(speed_mps)
                if speed_mps > _MOVING_MPS:  # moving: continue the commanded acceleration
                    a = self._last_torque / (self._vp[0] * self._vp[6])
                    self.ramp.ramp_accel_mps2 = min(max(a, -self.ocp.target_decel_mps2),
                                                    self.ocp.target_accel_mps2)
            return False
        if speed_mps >= p.handover_speed_mps and free_m >= p.handover_free_m:
            self.active = False
            self._t_handover = t_s
            self.count += 1
            return True
        return False

    def weight(self, t_s: float) -> float:
        """1 in launch mode, easing to 0 over blend_s after the hand-over, else 0."""
        if self.active:
            return 1.0
        blend = self.params.blend_s
        if t_s - self._t_handover < blend:
            phi = min(max((t_s - self._t_handover) / blend, 0.0), 1.0)
            return 1.0 - phi * phi * (3.0 - 2.0 * phi)
        return 0.0

    def observe_torque(self, torque_nm: float) -> None:
        """The torque commanded this step (a later engagement continues its accel)."""
        self._last_torque = float(torque_nm)

    def command(self, state: np.ndarray, x0: np.ndarray, speed_mps: float, target_mps: float,
                y_target_m: float, obstacles: Obstacles, pass_side: int,
                dt_s: float) -> tuple[float, float]:
        """(steer_rad, torque_nm) of the launch law (module docstring); advances the ramp.

        state: (6,) measured plant state; x0: its Frenet (s, y, theta); y_target_m: the
        lateral reference r_raw [m]."""
        p = self.params
        vp = self._vp
        if self._path is None:
            raise RuntimeError("LaunchSupervisor.command called before reset")
        yt = y_target_m if math.isfinite(y_target_m) else float(x0[1])
        h = math.atan2(yt - float(x0[1]), p.lookahead_m)
        h = min(max(h, -p.max_heading_rad), p.max_heading_rad)
        free_m = box_free_distance_m(float(x0[0]), float(x0[1]), h, obstacles, pass_side,
                                     self.policy, p.clearance_m)
        # Where the car is heading now, too: the ray along h may already miss the box while
        # the car, still turning toward h, drives at it.
        meta, coef, _ = self._path.tables()
        g, kappa, _ = path_gamma(meta, coef, float(x0[0]))
        heading = (float(x0[2]) - g + math.pi) % (2.0 * math.pi) - math.pi
        free_m = min(free_m, box_free_distance_m(float(x0[0]), float(x0[1]), heading,
                                                 obstacles, pass_side, self.policy,
                                                 p.clearance_m))
        if abs(yt - float(x0[1])) <= _ON_LANE_M:  # not pulling out: the OCP's ellipses too
            free_m = min(free_m, free_distance_m(float(x0[0]), float(x0[1]), obstacles))
        set_point = target_mps if math.isfinite(target_mps) else 0.0
        set_point = min(set_point, p.max_speed_mps if self.active else math.inf)
        if math.isfinite(free_m):
            set_point = min(set_point, math.sqrt(2.0 * p.guard_decel_mps2
                                                 * max(free_m - p.clearance_m, 0.0)))
        if set_point <= p.hold_target_mps:
            set_point = 0.0
        vr = self.ramp.update(set_point, dt_s)
        ar = self.ramp.ramp_accel_mps2
        m_r = vp[0] * vp[6]
        torque = m_r * ar + p.k_pv * (vr - speed_mps)
        if set_point == 0.0 and vr <= 0.0 and speed_mps < p.engage_speed_mps:
            torque = min(torque, -m_r * p.hold_decel_mps2)  # hold the brakes
        e_psi = (g + h - float(state[2]) + math.pi) % (2.0 * math.pi) - math.pi
        steer = self._vehicle.steady_state_steer_rad(speed_mps, kappa) + p.k_heading * e_psi
        steer *= min(speed_mps / p.steer_speed_mps, 1.0)
        return float(steer), float(torque)

    def plan(self, x0: np.ndarray) -> OuterPlan:
        """What the launch law does, as a plan for the logs: the ramp along the lane."""
        if self._path is None:
            raise RuntimeError("LaunchSupervisor.plan called before reset")
        n = self.ocp.n_stages
        tau = np.linspace(0.0, self.ocp.horizon_s, n + 1)
        v = np.maximum(self.ramp.speed_mps + self.ramp.ramp_accel_mps2 * tau, 0.0)
        s = float(x0[0]) + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1])
                                                              * np.diff(tau))])
        states = np.column_stack([s, np.full(n + 1, float(x0[1])), self._path.gamma(s)])
        return OuterPlan(stage_times_s=tau, states=states, speeds_mps=v[:-1].copy(),
                         headings_rad=states[:-1, 2].copy(), residual=0.0, fallback=False,
                         guard_fired=0, solve_s=0.0, target_speed_mps=self.ramp.speed_mps)
