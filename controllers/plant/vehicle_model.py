"""Single-track vehicle model (STVM), docs/method.md §6: the ego's plant and the inner loop's model.

State vector (shape (6,)), SI units:
    x = [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps]
X, Y: centre of gravity in the world frame; psi: yaw, counter-clockwise from +X;
u, v: body-frame longitudinal / lateral velocity; r: yaw rate.
Inputs: front-wheel steering angle delta [rad], total drive torque T [N m]
(negative brakes), split equally over both axles: F_x1 = F_x2 = T / (2 R).

    m (u' - r v) = F_x2 + F_x1 cos d - F_y1 sin d
    m (v' + r u) = F_y2 + F_x1 sin d + F_y1 cos d
    I r'         = a (F_y1 cos d + F_x1 sin d) - b F_y2
    X' = u cos psi - v sin psi,  Y' = u sin psi + v cos psi,  psi' = r
    F_yi = C_i alpha_i,  alpha_1 = d - atan((v + a r)/u),  alpha_2 = -atan((v - b r)/u)

Slip angles are singular at standstill; they are computed with u clamped to
``min_slip_speed_mps`` (a common low-speed guard) and the speed is kept >= 0 by
clamping braking force when the car is (nearly) stopped.

This linear model is the controllers' (the outer OCP's and the inner loop's preview,
:mod:`controllers.two_loop.preview`). The simulated car, :class:`SingleTrackPlant`,
integrates the same model with the limits of a real car instead: a friction ellipse per
axle, a drive power limit, aerodynamic drag and rolling resistance
(:mod:`controllers.plant.limited`, docs/plant.md); the inner loop absorbs the difference.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from controllers.plant.limited import PLANT_ARRAY_SIZE, axle_forces, plant_rk4

STATE_NAMES = ("X_m", "Y_m", "psi_rad", "u_mps", "v_mps", "r_radps")


@dataclass(frozen=True)
class VehicleParams:
    """Mid-size passenger car (docs/method.md §6; limits: docs/plant.md). Units in the names.

    The first block is the paper's linear single-track model, shared by the controllers
    and the plant. The second block holds the limits only the plant applies
    (:mod:`controllers.plant.limited`); their defaults describe a mid-size saloon (VW
    Passat / Toyota Camry class, 1500 kg):

    * ``friction_coeff`` mu = 1.0: peak tyre-road friction of summer tyres on dry asphalt
      (0.9-1.1; wet 0.5-0.7, snow 0.2-0.3). A road property: the catalog's ``friction``
      key sets it per scenario. ``lateral_friction_ratio`` = mu_y / mu: 1 gives the
      friction circle, < 1 an ellipse narrower across than along.
    * ``max_drive_power_w`` = 110 kW at the wheels: a 1.5-2.0 l engine of a mid-size car
      (100-120 kW rated). Braking has no power limit, only friction and the brake torque.
    * ``drag_coeff`` c_d = 0.29 and ``frontal_area_m2`` A = 2.2 m^2: mid-size saloons have
      c_d 0.26-0.32 and A 2.1-2.3 m^2 (c_d A ~ 0.64 m^2); ``air_density_kgpm3`` = 1.2
      (dry air at 20 degC, sea level).
    * ``rolling_resistance_coeff`` c_rr = 0.012: passenger-car tyres on asphalt
      (0.010-0.015).

    With these the top speed, where 110 kW = (rho c_d A v^2 / 2 + c_rr m g) v, is
    63.7 m/s (229 km/h); the drive force is torque-limited (3000 N m / 0.3 m = 10 kN,
    6.7 m/s^2) below 11 m/s and power-limited above (2.4 m/s^2 of drive at 31 m/s).
    """

    mass_kg: float = 1500.0
    yaw_inertia_kgm2: float = 2500.0
    cg_to_front_axle_m: float = 1.2  # a
    cg_to_rear_axle_m: float = 1.6  # b
    cornering_stiffness_front_npr: float = 80_000.0  # C1, per axle [N/rad]
    cornering_stiffness_rear_npr: float = 80_000.0  # C2, per axle [N/rad]
    wheel_radius_m: float = 0.3  # R
    length_m: float = 4.8
    width_m: float = 1.9
    front_overhang_m: float = 1.0  # front axle to front bumper
    max_steer_rad: float = 0.5
    max_drive_torque_nm: float = 3000.0
    max_brake_torque_nm: float = 4500.0  # magnitude; applied as negative torque
    min_slip_speed_mps: float = 1.0
    # --- limits of the plant only (docs/plant.md)
    friction_coeff: float = 1.0  # mu [-], tyre-road, longitudinal
    lateral_friction_ratio: float = 1.0  # mu_y / mu [-]; 1 = friction circle
    max_drive_power_w: float = 110_000.0  # P_max [W] at the wheels, traction only
    drag_coeff: float = 0.29  # c_d [-]
    frontal_area_m2: float = 2.2  # A [m^2]
    air_density_kgpm3: float = 1.2  # rho_air [kg/m^3]
    rolling_resistance_coeff: float = 0.012  # c_rr [-]
    gravity_mps2: float = 9.81  # g [m/s^2]

    def __post_init__(self) -> None:
        positive = (
            "mass_kg", "yaw_inertia_kgm2", "cg_to_front_axle_m", "cg_to_rear_axle_m",
            "cornering_stiffness_front_npr", "cornering_stiffness_rear_npr", "wheel_radius_m",
            "length_m", "width_m", "max_steer_rad", "max_drive_torque_nm",
            "max_brake_torque_nm", "min_slip_speed_mps", "friction_coeff",
            "lateral_friction_ratio", "max_drive_power_w", "air_density_kgpm3",
            "gravity_mps2",
        )
        for name in positive:
            value = getattr(self, name)
            if not _is_real(value) or not value > 0:
                raise ValueError(
                    f"VehicleParams.{name} must be a finite positive number, got {value!r}")
        for name in ("drag_coeff", "frontal_area_m2", "rolling_resistance_coeff"):
            value = getattr(self, name)
            if not _is_real(value) or value < 0:
                raise ValueError(
                    f"VehicleParams.{name} must be a finite number >= 0, got {value!r}")
        if self.front_overhang_m < 0:
            raise ValueError(
                f"VehicleParams.front_overhang_m must be >= 0, got {self.front_overhang_m}")
        if self.wheelbase_m + self.front_overhang_m > self.length_m:
            raise ValueError("VehicleParams: wheelbase + front overhang exceeds length_m")

    @property
    def wheelbase_m(self) -> float:
        return self.cg_to_front_axle_m + self.cg_to_rear_axle_m

    @property
    def cg_to_front_bumper_m(self) -> float:
        return self.cg_to_front_axle_m + self.front_overhang_m

    @property
    def cg_to_box_centre_m(self) -> float:
        """Signed distance from the CG forward to the centre of the body box."""
        return self.cg_to_front_bumper_m - 0.5 * self.length_m

    @property
    def understeer_gradient_rad_per_mps2(self) -> float:
        """K_us = m/L (b/C1 - a/C2): steady-state delta = L/R_turn + K_us a_y."""
        return (self.mass_kg / self.wheelbase_m) * (
            self.cg_to_rear_axle_m / self.cornering_stiffness_front_npr
            - self.cg_to_front_axle_m / self.cornering_stiffness_rear_npr
        )

    def steady_state_steer_rad(self, speed_mps: float, curvature_1pm: float) -> float:
        """delta = (L + K_us v²) kappa [rad]: the steering that holds a path of curvature
        kappa [1/m] at speed v [m/s] (L/R_turn + K_us a_y with a_y = v² kappa). The
        compiled conversion's feed-forward (``controllers/two_loop/preview.py``) writes
        the same expression inline, for numba."""
        return (self.wheelbase_m + self.understeer_gradient_rad_per_mps2 * speed_mps
                * speed_mps) * curvature_1pm

    def as_array(self) -> np.ndarray:
        """Packed parameters for the compiled kernels: [m, I, a, b, C1, C2, R, v_min]."""
        return np.array(
            [
                self.mass_kg, self.yaw_inertia_kgm2, self.cg_to_front_axle_m,
                self.cg_to_rear_axle_m, self.cornering_stiffness_front_npr,
                self.cornering_stiffness_rear_npr, self.wheel_radius_m, self.min_slip_speed_mps,
            ],
            dtype=np.float64,
        )

    @property
    def static_axle_loads_n(self) -> tuple[float, float]:
        """(F_z1, F_z2) [N]: the weight m g shared by the axles, m g b / L and m g a / L."""
        weight = self.mass_kg * self.gravity_mps2
        return (weight * self.cg_to_rear_axle_m / self.wheelbase_m,
                weight * self.cg_to_front_axle_m / self.wheelbase_m)

    def plant_array(self) -> np.ndarray:
        """Packed parameters of the plant's limited model (:mod:`controllers.plant.limited`,
        layout ``P_*`` there): the linear model's eight, then mu, mu_y, P_max,
        rho c_d A / 2, c_rr m g, F_z1, F_z2."""
        fz1, fz2 = self.static_axle_loads_n
        out = np.array(
            [
                *self.as_array(), self.friction_coeff,
                self.friction_coeff * self.lateral_friction_ratio, self.max_drive_power_w,
                0.5 * self.air_density_kgpm3 * self.drag_coeff * self.frontal_area_m2,
                self.rolling_resistance_coeff * self.mass_kg * self.gravity_mps2, fz1, fz2,
            ],
            dtype=np.float64,
        )
        if out.shape != (PLANT_ARRAY_SIZE,):  # pragma: no cover - layout guard
            raise RuntimeError("VehicleParams.plant_array: layout out of date")
        return out


def road_load_n(vehicle: VehicleParams, speed_mps: float) -> float:
    """Aerodynamic drag plus rolling resistance [N] at ``speed_mps`` (forward): what a
    speed controller feeds forward to hold a speed on the plant (rho c_d A v² / 2 +
    c_rr m g)."""
    v = max(float(speed_mps), 0.0)
    return (0.5 * vehicle.air_density_kgpm3 * vehicle.drag_coeff * vehicle.frontal_area_m2
            * v * v + vehicle.rolling_resistance_coeff * vehicle.mass_kg * vehicle.gravity_mps2
            * (1.0 if v > 0.1 else v / 0.1))


def _is_real(value: object) -> bool:
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value))


@numba.njit(cache=True, fastmath=False)
def stvm_derivative(state: np.ndarray, steer_rad: float, torque_nm: float,
                    p: np.ndarray) -> np.ndarray:
    """dx/dt of the STVM; ``p`` from :meth:`VehicleParams.as_array`. Shape (6,)."""
    m, inertia, a, b, c1, c2, radius, v_min = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
    psi, u, v, r = state[2], state[3], state[4], state[5]
    u_slip = max(u, v_min)
    alpha1 = steer_rad - math.atan((v + a * r) / u_slip)
    alpha2 = -math.atan((v - b * r) / u_slip)
    fy1 = c1 * alpha1
    fy2 = c2 * alpha2
    fx = torque_nm / (2.0 * radius)
    cd = math.cos(steer_rad)
    sd = math.sin(steer_rad)
    out = np.empty(6)
    out[0] = u * math.cos(psi) - v * math.sin(psi)
    out[1] = u * math.sin(psi) + v * math.cos(psi)
    out[2] = r
    out[3] = (fx + fx * cd - fy1 * sd) / m + r * v
    out[4] = (fy2 + fx * sd + fy1 * cd) / m - r * u
    out[5] = (a * (fy1 * cd + fx * sd) - b * fy2) / inertia
    return out


@numba.njit(cache=True, fastmath=False)
def stvm_rk4(state: np.ndarray, steer_rad: float, torque_nm: float, p: np.ndarray,
             dt_s: float, substeps: int) -> np.ndarray:
    """Integrate the STVM over ``dt_s`` with ``substeps`` RK4 steps (inputs held)."""
    h = dt_s / substeps
    x = state.copy()
    for _ in range(substeps):
        k1 = stvm_derivative(x, steer_rad, torque_nm, p)
        k2 = stvm_derivative(x + 0.5 * h * k1, steer_rad, torque_nm, p)
        k3 = stvm_derivative(x + 0.5 * h * k2, steer_rad, torque_nm, p)
        k4 = stvm_derivative(x + h * k3, steer_rad, torque_nm, p)
        x = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        if x[3] < 0.0:
            # Braking cannot reverse the car: it stops.
            x[3] = 0.0
            x[4] = 0.0
            x[5] = 0.0
    return x


@dataclass(frozen=True)
class AxleForces:
    """Tyre forces of both axles after the plant's limits [N] (each in its wheel's
    frame: x along the wheel, y across it) and how much of each axle's friction ellipse
    the unlimited forces would use [-] (> 1: the axle slides, its force was scaled back
    onto the ellipse)."""

    fx_front_n: float
    fy_front_n: float
    fx_rear_n: float
    fy_rear_n: float
    friction_use_front: float
    friction_use_rear: float

    @property
    def saturated(self) -> bool:
        """Either axle at its friction limit."""
        return self.friction_use_front > 1.0 or self.friction_use_rear > 1.0


class SingleTrackPlant:
    """The ego's ground truth: the single-track model with a real car's limits
    (:mod:`controllers.plant.limited`: friction ellipse per axle, drive power limit,
    drag, rolling resistance), integrated with RK4 sub-steps.

    ``step`` saturates the commands to the actuators' ranges, integrates over the
    control period and returns the new state (6,). Body-frame accelerations
    a_x = u' - r v and a_y = v' + r u of the last step are kept for the trace, and
    :attr:`last_forces` holds the tyre forces at the end of the last step.
    """

    def __init__(self, params: VehicleParams, state: np.ndarray,
                 substeps_per_step: int = 4) -> None:
        if substeps_per_step < 1:
            raise ValueError(f"substeps_per_step must be >= 1, got {substeps_per_step}")
        state = np.asarray(state, dtype=np.float64)
        if state.shape != (6,) or not np.all(np.isfinite(state)):
            raise ValueError(f"plant state must be 6 finite numbers, got {state!r}")
        self.params = params
        self._q = params.plant_array()
        self.state = state.copy()
        self.substeps = substeps_per_step
        self.long_acc_mps2 = 0.0
        self.lat_acc_mps2 = 0.0
        self.last_forces = self.forces(0.0, 0.0)

    def forces(self, steer_rad: float, torque_nm: float) -> AxleForces:
        """Tyre forces at the current state under a (saturated) command."""
        steer, torque = self.saturate(steer_rad, torque_nm)
        f = axle_forces(self.state, steer, torque, self._q)
        return AxleForces(float(f[0]), float(f[1]), float(f[2]), float(f[3]), float(f[4]),
                          float(f[5]))

    def saturate(self, steer_rad: float, torque_nm: float) -> tuple[float, float]:
        p = self.params
        steer = min(max(float(steer_rad), -p.max_steer_rad), p.max_steer_rad)
        torque = min(max(float(torque_nm), -p.max_brake_torque_nm), p.max_drive_torque_nm)
        if not (math.isfinite(steer) and math.isfinite(torque)):
            raise ValueError(f"non-finite command steer={steer_rad!r} torque={torque_nm!r}")
        return steer, torque

    def step(self, steer_rad: float, torque_nm: float, dt_s: float) -> np.ndarray:
        steer, torque = self.saturate(steer_rad, torque_nm)
        before = self.state
        if before[3] <= 0.0 and torque <= 0.0:
            # Stopped and braked: the brakes hold the car (no creeping from the RK4
            # stages' transient negative speed).
            self.long_acc_mps2 = 0.0
            self.lat_acc_mps2 = 0.0
            self.state = before.copy()
            self.state[3:] = 0.0
            self.last_forces = self.forces(0.0, 0.0)
            return self.state.copy()
        after = plant_rk4(before, steer, torque, self._q, dt_s, self.substeps)
        # Mean body-frame acceleration over the step from the velocity change.
        du = (after[3] - before[3]) / dt_s
        dv = (after[4] - before[4]) / dt_s
        r_mid = 0.5 * (after[5] + before[5])
        u_mid = 0.5 * (after[3] + before[3])
        v_mid = 0.5 * (after[4] + before[4])
        self.long_acc_mps2 = float(du - r_mid * v_mid)
        self.lat_acc_mps2 = float(dv + r_mid * u_mid)
        self.state = after
        self.last_forces = self.forces(steer, torque)
        return after.copy()

    def front_bumper_xy(self) -> tuple[float, float]:
        d = self.params.cg_to_front_bumper_m
        x, y, psi = self.state[0], self.state[1], self.state[2]
        return float(x + d * math.cos(psi)), float(y + d * math.sin(psi))
