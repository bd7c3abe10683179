"""The outer loop's optimal-control problem: SPMM in the Frenet frame (docs/method.md §2-§5).

Discretised problem (Euler, stage nodes tau_0 = 0 < tau_1 < ... < tau_N = T):

    x_{i+1} = x_i + f(x_i, u_i) dtau_i,              dtau_i = tau_{i+1} - tau_i
    min  sum_i dtau_i L(x_i, u_i) + m(x_N)
    s.t. c_j(x_i, t + tau_i) - Z_ij^2 = 0            (i >= 1, active slots j)

Models and costs (e = theta - gamma(s), D = 1 - y kappa(s)):

* J1, J2 (model (10)): x = (s, y), u = (theta, V, Z_1..Z_K)
* J3 (model (36)):     x = (s, y, theta), u = (V, omega, Z_1..Z_K)
* f1 = V cos(e)/D, f2 = V sin(e)  (and theta' = omega for J3)

    J1: L = Cy (y - yr)² + Ctheta e² + CV (V - Vt)² - sigma Cz sum ln(Z_j + zeta) + P(V) + Q(y)
    J2: L = Cy (y - yr)² + Cyd f2² + Csd (f1 - Vt)² - sigma Cz sum ln(Z_j + zeta) + P(V) + Q(y)
    J3: L = J2's L + Cthd omega²

Q(y) = C_lane (max(0, y - y_hi)² + max(0, y_lo - y)²): the lane corridor [y_lo, y_hi]
of the update (packed, ``_P_YLO``/``_P_YHI``; the lanes the behaviour lets the CG use,
docs/two_loop.md "Lane corridor"), exactly zero inside, C¹ at its edges, stiff enough
(C_lane >> Cy) that an ellipse's barrier cannot push the plan more than centimetres
past an edge. Q'(y) = 2 C_lane (max(0, y - y_hi) - max(0, y_lo - y)) enters H_y.

P(V) = Cvn min(V, 0)² keeps the planned speed from going negative (zero at V >= 0, so
cruising is untouched). sigma in [barrier_min_scale, 1] scales the barrier with the
problem's speed (packed, ``_P_CZS``; C/GMRES moves it across a control period at its
packed rate, like Cy): the barrier pushes the plan with about sigma Cz T |dc/ds| / (2 Z
(Z + zeta)) / (2 Csd) m/s whatever the speed, 0.6-1.1 m/s 11-15 m behind a car's
ellipse at Cz = 30: nothing at 25 m/s, the whole of a 0.9 m/s crawl, which it stopped
11 m short of the follow gap and planned backwards (docs/two_loop.md, "Barrier at low
speed").

yr: the lateral reference [m] (``Observation.lateral_reference_m``, smoothed by the
two-loop controller): a per-update parameter, constant over the horizon, packed with
the other per-update data (``pack_params(..., lateral_reference_m)``), so the kernels
are compiled once. yr = 0 is the paper's Cy y². Its rate ``yr'`` [m/s] is packed too:
the C/GMRES kernel moves yr linearly across one control period and through the F_t
forward difference (a moving parameter enters F_t like the obstacles' motion);
``ocp_residual`` itself only reads yr.

Terminal cost (not in the paper; a small documented addition that damps the
free end of the horizon): m = CyT (y_N - yr)² + CeT e_N² for J3, m = CyT (y_N - yr)²
for J1/J2.

Obstacle j (ellipse, slack form of docs/method.md §4):
    c_j = (s - s_j - v_sj tau)²/A² + (y - y_j - v_yj tau)²/B² - 1,   c_j - Z_j² = 0

Hamiltonian of stage i: H = L + sum_j mu_j (c_j - Z_j²) + p_{i+1}·f. With
a1 = 2 Csd (f1 - Vt) + p_s, a2 = 2 Cyd f2 + p_y (J2/J3; for J1 a1 = p_s, a2 = p_y):

    H_s = a1 (V kappa sin e / D + V y kappa' cos e / D²) - a2 V kappa cos e
          + sum mu_j dc_j/ds   (- 2 Ctheta e kappa for J1)
    H_y = 2 Cy (y - yr) + a1 V kappa cos e / D² + sum mu_j dc_j/dy
          + 2 C_lane (max(0, y - y_hi) - max(0, y_lo - y))
    H_theta = -a1 V sin e / D + a2 V cos e        (+ 2 Ctheta e for J1's input theta)
    H_V = a1 cos e / D + a2 sin e                 (+ 2 CV (V - Vt) for J1)
          + 2 Cvn min(V, 0)
    H_omega = 2 Cthd omega + p_theta              (J3)
    H_Zj = -sigma Cz / (Z_j + zeta) - 2 mu_j Z_j,   H_muj = c_j - Z_j²

Costate: p_N = dm/dx(x_N), p_i = p_{i+1} + H_x(x_i, u_i, mu_i, p_{i+1}) dtau_i.
Residual F(U) = [H_u(x_i, u_i, mu_i, p_{i+1}); c(x_i) - Z_i²]_{i=0..N-1} is exactly the
gradient of the discrete Lagrangian divided by dtau_i (so F = 0 is its KKT system).

Per-stage unknowns (m = 2 + 2K): [u_a, u_b, Z_1..Z_K, mu_1..mu_K] where (u_a, u_b) =
(theta, V) for J1/J2 and (V, omega) for J3. Stage 0's constraint rows and empty
obstacle slots get trivial rows Z - 1 = 0, mu = 0 (docs/method.md §9: x_0 is measured, so
its constraint cannot change the solution; this keeps F defined when the measured
state touches an ellipse, and makes empty slots inert).

Packed parameter vector, obstacle table, stage grid: :mod:`controllers.two_loop.outer.ocp_layout`
(``pack_params``, ``obstacle_table``, ``stage_fractions``); the Python-side view of the
problem: :class:`controllers.two_loop.outer.spmm_problem.SpmmProblem`; the target-speed
ramp fed to it: :mod:`controllers.two_loop.outer.target_ramp`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from controllers.path.frenet import path_gamma
from controllers.two_loop.outer.ocp_layout import (
    _FM,
    _P_CET,
    _P_CLANE,
    _P_COST,
    _P_CSD,
    _P_CTH,
    _P_CTHD,
    _P_CV,
    _P_CVN,
    _P_CY,
    _P_CYD,
    _P_CYT,
    _P_CZ,
    _P_CZS,
    _P_SCALE,
    _P_VT,
    _P_YHI,
    _P_YLO,
    _P_YREF,
    _P_ZETA,
)


@numba.njit(cache=True, error_model="numpy", inline="always")
def slot_weight(ob: np.ndarray, tshift: float) -> float:
    """Barrier weight factor clip(w + dw/dt tshift, 0, 1) of one obstacle row."""
    wgt: float = ob[7] + ob[8] * tshift
    if wgt < 0.0:
        return 0.0
    if wgt > 1.0:
        return 1.0
    return wgt


@numba.njit(cache=True, error_model="numpy", inline="always")
def corridor_penalty(y: float, prm: np.ndarray) -> tuple[float, float]:
    """(Q(y), Q'(y)) of the lane corridor: Q = C_lane (max(0, y - y_hi)² +
    max(0, y_lo - y)²), exactly zero inside [y_lo, y_hi], C¹ at its edges."""
    clane = prm[_P_CLANE]
    d = max(y - prm[_P_YHI], 0.0) - max(prm[_P_YLO] - y, 0.0)
    return clane * d * d, 2.0 * clane * d


# ----------------------------------------------------------------------------- kernels
@numba.njit(cache=True, error_model="numpy", inline="always")
def constraint_eval(s: float, y: float, tau: float, ob: np.ndarray) -> tuple[float, float, float]:
    """(c, dc/ds, dc/dy) of one obstacle row ``ob`` at time offset tau [s]."""
    ds = s - (ob[0] + ob[2] * tau)
    dy = y - (ob[1] + ob[3] * tau)
    ia2 = 1.0 / (ob[4] * ob[4])
    ib2 = 1.0 / (ob[5] * ob[5])
    return ds * ds * ia2 + dy * dy * ib2 - 1.0, 2.0 * ds * ia2, 2.0 * dy * ib2


@numba.njit(cache=True, error_model="numpy", inline="always")
def stage_geometry(x: np.ndarray, u: np.ndarray, prm: np.ndarray, meta: np.ndarray,
                   coef: np.ndarray, geo: np.ndarray) -> None:
    """Path geometry and model terms of one stage into geo (9,).

    geo = [gamma, kappa, kappa', cos e, sin e, D, f1, f2, theta] (theta: the heading
    actually used: the state for J3, the input for J1/J2).
    """
    cost = int(prm[_P_COST])
    if cost == 3:
        v = u[0]
        th = x[2]
    else:
        th = u[0]
        v = u[1]
    g, kap, dkap = path_gamma(meta, coef, x[0])
    e = th - g
    d = 1.0 - x[1] * kap
    ce = math.cos(e)
    se = math.sin(e)
    geo[0] = g
    geo[1] = kap
    geo[2] = dkap
    geo[3] = ce
    geo[4] = se
    geo[5] = d
    geo[6] = v * ce / d
    geo[7] = v * se
    geo[8] = th


@numba.njit(cache=True, error_model="numpy", inline="always")
def stage_eval_geo(x: np.ndarray, u: np.ndarray, p: np.ndarray, tau: float,  # noqa: PLR0915 - a numba kernel on the hot path, inlined whole
                   with_constraints: bool, prm: np.ndarray, obs: np.ndarray, czw: np.ndarray,
                   geo: np.ndarray, f_out: np.ndarray, hx_out: np.ndarray,
                   hu_out: np.ndarray) -> float:
    """Stage Hamiltonian, f, H_x and residual rows given :func:`stage_geometry`'s geo.

    czw (K,): barrier weight Cz of every slot (Cz times its fade factor).
    """
    cost = int(prm[_P_COST])
    k_obs = obs.shape[0]
    s = x[0]
    y = x[1]
    if cost == 3:
        v = u[0]
        om = u[1]
    else:
        v = u[1]
        om = 0.0
    kap = geo[1]
    dkap = geo[2]
    ce = geo[3]
    se = geo[4]
    d = geo[5]
    f1 = geo[6]
    f2 = geo[7]
    e = geo[8] - geo[0]
    inv_d = 1.0 / d
    f1_s = v * (kap * se * inv_d + y * dkap * ce * inv_d * inv_d)
    f1_y = v * ce * kap * inv_d * inv_d
    f1_th = -v * se * inv_d
    f1_v = ce * inv_d
    f2_s = -v * kap * ce
    f2_th = v * ce
    f2_v = se
    vt = prm[_P_VT]
    cy = prm[_P_CY]
    ey = y - prm[_P_YREF]
    ps = p[0]
    py = p[1]
    pth = p[2]
    if cost == 1:
        cth = prm[_P_CTH]
        cv = prm[_P_CV]
        a1 = ps
        a2 = py
        hval: float = cy * ey * ey + cth * e * e + cv * (v - vt) ** 2
        hs = -2.0 * cth * e * kap + a1 * f1_s + a2 * f2_s
        hy = 2.0 * cy * ey + a1 * f1_y
        hth = 0.0
        hu_out[0] = 2.0 * cth * e + a1 * f1_th + a2 * f2_th
        hu_out[1] = 2.0 * cv * (v - vt) + a1 * f1_v + a2 * f2_v
    else:
        csd = prm[_P_CSD]
        cyd = prm[_P_CYD]
        a1 = 2.0 * csd * (f1 - vt) + ps
        a2 = 2.0 * cyd * f2 + py
        hval = cy * ey * ey + cyd * f2 * f2 + csd * (f1 - vt) ** 2
        hs = a1 * f1_s + a2 * f2_s
        hy = 2.0 * cy * ey + a1 * f1_y
        if cost == 3:
            cthd = prm[_P_CTHD]
            hval += cthd * om * om
            hth = a1 * f1_th + a2 * f2_th
            hu_out[0] = a1 * f1_v + a2 * f2_v
            hu_out[1] = 2.0 * cthd * om + pth
        else:
            hth = 0.0
            hu_out[0] = a1 * f1_th + a2 * f2_th
            hu_out[1] = a1 * f1_v + a2 * f2_v
    q, dq = corridor_penalty(y, prm)
    hval += q
    hy += dq
    # Cvn min(V, 0)²: zero (and no gradient) at every V >= 0.
    vneg = min(v, 0.0)
    if vneg < 0.0:
        cvn = prm[_P_CVN]
        hval += cvn * vneg * vneg
        hu_out[0 if cost == 3 else 1] += 2.0 * cvn * vneg
    hval += ps * f1 + py * f2
    if cost == 3:
        hval += pth * om
    zeta = prm[_P_ZETA]
    for j in range(k_obs):
        z = u[2 + j]
        mu = u[2 + k_obs + j]
        cz = czw[j]
        if with_constraints and obs[j, 6] > 0.5:
            c, cs, cyy = constraint_eval(s, y, tau, obs[j])
            zz = z + zeta
            if zz < 1e-9:
                zz = 1e-9
            hval += -cz * math.log(zz) + mu * (c - z * z)
            hs += mu * cs
            hy += mu * cyy
            hu_out[2 + j] = -cz / zz - 2.0 * mu * z
            hu_out[2 + k_obs + j] = c - z * z
        else:
            hu_out[2 + j] = z - 1.0
            hu_out[2 + k_obs + j] = mu
    f_out[0] = f1
    f_out[1] = f2
    f_out[2] = om if cost == 3 else 0.0
    hx_out[0] = hs
    hx_out[1] = hy
    hx_out[2] = hth
    return hval


@numba.njit(cache=True, error_model="numpy")
def stage_eval(x: np.ndarray, u: np.ndarray, p: np.ndarray, tau: float, with_constraints: bool,
               prm: np.ndarray, obs: np.ndarray, meta: np.ndarray, coef: np.ndarray,
               f_out: np.ndarray, hx_out: np.ndarray, hu_out: np.ndarray) -> float:
    """One stage: returns H and fills f (3,), H_x (3,), residual rows (m,).

    x = (s, y, theta) (theta ignored for J1/J2), u = stage unknowns (m,),
    p = (p_s, p_y, p_theta) = p_{i+1}. ``with_constraints`` False (stage 0) makes the
    slack/multiplier rows trivial. For J1/J2 f_out[2] = 0 and hx_out[2] = 0.
    """
    geo = np.empty(9)
    stage_geometry(x, u, prm, meta, coef, geo)
    czw = np.empty(obs.shape[0])
    for j in range(obs.shape[0]):
        czw[j] = prm[_P_CZ] * prm[_P_CZS] * slot_weight(obs[j], 0.0)
    return stage_eval_geo(x, u, p, tau, with_constraints, prm, obs, czw, geo, f_out, hx_out,
                          hu_out)


@numba.njit(cache=True, error_model="numpy")
def terminal_eval(x: np.ndarray, prm: np.ndarray, meta: np.ndarray, coef: np.ndarray,
                  mx_out: np.ndarray) -> float:
    """Terminal cost m(x_N) and its gradient (3,)."""
    cost = int(prm[_P_COST])
    cyt = prm[_P_CYT]
    y = x[1] - prm[_P_YREF]
    mx_out[0] = 0.0
    mx_out[1] = 2.0 * cyt * y
    mx_out[2] = 0.0
    val: float = cyt * y * y
    if cost == 3:
        cet = prm[_P_CET]
        g, kap, _ = path_gamma(meta, coef, x[0])
        e = x[2] - g
        val += cet * e * e
        mx_out[0] = -2.0 * cet * e * kap
        mx_out[2] = 2.0 * cet * e
    return val


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def ocp_residual(uvec: np.ndarray, x0: np.ndarray, horizon: float, tshift: float,  # noqa: C901, PLR0912, PLR0915 - a numba kernel on the hot path, one loop
                 prm: np.ndarray, obs: np.ndarray, w: np.ndarray, meta: np.ndarray,
                 coef: np.ndarray, xs: np.ndarray, ps: np.ndarray, f_out: np.ndarray) -> None:
    """F(U, x0, t) (length N m) into ``f_out``; states (N+1, 3) into ``xs``, costates into ``ps``.

    horizon: current T [s]; tshift: time of the update minus the obstacles' time
    stamp [s] (obstacle j is at s_j + v_sj (tshift + tau_i) at stage i).
    For J1/J2 xs[i, 2] holds the planned heading input theta_i (xs[N, 2] = theta_{N-1}).
    ``ps`` must have N+1 rows and at least 12 columns: columns 3.. hold the stage
    geometry of the forward pass, reused by the backward pass.

    Row scaling (packed flag, ``CgmresParams.row_scaling``): F is returned as D(U) F,
    every row divided by an estimate of its diagonal Jacobian entry (same roots), so
    that the Krylov solver sees rows of comparable size (docs/method.md §9: the slack rows
    make F_U ill-conditioned): H_V / (2 Csd), H_omega / (2 Cthd) (J3); H_theta /
    (2 Cyd V²), H_V / (2 Csd) (J2); H_theta / (2 Ctheta), H_V / (2 CV) (J1);
    H_Z / (Cz_j/(Z + zeta)² + 2|Z|), (c - Z²) / (2|Z| + 1). Trivial rows unscaled.
    """
    n = w.shape[0] - 1
    k_obs = obs.shape[0]
    m = 2 + 2 * k_obs
    cost = int(prm[_P_COST])
    fv = np.empty(3)
    hx = np.empty(3)
    czw = np.empty(k_obs)
    for j in range(k_obs):
        czw[j] = prm[_P_CZ] * prm[_P_CZS] * slot_weight(obs[j], tshift)
    scale = prm[_P_SCALE] > 0.5
    if cost == 3:
        inv0, inv1 = 0.5 / prm[_P_CSD], 0.5 / prm[_P_CTHD]
    elif cost == 2:
        inv0, inv1 = -1.0, 0.5 / prm[_P_CSD]
    else:
        inv0, inv1 = 0.5 / prm[_P_CTH], 0.5 / prm[_P_CV]
    xs[0, 0] = x0[0]
    xs[0, 1] = x0[1]
    xs[0, 2] = x0[2]
    for i in range(n):
        b = i * m
        dt = horizon * (w[i + 1] - w[i])
        geo = ps[i, 3:12]
        stage_geometry(xs[i], uvec[b:b + m], prm, meta, coef, geo)
        xs[i + 1, 0] = xs[i, 0] + geo[6] * dt
        xs[i + 1, 1] = xs[i, 1] + geo[7] * dt
        if cost == 3:
            xs[i + 1, 2] = xs[i, 2] + uvec[b + 1] * dt
        else:
            xs[i, 2] = uvec[b]
            xs[i + 1, 2] = uvec[b]
    terminal_eval(xs[n], prm, meta, coef, hx)
    ps[n, 0] = hx[0]
    ps[n, 1] = hx[1]
    ps[n, 2] = hx[2]
    for i in range(n - 1, -1, -1):
        b = i * m
        dt = horizon * (w[i + 1] - w[i])
        tau = tshift + horizon * w[i]
        stage_eval_geo(xs[i], uvec[b:b + m], ps[i + 1], tau, i > 0, prm, obs, czw,
                       ps[i, 3:12], fv, hx, f_out[b:b + m])
        ps[i, 0] = ps[i + 1, 0] + hx[0] * dt
        ps[i, 1] = ps[i + 1, 1] + hx[1] * dt
        ps[i, 2] = ps[i + 1, 2] + hx[2] * dt
    if scale:
        zeta = prm[_P_ZETA]
        for i in range(n):
            b = i * m
            if inv0 > 0.0:
                f_out[b] *= inv0
            else:
                v = uvec[b + 1]
                f_out[b] /= 2.0 * prm[_P_CYD] * v * v + 0.02 * prm[_P_CSD] + 1e-6
            f_out[b + 1] *= inv1
            if i == 0:
                continue
            for j in range(k_obs):
                if obs[j, 6] > 0.5:
                    z = uvec[b + 2 + j]
                    zz = max(z + zeta, 1e-9)
                    az = 2.0 * abs(z)
                    f_out[b + 2 + j] /= czw[j] / (zz * zz) + az + 1e-3
                    f_out[b + 2 + k_obs + j] /= az + 1.0


@numba.njit(cache=True, error_model="numpy")
def ocp_objective(uvec: np.ndarray, x0: np.ndarray, horizon: float, tshift: float,
                  prm: np.ndarray, obs: np.ndarray, w: np.ndarray, meta: np.ndarray,
                  coef: np.ndarray, with_multipliers: bool = False) -> float:
    """Discrete objective sum dtau_i L(x_i, u_i) + m(x_N) including the barrier (tests).

    With ``with_multipliers`` the constraint terms sum dtau_i mu_i (c_i - Z_i²) are
    added: this is the reduced Lagrangian, whose gradient with respect to stage i's
    unknowns is dtau_i F_i (on the non-trivial rows).
    """
    n = w.shape[0] - 1
    k_obs = obs.shape[0]
    m = 2 + 2 * k_obs
    cost = int(prm[_P_COST])
    x = x0.copy()
    fv = np.empty(3)
    hx = np.empty(3)
    hu = np.empty(m)
    zero3 = np.zeros(3)
    total = 0.0
    for i in range(n):
        b = i * m
        dt = horizon * (w[i + 1] - w[i])
        u = uvec[b:b + m].copy()
        if not with_multipliers:
            for j in range(k_obs):
                u[2 + k_obs + j] = 0.0  # multipliers do not enter the objective
        lval = stage_eval(x, u, zero3, tshift + horizon * w[i], i > 0, prm, obs, meta, coef,
                          fv, hx, hu)
        total += lval * dt
        x[0] += fv[0] * dt
        x[1] += fv[1] * dt
        if cost == 3:
            x[2] += fv[2] * dt
    total += terminal_eval(x, prm, meta, coef, hx)
    return total
