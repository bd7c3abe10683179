"""The outer loop's role (METHOD.md §1, §5): a planner on the SPMM in the Frenet frame.

C/GMRES (``controllers.two_loop.outer.cgmres``) and the Ipopt baseline
(``controllers.two_loop.outer.ipopt``) both implement :class:`OuterSolver`, so the
two-loop controller can swap one for the other on the same scenarios.

Frenet state (augmented model (36), used with J3): x = [s_m, y_m, theta_rad]
where theta is the world heading of the SPMM velocity vector (CCW from +X,
unwrapped consistently with the path's tangent angle gamma(s)). Inputs:
u = [V_mps, omega_radps] (J3), plus one slack Z_j per obstacle slot.
For J1/J2 (model (10)) the state is [s_m, y_m] and the inputs [theta_rad, V_mps];
plans are still reported with three state columns, theta taken from the input.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from controllers.protocol import Obstacles


@dataclass
class OuterPlan:
    """One outer update's result.

    stage_times_s: (N+1,) offsets tau_i from now of the plan's nodes [s].
    states: (N+1, 3) planned [s_m, y_m, theta_rad] at those nodes.
    speeds_mps: (N,) planned V at stages 0..N-1; headings_rad: (N,) planned theta.
    residual: E = ||F||inf after the update (NaN if not applicable).
    fallback: True when the solver was re-initialised / a safe plan was used.
    guard_fired: barrier-guard interventions during this update.
    solve_s: wall time of the update [s].
    """

    stage_times_s: np.ndarray
    states: np.ndarray
    speeds_mps: np.ndarray
    headings_rad: np.ndarray
    residual: float
    fallback: bool
    guard_fired: int
    solve_s: float


class OuterSolver(Protocol):
    """reset once per run; update every outer period with the measured Frenet state
    (and the lateral reference yr the plan should settle on)."""

    def reset(self, x0: np.ndarray, target_speed_mps: float) -> None: ...

    def update(self, t_s: float, x0: np.ndarray, obstacles: Obstacles,
               target_speed_mps: float, dt_s: float,
               lateral_reference_m: float = 0.0,
               lateral_weight: float | None = None) -> OuterPlan:
        """lateral_reference_m: yr [m, left +] of the running cost Cy (y - yr)² (and of
        the terminal CyT (y_N - yr)²), constant over the horizon; 0 keeps the paper's
        Cy y². lateral_weight: Cy [1/(m² s)] of this update (None: OuterParams.c_y).
        Callers pass smooth signals (TwoLoopController shapes the runner's steps): a
        jump in yr or Cy is a jump in the optimality residual."""
        ...
