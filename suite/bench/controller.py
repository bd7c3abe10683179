"""``hwyeval bench``'s controller part: the two-loop controller timed on the plant-only loop.

``run_benchmark`` drives :class:`TwoLoopController` on a straight road at 25 m/s
past three stalled cars (one in the ego lane, two in the right lane, so that all
obstacle slots are active while passing), with the runner's lateral reference
(+3.5 m from detection of the car in the ego lane until 15 m past it), twice:

1. with every C/GMRES sub-update called and timed separately -> per-update times
   (one update = k_max + 3 residual evaluations + GMRES + Euler + guard, compiled);
2. normally (all sub-updates in one compiled call) -> the whole control step as
   the runner sees it (``controller.step`` wall time: projection, lateral shaper,
   launch check, outer loop, inner loop with preview, command and logging arrays).

The first ``warmup_steps`` steps (numba cache loading, first calls) are dropped.
Percentiles p50/p95/p99/max in microseconds and the ratios p99/p50 are printed and
returned. One run only; the numbers depend on the machine's load.
"""

from __future__ import annotations

import platform
import time
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np

from controllers.behaviour.ellipses import FrenetVehicle
from controllers.behaviour.types import ObstaclePolicy
from controllers.params import to_dict
from controllers.path.frenet import FrenetPath
from controllers.protocol import Command, Observation, ScenarioContext, StepDiagnostics
from controllers.sim.closed_loop import pass_reference, simulate
from controllers.two_loop.controller import TwoLoopController
from controllers.two_loop.diagnostics import TwoLoopDiagnostics
from controllers.two_loop.outer.cgmres import CgmresOuter
from controllers.two_loop.outer.protocol import OuterPlan, OuterPlanner
from controllers.two_loop.params import two_loop_params


class _TimedController:
    """Wraps a controller and records the wall time of every ``step``."""

    diagnostics_type: ClassVar[type[StepDiagnostics]] = TwoLoopDiagnostics

    def __init__(self, inner: TwoLoopController) -> None:
        self.inner = inner
        self.name = inner.name
        self.obstacle_policy: ObstaclePolicy | None = inner.obstacle_policy
        self.step_times_s: list[float] = []

    @property
    def plan(self) -> OuterPlan | None:
        return self.inner.plan

    def reset(self, context: ScenarioContext) -> None:
        self.inner.reset(context)

    def step(self, observation: Observation) -> Command:
        t0 = time.perf_counter()
        cmd = self.inner.step(observation)
        self.step_times_s.append(time.perf_counter() - t0)
        return cmd

    def parameters(self) -> Mapping[str, Any]:
        return self.inner.parameters()


def _stats(times_s: np.ndarray) -> dict[str, float]:
    us = np.asarray(times_s) * 1e6
    p50, p95, p99 = (float(np.percentile(us, q)) for q in (50, 95, 99))
    return {"n": float(us.size), "p50_us": p50, "p95_us": p95, "p99_us": p99,
            "max_us": float(us.max()), "mean_us": float(us.mean()),
            "std_us": float(us.std()), "p99_over_p50": p99 / p50}


def run_benchmark(options: Mapping[str, Any] | None = None, duration_s: float = 12.0,
                  warmup_steps: int = 25, print_fn: Callable[[str], None] | None = print,
                  ) -> dict[str, Any]:
    """Run the benchmark; ``options`` are two-loop catalog options (defaults otherwise)."""
    params = two_loop_params(dict(options or {}))
    road = np.array([[0.0, 0.0], [2000.0, 0.0]])
    cars = [FrenetVehicle(150.0, 0.0), FrenetVehicle(170.0, -3.5), FrenetVehicle(120.0, -3.5)]
    results: dict[str, Any] = {"params": to_dict(params), "machine": platform.processor()
                               or platform.machine(), "python": platform.python_version()}
    # 1) per-update timing: every C/GMRES sub-update called and timed on its own
    timed_outers: list[CgmresOuter] = []

    def timed_planner(path: FrenetPath, n_slots: int) -> OuterPlanner:
        outer = CgmresOuter(path, params.outer, n_slots)
        outer.time_each_subupdate = True
        timed_outers.append(outer)
        return outer

    ctl = TwoLoopController(params, timed_planner)
    detect_m = params.policy.detection_distance_m

    # The runner's lateral reference: the left lane while the car in the ego lane is passed.
    def lateral() -> Any:
        return pass_reference(150.0, 1, 3.5, detect_m, 15.0)

    tr1 = simulate(ctl, road, cars, duration_s=duration_s, pass_side=1, lateral_fn=lateral())
    sub = np.asarray(timed_outers[-1].subupdate_times_s, dtype=np.float64)
    sub = sub[warmup_steps * params.outer.sub_updates:]
    # 2) whole control step
    timed = _TimedController(TwoLoopController(params))
    tr2 = simulate(timed, road, cars, duration_s=duration_s, pass_side=1, lateral_fn=lateral())
    steps = np.asarray(timed.step_times_s[warmup_steps:])
    results["outer_update"] = _stats(sub) if sub.size else {}
    results["control_step"] = _stats(steps)
    results["outer_loop_per_step"] = _stats(tr2["outer_s"][warmup_steps:])
    results["inner_loop_per_step"] = _stats(tr2["inner_s"][warmup_steps:])
    results["residual_max"] = float(np.max(tr2["residual"]))
    results["residual_median"] = float(np.median(tr2["residual"]))
    results["fallbacks"] = int(np.sum(tr2["fallback"]))
    results["guard_fired"] = int(np.sum(tr2["guard_fired"]))
    results["min_ellipse_c"] = float(np.min(tr1["ellipse_c"]))
    if print_fn is not None:
        o = params.outer
        print_fn(f"two_loop benchmark: cost={o.cost} N={o.n_stages} "
                 f"K={params.policy.max_obstacles} k_max={o.k_max} "
                 f"sub_updates={o.sub_updates}, {steps.size} steps")
        for key in ("outer_update", "control_step", "outer_loop_per_step",
                    "inner_loop_per_step"):
            s = results[key]
            if s:
                print_fn(f"  {key:20s} p50 {s['p50_us']:8.1f} us  p95 {s['p95_us']:8.1f} us  "
                         f"p99 {s['p99_us']:8.1f} us  max {s['max_us']:8.1f} us  "
                         f"p99/p50 {s['p99_over_p50']:.2f}")
        print_fn(f"  residual E: median {results['residual_median']:.3g}, "
                 f"max {results['residual_max']:.3g}; fallbacks {results['fallbacks']}, "
                 f"guard firings {results['guard_fired']}")
    return results

