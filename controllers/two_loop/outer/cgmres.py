"""C/GMRES outer loop (docs/method.md §5) on the SPMM OCP of ``controllers.two_loop.outer.ocp``.

One control period runs ``sub_updates`` continuation updates inside a single
compiled call (:func:`cgmres_updates`). Between the previous and the current
measurement the initial state is interpolated linearly (x0' is the measured rate),
so after the last sub-update U belongs to the current measured state and time.

Every update: k_max + 3 residual evaluations (F0, F(x+h x'), F(U + h U'_prev),
k_max Arnoldi vectors) + O(k_max² n) Gram-Schmidt; no allocation proportional to
the iteration count, no data-dependent loop length. Afterwards:

* guard: Z_ij + zeta >= z_guard for every active slot (once Z + zeta crosses zero
  the barrier gradient flips sign and pulls the plan into the obstacle, docs/method.md §9);
  each clamp is counted (``guard_fired``).
* E = ||F(U, x0, t)||_inf at the current state (the paper's (29)).
* fallback: E > fallback_residual or anything non-finite => re-initialise (growing
  horizon restarted at the current state) and return a plan that brakes along the
  lane at the current lateral offset for ``fallback_hold_s``.

Initialisation: growing horizon T(t) = T_f (1 - exp(-rate (t - t_init))); at
t_init the horizon is zero and :func:`controllers.two_loop.outer.ocp.stage_init` is exact,
so E(t_init) is at round-off level. The horizon's growth enters the continuation
through the F_t forward difference, like the obstacles' motion.

Obstacle slots: the K slots keep their obstacle between updates (matched by the
constant-velocity prediction of the previous centre), so the unknowns Z_j, mu_j
stay continuous. A new obstacle takes a free slot; its barrier weight fades in
from 0 to Cz over ``obstacle_fade_s`` (Z = sqrt(c) on the current plan and mu = 0
make its rows vanish at that moment, so F stays continuous), and an obstacle that
left fades out the same way (kept at its constant-velocity prediction) before its
slot becomes inert (trivial rows). Switching obstacles in and out at full weight
makes E jump on every change, because the multipliers' mu dc/dx terms shift all
costates at once (docs/two_loop.md §4). At the very first update obstacles
enter at full weight (the closed-form initialisation handles them exactly).
"""

from __future__ import annotations

import math
import time

import numba
import numpy as np

from controllers.path.frenet import FrenetPath
from controllers.protocol import Obstacles
from controllers.two_loop.outer.gmres import arnoldi_mgs, back_substitute, combine, givens_column
from controllers.two_loop.outer.ocp import (
    _FM,
    _P_CY,
    _P_CYR,
    _P_SCALE,
    _P_YREF,
    _P_YREFD,
    TargetSpeedRamp,
    activate_slot,
    deactivate_slot,
    obstacle_table,
    ocp_residual,
    pack_params,
    stage_fractions,
    stage_init,
    stage_width,
)
from controllers.two_loop.outer.params import CgmresParams
from controllers.two_loop.outer.protocol import OuterPlan


@numba.njit(cache=True, error_model="numpy")
def _horizon(t: float, t_init: float, tf: float, rate: float) -> tuple[float, float]:
    a = math.exp(-rate * max(t - t_init, 0.0))
    return tf * (1.0 - a), rate * tf * a


# One compiled loop on purpose (no calls per sub-update, no allocation): its branches are
# the GMRES iteration, the guard and the finiteness checks, hence the complexity.
@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def cgmres_updates(  # noqa: C901
        uvec: np.ndarray, udot: np.ndarray, x0a: np.ndarray, x0b: np.ndarray, t_a: float,
        dt_total: float, n_sub: int, hz: np.ndarray, tshift_b: float, prm: np.ndarray,
        obs: np.ndarray, w: np.ndarray, meta: np.ndarray, coef: np.ndarray, cfg: np.ndarray,
        work: np.ndarray, xs_out: np.ndarray, stats: np.ndarray) -> None:
    """``n_sub`` C/GMRES updates from (x0a, t_a) to (x0b, t_a + dt_total), in place.

    hz = [t_init, T_f, growth rate]; tshift_b = (t_a + dt_total) - obstacle time stamp;
    prm[_P_YREF] is the lateral reference at t_a and prm[_P_YREFD] its rate: yr moves
    linearly to yr(t_a) + rate dt_total across the call, and its motion enters the F_t
    forward difference; likewise Cy (prm[_P_CY]) with rate prm[_P_CYR] (prm is
    restored on return);
    cfg = [k_max, zeta_s, h, z_guard, zeta]; work: flat scratch of length
    >= work_size(n, N, k_max). Outputs: xs_out (N+1, 3) plan at the end state;
    stats = [E, guard count, non-finite flag, GMRES residual of the last solve].
    """
    n = uvec.shape[0]
    nst = w.shape[0] - 1
    k_obs = obs.shape[0]
    m = 2 + 2 * k_obs
    kmax = int(cfg[0])
    zeta_s = cfg[1]
    h = cfg[2]
    zmin = cfg[3]
    zeta = cfg[4]
    off = 0
    f0 = work[off:off + n]
    off += n
    fxh = work[off:off + n]
    off += n
    fw = work[off:off + n]
    off += n
    ut = work[off:off + n]
    off += n
    vb = work[off:off + (kmax + 1) * n].reshape((kmax + 1, n))
    off += (kmax + 1) * n
    hm = work[off:off + (kmax + 1) * kmax].reshape((kmax + 1, kmax))
    off += (kmax + 1) * kmax
    cs = work[off:off + kmax]
    off += kmax
    sn = work[off:off + kmax]
    off += kmax
    g = work[off:off + kmax + 1]
    off += kmax + 1
    yv = work[off:off + kmax]
    off += kmax
    ps = work[off:off + 12 * (nst + 1)].reshape((nst + 1, 12))
    off += 12 * (nst + 1)
    xd = np.empty(3)
    xk = np.empty(3)
    xh = np.empty(3)
    ddt = dt_total / n_sub
    for c in range(3):
        xd[c] = (x0b[c] - x0a[c]) / dt_total
    guards = 0
    gres = 0.0
    yr_a = prm[_P_YREF]
    yr_rate = prm[_P_YREFD]
    cy_a = prm[_P_CY]
    cy_rate = prm[_P_CYR]
    for k in range(n_sub):
        tk = t_a + k * ddt
        frac = k / n_sub
        yr_k = yr_a + yr_rate * (k * ddt)
        for c in range(3):
            xk[c] = x0a[c] + frac * (x0b[c] - x0a[c])
            xh[c] = xk[c] + h * xd[c]
        tk_shift = tshift_b - dt_total + k * ddt
        tt, tdot = _horizon(tk, hz[0], hz[1], hz[2])
        tth = tt + h * tdot
        cy_k = cy_a + cy_rate * (k * ddt)
        prm[_P_YREF] = yr_k
        prm[_P_CY] = cy_k
        ocp_residual(uvec, xk, tt, tk_shift, prm, obs, w, meta, coef, xs_out, ps, f0)
        prm[_P_YREF] = yr_k + h * yr_rate
        prm[_P_CY] = cy_k + h * cy_rate
        ocp_residual(uvec, xh, tth, tk_shift + h, prm, obs, w, meta, coef, xs_out, ps, fxh)
        for i in range(n):
            ut[i] = uvec[i] + h * udot[i]
        ocp_residual(ut, xh, tth, tk_shift + h, prm, obs, w, meta, coef, xs_out, ps, fw)
        beta = 0.0
        for i in range(n):
            r = -zeta_s * f0[i] - (fxh[i] - f0[i]) / h - (fw[i] - fxh[i]) / h
            vb[0, i] = r
            beta += r * r
        beta = math.sqrt(beta)
        if beta > 1e-300:
            for i in range(n):
                vb[0, i] /= beta
            for i in range(kmax + 1):
                g[i] = 0.0
            g[0] = beta
            kused = 0
            for j in range(kmax):
                for i in range(n):
                    ut[i] = uvec[i] + h * vb[j, i]
                ocp_residual(ut, xh, tth, tk_shift + h, prm, obs, w, meta, coef, xs_out, ps,
                             fw)
                for i in range(n):
                    vb[j + 1, i] = (fw[i] - fxh[i]) / h
                nrm = arnoldi_mgs(vb, hm, j)
                gres = givens_column(hm, cs, sn, g, j)
                kused = j + 1
                if nrm < 1e-14 * beta:
                    break
            back_substitute(hm, g, kused, yv)
            combine(udot, vb, yv, kused)
        for i in range(n):
            uvec[i] += ddt * udot[i]
        # Barrier guard: keep Z + zeta >= z_guard on active constraint rows.
        for i in range(1, nst):
            for j in range(k_obs):
                if obs[j, 6] > 0.5:
                    idx = i * m + 2 + j
                    if uvec[idx] + zeta < zmin:
                        uvec[idx] = zmin - zeta
                        if udot[idx] < 0.0:
                            udot[idx] = 0.0
                        guards += 1
    tb = t_a + dt_total
    tt, _ = _horizon(tb, hz[0], hz[1], hz[2])
    # E on the unscaled residual (row scaling, if any, is a solver device only).
    scale_flag = prm[_P_SCALE]
    prm[_P_SCALE] = 0.0
    prm[_P_YREF] = yr_a + yr_rate * dt_total
    prm[_P_CY] = cy_a + cy_rate * dt_total
    ocp_residual(uvec, x0b, tt, tshift_b, prm, obs, w, meta, coef, xs_out, ps, f0)
    prm[_P_SCALE] = scale_flag
    prm[_P_YREF] = yr_a
    prm[_P_CY] = cy_a
    e = 0.0
    finite = True
    for i in range(n):
        a = abs(f0[i])
        if not (a < 1e300):
            finite = False
        if a > e:
            e = a
    for i in range(nst + 1):
        for c in range(3):
            if not (abs(xs_out[i, c]) < 1e300):
                finite = False
    stats[0] = e
    stats[1] = guards
    stats[2] = 0.0 if finite else 1.0
    stats[3] = gres


def work_size(n: int, n_stages: int, k_max: int) -> int:
    """Length of the flat scratch array :func:`cgmres_updates` needs (n unknowns)."""
    return 4 * n + (k_max + 1) * n + (k_max + 1) * k_max + 4 * k_max + 1 + 12 * (n_stages + 1)


class CgmresOuter:
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
        self._cfg = np.array([params.k_max, params.zeta_s, params.fd_step, params.z_guard,
                              params.zeta], dtype=np.float64)
        self._obs = obstacle_table(n_slots)
        self._obs_t = 0.0
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
        self._fallback_until = -math.inf
        self._fallback_v0 = 0.0
        self.fallback_count = 0
        self.guard_total = 0
        self._load_kernels()

    def _pack(self, target_speed_mps: float, lateral_reference_m: float = 0.0,
              lateral_weight: float | None = None) -> np.ndarray:
        return pack_params(self.params, target_speed_mps, lateral_reference_m,
                           lateral_weight=lateral_weight, row_scaling=self.params.row_scaling)

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
        cgmres_updates(u, np.zeros_like(u), xs[0], xs[0], 0.0, 0.01, 1, hz, 0.0, prm, tab, self.w,
                       self.meta, self.coef, self._cfg, self._work, xs, np.zeros(4))

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
        self._obs = obstacle_table(self.n_slots)
        self._fallback_until = -math.inf
        self.fallback_count = 0
        self.guard_total = 0
        self.subupdate_times_s.clear()

    def set_cruise_speed(self, cruise_speed_mps: float) -> None:
        """The run's cruise set-point [m/s]: the target ramp decelerates toward a
        set-point at or above it at ``set_speed_decel_mps2``, toward a lower one (the
        behaviour lowered it to follow) at ``target_decel_mps2`` (:class:`TargetSpeedRamp`).
        Until it is given (after ``reset``), ``target_decel_mps2`` everywhere."""
        self._ramp.cruise_speed_mps = float(cruise_speed_mps)

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
        self._obs = obstacle_table(self.n_slots)
        self._fallback_until = -math.inf

    @property
    def ocp_target_speed_mps(self) -> float:
        """The rate-limited target speed the OCP currently uses."""
        return self._vt

    def horizon_now(self, t_s: float) -> float:
        """The grown horizon T(t_s) [s]."""
        return self.params.horizon_s * (1.0 - math.exp(-self.params.horizon_growth_rate
                                                       * max(t_s - self._hz[0], 0.0)))

    def _initialise(self, t_s: float, x0: np.ndarray) -> None:
        self._hz[0] = t_s
        prm = self._pack(self._vt, self._yr, lateral_weight=self._cy)
        stage_init(x0, 0.0, prm, self._obs, self.meta, self.coef, self.params.n_stages, self._u)
        self._udot[:] = 0.0
        self._initialised = True

    # ------------------------------------------------------------ obstacle slots
    def _match_obstacles(self, t_s: float, obstacles: Obstacles, horizon: float,
                         prm: np.ndarray) -> None:
        """Keep each obstacle in its slot; fade slots in and out (see module docstring)."""
        if self.n_slots == 0:
            return
        self._advance_slots(max(t_s - self._obs_t, 0.0))
        used, assign = self._assign_known(obstacles)
        fade_rate = 1.0 / self.params.obstacle_fade_s
        # Slots whose obstacle is gone fade out, then become inert.
        tab = self._obs
        for j in range(self.n_slots):
            if tab[j, 6] > 0.5 and not used[j]:
                tab[j, 8] = -fade_rate
                if tab[j, 7] <= 0.0 and self._multipliers_gone(j):
                    self._free_slot(j)
        for q in range(assign.shape[0]):
            new = assign[q] < 0
            if new:
                j_new = self._take_slot(used)
                if j_new < 0:
                    continue
                assign[q] = j_new
                used[j_new] = True
            self._fill_slot(int(assign[q]), obstacles, q, new, fade_rate, horizon, prm)
        self._obs_t = t_s

    def _advance_slots(self, dt: float) -> None:
        """Every active slot to dt later: constant velocity, weight ramp."""
        tab = self._obs
        for j in range(self.n_slots):
            if tab[j, 6] > 0.5:
                tab[j, 0] += tab[j, 2] * dt
                tab[j, 1] += tab[j, 3] * dt
                tab[j, 7] = min(max(tab[j, 7] + tab[j, 8] * dt, 0.0), 1.0)

    def _assign_known(self, obstacles: Obstacles) -> tuple[np.ndarray, np.ndarray]:
        """(used (K,) bool, assign (n,) slot or -1): each of the first n = min(count, K)
        obstacles matched to the nearest active slot within 3 m / half its A along
        and 1 m across."""
        tab = self._obs
        k = self.n_slots
        n_in = min(obstacles.count, k)
        used = np.zeros(k, dtype=bool)
        assign = -np.ones(n_in, dtype=np.int64)
        for q in range(n_in):
            best, best_d = -1, math.inf
            for j in range(k):
                if used[j] or tab[j, 6] < 0.5:
                    continue
                ds = abs(float(obstacles.s_m[q]) - tab[j, 0])
                dy = abs(float(obstacles.y_m[q]) - tab[j, 1])
                if ds < max(3.0, 0.5 * tab[j, 4]) and dy < 1.0 and ds + dy < best_d:
                    best, best_d = j, ds + dy
            if best >= 0:
                used[best] = True
                assign[q] = best
        return used, assign

    def _multipliers_gone(self, j: int) -> bool:
        """Slot j's multipliers mu_ij have decayed (|mu| <= 1e-3 Cz at every stage): only
        then do its rows become the trivial ones. Freed while mu still lags behind the
        faded weight, the mu dc/dx terms vanish from every costate at once and E jumps
        (to ~4 one step after the fade-out, before this check)."""
        p = self.params
        m = self.stage_width
        mu = self._u.reshape(p.n_stages, m)[:, 2 + self.n_slots + j]
        return bool(np.max(np.abs(mu)) <= 1e-3 * p.c_z)

    def _free_slot(self, j: int) -> None:
        self._obs[j] = obstacle_table(1)[0]
        deactivate_slot(self._u, self.params.n_stages, self.n_slots, j)

    def _take_slot(self, used: np.ndarray) -> int:
        """A free slot for a new obstacle: an inert one, else the weakest fading one
        (its multipliers are the smallest), freed; -1 if every slot is in use."""
        tab = self._obs
        free = [j for j in range(self.n_slots) if not used[j] and tab[j, 6] < 0.5]
        if free:
            return free[0]
        fading = [j for j in range(self.n_slots) if not used[j]]
        if not fading:
            return -1
        jf = min(fading, key=lambda jj: tab[jj, 7])
        self._free_slot(jf)
        return jf

    def _fill_slot(self, j: int, obstacles: Obstacles, q: int, new: bool, fade_rate: float,
                   horizon: float, prm: np.ndarray) -> None:
        """Write obstacle q into slot j; a new one fades in (at full weight at the very
        first update) and its Z, mu start where its rows vanish."""
        tab = self._obs
        tab[j, 0] = float(obstacles.s_m[q])
        tab[j, 1] = float(obstacles.y_m[q])
        tab[j, 2] = float(obstacles.speed_s_mps[q])
        tab[j, 3] = float(obstacles.speed_y_mps[q])
        tab[j, 4] = max(float(obstacles.semi_a_m[q]), 1e-3)
        tab[j, 5] = max(float(obstacles.semi_b_m[q]), 1e-3)
        if new:
            tab[j, 6] = 1.0
            tab[j, 7] = 0.0 if self._initialised else 1.0
        tab[j, 8] = fade_rate if tab[j, 7] < 1.0 else 0.0
        if new and self._initialised:
            activate_slot(self._u, self._xs, horizon, 0.0, self.w, prm, tab, j)

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
        prm = self._pack(self._vt, yr, lateral_weight=cy)
        horizon_prev = self.horizon_now(self._t_prev) if self._initialised else 0.0
        self._match_obstacles(t_s, obstacles, horizon_prev, prm)
        fallback = False
        guards = 0
        if not self._initialised:
            self._yr = yr
            self._cy = cy
            self._initialise(t_s, x0)
            self._stats[:] = 0.0
            self._final_residual(t_s, x0, prm)
        else:
            guards = self._continue(t_s, x0, dt_s, yr, cy, prm)
            e = float(self._stats[0])
            if self._stats[2] > 0.5 or not math.isfinite(e) or e > p.fallback_residual:
                fallback = True
        self.guard_total += guards
        self._t_prev = t_s
        self._x_prev = x0
        self._yr = yr
        self._cy = cy
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

    def _continue(self, t_s: float, x0: np.ndarray, dt_s: float, yr: float, cy: float,
                  prm: np.ndarray) -> int:
        """``sub_updates`` continuation updates from the previous update to (t_s, x0);
        yr and Cy move linearly from their previous values. Returns the guard count."""
        p = self.params
        dt = t_s - self._t_prev
        if not dt > 0:
            dt = dt_s
        # yr at the start of the interval and its rate (restored to yr afterwards).
        prm[_P_YREF] = self._yr
        prm[_P_YREFD] = (yr - self._yr) / dt
        prm[_P_CY] = self._cy
        prm[_P_CYR] = (cy - self._cy) / dt
        guards = 0
        if self.time_each_subupdate:
            n_sub = p.sub_updates
            ddt = dt / n_sub
            xa = self._x_prev.copy()
            for k in range(n_sub):
                xb = self._x_prev + (k + 1) / n_sub * (x0 - self._x_prev)
                prm[_P_YREF] = self._yr + prm[_P_YREFD] * k * ddt
                prm[_P_CY] = self._cy + prm[_P_CYR] * k * ddt
                t0 = time.perf_counter()
                cgmres_updates(self._u, self._udot, xa, xb, self._t_prev + k * ddt, ddt, 1,
                               self._hz, self._t_prev + (k + 1) * ddt - t_s, prm,
                               self._obs, self.w, self.meta, self.coef, self._cfg,
                               self._work, self._xs, self._stats)
                self.subupdate_times_s.append(time.perf_counter() - t0)
                guards += int(self._stats[1])
                xa = xb
        else:
            cgmres_updates(self._u, self._udot, self._x_prev, x0, self._t_prev, dt,
                           p.sub_updates, self._hz, 0.0, prm, self._obs, self.w,
                           self.meta, self.coef, self._cfg, self._work, self._xs,
                           self._stats)
            guards = int(self._stats[1])
        prm[_P_YREF] = yr
        prm[_P_YREFD] = 0.0
        prm[_P_CY] = cy
        prm[_P_CYR] = 0.0
        return guards

    # ------------------------------------------------------------------ helpers
    def _final_residual(self, t_s: float, x0: np.ndarray, prm: np.ndarray) -> None:
        f = np.empty(self._u.shape[0])
        ps = np.empty((self.params.n_stages + 1, 12))
        ocp_residual(self._u, x0, self.horizon_now(t_s), 0.0, prm, self._obs, self.w, self.meta,
                     self.coef, self._xs, ps, f)
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
        return self._obs
