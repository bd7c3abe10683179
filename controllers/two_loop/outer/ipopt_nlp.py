"""Ipopt outer loop, the NLP: the C/GMRES problem (docs/method.md §2-§5) as CasADi builds it.

The planner that solves it every update is :mod:`controllers.two_loop.outer.ipopt_planner`
(:class:`~controllers.two_loop.outer.ipopt_planner.IpoptOuter`); its warm start is
:mod:`controllers.two_loop.outer.ipopt_warmstart`.

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
c_sdot, c_thetadot, c_z, zeta, c_y_terminal, c_e_terminal).

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
from controllers.two_loop.outer.ocp_layout import stage_times
from controllers.two_loop.outer.params import OcpParams

__all__ = ["N_WEIGHTS", "OBS_COLS", "J3Weights", "Nlp", "PathLike", "PathLookup",
           "NlpSolution", "checked_stage_times", "ellipse_values", "get_nlp", "pack_obstacles",
           "path_lookup", "solve_nlp", "weights_from_params"]

# Columns of the packed obstacle parameter block.
OBS_COLS = 6  # s_m, y_m, speed_s_mps, speed_y_mps, semi_a_m, semi_b_m


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


N_WEIGHTS = 8


def weights_from_params(params: OcpParams) -> J3Weights:
    """The J3 weights of an :class:`OcpParams` (same names, same units)."""
    return J3Weights(
        c_y=float(params.c_y), c_ydot=float(params.c_ydot), c_sdot=float(params.c_sdot),
        c_omega=float(params.c_thetadot), c_z=float(params.c_z), zeta=float(params.zeta),
        term_y=float(params.c_y_terminal), term_e=float(params.c_e_terminal))


def checked_stage_times(params: OcpParams) -> np.ndarray:
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
_SOLVERS: OrderedDict[tuple[Any, ...], Nlp] = OrderedDict()
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
class Nlp:
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


class _NlpBuilder:
    """The NLP of one (path, N, K, formulation) as it is written down: its parameters,
    its decision variables ``w`` and constraints ``g`` (with bounds) in the order they
    are added, the index tables of :class:`Nlp`, the cost so far, and the state node
    (s, y, theta) and stage time tau [s] the next stage starts from."""

    def __init__(self, ca: Any, lookup: PathLookup, n: int, k: int, formulation: str) -> None:
        self.ca = ca
        self.lookup = lookup
        self.n, self.k, self.formulation = n, k, formulation
        sx = ca.SX
        self.p_x0 = sx.sym("x0", 3)
        self.p_vt = sx.sym("vt")
        self.p_dt = sx.sym("dtau", n)
        self.p_obs = sx.sym("obs", OBS_COLS * k)
        self.p_w = sx.sym("w", N_WEIGHTS)
        self.p_yr = sx.sym("yref")
        self.weights = tuple(self.p_w[i] for i in range(N_WEIGHTS))
        self.w: list[Any] = []
        self.g: list[Any] = []
        self.lbg: list[float] = []
        self.ubg: list[float] = []
        self.iu = np.full((n, 2), -1, dtype=np.int64)
        self.iz = np.full((n, k), -1, dtype=np.int64)
        self.ix = np.full((n + 1, 3), -1, dtype=np.int64)
        self.gdyn = np.full((n, 3), -1, dtype=np.int64)
        self.gobs = np.full((n + 1, k), -1, dtype=np.int64)
        self.state: tuple[Any, Any, Any] = (self.p_x0[0], self.p_x0[1], self.p_x0[2])
        self.tau: Any = 0.0
        self.cost: Any = 0.0

    def new_var(self, name: str) -> Any:
        """A new decision variable, appended to ``w``."""
        v = self.ca.SX.sym(name)
        self.w.append(v)
        return v

    def add_con(self, expr: Any, lo: float, hi: float) -> int:
        """Append the constraint lo <= expr <= hi; its row in ``g``."""
        self.g.append(expr)
        self.lbg.append(lo)
        self.ubg.append(hi)
        return len(self.g) - 1

    def ellipse(self, j: int, s: Any, y: Any, tau: Any) -> Any:
        """c_j(s, y, tau) of obstacle j (module docstring)."""
        o = self.p_obs[OBS_COLS * j:OBS_COLS * (j + 1)]
        ds = s - (o[0] + o[2] * tau)
        dy = y - (o[1] + o[3] * tau)
        return ds * ds / (o[4] * o[4]) + dy * dy / (o[5] * o[5]) - 1.0

    def add_stage(self, i: int) -> None:
        """Stage i: its inputs V_i, omega_i (and slacks Z_ij), its running cost, its
        obstacle constraints and the Euler step to node i + 1."""
        ca = self.ca
        c_y, c_yd, c_sd, c_om, c_z, zeta, _, _ = self.weights
        x_s, x_y, x_th = self.state
        v = self.new_var(f"V_{i}")
        om = self.new_var(f"w_{i}")
        self.iu[i] = (len(self.w) - 2, len(self.w) - 1)
        zs = self._slacks(i)
        gam = self.lookup.gamma_ca(x_s)
        kap = self.lookup.kappa_ca(x_s)
        e = x_th - gam
        d = 1.0 - x_y * kap
        f1 = v * ca.cos(e) / d
        f2 = v * ca.sin(e)
        run = (c_y * (x_y - self.p_yr) ** 2 + c_yd * f2**2 + c_sd * (f1 - self.p_vt) ** 2
               + c_om * om**2)
        for j, z in enumerate(zs):
            run = run - c_z * ca.log(z + zeta)
            self.gobs[i, j] = self.add_con(self.ellipse(j, x_s, x_y, self.tau) - z * z,
                                           0.0, 0.0)
        if self.formulation == "hard" and i >= 1:
            self.add_hard_constraints(i)
        self.cost = self.cost + run * self.p_dt[i]
        self._euler_step(i, f1, f2, om)

    def _slacks(self, i: int) -> list[Any]:
        """The slacks Z_ij of stage i (barrier formulation, stages 1..N-1; else none)."""
        zs = []
        if self.formulation == "barrier" and i >= 1:
            for j in range(self.k):
                zs.append(self.new_var(f"Z_{i}_{j}"))
                self.iz[i, j] = len(self.w) - 1
        return zs

    def add_hard_constraints(self, i: int) -> None:
        """The hard formulation's c_j >= 0 at node i (the current state and tau)."""
        x_s, x_y, _ = self.state
        for j in range(self.k):
            self.gobs[i, j] = self.add_con(self.ellipse(j, x_s, x_y, self.tau), 0.0, math.inf)

    def _euler_step(self, i: int, f1: Any, f2: Any, om: Any) -> None:
        """Node i + 1 (ds relative to s_0, y, theta) and its Euler constraints from node i
        with rates (f1, f2, omega); it becomes the current state, tau advances."""
        x_s, x_y, x_th = self.state
        dt = self.p_dt[i]
        nxt_ds = self.new_var(f"ds_{i + 1}")
        nxt_y = self.new_var(f"y_{i + 1}")
        nxt_th = self.new_var(f"th_{i + 1}")
        self.ix[i + 1] = (len(self.w) - 3, len(self.w) - 2, len(self.w) - 1)
        nxt_s = self.p_x0[0] + nxt_ds
        self.gdyn[i, 0] = self.add_con(nxt_s - (x_s + f1 * dt), 0.0, 0.0)
        self.gdyn[i, 1] = self.add_con(nxt_y - (x_y + f2 * dt), 0.0, 0.0)
        self.gdyn[i, 2] = self.add_con(nxt_th - (x_th + om * dt), 0.0, 0.0)
        self.state = (nxt_s, nxt_y, nxt_th)
        self.tau = self.tau + dt

    def terminal_cost(self) -> Any:
        """m(x_N) of the current (last) node."""
        x_s, x_y, x_th = self.state
        t_y, t_e = self.weights[6], self.weights[7]
        return _terminal_cost(self.ca, x_s, x_y - self.p_yr, x_th, self.lookup, t_y, t_e)


def _build_nlp(lookup: PathLookup, n: int, k: int, formulation: str,
               ipopt_opts: dict[str, Any]) -> Nlp:
    ca = _casadi()
    t0 = time.perf_counter()
    b = _NlpBuilder(ca, lookup, n, k, formulation)
    for i in range(n):
        b.add_stage(i)
    if formulation == "hard":
        b.add_hard_constraints(n)
    cost = b.cost + b.terminal_cost()

    nlp = {"x": ca.vertcat(*b.w), "f": cost, "g": ca.vertcat(*b.g),
           "p": ca.vertcat(b.p_x0, b.p_vt, b.p_dt, b.p_obs, b.p_w, b.p_yr)}
    opts = {"ipopt": dict(ipopt_opts), "print_time": False, "error_on_fail": False,
            "record_time": False}
    solver = ca.nlpsol(f"ipopt_outer_n{n}_k{k}_{formulation}", "ipopt", nlp, opts)
    return Nlp(solver=solver, n=n, k=k, formulation=formulation, n_w=len(b.w), n_g=len(b.g),
               iu=b.iu, iz=b.iz, ix=b.ix, gdyn=b.gdyn, gobs=b.gobs, lbg=np.array(b.lbg),
               ubg=np.array(b.ubg), build_s=time.perf_counter() - t0, lookup=lookup)


def _terminal_cost(ca: Any, s: Any, y: Any, th: Any, lookup: PathLookup, t_y: Any,
                   t_e: Any) -> Any:
    """m(x_N) = term_y y^2 + term_e (theta_N - gamma(s_N))^2 (y: y_N - yr)."""
    e = th - lookup.gamma_ca(s)
    return t_y * y**2 + t_e * e**2


def get_nlp(lookup: PathLookup, n: int, k: int, formulation: str,
            ipopt_opts: dict[str, Any]) -> Nlp:
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


@dataclass(frozen=True)
class NlpSolution:
    """One Ipopt call (:func:`solve_nlp`): the primal solution ``w`` and multipliers
    ``lam_x``, ``lam_g`` of the NLP, Ipopt's success flag, return status, iteration
    count and final KKT error max(inf_pr, inf_du) (NaN before a first iterate), and
    the call's wall and thread CPU times [s]."""

    w: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    success: bool
    status: str
    iterations: int
    residual: float
    wall_s: float
    cpu_s: float


def solve_nlp(nlp: Nlp, args: dict[str, Any]) -> NlpSolution:
    """One call of ``nlp``'s Ipopt solver on ``args``, timed (wall and thread CPU)."""
    t_ip = time.perf_counter()
    c_ip = time.thread_time()
    sol = nlp.solver(**args)
    ipopt_cpu_s = time.thread_time() - c_ip
    ipopt_s = time.perf_counter() - t_ip
    stats = nlp.solver.stats()
    return NlpSolution(
        w=np.asarray(sol["x"], dtype=np.float64).ravel(),
        lam_x=np.asarray(sol["lam_x"], dtype=np.float64).ravel(),
        lam_g=np.asarray(sol["lam_g"], dtype=np.float64).ravel(),
        success=bool(stats.get("success", False)),
        status=str(stats.get("return_status", "unknown")),
        iterations=int(stats.get("iter_count", -1)),
        residual=_final_kkt_error(stats), wall_s=ipopt_s, cpu_s=ipopt_cpu_s)


def _final_kkt_error(stats: dict[str, Any]) -> float:
    """max(inf_pr, inf_du) of Ipopt's last iterate in ``stats`` (NaN: no iterate)."""
    it = stats.get("iterations")
    if isinstance(it, dict):
        pr = it.get("inf_pr") or []
        du = it.get("inf_du") or []
        if pr and du:
            return float(max(pr[-1], du[-1]))
    return float("nan")


def pack_obstacles(obstacles: Obstacles) -> np.ndarray:
    k = obstacles.count
    if k == 0:
        return np.zeros((0, OBS_COLS))
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
