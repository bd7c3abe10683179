"""The Controller role: what the runner gives a controller and what it gets back.

Frames and units
----------------
* World frame: SUMO's network coordinates [m], heading ``psi`` counter-clockwise
  from +X [rad] (the runner converts to SUMO's navigation degrees).
* Reference-path Frenet frame: ``s`` arc length along the route's reference
  centreline [m], ``y`` signed lateral offset, positive to the left [m].
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from controllers.plant.vehicle_model import VehicleParams


class ConfigError(ValueError):
    """A controller option is wrong. ``key`` names it (dotted), ``expected`` says what fits."""

    def __init__(self, key: str, expected: str, got: Any = None) -> None:
        self.key = key
        self.expected = expected
        self.got = got
        super().__init__(f"{key}: expected {expected}, got {got!r}")


@dataclass(frozen=True)
class ScenarioContext:
    """What a controller learns once, at ``reset``.

    reference_xy_m: (M, 2) polyline of the ego lane's centreline along the route,
        in driving order (from SUMO lane shapes). The Frenet path is built from it.
    lane_width_m: width of the ego's start lane.
    target_speed_mps: cruise speed set-point.
    control_period_s: time between two ``step`` calls.
    vehicle: the ego's STVM parameters (the plant is exactly this model).
    initial_state: (6,) plant state at t = 0, see ``vehicle_model.STATE_NAMES``.
    """

    reference_xy_m: np.ndarray
    lane_width_m: float
    target_speed_mps: float
    control_period_s: float
    vehicle: VehicleParams
    initial_state: np.ndarray

    def __post_init__(self) -> None:
        ref = np.asarray(self.reference_xy_m, dtype=np.float64)
        if ref.ndim != 2 or ref.shape[1] != 2 or ref.shape[0] < 2:
            raise ValueError(f"reference_xy_m must have shape (M>=2, 2), got {ref.shape}")
        if self.lane_width_m <= 0 or self.target_speed_mps < 0 or self.control_period_s <= 0:
            raise ValueError(
                "ScenarioContext: lane width and control period must be > 0, speed >= 0")


@dataclass(frozen=True)
class Obstacles:
    """Obstacle ellipses as the controller sees them, all arrays of shape (K,).

    In the reference-path Frenet frame: centre ``(s_m, y_m)`` at t (the lateral
    offset OS already applied, away from the pass side), velocity
    ``(speed_s_mps, speed_y_mps)`` for the constant-velocity prediction
    s_j(tau) = s_m + speed_s_mps * tau, semi-axes ``semi_a_m`` (along the path) and
    ``semi_b_m`` (across), already including the ego allowance and safety margin.
    """

    s_m: np.ndarray
    y_m: np.ndarray
    speed_s_mps: np.ndarray
    speed_y_mps: np.ndarray
    semi_a_m: np.ndarray
    semi_b_m: np.ndarray

    @staticmethod
    def empty() -> Obstacles:
        z = np.zeros(0)
        return Obstacles(z, z, z, z, z, z)

    @property
    def count(self) -> int:
        return int(self.s_m.shape[0])


@dataclass(frozen=True)
class Observation:
    """What a controller gets every control period.

    state: (6,) measured plant state [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps].
    target_speed_mps: current speed set-point (the runner lowers it to follow a
        blocked lane's obstacle when no side is free).
    obstacles: ellipses within the detection distance, nearest first.
    pass_side: +1 pass on the left, -1 on the right, 0 no obstacle or follow.
    lateral_reference_m: where the plan should settle across the reference path
        [m, left +]: 0 on the reference lane; the centre of the neighbour lane
        (signed distance between lane centres) while passing on that side. The
        runner steps it; controllers smooth it (see ``TwoLoopParams``).
    """

    t_s: float
    state: np.ndarray
    target_speed_mps: float
    obstacles: Obstacles = field(default_factory=Obstacles.empty)
    pass_side: int = 0
    lateral_reference_m: float = 0.0


@dataclass
class Command:
    """A controller's output for one period.

    steer_rad: front-wheel angle; torque_nm: total drive torque (negative brakes).
    diagnostics: per-step scalars, names with units. Well-known keys (all optional):
      ``outer_s``, ``inner_s`` (time spent per loop), ``residual`` (E = ||F||inf),
      ``fallback`` (1.0 if a safe fallback replaced the plan this step),
      ``guard_fired`` (barrier guard count this step), ``steer_outer_rad``,
      ``steer_corr_rad``, ``torque_outer_nm``, ``torque_corr_nm``,
      ``planned_speed_mps``, ``preview_err_t_m``, ``preview_err_n_m``.
    arrays: optional per-step arrays for logs: ``plan_xy_m`` (N+1, 2) planned SPMM
      positions in the world frame, ``preview_xy_m`` (Np+1, 2) STVM preview of CG.
    """

    steer_rad: float
    torque_nm: float
    diagnostics: dict[str, float] = field(default_factory=dict)
    arrays: dict[str, np.ndarray] = field(default_factory=dict)


@runtime_checkable
class Controller(Protocol):
    """One per scenario run. ``reset`` once, then ``step`` every control period.

    ``simulated_by_sumo`` is True only for the controller that hands the ego to
    SUMO's own driver model; the runner then reads the ego's pose from SUMO.
    """

    name: str
    simulated_by_sumo: bool

    def reset(self, context: ScenarioContext) -> None: ...

    def step(self, observation: Observation) -> Command: ...

    def parameters(self) -> Mapping[str, Any]:
        """Flat, JSON-serialisable parameters, for logs and reports."""
        ...


@dataclass(frozen=True)
class ObstaclePolicy:
    """How the runner turns other vehicles into the controller's ellipses (METHOD.md §4).

    A controller that avoids obstacles exposes one as ``obstacle_policy``; the
    runner builds ``Observation.obstacles`` with it. Semi-axes:
    A = length_obstacle/2 + length_ego/2 + margin_long_m  (along the path),
    B = width_obstacle/2 + width_ego/2 + margin_lat_m     (across),
    i.e. the obstacle's half size plus the ego's half size (the SPMM is a point)
    plus a margin. Vehicles whose box centre is within ``detection_distance_m``
    of the ego CG (and not more than ``rear_range_m`` behind it) enter the problem,
    nearest first, at most ``max_obstacles``. ``offset_m`` is added to the
    obstacle's y away from the pass side. ``moving_obstacles`` feeds traffic with
    its speed (constant-velocity prediction); otherwise only stalled vehicles.
    """

    # 100 m: at 30 m/s the obstacle must enter before the end of a 2.4 s (72 m)
    # horizon reaches its ellipse (A ~ 10.5 m), else E jumps when it appears.
    detection_distance_m: float = 100.0
    rear_range_m: float = 10.0
    margin_long_m: float = 2.0
    margin_lat_m: float = 0.4
    offset_m: float = 0.3
    max_obstacles: int = 3
    moving_obstacles: bool = True

    def __post_init__(self) -> None:
        for name in ("detection_distance_m", "rear_range_m", "margin_long_m", "margin_lat_m",
                     "offset_m"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and np.isfinite(value) and value >= 0):
                raise ValueError(
                    f"ObstaclePolicy.{name} must be a finite number >= 0, got {value!r}")
        if not (isinstance(self.max_obstacles, int) and self.max_obstacles >= 0):
            raise ValueError(
                f"ObstaclePolicy.max_obstacles must be an int >= 0, got {self.max_obstacles!r}")
