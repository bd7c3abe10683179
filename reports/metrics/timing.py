"""Timing and optimiser-health metrics.

Per loop — ``outer`` (``outer_s``), ``inner`` (``inner_s``), ``obstacles``
(``obstacles_s``) and ``step`` (the whole controller step, ``controller_s``) — the
percentiles p50/p95/p99, the mean and max in milliseconds (``{loop}_ms_p50`` …), and
the variance of the per-step time in s² (``step_var_s2`` for the whole step,
``{loop}_step_var_s2`` for the others). ``deadline_misses`` counts steps whose
``controller_s`` exceeds the control period (``run.json`` ``step_s``);
``deadline_miss_frac`` is that count over the steps. ``sumo_ms_*`` time SUMO's own step.
``realtime_factor`` = sim_time_s / wall_s (> 1 is faster than real time).

Health: ``residual_max`` / ``residual_final`` (outer-loop residual E = ‖F‖∞, NaN if the
controller has none), ``fallbacks`` (steps where a safe fallback replaced the plan),
``guards`` (total barrier-guard firings).
"""

from __future__ import annotations

import math

import numpy as np

from reports.metrics.tracking import column, control_period_s
from reports.run_record import RunRecord

LOOPS: dict[str, str] = {
    "step": "controller_s",
    "outer": "outer_s",
    "inner": "inner_s",
    "obstacles": "obstacles_s",
    "sumo": "sumo_s",
}


def loop_times_s(record: RunRecord, loop: str) -> np.ndarray:
    """Finite per-step times [s] of one loop (a key of ``LOOPS``)."""
    t = column(record, LOOPS[loop])
    return t[np.isfinite(t)]


def _var_name(prefix: str) -> str:
    """``step_var_s2`` for the whole step, ``<loop>_step_var_s2`` for a loop."""
    return "step_var_s2" if prefix == "step" else f"{prefix}_step_var_s2"


def loop_stats(times_s: np.ndarray, prefix: str) -> dict[str, float]:
    """p50/p95/p99/mean/max [ms] and variance [s²] of a sample of times [s]."""
    nan = float("nan")
    if times_s.size == 0:
        return {f"{prefix}_ms_p50": nan, f"{prefix}_ms_p95": nan, f"{prefix}_ms_p99": nan,
                f"{prefix}_ms_mean": nan, f"{prefix}_ms_max": nan, _var_name(prefix): nan}
    p50, p95, p99 = np.percentile(times_s, [50, 95, 99]) * 1e3
    return {
        f"{prefix}_ms_p50": float(p50),
        f"{prefix}_ms_p95": float(p95),
        f"{prefix}_ms_p99": float(p99),
        f"{prefix}_ms_mean": float(times_s.mean() * 1e3),
        f"{prefix}_ms_max": float(times_s.max() * 1e3),
        _var_name(prefix): float(times_s.var()),
    }


def deadline_misses(record: RunRecord) -> float:
    """Steps whose whole controller time exceeded the control period [-]."""
    period = control_period_s(record)
    t = loop_times_s(record, "step")
    if not math.isfinite(period):
        return float("nan")
    return float(np.sum(t > period))


def realtime_factor(record: RunRecord) -> float:
    """sim_time_s / wall_s from run.json [-] (NaN if unknown)."""
    sim = record.meta.get("sim_time_s")
    wall = record.meta.get("wall_s")
    if not isinstance(sim, int | float) or not isinstance(wall, int | float) or wall <= 0:
        return float("nan")
    return float(sim) / float(wall)


def timing_metrics(record: RunRecord) -> dict[str, float]:
    """All timing metrics by name (see module doc)."""
    out: dict[str, float] = {}
    for loop in LOOPS:
        out.update(loop_stats(loop_times_s(record, loop), loop))
    n_steps = len(record.trace)
    misses = deadline_misses(record)
    out["deadline_misses"] = misses
    out["deadline_miss_frac"] = misses / n_steps if n_steps else float("nan")
    out["control_period_ms"] = control_period_s(record) * 1e3
    for key in ("sim_time_s", "wall_s"):
        value = record.meta.get(key)
        out[key] = float(value) if isinstance(value, int | float) else float("nan")
    out["realtime_factor"] = realtime_factor(record)
    return out


def health_metrics(record: RunRecord) -> dict[str, float]:
    """Optimiser health: residual_max, residual_final, fallbacks, guards."""
    res = column(record, "residual")
    finite = res[np.isfinite(res)]
    fallback = np.nan_to_num(column(record, "fallback"))
    guards = np.nan_to_num(column(record, "guard_fired"))
    return {
        "residual_max": float(finite.max()) if finite.size else float("nan"),
        "residual_final": float(finite[-1]) if finite.size else float("nan"),
        "fallbacks": float(np.sum(fallback != 0)),
        "guards": float(np.sum(guards)),
        "steps": float(len(record.trace)),
    }
