"""Timing (wall-clock) and optimiser-health metrics.

Timing, per loop of :data:`LOOPS` (``step`` = the whole behaviour + controller step):
``{loop}_ms_p50``/``_p95``/``_p99``/``_mean``/``_max`` [ms] over the steps with a time,
and the variance of the per-step time [s²] (``step_var_s2`` for the whole step,
``{loop}_step_var_s2`` for the others). ``deadline_misses`` counts the steps whose
``controller_s`` exceeds the control period, ``deadline_miss_frac`` is that count over
the steps. ``realtime_factor`` = sim_time_s / wall_s (> 1: faster than real time);
``sim_time_s``, ``wall_s`` and ``control_period_ms`` are copied for the tables.

Health: ``residual_max`` / ``residual_final`` (outer-loop residual E = ‖F‖∞, NaN if the
controller has none), ``fallbacks`` (steps where a safe fallback replaced the plan),
``guards`` (barrier-guard firings in total; a negative entry means 'not recorded' and
counts 0), ``steps`` (trace rows).
"""

from __future__ import annotations

import math

import numpy as np

from reports.metrics.catalogue import LOOPS, STATS, var_name
from reports.metrics.context import RunContext
from reports.metrics.values import Measured, extreme, measured
from reports.record import Trace
from reports.record.columns import FloatColumn


def loop_column_s(trace: Trace, loop: str) -> FloatColumn:
    """The per-step time column [s] of a loop of :data:`LOOPS`."""
    columns = {"step": trace.timing.controller_s, "outer": trace.controller.outer_s,
               "inner": trace.controller.inner_s, "obstacles": trace.timing.obstacles_s,
               "sumo": trace.timing.sumo_s}
    return columns[loop]


def loop_times_s(trace: Trace, loop: str) -> FloatColumn:
    """The finite per-step times [s] of a loop of :data:`LOOPS`."""
    t = loop_column_s(trace, loop)
    out: FloatColumn = t[np.isfinite(t)]
    return out


def loop_stats(times_s: np.ndarray, loop: str) -> list[Measured]:
    """p50/p95/p99/mean/max [ms] and variance [s²] of a sample of times [s]."""
    names = [f"{loop}_ms_{stat}" for stat in STATS]
    if times_s.size == 0:
        values = [math.nan] * 5
        var = math.nan
    else:
        p50, p95, p99 = np.percentile(times_s, [50, 95, 99]) * 1e3
        values = [float(p50), float(p95), float(p99), float(times_s.mean() * 1e3),
                  float(times_s.max() * 1e3)]
        var = float(times_s.var())
    out = [measured(name, value) for name, value in zip(names, values, strict=True)]
    return out + [measured(var_name(loop), var)]


def _deadline_metrics(ctx: RunContext) -> list[Measured]:
    period = ctx.period_s
    step_s = loop_column_s(ctx.record.trace, "step")
    if math.isfinite(period):
        late = np.isfinite(step_s) & (step_s > period)
        misses = float(np.sum(late))
        increments = late.astype(np.float64)
    else:
        misses, increments = math.nan, None
    frac = misses / ctx.n if ctx.n else math.nan
    return [measured("deadline_misses", misses, increments=increments),
            measured("deadline_miss_frac", frac)]


def _run_clock_metrics(ctx: RunContext) -> list[Measured]:
    outcome = ctx.record.outcome
    sim, wall = float(outcome.sim_time_s), float(outcome.wall_s)
    rtf = sim / wall if math.isfinite(wall) and wall > 0 else math.nan
    return [measured("control_period_ms", ctx.period_s * 1e3), measured("sim_time_s", sim),
            measured("wall_s", wall), measured("realtime_factor", rtf)]


def timing_metrics(ctx: RunContext) -> list[Measured]:
    """Every timing metric (see the module doc)."""
    out: list[Measured] = []
    for loop in LOOPS:
        out += loop_stats(loop_times_s(ctx.record.trace, loop), loop)
    return out + _deadline_metrics(ctx) + _run_clock_metrics(ctx)


def health_metrics(ctx: RunContext) -> list[Measured]:
    """residual_max, residual_final, fallbacks, guards, steps (see the module doc)."""
    ctrl = ctx.record.trace.controller
    residual = np.asarray(ctrl.residual, dtype=np.float64)
    res_max, res_row = extreme(residual, "max")
    finite = residual[np.isfinite(residual)]
    fallback = np.asarray(ctrl.fallback, dtype=bool)
    guards = np.maximum(np.asarray(ctrl.guard_fired, dtype=np.float64), 0.0)
    return [
        measured("residual_max", res_max, worst_step=res_row),
        measured("residual_final", float(finite[-1]) if finite.size else math.nan),
        measured("fallbacks", float(np.sum(fallback)), increments=fallback.astype(np.float64)),
        measured("guards", float(np.sum(guards))),
        measured("steps", float(ctx.n)),
    ]
