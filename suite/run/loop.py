"""The simulation loop: scene -> decision -> command -> dynamics -> record -> stop.

Each stage is a small protocol (World inside the dynamics, Behaviour, Controller,
EgoDynamics, Recorder, StopRule); :class:`Stages` holds one run's instances, built by
:mod:`suite.run.runner` (SUMO) or by a test (a fake World).

Two rates. The controller, the plant, the safety monitor and the recorder run every
control step (``step_s``). The behaviour decides at the scene's rate: on a *fresh* scene
(:attr:`suite.world.protocol.Scene.fresh`: a SUMO step, 10 Hz by default, or every step
of a world without multi-rate). Between two fresh scenes the world only extrapolates its
last state, so deciding again would decide on the same information; instead the
controller gets the last decision tau = t - t_decision later with its obstacles moved by
their own constant-velocity prediction (:meth:`controllers.behaviour.types.Decision.
ahead`), the prediction the controller makes over its horizon anyway, and narrowed
where the ego has moved into one (as the behaviour narrows them when it decides). A run
with ``sumo_step_s = step_s`` has only fresh scenes and decides every step.
"""

from __future__ import annotations

import gc
import time
from dataclasses import dataclass
from typing import Protocol

from controllers.behaviour.protocol import Behaviour
from controllers.behaviour.types import Decision, LaneContext
from controllers.protocol import Controller, Observation
from reports.collector import collector_paused
from suite.run.dynamics import EgoDynamics
from suite.run.ego import EgoState
from suite.run.recorder import Recorder, StepTiming
from suite.run.safety import SafetyMonitor
from suite.run.stop import StopRule

DURATION = "duration"
EGO_LEFT = "the ego left the simulation"


class LaneSource(Protocol):
    def at(self, s_m: float) -> LaneContext: ...


@dataclass
class Stages:
    """One run's stages; ``set_speed_mps`` the cruise set-point, ``step_s`` the period."""

    dynamics: EgoDynamics
    behaviour: Behaviour
    lanes: LaneSource
    controller: Controller
    monitor: SafetyMonitor
    recorder: Recorder
    stop: StopRule
    set_speed_mps: float
    step_s: float


def observe(t_s: float, ego: EgoState, decision: Decision) -> Observation:
    """The controller's view of this step: the decision, and the ego's state with its
    projection on the reference path (the one the behaviour and the trace use)."""
    return Observation(t_s=t_s, state=ego.state.copy(), target_speed_mps=decision.target_speed_mps,
                       obstacles=decision.obstacles, pass_side=decision.pass_side,
                       lateral_reference_m=decision.lateral_reference_m,
                       evasive=decision.evasive, side=decision.side, ego=ego.on_path)


YOUNG_COLLECT_STEPS = 500  # steps between collections of the youngest generation


def run_loop(stages: Stages, n_steps: int) -> str:
    """Run up to ``n_steps`` steps; returns why the run stopped.

    Python's cyclic garbage collector is paused while the steps run (and resumed as it
    was, whatever happens): the loop's per-step objects are freed by reference counting,
    and a collection landing on a step was a pause of its own in the step's time (up to
    ~0.6 ms). So that a long run cannot pile up cycles, the youngest generation is
    collected every :data:`YOUNG_COLLECT_STEPS` steps (between two steps, outside their
    timed part); the rest after the run."""
    with collector_paused():
        return _steps(stages, n_steps)


def _steps(stages: Stages, n_steps: int) -> str:
    clock = time.perf_counter
    ego, scene = stages.dynamics.start()
    decided: Decision | None = None  # the behaviour's last decision, taken at decided_t_s
    decided_t_s = 0.0
    for step in range(n_steps):
        if step % YOUNG_COLLECT_STEPS == YOUNG_COLLECT_STEPS - 1:
            gc.collect(0)
        t0 = clock()
        t_s = step * stages.step_s
        if scene.fresh or decided is None:
            decided = stages.behaviour.decide(ego.frenet(t_s), scene.traffic,
                                              stages.lanes.at(ego.s_m), stages.set_speed_mps)
            decided_t_s = t_s
            decision = decided
        else:
            decision = decided.ahead(t_s - decided_t_s, ego.s_m, ego.lat_m)
        t1 = clock()
        command = stages.controller.step(observe(t_s, ego, decision))
        t2 = clock()
        after, scene = stages.dynamics.advance(command)
        t3 = clock()
        if after is None:
            return EGO_LEFT
        ego = after
        safety = stages.monitor.check(ego, scene)
        stages.recorder.record(step, scene.t_s, ego, decision, command, safety,
                               StepTiming(t1 - t0, t2 - t0, t3 - t2), scene.traffic)
        reason = stages.stop.check(scene.t_s, ego, safety)
        if reason is not None:
            return reason
    return DURATION
