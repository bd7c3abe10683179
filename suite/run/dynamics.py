"""The EgoDynamics role: who moves the ego, a plant from the controller's commands or
SUMO's own driver model.

``start`` puts the ego into the world and returns its first state and the first scene;
``advance`` applies one command (ignored when SUMO drives), steps the world and returns
the new state (None once the ego has left the simulation) and scene.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import Command
from suite.run.ego import EgoProjector, EgoState, FloatArray
from suite.world.protocol import EgoPose, Scene, World


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
        return EgoState(state, 0.0, 0.0, math.nan, math.nan, s, y, e, scene.ego), scene

    def advance(self, command: Command) -> tuple[EgoState | None, Scene]:
        steer, torque = self.plant.saturate(command.steer_rad, command.torque_nm)
        state = self.plant.step(steer, torque, self.step_s)
        scene = self.world.step(self._pose())
        s, y, e = self.projector.project(state)
        return EgoState(state, self.plant.long_acc_mps2, self.plant.lat_acc_mps2, steer, torque,
                        s, y, e, scene.ego), scene


class SumoDrivenDynamics:
    """SUMO's driver model moves the ego; its state is read back each step.

    SUMO gives the front bumper, heading and speed: the CG lies ``cg_to_front_bumper_m``
    behind the bumper, the yaw rate is the heading change over the step, the
    longitudinal acceleration the speed change and the lateral one speed times yaw rate
    (no body slip: v = 0).
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
        self._speed = math.hypot(float(self._state0[3]), float(self._state0[4]))

    def start(self) -> tuple[EgoState, Scene]:
        scene = self.world.start(None)
        s, y, e = self.projector.project(self._state0)
        return EgoState(self._state0.copy(), 0.0, 0.0, math.nan, math.nan, s, y, e,
                        scene.ego), scene

    def advance(self, command: Command) -> tuple[EgoState | None, Scene]:
        del command  # SUMO drives
        scene = self.world.step(None)
        es = scene.ego
        if es is None:
            return None, scene
        dt = self.step_s
        d = self.vehicle.cg_to_front_bumper_m
        dpsi = math.remainder(es.heading_rad - self._psi, 2 * math.pi)
        psi = es.heading_rad
        r = dpsi / dt
        state = np.array([es.front_x_m - d * math.cos(psi), es.front_y_m - d * math.sin(psi),
                          self._psi + dpsi, es.speed_mps, 0.0, r])
        long_acc = (es.speed_mps - self._speed) / dt
        self._psi, self._speed = float(state[2]), es.speed_mps
        s, y, e = self.projector.project(state)
        return EgoState(state, long_acc, es.speed_mps * r, math.nan, math.nan, s, y, e,
                        es), scene
