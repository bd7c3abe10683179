"""The discretised OCP seen from Python (tests, baselines, tools): :class:`SpmmProblem`."""

from __future__ import annotations

import numpy as np

from controllers.path.frenet import FrenetPath
from controllers.two_loop.outer.ocp import ocp_objective, ocp_residual
from controllers.two_loop.outer.ocp_layout import pack_params, stage_fractions, stage_width
from controllers.two_loop.outer.ocp_start import stage_init
from controllers.two_loop.outer.params import OcpParams

__all__ = ["SpmmProblem"]


class SpmmProblem:
    """Python-side view of the discretised OCP for one path (tests, baselines, tools).

    Holds the path tables and stage fractions; the number of slots K is that of the
    obstacle table ``obs`` (K, OBS_COLS) each call gets, U has N (2 + 2K) entries.
    ``residual(U, x0, ...)`` returns F (N m,), the states and costates (N+1, 3). Not
    used in the real-time loop (which calls the kernels).
    """

    def __init__(self, path: FrenetPath, params: OcpParams) -> None:
        self.path = path
        self.params = params
        self.meta, self.coef, _ = path.tables()
        self.w = stage_fractions(params)

    def n_unknowns(self, n_slots: int) -> int:
        """N (2 + 2K): the length of U with K obstacle slots."""
        return self.params.n_stages * stage_width(n_slots)

    def residual(self, uvec: np.ndarray, x0: np.ndarray, obs: np.ndarray,  # noqa: PLR0913 - a hot path: the kernels' flat arrays and scalars
                 target_speed: float,
                 horizon: float | None = None, tshift: float = 0.0, scaled: bool = False,
                 lateral_reference_m: float = 0.0,
                 lane_corridor_m: tuple[float, float] | None = None,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(F, states (N+1, 3), costates (N+1, 3)); F unscaled unless ``scaled``;
        lane_corridor_m: (y_lo, y_hi) of the corridor penalty (None: none)."""
        n = self.params.n_stages
        prm = pack_params(self.params, target_speed, lateral_reference_m, row_scaling=scaled,
                          lane_corridor_m=lane_corridor_m)
        xs = np.empty((n + 1, 3))
        ps = np.empty((n + 1, 12))
        f = np.empty(self.n_unknowns(obs.shape[0]))
        ocp_residual(np.ascontiguousarray(uvec, dtype=np.float64),
                     np.asarray(x0, dtype=np.float64), float(horizon or self.params.horizon_s),
                     float(tshift), prm, obs, self.w, self.meta, self.coef, xs, ps, f)
        return f, xs, ps[:, :3].copy()

    def objective(self, uvec: np.ndarray, x0: np.ndarray, obs: np.ndarray,  # noqa: PLR0913 - a hot path: the kernels' flat arrays and scalars
                  target_speed: float,
                  horizon: float | None = None, tshift: float = 0.0,
                  with_multipliers: bool = False, lateral_reference_m: float = 0.0,
                  lane_corridor_m: tuple[float, float] | None = None) -> float:
        """The discrete objective (reduced Lagrangian with ``with_multipliers``)."""
        return float(ocp_objective(np.ascontiguousarray(uvec, dtype=np.float64),
                                   np.asarray(x0, dtype=np.float64),
                                   float(horizon or self.params.horizon_s), float(tshift),
                                   pack_params(self.params, target_speed, lateral_reference_m,
                                               lane_corridor_m=lane_corridor_m),
                                   obs, self.w,
                                   self.meta, self.coef, with_multipliers))

    def initial_guess(self, x0: np.ndarray, obs: np.ndarray, target_speed: float,
                      tshift: float = 0.0, lateral_reference_m: float = 0.0) -> np.ndarray:
        """The exact zero-horizon solution (:func:`stage_init`), U of length N (2 + 2K)."""
        u = np.empty(self.n_unknowns(obs.shape[0]))
        stage_init(np.asarray(x0, dtype=np.float64), float(tshift),
                   pack_params(self.params, target_speed, lateral_reference_m), obs,
                   self.meta, self.coef,
                   self.params.n_stages, u)
        return u
