"""The outer loop's role (docs/method.md §1, §5): a planner on the SPMM in the Frenet frame.

C/GMRES (:class:`controllers.two_loop.outer.cgmres.CgmresOuter`) and the Ipopt baseline
(:class:`controllers.two_loop.outer.ipopt_planner.IpoptOuter`) both implement
:class:`OuterPlanner`, so the two-loop controller runs either on the same scenarios.

Frenet state (augmented model (36), used with J3): x = [s_m, y_m, theta_rad] where
theta is the world heading of the SPMM velocity vector (CCW from +X, unwrapped
consistently with the path's tangent angle gamma(s)). Inputs: u = [V_mps,
omega_radps] (J3), plus one slack Z_j per obstacle slot. For J1/J2 (model (10)) the
state is [s_m, y_m] and the inputs [theta_rad, V_mps]; plans are still reported with
three state columns, theta taken from the input.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from controllers.behaviour.types import Obstacles
from controllers.path.frenet import FrenetPath


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
    target_speed_mps: the OCP's target speed Vt of this update, the set-point through
        the jerk-limited ramp [m/s] (NaN if the plan has none).
    """

    stage_times_s: np.ndarray
    states: np.ndarray
    speeds_mps: np.ndarray
    headings_rad: np.ndarray
    residual: float
    fallback: bool
    guard_fired: int
    solve_s: float
    target_speed_mps: float = math.nan


class OuterPlanner(Protocol):
    """``reset`` once per run, ``update`` every control period with the measured Frenet
    state x0 (3,); ``restart`` re-initialises mid-run (after a launch hand-over).

    updates_per_period: solver updates one ``update`` call runs (diagnostics);
    horizon_growth(elapsed_s): relative length in [0, 1] of the planner's horizon
    ``elapsed_s`` after a start (1 for a planner whose horizon is full at once).
    """

    @property
    def updates_per_period(self) -> int: ...

    def horizon_growth(self, elapsed_s: float) -> float: ...

    def reset(self, x0: np.ndarray, target_speed_mps: float) -> None:
        """Forget the run; the next update starts afresh at its state, its OCP target
        speed ramping from ``target_speed_mps`` (the measured speed) toward each update's
        set-point."""
        ...

    def restart(self, x0: np.ndarray, target_speed_mps: float,
                target_accel_mps2: float = 0.0) -> None:
        """Start afresh at the next update, keeping the run's counters; the OCP's
        target-speed ramp continues from ``target_speed_mps`` [m/s] with acceleration
        ``target_accel_mps2`` [m/s²] (no step in the planned speed's rate)."""
        ...

    def update(self, t_s: float, x0: np.ndarray, obstacles: Obstacles,
               target_speed_mps: float, dt_s: float,
               lateral_reference_m: float = 0.0,
               lateral_weight: float | None = None) -> OuterPlan:
        """lateral_reference_m: yr [m, left +] of the running cost Cy (y - yr)² (and of
        the terminal CyT (y_N - yr)²), constant over the horizon; 0 keeps the paper's
        Cy y². lateral_weight: Cy [1/(m² s)] of this update (None: the OCP's c_y).
        Callers pass smooth signals (the lateral-reference shaper smooths the
        behaviour's steps): a jump in yr or Cy is a jump in the optimality residual."""
        ...


@runtime_checkable
class CruiseAware(Protocol):
    """A planner that takes the run's cruise set-point (after ``reset``): set-points at
    or above it ramp down at ``set_speed_decel_mps2``, lower ones (the behaviour lowered
    them to follow) at ``target_decel_mps2``
    (:class:`controllers.two_loop.outer.target_ramp.TargetSpeedRamp`). Both built-in planners
    are; a planner that is not ramps as it likes (the controller only tells those that
    are)."""

    def set_cruise_speed(self, cruise_speed_mps: float) -> None: ...


@runtime_checkable
class LaneCorridorAware(Protocol):
    """A planner whose OCP keeps its plan in a lane corridor [y_lo, y_hi] [m, left +]
    across the reference path (the lanes the behaviour lets the car use): C/GMRES's
    exterior penalty (docs/two_loop.md, "Lane corridor"). The controller hands it the
    corridor before every update; a planner that is not keeps no corridor (Ipopt)."""

    def set_lane_corridor(self, y_lo_m: float, y_hi_m: float) -> None: ...


# Builds a run's planner once the path is known: (path, number of obstacle slots K).
PlannerFactory = Callable[[FrenetPath, int], OuterPlanner]
