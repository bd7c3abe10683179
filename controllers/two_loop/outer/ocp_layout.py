"""The data layout of the outer loop's OCP (:mod:`controllers.two_loop.outer.ocp`).

What the compiled kernels are given, packed into float arrays so that they are compiled
once: the stage grid (``stage_fractions``: tau_i / T, (N+1,)), the per-update parameter
vector (``pack_params``: (N_PACKED,), indices ``_P_*``), the obstacle slot table
(``obstacle_table``: (K, OBS_COLS)) and the per-stage width of the unknowns U
(``stage_width``: m = 2 + 2K).
"""

from __future__ import annotations

import math

import numpy as np

from controllers.two_loop.outer.params import OcpParams

__all__ = ["N_PACKED", "OBS_COLS", "barrier_scale", "obstacle_row", "obstacle_table",
           "pack_params", "stage_fractions", "stage_times", "stage_width"]

# Indices into the packed parameter vector.
_P_COST, _P_CY, _P_CYD, _P_CSD, _P_CTHD, _P_CTH, _P_CV, _P_CZ, _P_ZETA = range(9)
_P_CYT, _P_CET, _P_VT, _P_SCALE = 9, 10, 11, 12
_P_YREF, _P_YREFD = 13, 14  # lateral reference yr [m] and its rate [m/s] (C/GMRES only)
_P_CYR = 15  # rate of Cy [1/(m² s²)] when the caller schedules it (C/GMRES only)
# The barrier's speed scale sigma in [barrier_min_scale, 1] (Cz_eff = sigma Cz), its rate
# [1/s] (C/GMRES only), and the weight Cvn of the penalty Cvn min(V, 0)² on negative speeds.
_P_CZS, _P_CZSR, _P_CVN = 16, 17, 18
# The lane corridor [y_lo, y_hi] [m] of the update (the lanes the behaviour lets the CG
# use; -inf / +inf: none) and the weight C_lane of its exterior penalty
# C_lane (max(0, y - y_hi)² + max(0, y_lo - y)²).
_P_YLO, _P_YHI, _P_CLANE = 19, 20, 21
N_PACKED = 22
# Fast-math flags of the hot kernels: no 'nnan'/'ninf' (non-finite checks stay valid), and
# no 'reassoc'/'contract': with them LLVM may reorder sums and fuse multiply-adds
# differently when a kernel is compiled in the run's process than when it comes from
# numba's cache, so the first run after an install or a change gave other numbers than
# every later one (a two_loop run of the paper catalog differed from step 1). Without
# them a kernel computes the same bits however it was compiled.
_FM = {"nsz", "arcp", "afn"}
# Obstacle table columns: s, y, v_s, v_y, A, B, active, barrier weight w, dw/dt.
OBS_COLS = 9


def stage_width(n_slots: int) -> int:
    """Unknowns per stage m = 2 + 2K (two inputs, a slack and a multiplier per slot)."""
    return 2 + 2 * n_slots


def stage_fractions(params: OcpParams) -> np.ndarray:
    """tau_i / T, shape (N+1,), from 0 to 1 (uniform or Chebyshev)."""
    i = np.arange(params.n_stages + 1, dtype=np.float64)
    if params.chebyshev:
        w = 0.5 * (1.0 - np.cos(i * np.pi / params.n_stages))
    else:
        w = i / params.n_stages
    w[0], w[-1] = 0.0, 1.0
    return w


def stage_times(params: OcpParams, horizon_s: float | None = None) -> np.ndarray:
    """Stage nodes tau_i [s], shape (N+1,), for the full (or a given) horizon."""
    return stage_fractions(params) * (params.horizon_s if horizon_s is None else horizon_s)


def barrier_scale(params: OcpParams, speed_scale_mps: float) -> float:
    """sigma = clip(v / ``barrier_speed_mps``, ``barrier_min_scale``, 1) of the speed scale
    v [m/s] of the problem (the larger of the target speed and the planned speed now):
    the barrier's weight is sigma Cz (docs/two_loop.md, "Barrier at low speed")."""
    v = float(speed_scale_mps)
    if not math.isfinite(v):
        return 1.0
    return min(max(v / params.barrier_speed_mps, params.barrier_min_scale), 1.0)


def pack_params(params: OcpParams, target_speed_mps: float,  # noqa: PLR0913 - a keyword per packed field
                lateral_reference_m: float = 0.0, lateral_reference_rate_mps: float = 0.0,
                lateral_weight: float | None = None, lateral_weight_rate: float = 0.0,
                row_scaling: bool = False, barrier_weight_scale: float | None = None,
                barrier_weight_scale_rate: float = 0.0,
                lane_corridor_m: tuple[float, float] | None = None) -> np.ndarray:
    """Packed float vector (N_PACKED,) for the compiled kernels (per-update data included).

    target_speed_mps: Vt [m/s]; lateral_reference_m: yr [m] in Cy (y - yr)² and
    CyT (y_N - yr)²; lateral_weight: Cy [1/(m² s)] of this update (None: params.c_y;
    a caller may schedule it); the rates yr' [m/s] and Cy' [1/(m² s²)] are used by
    :func:`controllers.two_loop.outer.cgmres.cgmres_updates` to move yr and Cy across a
    control period (ignored by the residual itself); row_scaling: the residual returns
    D(U) F (a C/GMRES device, see :func:`ocp_residual`); barrier_weight_scale: sigma of
    the barrier weight sigma Cz (None: :func:`barrier_scale` of the target speed), its rate
    [1/s] moved across a control period by C/GMRES like Cy's; lane_corridor_m: the
    lane corridor (y_lo, y_hi) [m] of the penalty C_lane (max(0, y - y_hi)² +
    max(0, y_lo - y)²) (None: no corridor, the penalty is zero everywhere).
    """
    out = np.zeros(N_PACKED)
    out[_P_COST] = params.cost_id
    out[_P_CY] = params.c_y if lateral_weight is None else lateral_weight
    out[_P_CYD] = params.c_ydot
    out[_P_CSD] = params.c_sdot
    out[_P_CTHD] = params.c_thetadot
    out[_P_CTH] = params.c_theta
    out[_P_CV] = params.c_v
    out[_P_CZ] = params.c_z
    out[_P_ZETA] = params.zeta
    out[_P_CYT] = params.c_y_terminal
    out[_P_CET] = params.c_e_terminal
    out[_P_VT] = target_speed_mps
    out[_P_SCALE] = 1.0 if row_scaling else 0.0
    out[_P_YREF] = lateral_reference_m
    out[_P_YREFD] = lateral_reference_rate_mps
    out[_P_CYR] = lateral_weight_rate
    out[_P_CZS] = (barrier_scale(params, target_speed_mps) if barrier_weight_scale is None
                   else barrier_weight_scale)
    out[_P_CZSR] = barrier_weight_scale_rate
    out[_P_CVN] = params.c_v_negative
    lo, hi = (-math.inf, math.inf) if lane_corridor_m is None else lane_corridor_m
    if not lo <= hi:
        raise ValueError(f"lane_corridor_m: expected y_lo <= y_hi, got {lane_corridor_m!r}")
    out[_P_YLO] = lo
    out[_P_YHI] = hi
    out[_P_CLANE] = params.c_lane
    return out


def obstacle_row(s_m: float, y_m: float, a_m: float, b_m: float, *, vs_mps: float = 0.0,  # noqa: PLR0913 - a keyword per column of the kernels' obstacle row
                 vy_mps: float = 0.0, active: bool = True, weight: float = 1.0,
                 weight_rate_1ps: float = 0.0) -> np.ndarray:
    """One slot of the obstacle table (OBS_COLS,): an ellipse centred at (s, y) [m] with
    semi-axes A = ``a_m`` along s and B = ``b_m`` across [m], moving at (v_s, v_y) [m/s],
    barrier weight in [0, 1] changing at ``weight_rate_1ps`` [1/s]
    (:func:`obstacle_table` names the columns)."""
    if not (a_m > 0.0 and b_m > 0.0):
        raise ValueError(f"a_m/b_m: expected > 0, got {a_m}/{b_m}")
    if not 0.0 <= weight <= 1.0:
        raise ValueError(f"weight: expected in [0, 1], got {weight}")
    return np.array([s_m, y_m, vs_mps, vy_mps, a_m, b_m, 1.0 if active else 0.0, weight,
                     weight_rate_1ps], dtype=np.float64)


def obstacle_table(n_slots: int) -> np.ndarray:
    """Empty obstacle table (K, 9).

    Columns: s, y [m] and v_s, v_y [m/s] at the table's time stamp, A, B [m],
    active (0/1), barrier weight w in [0, 1] at the time stamp, dw/dt [1/s].
    Slot j's barrier weight at update time t is Cz clip(w + dw/dt (t - t_stamp), 0, 1):
    obstacles fade in and out of the problem instead of switching (see
    ``controllers.two_loop.outer.cgmres``); the fade enters F_t like the obstacle's motion.
    """
    tab = np.zeros((n_slots, OBS_COLS))
    tab[:, 4] = 1.0
    tab[:, 5] = 1.0
    tab[:, 7] = 1.0
    return tab
