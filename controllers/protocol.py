"""The Controller role: what the loop gives a controller each step and what it returns.

Frames and units
----------------
* World frame: SUMO's network coordinates [m], heading ``psi`` counter-clockwise from
  +X [rad] (the SUMO adapter converts to SUMO's navigation degrees).
* Reference-path Frenet frame: ``s`` arc length along the route's reference centreline
  [m], ``y`` signed lateral offset, positive to the left [m].

A controller declares its per-step diagnostics as a frozen dataclass deriving from
:class:`StepDiagnostics` (``diagnostics_type``); every field becomes a column of the
run's trace, so nothing a controller reports is lost on the way.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from controllers.behaviour.types import ObstaclePolicy, Obstacles, Side

if TYPE_CHECKING:  # numba modules: the registry (and the catalog check in the command's
    # parent process) import this module, and need neither
    from controllers.path.frenet import FrenetPath
    from controllers.plant.vehicle_model import VehicleParams

__all__ = ["Command", "ConfigError", "Controller", "ControllerBase", "EgoOnPath",
           "Observation", "ObstaclePolicy", "Obstacles", "ScenarioContext", "Side",
           "StepDiagnostics", "SumoDriverModel"]


class ConfigError(ValueError):
    """A controller option is wrong. ``key`` names it (dotted), ``expected`` says what fits."""

    def __init__(self, key: str, expected: str, got: Any = None,
                 more: tuple[ConfigError, ...] = ()) -> None:
        self.key = key
        self.expected = expected
        self.got = got
        # the other problems of the same options table, when all were collected
        self.more = more
        super().__init__(f"{key}: expected {expected}, got {got!r}"
                         + (f" (+{len(more)} more)" if more else ""))

    @property
    def all(self) -> tuple[ConfigError, ...]:
        """This problem and every other one found with it."""
        return (self, *self.more)


@dataclass(frozen=True)
class ScenarioContext:
    """What a controller learns once, at ``reset``.

    reference_xy_m: (M, 2) polyline of the ego lane's centreline along the route, in
        driving order. The Frenet path is built from it.
    lane_width_m: width of the ego's start lane [m].
    target_speed_mps: cruise speed set-point [m/s].
    control_period_s: time between two ``step`` calls [s].
    vehicle: the ego's single-track parameters (the plant is exactly this model).
    initial_state: (6,) plant state at t = 0, see ``vehicle_model.STATE_NAMES``.
    reference_smoothing_m: the heading smoothing [m] to build the Frenet path with
        (:meth:`reference_path`): 4 m for a raw lane polyline; the runs hand over an
        already smooth reference (``suite.road.reference``) and use a small value.
    """

    reference_xy_m: np.ndarray
    lane_width_m: float
    target_speed_mps: float
    control_period_s: float
    vehicle: VehicleParams
    initial_state: np.ndarray
    reference_smoothing_m: float = 4.0

    def reference_path(self) -> FrenetPath:
        """The Frenet path of the reference (cached: the loop and the controller share it)."""
        from controllers.path.frenet import FrenetPath

        return FrenetPath.cached(np.asarray(self.reference_xy_m, dtype=np.float64),
                                 smoothing_m=self.reference_smoothing_m)

    def __post_init__(self) -> None:
        ref = np.asarray(self.reference_xy_m, dtype=np.float64)
        if ref.ndim != 2 or ref.shape[1] != 2 or ref.shape[0] < 2:
            raise ValueError(f"reference_xy_m must have shape (M>=2, 2), got {ref.shape}")
        if self.lane_width_m <= 0 or self.target_speed_mps < 0 or self.control_period_s <= 0:
            raise ValueError(
                "ScenarioContext: lane width and control period must be > 0, speed >= 0")


@dataclass(frozen=True)
class EgoOnPath:
    """The ego's CG on the reference path, as the loop projected it this step (the same
    projection, hinted by the previous step's, that the behaviour and the trace use).

    s_m: arc length [m]; lat_m: lateral offset [m, left +]; heading_err_rad: yaw minus
    the path's tangent angle there, wrapped to (-pi, pi] [rad] (SUMO's driver: its yaw
    relative to its lane); path_heading_rad: the tangent angle gamma(s_m) [rad, CCW from
    +X]; curvature_1pm: the path's curvature kappa(s_m) [1/m, left +].
    """

    s_m: float
    lat_m: float
    heading_err_rad: float
    path_heading_rad: float
    curvature_1pm: float

    def __post_init__(self) -> None:
        for name in ("s_m", "lat_m", "heading_err_rad", "path_heading_rad", "curvature_1pm"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValueError(f"EgoOnPath.{name} must be a finite number, got {v!r}")


@dataclass(frozen=True)
class Observation:
    """What a controller gets every control period.

    state: (6,) measured plant state [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps].
    target_speed_mps: speed set-point (the behaviour lowers it to follow).
    obstacles: ellipses within the detection distance, nearest first, each with its
        vehicle's id (``obstacles.vehicle_ids``, () when not known).
    pass_side: +1 pass on the left, -1 on the right, 0 no obstacle or follow.
    lateral_reference_m: where the plan should settle across the reference path [m,
        left +]: 0 on the reference lane, the neighbour lane's centre while passing.
        It steps; controllers smooth it.
    evasive: the lateral move evades a stopped vehicle ahead that the ego could not stop
        for at a comfortable deceleration: a controller may move sideways faster.
    side: the behaviour's :class:`Side` (FOLLOW too, which passes on no side); None:
        the one of ``pass_side`` (LEFT, RIGHT or KEEP). It must agree with ``pass_side``.
    ego: the ego's CG on the reference path, already projected by the loop (None when
        the caller did not: a controller then projects ``state`` itself).
    """

    t_s: float
    state: np.ndarray
    target_speed_mps: float
    obstacles: Obstacles = field(default_factory=Obstacles.empty)
    pass_side: int = 0
    lateral_reference_m: float = 0.0
    evasive: bool = False
    side: Side | None = None
    ego: EgoOnPath | None = None

    def __post_init__(self) -> None:
        if self.pass_side not in (-1, 0, 1) or isinstance(self.pass_side, bool):
            raise ValueError(f"Observation.pass_side must be -1, 0 or +1, got {self.pass_side!r}")
        side = Side(self.pass_side) if self.side is None else Side(self.side)
        if side.pass_side != self.pass_side:
            raise ValueError(f"Observation.side {side.name} disagrees with pass_side "
                             f"{self.pass_side!r}")
        object.__setattr__(self, "side", side)


@dataclass(frozen=True, slots=True)
class StepDiagnostics:
    """Health and timing every controller reports each step (trace columns).

    outer_s, inner_s: time spent in the outer / inner loop [s] (NaN if n/a);
    residual: outer-loop optimality residual E = ||F||inf [-] (NaN if n/a);
    fallback: a safe fallback replaced the plan this step;
    guard_fired: barrier-guard interventions this step [-].
    """

    outer_s: float = math.nan
    inner_s: float = math.nan
    residual: float = math.nan
    fallback: bool = False
    guard_fired: int = 0


@dataclass(frozen=True)
class Command:
    """A controller's output for one period.

    steer_rad: front-wheel angle [rad]; torque_nm: total drive torque [N m] (negative
    brakes); diagnostics: an instance of the controller's ``diagnostics_type``;
    plan_xy_m: (N+1, 2) planned positions in the world frame (None: no plan);
    preview_xy_m: (Np+1, 2) the inner loop's preview of the CG (None: none).
    """

    steer_rad: float
    torque_nm: float
    diagnostics: StepDiagnostics = field(default_factory=StepDiagnostics)
    plan_xy_m: np.ndarray | None = None
    preview_xy_m: np.ndarray | None = None


@runtime_checkable
class Controller(Protocol):
    """One per scenario run. ``reset`` once, then ``step`` every control period.

    name: the registered name; diagnostics_type: the dataclass its commands carry;
    obstacle_policy: how the behaviour layer builds its ellipses (None: the controller
    takes no obstacles and drives its lane at the set speed).
    """

    name: str
    diagnostics_type: ClassVar[type[StepDiagnostics]]
    obstacle_policy: ObstaclePolicy | None

    def reset(self, context: ScenarioContext) -> None: ...

    def step(self, observation: Observation) -> Command: ...

    def parameters(self) -> Mapping[str, Any]:
        """JSON-serialisable parameters (nested tables allowed), for logs and reports."""
        ...


class ControllerBase:
    """A :class:`Controller` with defaults for everything but ``reset`` and ``step``.

    Subclass it and write those two: ``diagnostics_type`` is :class:`StepDiagnostics`
    (override it with your own frozen dataclass), ``obstacle_policy`` None (the controller
    takes no obstacles: the behaviour keeps it in its lane at the set speed; set an
    :class:`ObstaclePolicy` to get ellipses), ``parameters()`` {} and ``name`` the name the
    registry built it under (``controllers.registry.register(name, MyController)``
    registers the class itself as the factory; docs/plugins.md).
    """

    name: str = ""
    diagnostics_type: ClassVar[type[StepDiagnostics]] = StepDiagnostics
    obstacle_policy: ObstaclePolicy | None = None

    def reset(self, context: ScenarioContext) -> None:
        """Start a run (once, before the first ``step``)."""
        raise NotImplementedError(f"{type(self).__name__}.reset")

    def step(self, observation: Observation) -> Command:
        """One control period: the command to apply until the next call."""
        raise NotImplementedError(f"{type(self).__name__}.step")

    def parameters(self) -> Mapping[str, Any]:
        """JSON-serialisable parameters for logs and reports (none by default)."""
        return {}


@dataclass(frozen=True)
class SumoDriverModel:
    """Not a controller: SUMO's own driver model drives the ego (catalog name ``sumo``).

    The run then takes the ego's pose from SUMO instead of from a plant; its car
    following and lane-change models are SUMO's (named here for the record).
    """

    name: str = "sumo"
    car_following: str = "Krauss"
    lane_change: str = "LC2013"

    def parameters(self) -> Mapping[str, Any]:
        return {"car_following": self.car_following, "lane_change": self.lane_change}
