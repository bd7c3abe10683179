"""The paper's two-loop controller (docs/method.md §1), composed from its stages.

Per control period (:meth:`TwoLoopController.step`):

1. measured state (6,) -> Frenet x0 = (s, y, theta_a): (s, y) and gamma(s) the loop's
   projection (``Observation.ego``; without it, its own, hinted by the previous s);
   theta_a = psi + atan2(v, u) unwrapped next to gamma(s);
2. lateral-reference shaper (:mod:`controllers.two_loop.lateral`): the behaviour's
   stepped ``lateral_reference_m`` -> smooth yr and the scheduled weight Cy, and the
   lane corridor [y_lo, y_hi] the plan is kept in (the lane of the reference, or the
   lanes of a change under way; C/GMRES only);
3. launch supervisor (:mod:`controllers.two_loop.launch`): below walking speed it may
   drive instead of the planner, and hands over with a blend;
4. outer planner (:class:`controllers.two_loop.outer.protocol.OuterPlanner`: C/GMRES
   for ``two_loop``, Ipopt for ``ipopt_nmpc``): a plan from x0, the obstacles, the
   target speed (through its jerk-limited ramp, started at the measured speed), yr and
   Cy;
5. inner preview tracker (:mod:`controllers.two_loop.tracker`): conversion (13)(14),
   preview and corrections (38)-(41);
6. longitudinal jerk limiter (:mod:`controllers.two_loop.jerk`): the torque's rate is
   bounded, from the torque that holds the initial speed and within the actuators'
   range (during the manoeuvre below at least at that manoeuvre's own jerk bound;
   raised for an emergency, which is an obstacle's only:
   :func:`controllers.two_loop.fallback.planner_emergency`; bypassed during the launch);
   The threat floor (:mod:`controllers.two_loop.threat`) comes first: from an
   emergency until the obstacle's need has fallen below comfort, the torque is capped
   at the braking the need calls for, held while the need rises;
7. minimal-risk manoeuvre (:mod:`controllers.two_loop.fallback`): when the planner
   fails (or a command is non-finite), a committed, jerk-limited braking plan in the
   lane replaces the planner's for at least its hold time; the planner then restarts at
   the measured state. A non-finite command (never expected) is replaced by lane-keeping
   braking (heading K_Ps wrap(gamma - psi), torque -m R fallback_decel_mps2).

Its output: :class:`controllers.protocol.Command` with :class:`TwoLoopDiagnostics`,
the plan's positions ``plan_xy_m`` (N+1, 2) and the preview ``preview_xy_m``
(Np+1, 2) in the world frame. Design notes and tuning: docs/two_loop.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from controllers.behaviour.types import ObstaclePolicy
from controllers.params import to_dict
from controllers.path.frenet import FrenetPath, _points_many, path_gamma, path_project_local
from controllers.plant.limited import resistance_n
from controllers.protocol import (
    Command,
    EgoOnPath,
    Observation,
    Obstacles,
    ScenarioContext,
    StepDiagnostics,
)
from controllers.two_loop.diagnostics import (
    StepBraking,
    StepReferences,
    StepTimes,
    TwoLoopDiagnostics,
)
from controllers.two_loop.fallback import (
    NO_EMERGENCY,
    Emergency,
    MinimalRiskManeuver,
    most_urgent_obstacle,
    onset_jerk_mps3,
    planner_emergency,
)
from controllers.two_loop.jerk import JerkLimiter
from controllers.two_loop.lateral import LaneCorridor, LateralReferenceShaper
from controllers.two_loop.launch import LaunchSupervisor
from controllers.two_loop.outer.protocol import (
    CruiseAware,
    LaneCorridorAware,
    OuterPlan,
    OuterPlanner,
    PlannerFactory,
)
from controllers.two_loop.params import (
    IpoptNmpcParams,
    TwoLoopParams,
    TwoLoopParamsBase,
    two_loop_params,
)
from controllers.two_loop.steer_rate import SteerRateLimiter
from controllers.two_loop.threat import BrakeSource, ThreatFloor
from controllers.two_loop.tracker import PreviewTracker, TrackerOutput

__all__ = ["TwoLoopController", "TwoLoopDiagnostics", "cgmres_planner", "ipopt_planner",
           "make_two_loop"]


def cgmres_planner(params: TwoLoopParams) -> PlannerFactory:
    """C/GMRES on ``params.outer``, with the policy's K slots."""

    def factory(path: FrenetPath, n_slots: int) -> OuterPlanner:
        from controllers.two_loop.outer.cgmres import CgmresOuter

        return CgmresOuter(path, params.outer, n_slots)

    return factory


def ipopt_planner(params: IpoptNmpcParams) -> PlannerFactory:
    """Ipopt on ``params.outer``; the NLPs for 0..K obstacles are built at once."""

    def factory(path: FrenetPath, n_slots: int) -> OuterPlanner:
        from controllers.two_loop.outer.ipopt_planner import IpoptOuter

        outer = IpoptOuter(path, params.outer, n_slots)
        outer.prepare()  # NLPs built at reset, not mid-run
        return outer

    return factory


def make_two_loop(options: Mapping[str, Any]) -> TwoLoopController:
    """``two_loop`` from catalog options (cheap: validation only, nothing compiled)."""
    params = two_loop_params(options)
    return TwoLoopController(params, cgmres_planner(params))


class TwoLoopController:
    """The Controller: frame change, then the stages in the module docstring's order.

    params: the sections (``outer`` the planner's); planner_factory: builds the
    planner at ``reset`` (default: C/GMRES on ``params.outer``, which must then be
    :class:`TwoLoopParams`); name: the registered name. ``plan`` is the last
    :class:`OuterPlan` (the launch law's own while it drives), ``launch_count`` the
    hand-overs of the run.
    """

    diagnostics_type: ClassVar[type[StepDiagnostics]] = TwoLoopDiagnostics

    def __init__(self, params: TwoLoopParamsBase | None = None,
                 planner_factory: PlannerFactory | None = None, name: str = "two_loop") -> None:
        self.params: TwoLoopParamsBase = params if params is not None else TwoLoopParams()
        if planner_factory is None:
            if not isinstance(self.params, TwoLoopParams):
                raise TypeError("TwoLoopController: give a planner_factory for "
                                f"{type(self.params).__name__}")
            planner_factory = cgmres_planner(self.params)
        self.name = name
        self.obstacle_policy: ObstaclePolicy | None = self.params.policy
        self._planner_factory = planner_factory
        p = self.params
        self.lateral = LateralReferenceShaper(p.lateral)
        self.corridor = LaneCorridor(p.lateral)
        self.launch = LaunchSupervisor(p.launch, p.outer, p.policy)
        self.tracker = PreviewTracker(p.inner)
        self.mrm = MinimalRiskManeuver(p.fallback, p.outer.target_accel_mps2, p.policy)
        self.jerk = JerkLimiter(p.jerk)
        self.threat = ThreatFloor(p.threat)
        self.steer_rate = SteerRateLimiter(p.fallback.lat_jerk_mps3, p.fallback.blend_s,
                                           p.fallback.rate_speed_floor_mps)
        self.path: FrenetPath | None = None
        self.planner: OuterPlanner | None = None
        # the planner as a corridor taker, resolved once at reset: a runtime Protocol
        # check costs ~10 µs, 3 % of a dense step
        self._corridor_planner: LaneCorridorAware | None = None
        self.plan: OuterPlan | None = None
        self._vp = np.zeros(8)
        self._dt = 0.0
        self._s_hint = 0.0
        self._t_prev: float | None = None
        self._t_first = 0.0
        self._emergency: Emergency = NO_EMERGENCY

    @property
    def launch_count(self) -> int:
        """Launch hand-overs so far in this run."""
        return self.launch.count

    # ----------------------------------------------------------------- protocol
    def reset(self, context: ScenarioContext) -> None:
        p = self.params
        self.path = context.reference_path()
        self.planner = self._planner_factory(self.path, p.policy.max_obstacles)
        self._corridor_planner = self.planner if isinstance(self.planner, LaneCorridorAware) \
            else None
        self._vp = context.vehicle.as_array()
        self._dt = context.control_period_s
        st = np.asarray(context.initial_state, dtype=np.float64)
        s, _ = self.path.project(st[0], st[1])
        self._s_hint = float(s)
        x0 = self._frenet_state(st, self._on_path(st, None))
        v0 = float(math.hypot(st[3], st[4]))
        # The OCP's target ramp starts at the car's speed, whatever the set-point: its
        # closed-form start puts every stage's V at the ramp's speed, and the conversion
        # (14) turns V - v into torque at once (started at the set-point 6 m/s below the
        # car, the first command braked at 10 m/s²). The cruise set-point selects the
        # ramp's deceleration limit (docs/two_loop.md, "Speed reference").
        self.planner.reset(x0, v0)
        if isinstance(self.planner, CruiseAware):
            self.planner.set_cruise_speed(float(context.target_speed_mps))
        self._t_prev = None
        self.plan = None
        self.lateral.reset()
        self.corridor.reset(context.lane_width_m, context.vehicle.width_m)
        self.mrm.reset()
        vp = context.vehicle
        # The car starts cruising: the limiter starts at the torque that holds its speed.
        self.jerk.reset(vp.wheel_radius_m * resistance_n(v0, vp.plant_array()),
                        (-vp.max_brake_torque_nm, vp.max_drive_torque_nm))
        self._emergency = NO_EMERGENCY
        self.threat.reset()
        self.steer_rate.reset(context.vehicle)
        self.launch.reset(self.path, context.vehicle)
        self.tracker.reset(self.path, context.vehicle, p.outer.n_stages, st)
        meta, coef, knots = self.path.tables()
        _points_many(meta, coef, knots, np.zeros(1), np.zeros(1), np.zeros((1, 2)))

    def _on_path(self, st: np.ndarray, given: EgoOnPath | None) -> EgoOnPath:
        """The CG on the reference path: the loop's projection when ``given``, else this
        controller's own (hinted by the previous s; the loop's is the same, bit for bit)."""
        if self.path is None:
            raise RuntimeError("TwoLoopController used before reset")
        if given is not None:
            self._s_hint = given.s_m
            return given
        meta, coef, knots = self.path.tables()
        s, d, ok = path_project_local(meta, coef, knots, float(st[0]), float(st[1]),
                                      self._s_hint)
        if not ok or abs(s - self._s_hint) > 50.0:
            s_arr, d_arr = self.path.project(st[0], st[1])
            s, d = float(s_arr), float(d_arr)
        self._s_hint = s
        g, k, _ = path_gamma(meta, coef, s)
        e = (float(st[2]) - g + math.pi) % (2.0 * math.pi) - math.pi
        return EgoOnPath(s, d, e, g, k)

    @staticmethod
    def _frenet_state(st: np.ndarray, on_path: EgoOnPath) -> np.ndarray:
        """Measured state -> Frenet x0 = (s, y, theta_a) with theta_a next to gamma(s)."""
        u, v = float(st[3]), float(st[4])
        speed = math.hypot(u, v)
        tha = float(st[2]) + (math.atan2(v, u) if speed > 0.5 else 0.0)
        g = on_path.path_heading_rad
        e = (tha - g + math.pi) % (2.0 * math.pi) - math.pi
        return np.array([on_path.s_m, on_path.lat_m, g + e])

    def step(self, observation: Observation) -> Command:
        """One control period: measure, shape the lateral references, plan (or launch, or
        the minimal-risk manoeuvre), track, then the limiting stages (safe stop, steering
        rate, threat floor, jerk) in the module docstring's order."""
        planner = self._planner()
        t_outer0 = time.perf_counter()
        t_s = float(observation.t_s)
        st = np.asarray(observation.state, dtype=np.float64)
        on_path = self._on_path(st, observation.ego)
        x0 = self._frenet_state(st, on_path)
        first = self._t_prev is None
        dt = self._dt if self._t_prev is None else max(observation.t_s - self._t_prev, 1e-6)
        if first:
            self._t_first = t_s
        speed = math.hypot(float(st[3]), float(st[4]))
        refs = self._references(observation, planner, on_path, x0, speed, None if first else dt)
        if self.mrm.due(t_s):  # back to the planner, restarted at the measured state
            self.mrm.release(t_s)
            planner.restart(x0, self.mrm.ramp.speed_mps, self.mrm.ramp.ramp_accel_mps2)
        target = float(observation.target_speed_mps)
        launch = (0.0, 0.0, 0.0) if self.mrm.active else \
            self._launch_step(observation, st, x0, speed, target, dt)
        plan, out, command, updates, t_inner0 = self._plan_and_track(
            observation, planner, (st, x0, speed, dt), target, refs, launch)
        steer, torque = command
        fallback = bool(plan.fallback) or self.mrm.active
        safe_stop = not (math.isfinite(steer) and math.isfinite(torque))
        if safe_stop:
            fallback = True
            steer, torque = self._brake_along_lane(st, x0)
            out = TrackerOutput(steer, torque, out.preview_err_t_m, out.preview_err_n_m, 0.0, 0.0)
            if not self.mrm.active:
                self.mrm.engage(t_s, speed, -self.params.outer.fallback_decel_mps2)
        if self.mrm.active and not safe_stop:
            torque = self._mrm_limits(torque, speed)
        steer, _ = self.steer_rate.limit(steer, t_s, dt, speed, float(st[5]), self.mrm.active)
        lw = launch[2]
        # the obstacles' braking need, once for the emergency test and the threat floor
        # (none while the launch law drives or blends out: it brakes for its own obstacles)
        urgent = None if self.launch.active or lw > 0.0 else most_urgent_obstacle(
            x0, speed, observation.obstacles, self.params.policy,
            self.params.fallback.standstill_m)
        self._emergency = self._emergency_now(x0, speed, plan, observation.obstacles, urgent)
        source = self._source(fallback, lw, safe_stop)
        need, floor = self._threat(urgent)
        if floor > 0.0 and torque > -self._vp[0] * self._vp[6] * floor:
            torque, source = -self._vp[0] * self._vp[6] * floor, BrakeSource.THREAT_FLOOR
        torque = self._limit_torque(torque, dt, lw, floor)
        self.launch.observe_torque(torque)
        t_end = time.perf_counter()
        self._t_prev = observation.t_s
        self.plan = plan
        diag = self._diagnostics(plan, out, refs, StepTimes(t_outer0, t_inner0, t_end),
                                 fallback, updates, lw, StepBraking(need, floor, source))
        return Command(steer_rad=float(steer), torque_nm=float(torque), diagnostics=diag,
                       plan_xy_m=self._plan_xy(plan),
                       preview_xy_m=self.tracker.preview_xy_m.copy())

    def _references(self, observation: Observation, planner: OuterPlanner, on_path: EgoOnPath,
                    x0: np.ndarray, speed_mps: float, dt_s: float | None) -> StepReferences:
        """The lateral reference and its weight, then the lane corridor (handed to a
        planner that takes one); ``dt_s`` None at the first step."""
        y_ref = self.lateral.update(float(observation.lateral_reference_m), dt_s, float(x0[1]),
                                    speed_mps, planner.horizon_growth(
                                        float(observation.t_s) - self._t_first),
                                    evasive=bool(observation.evasive),
                                    curvature_1pm=on_path.curvature_1pm)
        c_y = self.lateral.weight(self.params.outer.c_y)
        y_lo, y_hi = self.corridor.update(float(observation.lateral_reference_m),
                                          float(x0[1]), y_ref)
        if self._corridor_planner is not None:
            self._corridor_planner.set_lane_corridor(y_lo, y_hi)
        return StepReferences(y_ref, c_y, y_lo, y_hi)

    def _plan_and_track(self, observation: Observation, planner: OuterPlanner,
                        measured: tuple[np.ndarray, np.ndarray, float, float], target_mps: float,
                        refs: StepReferences, launch: tuple[float, float, float],
                        ) -> tuple[OuterPlan, TrackerOutput, tuple[float, float], int, float]:
        """The plan this period follows and the tracker's command on it: the launch law's
        plan while it drives (the tracker held), else the outer planner's (the
        minimal-risk manoeuvre's when it failed or the manoeuvre drives), tracked by the
        preview loop and blended with the launch command while it hands over. Returns
        (plan, tracker output, (steer_rad, torque_nm), outer updates, the inner loop's
        start)."""
        st, x0, speed_mps, dt_s = measured  # state, Frenet x0, speed [m/s], period [s]
        steer_l, torque_l, lw = launch
        if self.launch.active:
            plan = self.launch.plan(x0)
            t_inner0 = time.perf_counter()
            self.tracker.hold(st)
            return (plan, TrackerOutput(0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (steer_l, torque_l), 0,
                    t_inner0)
        solved = None if self.mrm.active else planner.update(
            observation.t_s, x0, observation.obstacles, target_mps, self._dt,
            lateral_reference_m=refs.y_ref_m, lateral_weight=refs.c_y)
        if solved is not None and solved.fallback:
            self.mrm.engage(float(observation.t_s), speed_mps,
                            self.jerk.last_torque_nm / (self._vp[0] * self._vp[6]))
        updates = 0
        if solved is None or self.mrm.active:
            plan = self._mrm_plan(x0, refs.y_ref_m, target_mps, dt_s, observation.obstacles)
        else:
            plan = solved
            updates = planner.updates_per_period
        t_inner0 = time.perf_counter()
        out = self.tracker.track(st, plan, dt_s)
        steer, torque = out.steer_rad, out.torque_nm
        if lw > 0.0:  # hand-over blend from the launch command to the two-loop one
            steer = lw * steer_l + (1.0 - lw) * steer
            torque = lw * torque_l + (1.0 - lw) * torque
        return plan, out, (steer, torque), updates, t_inner0

    def _diagnostics(self, plan: OuterPlan, out: TrackerOutput, refs: StepReferences,
                     times: StepTimes, fallback: bool, updates: int, launch_weight: float,
                     braking: StepBraking) -> TwoLoopDiagnostics:
        """This period's diagnostics (:class:`TwoLoopDiagnostics`)."""
        speeds = np.asarray(plan.speeds_mps, dtype=np.float64)
        return TwoLoopDiagnostics(
            outer_s=times.inner0 - times.outer0, inner_s=times.end - times.inner0,
            residual=float(plan.residual), fallback=fallback,
            guard_fired=int(plan.guard_fired),
            steer_outer_rad=out.steer_outer_rad, steer_corr_rad=out.steer_corr_rad,
            steer_corr_integral_rad=out.steer_corr_integral_rad,
            preview_weight=out.preview_weight,
            torque_outer_nm=out.torque_outer_nm, torque_corr_nm=out.torque_corr_nm,
            planned_speed_mps=float(speeds[0]) if speeds.size else 0.0,
            planned_speed_min_mps=float(speeds.min()) if speeds.size else 0.0,
            preview_err_t_m=out.preview_err_t_m, preview_err_n_m=out.preview_err_n_m,
            outer_updates=updates, lateral_ref_m=refs.y_ref_m,
            lateral_ref_rate_mps=self.lateral.rate_mps, lateral_weight=refs.c_y,
            lane_corridor_lo_m=refs.y_lo_m, lane_corridor_hi_m=refs.y_hi_m,
            launch=self.launch.active, launch_weight=launch_weight,
            launch_ramp_speed_mps=self.launch.ramp.speed_mps, mrm=self.mrm.active,
            mrm_hold_s=self.mrm.hold_s, ocp_target_speed_mps=float(plan.target_speed_mps),
            emergency=self._emergency.active,
            emergency_decel_mps2=self._emergency.decel_mps2,
            emergency_ds_m=self._emergency.ds_m, emergency_dy_m=self._emergency.dy_m,
            threat_need_mps2=braking.need_mps2, brake_floor_mps2=braking.floor_mps2,
            brake_source=int(braking.source))

    def _launch_step(self, observation: Observation, st: np.ndarray, x0: np.ndarray,
                     speed: float, target: float, dt: float) -> tuple[float, float, float]:
        """Launch transitions (restarting the other stages on a hand-over), then the
        launch command and its weight: (steer_rad, torque_nm, weight)."""
        launch = self.launch
        if launch.watching(speed):
            handed_over = launch.transition(float(observation.t_s), x0, speed, target,
                                            observation.obstacles,
                                            float(observation.lateral_reference_m))
            if handed_over:
                self.tracker.clear()
                # The lateral reference restarts at the car's offset (the pull-out may
                # have taken it part of the way), at rest; it then moves on as usual.
                self.lateral.restart(float(x0[1]))
                self._planner().restart(x0, launch.ramp.speed_mps, launch.ramp.ramp_accel_mps2)
        lw = launch.weight(float(observation.t_s))
        if lw <= 0.0:
            return 0.0, 0.0, lw
        steer, torque = launch.command(st, x0, speed, target, self.lateral.raw_m,
                                       observation.obstacles, int(observation.pass_side), dt)
        return steer, torque, lw

    def _emergency_now(self, x0: np.ndarray, speed_mps: float, plan: OuterPlan,
                       obstacles: Obstacles, urgent: tuple[float, int] | None) -> Emergency:
        """This step's emergency braking, for an obstacle only: the manoeuvre's own brace
        while it drives, else :func:`planner_emergency` on the plan with the step's
        ``urgent`` obstacle (None: the launch law drives or blends out, no emergency)."""
        if urgent is None:
            return NO_EMERGENCY
        if self.mrm.active:
            return self.mrm.emergency
        return planner_emergency(self.params.fallback, x0, speed_mps, plan, obstacles,
                                 self.params.policy, urgent=urgent)

    def _mrm_limits(self, torque_nm: float, speed_mps: float) -> float:
        """The minimal-risk manoeuvre's own limits at the wheels (module docstring of
        :mod:`controllers.two_loop.fallback`): no braking beyond the ramp's current
        deceleration (its ``decel_mps2``, raised only by an emergency's brace), and none
        at all below the ramp's set-point (0.2 m/s of tolerance) unless an obstacle's
        emergency braces it."""
        m_r = float(self._vp[0] * self._vp[6])
        lowest = -m_r * self.mrm.ramp.decel_mps2
        if speed_mps < self.mrm.set_point_mps - 0.2 and not self.mrm.emergency.active:
            lowest = 0.0
        return max(torque_nm, lowest)

    def _source(self, fallback: bool, launch_weight: float, safe_stop: bool) -> BrakeSource:
        """Which stage set this period's command before the threat floor."""
        if safe_stop:
            return BrakeSource.SAFE_STOP
        if self.launch.active or launch_weight > 0.0:
            return BrakeSource.LAUNCH
        return BrakeSource.FALLBACK if fallback else BrakeSource.PLAN

    def _threat(self, urgent: tuple[float, int] | None) -> tuple[float, float]:
        """(need b, floor F) [m/s²] of the threat floor (:mod:`controllers.two_loop.
        threat`) from the step's ``urgent`` obstacle's need (None: the launch law drives
        or blends out, no floor)."""
        if urgent is None:
            self.threat.reset()
            return 0.0, 0.0
        return urgent[0], self.threat.update(urgent[0], self._emergency.active)

    def _limit_torque(self, torque_nm: float, dt: float, launch_weight: float,
                      floor_mps2: float) -> float:
        """The jerk limiter's stage (module docstring, step 6): bypassed while the launch
        law drives, bounded at the manoeuvre's own jerk while it drives, else at the
        limiter's bounds, raised only for this step's emergency (an obstacle's) and while
        the threat floor ``floor_mps2`` acts (to :func:`onset_jerk_mps3` of it)."""
        m_r = self._vp[0] * self._vp[6]
        if self.launch.active or launch_weight > 0.0:
            return self.jerk.follow(torque_nm)
        floor_jerk = onset_jerk_mps3(self.params.fallback, floor_mps2) if floor_mps2 > 0.0 \
            else 0.0
        if self.mrm.active:
            return self.jerk.limit(torque_nm, dt, m_r, max(self.mrm.ramp.jerk_mps3, floor_jerk))
        at_least = self._emergency.jerk_mps3 if self._emergency.active else 0.0
        return self.jerk.limit(torque_nm, dt, m_r, max(at_least, floor_jerk))

    def _mrm_plan(self, x0: np.ndarray, y_ref: float, target: float, dt: float,
                  obstacles: Obstacles) -> OuterPlan:
        o = self.params.outer
        return self.mrm.plan(self._path(), x0, y_ref, target, dt, o.horizon_s, o.n_stages,
                             obstacles)

    def _planner(self) -> OuterPlanner:
        if self.planner is None:
            raise RuntimeError("TwoLoopController used before reset")
        return self.planner

    def _path(self) -> FrenetPath:
        if self.path is None:
            raise RuntimeError("TwoLoopController used before reset")
        return self.path

    def _brake_along_lane(self, st: np.ndarray, x0: np.ndarray) -> tuple[float, float]:
        """Never hand out NaN: hold the lane heading and brake."""
        g = float(self._path().gamma(x0[0]))
        steer = self.params.inner.k_ps * ((g - float(st[2]) + math.pi) % (2 * math.pi) - math.pi)
        torque = -self._vp[0] * self._vp[6] * self.params.outer.fallback_decel_mps2
        return float(steer), float(torque)

    def _plan_xy(self, plan: OuterPlan) -> np.ndarray:
        """The plan's (N+1, 2) positions in the world frame."""
        meta, coef, knots = self._path().tables()
        states = np.ascontiguousarray(plan.states, dtype=np.float64)
        plan_xy = np.empty((states.shape[0], 2))
        _points_many(meta, coef, knots, states[:, 0].copy(), states[:, 1].copy(), plan_xy)
        return plan_xy

    def parameters(self) -> dict[str, Any]:
        """``{"name": ..., **nested sections}``: accepted back by the factory."""
        return {"name": self.name, **to_dict(self.params)}
