"""``pd_follow``: PD lane keeping on the behaviour's lateral reference, constant time-gap
car following, jerk-limited acceleration. A small, real controller for the plug-in API.

Frames: the reference path's Frenet frame (s along, y left +) from
``ScenarioContext.reference_path()``; obstacles arrive in that frame
(``Observation.obstacles``: ellipse centre s, y, speed along s, semi-axes).

Lateral (PD on the lateral error, as a curvature command). With e_y = y − y_r the
offset from the lateral target y_r (the behaviour's ``lateral_reference_m`` through a
first-order filter of time constant τ_y, so a lane change is a smooth S), e_ψ the
heading error against the path tangent and v the speed:

    ė_y = v sin e_ψ,   a_y* = −ω² e_y − 2 ζ ω ė_y,
    κ_cmd = κ_ref(s) + a_y* / max(v, v_min)²,   δ = atan(L κ_cmd)  (clipped)

with L the wheelbase: the error obeys ë_y + 2ζω ė_y + ω² e_y = 0 on a kinematic car.

Longitudinal (constant time gap h to the nearest obstacle ahead in the ego's lane,
|y_obs − y| < w_lane / 2): the gap g = s_obs − s − a_obs (to the ellipse's rear
boundary; the ellipse holds both boxes and margins), the wanted gap
g* = g₀ + h v, and

    a_follow = k_g (g − g*) + k_v (v_obs − v),   a_cruise = k_c (v_set − v),
    a* = clip(min(a_follow, a_cruise), −a_brake, a_max),

rate-limited to |da/dt| ≤ j_max; the drive torque of the drag-free single-track model
is T = m R a.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from controllers.behaviour.types import ObstaclePolicy
from controllers.params import build, check_leaves, check_range, param, to_dict
from controllers.path.frenet import FrenetPath
from controllers.protocol import (
    Command,
    ConfigError,
    Observation,
    ScenarioContext,
    StepDiagnostics,
)

NAME = "pd_follow"


@dataclass(frozen=True)
class PdFollowParams:
    """Gains and limits of ``pd_follow`` (module docstring)."""

    omega_radps: float = param(0.7, "rad/s", "ω: natural frequency of the lateral error")
    zeta: float = param(0.9, "-", "ζ: damping ratio of the lateral error")
    lateral_tau_s: float = param(1.2, "s", "τ_y: filter of the lateral target")
    min_speed_mps: float = param(3.0, "m/s", "v_min: speed floor of the curvature command")
    time_gap_s: float = param(1.6, "s", "h: time gap to the vehicle ahead")
    standstill_gap_m: float = param(4.0, "m", "g₀: gap kept at standstill")
    gap_gain_per_s2: float = param(0.12, "1/s²", "k_g: gap error -> acceleration")
    speed_gain_per_s: float = param(0.5, "1/s", "k_v: speed difference -> acceleration")
    cruise_gain_per_s: float = param(0.4, "1/s", "k_c: set-speed error -> acceleration")
    max_accel_mps2: float = param(1.5, "m/s²", "a_max: largest acceleration")
    max_brake_mps2: float = param(3.5, "m/s²", "a_brake: hardest braking")
    max_jerk_mps3: float = param(2.5, "m/s³", "j_max: acceleration rate limit")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("omega_radps", "zeta", "lateral_tau_s", "min_speed_mps", "time_gap_s",
                     "max_accel_mps2", "max_brake_mps2", "max_jerk_mps3"):
            check_range(self, name, gt=0.0)
        for name in ("standstill_gap_m", "gap_gain_per_s2", "speed_gain_per_s",
                     "cruise_gain_per_s"):
            check_range(self, name, ge=0.0)


@dataclass(frozen=True, slots=True)
class PdFollowDiagnostics(StepDiagnostics):
    """What ``pd_follow`` reports each step (trace columns, Rerun /controller/<name>).

    lateral_target_m: the filtered lateral target y_r [m, left +];
    lateral_error_m: e_y = y − y_r [m]; curvature_cmd_1pm: κ_cmd [1/m];
    lead_gap_m: gap g to the obstacle followed [m] (NaN: none ahead in the lane);
    desired_gap_m: g* [m]; accel_cmd_mps2: the rate-limited acceleration a* [m/s²].
    """

    lateral_target_m: float = math.nan
    lateral_error_m: float = math.nan
    curvature_cmd_1pm: float = math.nan
    lead_gap_m: float = math.nan
    desired_gap_m: float = math.nan
    accel_cmd_mps2: float = math.nan


class PdFollowController:
    """One instance per run: ``reset`` once, then ``step`` every control period."""

    name = NAME
    diagnostics_type: ClassVar[type[StepDiagnostics]] = PdFollowDiagnostics

    def __init__(self, params: PdFollowParams | None = None) -> None:
        self.params = params if params is not None else PdFollowParams()
        # obstacles within 120 m ahead, moving traffic included: the follower needs them
        self.obstacle_policy: ObstaclePolicy | None = ObstaclePolicy(detection_distance_m=120.0)
        self._ctx: ScenarioContext | None = None
        self._path: FrenetPath | None = None
        self._s_hint = 0.0
        self._lat_target_m = 0.0
        self._accel_mps2 = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        self._path = context.reference_path()
        x, y = float(context.initial_state[0]), float(context.initial_state[1])
        s, d = self._path.project(x, y)
        self._s_hint = float(s)
        self._lat_target_m = float(d)
        self._accel_mps2 = 0.0

    def _lead(self, obs: Observation, s_m: float, y_m: float, lane_w: float
              ) -> tuple[float, float]:
        """(gap [m], speed along s [m/s]) of the nearest obstacle ahead in the lane."""
        o = obs.obstacles
        best_gap, best_speed = math.inf, math.nan
        for j in range(o.count):
            if abs(float(o.y_m[j]) - y_m) >= 0.5 * lane_w or float(o.s_m[j]) <= s_m:
                continue
            gap = float(o.s_m[j]) - s_m - float(o.semi_a_m[j])
            if gap < best_gap:
                best_gap, best_speed = gap, float(o.speed_s_mps[j])
        return best_gap, best_speed

    def step(self, observation: Observation) -> Command:
        if self._path is None or self._ctx is None:
            raise RuntimeError("PdFollowController.step called before reset")
        t0 = time.perf_counter()
        p, veh, dt = self.params, self._ctx.vehicle, self._ctx.control_period_s
        x, y, psi, u, v = (float(observation.state[i]) for i in range(5))
        speed = math.hypot(u, v)
        if observation.ego is not None:  # the loop's projection of the CG
            s, d, e_psi = (observation.ego.s_m, observation.ego.lat_m,
                           observation.ego.heading_err_rad)
        else:
            s_arr, d_arr, e_psi_arr = self._path.project_pose(x, y, psi, s_hint=self._s_hint)
            s, d, e_psi = float(s_arr), float(d_arr), float(e_psi_arr)
        self._s_hint = s
        # lateral: filtered target, PD on the error as a curvature command
        self._lat_target_m += (observation.lateral_reference_m - self._lat_target_m) * (
            dt / (p.lateral_tau_s + dt))
        e_y = d - self._lat_target_m
        e_y_dot = speed * math.sin(e_psi)
        a_y = -p.omega_radps ** 2 * e_y - 2.0 * p.zeta * p.omega_radps * e_y_dot
        kappa = float(self._path.kappa(s)) + a_y / max(speed, p.min_speed_mps) ** 2
        steer = min(max(math.atan(veh.wheelbase_m * kappa), -veh.max_steer_rad),
                    veh.max_steer_rad)
        # longitudinal: time-gap follower under the cruise law, jerk-limited
        gap, lead_speed = self._lead(observation, s, d, self._ctx.lane_width_m)
        desired = p.standstill_gap_m + p.time_gap_s * speed
        a_cruise = p.cruise_gain_per_s * (observation.target_speed_mps - speed)
        a_want = a_cruise
        if math.isfinite(gap):
            a_want = min(a_cruise, p.gap_gain_per_s2 * (gap - desired)
                         + p.speed_gain_per_s * (lead_speed - speed))
        a_want = min(max(a_want, -p.max_brake_mps2), p.max_accel_mps2)
        step = p.max_jerk_mps3 * dt
        self._accel_mps2 += min(max(a_want - self._accel_mps2, -step), step)
        torque = veh.mass_kg * veh.wheel_radius_m * self._accel_mps2
        elapsed = time.perf_counter() - t0
        diag = PdFollowDiagnostics(
            outer_s=elapsed, inner_s=0.0, lateral_target_m=self._lat_target_m,
            lateral_error_m=e_y, curvature_cmd_1pm=kappa,
            lead_gap_m=gap if math.isfinite(gap) else math.nan,
            desired_gap_m=desired if math.isfinite(gap) else math.nan,
            accel_cmd_mps2=self._accel_mps2)
        return Command(steer_rad=steer, torque_nm=torque, diagnostics=diag)

    def parameters(self) -> dict[str, Any]:
        """``{"name": "pd_follow", **parameters}``: accepted back by the factory."""
        return {"name": self.name, **to_dict(self.params)}


def make_pd_follow(options: Mapping[str, Any]) -> PdFollowController:
    """``pd_follow`` from catalog options; raises ConfigError naming a bad key."""
    opts = dict(options)
    given = opts.pop("name", NAME)
    if given != NAME:
        raise ConfigError("controller.name", f"{NAME!r}", given)
    return PdFollowController(build(PdFollowParams, opts))
