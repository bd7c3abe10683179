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
from controllers.behaviour.types import (
    SIDE_LEFT,
    Decision,
    EgoFrenet,
    LaneContext,
    LaneSlot,
    ObstaclePolicy,
    Obstacles,
    Traffic,
)
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


def moving_at(x0_m: float, speed_mps: float) -> Callable[[float], Traffic]:
    """One car on the lane's centre line at constant speed: x = x0 + v t."""
    def traffic(t_s: float) -> Traffic:
        return Traffic(("car0",), np.array([x0_m + speed_mps * t_s]), np.zeros(1),
                       np.zeros(1), np.array([speed_mps]), np.array([4.8]), np.array([1.9]),
                       np.zeros(1, dtype=np.int64), ("e0",), np.zeros(1, dtype=bool))
    return traffic


class EveryMthFresh(ScriptedWorld):
    """A multi-rate world: its own state is new every ``m``-th step only (as SUMO at 10 Hz
    under a 50 Hz loop); the other scenes are its exact traffic marked not fresh."""

    def __init__(self, traffic: Callable[[float], Traffic], m: int) -> None:
        super().__init__(traffic)
        self.m = m
        self.k = 0

    def step(self, ego_pose: EgoPose | None) -> Scene:
        self.k += 1
        scene = super().step(ego_pose)
        return Scene(scene.t_s, scene.traffic, scene.ego, fresh=self.k % self.m == 0)


class CountingBehaviour:
    """A behaviour that counts its decisions and records the time of each."""

    def __init__(self, inner: LaneBehaviour) -> None:
        self.inner = inner
        self.times_s: list[float] = []

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        self.times_s.append(ego.t_s)
        return self.inner.decide(ego, traffic, lanes, set_speed_mps)


def _observed_obstacles(m: int, n_steps: int) -> tuple[list[Observation], list[float]]:
    controller = ProbeController(ObstaclePolicy())
    world = EveryMthFresh(moving_at(160.0, 15.0), m)
    st, _ = stages(world, controller, n_steps=n_steps)
    counting = CountingBehaviour(st.behaviour)  # type: ignore[arg-type]
    st.behaviour = counting
    assert run_loop(st, n_steps) == DURATION
    return controller.observations, counting.times_s


def test_the_behaviour_decides_on_fresh_scenes_and_its_obstacles_move_between() -> None:
    n = 50
    every, decided_every = _observed_obstacles(1, n)
    fifth, decided_fifth = _observed_obstacles(5, n)
    # the start's scene and every 5th step's: steps 0, 5, 10, ... decide
    assert decided_every == pytest.approx([k * DT for k in range(n)])
    assert decided_fifth == pytest.approx([k * DT for k in range(0, n, 5)])
    # Between decisions the controller sees the last decision's ellipses moved by their
    # own constant velocity; for a car at constant speed on a straight road that is
    # where deciding afresh puts them (the deciding-every-step run, an independent path).
    for a, b in zip(every, fifth, strict=True):
        assert a.obstacles.count == b.obstacles.count == 1
        assert b.obstacles.s_m == pytest.approx(a.obstacles.s_m, abs=1e-9)
        assert b.obstacles.y_m == pytest.approx(a.obstacles.y_m, abs=1e-9)
        assert b.obstacles.vehicle_ids == ("car0",)
    # and it does move: 15 m/s x 0.08 s from a decision to the step before the next
    assert fifth[4].obstacles.s_m[0] - fifth[0].obstacles.s_m[0] == pytest.approx(15.0 * 0.08)


def test_between_decisions_an_ellipse_the_ego_moved_into_is_narrowed() -> None:
    """A car alongside: its ellipse (A 10 m, B 2.2 m) 2.4 m left of the ego's CG leaves it
    outside when decided; 0.08 s later the ego has moved 0.4 m toward it, inside, and the
    ellipse handed to the controller is narrowed across (B) to put the ego at 1.05."""
    obstacles = Obstacles(s_m=np.array([100.0]), y_m=np.array([2.4]), speed_s_mps=np.zeros(1),
                          speed_y_mps=np.zeros(1), semi_a_m=np.array([10.0]),
                          semi_b_m=np.array([2.2]), vehicle_ids=("car",),
                          half_length_m=np.array([4.7]))
    decision = Decision(obstacles=obstacles)
    kept = decision.ahead(0.08, 100.0, 0.0).obstacles  # outside: untouched
    assert (kept.semi_a_m[0], kept.semi_b_m[0]) == (10.0, 2.2)
    moved = decision.ahead(0.08, 100.0, 0.4).obstacles
    assert moved.semi_a_m[0] == 10.0
    assert moved.semi_b_m[0] == pytest.approx(2.0 / math.sqrt(1.05))
    assert (2.0 / moved.semi_b_m[0]) ** 2 == pytest.approx(1.05)
