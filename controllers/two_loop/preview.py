"""Inner loop kernels: SPMM plan -> STVM inputs, and the preview corrector (docs/method.md §7).

Conversion (paper (13)(14), with documented additions):

    delta_ol = K_Ps wrap(theta*(tau_la) - (theta_a + r tau_la)) + delta_ff
    T_ol     = K_Pv (V*(tau_la) - V_a) + T_ff

* theta_a = psi + atan2(v, u), V_a = sqrt(u² + v²) (the STVM's velocity vector);
  below 0.5 m/s theta_a = psi (the slip angle is meaningless at standstill).
* tau_la = ``lookahead_s``: the plan's heading at tau = 0 equals the measured one
  for J3 (theta is a state starting at theta_a), so (13) is evaluated a little
  ahead on the plan; theta*(tau) is the plan's piecewise-linear heading. The
  measured heading is extrapolated by the yaw rate r over the same time so that
  the path's own heading advance is not counted twice (it is in delta_ff; see
  docs/two_loop.md §5).
* delta_ff (``feedforward``): steady-state cornering steer for the planned heading
  rate omega*: delta_ff = (L + K_us V*²) omega* / V*, K_us the understeer gradient
  (the kinematic (a + b) omega*/V* plus the understeer of the linear-tyre STVM,
  comparable in size on highway curves).
* T_ff (``feedforward``): torque for the planned acceleration, m R dV*/dtau
  (both axles driven, F_x total = T / R).

Preview corrector (paper (38)-(41)): from the *measured* state, the STVM is
integrated Np steps of ``preview_dt_s`` (RK4, sub-stepped for stability at low
speed), each step driven by the conversion law above evaluated on the previewed
state and the plan at that time. The predicted CG at tau_p = Np dt_p is compared
with the plan's point at tau_p (Euler-exact interpolation of the plan's Frenet
states, mapped to the world). With t, n the path tangent/normal at s*(tau_p):

    PE = planned - predicted,  PE_t = PE.t,  PE_n = PE.n
    T_c = K_Pvc PE_t,  delta_c = K_Psc PE_n + K_Isc int PE_n dt   (integral clamped)
    T = T_ol + T_c,    delta = delta_ol + delta_c

With ``preview`` off, delta_c = T_c = 0 (the preview is still computed for logs).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from controllers.path.frenet import path_gamma, path_to_global
from controllers.plant.vehicle_model import stvm_rk4


@numba.njit(cache=True, error_model="numpy")
def _stage_index(tau_nodes: np.ndarray, tau: float) -> int:
    n = tau_nodes.shape[0] - 1
    i = 0
    while i < n - 1 and tau >= tau_nodes[i + 1]:
        i += 1
    return i


@numba.njit(cache=True, error_model="numpy")
def plan_reference(tau_nodes: np.ndarray, states: np.ndarray, speeds: np.ndarray,
                   tau: float) -> tuple[float, float, float, float, float, float]:
    """Plan at time tau: (s*, y*, theta*, V*, omega*, dV*/dtau).

    Inputs are piecewise constant on stages, states piecewise linear (Euler-exact).
    """
    n = tau_nodes.shape[0] - 1
    total = tau_nodes[n]
    if tau > total:
        tau = total
    if tau < 0.0:
        tau = 0.0
    i = _stage_index(tau_nodes, tau)
    dt = tau_nodes[i + 1] - tau_nodes[i]
    if dt > 1e-9:
        r = (tau - tau_nodes[i]) / dt
        om = (states[i + 1, 2] - states[i, 2]) / dt
    else:
        r = 0.0
        om = 0.0
    if r > 1.0:
        r = 1.0
    s = states[i, 0] + r * (states[i + 1, 0] - states[i, 0])
    y = states[i, 1] + r * (states[i + 1, 1] - states[i, 1])
    th = states[i, 2] + r * (states[i + 1, 2] - states[i, 2])
    v = speeds[i]
    if i + 1 < speeds.shape[0] and tau_nodes[i + 2] - tau_nodes[i] > 1e-9:
        acc = (speeds[i + 1] - speeds[i]) / (0.5 * (tau_nodes[i + 2] - tau_nodes[i]))
    else:
        acc = 0.0
    return s, y, th, v, om, acc


@numba.njit(cache=True, error_model="numpy")
def convert(state: np.ndarray, th_ref: float, v_ref: float, om_ref: float, acc_ref: float,
            gains: np.ndarray, vp: np.ndarray) -> tuple[float, float]:
    """(delta_ol, T_ol) by (13)(14) + optional feed-forward; see module docstring.

    gains = [K_Ps, K_Pv, K_Pvc, K_Psc, K_Isc, feedforward(0/1), lookahead_s, K_us];
    vp = VehicleParams.as_array().
    """
    psi = state[2]
    u = state[3]
    v = state[4]
    va = math.sqrt(u * u + v * v)
    tha = psi + math.atan2(v, u) if va > 0.5 else psi
    # Compare the plan's heading at the look-ahead time with the measured heading
    # extrapolated by the yaw rate over the same time: otherwise the path's own
    # heading advance would be counted twice (here and in delta_ff).
    err = th_ref - (tha + state[5] * gains[6])
    err = (err + math.pi) % (2.0 * math.pi) - math.pi
    delta = gains[0] * err
    torque = gains[1] * (v_ref - va)
    if gains[5] > 0.5:
        wb = vp[2] + vp[3]
        vv = max(v_ref, 1.0)
        delta += (wb + gains[7] * vv * vv) * om_ref / vv
        torque += vp[0] * vp[6] * acc_ref
    return delta, torque


@numba.njit(cache=True, error_model="numpy")
def _rk4_adaptive(x: np.ndarray, delta: float, torque: float, vp: np.ndarray,
                  dt: float) -> np.ndarray:
    """RK4 over dt, sub-stepped so that h * (fastest lateral eigenvalue) <= 1.5."""
    m, inertia, a, b, c1, c2 = vp[0], vp[1], vp[2], vp[3], vp[4], vp[5]
    us = max(x[3], vp[7])
    lam = (c1 + c2) / (m * us) + (a * a * c1 + b * b * c2) / (inertia * us)
    nsub = int(math.ceil(dt * lam / 1.5))
    if nsub < 1:
        nsub = 1
    return stvm_rk4(x, delta, torque, vp, dt, nsub)


@numba.njit(cache=True, error_model="numpy")
def inner_step(state: np.ndarray, tau_nodes: np.ndarray, states: np.ndarray,
               speeds: np.ndarray, gains: np.ndarray, vp: np.ndarray, limits: np.ndarray,
               n_preview: int, dt_p: float, meta: np.ndarray, coef: np.ndarray,
               knot_xy: np.ndarray, preview_xy: np.ndarray, out: np.ndarray) -> None:
    """Conversion + preview for one control period (integral state not updated here).

    limits = [max_steer_rad, max_drive_torque_nm, max_brake_torque_nm] (the preview
    saturates its inputs like the plant). Fills preview_xy (Np+1, 2) and
    out = [delta_ol, T_ol, PE_t, PE_n, planned_x, planned_y].
    """
    la = gains[6]
    s, y, th, v, om, acc = plan_reference(tau_nodes, states, speeds, la)
    d_ol, t_ol = convert(state, th, v, om, acc, gains, vp)
    out[0] = d_ol
    out[1] = t_ol
    x = state.copy()
    preview_xy[0, 0] = x[0]
    preview_xy[0, 1] = x[1]
    tau_p = n_preview * dt_p
    if tau_p > tau_nodes[tau_nodes.shape[0] - 1]:
        dt_p = tau_nodes[tau_nodes.shape[0] - 1] / max(n_preview, 1)
        tau_p = n_preview * dt_p
    for k in range(n_preview):
        if k == 0:
            d, tq = d_ol, t_ol
        else:
            s, y, th, v, om, acc = plan_reference(tau_nodes, states, speeds, k * dt_p + la)
            d, tq = convert(x, th, v, om, acc, gains, vp)
        d = min(max(d, -limits[0]), limits[0])
        tq = min(max(tq, -limits[2]), limits[1])
        if dt_p > 0.0:
            x = _rk4_adaptive(x, d, tq, vp, dt_p)
        preview_xy[k + 1, 0] = x[0]
        preview_xy[k + 1, 1] = x[1]
    s, y, th, v, om, acc = plan_reference(tau_nodes, states, speeds, tau_p)
    px, py = path_to_global(meta, coef, knot_xy, s, y)
    g, _, _ = path_gamma(meta, coef, s)
    ex = px - x[0]
    ey = py - x[1]
    out[2] = ex * math.cos(g) + ey * math.sin(g)
    out[3] = -ex * math.sin(g) + ey * math.cos(g)
    out[4] = px
    out[5] = py
