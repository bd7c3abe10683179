"""Plant-only runs: production's loop (:func:`suite.run.loop.run_loop`) on a scripted world.

:func:`run_plant` composes the same stages as a SUMO run (:mod:`suite.run.runner`):
:class:`~suite.run.dynamics.PlantDynamics` (the single-track plant pushes its pose into
the world), the controller's behaviour (:class:`~controllers.behaviour.decision.LaneBehaviour`
when it takes obstacles, else :class:`~controllers.behaviour.protocol.CruiseBehaviour`),
the safety monitor, the trace recorder and the standard stop rule, with a
:class:`~suite.world.scripted.ScriptedWorld` instead of SUMO and the road's lanes as the
lane source. What it returns is the recorder's typed :class:`~reports.record.Trace`
(one row per control step, after the step: t_s = (k + 1) dt) with the controller's
plans and step times beside it.

Two inputs stand for the driver, not for the behaviour:

* ``set_speed_fn(t_s)`` [m/s]: the cruise set-point as the driver changes it (the
  behaviour may still lower the speed target to follow);
* ``decisions`` (:class:`DecisionSchedule`): for controller unit tests on an *empty*
  road only, a given side and lateral reference over time instead of the behaviour
  (there is no obstacle to build: with traffic it refuses to run).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.ellipses import ellipse_semi_axes
from controllers.behaviour.protocol import Behaviour, CruiseBehaviour
from controllers.behaviour.types import (
    Decision,
    EgoFrenet,
    LaneContext,
    ObstaclePolicy,
    Reason,
    Side,
    Traffic,
)
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import (
    Command,
    Controller,
    Observation,
    ScenarioContext,
    StepDiagnostics,
)
from reports.record import ControllerArrays, Trace
from suite.run.dynamics import PlantDynamics
from suite.run.ego import EgoProjector
from suite.run.loop import Stages, run_loop
from suite.run.recorder import TraceRecorder
from suite.run.safety import SafetyMonitor
from suite.run.stop import StandardStop
from suite.world.scripted import ScriptedRoad, ScriptedVehicle, ScriptedWorld

FloatArray = npt.NDArray[np.float64]
RECORD_RADIUS_M = 200.0  # neighbours recorded within this of the ego's CG


@dataclass(frozen=True)
class PlanSample:
    """The controller's plan after one step: stage times tau [s] (N+1,) from the step's
    time and the planned Frenet states (N+1, 3) [s_m, y_m, ...]."""

    stage_times_s: FloatArray
    states: FloatArray


class ProbedController:
    """A controller stage that passes every call through to ``inner`` and keeps, per
    step, the wall time of ``inner.step`` [s] and the plan it exposes (``plan``, an
    object with ``stage_times_s`` and ``states``; None when it has none). A non-finite
    command raises ValueError (a plant-only run has no use for one)."""

    diagnostics_type: ClassVar[type[StepDiagnostics]] = StepDiagnostics

    def __init__(self, inner: Controller) -> None:
        self.inner = inner
        self.name = inner.name
        self.diagnostics_type = inner.diagnostics_type  # type: ignore[misc]
        self.obstacle_policy: ObstaclePolicy | None = inner.obstacle_policy
        self.step_times_s: list[float] = []
        self.plans: list[PlanSample | None] = []

    def reset(self, context: ScenarioContext) -> None:
        self.inner.reset(context)

    def step(self, observation: Observation) -> Command:
        t0 = time.perf_counter()
        cmd = self.inner.step(observation)
        self.step_times_s.append(time.perf_counter() - t0)
        if not (math.isfinite(cmd.steer_rad) and math.isfinite(cmd.torque_nm)):
            raise ValueError(f"non-finite command at t = {observation.t_s} s")
        plan = getattr(self.inner, "plan", None)
        self.plans.append(None if plan is None else PlanSample(
            np.array(plan.stage_times_s, dtype=np.float64),
            np.array(plan.states, dtype=np.float64)))
        return cmd

    def parameters(self) -> Mapping[str, Any]:
        return self.inner.parameters()


@dataclass(frozen=True)
class DecisionSchedule:
    """A given decision over time for an empty road: ``fn(t_s) -> (side,
    lateral_reference_m)`` [-, m], the speed target the set-point (see the module
    docstring). Raises ValueError when there is traffic."""

    fn: Callable[[float], tuple[Side, float]]

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        del lanes
        if traffic.count:
            raise ValueError("DecisionSchedule is for an empty road; with traffic the "
                             "behaviour decides")
        side, y_ref = self.fn(ego.t_s)
        return Decision(side=side, target_speed_mps=set_speed_mps,
                        lateral_reference_m=float(y_ref), reason="scheduled",
                        reason_code=Reason.NONE)


@dataclass(frozen=True)
class DriverSetSpeed:
    """A behaviour stage whose set-point the driver changes over time: ``inner`` decides
    with ``set_speed_fn(t_s)`` [m/s] instead of the run's constant set-point."""

    inner: Behaviour
    set_speed_fn: Callable[[float], float]

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        del set_speed_mps
        return self.inner.decide(ego, traffic, lanes, float(self.set_speed_fn(ego.t_s)))


@dataclass(frozen=True)
class PlantRun:
    """A plant-only run: the recorded ``trace`` and controller ``arrays``, why it stopped,
    the reference ``path``, the ``world`` (its vehicles' tracks), the controller's
    obstacle ``policy`` (None: it takes none), the ego ``vehicle``, the controller's
    ``plans`` and ``step_times_s`` [s] per row."""

    trace: Trace
    arrays: ControllerArrays
    stop_reason: str
    path: FrenetPath
    world: ScriptedWorld
    policy: ObstaclePolicy | None
    vehicle: VehicleParams
    plans: tuple[PlanSample | None, ...]
    step_times_s: FloatArray

    def diagnostic(self, name: str) -> FloatArray:
        """A diagnostic column by name (the common ones or the controller's extras)."""
        if name in self.trace.extra:
            return self.trace.extra[name]
        return np.asarray(getattr(self.trace.controller, name), dtype=np.float64)

    def ellipse_values(self, margins: bool = False) -> FloatArray:
        """(K, n vehicles) ellipse value c of the ego CG for every scripted vehicle,

            c = (s - s_j)² / A_j² + (y - y_j)² / B_j² - 1    (< 0: CG inside),

        A_j, B_j from :func:`~controllers.behaviour.ellipses.ellipse_semi_axes` with the
        policy's margins (``margins``) or none, no offset; inf where a vehicle is absent."""
        ego = self.trace.ego
        tracks = self.world.tracks(self.trace.t_s)
        policy = self.policy or ObstaclePolicy()
        if not margins:
            policy = ObstaclePolicy(margin_long_m=0.0, margin_lat_m=0.0, offset_m=0.0)
        else:
            policy = dataclasses.replace(policy, offset_m=0.0)
        axes = np.array([ellipse_semi_axes(v.length_m, v.width_m, self.vehicle.length_m,
                                           self.vehicle.width_m, policy)
                         for v in self.world.vehicles]).reshape(-1, 2)
        c = ((ego.s_m[:, None] - tracks.s_m) ** 2 / axes[:, 0] ** 2
             + (ego.lat_dev_m[:, None] - tracks.y_m) ** 2 / axes[:, 1] ** 2 - 1.0)
        return np.where(tracks.present, c, np.inf)

    def plan_tracking_error(self, tau_s: float = 0.5) -> FloatArray:
        """Lateral error y(t_k + tau) - y_plan,k(tau) [m] (K,), the paper's Fig. 12: where
        the car was tau after step k against step k's plan there (linear interpolation;
        NaN past the run's end, where the plan is shorter than tau or there is none)."""
        t, y = self.trace.t_s, self.trace.ego.lat_dev_m
        t_plan = t - (t[1] - t[0] if t.size > 1 else 0.0)  # the plan was made a step before
        out = np.full(t.shape[0], np.nan)
        for k, plan in enumerate(self.plans):
            if plan is None or plan.stage_times_s[-1] < tau_s or t_plan[k] + tau_s > t[-1]:
                continue
            y_plan = float(np.interp(tau_s, plan.stage_times_s, plan.states[:, 1]))
            out[k] = float(np.interp(t_plan[k] + tau_s, t, y)) - y_plan
        return out


def steering_chatter(steer_rad: FloatArray, dt_s: float,
                     mask: npt.NDArray[np.bool_] | None = None) -> float:
    """High-frequency steering measure [rad/s²]: RMS of the second difference of the
    steering angle delta over dt²,  sqrt(mean(((delta_{k+1} - 2 delta_k + delta_{k-1})
    / dt²)²)). For a smooth delta(t) it is the RMS of delta''; a command flipping from
    step to step (the paper's J1 chatter, Fig. 10) makes it large, the second difference
    of a period-2 oscillation of amplitude a being 4 a / dt². ``mask`` (same length)
    restricts it to a window (e.g. obstacle in view)."""
    d2 = np.diff(np.asarray(steer_rad, dtype=np.float64), 2) / dt_s**2
    if mask is not None:
        d2 = d2[np.asarray(mask)[1:-1]]
    return float(np.sqrt(np.mean(d2**2))) if d2.size else 0.0


@dataclass(frozen=True)
class PlantStart:
    """The ego at t = 0: CG at ``s_m`` along the path, ``lat_m`` [m, left +] off it,
    heading along the path, speed ``speed_mps`` [m/s]."""

    s_m: float = 0.0
    lat_m: float = 0.0
    speed_mps: float = 25.0

    def __post_init__(self) -> None:
        for name in ("s_m", "lat_m", "speed_mps"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v)):
                raise ValueError(f"PlantStart.{name} must be a finite number, got {v!r}")
        if self.speed_mps < 0.0:
            raise ValueError(f"PlantStart.speed_mps must be >= 0, got {self.speed_mps}")

    def state(self, path: FrenetPath) -> FloatArray:
        """(6,) plant state [X_m, Y_m, psi_rad, u_mps, v_mps, r_radps]."""
        x, y = path.to_global(self.s_m, self.lat_m)
        return np.array([float(x), float(y), float(path.gamma(self.s_m)), self.speed_mps,
                         0.0, 0.0])


def _behaviour(policy: ObstaclePolicy | None, path: FrenetPath, road: ScriptedRoad,
               vehicle: VehicleParams, allow_shoulder: bool,
               decisions: DecisionSchedule | None) -> Behaviour:
    if decisions is not None:
        return decisions
    if policy is None:
        return CruiseBehaviour()
    return LaneBehaviour(path, policy, EgoShape(vehicle.length_m, vehicle.width_m,
                                                allow_shoulder), road.lane_width_m)


def run_plant(controller: Controller, road: ScriptedRoad,  # noqa: PLR0913 - keyword options of the test plant, 23 callers
              vehicles: tuple[ScriptedVehicle, ...] = (), *, duration_s: float,
              step_s: float = 0.02, start: PlantStart | None = None,
              set_speed_mps: float = 25.0, set_speed_fn: Callable[[float], float] | None = None,
              decisions: DecisionSchedule | None = None, vehicle: VehicleParams | None = None,
              allow_shoulder: bool = False) -> PlantRun:
    """Reset ``controller`` and run it for ``duration_s`` [s] (round(duration / step)
    steps) on ``road`` among ``vehicles``; see the module docstring."""
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration_s must be a finite number > 0, got {duration_s!r}")
    vp = vehicle or VehicleParams()
    context = ScenarioContext(road.reference_xy_m, road.lane_width_m, set_speed_mps, step_s,
                              vp, np.zeros(6))
    path = context.reference_path()
    state0 = (start or PlantStart(speed_mps=25.0)).state(path)
    probe = ProbedController(controller)
    probe.reset(dataclasses.replace(context, initial_state=state0))
    world = ScriptedWorld(road, tuple(vehicles), step_s)
    policy = controller.obstacle_policy
    behaviour = _behaviour(policy, path, road, vp, allow_shoulder, decisions)
    if set_speed_fn is not None:
        behaviour = DriverSetSpeed(behaviour, set_speed_fn)
    n_steps = int(round(duration_s / step_s))
    recorder = TraceRecorder(n_steps, controller.diagnostics_type, path, RECORD_RADIUS_M)
    stages = Stages(dynamics=PlantDynamics(SingleTrackPlant(vp, state0), world,
                                           EgoProjector(path), step_s),
                    behaviour=behaviour, lanes=road, controller=probe,
                    monitor=SafetyMonitor(vp), recorder=recorder,
                    stop=StandardStop(path.length_m), set_speed_mps=set_speed_mps,
                    step_s=step_s)
    reason = run_loop(stages, n_steps)
    world.close()
    trace, _, arrays = recorder.finish(policy.detection_distance_m if policy else 0.0)
    return PlantRun(trace=trace, arrays=arrays, stop_reason=reason, path=path, world=world,
                    policy=policy, vehicle=vp, plans=tuple(probe.plans),
                    step_times_s=np.asarray(probe.step_times_s, dtype=np.float64))
