"""``pd_follow_module``: the example controller as a bare module for ``--plugin``.

    hwyeval run CATALOG --out DIR --plugin examples/hwyeval_example_controller/pd_follow_module.py

Importing this file registers ``pd_follow_bare``. The controller itself is written in
this file (a bare module is shipped to Ray workers as its source text, so it must not
import sibling files): a copy of the package's PD lane keeper with the time-gap
follower, with its own name so that both can be installed side by side.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from controllers import registry
from controllers.behaviour.types import ObstaclePolicy
from controllers.params import build, check_leaves, check_range, param, to_dict
from controllers.protocol import (
    Command,
    ConfigError,
    Observation,
    ScenarioContext,
    StepDiagnostics,
)

NAME = "pd_follow_bare"


@dataclass(frozen=True)
class BareParams:
    """Gains: ω [rad/s], ζ, time gap h [s], standstill gap [m], jerk limit [m/s³]."""

    omega_radps: float = param(0.7, "rad/s", "natural frequency of the lateral error")
    zeta: float = param(0.9, "-", "damping ratio of the lateral error")
    time_gap_s: float = param(1.6, "s", "time gap to the vehicle ahead")
    standstill_gap_m: float = param(4.0, "m", "gap kept at standstill")
    max_jerk_mps3: float = param(2.5, "m/s³", "acceleration rate limit")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("omega_radps", "zeta", "time_gap_s", "max_jerk_mps3"):
            check_range(self, name, gt=0.0)
        check_range(self, "standstill_gap_m", ge=0.0)


@dataclass(frozen=True, slots=True)
class BareDiagnostics(StepDiagnostics):
    """lateral_error_m [m]; lead_gap_m [m] (NaN: none); accel_cmd_mps2 [m/s²]."""

    lateral_error_m: float = math.nan
    lead_gap_m: float = math.nan
    accel_cmd_mps2: float = math.nan


class BarePdFollow:
    """PD lane keeping (curvature command) and a constant time-gap follower."""

    name = NAME
    diagnostics_type: ClassVar[type[StepDiagnostics]] = BareDiagnostics

    def __init__(self, params: BareParams) -> None:
        self.params = params
        self.obstacle_policy: ObstaclePolicy | None = ObstaclePolicy(detection_distance_m=120.0)
        self._ctx: ScenarioContext | None = None
        self._s = 0.0
        self._target = 0.0
        self._accel = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        s, d = context.reference_path().project(float(context.initial_state[0]),
                                                float(context.initial_state[1]))
        self._s, self._target, self._accel = float(s), float(d), 0.0

    def step(self, observation: Observation) -> Command:
        if self._ctx is None:
            raise RuntimeError("step before reset")
        t0 = time.perf_counter()
        p, ctx = self.params, self._ctx
        veh, dt, path = ctx.vehicle, ctx.control_period_s, ctx.reference_path()
        x, y, psi, u, v = (float(observation.state[i]) for i in range(5))
        speed = math.hypot(u, v)
        if observation.ego is not None:  # the loop's projection of the CG
            s, d, e_psi = (observation.ego.s_m, observation.ego.lat_m,
                           observation.ego.heading_err_rad)
        else:
            s_a, d_a, e_a = path.project_pose(x, y, psi, s_hint=self._s)
            s, d, e_psi = float(s_a), float(d_a), float(e_a)
        self._s = s
        self._target += (observation.lateral_reference_m - self._target) * dt / (1.2 + dt)
        e_y = d - self._target
        a_y = -p.omega_radps ** 2 * e_y - 2 * p.zeta * p.omega_radps * speed * math.sin(e_psi)
        kappa = float(path.kappa(s)) + a_y / max(speed, 3.0) ** 2
        steer = min(max(math.atan(veh.wheelbase_m * kappa), -veh.max_steer_rad),
                    veh.max_steer_rad)
        o, gap, lead_v = observation.obstacles, math.inf, math.nan
        for j in range(o.count):
            if abs(float(o.y_m[j]) - d) < 0.5 * ctx.lane_width_m and float(o.s_m[j]) > s:
                g = float(o.s_m[j]) - s - float(o.semi_a_m[j])
                if g < gap:
                    gap, lead_v = g, float(o.speed_s_mps[j])
        want = 0.4 * (observation.target_speed_mps - speed)
        if math.isfinite(gap):
            desired = p.standstill_gap_m + p.time_gap_s * speed
            want = min(want, 0.12 * (gap - desired) + 0.5 * (lead_v - speed))
        want = min(max(want, -3.5), 1.5)
        self._accel += min(max(want - self._accel, -p.max_jerk_mps3 * dt), p.max_jerk_mps3 * dt)
        diag = BareDiagnostics(outer_s=time.perf_counter() - t0, inner_s=0.0,
                               lateral_error_m=e_y,
                               lead_gap_m=gap if math.isfinite(gap) else math.nan,
                               accel_cmd_mps2=self._accel)
        return Command(steer_rad=steer, torque_nm=veh.mass_kg * veh.wheel_radius_m * self._accel,
                       diagnostics=diag)

    def parameters(self) -> dict[str, Any]:
        return {"name": self.name, **to_dict(self.params)}


def make(options: Mapping[str, Any]) -> BarePdFollow:
    opts = dict(options)
    given = opts.pop("name", NAME)
    if given != NAME:
        raise ConfigError("controller.name", f"{NAME!r}", given)
    return BarePdFollow(build(BareParams, opts))


registry.register(NAME, make, BareParams)
