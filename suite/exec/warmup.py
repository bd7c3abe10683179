""":func:`warm_up`: load every compiled kernel a run uses, in the process scenario
processes are forked from (called by :func:`suite.exec.prepare.prepare_process`, step 4;
importing this module only imports).

Its imports are the heavy modules a run needs and would otherwise import lazily (Rerun,
``pyarrow.parquet``, the XML parser of the network reader, the bundled networks);
:func:`warm_up` then imports the eclipse-sumo package and loads every kernel from numba's
on-disk cache (or compiles it once) by running the lane behaviour and the two-loop
controller for a few steps on a tiny problem (and the reference's and the path's kernels
once), so that each forked scenario process inherits them instead of paying for them
again: a catalog pays compilation and imports once. Missing one costs every run its
import or cache load (``scipy.signal`` was 0.35 s of each 40 s run until it was
preloaded, and is no longer used at all; the path's ``_gamma_many`` 20 ms);
``tests/test_warmup_coverage.py`` checks that nothing is left (docs/performance.md).
"""

from __future__ import annotations

import xml.sax.expatreader  # noqa: F401 - the network reader's parser

import numpy as np
import pyarrow.parquet  # noqa: F401 - the run's files

import reports.metrics  # noqa: F401
import suite.rerun.log  # noqa: F401 - rerun
import sumo_nets  # the bundled networks, and where SUMO is
from controllers import registry
from controllers.baselines.recorded_driver import RecordedDriverModel
from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.types import EgoFrenet, LaneContext, LaneSlot, Traffic
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams
from controllers.protocol import (
    Observation,
    ObstaclePolicy,
    Obstacles,
    ScenarioContext,
    SumoDriverModel,
)
from reports.geometry import polyline_frenet
from suite.road.reference import offsets_to_polyline
from suite.run import recorder

__all__ = ["warm_up"]


def _warm_behaviour(steps: int) -> None:
    """The lane behaviour's kernels (traffic projection, lead search, obstacle choice):
    two lanes, a stalled car ahead in the ego's and a car in the other."""
    path = FrenetPath.cached(np.array([[0.0, 0.0], [400.0, 0.0]]))
    path.gamma(np.array([1.0, 2.0]))  # the recorder's projections (20 ms a run else)
    behaviour = LaneBehaviour(path, ObstaclePolicy(), EgoShape(4.8, 1.9), 3.5)
    lanes = LaneContext({0: LaneSlot(0, 3.5, True, False, offset_m=0.0),
                         1: LaneSlot(1, 3.5, True, False, offset_m=3.5)}, 0)
    traffic = Traffic(ids=("stalled", "left"), x_m=np.array([60.0, 20.0]),
                      y_m=np.array([0.0, 3.5]), heading_rad=np.zeros(2),
                      speed_mps=np.array([0.0, 22.0]), length_m=np.full(2, 4.8),
                      width_m=np.full(2, 1.9), lane_index=np.array([0, 1]),
                      road_id=("", ""), stalled=np.array([True, False]))
    for k in range(steps):
        behaviour.decide(EgoFrenet(0.5 * k, 0.0, 0.5 * k, 0.0, 20.0, 0.02 * k), traffic, lanes,
                         25.0)


def warm_up(steps: int = 3) -> None:
    """Load the kernels a run uses (module doc): ``steps`` steps of each controller."""
    sumo_nets.sumo_home()  # imports the eclipse-sumo package (every run's SUMO start did)
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    offsets_to_polyline(line, np.tile([0.0, 1.0], (3, 1)), line)  # the reference's kernel
    polyline_frenet(line, line[:, 0], line[:, 1], track=True)  # TTC along the road (metrics)
    _warm_behaviour(steps)
    recorder.load_kernels()  # the neighbour rows
    vehicle = VehicleParams()
    reference = np.array([[0.0, 0.0], [400.0, 0.0]])
    state = np.array([10.0, 0.0, 0.0, 20.0, 0.0, 0.0])
    obstacles = Obstacles(np.array([60.0]), np.array([-0.3]), np.zeros(1), np.zeros(1),
                          np.array([10.0]), np.array([2.6]))
    for name in ("two_loop", "lane_keep"):
        controller = registry.make(name, {})
        if isinstance(controller, SumoDriverModel | RecordedDriverModel):
            continue
        controller.reset(ScenarioContext(reference, 3.5, 20.0, 0.02, vehicle, state))
        plant = SingleTrackPlant(vehicle, state)
        for k in range(steps):
            cmd = controller.step(Observation(0.02 * k, plant.state.copy(), 20.0, obstacles, 1,
                                              3.5))
            plant.step(cmd.steer_rad, cmd.torque_nm, 0.02)

