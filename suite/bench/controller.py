"""``hwyeval bench``'s controller part: the two-loop controller timed on the plant-only loop.

``run_benchmark`` drives :class:`TwoLoopController` on production's loop without SUMO
(:func:`suite.run.scripted.run_plant`: the lane behaviour, the plant, the recorder) on a
straight three-lane road at 25 m/s, the ego in the middle lane, past three stalled
cars (one in the ego lane 150 m ahead, two in the right lane at 120 m and 170 m): the
behaviour passes on the left (lateral reference +3.5 m) and back, with the cars it
selects as obstacles. Twice:

1. with every C/GMRES sub-update called and timed separately -> per-update times
   (one update = k_max + 3 residual evaluations + GMRES + Euler + guard, compiled);
2. normally (all sub-updates in one compiled call) -> the whole control step as
   the loop sees it (``controller.step`` wall time: projection, lateral shaper,
   launch check, outer loop, inner loop with preview, command and logging arrays).

The first ``warmup_steps`` steps (numba cache loading, first calls) are dropped.
Percentiles p50/p95/p99/max in microseconds and the ratios p99/p50 are printed and
returned. One run only; the numbers depend on the machine's load.
"""

from __future__ import annotations

import platform
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from controllers.params import to_dict
from controllers.path.frenet import FrenetPath
from controllers.two_loop.controller import TwoLoopController
from controllers.two_loop.outer.cgmres import CgmresOuter
from controllers.two_loop.outer.protocol import OuterPlanner
from controllers.two_loop.params import two_loop_params
from suite.run.scripted import run_plant
from suite.world.scripted import ScriptedRoad, ScriptedVehicle

ROAD = ScriptedRoad(np.array([[0.0, 0.0], [2000.0, 0.0]]), lane_count=3, reference_lane=1)
CARS = (ScriptedVehicle("ego_lane", 150.0, 1), ScriptedVehicle("right_far", 170.0, 0),
        ScriptedVehicle("right_near", 120.0, 0))


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
    results: dict[str, Any] = {"params": to_dict(params), "machine": platform.processor()
                               or platform.machine(), "python": platform.python_version()}
    # 1) per-update timing: every C/GMRES sub-update called and timed on its own
    timed_outers: list[CgmresOuter] = []

    def timed_planner(path: FrenetPath, n_slots: int) -> OuterPlanner:
        outer = CgmresOuter(path, params.outer, n_slots)
        outer.time_each_subupdate = True
        timed_outers.append(outer)
        return outer

    run1 = run_plant(TwoLoopController(params, timed_planner), ROAD, CARS,
                     duration_s=duration_s)
    sub = np.asarray(timed_outers[-1].subupdate_times_s, dtype=np.float64)
    sub = sub[warmup_steps * params.outer.sub_updates:]
    # 2) whole control step
    run2 = run_plant(TwoLoopController(params), ROAD, CARS, duration_s=duration_s)
    steps = run2.step_times_s[warmup_steps:]
    ctl = run2.trace.controller
    results["outer_update"] = _stats(sub) if sub.size else {}
    results["control_step"] = _stats(steps)
    results["outer_loop_per_step"] = _stats(ctl.outer_s[warmup_steps:])
    results["inner_loop_per_step"] = _stats(ctl.inner_s[warmup_steps:])
    results["residual_max"] = float(np.max(ctl.residual))
    results["residual_median"] = float(np.median(ctl.residual))
    results["fallbacks"] = int(np.sum(ctl.fallback))
    results["guard_fired"] = int(np.sum(ctl.guard_fired))
    results["min_ellipse_c"] = float(np.min(run1.ellipse_values()))
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

