"""The plant's own dynamics: the single-track model with the limits of a real car.

The controllers keep the paper's linear-tyre STVM (:func:`~controllers.plant.vehicle_model.
stvm_derivative`, docs/method.md §6); the simulated car, :class:`~controllers.plant.
vehicle_model.SingleTrackPlant`, integrates this model instead (docs/plant.md). State and
inputs are the STVM's: x = [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps] (shape (6,)),
front-wheel angle delta [rad], total wheel torque T [N m] (negative brakes).

Tyre forces per axle i (1 front, 2 rear), before the friction limit:

    F_yi = C_i alpha_i                        (the STVM's linear tyres, same slip angles)
    drive  (T >= 0): F_d = min(T / R, P_max / u)   (|F_x u| <= P_max; no limit for u <= 0)
                     F_x1 = F_x2 = F_d / 2          (the STVM's equal split)
    brake  (T < 0):  F_x1 = (T / R) F_z1 / (m g),  F_x2 = (T / R) F_z2 / (m g)
                     (in proportion to the static axle loads: both axles reach the
                     friction limit together; braking has no power limit)

Combined slip, the friction ellipse of each axle on its static load
F_z1 = m g b / L, F_z2 = m g a / L:

    rho_i = sqrt((F_xi / (mu F_zi))^2 + (F_yi / (mu_y F_zi))^2),  mu_y = mu * lateral ratio
    rho_i > 1:  (F_xi, F_yi) <- (F_xi, F_yi) / rho_i     (scaled back onto the ellipse)

Resistances along the body x axis at the CG (no yaw moment):

    F_aero = k_aero u |u|,  k_aero = rho_air c_d A / 2
    F_roll = c_rr m g min(max(u, 0) / v_roll, 1)   (v_roll = 0.1 m/s: no push at rest)

Equations of motion (as the STVM's, plus the resistances):

    m (u' - r v) = F_x2 + F_x1 cos d - F_y1 sin d - F_aero - F_roll
    m (v' + r u) = F_y2 + F_x1 sin d + F_y1 cos d
    I r'         = a (F_y1 cos d + F_x1 sin d) - b F_y2

Within every limit (rho_i <= 1, F_d = T / R) and without resistances these are the
STVM's equations term by term, except braking, whose split follows the axle loads.

Parameters come packed by :meth:`VehicleParams.plant_array` (layout: the ``P_*`` indices
below). Every kernel is compiled with numba (``cache=True``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

# Layout of VehicleParams.plant_array() (units in the comments).
P_MASS = 0  # m [kg]
P_INERTIA = 1  # I [kg m^2]
P_A = 2  # CG to front axle [m]
P_B = 3  # CG to rear axle [m]
P_C1 = 4  # front cornering stiffness [N/rad]
P_C2 = 5  # rear cornering stiffness [N/rad]
P_RADIUS = 6  # wheel radius [m]
P_V_SLIP = 7  # speed floor of the slip angles [m/s]
P_MU_X = 8  # longitudinal friction coefficient [-]
P_MU_Y = 9  # lateral friction coefficient [-]
P_POWER = 10  # maximum drive power at the wheels [W]
P_K_AERO = 11  # rho_air c_d A / 2 [kg/m]
P_F_ROLL = 12  # rolling resistance force c_rr m g [N]
P_FZ1 = 13  # static front axle load [N]
P_FZ2 = 14  # static rear axle load [N]
PLANT_ARRAY_SIZE = 15

ROLL_SMOOTHING_SPEED_MPS = 0.1
"""Below this speed the rolling resistance fades linearly to 0 (it cannot push a car at
rest backwards; the integrator's stop clamp handles the rest)."""


@numba.njit(cache=True, fastmath=False)
def axle_forces(state: np.ndarray, steer_rad: float, torque_nm: float,
                q: np.ndarray) -> np.ndarray:
    """Tyre forces after the limits and friction use: shape (6,)
    [F_x1, F_y1, F_x2, F_y2 (N, wheel frame of each axle), rho_1, rho_2 (-)];
    rho_i is the use of the axle's friction ellipse *before* saturation (> 1: saturated).
    ``q`` from :meth:`VehicleParams.plant_array`."""
    a, b = q[P_A], q[P_B]
    u, v, r = state[3], state[4], state[5]
    u_slip = max(u, q[P_V_SLIP])
    fy1 = q[P_C1] * (steer_rad - math.atan((v + a * r) / u_slip))
    fy2 = q[P_C2] * (-math.atan((v - b * r) / u_slip))
    fz1, fz2 = q[P_FZ1], q[P_FZ2]
    if torque_nm >= 0.0:
        drive = torque_nm / q[P_RADIUS]
        if u > 0.0:
            drive = min(drive, q[P_POWER] / u)
        fx1 = 0.5 * drive
        fx2 = 0.5 * drive
    else:
        brake = torque_nm / q[P_RADIUS]
        fx1 = brake * fz1 / (fz1 + fz2)
        fx2 = brake * fz2 / (fz1 + fz2)
    mu_x, mu_y = q[P_MU_X], q[P_MU_Y]
    rho1 = math.sqrt((fx1 / (mu_x * fz1)) ** 2 + (fy1 / (mu_y * fz1)) ** 2)
    rho2 = math.sqrt((fx2 / (mu_x * fz2)) ** 2 + (fy2 / (mu_y * fz2)) ** 2)
    out = np.empty(6)
    s1 = 1.0 / rho1 if rho1 > 1.0 else 1.0
    s2 = 1.0 / rho2 if rho2 > 1.0 else 1.0
    out[0] = fx1 * s1
    out[1] = fy1 * s1
    out[2] = fx2 * s2
    out[3] = fy2 * s2
    out[4] = rho1
    out[5] = rho2
    return out


@numba.njit(cache=True, fastmath=False)
def resistance_n(u_mps: float, q: np.ndarray) -> float:
    """Aerodynamic drag plus rolling resistance along the body x axis [N] (>= 0 for u >= 0)."""
    roll = float(q[P_F_ROLL]) * min(max(u_mps, 0.0) / ROLL_SMOOTHING_SPEED_MPS, 1.0)
    return float(q[P_K_AERO]) * u_mps * abs(u_mps) + roll


@numba.njit(cache=True, fastmath=False)
def plant_derivative(state: np.ndarray, steer_rad: float, torque_nm: float,
                     q: np.ndarray) -> np.ndarray:
    """dx/dt of the limited single-track model (module doc). Shape (6,)."""
    m, inertia, a, b = q[P_MASS], q[P_INERTIA], q[P_A], q[P_B]
    psi, u, v, r = state[2], state[3], state[4], state[5]
    f = axle_forces(state, steer_rad, torque_nm, q)
    fx1, fy1, fx2, fy2 = f[0], f[1], f[2], f[3]
    cd = math.cos(steer_rad)
    sd = math.sin(steer_rad)
    out = np.empty(6)
    out[0] = u * math.cos(psi) - v * math.sin(psi)
    out[1] = u * math.sin(psi) + v * math.cos(psi)
    out[2] = r
    out[3] = (fx2 + fx1 * cd - fy1 * sd - resistance_n(u, q)) / m + r * v
    out[4] = (fy2 + fx1 * sd + fy1 * cd) / m - r * u
    out[5] = (a * (fy1 * cd + fx1 * sd) - b * fy2) / inertia
    return out


@numba.njit(cache=True, fastmath=False)
def plant_rk4(state: np.ndarray, steer_rad: float, torque_nm: float, q: np.ndarray,
              dt_s: float, substeps: int) -> np.ndarray:
    """Integrate :func:`plant_derivative` over ``dt_s`` with ``substeps`` RK4 steps
    (inputs held); a car braked below zero speed stops (u = v = r = 0)."""
    h = dt_s / substeps
    x = state.copy()
    for _ in range(substeps):
        k1 = plant_derivative(x, steer_rad, torque_nm, q)
        k2 = plant_derivative(x + 0.5 * h * k1, steer_rad, torque_nm, q)
        k3 = plant_derivative(x + 0.5 * h * k2, steer_rad, torque_nm, q)
        k4 = plant_derivative(x + h * k3, steer_rad, torque_nm, q)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if x[3] < 0.0:
            x[3] = 0.0
            x[4] = 0.0
            x[5] = 0.0
    return x
