"""Ipopt outer loop: the C/GMRES problem (docs/method.md §2-§5) solved by an NLP solver.

This is the comparison baseline of docs/method.md §8, result 3: the *same* Euler-discretised
J3 problem as :class:`controllers.two_loop.outer.cgmres.CgmresOuter`, solved to convergence by
Ipopt (through CasADi) at every outer update, warm-started from the previous
solution shifted by the elapsed time (primal *and* dual).

Discretised problem (identical to the C/GMRES one)
---------------------------------------------------
Augmented SPMM (36), Frenet frame, x = (s, y, theta), u = (V, omega)::

    e = theta - gamma(s),  D = 1 - y kappa(s)
    f1 = V cos(e) / D,  f2 = V sin(e),  f3 = omega
    x_{i+1} = x_i + f(x_i, u_i) dtau_i,    i = 0..N-1,   x_0 = measured state

with ``dtau_i = diff(stage_times(params))`` (uniform or Chebyshev, as C/GMRES), and::

    J = sum_i L(x_i, u_i, Z_i, tau_i) dtau_i + m(x_N)
    L = Cy (y - yr)^2 + Cyd f2^2 + Csd (f1 - Vt)^2 + Cwd omega^2 - Cz sum_j ln(Z_ij + zeta)
    m = CyT (y_N - yr)^2 + CeT (theta_N - gamma(s_N))^2   (the OCP's terminal cost)

yr: the lateral reference of the update (``update(..., lateral_reference_m=)``), an NLP
parameter constant over the horizon, as in C/GMRES (0: the paper's Cy y^2); Cy may be
overridden per update (``lateral_weight=``), also an NLP parameter.

with the weights of :class:`controllers.two_loop.outer.params.OcpParams` (c_y, c_ydot,
c_sdot, c_thetadot, c_z, zeta, c_y_terminal, c_e_terminal). Differences from CgmresOuter,
all outside the discretised OCP: the horizon is the full T of ``stage_times(params)``
from the first update (Ipopt needs no growing horizon to start), and the K obstacles
of the update are the K constraints (no inert empty slots). Like CgmresOuter, the
target speed fed to the OCP is rate-limited (OcpParams.target_accel_mps2 /
target_decel_mps2, starting from the speed given to ``reset``).

Obstacle j (ellipse (42), constant-velocity prediction over the horizon)::

    c_j(s, y, tau) = (s - s_j - vs_j tau)^2 / A_j^2 + (y - y_j - vy_j tau)^2 / B_j^2 - 1

Two formulations (``formulation=``):

* ``"barrier"`` (default): the C/GMRES form of docs/method.md §4: slack Z_ij per stage i = 1..N-1,
  equality ``c_j(x_i, tau_i) - Z_ij^2 = 0`` and the barrier ``-Cz ln(Z_ij + zeta)`` in L.
  The stage-0 constraint cannot change the solution (x_0 is measured), so, like
  C/GMRES, it is left out. Z_ij >= 0 is imposed as a bound (Z -> -Z leaves the
  constraint unchanged and the barrier prefers the positive root; the bound is
  inactive at the solution since the barrier keeps Z away from 0). At a KKT point
  this is the same stationarity system F(U) = 0 that C/GMRES tracks, so the plans
  agree to the solvers' tolerances.
* ``"hard"``: the paper's Ipopt baseline: no slack, no barrier, the inequality
  ``c_j(x_i, tau_i) >= 0`` at the nodes i = 1..N (the terminal node included, a
  choice: nothing then prefers ending a plan inside the ellipse). Its plans ride on
  the ellipse boundary: when the ego follows its plan exactly it deadlocks there
  (docs/method.md §9: x_1 = x_0 + V_0 dtau_0 (cos e_0, sin e_0) with e_0 measured, so
  once x_0 touches the ellipse heading into it only V_0 ~ 0 is feasible); on the
  plant see docs/two_loop.md §8.

Decision variables: V_i, omega_i (i = 0..N-1), Z_ij (barrier), and the nodes
x_1..x_N (multiple shooting, the Euler steps as equality constraints; ``s`` is
decision-variable-relative to the measured s_0 for conditioning). Bounds:
0 <= V <= max(v_max_factor * Vt, v_cap_floor_mps), |omega| <= omega_max_radps.

Path geometry
-------------
gamma(s) and kappa(s) enter the NLP as CasADi B-spline Functions built **once per
path** over the whole route (:class:`PathLookup`: for a ``FrenetPath`` an exact
re-expression of its C^2 quintic pieces, kappa the exact derivative). The NLP is
therefore built once per (path, N, K, formulation) and cached at module level
(K = number of obstacles in the problem, built lazily the first time K obstacles
are seen, or up front with :meth:`IpoptOuter.prepare`); everything that changes
per step (x_0, Vt, dtau, the obstacles, the cost weights) is an NLP parameter
(why not a path-independent NLP: docs/two_loop.md §8).

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
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from controllers.behaviour.types import Obstacles
from controllers.two_loop.outer.ocp import TargetSpeedRamp, stage_times
from controllers.two_loop.outer.params import (
    FORMULATIONS,
    CgmresParams,
    IpoptParams,
    OcpParams,
    ipopt_params,
)
from controllers.two_loop.outer.protocol import OuterPlan

__all__ = ["FORMULATIONS", "IpoptOuter", "PathLookup", "benchmark_ipopt", "benchmark_outer",
           "compare_with_cgmres", "ellipse_values"]

# Columns of the packed obstacle parameter block.
_OBS_COLS = 6  # s_m, y_m, speed_s_mps, speed_y_mps, semi_a_m, semi_b_m


class PathLike(Protocol):
    """What this module needs from ``controllers.path.frenet.FrenetPath``."""

    @property
    def length_m(self) -> float: ...

    def gamma(self, s: Any) -> Any: ...

    def kappa(self, s: Any) -> Any: ...


def _casadi() -> Any:
    try:
        import casadi
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("the Ipopt baseline needs CasADi: "
                          "pip install 'hwyeval[baselines]'") from exc
    return casadi


# ---------------------------------------------------------------------------
# Parameters taken from OcpParams (controllers.two_loop.outer.params)
# ---------------------------------------------------------------------------

@dataclass(frozen=True)
class J3Weights:
    """The J3 cost weights of OcpParams, in the order of the NLP's weight parameter."""

    c_y: float
    c_ydot: float
    c_sdot: float
    c_omega: float
    c_z: float
    zeta: float
    term_y: float
    term_e: float

    def as_array(self) -> np.ndarray:
        return np.array([self.c_y, self.c_ydot, self.c_sdot, self.c_omega, self.c_z,
                         self.zeta, self.term_y, self.term_e], dtype=np.float64)


_N_WEIGHTS = 8


def weights_from_params(params: OcpParams) -> J3Weights:
    """The J3 weights of an :class:`OcpParams` (same names, same units)."""
    return J3Weights(
        c_y=float(params.c_y), c_ydot=float(params.c_ydot), c_sdot=float(params.c_sdot),
        c_omega=float(params.c_thetadot), c_z=float(params.c_z), zeta=float(params.zeta),
        term_y=float(params.c_y_terminal), term_e=float(params.c_e_terminal))


def _stage_times(params: OcpParams) -> np.ndarray:
    tau = np.asarray(stage_times(params), dtype=np.float64)
    if tau.ndim != 1 or tau.shape[0] < 2 or not np.all(np.diff(tau) > 0) or tau[0] != 0.0:
        raise ValueError(f"stage_times(params) must be increasing from 0, got {tau!r}")
    return tau


# ---------------------------------------------------------------------------
# Path lookup: gamma/kappa as CasADi bspline interpolants, built once per path
# ---------------------------------------------------------------------------

def _eval_path(fn: Callable[[Any], Any], s: np.ndarray) -> np.ndarray:
    """Evaluate a path function on an array, whether or not it is vectorised."""
    try:
        out = np.asarray(fn(s), dtype=np.float64)
        if out.shape == s.shape:
            return out
    except (TypeError, ValueError):
        pass
    return np.array([float(fn(float(v))) for v in s], dtype=np.float64)


class PathLookup:
    """gamma(s), kappa(s) of one path, in numpy (the path's own) and in CasADi (for the NLP).

    CasADi side: gamma is a quintic B-spline with breakpoints every h and triple
    interior knots (the space of C^2 piecewise quintics), fitted by least squares to
    8 samples per interval; kappa is its exact derivative (a quartic B-spline).
    For a ``FrenetPath`` (piecewise quintic Hermite, C^2, on uniform knots read from
    ``tables()``) the breakpoints coincide with the path's knots, so the fit
    reproduces gamma and kappa to rounding error (~1e-15). Other paths get
    breakpoints every ``grid_m`` over [-pad_back_m, length_m + pad_fwd_m] (exact for
    straight lines and circles). Both splines are wrapped as non-inlined CasADi
    Functions so they enter the SX expression graph as call nodes.
    """

    def __init__(self, path: PathLike, grid_m: float = 1.0, pad_back_m: float = 50.0,
                 pad_fwd_m: float = 300.0) -> None:
        from scipy.interpolate import BSpline
        from scipy.sparse.linalg import spsolve

        ca = _casadi()
        self.path = path
        self.length_m = float(path.length_m)
        tables = getattr(path, "tables", None)
        if callable(tables):
            meta = np.asarray(tables()[0], dtype=np.float64)
            s_lo, h, n_seg = float(meta[0]), float(meta[1]), int(meta[2])
        else:
            s_lo = -float(pad_back_m)
            n_seg = max(int(math.ceil((self.length_m + pad_fwd_m - s_lo) / grid_m)), 4)
            h = (self.length_m + pad_fwd_m - s_lo) / n_seg
        brk = s_lo + h * np.arange(n_seg + 1)
        deg = 5
        knots = np.concatenate([np.full(deg + 1, brk[0]), np.repeat(brk[1:-1], 3),
                                np.full(deg + 1, brk[-1])])
        frac = (np.arange(8) + 0.5) / 8.0
        samples = (brk[:-1, None] + h * frac[None, :]).ravel()
        # Least squares through the sparse normal equations (banded, O(n); scipy's
        # make_lsq_spline QR took ~2 s for a 5 km route).
        design = BSpline.design_matrix(samples, knots, deg).tocsc()
        normal = (design.T @ design).tocsc()
        coeffs = spsolve(normal, design.T @ self.gamma_np(samples))
        spl = BSpline(knots, np.asarray(coeffs, dtype=np.float64), deg)
        dspl = spl.derivative()
        n_dc = len(dspl.t) - (deg - 1) - 1
        self.fit_error = float(np.abs(spl(samples) - self.gamma_np(samples)).max())
        g_bs = ca.Function.bspline("gamma_bs", [list(spl.t)], list(spl.c), [deg], 1, {})
        k_bs = ca.Function.bspline("kappa_bs", [list(dspl.t)], list(dspl.c[:n_dc]), [deg - 1],
                                   1, {})
        s_mx = ca.MX.sym("s")
        self.gamma_ca = ca.Function("gamma_path", [s_mx], [g_bs(s_mx)], {"never_inline": True})
        self.kappa_ca = ca.Function("kappa_path", [s_mx], [k_bs(s_mx)], {"never_inline": True})

    def gamma_np(self, s: np.ndarray | float) -> np.ndarray:
        return _eval_path(self.path.gamma, np.atleast_1d(np.asarray(s, dtype=np.float64)))

    def kappa_np(self, s: np.ndarray | float) -> np.ndarray:
        return _eval_path(self.path.kappa, np.atleast_1d(np.asarray(s, dtype=np.float64)))


_LOOKUPS: OrderedDict[tuple[int, float], PathLookup] = OrderedDict()
_SOLVERS: OrderedDict[tuple[Any, ...], _Nlp] = OrderedDict()
_CACHE_SIZE = 8


def path_lookup(path: PathLike, grid_m: float = 1.0) -> PathLookup:
    """The (cached) lookup of ``path``; the cache holds the path, so ids stay unique."""
    key = (id(path), float(grid_m))
    hit = _LOOKUPS.get(key)
    if hit is not None and hit.path is path:
        _LOOKUPS.move_to_end(key)
        return hit
    lookup = PathLookup(path, grid_m)
    _LOOKUPS[key] = lookup
    while len(_LOOKUPS) > _CACHE_SIZE:
        _LOOKUPS.popitem(last=False)
    return lookup


# ---------------------------------------------------------------------------
# The NLP, built once per (path, N, K, formulation, solver options)
# ---------------------------------------------------------------------------

@dataclass
class _Nlp:
    solver: Any
    n: int
    k: int
    formulation: str
    n_w: int
    n_g: int
    iu: np.ndarray  # (N, 2) indices of V_i, omega_i in w
    iz: np.ndarray  # (N, K) indices of Z_ij (-1: none)
    ix: np.ndarray  # (N+1, 3) indices of ds, y, theta at node i (-1 for node 0)
    gdyn: np.ndarray  # (N, 3) rows of the Euler constraints x_{i+1} - x_i - f dtau = 0
    gobs: np.ndarray  # (N+1, K) rows of the obstacle constraints (-1: none)
    lbg: np.ndarray
    ubg: np.ndarray
    build_s: float
    lookup: PathLookup  # held so that the cache key's id stays this lookup's


def _build_nlp(lookup: PathLookup, n: int, k: int, formulation: str,
               ipopt_opts: dict[str, Any]) -> _Nlp:
    ca = _casadi()
    t0 = time.perf_counter()
    sx = ca.SX
    p_x0 = sx.sym("x0", 3)
    p_vt = sx.sym("vt")
    p_dt = sx.sym("dtau", n)
    p_obs = sx.sym("obs", _OBS_COLS * k)
    p_w = sx.sym("w", _N_WEIGHTS)
    p_yr = sx.sym("yref")
    c_y, c_yd, c_sd, c_om, c_z, zeta, t_y, t_e = (p_w[i] for i in range(_N_WEIGHTS))

    w: list[Any] = []
    g: list[Any] = []
    lbg: list[float] = []
    ubg: list[float] = []
    iu = np.full((n, 2), -1, dtype=np.int64)
    iz = np.full((n, k), -1, dtype=np.int64)
    ix = np.full((n + 1, 3), -1, dtype=np.int64)
    gdyn = np.full((n, 3), -1, dtype=np.int64)
    gobs = np.full((n + 1, k), -1, dtype=np.int64)

    def new_var(name: str) -> Any:
        v = sx.sym(name)
        w.append(v)
        return v

    def add_con(expr: Any, lo: float, hi: float) -> int:
        g.append(expr)
        lbg.append(lo)
        ubg.append(hi)
        return len(g) - 1

    def ellipse(j: int, s: Any, y: Any, tau: Any) -> Any:
        o = p_obs[_OBS_COLS * j:_OBS_COLS * (j + 1)]
        ds = s - (o[0] + o[2] * tau)
        dy = y - (o[1] + o[3] * tau)
        return ds * ds / (o[4] * o[4]) + dy * dy / (o[5] * o[5]) - 1.0

    s0 = p_x0[0]
    x_s, x_y, x_th = p_x0[0], p_x0[1], p_x0[2]
    tau: Any = 0.0
    cost: Any = 0.0
    for i in range(n):
        v = new_var(f"V_{i}")
        om = new_var(f"w_{i}")
        iu[i] = (len(w) - 2, len(w) - 1)
        zs = []
        if formulation == "barrier" and i >= 1:
            for j in range(k):
                zs.append(new_var(f"Z_{i}_{j}"))
                iz[i, j] = len(w) - 1
        gam = lookup.gamma_ca(x_s)
        kap = lookup.kappa_ca(x_s)
        e = x_th - gam
        d = 1.0 - x_y * kap
        f1 = v * ca.cos(e) / d
        f2 = v * ca.sin(e)
        run = c_y * (x_y - p_yr) ** 2 + c_yd * f2**2 + c_sd * (f1 - p_vt) ** 2 + c_om * om**2
        for j, z in enumerate(zs):
            run = run - c_z * ca.log(z + zeta)
            gobs[i, j] = add_con(ellipse(j, x_s, x_y, tau) - z * z, 0.0, 0.0)
        if formulation == "hard" and i >= 1:
            for j in range(k):
                gobs[i, j] = add_con(ellipse(j, x_s, x_y, tau), 0.0, math.inf)
        cost = cost + run * p_dt[i]
        nxt_ds = new_var(f"ds_{i + 1}")
        nxt_y = new_var(f"y_{i + 1}")
        nxt_th = new_var(f"th_{i + 1}")
        ix[i + 1] = (len(w) - 3, len(w) - 2, len(w) - 1)
        nxt_s = s0 + nxt_ds
        gdyn[i, 0] = add_con(nxt_s - (x_s + f1 * p_dt[i]), 0.0, 0.0)
        gdyn[i, 1] = add_con(nxt_y - (x_y + f2 * p_dt[i]), 0.0, 0.0)
        gdyn[i, 2] = add_con(nxt_th - (x_th + om * p_dt[i]), 0.0, 0.0)
        x_s, x_y, x_th = nxt_s, nxt_y, nxt_th
        tau = tau + p_dt[i]
    if formulation == "hard":
        for j in range(k):
            gobs[n, j] = add_con(ellipse(j, x_s, x_y, tau), 0.0, math.inf)
    cost = cost + _terminal_cost(ca, x_s, x_y - p_yr, x_th, lookup, t_y, t_e)

    nlp = {"x": ca.vertcat(*w), "f": cost, "g": ca.vertcat(*g),
           "p": ca.vertcat(p_x0, p_vt, p_dt, p_obs, p_w, p_yr)}
    opts = {"ipopt": dict(ipopt_opts), "print_time": False, "error_on_fail": False,
            "record_time": False}
    solver = ca.nlpsol(f"ipopt_outer_n{n}_k{k}_{formulation}", "ipopt", nlp, opts)
    return _Nlp(solver=solver, n=n, k=k, formulation=formulation, n_w=len(w), n_g=len(g),
                iu=iu, iz=iz, ix=ix, gdyn=gdyn, gobs=gobs, lbg=np.array(lbg),
                ubg=np.array(ubg), build_s=time.perf_counter() - t0, lookup=lookup)


def _terminal_cost(ca: Any, s: Any, y: Any, th: Any, lookup: PathLookup, t_y: Any,
                   t_e: Any) -> Any:
    """m(x_N) = term_y y^2 + term_e (theta_N - gamma(s_N))^2 (y: y_N - yr)."""
    e = th - lookup.gamma_ca(s)
    return t_y * y**2 + t_e * e**2


def get_nlp(lookup: PathLookup, n: int, k: int, formulation: str,
            ipopt_opts: dict[str, Any]) -> _Nlp:
    """The cached NLP solver for (path, N, K, formulation, options)."""
    key = (id(lookup), n, k, formulation, tuple(sorted(ipopt_opts.items())))
    hit = _SOLVERS.get(key)
    if hit is not None and hit.lookup is lookup:
        _SOLVERS.move_to_end(key)
        return hit
    nlp = _build_nlp(lookup, n, k, formulation, ipopt_opts)
    _SOLVERS[key] = nlp
    while len(_SOLVERS) > 4 * _CACHE_SIZE:
        _SOLVERS.popitem(last=False)
    return nlp


# ---------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------

@dataclass
class _Solution:
    """An accepted plan on its own time grid, with the duals Ipopt returned."""

    t_s: float
    tau: np.ndarray  # (N+1,)
    x: np.ndarray  # (N+1, 3), absolute s
    u: np.ndarray  # (N, 2)
    z: np.ndarray  # (N, K) slacks (NaN where not defined)
    obs: np.ndarray  # (K, 6) obstacles it was solved with, at t_s
    lam_dyn: np.ndarray  # (N, 3)
    lam_obs: np.ndarray  # (N+1, K), divided by the stage's dtau (NaN where none)
    lam_u: np.ndarray  # (N, 2) bound multipliers of V, omega divided by dtau
    lam_z: np.ndarray  # (N, K) bound multipliers of Z divided by dtau


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


class IpoptOuter:
    """OuterPlanner: the J3 SPMM OCP solved by Ipopt every update (see the module doc).

    path: a ``controllers.path.frenet.FrenetPath`` (or anything with length_m, gamma, kappa).
    params: :class:`IpoptParams`: the OCP's weights, horizon and stages, and Ipopt's
    formulation ("barrier": C/GMRES's slack + log barrier; "hard": c_j >= 0), max_iter
    and tol (acceptable_tol 1e2 * tol). n_slots: the number of obstacle slots K of the
    controller (the NLP is built for the K obstacles of each update; ``n_slots`` sets
    :meth:`stage_unknowns`'s layout and what :meth:`prepare` builds by default).
    max_wall_s: Ipopt's max_wall_time (None: unlimited). omega_max_radps,
    v_max_factor, v_cap_floor_mps: input bounds. brake_decel_mps2: deceleration of
    the brake-along-lane fallback (default ``params.fallback_decel_mps2``). warm_mu:
    Ipopt's mu_init for warm-started solves. weights, stage_times_s: override the
    ones derived from ``params`` (tests; e.g. C/GMRES's current grown horizon).
    """

    updates_per_period = 1  # one NLP solve per control period

    def __init__(self, path: PathLike, params: IpoptParams, n_slots: int = 3, *,
                 max_wall_s: float | None = None,
                 omega_max_radps: float = 0.5, v_max_factor: float = 1.5,
                 v_cap_floor_mps: float = 5.0, brake_decel_mps2: float | None = None,
                 warm_mu: float = 1e-6, path_grid_m: float = 1.0,
                 weights: J3Weights | None = None, stage_times_s: np.ndarray | None = None) -> None:
        if not isinstance(params, IpoptParams):
            raise TypeError(f"IpoptOuter needs IpoptParams, got {type(params).__name__}")
        if not (isinstance(n_slots, int) and n_slots >= 0):
            raise ValueError(f"n_slots must be an int >= 0, got {n_slots!r}")
        self.path = path
        self.params = params
        self.n_slots = n_slots
        self.formulation = params.formulation
        self.weights = weights if weights is not None else weights_from_params(params)
        tau = stage_times_s if stage_times_s is not None else _stage_times(params)
        self.tau = np.asarray(tau, dtype=np.float64)
        self.n = int(self.tau.shape[0] - 1)
        self.dtau = np.diff(self.tau)
        self.omega_max = float(omega_max_radps)
        self.v_max_factor = float(v_max_factor)
        self.v_cap_floor = float(v_cap_floor_mps)
        self.brake_decel = float(brake_decel_mps2 if brake_decel_mps2 is not None
                                 else params.fallback_decel_mps2)
        self.lookup = path_lookup(path, path_grid_m)
        self._cold_opts: dict[str, Any] = {
            "print_level": 0, "sb": "yes", "max_iter": int(params.max_iter),
            "tol": float(params.tol), "acceptable_tol": 100.0 * float(params.tol),
            "acceptable_iter": 5, "mu_strategy": "monotone",
            # Ipopt's defaults, stated: the exact Hessian of the Lagrangian (CasADi's
            # algorithmic derivatives) and the MUMPS sparse linear solver.
            "hessian_approximation": "exact", "linear_solver": "mumps",
        }
        if max_wall_s is not None:
            self._cold_opts["max_wall_time"] = float(max_wall_s)
        self._warm_opts = dict(self._cold_opts)
        self._warm_opts.update({
            "warm_start_init_point": "yes", "mu_init": float(warm_mu),
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
        self._prev: _Solution | None = None
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

    def _nlp(self, k: int, warm: bool) -> _Nlp:
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

    def set_cruise_speed(self, cruise_speed_mps: float) -> None:
        """The run's cruise set-point [m/s]: the target ramp decelerates toward a
        set-point at or above it at ``set_speed_decel_mps2``, toward a lower one (the
        behaviour lowered it to follow) at ``target_decel_mps2`` (:class:`TargetSpeedRamp`).
        Until it is given (after ``reset``), ``target_decel_mps2`` everywhere."""
        self._ramp.cruise_speed_mps = float(cruise_speed_mps)

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
        obs = _pack_obstacles(obstacles)
        warm = self._prev is not None
        nlp = self._nlp(k, warm)
        t_start = time.perf_counter()

        if self._prev is not None:
            guess = _shift(self._prev, t_s, self.tau, x0, obs, self.weights)
        else:
            guess = self._initial_guess(t_s, x0, vt, obs)
        w0, lam_x0, lam_g0 = self._pack_guess(nlp, guess, x0)
        v_hi = max(self.v_max_factor * vt, self.v_cap_floor)
        lbx = np.full(nlp.n_w, -np.inf)
        ubx = np.full(nlp.n_w, np.inf)
        lbx[nlp.iu[:, 0]] = 0.0
        ubx[nlp.iu[:, 0]] = v_hi
        lbx[nlp.iu[:, 1]] = -self.omega_max
        ubx[nlp.iu[:, 1]] = self.omega_max
        zi = nlp.iz[nlp.iz >= 0]
        lbx[zi] = 0.0
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
        t_ip = time.perf_counter()
        c_ip = time.thread_time()
        sol = nlp.solver(**args)
        ipopt_cpu_s = time.thread_time() - c_ip
        ipopt_s = time.perf_counter() - t_ip
        stats = nlp.solver.stats()
        success = bool(stats.get("success", False))
        status = str(stats.get("return_status", "unknown"))
        iters = int(stats.get("iter_count", -1))
        residual = _final_kkt_error(stats)
        w = np.asarray(sol["x"], dtype=np.float64).ravel()
        lam_x = np.asarray(sol["lam_x"], dtype=np.float64).ravel()
        lam_g = np.asarray(sol["lam_g"], dtype=np.float64).ravel()
        fallback = not (success and np.all(np.isfinite(w)) and np.all(np.isfinite(lam_g)))
        if not fallback:
            accepted = self._unpack(nlp, t_s, x0, obs, w, lam_x, lam_g)
            self._last_success_t = float(t_s)
        else:
            self.fallback_count += 1
            accepted = self._fallback_plan(t_s, x0, vt, obs)
            if not np.isfinite(residual):
                residual = math.inf  # Ipopt stopped before a first iterate: never NaN
        self._prev = accepted
        self._vt = vt
        self._t_prev = float(t_s)
        plan = OuterPlan(
            stage_times_s=self.tau.copy(),
            states=accepted.x.copy(),
            speeds_mps=accepted.u[:, 0].copy(),
            headings_rad=accepted.x[:-1, 2].copy(),
            residual=float(residual),
            fallback=fallback,
            guard_fired=0,
            solve_s=time.perf_counter() - t_start,
            target_speed_mps=vt,
        )
        self.update_count += 1
        self.last_iterations = iters
        self.last_status = status
        self.history.append(UpdateStats(t_s=float(t_s), k=k, iterations=iters, status=status,
                                        success=success, residual=plan.residual,
                                        solve_s=plan.solve_s, ipopt_s=ipopt_s,
                                        ipopt_cpu_s=ipopt_cpu_s))
        return plan

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

    def _initial_guess(self, t_s: float, x0: np.ndarray, vt: float, obs: np.ndarray) -> _Solution:
        speeds = np.full(self.n, vt)
        x, u = self._rollout(x0, speeds, follow_lane=True)
        return _with_obstacles(_Solution(t_s, self.tau.copy(), x, u, np.zeros((self.n, 0)),
                                         np.zeros((0, _OBS_COLS)), np.zeros((self.n, 3)),
                                         np.zeros((self.n + 1, 0)), np.zeros((self.n, 2)),
                                         np.zeros((self.n, 0))), obs)

    def _fallback_plan(self, t_s: float, x0: np.ndarray, vt: float, obs: np.ndarray) -> _Solution:
        prev = self._prev
        half = 0.5 * float(self.tau[-1])
        last_ok = self._last_success_t
        if prev is not None and last_ok is not None and t_s - last_ok <= half:
            shifted = _shift(prev, t_s, self.tau, x0, obs, self.weights)
            x, u = self._rollout(x0, shifted.u[:, 0], follow_lane=False, omegas=shifted.u[:, 1])
            shifted.x = x
            shifted.u = u
            return shifted
        v0 = float(prev.u[0, 0]) if prev is not None else vt
        speeds = np.maximum(v0 - self.brake_decel * self.tau[:-1], 0.0)
        x, u = self._rollout(x0, speeds, follow_lane=True)
        return _with_obstacles(_Solution(t_s, self.tau.copy(), x, u, np.zeros((self.n, 0)),
                                         np.zeros((0, _OBS_COLS)), np.zeros((self.n, 3)),
                                         np.zeros((self.n + 1, 0)), np.zeros((self.n, 2)),
                                         np.zeros((self.n, 0))), obs)

    def _pack_guess(self, nlp: _Nlp, g: _Solution, x0: np.ndarray
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

    def _unpack(self, nlp: _Nlp, t_s: float, x0: np.ndarray, obs: np.ndarray, w: np.ndarray,
                lam_x: np.ndarray, lam_g: np.ndarray) -> _Solution:
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
        return _Solution(float(t_s), self.tau.copy(), x, u, z, obs.copy(), lam_dyn, lam_obs,
                         lam_u, lam_z)


def _pack_obstacles(obstacles: Obstacles) -> np.ndarray:
    k = obstacles.count
    if k == 0:
        return np.zeros((0, _OBS_COLS))
    obs = np.stack([np.asarray(obstacles.s_m, dtype=np.float64),
                    np.asarray(obstacles.y_m, dtype=np.float64),
                    np.asarray(obstacles.speed_s_mps, dtype=np.float64),
                    np.asarray(obstacles.speed_y_mps, dtype=np.float64),
                    np.asarray(obstacles.semi_a_m, dtype=np.float64),
                    np.asarray(obstacles.semi_b_m, dtype=np.float64)], axis=1)
    if not np.all(np.isfinite(obs)) or np.any(obs[:, 4:] <= 0):
        raise ValueError(f"obstacles must be finite with positive semi-axes, got {obs!r}")
    return obs


def ellipse_values(states: np.ndarray, tau: np.ndarray, obs: np.ndarray) -> np.ndarray:
    """c_j(s_i, y_i, tau_i) for every node i and obstacle j: shape (len(tau), K)."""
    s = states[:, 0:1]
    y = states[:, 1:2]
    t = np.asarray(tau)[:, None]
    ds = s - (obs[None, :, 0] + obs[None, :, 2] * t)
    dy = y - (obs[None, :, 1] + obs[None, :, 3] * t)
    out: np.ndarray = ds**2 / obs[None, :, 4] ** 2 + dy**2 / obs[None, :, 5] ** 2 - 1.0
    return out


def _interp_rows(t_new: np.ndarray, t_old: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation of each column of values (len(t_old), m) at t_new, held at ends."""
    if values.shape[1] == 0:
        return np.zeros((t_new.shape[0], 0))
    return np.stack([np.interp(t_new, t_old, values[:, c]) for c in range(values.shape[1])],
                    axis=1)


def _shift(prev: _Solution, t_s: float, tau: np.ndarray, x0: np.ndarray, obs: np.ndarray,
           weights: J3Weights) -> _Solution:
    """The previous solution moved to now: every quantity re-sampled at tau + elapsed.

    Stage quantities (inputs, slacks, multipliers / dtau) are interpolated on the old
    stage grid tau_0..tau_{N-1}, node quantities (states, node multipliers) on
    tau_0..tau_N; past the old horizon they are held (s extrapolated with the last
    speed). Obstacles are matched to the previous ones by their predicted centres;
    a new obstacle gets Z from the ellipse value of the shifted plan and zero duals.
    """
    shift = max(float(t_s) - prev.t_s, 0.0)
    n = tau.shape[0] - 1
    ts = tau[:-1] + shift
    tn = tau + shift
    u = _interp_rows(ts, prev.tau[:-1], prev.u)
    lam_u = _interp_rows(ts, prev.tau[:-1], prev.lam_u)
    lam_dyn = _interp_rows(ts, prev.tau[:-1], prev.lam_dyn)
    x = _interp_rows(tn, prev.tau, prev.x)
    beyond = tn > prev.tau[-1]
    if np.any(beyond):
        x[beyond, 0] = prev.x[-1, 0] + prev.u[-1, 0] * (tn[beyond] - prev.tau[-1])
    # Re-anchor at the measured state, keeping the plan's shape.
    offset = x0 - x[0]
    x = x + offset[None, :] * np.linspace(1.0, 0.0, n + 1)[:, None]
    x[0] = x0
    out = _Solution(float(t_s), tau.copy(), x, u, np.zeros((n, 0)), np.zeros((0, _OBS_COLS)),
                    lam_dyn, np.zeros((n + 1, 0)), lam_u, np.zeros((n, 0)))
    return _with_obstacles(out, obs, prev=prev, shift=shift, weights=weights)


def _with_obstacles(sol: _Solution, obs: np.ndarray, prev: _Solution | None = None,
                    shift: float = 0.0, weights: J3Weights | None = None) -> _Solution:
    """Attach obstacles ``obs`` to a guess: slacks and obstacle multipliers per obstacle."""
    n = sol.tau.shape[0] - 1
    k = obs.shape[0]
    z = np.zeros((n, k))
    lam_z = np.zeros((n, k))
    lam_obs = np.zeros((n + 1, k))
    cvals = ellipse_values(sol.x, sol.tau, obs) if k else np.zeros((n + 1, 0))
    for j in range(k):
        match = -1
        if prev is not None and prev.obs.shape[0]:
            pred_s = prev.obs[:, 0] + prev.obs[:, 2] * shift
            pred_y = prev.obs[:, 1] + prev.obs[:, 3] * shift
            dist = np.abs(pred_s - obs[j, 0]) + np.abs(pred_y - obs[j, 1])
            best = int(np.argmin(dist))
            if dist[best] < 3.0:
                match = best
        if match >= 0 and prev is not None:
            ts = sol.tau[:-1] + shift
            tn = sol.tau + shift
            z[:, j] = np.interp(ts, prev.tau[:-1], np.nan_to_num(prev.z[:, match], nan=1.0))
            lam_z[:, j] = np.interp(ts, prev.tau[:-1], prev.lam_z[:, match])
            lam_obs[:, j] = np.interp(tn, prev.tau, prev.lam_obs[:, match])
        else:
            z[:, j] = np.sqrt(np.maximum(cvals[:-1, j], 0.0)) + 0.1
    sol.z = z
    sol.lam_z = lam_z
    sol.lam_obs = lam_obs
    sol.obs = obs.copy()
    return sol


def _final_kkt_error(stats: dict[str, Any]) -> float:
    it = stats.get("iterations")
    if isinstance(it, dict):
        pr = it.get("inf_pr") or []
        du = it.get("inf_du") or []
        if pr and du:
            return float(max(pr[-1], du[-1]))
    return float("nan")


# ---------------------------------------------------------------------------
# Timing benchmark (paper Fig. 15)
# ---------------------------------------------------------------------------

def benchmark_outer(outer: Any, *, duration_s: float = 6.0, period_s: float = 0.02,
                    speed_mps: float = 25.0, obstacle_s_m: float = 110.0,
                    obstacle_y_m: float = -0.3, semi_a_m: float = 6.8, semi_b_m: float = 2.3,
                    detection_m: float = 80.0, iterations: Callable[[], int] | None = None
                    ) -> dict[str, Any]:
    """Per-update times of any OuterSolver on the paper's straight-road scenario.

    Straight path along +X (s = X), ego at s = 0, y = 0, 25 m/s; one stalled car in the
    lane at ``obstacle_s_m`` (default 110 m as in the paper), its ellipse A = 6.8 m,
    B = 2.3 m (4.8 x 1.9 m cars, 2 m / 0.4 m margins) offset 0.3 m to the right so
    the plan passes on the left; it enters the problem once within ``detection_m``
    of the ego, i.e. mid-run. The ego is the SPMM following its own plan (its next
    state is the plan interpolated at tau = period): this times the outer solver,
    not the plant. Returns p50/p99/max/mean/variance of ``OuterPlan.solve_s``
    [s, s^2], overall and after the obstacle entered, the residuals, fallbacks and
    the minimum ellipse value along the executed trajectory. ``times_s`` holds the
    raw samples.
    """
    x = np.array([0.0, 0.0, 0.0])
    outer.reset(x, speed_mps)
    obstacle = Obstacles(np.array([obstacle_s_m]), np.array([obstacle_y_m]), np.zeros(1),
                         np.zeros(1), np.array([semi_a_m]), np.array([semi_b_m]))
    obs_arr = _pack_obstacles(obstacle)
    times: list[float] = []
    iters: list[int] = []
    residuals: list[float] = []
    fallbacks = 0
    entered_at = -1
    c_min = math.inf
    y_max = 0.0
    steps = int(round(duration_s / period_s))
    for step in range(steps):
        t = step * period_s
        near = obstacle_s_m - x[0] < detection_m and x[0] - obstacle_s_m < 10.0
        obs = obstacle if near else Obstacles.empty()
        if near and entered_at < 0:
            entered_at = step
        plan = outer.update(t, x, obs, speed_mps, period_s)
        times.append(plan.solve_s)
        residuals.append(plan.residual)
        fallbacks += int(plan.fallback)
        if iterations is not None:
            iters.append(iterations())
        x = np.array([np.interp(period_s, plan.stage_times_s, plan.states[:, c])
                      for c in range(3)])
        if not np.all(np.isfinite(x)):
            raise RuntimeError(f"non-finite state at step {step}: {x!r}")
        c_min = min(c_min, float(ellipse_values(x[None, :], np.full(1, 0.0), obs_arr)[0, 0]))
        y_max = max(y_max, float(x[1]))
    arr = np.asarray(times)
    after = arr[max(entered_at, 0):]
    before = arr[:entered_at] if entered_at > 0 else arr[:0]
    out: dict[str, Any] = {
        "updates": int(arr.size),
        "p50_s": float(np.percentile(arr, 50)), "p99_s": float(np.percentile(arr, 99)),
        "max_s": float(arr.max()), "mean_s": float(arr.mean()), "var_s2": float(arr.var()),
        "p50_before_entry_s": float(np.percentile(before, 50)) if before.size else float("nan"),
        "p50_after_entry_s": float(np.percentile(after, 50)),
        "p99_after_entry_s": float(np.percentile(after, 99)),
        "residual_p50": float(np.nanpercentile(residuals, 50)),
        "residual_max": float(np.nanmax(residuals)),
        "fallbacks": fallbacks, "obstacle_entered_step": entered_at,
        "min_ellipse_value": c_min, "max_lateral_m": y_max, "final_s_m": float(x[0]),
        "times_s": arr,
    }
    if iters:
        it = np.asarray(iters)
        pre = it[1:entered_at] if entered_at > 1 else it[:0]  # without the cold start
        post = it[max(entered_at, 0):]
        out.update({"iter_p50": float(np.percentile(it, 50)), "iter_max": int(it.max()),
                    "iter_mean_before_entry": float(pre.mean()) if pre.size else float("nan"),
                    "iter_mean_after_entry": float(post.mean()),
                    "iter_max_after_entry": int(post.max())})
    return out


def _straight_frenet(length_m: float) -> PathLike:
    try:
        from controllers.path.frenet import FrenetPath
    except ImportError:  # pragma: no cover - frenet is part of the package
        return StraightPath(length_m)
    return FrenetPath.cached(np.array([[0.0, 0.0], [length_m, 0.0]]))


def benchmark_ipopt(params: IpoptParams | None = None, **scenario: Any) -> dict[str, Any]:
    """:func:`benchmark_outer` for :class:`IpoptOuter` (NLPs built before timing).

    ``params`` defaults to ``IpoptParams()`` (its formulation, max_iter and tol are
    the solver's); ``scenario`` is passed to :func:`benchmark_outer` (duration_s,
    period_s, obstacle_s_m, ...). Adds Ipopt's iteration counts (``iter_*``) and its
    pure solver-call time (``ipopt_p50_s``...). The path is a straight 4 km FrenetPath.
    """
    params = params if params is not None else IpoptParams()
    formulation = params.formulation
    outer = IpoptOuter(_straight_frenet(4000.0), params)
    outer.prepare(1)
    out = benchmark_outer(outer, iterations=lambda: outer.last_iterations, **scenario)
    ip = np.array([h.ipopt_s for h in outer.history])
    out.update({"solver": f"ipopt_{formulation}", "build_s": outer.build_s,
                "ipopt_p50_s": float(np.percentile(ip, 50)),
                "ipopt_p99_s": float(np.percentile(ip, 99)),
                "ipopt_var_s2": float(ip.var())})
    cpu = np.array([h.ipopt_cpu_s for h in outer.history])
    out.update({"ipopt_cpu_p50_s": float(np.percentile(cpu, 50)),
                "ipopt_cpu_p99_s": float(np.percentile(cpu, 99)),
                "ipopt_cpu_var_s2": float(cpu.var())})
    return out


def compare_with_cgmres(params: CgmresParams | None = None, *, repeats: int = 1,
                        n_slots: int = 3, **scenario: Any) -> dict[str, Any]:
    """Fig. 15 in one process: C/GMRES, Ipopt (barrier), Ipopt (hard) on the same scenario.

    ``params`` (default ``CgmresParams()``): C/GMRES's settings; both Ipopt runs solve
    the same OCP (its :class:`OcpParams` part). ``n_slots``: C/GMRES's obstacle slots.
    Each solver runs once untimed first (numba compilation, NLP construction), then
    ``repeats`` timed runs whose samples are pooled. Returns per-solver summaries and
    the Ipopt/C-GMRES ratios of p50, p99 and variance.
    """
    from controllers.path.frenet import FrenetPath
    from controllers.two_loop.outer.cgmres import CgmresOuter

    cg = params if params is not None else CgmresParams()
    path = FrenetPath.cached(np.array([[0.0, 0.0], [4000.0, 0.0]]))
    out: dict[str, Any] = {}
    makers: dict[str, Callable[[], Any]] = {
        "cgmres": lambda: CgmresOuter(path, cg, n_slots),
        "ipopt_barrier": lambda: IpoptOuter(path, ipopt_params(cg, formulation="barrier")),
        "ipopt_hard": lambda: IpoptOuter(path, ipopt_params(cg, formulation="hard")),
    }
    for name, make in makers.items():
        warm = make()
        if isinstance(warm, IpoptOuter):
            warm.prepare(1)
        benchmark_outer(warm, **scenario)
        samples = []
        summary: dict[str, Any] = {}
        for _ in range(repeats):
            outer = make()
            summary = benchmark_outer(outer, **scenario)
            samples.append(summary["times_s"])
        arr = np.concatenate(samples)
        summary.update({"p50_s": float(np.percentile(arr, 50)),
                        "p99_s": float(np.percentile(arr, 99)), "max_s": float(arr.max()),
                        "mean_s": float(arr.mean()), "var_s2": float(arr.var()),
                        "updates": int(arr.size), "times_s": arr})
        out[name] = summary
    base = out["cgmres"]
    for name in ("ipopt_barrier", "ipopt_hard"):
        out[f"{name}_over_cgmres"] = {
            key: out[name][key] / base[key] for key in ("p50_s", "p99_s", "var_s2")
            if base[key] > 0}
    return out


class StraightPath:
    """A straight reference along +X (gamma = 0, kappa = 0), for benchmarks and tests."""

    def __init__(self, length_m: float) -> None:
        self.length_m = float(length_m)

    def gamma(self, s: Any) -> Any:
        return np.zeros_like(np.asarray(s, dtype=np.float64))

    def kappa(self, s: Any) -> Any:
        return np.zeros_like(np.asarray(s, dtype=np.float64))
