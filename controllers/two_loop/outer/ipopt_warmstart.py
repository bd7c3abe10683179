"""Ipopt outer loop, the warm start: the previous solution (primal and dual) moved to now.

An accepted :class:`Solution` lives on its own stage grid tau_0..tau_N (relative to its
time t_s); :func:`shift_solution` re-samples it at tau + (t - t_s) and re-anchors it at
the measured state, :func:`with_obstacles` gives each obstacle of the update its slacks
Z_ij and multipliers (carried over from a matched previous obstacle, else
Z = sqrt(max(c_j, 0)) + 0.1 and zero duals). Used by
:class:`controllers.two_loop.outer.ipopt_planner.IpoptOuter`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from controllers.two_loop.outer.ipopt_nlp import OBS_COLS, J3Weights, ellipse_values

__all__ = ["Solution", "shift_solution", "with_obstacles"]


@dataclass
class Solution:
    """An accepted plan on its own time grid, with the duals Ipopt returned."""

    t_s: float
    tau: np.ndarray  # (N+1,)
    x: np.ndarray  # (N+1, 3), absolute s
    u: np.ndarray  # (N, 2)
    z: np.ndarray  # (N, K) slacks (NaN where not defined)
    obs: np.ndarray  # (K, 6) obstacles it was solved with, at t_s
    lam_dyn: np.ndarray  # (N, 3)
    lam_obs: np.ndarray  # (N+1, K), divided by the stage's dtau (NaN where none)
    lam_u: np.ndarray  # (N, 2) bound multipliers of V, omega divided by dtau
    lam_z: np.ndarray  # (N, K) bound multipliers of Z divided by dtau


def _interp_rows(t_new: np.ndarray, t_old: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear interpolation of each column of values (len(t_old), m) at t_new, held at ends."""
    if values.shape[1] == 0:
        return np.zeros((t_new.shape[0], 0))
    return np.stack([np.interp(t_new, t_old, values[:, c]) for c in range(values.shape[1])],
                    axis=1)


def shift_solution(prev: Solution, t_s: float, tau: np.ndarray, x0: np.ndarray, obs: np.ndarray,
           weights: J3Weights) -> Solution:
    """The previous solution moved to now: every quantity re-sampled at tau + elapsed.

    Stage quantities (inputs, slacks, multipliers / dtau) are interpolated on the old
    stage grid tau_0..tau_{N-1}, node quantities (states, node multipliers) on
    tau_0..tau_N; past the old horizon they are held (s extrapolated with the last
    speed). Obstacles are matched to the previous ones by their predicted centres;
    a new obstacle gets Z from the ellipse value of the shifted plan and zero duals.
    """
    shift = max(float(t_s) - prev.t_s, 0.0)
    n = tau.shape[0] - 1
    ts = tau[:-1] + shift
    tn = tau + shift
    u = _interp_rows(ts, prev.tau[:-1], prev.u)
    lam_u = _interp_rows(ts, prev.tau[:-1], prev.lam_u)
    lam_dyn = _interp_rows(ts, prev.tau[:-1], prev.lam_dyn)
    x = _interp_rows(tn, prev.tau, prev.x)
    beyond = tn > prev.tau[-1]
    if np.any(beyond):
        x[beyond, 0] = prev.x[-1, 0] + prev.u[-1, 0] * (tn[beyond] - prev.tau[-1])
    # Re-anchor at the measured state, keeping the plan's shape.
    offset = x0 - x[0]
    x = x + offset[None, :] * np.linspace(1.0, 0.0, n + 1)[:, None]
    x[0] = x0
    out = Solution(float(t_s), tau.copy(), x, u, np.zeros((n, 0)), np.zeros((0, OBS_COLS)),
                    lam_dyn, np.zeros((n + 1, 0)), lam_u, np.zeros((n, 0)))
    return with_obstacles(out, obs, prev=prev, shift=shift, weights=weights)


def with_obstacles(sol: Solution, obs: np.ndarray, prev: Solution | None = None,
                    shift: float = 0.0, weights: J3Weights | None = None) -> Solution:
    """Attach obstacles ``obs`` to a guess: slacks and obstacle multipliers per obstacle."""
    n = sol.tau.shape[0] - 1
    k = obs.shape[0]
    z = np.zeros((n, k))
    lam_z = np.zeros((n, k))
    lam_obs = np.zeros((n + 1, k))
    cvals = ellipse_values(sol.x, sol.tau, obs) if k else np.zeros((n + 1, 0))
    for j in range(k):
        match = -1
        if prev is not None and prev.obs.shape[0]:
            pred_s = prev.obs[:, 0] + prev.obs[:, 2] * shift
            pred_y = prev.obs[:, 1] + prev.obs[:, 3] * shift
            dist = np.abs(pred_s - obs[j, 0]) + np.abs(pred_y - obs[j, 1])
            best = int(np.argmin(dist))
            if dist[best] < 3.0:
                match = best
        if match >= 0 and prev is not None:
            ts = sol.tau[:-1] + shift
            tn = sol.tau + shift
            z[:, j] = np.interp(ts, prev.tau[:-1], np.nan_to_num(prev.z[:, match], nan=1.0))
            lam_z[:, j] = np.interp(ts, prev.tau[:-1], prev.lam_z[:, match])
            lam_obs[:, j] = np.interp(tn, prev.tau, prev.lam_obs[:, match])
        else:
            z[:, j] = np.sqrt(np.maximum(cvals[:-1, j], 0.0)) + 0.1
    sol.z = z
    sol.lam_z = lam_z
    sol.lam_obs = lam_obs
    sol.obs = obs.copy()
    return sol
