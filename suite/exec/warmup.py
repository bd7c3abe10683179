"""Imported by the forkserver before it forks scenario processes (see ``executors``).

Importing this module loads every compiled kernel from numba's on-disk cache (or
compiles it once) by running the lane behaviour and the two-loop controller for a few
steps on a tiny problem (and the reference's and the path's kernels once), and imports
the heavy modules a run needs (Rerun, ``pyarrow.parquet``, the XML parser of the network
reader, the bundled networks, the eclipse-sumo package), so that each forked scenario
process inherits them instead of paying for them again: a catalog pays compilation and
imports once. Missing one costs every run its import or cache load (``scipy.signal``
was 0.35 s of each 40 s run until it was preloaded, and is no longer used at all; the
path's ``_gamma_many`` 20 ms); ``tests/test_warmup_coverage.py`` checks that nothing is
left (docs/performance.md).

In the forkserver itself (not when imported anywhere else) it freezes the garbage
collector's view of what the preload made (``gc.freeze``: a run's collections skip it),
and makes the server's exit quick: the forkserver ends by ``SystemExit`` once its parent
is gone, and the interpreter's teardown of everything preloaded then took 0.55 s, during
which it still held the command's stdout and stderr (a pipe reading ``hwyeval run`` saw
its end that much later). An atexit handler ends it with
:func:`suite.exec.quick_exit.exit_without_teardown`.
"""

from __future__ import annotations

import atexit
import gc
import os
import sys
import xml.sax.expatreader  # noqa: F401 - the network reader's parser
from types import FrameType

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
from suite.exec.quick_exit import exit_without_teardown
from suite.road.reference import offsets_to_polyline
from suite.run import recorder


def in_forkserver() -> bool:
    """Whether this import runs in multiprocessing's forkserver preload (its ``main`` is
    on the call stack)."""
    frame: FrameType | None = sys._getframe()
    target = os.path.join("multiprocessing", "forkserver.py")
    while frame is not None:
        if frame.f_code.co_name == "main" and frame.f_code.co_filename.endswith(target):
            return True
        frame = frame.f_back
    return False


def _exit_without_teardown() -> None:
    atexit.unregister(_exit_without_teardown)  # the other handlers run, not this again
    exit_without_teardown(0)


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


try:
    warm_up()
except Exception:  # noqa: BLE001 - a failed warm-up must not take the forkserver down;
    pass  # the scenario itself will then raise and be reported with its traceback.

if in_forkserver():
    atexit.register(_exit_without_teardown)
    # Every object the preload made (~200 000: modules, numba's and numpy's state) goes
    # to the collector's permanent generation, which scenario processes inherit: their
    # cyclic collections no longer walk it. One gen-2 collection over it was ~190 ms of
    # every 40 s run (docs/performance.md); and walking it wrote to every object's
    # header, copying the forkserver's pages into each process.
    gc.freeze()
gc.enable()  # paused by suite.exec.gc_pause, the preload's first module
