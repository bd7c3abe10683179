"""Ipopt outer loop: the C/GMRES problem (docs/method.md §2-§5) solved by an NLP solver.

This is the comparison baseline of docs/method.md §8, result 3: the *same* Euler-discretised
J3 problem as :class:`controllers.two_loop.outer.cgmres.CgmresOuter`, solved to convergence by
Ipopt (through CasADi) at every outer update, warm-started from the previous
solution shifted by the elapsed time (primal *and* dual).

The NLP (the discretised problem, its two formulations, the path geometry) is
:mod:`controllers.two_loop.outer.ipopt_nlp`; the warm start (the previous solution
shifted to now) is :mod:`controllers.two_loop.outer.ipopt_warmstart`.

Differences from CgmresOuter, all outside the discretised OCP: the horizon is the full T
of ``stage_times(params)`` from the first update (Ipopt needs no growing horizon to
start), and the K obstacles of the update are the K constraints (no inert empty slots).
Like CgmresOuter, the target speed fed to the OCP is rate-limited (OcpParams.target_accel_mps2 /
target_decel_mps2, starting from the speed given to ``reset``).

Reported quantities
-------------------
* ``residual``: Ipopt's final optimality error max(inf_pr, inf_du) of the last
  iterate (from ``solver.stats()['iterations']``; inf_du is Ipopt's *scaled* dual
  infeasibility, inf_pr the unscaled max constraint violation). It is not the
  dimensionless E = ||F||inf of C/GMRES, but it is the analogous KKT error
  (tests check that Ipopt's solutions zero the OCP's F to < 1e-6). ``inf`` if
  Ipopt stopped before its first iterate (never NaN).
* ``fallback``: Ipopt did not report success (``stats()['success']`` False: max_iter,
  max_wall_time, infeasibility, restoration failure, ...) or returned non-finite
  values. The plan is then the last successful solution shifted to now and
  re-rolled from the measured state (while it is younger than half the horizon),
  else a brake-along-the-lane plan (OcpParams.fallback_decel_mps2).
  ``fallback_count`` counts them. The next solve is warm-started from that plan.
* ``solve_s``: wall time of the whole update (warm-start shift, Ipopt call, plan
  extraction), ``time.perf_counter``. Building the NLP (once per K) is excluded and
  recorded in ``build_s``.
* ``guard_fired``: always 0 (Ipopt keeps Z within its bounds itself).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.behaviour.types import Obstacles
from controllers.two_loop.outer.ipopt_nlp import (
    OBS_COLS,
    J3Weights,
    Nlp,
    PathLike,
    checked_stage_times,
    get_nlp,
    pack_obstacles,
    path_lookup,
    solve_nlp,
    weights_from_params,
)
from controllers.two_loop.outer.ipopt_warmstart import Solution, shift_solution, with_obstacles
from controllers.two_loop.outer.params import FORMULATIONS, IpoptParams
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.outer.target_ramp import CruiseSetPoint, TargetSpeedRamp

__all__ = ["FORMULATIONS", "IpoptOuter", "IpoptOuterOptions", "UpdateStats"]


@dataclass
class UpdateStats:
    """Per-update diagnostics kept by :class:`IpoptOuter` (``history``)."""

    t_s: float
    k: int
    iterations: int
    status: str
    success: bool
    residual: float
    solve_s: float  # wall time of the update
    ipopt_s: float  # wall time of the Ipopt call alone
    ipopt_cpu_s: float  # this thread's CPU time in the Ipopt call (robust to machine load)


@dataclass(frozen=True)
class IpoptOuterOptions:
    """The solver settings of :class:`IpoptOuter` outside :class:`IpoptParams`.

    max_wall_s: Ipopt's max_wall_time [s] (None: unlimited). omega_max_radps,
    v_max_factor, v_cap_floor_mps: the input bounds |omega| <= omega_max_radps [rad/s]
    and 0 <= V <= max(v_max_factor Vt, v_cap_floor_mps) [m/s]. brake_decel_mps2: the
    deceleration [m/s²] of the brake-along-lane fallback (None: the params'
    ``fallback_decel_mps2``). warm_mu: Ipopt's mu_init for warm-started solves.
    path_grid_m: the breakpoint spacing [m] of the path lookup for paths without knots.
    """

    max_wall_s: float | None = None
    omega_max_radps: float = 0.5
    v_max_factor: float = 1.5
    v_cap_floor_mps: float = 5.0
    brake_decel_mps2: float | None = None
    warm_mu: float = 1e-6
    path_grid_m: float = 1.0


class IpoptOuter(CruiseSetPoint):
    """OuterPlanner: the J3 SPMM OCP solved by Ipopt every update (see the module doc).

    path: a ``controllers.path.frenet.FrenetPath`` (or anything with length_m, gamma, kappa).
    params: :class:`IpoptParams`: the OCP's weights, horizon and stages, and Ipopt's
    formulation ("barrier": C/GMRES's slack + log barrier; "hard": c_j >= 0), max_iter
    and tol (acceptable_tol 1e2 * tol). n_slots: the number of obstacle slots K of the
    controller (the NLP is built for the K obstacles of each update; ``n_slots`` sets
    :meth:`stage_unknowns`'s layout and what :meth:`prepare` builds by default).
    options: the solver settings outside ``params`` (:class:`IpoptOuterOptions`: Ipopt's
    wall-time limit, the input bounds, the fallback's deceleration, the warm mu_init,
    the path grid; None: its defaults). weights, stage_times_s: override the ones
    derived from ``params`` (tests; e.g. C/GMRES's current grown horizon).
    """

    updates_per_period = 1  # one NLP solve per control period

    def __init__(self, path: PathLike, params: IpoptParams, n_slots: int = 3, *,
                 options: IpoptOuterOptions | None = None, weights: J3Weights | None = None,
                 stage_times_s: np.ndarray | None = None) -> None:
        if not isinstance(params, IpoptParams):
            raise TypeError(f"IpoptOuter needs IpoptParams, got {type(params).__name__}")
        if not (isinstance(n_slots, int) and n_slots >= 0):
            raise ValueError(f"n_slots must be an int >= 0, got {n_slots!r}")
        opts = options if options is not None else IpoptOuterOptions()
        self.path = path
        self.params = params
        self.n_slots = n_slots
        self.formulation = params.formulation
        self.weights = weights if weights is not None else weights_from_params(params)
        tau = stage_times_s if stage_times_s is not None else checked_stage_times(params)
        self.tau = np.asarray(tau, dtype=np.float64)
        self.n = int(self.tau.shape[0] - 1)
        self.dtau = np.diff(self.tau)
        self.omega_max = float(opts.omega_max_radps)
        self.v_max_factor = float(opts.v_max_factor)
        self.v_cap_floor = float(opts.v_cap_floor_mps)
        self.brake_decel = float(opts.brake_decel_mps2 if opts.brake_decel_mps2 is not None
                                 else params.fallback_decel_mps2)
        self.lookup = path_lookup(path, opts.path_grid_m)
        self._cold_opts: dict[str, Any] = {
            "print_level": 0, "sb": "yes", "max_iter": int(params.max_iter),
            "tol": float(params.tol), "acceptable_tol": 100.0 * float(params.tol),
            "acceptable_iter": 5, "mu_strategy": "monotone",
            # Ipopt's defaults, stated: the exact Hessian of the Lagrangian (CasADi's
            # algorithmic derivatives) and the MUMPS sparse linear solver.
            "hessian_approximation": "exact", "linear_solver": "mumps",
        }
        if opts.max_wall_s is not None:
            self._cold_opts["max_wall_time"] = float(opts.max_wall_s)
        self._warm_opts = dict(self._cold_opts)
        self._warm_opts.update({
            "warm_start_init_point": "yes", "mu_init": float(opts.warm_mu),
            "warm_start_bound_push": 1e-6, "warm_start_bound_frac": 1e-6,
            "warm_start_slack_bound_push": 1e-6, "warm_start_slack_bound_frac": 1e-6,
            "warm_start_mult_bound_push": 1e-6,
        })
        self.fallback_count = 0
        self.update_count = 0
        self.history: list[UpdateStats] = []
        self.last_iterations = 0
        self.last_status = ""
        self.build_s = 0.0
        self._built: set[int] = set()
        self._prev: Solution | None = None
        self._vt = 0.0
        self._vt_set = False
        self._ramp = TargetSpeedRamp(params.target_accel_mps2, params.target_decel_mps2,
                                     params.target_jerk_mps3, params.set_speed_decel_mps2)
        self._t_prev: float | None = None
        self._last_success_t: float | None = None

    def horizon_growth(self, elapsed_s: float) -> float:
        """1: the horizon is the full T from the first update (no growing horizon)."""
        del elapsed_s
        return 1.0

    # -- set-up -------------------------------------------------------------

    def prepare(self, max_obstacles: int | None = None) -> float:
        """Build the NLPs for K = 0..max_obstacles (default n_slots) now (else lazily);
        returns the build time [s]."""
        t0 = time.perf_counter()
        k_max = self.n_slots if max_obstacles is None else max_obstacles
        for k in range(k_max + 1):
            for warm in (False, True):
                self._nlp(k, warm)
        return time.perf_counter() - t0

    def _nlp(self, k: int, warm: bool) -> Nlp:
        nlp = get_nlp(self.lookup, self.n, k, self.formulation,
                      self._warm_opts if warm else self._cold_opts)
        if id(nlp) not in self._built:
            self._built.add(id(nlp))
            self.build_s += nlp.build_s
        return nlp

    def reset(self, x0: np.ndarray, target_speed_mps: float) -> None:
        """Forget the previous solution; the next update is a cold start, its guess at
        the OCP target speed ``target_speed_mps`` (the measured speed). The cruise
        set-point is forgotten too (:meth:`set_cruise_speed`)."""
        self._prev = None
        self._vt = float(target_speed_mps)
        self._vt_set = True
        self._ramp.reset(self._vt)
        self._ramp.cruise_speed_mps = math.inf
        self._t_prev = None
        self._last_success_t = None
        self.fallback_count = 0
        self.update_count = 0
        self.history.clear()

    def restart(self, x0: np.ndarray, target_speed_mps: float,
                target_accel_mps2: float = 0.0) -> None:
        """Forget the previous solution (the next update is a cold start) but not the
        run's counters; the target-speed ramp continues from ``target_speed_mps`` with
        acceleration ``target_accel_mps2`` (as :meth:`CgmresOuter.restart`)."""
        del x0
        vt = float(target_speed_mps)
        acc = float(target_accel_mps2)
        self._prev = None
        self._vt = vt if math.isfinite(vt) and vt > 0.0 else 0.0
        self._vt_set = True
        self._ramp.reset(self._vt)
        if math.isfinite(acc):
            self._ramp.ramp_accel_mps2 = acc
        self._t_prev = None
        self._last_success_t = None

    # -- one update ---------------------------------------------------------

    def update(self, t_s: float, x0: np.ndarray, obstacles: Obstacles,
               target_speed_mps: float, dt_s: float,
               lateral_reference_m: float = 0.0,
               lateral_weight: float | None = None) -> OuterPlan:
        x0 = np.asarray(x0, dtype=np.float64).reshape(3)
        yr = float(lateral_reference_m)
        if not math.isfinite(yr):
            raise ValueError(f"lateral_reference_m must be finite, got {lateral_reference_m!r}")
        vt = self._ramped_target(t_s, float(target_speed_mps))
        k = obstacles.count
        obs = pack_obstacles(obstacles)
        warm = self._prev is not None
        nlp = self._nlp(k, warm)
        t_start = time.perf_counter()

        args = self._solver_args(nlp, t_s, x0, vt, obs, yr, lateral_weight)
        res = solve_nlp(nlp, args)
        residual = res.residual
        fallback = not (res.success and np.all(np.isfinite(res.w))
                        and np.all(np.isfinite(res.lam_g)))
        if not fallback:
            accepted = self._unpack(nlp, t_s, x0, obs, res.w, res.lam_x, res.lam_g)
            self._last_success_t = float(t_s)
        else:
            self.fallback_count += 1
            accepted = self._fallback_plan(t_s, x0, vt, obs)
            if not np.isfinite(residual):
                residual = math.inf  # Ipopt stopped before a first iterate: never NaN
        self._prev = accepted
        self._vt = vt
        self._t_prev = float(t_s)
        plan = OuterPlan(stage_times_s=self.tau.copy(), states=accepted.x.copy(),
                         speeds_mps=accepted.u[:, 0].copy(),
                         headings_rad=accepted.x[:-1, 2].copy(), residual=float(residual),
                         fallback=fallback, guard_fired=0,
                         solve_s=time.perf_counter() - t_start, target_speed_mps=vt)
        self.update_count += 1
        self.last_iterations = res.iterations
        self.last_status = res.status
        self.history.append(UpdateStats(t_s=float(t_s), k=k, iterations=res.iterations,
                                        status=res.status, success=res.success,
                                        residual=plan.residual, solve_s=plan.solve_s,
                                        ipopt_s=res.wall_s, ipopt_cpu_s=res.cpu_s))
        return plan

    def _solver_args(self, nlp: Nlp, t_s: float, x0: np.ndarray, vt: float, obs: np.ndarray,
                     yr: float, lateral_weight: float | None) -> dict[str, Any]:
        """The arguments of the Ipopt call of an update at ``t_s`` [s] from state ``x0``
        with OCP target speed ``vt`` [m/s], packed obstacles ``obs``, lateral reference
        ``yr`` [m] and Cy override ``lateral_weight``: the warm start (the previous
        solution shifted to now, else a lane-following guess, with multipliers when
        warm), the input bounds and the NLP parameter vector."""
        warm = self._prev is not None
        if self._prev is not None:
            guess = shift_solution(self._prev, t_s, self.tau, x0, obs, self.weights)
        else:
            guess = self._initial_guess(t_s, x0, vt, obs)
        w0, lam_x0, lam_g0 = self._pack_guess(nlp, guess, x0)
        lbx, ubx = self._input_bounds(nlp, vt)
        w0 = np.clip(w0, lbx, ubx)
        wts = self.weights.as_array()
        if lateral_weight is not None:
            wts[0] = float(lateral_weight)  # Cy of this update (scheduled by the caller)
        p = np.concatenate([x0, [vt], self.dtau, obs.reshape(-1), wts, [yr]])
        args: dict[str, Any] = {"x0": w0, "p": p, "lbx": lbx, "ubx": ubx,
                                "lbg": nlp.lbg, "ubg": nlp.ubg}
        if warm:
            args["lam_x0"] = lam_x0
            args["lam_g0"] = lam_g0
        return args

    def _input_bounds(self, nlp: Nlp, vt: float) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) bounds of the NLP's variables: 0 <= V <= max(v_max_factor vt,
        v_cap_floor) [m/s], |omega| <= omega_max [rad/s], Z >= 0, the nodes free."""
        v_hi = max(self.v_max_factor * vt, self.v_cap_floor)
        lbx = np.full(nlp.n_w, -np.inf)
        ubx = np.full(nlp.n_w, np.inf)
        lbx[nlp.iu[:, 0]] = 0.0
        ubx[nlp.iu[:, 0]] = v_hi
        lbx[nlp.iu[:, 1]] = -self.omega_max
        ubx[nlp.iu[:, 1]] = self.omega_max
        zi = nlp.iz[nlp.iz >= 0]
        lbx[zi] = 0.0
        return lbx, ubx

    def stage_unknowns(self, n_slots: int | None = None) -> np.ndarray:
        """The last accepted solution in C/GMRES's layout U = [V, omega, Z_1..K, mu_1..K]_i.

        Barrier formulation only. mu_ij = Ipopt's multiplier of c_j - Z_ij^2 = 0 divided
        by dtau_i (the C/GMRES Hamiltonian carries mu per unit time). Stage 0 and slots
        beyond the obstacles of the last update get the trivial Z = 1, mu = 0 of
        ``controllers.two_loop.outer.ocp``. Shape (N * (2 + 2 n_slots),); n_slots defaults to
        the planner's own.
        """
        if self.formulation != "barrier":
            raise ValueError("stage_unknowns: only the barrier formulation has Z and mu")
        if self._prev is None:
            raise ValueError("stage_unknowns: no solution yet")
        k_slots = int(self.n_slots if n_slots is None else n_slots)
        sol = self._prev
        k = sol.obs.shape[0]
        if k > k_slots:
            raise ValueError(f"stage_unknowns: {k} obstacles > {k_slots} slots")
        m = 2 + 2 * k_slots
        out = np.zeros((self.n, m))
        out[:, 0:2] = sol.u
        out[:, 2:2 + k_slots] = 1.0
        out[1:, 2:2 + k] = sol.z[1:, :k]
        out[1:, 2 + k_slots:2 + k_slots + k] = sol.lam_obs[1:self.n, :k]
        return out.ravel()

    @property
    def ocp_target_speed_mps(self) -> float:
        """The rate-limited target speed the OCP currently uses (as CgmresOuter)."""
        return self._vt

    def _ramped_target(self, t_s: float, target: float) -> float:
        """The jerk-limited target-speed ramp shared with CgmresOuter."""
        if self._t_prev is None:
            if not self._vt_set:
                self._ramp.reset(target)
            return self._ramp.speed_mps
        return self._ramp.update(target, max(float(t_s) - self._t_prev, 0.0))

    # -- guesses, packing ---------------------------------------------------

    def _rollout(self, x0: np.ndarray, speeds: np.ndarray, follow_lane: bool,
                 omegas: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Euler rollout of (36) from x0; with follow_lane, omega steers theta onto gamma."""
        n = self.n
        x = np.empty((n + 1, 3))
        u = np.empty((n, 2))
        x[0] = x0
        for i in range(n):
            s, y, th = x[i]
            gam = float(self.lookup.gamma_np(s)[0])
            kap = float(self.lookup.kappa_np(s)[0])
            v = float(speeds[i])
            if omegas is not None:
                om = float(omegas[i])
            elif follow_lane:
                # Heading rate that follows the lane's turning and removes the heading
                # error over ~1 s (a smooth, feasible initial guess; not optimal).
                om = kap * v - (th - gam) / max(1.0, self.dtau[i])
            else:
                om = 0.0
            om = float(np.clip(om, -self.omega_max, self.omega_max))
            e = th - gam
            d = 1.0 - y * kap
            x[i + 1] = (s + v * math.cos(e) / d * self.dtau[i], y + v * math.sin(e) * self.dtau[i],
                        th + om * self.dtau[i])
            u[i] = (v, om)
        return x, u

    def _initial_guess(self, t_s: float, x0: np.ndarray, vt: float, obs: np.ndarray) -> Solution:
        speeds = np.full(self.n, vt)
        x, u = self._rollout(x0, speeds, follow_lane=True)
        return self._lane_solution(t_s, x, u, obs)

    def _lane_solution(self, t_s: float, x: np.ndarray, u: np.ndarray,
                       obs: np.ndarray) -> Solution:
        """The solution of the rollout ``x``, ``u`` at ``t_s`` [s], zero multipliers, its
        slacks and multipliers for the obstacles ``obs`` from :func:`with_obstacles`."""
        return with_obstacles(Solution(t_s, self.tau.copy(), x, u, np.zeros((self.n, 0)),
                                       np.zeros((0, OBS_COLS)), np.zeros((self.n, 3)),
                                       np.zeros((self.n + 1, 0)), np.zeros((self.n, 2)),
                                       np.zeros((self.n, 0))), obs)

    def _fallback_plan(self, t_s: float, x0: np.ndarray, vt: float, obs: np.ndarray) -> Solution:
        prev = self._prev
        half = 0.5 * float(self.tau[-1])
        last_ok = self._last_success_t
        if prev is not None and last_ok is not None and t_s - last_ok <= half:
            shifted = shift_solution(prev, t_s, self.tau, x0, obs, self.weights)
            x, u = self._rollout(x0, shifted.u[:, 0], follow_lane=False, omegas=shifted.u[:, 1])
            shifted.x = x
            shifted.u = u
            return shifted
        v0 = float(prev.u[0, 0]) if prev is not None else vt
        speeds = np.maximum(v0 - self.brake_decel * self.tau[:-1], 0.0)
        x, u = self._rollout(x0, speeds, follow_lane=True)
        return self._lane_solution(t_s, x, u, obs)

    def _pack_guess(self, nlp: Nlp, g: Solution, x0: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = np.zeros(nlp.n_w)
        lam_x = np.zeros(nlp.n_w)
        lam_g = np.zeros(nlp.n_g)
        w[nlp.iu[:, 0]] = g.u[:, 0]
        w[nlp.iu[:, 1]] = g.u[:, 1]
        lam_x[nlp.iu[:, 0]] = g.lam_u[:, 0] * self.dtau
        lam_x[nlp.iu[:, 1]] = g.lam_u[:, 1] * self.dtau
        nodes = np.arange(1, self.n + 1)
        w[nlp.ix[nodes, 0]] = g.x[1:, 0] - x0[0]
        w[nlp.ix[nodes, 1]] = g.x[1:, 1]
        w[nlp.ix[nodes, 2]] = g.x[1:, 2]
        lam_g[nlp.gdyn.ravel()] = g.lam_dyn.ravel()
        dt_node = np.concatenate([self.dtau, [self.dtau[-1]]])
        for j in range(nlp.k):
            for i in range(self.n + 1):
                if i < self.n and nlp.iz[i, j] >= 0:
                    w[nlp.iz[i, j]] = g.z[i, j]
                    lam_x[nlp.iz[i, j]] = g.lam_z[i, j] * self.dtau[i]
                if nlp.gobs[i, j] >= 0:
                    lam_g[nlp.gobs[i, j]] = g.lam_obs[i, j] * dt_node[i]
        return (np.nan_to_num(w), np.nan_to_num(lam_x), np.nan_to_num(lam_g))

    def _unpack(self, nlp: Nlp, t_s: float, x0: np.ndarray, obs: np.ndarray, w: np.ndarray,
                lam_x: np.ndarray, lam_g: np.ndarray) -> Solution:
        n, k = self.n, nlp.k
        x = np.empty((n + 1, 3))
        x[0] = x0
        nodes = np.arange(1, n + 1)
        x[1:, 0] = x0[0] + w[nlp.ix[nodes, 0]]
        x[1:, 1] = w[nlp.ix[nodes, 1]]
        x[1:, 2] = w[nlp.ix[nodes, 2]]
        u = np.stack([w[nlp.iu[:, 0]], w[nlp.iu[:, 1]]], axis=1)
        lam_u = np.stack([lam_x[nlp.iu[:, 0]], lam_x[nlp.iu[:, 1]]], axis=1) / self.dtau[:, None]
        z = np.full((n, k), np.nan)
        lam_z = np.zeros((n, k))
        lam_obs = np.zeros((n + 1, k))
        dt_node = np.concatenate([self.dtau, [self.dtau[-1]]])
        for j in range(k):
            for i in range(n + 1):
                if i < n and nlp.iz[i, j] >= 0:
                    z[i, j] = w[nlp.iz[i, j]]
                    lam_z[i, j] = lam_x[nlp.iz[i, j]] / self.dtau[i]
                if nlp.gobs[i, j] >= 0:
                    lam_obs[i, j] = lam_g[nlp.gobs[i, j]] / dt_node[i]
        lam_dyn = lam_g[nlp.gdyn.ravel()].reshape(n, 3)
        return Solution(float(t_s), self.tau.copy(), x, u, z, obs.copy(), lam_dyn, lam_obs,
                         lam_u, lam_z)
