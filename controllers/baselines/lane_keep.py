"""``lane_keep``: pure pursuit on the reference lane centreline + PI speed control.

It makes no attempt to avoid obstacles: it is the floor every other controller
must beat, and the fixture for "drives into a stalled car" tests.

Steering (pure pursuit about the rear axle, wheelbase L, look-ahead distance
L_d = clip(k_la * V, L_d,min, L_d,max)): with alpha the angle between the car's
heading and the line from the rear axle to the look-ahead point on the path,
    delta = atan(2 L sin(alpha) / L_d).
Speed: a = K_p (V_t - V) + K_i * integral(V_t - V) (clamped integral), and the
torque that yields it on the drag-free STVM: T = m R a (split over both axles
by the plant).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from controllers.path.frenet import FrenetPath
from controllers.protocol import Command, ConfigError, Observation, ScenarioContext
from controllers.registry import check_options


@dataclass(frozen=True)
class LaneKeepParams:
    lookahead_gain_s: float = 0.6
    lookahead_min_m: float = 6.0
    lookahead_max_m: float = 40.0
    speed_kp_per_s: float = 0.8
    speed_ki_per_s2: float = 0.1
    integral_limit_mps: float = 5.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(
                    f"LaneKeepParams.{name} must be a finite number >= 0, got {value!r}")
        if self.lookahead_min_m <= 0 or self.lookahead_max_m < self.lookahead_min_m:
            raise ValueError("LaneKeepParams: need 0 < lookahead_min_m <= lookahead_max_m")


class LaneKeepController:
    name = "lane_keep"
    simulated_by_sumo = False
    obstacle_policy = None

    def __init__(self, params: LaneKeepParams) -> None:
        self.params = params
        self._path: FrenetPath | None = None
        self._ctx: ScenarioContext | None = None
        self._s_hint = 0.0
        self._integral = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        self._path = FrenetPath.cached(np.asarray(context.reference_xy_m, dtype=np.float64))
        x, y = float(context.initial_state[0]), float(context.initial_state[1])
        s, _ = self._path.project(x, y)
        self._s_hint = float(s)
        self._integral = 0.0

    def step(self, observation: Observation) -> Command:
        if self._path is None or self._ctx is None:
            raise RuntimeError("LaneKeepController.step called before reset")
        t0 = time.perf_counter()
        p = self.params
        veh = self._ctx.vehicle
        x, y, psi, u, v = (float(observation.state[i]) for i in range(5))
        speed = math.hypot(u, v)
        # Rear axle: pure pursuit's geometric centre.
        rx = x - veh.cg_to_rear_axle_m * math.cos(psi)
        ry = y - veh.cg_to_rear_axle_m * math.sin(psi)
        s, _ = self._path.project(rx, ry, s_hint=self._s_hint)
        self._s_hint = float(s)
        ld = min(max(p.lookahead_gain_s * speed, p.lookahead_min_m), p.lookahead_max_m)
        tx, ty = self._path.point(float(s) + ld)
        alpha = math.atan2(float(ty) - ry, float(tx) - rx) - psi
        alpha = math.atan2(math.sin(alpha), math.cos(alpha))
        dist = max(math.hypot(float(tx) - rx, float(ty) - ry), 1e-3)
        steer = math.atan2(2.0 * veh.wheelbase_m * math.sin(alpha), dist)
        dt = self._ctx.control_period_s
        err = observation.target_speed_mps - speed
        self._integral = min(max(self._integral + err * dt, -p.integral_limit_mps),
                             p.integral_limit_mps)
        acc = p.speed_kp_per_s * err + p.speed_ki_per_s2 * self._integral
        torque = veh.mass_kg * veh.wheel_radius_m * acc
        elapsed = time.perf_counter() - t0
        return Command(steer_rad=steer, torque_nm=torque,
                       diagnostics={"outer_s": elapsed, "inner_s": 0.0})

    def parameters(self) -> Mapping[str, Any]:
        return {"controller": self.name, **asdict(self.params)}


def make_lane_keep(options: Mapping[str, Any]) -> LaneKeepController:
    check_options(options, {k: (int, float) for k in LaneKeepParams.__dataclass_fields__})
    try:
        params = LaneKeepParams(**{k: float(v) for k, v in options.items()})
    except ValueError as exc:
        raise ConfigError("controller", "valid lane_keep parameters", str(exc)) from exc
    return LaneKeepController(params)
