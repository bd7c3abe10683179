"""Tracking and progress metrics.

rms_lat_dev_m [m]: RMS of ``lat_dev_m`` (CG offset from the reference centreline).
max_abs_lat_dev_m [m], max_abs_heading_err_rad [rad]: extremes of |lat_dev_m|,
    |heading_err_rad|.
final_abs_lat_dev_m [m]: max |lat_dev_m| over the last ``FINAL_WINDOW_S`` (2 s): has
    the car settled back on its lane centre (e.g. after passing an obstacle)?
mean_speed_mps, mean_target_speed_mps, mean_speed_error_mps [m/s]: means of the speed,
    of the set-point given to the controller and of their difference (negative:
    slower than asked); the set-point falls back to ``info.target_speed_mps``.
progress_m [m]: progress along the reference path, last − first finite ``s_m``.
expected_progress_m [m]: ∫ set-point dt over the trace (the set-point the controller
    was given, which the behaviour lowers to follow a blocking car: following is not
    a progress failure), the first row's interval excluded because it happened before
    the first recorded ``s_m``; then min(that, route length remaining at the start),
    so a run longer than the route is not asked to drive past its end.
progress_ratio [-]: progress_m / expected_progress_m (NaN if nothing was expected).
route_fraction [-]: progress_m / route length remaining at the start.
"""

from __future__ import annotations

import math

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.values import Measured, extreme, measured

FINAL_WINDOW_S = 2.0


def _finite(values: np.ndarray) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    return v[np.isfinite(v)]


def _mean(values: np.ndarray) -> float:
    v = _finite(values)
    return float(np.mean(v)) if v.size else float("nan")


def _set_point_mps(ctx: RunContext) -> np.ndarray:
    """The per-row set-point [m/s], ``info.target_speed_mps`` where not recorded."""
    target = ctx.record.trace.decision.target_speed_mps
    return np.where(np.isfinite(target), target, ctx.record.info.target_speed_mps)


def progress_m(ctx: RunContext) -> float:
    """Last − first finite ``s_m`` [m] (NaN if none)."""
    s = _finite(ctx.record.trace.ego.s_m)
    return float(s[-1] - s[0]) if s.size else float("nan")


def route_remaining_m(ctx: RunContext) -> float:
    """Reference-path length left at the start of the run [m] (NaN if unknown)."""
    length = ctx.record.road.reference_length_m
    s = _finite(ctx.record.trace.ego.s_m)
    if not math.isfinite(length) or not s.size:
        return float("nan")
    return max(float(length) - float(s[0]), 0.0)


def expected_progress_m(ctx: RunContext) -> float:
    """∫ set-point dt over the run (first row excluded), capped by the route [m]."""
    if ctx.n == 0:
        return float("nan")
    target = _set_point_mps(ctx)
    if not np.any(np.isfinite(target)):
        return float("nan")
    expected = float(np.nansum(target[1:] * ctx.durations_s[1:]))
    remaining = route_remaining_m(ctx)
    if math.isfinite(remaining):
        expected = min(expected, remaining)
    return expected


def _final_abs_lat_dev(ctx: RunContext) -> Measured:
    lat = ctx.record.trace.ego.lat_dev_m
    t = ctx.t_s
    if lat.size == 0:
        return measured("final_abs_lat_dev_m", math.nan)
    window = np.where(t >= t[-1] - FINAL_WINDOW_S, np.abs(lat), np.nan)
    value, row = extreme(window, "max")
    return measured("final_abs_lat_dev_m", value, worst_step=row)


def _lat_dev_metrics(ctx: RunContext) -> list[Measured]:
    ego = ctx.record.trace.ego
    d = _finite(ego.lat_dev_m)
    rms = float(np.sqrt(np.mean(d * d))) if d.size else float("nan")
    max_dev, dev_row = extreme(np.abs(ego.lat_dev_m), "max")
    max_head, head_row = extreme(np.abs(ego.heading_err_rad), "max")
    return [
        measured("rms_lat_dev_m", rms),
        measured("max_abs_lat_dev_m", max_dev, worst_step=dev_row),
        _final_abs_lat_dev(ctx),
        measured("max_abs_heading_err_rad", max_head, worst_step=head_row),
    ]


def _speed_metrics(ctx: RunContext) -> list[Measured]:
    trace = ctx.record.trace
    speed = trace.ego.speed_mps
    recorded = trace.decision.target_speed_mps
    mean_target = _mean(recorded)
    if math.isnan(mean_target) and ctx.n:
        mean_target = float(ctx.record.info.target_speed_mps)
    target = recorded if np.any(np.isfinite(recorded)) \
        else np.full(ctx.n, ctx.record.info.target_speed_mps)
    return [
        measured("mean_speed_mps", _mean(speed)),
        measured("mean_target_speed_mps", mean_target),
        measured("mean_speed_error_mps", _mean(speed - target)),
    ]


def _progress_metrics(ctx: RunContext) -> list[Measured]:
    progress = progress_m(ctx)
    expected = expected_progress_m(ctx)
    remaining = route_remaining_m(ctx)
    ratio = progress / expected if math.isfinite(expected) and expected > 1e-6 \
        else float("nan")
    fraction = progress / remaining if math.isfinite(remaining) and remaining > 0 \
        else float("nan")
    return [
        measured("progress_m", progress),
        measured("expected_progress_m", expected),
        measured("progress_ratio", ratio),
        measured("route_fraction", fraction),
    ]


def tracking_metrics(ctx: RunContext) -> list[Measured]:
    """Every tracking and progress metric (see the module doc)."""
    return _lat_dev_metrics(ctx) + _speed_metrics(ctx) + _progress_metrics(ctx)
