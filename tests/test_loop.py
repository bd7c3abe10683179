"""The composed loop driven by a scripted fake World: no SUMO, every stage real otherwise."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.protocol import CruiseBehaviour
from controllers.behaviour.types import SIDE_LEFT, LaneContext, LaneSlot, ObstaclePolicy, Traffic
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import Command, Observation, ScenarioContext, StepDiagnostics
from suite.run.dynamics import PlantDynamics
from suite.run.ego import EgoProjector
from suite.run.loop import DURATION, Stages, run_loop
from suite.run.recorder import TraceRecorder
from suite.run.safety import SafetyMonitor
from suite.run.stop import StandardStop
from suite.world.protocol import EgoPose, Scene, WorldEgo, WorldSummary

DT = 0.02
W = 3.5
ROAD = np.array([[0.0, 0.0], [3000.0, 0.0]])
# Coasting at constant speed: the probe commands no torque, so the plant has no drag
# or rolling resistance here (the loop, not the plant, is under test).
VEHICLE = VehicleParams(drag_coeff=0.0, rolling_resistance_coeff=0.0)


def stalled_at(x_m: float, y_m: float = 0.0) -> Callable[[float], Traffic]:
    def traffic(t_s: float) -> Traffic:
        del t_s
        return Traffic(("stalled0",), np.array([x_m]), np.array([y_m]), np.zeros(1),
                       np.zeros(1), np.array([4.8]), np.array([1.9]),
                       np.zeros(1, dtype=np.int64), ("e0",), np.ones(1, dtype=bool))
    return traffic


def no_traffic(t_s: float) -> Traffic:
    del t_s
    return Traffic.empty()


class ScriptedWorld:
    """A World whose other vehicles follow a script; it remembers every pushed pose."""

    def __init__(self, traffic: Callable[[float], Traffic], step_s: float = DT) -> None:
        self.traffic = traffic
        self.step_s = step_s
        self.t_s = 0.0
        self.poses: list[EgoPose] = []
        self.closed = False

    def _scene(self, pose: EgoPose | None) -> Scene:
        ego = None
        if pose is not None:
            self.poses.append(pose)
            ego = WorldEgo(pose.front_x_m, pose.front_y_m, pose.heading_rad, 0.0, 0.0, 1, "e0")
        return Scene(self.t_s, self.traffic(self.t_s), ego)

    def start(self, ego_pose: EgoPose | None) -> Scene:
        return self._scene(ego_pose)

    def step(self, ego_pose: EgoPose | None) -> Scene:
        self.t_s += self.step_s
        return self._scene(ego_pose)

    def close(self) -> WorldSummary:
        self.closed = True
        return WorldSummary()


@dataclass(frozen=True, slots=True)
class ProbeDiagnostics(StepDiagnostics):
    """A controller-specific diagnostic that must reach the trace."""

    seen_obstacles: float = math.nan
    seen_pass_side: float = math.nan


class ProbeController:
    """Holds the speed (zero torque on the drag-free plant), steers straight, and reports
    what it was told in its diagnostics."""

    name = "probe"
    diagnostics_type: ClassVar[type[StepDiagnostics]] = ProbeDiagnostics

    def __init__(self, policy: ObstaclePolicy | None = None) -> None:
        self.obstacle_policy = policy
        self.observations: list[Observation] = []

    def reset(self, context: ScenarioContext) -> None:
        del context

    def step(self, observation: Observation) -> Command:
        self.observations.append(observation)
        return Command(0.0, 0.0, ProbeDiagnostics(
            outer_s=1e-4, seen_obstacles=float(observation.obstacles.count),
            seen_pass_side=float(observation.pass_side)))

    def parameters(self) -> dict[str, object]:
        return {}


def stages(world: ScriptedWorld, controller: ProbeController, *, speed_mps: float = 20.0,
           lanes: LaneContext | None = None, n_steps: int = 100) -> tuple[Stages, TraceRecorder]:
    path = FrenetPath.cached(ROAD)
    state0 = np.array([100.0, 0.0, 0.0, speed_mps, 0.0, 0.0])
    controller.reset(ScenarioContext(ROAD, W, speed_mps, DT, VEHICLE, state0))
    plant = SingleTrackPlant(VEHICLE, state0)
    policy = controller.obstacle_policy
    behaviour = CruiseBehaviour() if policy is None else LaneBehaviour(
        path, policy, EgoShape(VEHICLE.length_m, VEHICLE.width_m), W)
    recorder = TraceRecorder(n_steps, controller.diagnostics_type, path, 150.0)
    ctx = lanes or LaneContext({0: LaneSlot(0, W, True, False)}, 0)

    class Lanes:
        def at(self, s_m: float) -> LaneContext:
            del s_m
            return ctx

    return Stages(dynamics=PlantDynamics(plant, world, EgoProjector(path), DT),
                  behaviour=behaviour, lanes=Lanes(), controller=controller,
                  monitor=SafetyMonitor(VEHICLE), recorder=recorder,
                  stop=StandardStop(path.length_m), set_speed_mps=speed_mps,
                  step_s=DT), recorder


def test_twenty_metres_per_second_for_two_seconds_is_forty_metres() -> None:
    world = ScriptedWorld(no_traffic)
    st, rec = stages(world, ProbeController(), n_steps=100)
    assert run_loop(st, 100) == DURATION
    trace, _, _ = rec.finish(0.0)
    assert len(trace) == 100
    assert trace.t_s[-1] == pytest.approx(2.0)
    assert trace.ego.s_m[-1] - 100.0 == pytest.approx(40.0, abs=1e-6)
    assert np.allclose(trace.ego.speed_mps, 20.0)
    # The pose pushed into the world is the plant's front bumper, every step.
    assert len(world.poses) == 101
    assert world.poses[-1].front_x_m == pytest.approx(140.0 + VEHICLE.cg_to_front_bumper_m)


def test_a_scripted_stalled_car_is_hit_and_the_run_stops_half_a_second_later() -> None:
    world = ScriptedWorld(stalled_at(130.0))
    st, rec = stages(world, ProbeController(), n_steps=500)
    reason = run_loop(st, 500)
    trace, neighbours, _ = rec.finish(0.0)
    hit = np.flatnonzero(trace.safety.geom_collision)
    assert reason.startswith("collision") and hit.size
    assert trace.t_s[-1] - trace.t_s[hit[0]] == pytest.approx(0.5, abs=DT / 2)
    # Bumper gap before contact: 130 - 2.4 (car) - 100 - 2.2 (ego CG to bumper) at t = 0.
    first_gap = 130.0 - 2.4 - (100.0 + 20.0 * DT + VEHICLE.cg_to_front_bumper_m)
    assert trace.safety.min_gap_m[0] == pytest.approx(first_gap, abs=0.05)
    assert set(neighbours.id) == {"stalled0"}


def test_the_decision_reaches_the_controller_and_the_trace() -> None:
    lanes = LaneContext({0: LaneSlot(0, W, True, False), 1: LaneSlot(1, W, True, False)}, 0)
    controller = ProbeController(ObstaclePolicy())
    world = ScriptedWorld(stalled_at(170.0))
    st, rec = stages(world, controller, lanes=lanes, n_steps=20)
    run_loop(st, 20)
    trace, _, arrays = rec.finish(100.0)
    first = controller.observations[0]
    assert first.pass_side == SIDE_LEFT and first.lateral_reference_m == pytest.approx(W)
    assert first.obstacles.count == 1
    assert np.all(trace.decision.side == SIDE_LEFT)
    codes = list(trace.decision.reason_code)
    assert codes[0] == "pass" and set(codes[1:]) <= {"pass", "passing"}
    assert trace.decision.side_reason[0].startswith("pass stalled0")  # the text beside it
    assert np.all(trace.decision.lat_ref_m == pytest.approx(W))
    # the obstacles name their vehicle, in the observation and beside each ellipse
    assert first.obstacles.vehicle_ids == ("stalled0",) and first.side == SIDE_LEFT
    assert [arrays.ellipse_id(k, 0) for k in range(20)] == ["stalled0"] * 20
    # the ego's projection is the loop's (the trace's) one, handed to the controller
    for k, ob in enumerate(controller.observations[1:]):
        assert ob.ego is not None
        assert (ob.ego.s_m, ob.ego.lat_m) == (trace.ego.s_m[k], trace.ego.lat_dev_m[k])
    # The controller's own diagnostics are trace columns with the values it returned.
    assert np.all(trace.extra["seen_obstacles"] == 1.0)
    assert np.all(trace.extra["seen_pass_side"] == 1.0)
    assert np.all(trace.controller.outer_s == 1e-4)
    assert arrays.ellipses.shape == (20, 1, 6)


def test_diagnostics_of_another_type_than_declared_fail_loudly() -> None:
    class Liar(ProbeController):
        def step(self, observation: Observation) -> Command:
            return Command(0.0, 0.0, StepDiagnostics())

    st, _ = stages(ScriptedWorld(no_traffic), Liar(), n_steps=5)
    with pytest.raises(TypeError, match="declared diagnostics ProbeDiagnostics"):
        run_loop(st, 5)
