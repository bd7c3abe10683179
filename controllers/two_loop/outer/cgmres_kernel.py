"""The compiled C/GMRES continuation kernel (docs/method.md §5): ``n_sub`` updates in one call.

Update k of a call (t_k = t_a + k dt, x_k = x0a + (k / n_sub)(x0b - x0a), x' the measured
rate (x0b - x0a) / dt_total, h the forward-difference step, T(t) the growing horizon)::

    F0 = F(U, x_k, t_k),  Fx = F(U, x_k + h x', t_k + h),  Fw = F(U + h U', x_k + h x', t_k + h)
    r  = -zeta_s F0 - (Fx - F0) / h - (Fw - Fx) / h
    U' <- U' + V y,   y = argmin ||r - A V y||  over the k_max-dim. Krylov space of
                      A v = (F(U + h v, x_k + h x', t_k + h) - Fx) / h   (GMRES, MGS + Givens)
    U  <- U + dt U',   then the barrier guard Z_ij + zeta >= z_guard on active slots

The lateral reference yr, the weight Cy and the barrier's speed scale sigma move linearly
across the call at the rates packed in prm (their motion enters F_t with the state's).
The lane corridor [y_lo, y_hi] is held across the call (no rate: its penalty is zero
inside, and the controller widens it at a change and narrows it only once the car is
inside the narrower one, so a plan inside it sees no step in F).
Afterwards E = ||F(U, x0b, t_a + dt_total)||_inf on the unscaled residual.

Arguments are grouped (numba reads NamedTuples of arrays and scalars): :class:`Unknowns`
(U, U', in place), :class:`Interval` (the states and times the call runs between),
:class:`OcpData` (the packed OCP data of ``controllers.two_loop.outer.ocp_layout``),
:class:`SolverConfig` (k_max, zeta_s, h, the guard), :class:`Buffers` (scratch and
outputs). NamedTuples, not dataclasses, because the compiled kernel takes them; their
values come from validated :class:`controllers.two_loop.outer.params.CgmresParams`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from controllers.two_loop.outer.gmres import arnoldi_mgs, back_substitute, combine, givens_column
from controllers.two_loop.outer.ocp import ocp_residual
from controllers.two_loop.outer.ocp_layout import (
    _FM,
    _P_CY,
    _P_CYR,
    _P_CZS,
    _P_CZSR,
    _P_SCALE,
    _P_YREF,
    _P_YREFD,
)
from controllers.two_loop.outer.params import CgmresParams

__all__ = ["Buffers", "Interval", "OcpData", "SolverConfig", "Unknowns", "cgmres_updates",
           "solver_config", "work_size"]


class Unknowns(NamedTuple):
    """U (n,) and its rate U' (n,) [1/s]; updated in place."""

    u: np.ndarray
    udot: np.ndarray


class Interval(NamedTuple):
    """What one call runs between: x0a (3,) at t_a_s [s], x0b (3,) at t_a_s + dt_total_s,
    in n_sub updates; horizon = [t_init_s, T_f_s, growth rate 1/s] of T(t) = T_f (1 -
    exp(-rate (t - t_init))); tshift_b_s = (t_a_s + dt_total_s) - the obstacle table's
    time stamp [s]."""

    x0a: np.ndarray
    x0b: np.ndarray
    t_a_s: float
    dt_total_s: float
    n_sub: int
    horizon: np.ndarray
    tshift_b_s: float


class OcpData(NamedTuple):
    """prm (N_PACKED,) packed parameters (yr, Cy, sigma and their rates at t_a; restored on
    return); obs (K, OBS_COLS) the slot table; w (N+1,) stage fractions; meta, coef the
    path tables (``FrenetPath.tables()``)."""

    prm: np.ndarray
    obs: np.ndarray
    w: np.ndarray
    meta: np.ndarray
    coef: np.ndarray


class SolverConfig(NamedTuple):
    """k_max: GMRES iterations; zeta_s [1/s]: continuation stabilisation; fd_step_s: h [s];
    z_guard: the lower bound of Z + zeta; zeta: the barrier's offset."""

    k_max: int
    zeta_s: float
    fd_step_s: float
    z_guard: float
    zeta: float


class Buffers(NamedTuple):
    """work: flat scratch of length >= work_size(n, N, k_max); xs_out (N+1, 3): the plan
    at the end state; stats (4,) = [E, guard count, non-finite flag, GMRES residual]."""

    work: np.ndarray
    xs_out: np.ndarray
    stats: np.ndarray


class _Scratch(NamedTuple):
    f0: np.ndarray
    fxh: np.ndarray
    fw: np.ndarray
    ut: np.ndarray
    vb: np.ndarray
    hm: np.ndarray
    cs: np.ndarray
    sn: np.ndarray
    g: np.ndarray
    yv: np.ndarray
    ps: np.ndarray


class _Schedule(NamedTuple):
    yr_m: float
    yr_rate_mps: float
    cy: float
    cy_rate: float
    czs: float
    czs_rate: float


def solver_config(params: CgmresParams) -> SolverConfig:
    """The kernel's settings from the solver's parameters."""
    return SolverConfig(int(params.k_max), float(params.zeta_s), float(params.fd_step),
                        float(params.z_guard), float(params.zeta))


def work_size(n: int, n_stages: int, k_max: int) -> int:
    """Length of the flat scratch array :func:`cgmres_updates` needs (n unknowns)."""
    return 4 * n + (k_max + 1) * n + (k_max + 1) * k_max + 4 * k_max + 1 + 12 * (n_stages + 1)


@numba.njit(cache=True, error_model="numpy")
def _horizon(t: float, t_init: float, tf: float, rate: float) -> tuple[float, float]:
    a = math.exp(-rate * max(t - t_init, 0.0))
    return tf * (1.0 - a), rate * tf * a


@numba.njit(cache=True, error_model="numpy", inline="always")
def _scratch(work: np.ndarray, n: int, nst: int, kmax: int) -> _Scratch:
    """Views of ``work``: 4 residual-sized vectors, the Krylov basis (kmax+1, n), the
    Hessenberg matrix (kmax+1, kmax), Givens cosines/sines, g, y, and (N+1, 12) stage rows."""
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
    return _Scratch(f0, fxh, fw, ut, vb, hm, cs, sn, g, yv, ps)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _residual(u: np.ndarray, x: np.ndarray, horizon: float, tshift: float, ocp: OcpData,
              xs: np.ndarray, ps: np.ndarray, out: np.ndarray) -> None:
    ocp_residual(u, x, horizon, tshift, ocp.prm, ocp.obs, ocp.w, ocp.meta, ocp.coef, xs, ps,
                 out)


@numba.njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _gmres(unk: Unknowns, xh: np.ndarray, tth: float, tsh: float, beta: float, ocp: OcpData,
           cfg: SolverConfig, sc: _Scratch, xs: np.ndarray, gres: float) -> float:
    """U' += V y (module docstring) from vb[0] = r of norm beta > 0; returns the GMRES
    residual of the last iteration (``gres`` if there is none)."""
    n = unk.u.shape[0]
    kmax = cfg.k_max
    h = cfg.fd_step_s
    for i in range(n):
        sc.vb[0, i] /= beta
    for i in range(kmax + 1):
        sc.g[i] = 0.0
    sc.g[0] = beta
    kused = 0
    for j in range(kmax):
        for i in range(n):
            sc.ut[i] = unk.u[i] + h * sc.vb[j, i]
        _residual(sc.ut, xh, tth, tsh, ocp, xs, sc.ps, sc.fw)
        for i in range(n):
            sc.vb[j + 1, i] = (sc.fw[i] - sc.fxh[i]) / h
        nrm = arnoldi_mgs(sc.vb, sc.hm, j)
        gres = givens_column(sc.hm, sc.cs, sc.sn, sc.g, j)
        kused = j + 1
        if nrm < 1e-14 * beta:
            break
    back_substitute(sc.hm, sc.g, kused, sc.yv)
    combine(unk.udot, sc.vb, sc.yv, kused)
    return gres


@numba.njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _direction(unk: Unknowns, xk: np.ndarray, xh: np.ndarray, tk: float, tk_shift: float,
               dt_k: float, sched: _Schedule, hz: np.ndarray, ocp: OcpData,
               cfg: SolverConfig, sc: _Scratch, xs: np.ndarray, gres: float) -> float:
    """U' of update k (module docstring): F0, Fx, Fw, r, then GMRES; yr and Cy at
    t_a + dt_k (and + h for the shifted evaluations). Returns the GMRES residual."""
    n = unk.u.shape[0]
    h = cfg.fd_step_s
    prm = ocp.prm
    yr_k = sched.yr_m + sched.yr_rate_mps * dt_k
    tt, tdot = _horizon(tk, hz[0], hz[1], hz[2])
    tth = tt + h * tdot
    cy_k = sched.cy + sched.cy_rate * dt_k
    czs_k = sched.czs + sched.czs_rate * dt_k
    prm[_P_YREF] = yr_k
    prm[_P_CY] = cy_k
    prm[_P_CZS] = czs_k
    _residual(unk.u, xk, tt, tk_shift, ocp, xs, sc.ps, sc.f0)
    prm[_P_YREF] = yr_k + h * sched.yr_rate_mps
    prm[_P_CY] = cy_k + h * sched.cy_rate
    prm[_P_CZS] = czs_k + h * sched.czs_rate
    _residual(unk.u, xh, tth, tk_shift + h, ocp, xs, sc.ps, sc.fxh)
    for i in range(n):
        sc.ut[i] = unk.u[i] + h * unk.udot[i]
    _residual(sc.ut, xh, tth, tk_shift + h, ocp, xs, sc.ps, sc.fw)
    beta = 0.0
    for i in range(n):
        r = -cfg.zeta_s * sc.f0[i] - (sc.fxh[i] - sc.f0[i]) / h - (sc.fw[i] - sc.fxh[i]) / h
        sc.vb[0, i] = r
        beta += r * r
    beta = math.sqrt(beta)
    if beta > 1e-300:
        gres = _gmres(unk, xh, tth, tk_shift + h, beta, ocp, cfg, sc, xs, gres)
    return gres


@numba.njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _barrier_guard(unk: Unknowns, obs: np.ndarray, nst: int, cfg: SolverConfig) -> int:
    """Clamp Z_ij to z_guard - zeta on active slots (stages 1..N-1; U'_ij <- max(U'_ij, 0)
    there); returns the number of clamps."""
    k_obs = obs.shape[0]
    m = 2 + 2 * k_obs
    guards = 0
    for i in range(1, nst):
        for j in range(k_obs):
            if obs[j, 6] > 0.5:
                idx = i * m + 2 + j
                if unk.u[idx] + cfg.zeta < cfg.z_guard:
                    unk.u[idx] = cfg.z_guard - cfg.zeta
                    if unk.udot[idx] < 0.0:
                        unk.udot[idx] = 0.0
                    guards += 1
    return guards


@numba.njit(cache=True, error_model="numpy", fastmath=_FM, inline="always")
def _final_stats(unk: Unknowns, iv: Interval, ocp: OcpData, sched: _Schedule, sc: _Scratch,
                 out: Buffers, guards: int, gres: float) -> None:
    """stats = [E, guards, non-finite flag, gres] at (x0b, t_a + dt_total); E on the
    unscaled residual (row scaling, if any, is a solver device only); prm restored."""
    n = unk.u.shape[0]
    nst = ocp.w.shape[0] - 1
    prm = ocp.prm
    hz = iv.horizon
    tb = iv.t_a_s + iv.dt_total_s
    tt, _ = _horizon(tb, hz[0], hz[1], hz[2])
    scale_flag = prm[_P_SCALE]
    prm[_P_SCALE] = 0.0
    prm[_P_YREF] = sched.yr_m + sched.yr_rate_mps * iv.dt_total_s
    prm[_P_CY] = sched.cy + sched.cy_rate * iv.dt_total_s
    prm[_P_CZS] = sched.czs + sched.czs_rate * iv.dt_total_s
    _residual(unk.u, iv.x0b, tt, iv.tshift_b_s, ocp, out.xs_out, sc.ps, sc.f0)
    prm[_P_SCALE] = scale_flag
    prm[_P_YREF] = sched.yr_m
    prm[_P_CY] = sched.cy
    prm[_P_CZS] = sched.czs
    e = 0.0
    finite = True
    for i in range(n):
        a = abs(sc.f0[i])
        if not (a < 1e300):
            finite = False
        if a > e:
            e = a
    for i in range(nst + 1):
        for c in range(3):
            if not (abs(out.xs_out[i, c]) < 1e300):
                finite = False
    out.stats[0] = e
    out.stats[1] = guards
    out.stats[2] = 0.0 if finite else 1.0
    out.stats[3] = gres


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def cgmres_updates(unk: Unknowns, iv: Interval, ocp: OcpData, cfg: SolverConfig,
                   out: Buffers) -> None:
    """``iv.n_sub`` C/GMRES updates from (x0a, t_a) to (x0b, t_a + dt_total), in place
    (module docstring). Outputs: U, U' (``unk``), ``out.xs_out``, ``out.stats``."""
    n = unk.u.shape[0]
    nst = ocp.w.shape[0] - 1
    sc = _scratch(out.work, n, nst, cfg.k_max)
    prm = ocp.prm
    sched = _Schedule(prm[_P_YREF], prm[_P_YREFD], prm[_P_CY], prm[_P_CYR], prm[_P_CZS],
                      prm[_P_CZSR])
    xd = np.empty(3)
    xk = np.empty(3)
    xh = np.empty(3)
    ddt = iv.dt_total_s / iv.n_sub
    for c in range(3):
        xd[c] = (iv.x0b[c] - iv.x0a[c]) / iv.dt_total_s
    guards = 0
    gres = 0.0
    for k in range(iv.n_sub):
        tk = iv.t_a_s + k * ddt
        frac = k / iv.n_sub
        for c in range(3):
            xk[c] = iv.x0a[c] + frac * (iv.x0b[c] - iv.x0a[c])
            xh[c] = xk[c] + cfg.fd_step_s * xd[c]
        tk_shift = iv.tshift_b_s - iv.dt_total_s + k * ddt
        gres = _direction(unk, xk, xh, tk, tk_shift, k * ddt, sched, iv.horizon, ocp, cfg, sc,
                          out.xs_out, gres)
        for i in range(n):
            unk.u[i] += ddt * unk.udot[i]
        guards += _barrier_guard(unk, ocp.obs, nst, cfg)
    _final_stats(unk, iv, ocp, sched, sc, out, guards, gres)
