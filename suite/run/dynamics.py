"""The EgoDynamics role: who moves the ego, a plant from the controller's commands,
SUMO's own driver model, or the ego's own recording (:class:`suite.run.recorded.
RecordedDynamics`, the controller ``recorded``).

``start`` puts the ego into the world and returns its first state and the first scene;
``advance`` applies one command (ignored when SUMO drives), steps the world and returns
the new state (None once the ego has left the simulation) and scene.
"""

from __future__ import annotations

import math
from typing import ClassVar, Protocol

import numpy as np

from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import (
    Command,
    Observation,
    ObstaclePolicy,
    ScenarioContext,
    StepDiagnostics,
)
from suite.run.ego import EgoProjector, EgoState, FloatArray
from suite.world.protocol import EgoPose, Scene, World, WorldEgo


class EgoDynamics(Protocol):
    externally_driven: bool

    def start(self) -> tuple[EgoState, Scene]: ...

    def advance(self, command: Command) -> tuple[EgoState | None, Scene]: ...


class PlantDynamics:
    """The single-track plant is the ego's truth; its pose is pushed into the world."""

    externally_driven = True

    def __init__(self, plant: SingleTrackPlant, world: World, projector: EgoProjector,
                 step_s: float) -> None:
        self.plant = plant
        self.world = world
        self.projector = projector
        self.step_s = step_s

    def _pose(self) -> EgoPose:
        fx, fy = self.plant.front_bumper_xy()
        return EgoPose(fx, fy, float(self.plant.state[2]))

    def start(self) -> tuple[EgoState, Scene]:
        scene = self.world.start(self._pose())
        state = self.plant.state.copy()
        s, y, e = self.projector.project(state)
        return EgoState(state, 0.0, 0.0, math.nan, math.nan, s, y, e, scene.ego,
                        self.projector.at(s, y, e)), scene

    def advance(self, command: Command) -> tuple[EgoState | None, Scene]:
        steer, torque = self.plant.saturate(command.steer_rad, command.torque_nm)
        state = self.plant.step(steer, torque, self.step_s)
        scene = self.world.step(self._pose())
        s, y, e = self.projector.project(state)
        return EgoState(state, self.plant.long_acc_mps2, self.plant.lat_acc_mps2, steer, torque,
                        s, y, e, scene.ego, self.projector.at(s, y, e)), scene


class SumoDrivenDynamics:
    """SUMO's driver model moves the ego; its state is read back each step.

    SUMO moves vehicles along lane polylines whose heading steps at every vertex, so its
    heading is not the motion of a car: comfort measured on it would measure the
    polyline (tens of m/s² at OSM kinks). The ego's yaw is therefore taken as the smooth
    reference path's tangent at its position plus SUMO's yaw *relative to its lane*
    (zero while it follows a lane, the lane-change angle otherwise):

        psi = gamma(s) + wrap(psi_sumo - heading of the lane segment it is on)

    The yaw rate is psi's change over the step, the lateral acceleration speed times
    yaw rate, the longitudinal one SUMO's own acceleration; the CG lies
    ``cg_to_front_bumper_m`` behind SUMO's front bumper. This is the motion the
    plant-driven ego is measured on too: a car following the same smooth road. The first
    step starts from SUMO's own pose (no derivative against the path's initial guess).
    """

    externally_driven = False

    def __init__(self, world: World, projector: EgoProjector, vehicle: VehicleParams,
                 step_s: float, initial_state: FloatArray) -> None:
        self.world = world
        self.projector = projector
        self.vehicle = vehicle
        self.step_s = step_s
        self._state0 = np.asarray(initial_state, dtype=np.float64).copy()
        self._psi = float(self._state0[2])

    def _smooth_state(self, es: WorldEgo) -> tuple[FloatArray, float, float, float]:
        """(state with the smooth yaw, s_m, lat_m, heading error) of SUMO's ego."""
        d = self.vehicle.cg_to_front_bumper_m
        cg = np.array([es.front_x_m - d * math.cos(es.heading_rad),
                       es.front_y_m - d * math.sin(es.heading_rad)])
        relative = (math.remainder(es.heading_rad - es.lane_heading_rad, 2 * math.pi)
                    if math.isfinite(es.lane_heading_rad) else 0.0)
        s, y, _ = self.projector.project(np.array([cg[0], cg[1], es.heading_rad]))
        gamma = float(self.projector.path.gamma(s))
        psi = self._psi + math.remainder(gamma + relative - self._psi, 2 * math.pi)
        state = np.array([cg[0], cg[1], psi, es.speed_mps, 0.0, 0.0])
        return state, s, y, relative

    def start(self) -> tuple[EgoState, Scene]:
        scene = self.world.start(None)
        if scene.ego is None:
            raise RuntimeError("SUMO lost the ego at its insertion")
        state, s, y, e = self._smooth_state(scene.ego)
        self._psi = float(state[2])
        return EgoState(state, 0.0, 0.0, math.nan, math.nan, s, y, e, scene.ego,
                        self.projector.at(s, y, e)), scene

    def advance(self, command: Command) -> tuple[EgoState | None, Scene]:
        del command  # SUMO drives
        scene = self.world.step(None)
        es = scene.ego
        if es is None:
            return None, scene
        state, s, y, e = self._smooth_state(es)
        r = (float(state[2]) - self._psi) / self.step_s
        state[5] = r
        self._psi = float(state[2])
        return EgoState(state, es.accel_mps2, es.speed_mps * r, math.nan, math.nan, s, y, e,
                        es, self.projector.at(s, y, e)), scene


class DrivenEgoStage:
    """The loop's controller stage when the ego's dynamics drive it themselves (SUMO's
    driver model, a recorded track): it commands nothing (NaN steer and torque), takes no
    obstacles, and reports ``parameters`` (the driver's, and what it drives)."""

    diagnostics_type: ClassVar[type[StepDiagnostics]] = StepDiagnostics
    obstacle_policy: ObstaclePolicy | None = None

    def __init__(self, name: str, parameters: dict[str, object]) -> None:
        self.name = name
        self._parameters = dict(parameters)

    def reset(self, context: ScenarioContext) -> None:
        del context

    def step(self, observation: Observation) -> Command:
        del observation
        return Command(steer_rad=math.nan, torque_nm=math.nan)

    def parameters(self) -> dict[str, object]:
        return dict(self._parameters)
