"""C/GMRES outer loop (docs/method.md §5) on the SPMM OCP of ``controllers.two_loop.outer.ocp``.

One control period runs ``sub_updates`` continuation updates inside a single
compiled call (:func:`controllers.two_loop.outer.cgmres_kernel.cgmres_updates`). Between
the previous and the current measurement the initial state is interpolated linearly (x0'
is the measured rate), so after the last sub-update U belongs to the current measured
state and time.

Every update: k_max + 3 residual evaluations (F0, F(x+h x'), F(U + h U'_prev),
k_max Arnoldi vectors) + O(k_max² n) Gram-Schmidt; no allocation proportional to
the iteration count, no data-dependent loop length. Afterwards:

* guard: Z_ij + zeta >= z_guard for every active slot (once Z + zeta crosses zero
  the barrier gradient flips sign and pulls the plan into the obstacle, docs/method.md §9);
  each clamp is counted (``guard_fired``).
* E = ||F(U, x0, t)||_inf at the current state (the paper's (29)).
* fallback: E > fallback_residual, E > diverging_residual at every update for
  ``diverging_s``, or anything non-finite => re-initialise (growing horizon restarted at
  the current state) and return a plan that brakes along the lane at the current
  lateral offset for ``fallback_hold_s``. The second rule catches a continuation that
  diverges slowly: E at 5-48 for a second while its plans, no solutions, drifted the
  car 0.2 m out of its lane before E reached 50 (stress st0062); on the acceptance,
  behaviour, real-net and stress catalogs E stays above 5 for 0.36 s at most otherwise.

Initialisation: growing horizon T(t) = T_f (1 - exp(-rate (t - t_init))); at
t_init the horizon is zero and :func:`controllers.two_loop.outer.ocp_start.stage_init` is exact,
so E(t_init) is at round-off level. The horizon's growth enters the continuation
through the F_t forward difference, like the obstacles' motion.

Obstacle slots (:class:`controllers.two_loop.outer.slots.ObstacleSlots`): the K slots
keep their obstacle between updates (matched by its vehicle id; an obstacle without one
by the constant-velocity prediction of the previous centre), so the unknowns Z_j, mu_j
stay continuous. A new obstacle takes a free slot; its barrier weight fades in from 0
to Cz over ``obstacle_fade_s`` (Z = sqrt(c) on the current plan and mu = 0 make its
rows vanish at that moment, so F stays continuous),
and an obstacle that left fades out the same way (kept at its constant-velocity
prediction) before its slot becomes inert (trivial rows). Switching obstacles in and out
at full weight makes E jump on every change, because the multipliers' mu dc/dx terms
shift all costates at once (docs/two_loop.md §4). At the very first update obstacles
enter at full weight (the closed-form initialisation handles them exactly).
"""

from __future__ import annotations

import math
import time

import numpy as np

from controllers.path.frenet import FrenetPath
from controllers.protocol import Obstacles
from controllers.two_loop.outer.cgmres_kernel import (
    Buffers,
    Interval,
    OcpData,
    Unknowns,
    cgmres_updates,
    solver_config,
    work_size,
)
from controllers.two_loop.outer.ocp import ocp_residual
from controllers.two_loop.outer.ocp_layout import (
    _P_CY,
    _P_CYR,
    _P_CZS,
    _P_CZSR,
    _P_YREF,
    _P_YREFD,
    barrier_scale,
    obstacle_table,
    pack_params,
    stage_fractions,
    stage_width,
)
from controllers.two_loop.outer.ocp_start import activate_slot, deactivate_slot, stage_init
from controllers.two_loop.outer.params import CgmresParams
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.outer.slots import ObstacleSlots
from controllers.two_loop.outer.target_ramp import CruiseSetPoint, TargetSpeedRamp

__all__ = ["CgmresOuter", "cgmres_updates", "work_size"]


class CgmresOuter(CruiseSetPoint):
    """C/GMRES :class:`controllers.two_loop.outer.protocol.OuterPlanner` (module docstring).

    path: the reference path; params: the OCP and the solver's settings; n_slots: the
    number K of obstacle slots (the obstacle policy's ``max_obstacles``): U has
    N (2 + 2K) unknowns. Building it loads the compiled kernels (numba's cache).
    """

    def __init__(self, path: FrenetPath, params: CgmresParams, n_slots: int) -> None:
        if not (isinstance(n_slots, int) and n_slots >= 0):
            raise ValueError(f"n_slots must be an int >= 0, got {n_slots!r}")
        self.path = path
        self.params = params
        self.n_slots = n_slots
        self.meta, self.coef, _ = path.tables()
        self.w = stage_fractions(params)
        self.stage_width = stage_width(n_slots)
        n = params.n_stages * self.stage_width
        self._u = np.zeros(n)
        self._udot = np.zeros(n)
        self._work = np.zeros(work_size(n, params.n_stages, params.k_max))
        self._xs = np.zeros((params.n_stages + 1, 3))
        self._stats = np.zeros(4)
        self._cfg = solver_config(params)
        self._unk = Unknowns(self._u, self._udot)
        self._buffers = Buffers(self._work, self._xs, self._stats)
        self._slots = ObstacleSlots(params, n_slots, self.w)
        self.time_each_subupdate = False
        self.subupdate_times_s: list[float] = []
        self._initialised = False
        self._t_prev = 0.0
        self._x_prev = np.zeros(3)
        self._hz = np.array([0.0, params.horizon_s, params.horizon_growth_rate])
        self._vt = 0.0
        self._ramp = TargetSpeedRamp(params.target_accel_mps2, params.target_decel_mps2,
                                     params.target_jerk_mps3, params.set_speed_decel_mps2)
        self._yr = 0.0  # lateral reference at the previous update [m]
        self._cy = params.c_y  # Cy at the previous update
        self._czs = 1.0  # the barrier's speed scale sigma at the previous update
        self._corridor: tuple[float, float] | None = None  # lane corridor [y_lo, y_hi] [m]
        self._fallback_until = -math.inf
        self._diverging_since = math.inf  # when E first exceeded diverging_residual [s]
        self._fallback_v0 = 0.0
        self.fallback_count = 0
        self.guard_total = 0
        self._load_kernels()

    def _ocp_data(self, prm: np.ndarray, table: np.ndarray | None = None) -> OcpData:
        return OcpData(prm, self._slots.table if table is None else table, self.w, self.meta,
                       self.coef)

    def _pack(self, target_speed_mps: float, lateral_reference_m: float = 0.0,
              lateral_weight: float | None = None,
              barrier_weight_scale: float | None = None) -> np.ndarray:
        return pack_params(self.params, target_speed_mps, lateral_reference_m,
                           lateral_weight=lateral_weight, row_scaling=self.params.row_scaling,
                           barrier_weight_scale=barrier_weight_scale,
                           lane_corridor_m=self._corridor)

    def set_lane_corridor(self, y_lo_m: float, y_hi_m: float) -> None:
        """The lane corridor [y_lo, y_hi] [m, left +] of the following updates: the OCP's
        penalty C_lane (max(0, y - y_hi)² + max(0, y_lo - y)²) (:mod:`..ocp`, Q(y));
        infinite bounds: none. It is zero inside, so widening it (a lane change starting)
        leaves the residual of a plan inside unchanged; the caller narrows it only once
        the car is inside the narrower one
        (:class:`controllers.two_loop.lateral.LaneCorridor`)."""
        lo, hi = float(y_lo_m), float(y_hi_m)
        if math.isnan(lo) or math.isnan(hi) or lo > hi:
            raise ValueError(f"lane corridor: expected y_lo <= y_hi, got {lo!r}, {hi!r}")
        self._corridor = (lo, hi)

    @property
    def lane_corridor_m(self) -> tuple[float, float] | None:
        """The lane corridor of the updates (None: none)."""
        return self._corridor

    def _barrier_scale(self) -> float:
        """sigma of this update (:func:`barrier_scale`): from the larger of the OCP's target
        speed and the speed the current plan starts at (braking from speed toward a low
        target keeps the barrier the speed it is still driving at calls for)."""
        v = self._vt
        if self._initialised:
            v = max(v, self._v_estimate())
        return barrier_scale(self.params, v)

    def _load_kernels(self) -> None:
        # Load every compiled kernel now (from numba's cache, or compile once), so
        # that the first obstacle does not pay it inside a timed control step.
        tab = obstacle_table(self.n_slots)
        u = np.zeros_like(self._u)
        xs = np.zeros_like(self._xs)
        prm = self._pack(1.0)
        if self.n_slots:
            activate_slot(u, xs, 1.0, 0.0, self.w, prm, tab, 0)
            deactivate_slot(u, self.params.n_stages, self.n_slots, 0)
        stage_init(xs[0], 0.0, prm, tab, self.meta, self.coef, self.params.n_stages, u)
        hz = np.array([-1.0, 1.0, 1.0])
        cgmres_updates(Unknowns(u, np.zeros_like(u)), Interval(xs[0], xs[0], 0.0, 0.01, 1, hz, 0.0),
                       self._ocp_data(prm, tab), self._cfg, Buffers(self._work, xs, np.zeros(4)))

    # ------------------------------------------------------------------ protocol
    @property
    def updates_per_period(self) -> int:
        """Continuation updates in one ``update`` call (``sub_updates``)."""
        return self.params.sub_updates

    def horizon_growth(self, elapsed_s: float) -> float:
        """Relative length 1 - exp(-rate elapsed_s) of a horizon grown for elapsed_s."""
        return 1.0 - math.exp(-self.params.horizon_growth_rate * max(elapsed_s, 0.0))

    def reset(self, x0: np.ndarray, target_speed_mps: float) -> None:
        """Forget everything; the next update initialises at its state (E ~ 0) with the
        OCP's target speed at ``target_speed_mps`` (the measured speed: the closed-form
        start puts every stage's V there). The cruise set-point is forgotten too
        (:meth:`set_cruise_speed`)."""
        self._initialised = False
        self._x_prev = np.asarray(x0, dtype=np.float64).copy()
        self._vt = float(target_speed_mps)
        self._ramp.reset(self._vt)
        self._ramp.cruise_speed_mps = math.inf
        self._yr = 0.0
        self._cy = self.params.c_y
        self._czs = barrier_scale(self.params, self._vt)
        self._slots.clear()
        self._fallback_until = -math.inf
        self._diverging_since = math.inf
        self.fallback_count = 0
        self.guard_total = 0
        self.subupdate_times_s.clear()

    def restart(self, x0: np.ndarray, target_speed_mps: float,
                target_accel_mps2: float = 0.0) -> None:
        """Re-initialise at the next update (growing horizon from zero at its state, so
        E ~ 0) without forgetting the run's counters; the target-speed ramp continues
        from ``target_speed_mps`` with acceleration ``target_accel_mps2`` (a launch
        handed over mid-acceleration keeps its ramp: no step in the planned speed's
        rate). Obstacles re-enter at full weight (exact in the closed-form start)."""
        vt = float(target_speed_mps)
        acc = float(target_accel_mps2)
        self._initialised = False
        self._x_prev = np.asarray(x0, dtype=np.float64).copy()
        self._vt = vt if math.isfinite(vt) and vt > 0.0 else 0.0
        self._ramp.reset(self._vt)
        if math.isfinite(acc):
            self._ramp.ramp_accel_mps2 = acc
        self._slots.clear()
        self._fallback_until = -math.inf

    @property
    def ocp_target_speed_mps(self) -> float:
        """The rate-limited target speed the OCP currently uses."""
        return self._vt

    def horizon_now(self, t_s: float) -> float:
        """The grown horizon T(t_s) [s]."""
        return self.params.horizon_s * (1.0 - math.exp(-self.params.horizon_growth_rate
                                                       * max(t_s - self._hz[0], 0.0)))

    def _failed(self, t_s: float, e: float) -> bool:
        """Whether this update failed (module docstring): E non-finite or above
        ``fallback_residual``, or above ``diverging_residual`` since ``diverging_s``
        (the time it first was, :attr:`_diverging_since`, is kept until E falls back)."""
        p = self.params
        if self._stats[2] > 0.5 or not math.isfinite(e) or e > p.fallback_residual:
            return True
        if e <= p.diverging_residual:
            self._diverging_since = math.inf
            return False
        self._diverging_since = min(self._diverging_since, t_s)
        return t_s - self._diverging_since >= p.diverging_s - 1e-9

    def _initialise(self, t_s: float, x0: np.ndarray) -> None:
        self._diverging_since = math.inf
        self._hz[0] = t_s
        prm = self._pack(self._vt, self._yr, lateral_weight=self._cy,
                         barrier_weight_scale=self._czs)
        stage_init(x0, 0.0, prm, self._slots.table, self.meta, self.coef, self.params.n_stages,
                   self._u)
        self._udot[:] = 0.0
        self._initialised = True

    # ------------------------------------------------------------------- update
    def update(self, t_s: float, x0: np.ndarray, obstacles: Obstacles,
               target_speed_mps: float, dt_s: float,
               lateral_reference_m: float = 0.0,
               lateral_weight: float | None = None) -> OuterPlan:
        """One control period; ``lateral_reference_m`` is yr of Cy (y - yr)² at t_s,
        ``lateral_weight`` Cy at t_s (None: params.c_y).

        yr and Cy are taken as moving linearly from the previous update's values to
        these (their rates enter F_t), so smooth yr(t), Cy(t) are tracked without
        residual jumps; a step is a step in F (the caller should smooth them, as
        TwoLoopController does).
        """
        t_start = time.perf_counter()
        p = self.params
        x0 = np.asarray(x0, dtype=np.float64).copy()
        yr = float(lateral_reference_m)
        if not math.isfinite(yr):
            raise ValueError(f"lateral_reference_m must be finite, got {lateral_reference_m!r}")
        cy = p.c_y if lateral_weight is None else float(lateral_weight)
        if not (math.isfinite(cy) and cy >= 0.0):
            raise ValueError(f"lateral_weight must be finite and >= 0, got {lateral_weight!r}")
        # Jerk-limited target speed (the paper ramps Vtarget).
        if self._initialised:
            self._vt = self._ramp.update(float(target_speed_mps), max(t_s - self._t_prev, 0.0))
        czs = self._barrier_scale()
        prm = self._pack(self._vt, yr, lateral_weight=cy, barrier_weight_scale=czs)
        horizon_prev = self.horizon_now(self._t_prev) if self._initialised else 0.0
        self._slots.update(t_s, obstacles, self._u, self._xs, horizon_prev, prm,
                           self._initialised)
        fallback = False
        guards = 0
        if not self._initialised:
            self._yr = yr
            self._cy = cy
            self._czs = czs
            self._initialise(t_s, x0)
            self._stats[:] = 0.0
            self._final_residual(t_s, x0, prm)
        else:
            guards = self._continue(t_s, x0, dt_s, yr, cy, czs, prm)
            e = float(self._stats[0])
            fallback = self._failed(t_s, e)
        self.guard_total += guards
        self._t_prev = t_s
        self._x_prev = x0
        self._yr = yr
        self._cy = cy
        self._czs = czs
        if fallback:
            self.fallback_count += 1
            self._fallback_until = t_s + p.fallback_hold_s
            self._fallback_v0 = self._v_estimate()
            self._initialise(t_s, x0)
            self._final_residual(t_s, x0, prm)
        if t_s < self._fallback_until:
            plan = self._braking_plan(t_s, x0)
            plan.fallback = True
        else:
            plan = self._plan(t_s)
        plan.residual = float(self._stats[0])
        plan.guard_fired = guards
        plan.solve_s = time.perf_counter() - t_start
        return plan

    def _continue(self, t_s: float, x0: np.ndarray, dt_s: float, yr: float, cy: float,  # noqa: PLR0913 - one update's scalars, flat on the hot path
                  czs: float, prm: np.ndarray) -> int:
        """``sub_updates`` continuation updates from the previous update to (t_s, x0);
        yr, Cy and the barrier's scale sigma move linearly from their previous values.
        Returns the guard count."""
        p = self.params
        dt = t_s - self._t_prev
        if not dt > 0:
            dt = dt_s
        # yr at the start of the interval and its rate (restored to yr afterwards).
        prm[_P_YREF] = self._yr
        prm[_P_YREFD] = (yr - self._yr) / dt
        prm[_P_CY] = self._cy
        prm[_P_CYR] = (cy - self._cy) / dt
        prm[_P_CZS] = self._czs
        prm[_P_CZSR] = (czs - self._czs) / dt
        guards = 0
        ocp = self._ocp_data(prm)
        if self.time_each_subupdate:
            n_sub = p.sub_updates
            ddt = dt / n_sub
            xa = self._x_prev.copy()
            for k in range(n_sub):
                xb = self._x_prev + (k + 1) / n_sub * (x0 - self._x_prev)
                prm[_P_YREF] = self._yr + prm[_P_YREFD] * k * ddt
                prm[_P_CY] = self._cy + prm[_P_CYR] * k * ddt
                prm[_P_CZS] = self._czs + prm[_P_CZSR] * k * ddt
                iv = Interval(xa, xb, self._t_prev + k * ddt, ddt, 1, self._hz,
                              self._t_prev + (k + 1) * ddt - t_s)
                t0 = time.perf_counter()
                cgmres_updates(self._unk, iv, ocp, self._cfg, self._buffers)
                self.subupdate_times_s.append(time.perf_counter() - t0)
                guards += int(self._stats[1])
                xa = xb
        else:
            iv = Interval(self._x_prev, x0, self._t_prev, dt, p.sub_updates, self._hz, 0.0)
            cgmres_updates(self._unk, iv, ocp, self._cfg, self._buffers)
            guards = int(self._stats[1])
        prm[_P_YREF] = yr
        prm[_P_YREFD] = 0.0
        prm[_P_CY] = cy
        prm[_P_CYR] = 0.0
        prm[_P_CZS] = czs
        prm[_P_CZSR] = 0.0
        return guards

    # ------------------------------------------------------------------ helpers
    def _final_residual(self, t_s: float, x0: np.ndarray, prm: np.ndarray) -> None:
        f = np.empty(self._u.shape[0])
        ps = np.empty((self.params.n_stages + 1, 12))
        ocp_residual(self._u, x0, self.horizon_now(t_s), 0.0, prm, self._slots.table, self.w,
                     self.meta, self.coef, self._xs, ps, f)
        self._stats[0] = float(np.max(np.abs(f)))

    def _v_estimate(self) -> float:
        """Planned speed at stage 0 of the last plan (the OCP target if not finite)."""
        v = float(self._u[0] if self.params.cost == "J3" else self._u[1])
        return max(v if math.isfinite(v) else self._vt, 0.0)

    def _plan(self, t_s: float) -> OuterPlan:
        p = self.params
        u = self._u.reshape(p.n_stages, self.stage_width)
        if p.cost == "J3":
            speeds = u[:, 0].copy()
            headings = self._xs[:-1, 2].copy()
        else:
            speeds = u[:, 1].copy()
            headings = u[:, 0].copy()
        return OuterPlan(stage_times_s=self.w * self.horizon_now(t_s), states=self._xs.copy(),
                         speeds_mps=speeds, headings_rad=headings, residual=float('nan'),
                         fallback=False, guard_fired=0, solve_s=0.0,
                         target_speed_mps=self._vt)

    def _braking_plan(self, t_s: float, x0: np.ndarray) -> OuterPlan:
        """Brake at fallback_decel along the lane, keeping the current lateral offset."""
        p = self.params
        tau = self.w * p.horizon_s
        elapsed = max(t_s - (self._fallback_until - p.fallback_hold_s), 0.0)
        v_start = max(self._fallback_v0 - p.fallback_decel_mps2 * elapsed, 0.0)
        v = np.maximum(v_start - p.fallback_decel_mps2 * tau, 0.0)
        t_stop = v_start / p.fallback_decel_mps2
        tc = np.minimum(tau, t_stop)
        s = x0[0] + v_start * tc - 0.5 * p.fallback_decel_mps2 * tc**2
        states = np.column_stack([s, np.full_like(s, x0[1]), self.path.gamma(s)])
        return OuterPlan(stage_times_s=tau, states=states, speeds_mps=v[:-1].copy(),
                         headings_rad=states[:-1, 2].copy(), residual=float('nan'),
                         fallback=True, guard_fired=0, solve_s=0.0,
                         target_speed_mps=self._vt)

    # Accessors for tests and diagnostics.
    @property
    def unknowns(self) -> np.ndarray:
        """U (N (2 + 2K),), the solver's current unknowns (a view)."""
        return self._u

    @property
    def obstacle_slots(self) -> np.ndarray:
        """The obstacle table (K, OBS_COLS) (a view)."""
        return self._slots.table

    @property
    def obstacle_slot_ids(self) -> tuple[str, ...]:
        """The vehicle each slot holds (K,) ('' none, or an obstacle without an id)."""
        return tuple(self._slots.vehicle_ids)
