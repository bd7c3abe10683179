"""The paper's two-loop controller (METHOD.md §1): SPMM NLMPC outer loop + preview inner loop.

Per control period (``step``):

1. measured state -> Frenet x0 = (s, y, theta_a) (projection with the previous s
   as hint; theta_a = psi + atan2(v, u) unwrapped next to gamma(s));
2. outer loop (C/GMRES by default, ``outer = "cgmres"``; any
   :class:`controllers.two_loop.outer.protocol.OuterSolver` via ``outer_factory``):
   ``sub_updates`` continuation updates ending at the current state;
   The runner's lateral reference (``Observation.lateral_reference_m``, a step to
   the neighbour lane's centre while passing, back to 0 afterwards) is smoothed
   before it reaches the OCP's Cy (y - yr)² (see "Lateral reference" below);
3. inner loop (``controllers.two_loop.preview``): conversion (13)(14) + feed-forward,
   STVM preview of Np steps, corrections (38)(39), sum (40)(41);
4. a non-finite command (never expected) is replaced by lane-keeping braking and
   flagged as a fallback.

Lateral reference
-----------------
C/GMRES tracks a *moving* optimum: a step in a parameter is a step in the residual F
(E spikes, and the first plans after it are far from optimal). The runner's step
r_raw(t) is therefore shaped in two stages, updated every control period:

1. rate limiter: r(t) moves toward r_raw at most min(``lateral_ref_rate_mps``,
   V ``lateral_ref_heading_rad``) [m/s] (3.5 m in 2.3 s at the default 1.5 m/s; V
   the measured speed: a car slower than 15 m/s cannot follow that rate with a
   sensible heading, and at standstill -- stopped behind a stalled car until the
   neighbour lane clears -- a moving reference made E grow to the fallback level
   in SUMO's dense-traffic curve and the restart jerked); with C/GMRES, also times
   the horizon's relative length 1 - exp(-horizon_growth_rate t) after the first
   step (a reference set at the very first step on the R = 400 m curve at 30 m/s
   peaked at 4.3 m/s² with the short early horizon);
2. critically damped second-order filter with time constant T_f =
   ``lateral_ref_filter_s`` [s]:  yr'' = (r - yr)/T_f² - 2 yr'/T_f.

yr, yr' and yr'' are continuous (a ramp into this filter has yr'' = v t e^(-t/T_f)/T_f²
at its start, peak v/(e T_f) ≈ 2.8 m/s² at the defaults (1.5 m/s, 0.2 s), and the
same at its end; the delay is 2 T_f = 0.4 s). The OCP smooths further (the car's
peak lateral acceleration from the lane change alone was ~1.5 m/s² at 20-30 m/s).
Tuning (plant-only passes at 20/25/30 m/s, straight and R = 400 m, and SUMO's
acceptance catalog): a slower ramp (1.2 m/s, T_f 0.4 s) left the car 0.6 m short
of the target lane when the reference was reset 15 m past the car at 30 m/s, and
1.3 m/s left the S-curve return 0.32 m off at the end of its run; faster ones
(2.5 m/s) overshot the target lane and took the curve case over 4 m/s².
A change of r_raw mid-transition (e.g. the pass is aborted) just
redirects the ramp, continuity is kept. T_f = 0 gives the rate limiter alone
(yr' steps). The filter is integrated with semi-implicit Euler sub-steps <= T_f/10.
yr starts at the measured lateral offset, at rest (a reference already set at the
first step is then approached like any step). yr is handed to the outer solver
(C/GMRES moves it linearly between consecutive updates, inside its F_t term) and
logged as ``lateral_ref_m`` (yr' as ``lateral_ref_rate_mps``).

Weight schedule: Cy = c_y + (c_y_lateral_ref - c_y) (1 - cos(pi phi))/2 (C¹ in time:
a kink in Cy(t) left E ~ 0.17 when the blend ended), phi in [0, 1] ramping
linearly over ``lateral_weight_time_s`` toward 1 while a lateral reference is
engaged and toward 0 otherwise (logged as ``lateral_weight``). Engaged: from
r_raw != 0 until, after r_raw is back at 0, both yr and the car are on it (within
5 cm and 10 cm): dropping the weight while the car still lagged 0.7 m behind yr
made the end of the return slow (SUMO, S-curve at 20 m/s). Why: the log barrier
pushes the plan away from an obstacle with a force ~ Cz/distance even when it is
well clear; with the paper's Cy = 1 that push sets the car ~0.5-1.3 m beyond the
target lane while passing, so the reference needs a stiff weight (20). But with
no reference (r_raw = 0: obstacles the runner does not ask to pass, follow mode,
the paper's scenarios) the barrier alone must be able to move the car out of the
lane: with Cy = 20 everywhere it cannot (the plant hit the stalled car in our
tests). Cy moves continuously and C/GMRES carries its rate in F_t like yr's.

A non-finite r_raw holds the previous one.

Launch (low speed / standstill)
-------------------------------
The SPMM's input V multiplies every lateral term (df/dtheta ~ V), so at V = 0 heading
and lateral motion are uncontrollable and F_U is singular. Stopped behind a stalled
car with the target raised again (the runner found a free side), C/GMRES planned
*negative* speeds (the barrier of the ellipse a few metres ahead pushes the plan
back, and the OCP target is still ~0 at the start of its ramp), the car could not
follow, E grew to 15-40 with a braking torque, and when it broke loose the torque
saturated (6.3 m/s², 28 m/s³ in SUMO). Measured on the plant: even a fresh C/GMRES
start at 0.5-3 m/s from 8 m behind the car (where the follow profile stops it) ends
in fallbacks and contact; from 23 m behind it passes. So the outer plan is not used
from standstill until the car is moving and clear of the obstacle's ellipse:

* engage (``launch`` on): speed < ``launch_engage_speed_mps``, target above
  ``launch_speed_mps``, and either the lane ahead is free of ellipses for
  ``launch_handover_free_m`` or the lateral reference asks for a pull-out (|yr_raw - y|
  > 0.5 m). Stopped in follow mode (lane blocked, no side free) it does not engage:
  C/GMRES holds the car (E ~ 0 there, as before).
* launch law: a :class:`TargetSpeedRamp` (same accel/decel/jerk limits as the OCP's)
  towards min(target, ``launch_max_speed_mps``, sqrt(2 ``launch_guard_decel_mps2``
  (d - ``launch_clearance_m``))), torque = m R a_ramp + ``launch_k_pv`` (V_ramp - V).
  d is the free distance along the steering direction to the nearest obstacle's
  box-sum rectangle (the CG positions where the two boxes touch, recovered from
  the ellipse by inverting ``obstacle_geometry.ellipse_semi_axes``) grown by
  ``launch_clearance_m``; without a pull-out also to the OCP's ellipse itself.
  Steering: pure pursuit of the raw lateral reference (the lane centre, or the pass
  lane's) at ``launch_lookahead_m``, heading offset at most ``launch_max_heading_rad``:
  delta = (L + K_us V²) kappa + ``launch_k_heading`` (gamma + h - psi), scaled by
  min(V / ``launch_steer_speed_mps``, 1) (no steering at standstill: the linear-tyre
  STVM slides sideways when steered at u = 0). With no pull-out this holds the lane.
  Target below ``launch_hold_target_mps``: the ramp brakes to 0 and the brakes hold
  (-m R ``launch_hold_decel_mps2``).
* hand-over: speed >= ``launch_speed_mps`` and the lane ahead at the car's offset
  free of ellipses for ``launch_handover_free_m``: C/GMRES restarts at the measured
  state (growing horizon from 0, E ~ 0; ``CgmresOuter.restart`` keeps the ramp's speed
  *and* acceleration), the lateral-reference shaper restarts at the car's offset, the
  preview integral is cleared, and the command blends from the launch law to the
  two-loop one over ``launch_blend_s`` (C¹ smoothstep): no torque or steering step.
* diagnostics: ``launch`` (0/1), ``launch_weight`` (1 in launch, easing to 0),
  ``launch_ramp_speed_mps``; in launch mode ``residual`` is 0 (nothing solved) and
  ``outer_updates`` 0. Above ``launch_engage_speed_mps`` nothing of this runs (the
  cruising step is the paper's controller, unchanged).

Figures (plant, follow profile to a stop 8 m behind a stalled car, side free at t = 20
s, target 22 m/s; tests/test_two_loop_launch.py): straight / R = 400 m curve: long acc
[-0.96, 1.82] / [-1.72, 1.85] m/s², SG jerk 3.2 / 2.7 m/s³, lat acc 0.5 / 1.2 m/s², no
contact, no fallback, E <= 0.55 after the hand-over (at 2.6 / 1.8 m/s, 4.2 / 4.4 s after
the side freed), 22 / 21.8 m/s at t = 40 s, within 0.01 m of the pass lane. Without
the launch: long acc -10..7.3 m/s², jerk 48 m/s³, 249 fallback steps, contact.

All parameters live in :class:`TwoLoopParams` (flat, with units), validated in
``__post_init__``; :func:`make_two_loop` builds a controller from flat catalog
options and raises :class:`ConfigError` naming the bad key.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, fields
from typing import Any

import numpy as np

from controllers.path.frenet import FrenetPath, _points_many, path_gamma, path_project_local
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import (
    Command,
    ConfigError,
    Observation,
    ObstaclePolicy,
    Obstacles,
    ScenarioContext,
)
from controllers.registry import check_options
from controllers.two_loop.outer.ocp import COSTS, OuterParams, TargetSpeedRamp
from controllers.two_loop.outer.protocol import OuterPlan, OuterSolver
from controllers.two_loop.preview import inner_step

OuterFactory = Callable[[FrenetPath, OuterParams], OuterSolver]
OUTERS = ("cgmres", "ipopt")


# One source of truth for the defaults: the outer loop's and the obstacle policy's
# own dataclasses (the flat fields below exist so that catalogs can set any of them).
_OUTER_DEFAULTS = OuterParams()
_POLICY_DEFAULTS = ObstaclePolicy()

@dataclass(frozen=True)
class TwoLoopParams:
    """Every parameter of the two-loop controller, flat, with units.

    Outer loop (see :class:`controllers.two_loop.outer.ocp.OuterParams` for the maths):
      outer: 'cgmres' | 'ipopt'; cost: 'J1' | 'J2' | 'J3'; horizon_s [s]; n_stages;
      chebyshev (stage spacing); k_max; zeta_s [1/s] continuation gain; fd_step [-];
      sub_updates per control period; c_z [1/s], zeta [-] barrier; c_y [1/(m² s)],
      c_ydot [s/m²], c_sdot [s/m²], c_thetadot [s/rad²], c_theta [1/(rad² s)],
      c_v [s/m²]; c_y_terminal [1/m²], c_e_terminal [1/rad²]; horizon_growth_rate
      [1/s]; target_accel_mps2, target_decel_mps2, target_jerk_mps3 (OCP target-speed ramp);
      z_guard [-]; obstacle_fade_s [s]; row_scaling (on/off); fallback_residual [-],
      fallback_decel_mps2, fallback_hold_s [s].
    Inner loop (see ``controllers.two_loop.preview``):
      preview (on/off), n_preview (Np), preview_dt_s [s], lookahead_s [s];
      k_ps [rad/rad], k_pv [N m s/m], k_pvc [N m/m], k_psc [rad/m],
      k_isc [rad/(m s)], integral_limit_ms [m s]; feedforward (on/off).
    Lateral reference (see module docstring): lateral_ref_rate_mps [m/s] (> 0) rate
      limit of the runner's step, lateral_ref_filter_s [s] (>= 0) time constant of the
      critically damped second-order filter after it; lateral_ref_heading_rad
      [rad] (> 0) the rate limit is at most V times it; c_y_lateral_ref [1/(m² s)]
      (>= 0) Cy while a lateral reference is engaged, lateral_weight_time_s [s] (> 0)
      its blend time from/to c_y.
    Launch (see "Launch" in the module docstring): launch (on/off); launch_speed_mps
      [m/s] hand-over speed (> launch_engage_speed_mps [m/s], the standstill threshold
      below which it may engage); launch_max_speed_mps [m/s] (>= launch_speed_mps)
      speed cap until the hand-over; launch_blend_s [s] (> 0) hand-over blend;
      launch_k_pv [N m s/m] speed-error gain; launch_k_heading [rad/rad],
      launch_lookahead_m [m], launch_max_heading_rad [rad] pure pursuit;
      launch_steer_speed_mps [m/s] steering fades in up to it; launch_clearance_m [m]
      (>= 0) grown box-sum rectangle; launch_guard_decel_mps2 [m/s²] speed cap from
      the free distance; launch_handover_free_m [m] (>= 0) free lane ahead needed to
      engage without a pull-out and to hand over; launch_hold_target_mps [m/s]
      (< launch_speed_mps) target treated as "stop"; launch_hold_decel_mps2 [m/s²]
      holding brake (as -m R times it).
    Obstacle policy (``obstacle_policy``): detection_distance_m (100 m: at 80 m and
      30 m/s the horizon's end, 72 m ahead, was already inside a stalled car's ellipse
      (A ≈ 10.5 m) when it entered the problem: E jumped to 5-20 and the car braked),
      rear_range_m,
      margin_long_m, margin_lat_m, offset_m, max_obstacles (= OCP slots),
      moving_obstacles.
    """

    outer: str = "cgmres"
    cost: str = "J3"
    horizon_s: float = _OUTER_DEFAULTS.horizon_s
    n_stages: int = _OUTER_DEFAULTS.n_stages
    chebyshev: bool = _OUTER_DEFAULTS.chebyshev
    k_max: int = _OUTER_DEFAULTS.k_max
    zeta_s: float = _OUTER_DEFAULTS.zeta_s
    fd_step: float = _OUTER_DEFAULTS.fd_step
    sub_updates: int = _OUTER_DEFAULTS.sub_updates
    c_z: float = _OUTER_DEFAULTS.c_z
    zeta: float = _OUTER_DEFAULTS.zeta
    c_y: float = _OUTER_DEFAULTS.c_y
    c_ydot: float = _OUTER_DEFAULTS.c_ydot
    c_sdot: float = _OUTER_DEFAULTS.c_sdot
    c_thetadot: float = _OUTER_DEFAULTS.c_thetadot
    c_theta: float = _OUTER_DEFAULTS.c_theta
    c_v: float = _OUTER_DEFAULTS.c_v
    c_y_terminal: float = _OUTER_DEFAULTS.c_y_terminal
    c_e_terminal: float = _OUTER_DEFAULTS.c_e_terminal
    horizon_growth_rate: float = _OUTER_DEFAULTS.horizon_growth_rate
    target_accel_mps2: float = _OUTER_DEFAULTS.target_accel_mps2
    target_decel_mps2: float = _OUTER_DEFAULTS.target_decel_mps2
    target_jerk_mps3: float = _OUTER_DEFAULTS.target_jerk_mps3
    z_guard: float = _OUTER_DEFAULTS.z_guard
    obstacle_fade_s: float = _OUTER_DEFAULTS.obstacle_fade_s
    row_scaling: bool = _OUTER_DEFAULTS.row_scaling
    fallback_residual: float = _OUTER_DEFAULTS.fallback_residual
    fallback_decel_mps2: float = _OUTER_DEFAULTS.fallback_decel_mps2
    fallback_hold_s: float = _OUTER_DEFAULTS.fallback_hold_s
    preview: bool = True
    n_preview: int = 10
    preview_dt_s: float = 0.05
    lookahead_s: float = 0.15
    k_ps: float = 1.0
    k_pv: float = 1500.0
    k_pvc: float = 500.0
    k_psc: float = 0.1
    k_isc: float = 0.05
    integral_limit_ms: float = 5.0
    feedforward: bool = True
    lateral_ref_rate_mps: float = 1.5
    lateral_ref_filter_s: float = 0.2
    lateral_ref_heading_rad: float = 0.1
    c_y_lateral_ref: float = 20.0
    lateral_weight_time_s: float = 1.0
    detection_distance_m: float = _POLICY_DEFAULTS.detection_distance_m
    rear_range_m: float = _POLICY_DEFAULTS.rear_range_m
    margin_long_m: float = _POLICY_DEFAULTS.margin_long_m
    margin_lat_m: float = _POLICY_DEFAULTS.margin_lat_m
    offset_m: float = _POLICY_DEFAULTS.offset_m
    max_obstacles: int = _POLICY_DEFAULTS.max_obstacles
    moving_obstacles: bool = _POLICY_DEFAULTS.moving_obstacles
    launch: bool = True
    launch_speed_mps: float = 1.5
    launch_engage_speed_mps: float = 0.5
    launch_blend_s: float = 0.6
    launch_k_pv: float = 1500.0
    launch_max_speed_mps: float = 3.0
    launch_k_heading: float = 1.0
    launch_lookahead_m: float = 6.0
    launch_max_heading_rad: float = 0.35
    launch_steer_speed_mps: float = 1.0
    launch_clearance_m: float = 0.3
    launch_guard_decel_mps2: float = 1.0
    launch_handover_free_m: float = 20.0
    launch_hold_target_mps: float = 0.3
    launch_hold_decel_mps2: float = 1.0

    def __post_init__(self) -> None:
        def bad(key: str, expected: str) -> ConfigError:
            return ConfigError(f"controller.{key}", expected, getattr(self, key))

        if self.outer not in OUTERS:
            raise bad("outer", f"one of {OUTERS}")
        if self.cost not in COSTS:
            raise bad("cost", f"one of {COSTS}")
        for f in fields(self):
            v = getattr(self, f.name)
            if f.type in ("float",) and not (isinstance(v, int | float)
                                             and not isinstance(v, bool) and math.isfinite(v)):
                raise bad(f.name, "a finite number")
            if f.type == "int" and not (isinstance(v, int) and not isinstance(v, bool)):
                raise bad(f.name, "an integer")
            if f.type == "bool" and not isinstance(v, bool):
                raise bad(f.name, "true or false")
        positive = ("horizon_s", "zeta_s", "fd_step", "c_z", "zeta", "preview_dt_s",
                    "horizon_growth_rate", "target_accel_mps2", "target_decel_mps2",
                    "target_jerk_mps3", "z_guard",
                    "fallback_residual", "fallback_decel_mps2", "k_ps", "obstacle_fade_s",
                    "lateral_ref_rate_mps", "lateral_weight_time_s", "lateral_ref_heading_rad",
                    "launch_speed_mps", "launch_engage_speed_mps", "launch_blend_s",
                    "launch_steer_speed_mps", "launch_max_speed_mps", "launch_lookahead_m",
                    "launch_max_heading_rad", "launch_guard_decel_mps2")
        for key in positive:
            if not getattr(self, key) > 0:
                raise bad(key, "a number > 0")
        nonneg = ("c_y", "c_ydot", "c_sdot", "c_thetadot", "c_theta", "c_v", "c_y_terminal",
                  "c_e_terminal", "fallback_hold_s", "lookahead_s", "k_pv", "k_pvc", "k_psc",
                  "k_isc", "integral_limit_ms", "detection_distance_m", "rear_range_m",
                  "margin_long_m", "margin_lat_m", "offset_m", "lateral_ref_filter_s",
                  "c_y_lateral_ref", "launch_k_pv", "launch_k_heading",
                  "launch_hold_target_mps", "launch_hold_decel_mps2", "launch_clearance_m",
                  "launch_handover_free_m")
        for key in nonneg:
            if not getattr(self, key) >= 0:
                raise bad(key, "a number >= 0")
        for key, lo, hi in (("n_stages", 2, 400), ("k_max", 1, 200), ("sub_updates", 1, 100),
                            ("n_preview", 1, 1000), ("max_obstacles", 0, 16)):
            v = getattr(self, key)
            if not lo <= v <= hi:
                raise bad(key, f"an integer in [{lo}, {hi}]")
        if self.fd_step >= 1e-2:
            raise bad("fd_step", "a number in (0, 0.01)")
        if self.z_guard >= self.zeta:
            raise bad("z_guard", f"a number < zeta = {self.zeta}")
        if self.lookahead_s > self.horizon_s:
            raise bad("lookahead_s", "a number <= horizon_s")
        if self.n_preview * self.preview_dt_s > self.horizon_s:
            raise bad("n_preview", "n_preview * preview_dt_s <= horizon_s")
        if self.launch_engage_speed_mps >= self.launch_speed_mps:
            raise bad("launch_engage_speed_mps", f"a number < launch_speed_mps = "
                      f"{self.launch_speed_mps}")
        if self.launch_max_speed_mps < self.launch_speed_mps:
            raise bad("launch_max_speed_mps", f"a number >= launch_speed_mps = "
                      f"{self.launch_speed_mps}")
        if self.launch_hold_target_mps >= self.launch_speed_mps:
            raise bad("launch_hold_target_mps", f"a number < launch_speed_mps = "
                      f"{self.launch_speed_mps}")
        try:
            self.outer_params()
        except ValueError as exc:  # a cost-specific weight is zero
            raise ConfigError("controller.cost", "weights valid for this cost", str(exc)) from exc

    def outer_params(self) -> OuterParams:
        return OuterParams(
            cost=self.cost, horizon_s=self.horizon_s, n_stages=self.n_stages,
            chebyshev=self.chebyshev, n_obstacles=self.max_obstacles, c_y=self.c_y,
            c_ydot=self.c_ydot, c_sdot=self.c_sdot, c_thetadot=self.c_thetadot,
            c_theta=self.c_theta, c_v=self.c_v, c_z=self.c_z, zeta=self.zeta,
            c_y_terminal=self.c_y_terminal, c_e_terminal=self.c_e_terminal, k_max=self.k_max,
            zeta_s=self.zeta_s, fd_step=self.fd_step, sub_updates=self.sub_updates,
            horizon_growth_rate=self.horizon_growth_rate,
            target_accel_mps2=self.target_accel_mps2, target_decel_mps2=self.target_decel_mps2,
            target_jerk_mps3=self.target_jerk_mps3,
            z_guard=self.z_guard, obstacle_fade_s=self.obstacle_fade_s,
            row_scaling=self.row_scaling, fallback_residual=self.fallback_residual,
            fallback_decel_mps2=self.fallback_decel_mps2, fallback_hold_s=self.fallback_hold_s)

    @property
    def obstacle_policy(self) -> ObstaclePolicy:
        return ObstaclePolicy(
            detection_distance_m=self.detection_distance_m, rear_range_m=self.rear_range_m,
            margin_long_m=self.margin_long_m, margin_lat_m=self.margin_lat_m,
            offset_m=self.offset_m, max_obstacles=self.max_obstacles,
            moving_obstacles=self.moving_obstacles)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


_KINDS: dict[str, type | tuple[type, ...]] = {"float": (int, float), "int": int, "bool": bool,
                                              "str": str}
_OPTION_TYPES: dict[str, type | tuple[type, ...]] = {}
for _f in fields(TwoLoopParams):
    _OPTION_TYPES[_f.name] = _KINDS[str(_f.type)]
_OPTION_TYPES["name"] = str


def make_two_loop(options: Mapping[str, Any]) -> TwoLoopController:
    """Validate flat options (cheap, no compilation) and build the controller."""
    check_options(options, _OPTION_TYPES)
    opts = dict(options)
    name = opts.pop("name", "two_loop")
    if name != "two_loop":
        raise ConfigError("controller.name", "'two_loop'", name)
    params = TwoLoopParams(**opts)
    return TwoLoopController(params)


def _default_outer_factory(outer: str) -> OuterFactory:
    if outer == "cgmres":
        from controllers.two_loop.outer.cgmres import CgmresOuter

        return CgmresOuter
    from controllers.two_loop.outer.ipopt import IpoptOuter  # type: ignore[import-not-found]

    return IpoptOuter  # type: ignore[no-any-return]


class TwoLoopController:
    """Controller protocol implementation; see module docstring."""

    name = "two_loop"
    simulated_by_sumo = False

    def __init__(self, params: TwoLoopParams | None = None,
                 outer_factory: OuterFactory | None = None) -> None:
        self.params = params or TwoLoopParams()
        self.obstacle_policy: ObstaclePolicy = self.params.obstacle_policy
        self.outer_params = self.params.outer_params()
        self._outer_factory = outer_factory
        self.path: FrenetPath | None = None
        self.outer: OuterSolver | None = None
        self._context: ScenarioContext | None = None
        self._s_hint = 0.0
        self._integral = 0.0
        self._t_prev: float | None = None
        self.plan: OuterPlan | None = None
        # Lateral reference shaping: [raw target, ramp r, yr, yr', weight blend phi,
        # engaged flag] (NaN: not started).
        self._yref = np.full(6, np.nan)
        self._t_first = 0.0
        self._init_launch_state()

    def _init_launch_state(self) -> None:
        p = self.params
        self._launch_ramp = TargetSpeedRamp(p.target_accel_mps2, p.target_decel_mps2,
                                            p.target_jerk_mps3)
        self._launch_active = False
        self._launch_t_handover = -math.inf
        self._last_torque = 0.0
        self.launch_count = 0

    # ----------------------------------------------------------------- protocol
    def reset(self, context: ScenarioContext) -> None:
        p = self.params
        self._context = context
        self.path = FrenetPath.cached(context.reference_xy_m)
        factory = self._outer_factory or _default_outer_factory(p.outer)
        self.outer = factory(self.path, self.outer_params)
        vp: VehicleParams = context.vehicle
        self._vp = vp.as_array()
        self._limits = np.array([vp.max_steer_rad, vp.max_drive_torque_nm,
                                 vp.max_brake_torque_nm])
        self._gains = np.array([p.k_ps, p.k_pv, p.k_pvc, p.k_psc, p.k_isc,
                                1.0 if p.feedforward else 0.0, p.lookahead_s,
                                vp.understeer_gradient_rad_per_mps2])
        self._dt = context.control_period_s
        self._preview_xy = np.zeros((p.n_preview + 1, 2))
        self._inner_out = np.zeros(6)
        st = np.asarray(context.initial_state, dtype=np.float64)
        s, _ = self.path.project(st[0], st[1])
        self._s_hint = float(s)
        x0 = self._frenet_state(st)
        v0 = float(math.hypot(st[3], st[4]))
        self.outer.reset(x0, min(v0, context.target_speed_mps) if v0 > 0 else 0.0)
        self._integral = 0.0
        self._t_prev = None
        self.plan = None
        self._yref[:] = np.nan
        self._init_launch_state()
        # Load the inner loop's compiled kernels now rather than in the first step.
        meta, coef, knots = self.path.tables()
        n = self.outer_params.n_stages
        dummy_states = np.zeros((n + 1, 3))
        dummy_states[:, 0] = np.linspace(0.0, 1.0, n + 1)
        inner_step(st, np.linspace(0.0, 1.0, n + 1), dummy_states, np.ones(n), self._gains,
                   self._vp, self._limits, 1, 0.01, meta, coef, knots,
                   np.zeros((2, 2)), np.zeros(6))
        _points_many(meta, coef, knots, np.zeros(1), np.zeros(1), np.zeros((1, 2)))

    def _frenet_state(self, st: np.ndarray) -> np.ndarray:
        """Measured state -> Frenet x0 = (s, y, theta_a) with theta_a next to gamma(s)."""
        if self.path is None:
            raise RuntimeError("TwoLoopController used before reset")
        meta, coef, knots = self.path.tables()
        s, d, ok = path_project_local(meta, coef, knots, float(st[0]), float(st[1]),
                                      self._s_hint)
        if not ok or abs(s - self._s_hint) > 50.0:
            s_arr, d_arr = self.path.project(st[0], st[1])
            s, d = float(s_arr), float(d_arr)
        self._s_hint = s
        u, v = float(st[3]), float(st[4])
        speed = math.hypot(u, v)
        tha = float(st[2]) + (math.atan2(v, u) if speed > 0.5 else 0.0)
        g, _, _ = path_gamma(meta, coef, s)
        e = (tha - g + math.pi) % (2.0 * math.pi) - math.pi
        return np.array([s, d, g + e])

    def step(self, observation: Observation) -> Command:
        if self.path is None or self.outer is None:
            raise RuntimeError("TwoLoopController.step called before reset")
        p = self.params
        t_outer0 = time.perf_counter()
        st = np.asarray(observation.state, dtype=np.float64)
        x0 = self._frenet_state(st)
        dt = self._dt if self._t_prev is None else max(observation.t_s - self._t_prev, 1e-6)
        if self._t_prev is None:
            self._t_first = float(observation.t_s)
        speed = math.hypot(float(st[3]), float(st[4]))
        y_ref = self._lateral_reference(float(observation.lateral_reference_m),
                                        None if self._t_prev is None else dt, float(x0[1]),
                                        speed, float(observation.t_s) - self._t_first)
        blend = 0.5 * (1.0 - math.cos(math.pi * float(self._yref[4])))  # C¹ in time
        c_y = p.c_y + (p.c_y_lateral_ref - p.c_y) * blend
        t_s = float(observation.t_s)
        vt_obs = float(observation.target_speed_mps)
        if p.launch and (self._launch_active or speed < p.launch_engage_speed_mps):
            # (at speed nothing to do: keeps the cruising step as it was)
            free_m = self._free_distance(float(x0[0]), float(x0[1]), observation.obstacles)
            self._launch_transition(t_s, x0, speed, vt_obs, free_m,
                                    float(observation.lateral_reference_m))
        # Launch weight: 1 in launch mode, easing to 0 over launch_blend_s after the
        # hand-over (C¹ smoothstep), 0 otherwise.
        lw = 0.0
        if self._launch_active:
            lw = 1.0
        elif t_s - self._launch_t_handover < p.launch_blend_s:
            phi = min(max((t_s - self._launch_t_handover) / p.launch_blend_s, 0.0), 1.0)
            lw = 1.0 - phi * phi * (3.0 - 2.0 * phi)
        steer_l = torque_l = 0.0
        if lw > 0.0:
            steer_l, torque_l = self._launch_command(
                st, x0, speed, vt_obs, float(self._yref[0]), observation.obstacles,
                int(observation.pass_side), dt)
        meta, coef, knots = self.path.tables()
        if self._launch_active:
            plan = self._launch_plan(x0)
            t_inner0 = time.perf_counter()
            d_ol = t_ol = pe_t = pe_n = d_c = t_c = 0.0
            steer, torque = steer_l, torque_l
            self._preview_xy[:] = st[:2]
        else:
            plan = self.outer.update(observation.t_s, x0, observation.obstacles, vt_obs,
                                     self._dt, lateral_reference_m=y_ref, lateral_weight=c_y)
            t_inner0 = time.perf_counter()
            tau = np.ascontiguousarray(plan.stage_times_s, dtype=np.float64)
            states = np.ascontiguousarray(plan.states, dtype=np.float64)
            speeds = np.ascontiguousarray(plan.speeds_mps, dtype=np.float64)
            out = self._inner_out
            inner_step(st, tau, states, speeds, self._gains, self._vp, self._limits,
                       p.n_preview, p.preview_dt_s, meta, coef, knots, self._preview_xy, out)
            d_ol, t_ol, pe_t, pe_n = float(out[0]), float(out[1]), float(out[2]), float(out[3])
            if p.preview and math.isfinite(pe_n) and math.isfinite(pe_t):
                self._integral = min(max(self._integral + pe_n * dt, -p.integral_limit_ms),
                                     p.integral_limit_ms)
                d_c = p.k_psc * pe_n + p.k_isc * self._integral
                t_c = p.k_pvc * pe_t
            else:
                d_c, t_c = 0.0, 0.0
            steer = d_ol + d_c
            torque = t_ol + t_c
            if lw > 0.0:  # hand-over blend from the launch command to the two-loop one
                steer = lw * steer_l + (1.0 - lw) * steer
                torque = lw * torque_l + (1.0 - lw) * torque
        self.plan = plan
        states = np.ascontiguousarray(plan.states, dtype=np.float64)
        speeds = np.ascontiguousarray(plan.speeds_mps, dtype=np.float64)
        fallback = bool(plan.fallback)
        if not (math.isfinite(steer) and math.isfinite(torque)):
            # Never hand out NaN: hold the lane heading and brake.
            fallback = True
            g = float(self.path.gamma(x0[0]))
            steer = p.k_ps * ((g - float(st[2]) + math.pi) % (2 * math.pi) - math.pi)
            torque = -self._vp[0] * self._vp[6] * p.fallback_decel_mps2
            d_c = t_c = 0.0
            d_ol, t_ol = steer, torque
        self._last_torque = float(torque)
        t_end = time.perf_counter()
        self._t_prev = observation.t_s
        plan_xy = np.empty((states.shape[0], 2))
        _points_many(meta, coef, knots, states[:, 0].copy(), states[:, 1].copy(), plan_xy)
        diag = {
            "outer_s": t_inner0 - t_outer0,
            "inner_s": t_end - t_inner0,
            "residual": float(plan.residual),
            "fallback": 1.0 if fallback else 0.0,
            "guard_fired": float(plan.guard_fired),
            "steer_outer_rad": d_ol,
            "steer_corr_rad": d_c,
            "torque_outer_nm": t_ol,
            "torque_corr_nm": t_c,
            "planned_speed_mps": float(speeds[0]) if speeds.size else 0.0,
            "preview_err_t_m": pe_t,
            "preview_err_n_m": pe_n,
            "outer_updates": (0.0 if self._launch_active else
                              float(p.sub_updates if p.outer == "cgmres" else 1)),
            "lateral_ref_m": y_ref,
            "lateral_ref_rate_mps": float(self._yref[3]),
            "lateral_weight": c_y,
            "launch": 1.0 if self._launch_active else 0.0,
            "launch_weight": lw,
            "launch_ramp_speed_mps": self._launch_ramp.speed_mps,
        }
        return Command(steer_rad=float(steer), torque_nm=float(torque), diagnostics=diag,
                       arrays={"plan_xy_m": plan_xy, "preview_xy_m": self._preview_xy.copy()})

    # ------------------------------------------------------------------- launch
    @staticmethod
    def _free_distance(s: float, y: float, obstacles: Obstacles) -> float:
        """Distance [m] along the lane, at the lateral offset y, from s to the nearest
        obstacle ellipse (as the OCP sees it) ahead; 0 inside one, inf if none."""
        d = math.inf
        for j in range(obstacles.count):
            sj, yj = float(obstacles.s_m[j]), float(obstacles.y_m[j])
            a, b = float(obstacles.semi_a_m[j]), float(obstacles.semi_b_m[j])
            q = (y - yj) / b if b > 0.0 else math.inf
            if not (abs(q) < 1.0 and math.isfinite(sj) and math.isfinite(a)):
                continue
            half = a * math.sqrt(1.0 - q * q)
            if s > sj + half:
                continue  # behind us
            d = min(d, max(sj - half - s, 0.0))
        return d

    def _box_free_distance(self, s: float, y: float, heading: float, obstacles: Obstacles,
                           pass_side: int) -> float:
        """Distance [m] along the ray from (s, y) at ``heading`` (Frenet, relative to the
        lane) to the nearest box-sum rectangle (the set of CG positions where the two
        boxes touch when aligned with the lane, recovered from the ellipse by inverting
        ``controllers.behaviour.ellipses.ellipse_semi_axes``) grown by
        ``launch_clearance_m``; 0 inside one, inf if the ray misses them all."""
        pol = self.obstacle_policy
        clr = self.params.launch_clearance_m
        side = float(np.sign(pass_side)) if abs(pass_side) == 1 else 0.0
        ch, sh = math.cos(heading), math.sin(heading)
        best = math.inf
        for j in range(obstacles.count):
            a_e = float(obstacles.semi_a_m[j]) - pol.margin_long_m
            b0 = float(obstacles.semi_b_m[j]) - pol.offset_m
            b = b0 - max(pol.margin_lat_m, 0.05)
            if not (a_e > 0.0 and b0 > 0.0 and b > 0.0):
                continue
            a = a_e * math.sqrt(max(1.0 - (b / b0) ** 2, 0.0))
            sc = float(obstacles.s_m[j])
            yc = float(obstacles.y_m[j]) + side * pol.offset_m * (1.0 if b0 > 0 else 0.0)
            lo_s, hi_s = sc - a - clr - s, sc + a + clr - s
            lo_y, hi_y = yc - b - clr - y, yc + b + clr - y
            t0, t1 = 0.0, math.inf
            ok = True
            for lo, hi, dirc in ((lo_s, hi_s, ch), (lo_y, hi_y, sh)):
                if abs(dirc) < 1e-12:
                    if lo > 0.0 or hi < 0.0:
                        ok = False
                    continue
                ta, tb = lo / dirc, hi / dirc
                if ta > tb:
                    ta, tb = tb, ta
                t0, t1 = max(t0, ta), min(t1, tb)
            if not (ok and t0 <= t1):
                continue
            if t0 <= 0.0 and abs(y - yc) > b and sh * (y - yc) > 0.0:
                continue  # within the clearance band beside it and moving away
            best = min(best, t0)
        return best

    def _launch_transition(self, t_s: float, x0: np.ndarray, speed: float, target: float,
                           free_m: float, y_target: float) -> None:
        """Enter launch mode or hand over to the two-loop controller (module docstring)."""
        p = self.params
        vp = self._vp
        if not self._launch_active:
            pull_out = math.isfinite(y_target) and abs(y_target - float(x0[1])) > 0.5
            if (speed < p.launch_engage_speed_mps and target > p.launch_speed_mps
                    and (free_m >= p.launch_handover_free_m or pull_out)):
                self._launch_active = True
                self._launch_t_handover = -math.inf
                self._launch_ramp.reset(speed)
                if speed > 0.05:  # moving: continue the commanded acceleration
                    a = self._last_torque / (vp[0] * vp[6])
                    self._launch_ramp.ramp_accel_mps2 = min(max(a, -p.target_decel_mps2),
                                                            p.target_accel_mps2)
            return
        if speed >= p.launch_speed_mps and free_m >= p.launch_handover_free_m:
            self._launch_active = False
            self._launch_t_handover = t_s
            self.launch_count += 1
            self._integral = 0.0
            # The lateral reference restarts at the car's offset (the pull-out may
            # have taken it part of the way), at rest; it then moves on as usual.
            ys = self._yref
            ys[1] = ys[2] = float(x0[1])
            ys[3] = 0.0
            assert self.outer is not None
            restart = getattr(self.outer, "restart", None)
            if restart is not None:
                restart(x0, self._launch_ramp.speed_mps, self._launch_ramp.ramp_accel_mps2)
            else:
                self.outer.reset(x0, self._launch_ramp.speed_mps)

    def _launch_command(self, st: np.ndarray, x0: np.ndarray, speed: float, target: float,
                        y_target: float, obstacles: Obstacles, pass_side: int,
                        dt: float) -> tuple[float, float]:
        """Launch law: jerk-limited ramp, speed capped by the free distance ahead,
        pure-pursuit heading toward the lateral target, brake hold at standstill."""
        p = self.params
        vp = self._vp
        assert self.path is not None
        yt = y_target if math.isfinite(y_target) else float(x0[1])
        h = math.atan2(yt - float(x0[1]), p.launch_lookahead_m)
        h = min(max(h, -p.launch_max_heading_rad), p.launch_max_heading_rad)
        free_m = self._box_free_distance(float(x0[0]), float(x0[1]), h, obstacles, pass_side)
        if abs(yt - float(x0[1])) <= 0.25:  # not pulling out: the OCP's ellipses too
            free_m = min(free_m, self._free_distance(float(x0[0]), float(x0[1]), obstacles))
        set_point = target if math.isfinite(target) else 0.0
        set_point = min(set_point, p.launch_max_speed_mps if self._launch_active else math.inf)
        if math.isfinite(free_m):
            set_point = min(set_point, math.sqrt(2.0 * p.launch_guard_decel_mps2
                                                 * max(free_m - p.launch_clearance_m, 0.0)))
        if set_point <= p.launch_hold_target_mps:
            set_point = 0.0
        vr = self._launch_ramp.update(set_point, dt)
        ar = self._launch_ramp.ramp_accel_mps2
        m_r = vp[0] * vp[6]
        torque = m_r * ar + p.launch_k_pv * (vr - speed)
        if set_point == 0.0 and vr <= 0.0 and speed < p.launch_engage_speed_mps:
            torque = min(torque, -m_r * p.launch_hold_decel_mps2)  # hold the brakes
        meta, coef, _ = self.path.tables()
        g, kappa, _ = path_gamma(meta, coef, float(x0[0]))
        wb = vp[2] + vp[3]
        e_psi = (g + h - float(st[2]) + math.pi) % (2.0 * math.pi) - math.pi
        steer = (wb + float(self._gains[7]) * speed * speed) * kappa + p.launch_k_heading * e_psi
        steer *= min(speed / p.launch_steer_speed_mps, 1.0)
        return steer, torque

    def _launch_plan(self, x0: np.ndarray) -> OuterPlan:
        """What the launch law does, as a plan for the logs: the ramp along the lane."""
        assert self.path is not None
        p = self.params
        n = p.n_stages
        tau = np.linspace(0.0, p.horizon_s, n + 1)
        v = np.maximum(self._launch_ramp.speed_mps
                       + self._launch_ramp.ramp_accel_mps2 * tau, 0.0)
        s = float(x0[0]) + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1])
                                                              * np.diff(tau))])
        states = np.column_stack([s, np.full(n + 1, float(x0[1])), self.path.gamma(s)])
        return OuterPlan(stage_times_s=tau, states=states, speeds_mps=v[:-1].copy(),
                         headings_rad=states[:-1, 2].copy(), residual=0.0, fallback=False,
                         guard_fired=0, solve_s=0.0)

    def _lateral_reference(self, raw: float, dt: float | None, y_now: float,
                           speed: float, since_start_s: float = math.inf) -> float:
        """Advance the lateral-reference shaping by dt; returns yr [m].

        dt None (first step): the shaper starts at the measured offset y_now, at rest.
        State: [raw target, ramp r, yr, yr', weight blend phi, engaged flag].
        """
        st = self._yref
        if math.isfinite(raw):
            st[0] = raw
        elif not math.isfinite(st[0]):
            st[0] = 0.0
        p = self.params
        y_ok = y_now if math.isfinite(y_now) else 0.0
        if dt is None or not math.isfinite(st[2]):
            st[1] = st[2] = y_ok
            st[3] = 0.0
            st[5] = 1.0 if st[0] != 0.0 else 0.0
            st[4] = st[5]
            return float(st[2])
        # Engaged from a non-zero reference until both yr and the car are back on it.
        engaged = st[0] != 0.0 or (st[5] > 0.5 and (abs(st[2] - st[0]) > 0.05
                                                     or abs(y_ok - st[0]) > 0.1))
        st[5] = 1.0 if engaged else 0.0
        step = dt / p.lateral_weight_time_s
        st[4] = min(float(st[4]) + step, 1.0) if engaged else max(float(st[4]) - step, 0.0)
        tf = p.lateral_ref_filter_s
        n_sub = 1 if tf <= 0.0 else max(1, math.ceil(dt / (0.1 * tf)))
        h = dt / n_sub
        v = speed if math.isfinite(speed) and speed > 0.0 else 0.0
        rate = min(p.lateral_ref_rate_mps, v * p.lateral_ref_heading_rad)
        if p.outer == "cgmres":  # while the horizon grows, at its relative length
            rate *= 1.0 - math.exp(-p.horizon_growth_rate * max(since_start_s, 0.0))
        max_step = rate * h
        r, yr, yd = float(st[1]), float(st[2]), float(st[3])
        for _ in range(n_sub):
            r_prev = r
            r += min(max(st[0] - r, -max_step), max_step)
            if tf <= 0.0:
                yd = (r - r_prev) / h
                yr = r
            else:
                yd += h * ((r - yr) / (tf * tf) - 2.0 * yd / tf)
                yr += h * yd
        st[1], st[2], st[3] = r, yr, yd
        return yr

    def parameters(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name}
        out.update(self.params.as_dict())
        return out
