"""Imported by the forkserver before it forks scenario processes (see ``executors``).

Importing this module loads every compiled kernel from numba's on-disk cache (or
compiles it once) by running the two-loop controller for a few steps on a tiny
problem, and imports the heavy modules a run needs (Rerun, scipy via the
metrics), so that each forked scenario process inherits them instead of paying
for them again: a catalog pays compilation and imports once.
"""

from __future__ import annotations

import numpy as np

import reports.metrics  # noqa: F401 - scipy.signal and friends
import suite.rerun.log  # noqa: F401 - rerun
from controllers import registry
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import Observation, Obstacles, ScenarioContext, SumoDriverModel


def warm_up(steps: int = 3) -> None:
    vehicle = VehicleParams()
    reference = np.array([[0.0, 0.0], [400.0, 0.0]])
    state = np.array([10.0, 0.0, 0.0, 20.0, 0.0, 0.0])
    obstacles = Obstacles(np.array([60.0]), np.array([-0.3]), np.zeros(1), np.zeros(1),
                          np.array([10.0]), np.array([2.6]))
    for name in ("two_loop", "lane_keep"):
        controller = registry.make(name, {})
        if isinstance(controller, SumoDriverModel):
            continue
        controller.reset(ScenarioContext(reference, 3.5, 20.0, 0.02, vehicle, state))
        plant = SingleTrackPlant(vehicle, state)
        for k in range(steps):
            cmd = controller.step(Observation(0.02 * k, plant.state.copy(), 20.0, obstacles, 1,
                                              3.5))
            plant.step(cmd.steer_rad, cmd.torque_nm, 0.02)


try:
    warm_up()
except Exception:  # noqa: BLE001 - a failed warm-up must not take the forkserver down;
    pass  # the scenario itself will then raise and be reported with its traceback.
