"""Inner preview tracker: the plan -> STVM inputs, corrected by the preview error.

Around the compiled kernel :func:`controllers.two_loop.preview.inner_step` (conversion
(13)(14) with feed-forward, Np-step STVM preview from the measured state, preview
error PE = planned - predicted at tau_p = Np dt_p split along the path's tangent and
normal, docs/method.md §7), this stage holds what lives between steps: the integral
of PE_n and the preview itself. Per control period, with dt the elapsed time:

    v_lat   = |y*(tau_p) - y*(0)| / tau_p                               plan's lateral speed
    w       = exp(-(v_lat / manoeuvre_speed_mps)²)                      1 holding a lane
    I      <- clip(I exp(-(1 - w) dt / bleed_s) + w PE_n dt, ±integral_limit_ms)
    e_b     = sign(PE_n) max(|PE_n| - manoeuvre_band_m, 0)              beyond the band
    delta_c = K_Psc (w PE_n + (1 - w) e_b) + K_Isc I,  T_c = K_Pvc PE_t  (38)(39)
    delta   = delta_ol + delta_c,        T   = T_ol + T_c               (40)(41)

Why the weight w: the preview drives the STVM on *one* plan with the conversion alone,
while the real car gets a new plan every period, started at the measured state (the
outer loop closes the position loop). Where the plan moves across the road (a pass,
a return) the two differ: measured on the R = 400 m curve with feed-forward, the
preview predicted 0.05-0.08 m of lateral error during the pass where the car ended
0.00-0.03 m from the plan. Corrections on that prediction (and an integral charged
by it, which then steered for seconds after the manoeuvre) made the tracking worse.
Holding a lane (v_lat ~ 0) the prediction is right and what it sees is what the
conversion cannot do by itself (the paper's case: the steady cornering steer). So
the integration acts while the plan holds its lateral position, and while it moves
the integral is bled off over ``bleed_s``: it restarts from what the new lane needs,
not from what the manoeuvre charged. While the plan moves, the proportional part acts
only on the predicted error beyond ``manoeuvre_band_m`` (the size of the
misprediction the re-planning absorbs): a plan the conversion cannot follow at all
(the J1 cost's chattering heading, which without the preview leaves the road, 11 m
off its lane) is still corrected. The plan's lateral speed is read from its lateral
offset, |y*(tau_p) - y*(0)| / tau_p, a state that stays smooth where a cost makes the
heading chatter.

With ``preview`` off (or a non-finite PE) the corrections are 0 and I is kept.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.params import check_leaves, check_range, param
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import VehicleParams
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.preview import inner_step


@dataclass(frozen=True)
class PreviewParams:
    """Conversion gains and the preview corrector (docs/method.md §7)."""

    preview: bool = param(True, "-", "apply the preview corrections (the preview is logged "
                          "either way)")
    n_preview: int = param(10, "-", "Np: preview steps of the STVM")
    preview_dt_s: float = param(0.05, "s", "dt_p: preview step")
    lookahead_s: float = param(0.15, "s", "tau_la: plan time the conversion reads")
    k_ps: float = param(1.0, "rad/rad", "K_Ps: heading error -> steer (13)")
    k_pv: float = param(1500.0, "N m s/m", "K_Pv: speed error -> torque (14)")
    k_pvc: float = param(500.0, "N m/m", "K_Pvc: tangential preview error -> torque (38)")
    k_psc: float = param(0.1, "rad/m", "K_Psc: normal preview error -> steer (39)")
    k_isc: float = param(0.05, "rad/(m s)", "K_Isc: integral of the normal error -> steer")
    integral_limit_ms: float = param(5.0, "m s", "clamp of the integral of PE_n")
    manoeuvre_speed_mps: float = param(
        0.4, "m/s", "plan's lateral speed across the road at which the corrections fade "
        "to exp(-1): holding a lane the plan's stays below 0.1-0.3 m/s (a car settling "
        "back to the lane centre), a pass or return reaches 1-1.5 m/s")
    bleed_s: float = param(0.5, "s", "time constant of the integral's bleed while the plan "
                           "moves across the road (about the outer loop's settling time)")
    manoeuvre_band_m: float = param(
        0.1, "m", "while the plan moves across the road, the size of PE_n the "
        "re-planning absorbs (the preview mispredicted 0.05-0.08 m on a pass the car "
        "followed to 0.00-0.03 m): the proportional correction acts on the excess only")
    feedforward: bool = param(True, "-", "cornering steer (L + K_us V²) omega/V and m R dV/dt")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("preview_dt_s", "k_ps", "manoeuvre_speed_mps", "bleed_s"):
            check_range(self, name, gt=0.0)
        for name in ("lookahead_s", "k_pv", "k_pvc", "k_psc", "k_isc", "integral_limit_ms",
                     "manoeuvre_band_m"):
            check_range(self, name, ge=0.0)
        check_range(self, "n_preview", ge=1, le=1000)


@dataclass(frozen=True)
class TrackerOutput:
    """One period of the inner loop: open-loop conversion, preview error, corrections."""

    steer_outer_rad: float
    torque_outer_nm: float
    preview_err_t_m: float
    preview_err_n_m: float
    steer_corr_rad: float
    torque_corr_nm: float
    steer_corr_integral_rad: float = 0.0  # K_Isc I, the integral's part of steer_corr_rad
    preview_weight: float = 1.0  # w: 1 holding a lane, -> 0 while the plan moves across

    @property
    def steer_rad(self) -> float:
        return self.steer_outer_rad + self.steer_corr_rad

    @property
    def torque_nm(self) -> float:
        return self.torque_outer_nm + self.torque_corr_nm


class PreviewTracker:
    """Conversion + preview + corrections with the integral state (module docstring)."""

    def __init__(self, params: PreviewParams) -> None:
        self.params = params
        self.integral_ms = 0.0
        self.preview_xy_m = np.zeros((params.n_preview + 1, 2))
        self._path: FrenetPath | None = None
        self._out = np.zeros(6)
        self._vp = VehicleParams().as_array()
        self._limits = np.zeros(3)
        self._gains = np.zeros(8)

    def reset(self, path: FrenetPath, vehicle: VehicleParams, n_stages: int,
              state: np.ndarray) -> None:
        """Start of a run on ``path``; loads the compiled kernel (a plan of n_stages)."""
        p = self.params
        self._path = path
        self._vp = vehicle.as_array()
        self._limits = np.array([vehicle.max_steer_rad, vehicle.max_drive_torque_nm,
                                 vehicle.max_brake_torque_nm])
        self._gains = np.array([p.k_ps, p.k_pv, p.k_pvc, p.k_psc, p.k_isc,
                                1.0 if p.feedforward else 0.0, p.lookahead_s,
                                vehicle.understeer_gradient_rad_per_mps2])
        self.preview_xy_m = np.zeros((p.n_preview + 1, 2))
        self.integral_ms = 0.0
        # Load the compiled kernel now rather than in the first step.
        meta, coef, knots = path.tables()
        dummy_states = np.zeros((n_stages + 1, 3))
        dummy_states[:, 0] = np.linspace(0.0, 1.0, n_stages + 1)
        inner_step(np.asarray(state, dtype=np.float64), np.linspace(0.0, 1.0, n_stages + 1),
                   dummy_states, np.ones(n_stages), self._gains, self._vp, self._limits, 1,
                   0.01, meta, coef, knots, np.zeros((2, 2)), np.zeros(6))

    def clear(self) -> None:
        """Forget the integral (a new plan starts: launch hand-over)."""
        self.integral_ms = 0.0

    def hold(self, state: np.ndarray) -> None:
        """No plan to track this period (launch law): the preview collapses to the CG."""
        self.preview_xy_m[:] = state[:2]

    def track(self, state: np.ndarray, plan: OuterPlan, dt_s: float) -> TrackerOutput:
        """Conversion, preview and corrections for the measured (6,) ``state``."""
        if self._path is None:
            raise RuntimeError("PreviewTracker.track called before reset")
        p = self.params
        meta, coef, knots = self._path.tables()
        tau = np.ascontiguousarray(plan.stage_times_s, dtype=np.float64)
        states = np.ascontiguousarray(plan.states, dtype=np.float64)
        speeds = np.ascontiguousarray(plan.speeds_mps, dtype=np.float64)
        out = self._out
        inner_step(state, tau, states, speeds, self._gains, self._vp, self._limits,
                   p.n_preview, p.preview_dt_s, meta, coef, knots, self.preview_xy_m, out)
        d_ol, t_ol, pe_t, pe_n = float(out[0]), float(out[1]), float(out[2]), float(out[3])
        if p.preview and math.isfinite(pe_n) and math.isfinite(pe_t):
            w = self._lane_holding_weight(tau, states)
            bled = self.integral_ms * math.exp(-(1.0 - w) * dt_s / p.bleed_s)
            self.integral_ms = min(max(bled + w * pe_n * dt_s, -p.integral_limit_ms),
                                   p.integral_limit_ms)
            beyond = math.copysign(max(abs(pe_n) - p.manoeuvre_band_m, 0.0), pe_n)
            d_i = p.k_isc * self.integral_ms
            d_c = p.k_psc * (w * pe_n + (1.0 - w) * beyond) + d_i
            t_c = p.k_pvc * pe_t
        else:
            d_c, t_c, d_i, w = 0.0, 0.0, 0.0, 1.0
        return TrackerOutput(d_ol, t_ol, pe_t, pe_n, d_c, t_c, d_i, w)

    def _lane_holding_weight(self, tau: np.ndarray, states: np.ndarray) -> float:
        """w = exp(-(v_lat / manoeuvre_speed_mps)²), v_lat the plan's mean lateral speed
        across the road over the preview horizon, |y*(tau_p) - y*(0)| / tau_p (module
        docstring; the lateral offset y*, a state, is smooth where a cost such as J1
        makes the heading chatter); 1 if not finite."""
        p = self.params
        tau_p = min(p.n_preview * p.preview_dt_s, float(tau[-1]))
        if not tau_p > 0.0:
            return 1.0
        y_p = float(np.interp(tau_p, tau[: states.shape[0]], states[:, 1]))
        v_lat = abs(y_p - float(states[0, 1])) / tau_p
        if not math.isfinite(v_lat):
            return 1.0
        return math.exp(-((v_lat / p.manoeuvre_speed_mps) ** 2))
