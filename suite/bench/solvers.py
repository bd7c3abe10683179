"""``hwyeval bench``'s solver part: C/GMRES and Ipopt outer updates timed on one scenario
(paper Fig. 15).

:func:`benchmark_outer` drives any ``OuterPlanner`` on the paper's straight road (the ego
follows its own plan, one stalled car entering the problem mid-run) and returns the
per-update times [s]; :func:`benchmark_ipopt` adds Ipopt's iteration counts and its pure
solver-call times; :func:`solver_comparison` runs C/GMRES and both Ipopt formulations on
the same OCP with repeats. This is harness code: the numeric core it times is
:mod:`controllers.two_loop.outer`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from controllers.behaviour.types import Obstacles
from controllers.path.frenet import FrenetPath
from controllers.two_loop.outer.cgmres import CgmresOuter
from controllers.two_loop.outer.ipopt_nlp import PathLike, ellipse_values, pack_obstacles
from controllers.two_loop.outer.ipopt_planner import IpoptOuter
from controllers.two_loop.outer.params import CgmresParams, IpoptParams, ipopt_params

__all__ = ["StraightPath", "benchmark_ipopt", "benchmark_outer", "solver_comparison"]


def benchmark_outer(outer: Any, *, duration_s: float = 6.0, period_s: float = 0.02,  # noqa: PLR0913 - keyword options of the bench scenario
                    speed_mps: float = 25.0, obstacle_s_m: float = 110.0,
                    obstacle_y_m: float = -0.3, semi_a_m: float = 6.8, semi_b_m: float = 2.3,
                    detection_m: float = 80.0, iterations: Callable[[], int] | None = None
                    ) -> dict[str, Any]:
    """Per-update times of any OuterSolver on the paper's straight-road scenario.

    Straight path along +X (s = X), ego at s = 0, y = 0, 25 m/s; one stalled car in the
    lane at ``obstacle_s_m`` (default 110 m as in the paper), its ellipse A = 6.8 m,
    B = 2.3 m (4.8 x 1.9 m cars, 2 m / 0.4 m margins) offset 0.3 m to the right so
    the plan passes on the left; it enters the problem once within ``detection_m``
    of the ego, i.e. mid-run. The ego is the SPMM following its own plan (its next
    state is the plan interpolated at tau = period): this times the outer solver,
    not the plant. Returns p50/p99/max/mean/variance of ``OuterPlan.solve_s``
    [s, s^2], overall and after the obstacle entered, the residuals, fallbacks and
    the minimum ellipse value along the executed trajectory. ``times_s`` holds the
    raw samples.
    """
    x = np.array([0.0, 0.0, 0.0])
    outer.reset(x, speed_mps)
    obstacle = Obstacles(np.array([obstacle_s_m]), np.array([obstacle_y_m]), np.zeros(1),
                         np.zeros(1), np.array([semi_a_m]), np.array([semi_b_m]))
    obs_arr = pack_obstacles(obstacle)
    times: list[float] = []
    iters: list[int] = []
    residuals: list[float] = []
    fallbacks = 0
    entered_at = -1
    c_min = math.inf
    y_max = 0.0
    steps = int(round(duration_s / period_s))
    for step in range(steps):
        t = step * period_s
        near = obstacle_s_m - x[0] < detection_m and x[0] - obstacle_s_m < 10.0
        obs = obstacle if near else Obstacles.empty()
        if near and entered_at < 0:
            entered_at = step
        plan = outer.update(t, x, obs, speed_mps, period_s)
        times.append(plan.solve_s)
        residuals.append(plan.residual)
        fallbacks += int(plan.fallback)
        if iterations is not None:
            iters.append(iterations())
        x = np.array([np.interp(period_s, plan.stage_times_s, plan.states[:, c])
                      for c in range(3)])
        if not np.all(np.isfinite(x)):
            raise RuntimeError(f"non-finite state at step {step}: {x!r}")
        c_min = min(c_min, float(ellipse_values(x[None, :], np.full(1, 0.0), obs_arr)[0, 0]))
        y_max = max(y_max, float(x[1]))
    arr = np.asarray(times)
    after = arr[max(entered_at, 0):]
    before = arr[:entered_at] if entered_at > 0 else arr[:0]
    out: dict[str, Any] = {
        "updates": int(arr.size),
        "p50_s": float(np.percentile(arr, 50)), "p99_s": float(np.percentile(arr, 99)),
        "max_s": float(arr.max()), "mean_s": float(arr.mean()), "var_s2": float(arr.var()),
        "p50_before_entry_s": float(np.percentile(before, 50)) if before.size else float("nan"),
        "p50_after_entry_s": float(np.percentile(after, 50)),
        "p99_after_entry_s": float(np.percentile(after, 99)),
        "residual_p50": float(np.nanpercentile(residuals, 50)),
        "residual_max": float(np.nanmax(residuals)),
        "fallbacks": fallbacks, "obstacle_entered_step": entered_at,
        "min_ellipse_value": c_min, "max_lateral_m": y_max, "final_s_m": float(x[0]),
        "times_s": arr,
    }
    if iters:
        it = np.asarray(iters)
        pre = it[1:entered_at] if entered_at > 1 else it[:0]  # without the cold start
        post = it[max(entered_at, 0):]
        out.update({"iter_p50": float(np.percentile(it, 50)), "iter_max": int(it.max()),
                    "iter_mean_before_entry": float(pre.mean()) if pre.size else float("nan"),
                    "iter_mean_after_entry": float(post.mean()),
                    "iter_max_after_entry": int(post.max())})
    return out


def _straight_frenet(length_m: float) -> PathLike:
    return FrenetPath.cached(np.array([[0.0, 0.0], [length_m, 0.0]]))


def benchmark_ipopt(params: IpoptParams | None = None, **scenario: Any) -> dict[str, Any]:
    """:func:`benchmark_outer` for :class:`IpoptOuter` (NLPs built before timing).

    ``params`` defaults to ``IpoptParams()`` (its formulation, max_iter and tol are
    the solver's); ``scenario`` is passed to :func:`benchmark_outer` (duration_s,
    period_s, obstacle_s_m, ...). Adds Ipopt's iteration counts (``iter_*``) and its
    pure solver-call time (``ipopt_p50_s``...). The path is a straight 4 km FrenetPath.
    """
    params = params if params is not None else IpoptParams()
    formulation = params.formulation
    outer = IpoptOuter(_straight_frenet(4000.0), params)
    outer.prepare(1)
    out = benchmark_outer(outer, iterations=lambda: outer.last_iterations, **scenario)
    ip = np.array([h.ipopt_s for h in outer.history])
    out.update({"solver": f"ipopt_{formulation}", "build_s": outer.build_s,
                "ipopt_p50_s": float(np.percentile(ip, 50)),
                "ipopt_p99_s": float(np.percentile(ip, 99)),
                "ipopt_var_s2": float(ip.var())})
    cpu = np.array([h.ipopt_cpu_s for h in outer.history])
    out.update({"ipopt_cpu_p50_s": float(np.percentile(cpu, 50)),
                "ipopt_cpu_p99_s": float(np.percentile(cpu, 99)),
                "ipopt_cpu_var_s2": float(cpu.var())})
    return out


def solver_comparison(repeats: int = 5, n_slots: int = 3,
                      **scenario: Any) -> dict[str, Any]:
    """C/GMRES vs the Ipopt NMPC on the same OCP and scenario
    (:func:`benchmark_outer`: straight road, 25 m/s, a
    stalled car entering mid-run), each solver run ``repeats`` times after an untimed
    warm-up (numba cache, NLP construction).

    Ipopt at its best: warm start (the previous solution and multipliers, mu_init 1e-6),
    exact Hessian, MUMPS (``IpoptOuter``'s options). Per solver: ``raw``, the update
    times [s] pooled over the repeats, and ``min_of_repeats``, each update's minimum
    over the repeats (the update sequence is deterministic, so the minimum removes the
    machine's preemptions and keeps the solver's own variation: Ipopt's iteration
    counts, C/GMRES's fixed work). Ratios Ipopt / C/GMRES of p50, p99 and variance for
    both, and of the per-update minima split at the update where the obstacle enters
    the problem (``..._without_obstacle``, ``..._with_obstacle``: C/GMRES's time is
    bimodal, ~20 us with empty slots and ~80 us with one obstacle, and that step
    dominates its pooled variance); requires CasADi (``pip install 'hwyeval[baselines]'``).
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats}")
    cg = CgmresParams()
    path = FrenetPath.cached(np.array([[0.0, 0.0], [4000.0, 0.0]]))

    def make(name: str) -> Any:
        if name == "cgmres":
            return CgmresOuter(path, cg, n_slots)
        outer = IpoptOuter(path, ipopt_params(cg, formulation=name.removeprefix("ipopt_")))
        outer.prepare(1)
        return outer

    out: dict[str, Any] = {"repeats": repeats, "ipopt_options": {}}
    for name in ("cgmres", "ipopt_barrier", "ipopt_hard"):
        benchmark_outer(make(name), **scenario)  # warm-up, untimed
        runs = []
        entered = 0
        for _ in range(repeats):
            outer = make(name)
            result = benchmark_outer(outer, **scenario)
            runs.append(np.asarray(result["times_s"]))
            entered = max(int(result["obstacle_entered_step"]), 0)
            if isinstance(outer, IpoptOuter):
                out["ipopt_options"] = {k: v for k, v in outer._warm_opts.items()
                                        if k != "print_level"}
        n = min(r.size for r in runs)
        stacked = np.stack([r[:n] for r in runs])
        best = stacked.min(axis=0)
        out[name] = {"raw": _solver_stats(stacked.reshape(-1)),
                     "min_of_repeats": _solver_stats(best),
                     "obstacle_entered_update": entered}
        if 0 < entered < n:
            out[name]["min_of_repeats_without_obstacle"] = _solver_stats(best[:entered])
            out[name]["min_of_repeats_with_obstacle"] = _solver_stats(best[entered:])
    kinds = ("raw", "min_of_repeats", "min_of_repeats_without_obstacle",
             "min_of_repeats_with_obstacle")
    for name in ("ipopt_barrier", "ipopt_hard"):
        out[f"{name}_over_cgmres"] = {
            kind: {k: out[name][kind][k] / out["cgmres"][kind][k]
                   for k in ("p50_s", "p99_s", "var_s2") if out["cgmres"][kind][k] > 0}
            for kind in kinds if kind in out[name] and kind in out["cgmres"]}
    return out


def _solver_stats(times_s: np.ndarray) -> dict[str, float]:
    t = np.asarray(times_s, dtype=np.float64)
    return {"n": float(t.size), "p50_s": float(np.percentile(t, 50)),
            "p99_s": float(np.percentile(t, 99)), "max_s": float(t.max()),
            "var_s2": float(t.var())}


class StraightPath:
    """A straight reference along +X (gamma = 0, kappa = 0), for benchmarks and tests."""

    def __init__(self, length_m: float) -> None:
        self.length_m = float(length_m)

    def gamma(self, s: Any) -> Any:
        return np.zeros_like(np.asarray(s, dtype=np.float64))

    def kappa(self, s: Any) -> Any:
        return np.zeros_like(np.asarray(s, dtype=np.float64))
