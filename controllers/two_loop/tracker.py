"""Inner preview tracker: the plan -> STVM inputs, corrected by the preview error.

Around the compiled kernel :func:`controllers.two_loop.preview.inner_step` (conversion
(13)(14) with feed-forward, Np-step STVM preview from the measured state, preview
error PE = planned - predicted at tau_p = Np dt_p split along the path's tangent and
normal, docs/method.md §7), this stage holds what lives between steps: the integral
of PE_n and the preview itself. Per control period, with dt the elapsed time:

    I      <- clip(I + PE_n dt, -integral_limit_ms, integral_limit_ms)
    delta_c = K_Psc PE_n + K_Isc I,    T_c = K_Pvc PE_t                 (38)(39)
    delta   = delta_ol + delta_c,      T   = T_ol + T_c                 (40)(41)

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
    feedforward: bool = param(True, "-", "cornering steer (L + K_us V²) omega/V and m R dV/dt")

    def __post_init__(self) -> None:
        check_leaves(self)
        for name in ("preview_dt_s", "k_ps"):
            check_range(self, name, gt=0.0)
        for name in ("lookahead_s", "k_pv", "k_pvc", "k_psc", "k_isc", "integral_limit_ms"):
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
            self.integral_ms = min(max(self.integral_ms + pe_n * dt_s, -p.integral_limit_ms),
                                   p.integral_limit_ms)
            d_c = p.k_psc * pe_n + p.k_isc * self.integral_ms
            t_c = p.k_pvc * pe_t
        else:
            d_c, t_c = 0.0, 0.0
        return TrackerOutput(d_ol, t_ol, pe_t, pe_n, d_c, t_c)
