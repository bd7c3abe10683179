"""The outer loop's unknowns started and switched (docs/method.md §9): the exact solution
of F = 0 for a zero-length horizon (:func:`stage_init`, the growing horizon's start)
and an obstacle slot's activation and deactivation in the stacked unknowns
(:func:`activate_slot`, :func:`deactivate_slot`). The problem itself:
:mod:`controllers.two_loop.outer.ocp`."""

from __future__ import annotations

import math

import numba
import numpy as np

from controllers.path.frenet import path_gamma
from controllers.two_loop.outer.ocp import constraint_eval, slot_weight, stage_eval, terminal_eval
from controllers.two_loop.outer.ocp_layout import _P_COST, _P_CZ, _P_CZS, _P_VT, _P_ZETA


@numba.njit(cache=True, error_model="numpy")
def stage_init(x0: np.ndarray, tshift: float, prm: np.ndarray, obs: np.ndarray,
               meta: np.ndarray, coef: np.ndarray, n: int, uvec: np.ndarray) -> None:
    """Exact solution of F = 0 for a zero-length horizon (growing-horizon start).

    With T = 0 every x_i = x0 and p_i = dm/dx(x0), so every stage solves the same
    small system H_u(x0, u, p) = 0 (2 unknowns; Newton with a finite-difference
    Jacobian from theta = gamma, V = Vt / V = Vt, omega = 0), Z_j = sqrt(max(c_j, 1e-2)),
    mu_j from H_Zj = 0: mu_j = -Cz / (2 Z_j (Z_j + zeta)).
    """
    k_obs = obs.shape[0]
    m = 2 + 2 * k_obs
    cost = int(prm[_P_COST])
    p = np.empty(3)
    terminal_eval(x0, prm, meta, coef, p)
    g, _k0, _dk0 = path_gamma(meta, coef, x0[0])
    u = np.zeros(m)
    vt = prm[_P_VT]
    if cost == 3:
        u[0] = vt
    else:
        u[0] = g
        u[1] = vt
    for j in range(k_obs):
        u[2 + j] = 1.0
    fv = np.empty(3)
    hx = np.empty(3)
    r0 = np.empty(m)
    r1 = np.empty(m)
    for _it in range(30):
        stage_eval(x0, u, p, tshift, False, prm, obs, meta, coef, fv, hx, r0)
        if abs(r0[0]) + abs(r0[1]) < 1e-13:
            break
        jac = np.empty((2, 2))
        for col in range(2):
            du = 1e-7 * max(1.0, abs(u[col]))
            u[col] += du
            stage_eval(x0, u, p, tshift, False, prm, obs, meta, coef, fv, hx, r1)
            u[col] -= du
            jac[0, col] = (r1[0] - r0[0]) / du
            jac[1, col] = (r1[1] - r0[1]) / du
        det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
        if abs(det) < 1e-14:
            break
        d0 = (jac[1, 1] * r0[0] - jac[0, 1] * r0[1]) / det
        d1 = (-jac[1, 0] * r0[0] + jac[0, 0] * r0[1]) / det
        u[0] -= d0
        u[1] -= d1
    cz = prm[_P_CZ] * prm[_P_CZS]
    zeta = prm[_P_ZETA]
    for i in range(n):
        b = i * m
        uvec[b] = u[0]
        uvec[b + 1] = u[1]
        for j in range(k_obs):
            if i > 0 and obs[j, 6] > 0.5:
                c, _cs, _cy = constraint_eval(x0[0], x0[1], tshift, obs[j])
                z = math.sqrt(max(c, 1e-2))
                uvec[b + 2 + j] = z
                uvec[b + 2 + k_obs + j] = (-cz * slot_weight(obs[j], tshift)
                                           / (2.0 * z * (z + zeta)))
            else:
                uvec[b + 2 + j] = 1.0
                uvec[b + 2 + k_obs + j] = 0.0


@numba.njit(cache=True, error_model="numpy")
def activate_slot(uvec: np.ndarray, xs: np.ndarray, horizon: float, tshift: float,
                  w: np.ndarray, prm: np.ndarray, obs: np.ndarray, j: int) -> None:
    """Initialise slot j's Z, mu along the current plan so that its own rows vanish."""
    n = w.shape[0] - 1
    k_obs = obs.shape[0]
    m = 2 + 2 * k_obs
    cz = prm[_P_CZ] * prm[_P_CZS]
    zeta = prm[_P_ZETA]
    for i in range(n):
        b = i * m
        if i == 0:
            uvec[b + 2 + j] = 1.0
            uvec[b + 2 + k_obs + j] = 0.0
            continue
        c, _cs, _cy = constraint_eval(xs[i, 0], xs[i, 1], tshift + horizon * w[i], obs[j])
        z = math.sqrt(max(c, 1e-2))
        uvec[b + 2 + j] = z
        uvec[b + 2 + k_obs + j] = -cz * slot_weight(obs[j], tshift) / (2.0 * z * (z + zeta))


@numba.njit(cache=True, error_model="numpy")
def deactivate_slot(uvec: np.ndarray, n: int, k_obs: int, j: int) -> None:
    m = 2 + 2 * k_obs
    for i in range(n):
        uvec[i * m + 2 + j] = 1.0
        uvec[i * m + 2 + k_obs + j] = 0.0
