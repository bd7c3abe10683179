"""``lane_keep``: pure pursuit on the reference lane centreline + PI speed control.

It makes no attempt to avoid obstacles: it is the floor every other controller
must beat, and the fixture for "drives into a stalled car" tests.

Steering (pure pursuit about the rear axle, wheelbase L, look-ahead distance
L_d = clip(k_la * V, L_d,min, L_d,max)): with alpha the angle between the car's
heading and the line from the rear axle to the look-ahead point on the path,
    delta = atan(2 L sin(alpha) / L_d).
Speed: a = K_p (V_t - V) + K_i * integral(V_t - V) (clamped integral), and the
torque that yields it: T = R (m a + F_road(V)), F_road the drag and rolling resistance
the plant's car has at V (:func:`controllers.plant.vehicle_model.road_load_n`, fed
forward so that the set speed is held without a slow integral catching up), split over
both axles by the plant.
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
from controllers.plant.vehicle_model import road_load_n
from controllers.protocol import (
    Command,
    ConfigError,
    Observation,
    ScenarioContext,
    StepDiagnostics,
)

NAME = "lane_keep"


@dataclass(frozen=True)
class LaneKeepParams:
    """Pure pursuit and PI speed control (module docstring)."""

    lookahead_gain_s: float = param(0.6, "s", "k_la: look-ahead distance per unit speed")
    lookahead_min_m: float = param(6.0, "m", "shortest look-ahead distance")
    lookahead_max_m: float = param(40.0, "m", "longest look-ahead distance")
    speed_kp_per_s: float = param(0.8, "1/s", "K_p: speed error -> acceleration")
    speed_ki_per_s2: float = param(0.1, "1/s²", "K_i: integral of the speed error")
    integral_limit_mps: float = param(5.0, "m/s", "clamp of the speed-error integral")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("lookahead_gain_s", "speed_kp_per_s", "speed_ki_per_s2",
                     "integral_limit_mps"):
            check_range(self, name, ge=0.0)
        check_range(self, "lookahead_min_m", gt=0.0)
        check_range(self, "lookahead_max_m", ge=self.lookahead_min_m)


class LaneKeepController:
    """Pure pursuit on the reference lane; takes no obstacles (``obstacle_policy`` None)."""

    name = NAME
    diagnostics_type: ClassVar[type[StepDiagnostics]] = StepDiagnostics

    def __init__(self, params: LaneKeepParams | None = None) -> None:
        self.params = params if params is not None else LaneKeepParams()
        self.obstacle_policy: ObstaclePolicy | None = None
        self._path: FrenetPath | None = None
        self._ctx: ScenarioContext | None = None
        self._s_hint = 0.0
        self._integral = 0.0

    def reset(self, context: ScenarioContext) -> None:
        self._ctx = context
        self._path = context.reference_path()
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
        # Rear axle: pure pursuit's geometric centre. Its own projection, not the
        # loop's (observation.ego is the CG's: a different point, l_r behind it).
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
        torque = veh.wheel_radius_m * (veh.mass_kg * acc + road_load_n(veh, speed))
        elapsed = time.perf_counter() - t0
        return Command(steer_rad=steer, torque_nm=torque,
                       diagnostics=StepDiagnostics(outer_s=elapsed, inner_s=0.0))

    def parameters(self) -> dict[str, Any]:
        """``{"name": "lane_keep", **parameters}``: accepted back by the factory."""
        return {"name": self.name, **to_dict(self.params)}


def make_lane_keep(options: Mapping[str, Any]) -> LaneKeepController:
    """``lane_keep`` from catalog options; raises ConfigError naming the bad key."""
    opts = dict(options)
    given = opts.pop("name", NAME)
    if given != NAME:
        raise ConfigError("controller.name", f"{NAME!r}", given)
    return LaneKeepController(build(LaneKeepParams, opts))
