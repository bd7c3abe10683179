"""Tracking and progress metrics, plus the small trace helpers every metric module uses.

All functions take a :class:`reports.run_record.RunRecord` and tolerate an empty trace
(they then return NaN, or 0 for counts).
"""

from __future__ import annotations

import math

import numpy as np

from reports.run_record import RunRecord

# --------------------------------------------------------------------------- helpers


def column(record: RunRecord, name: str) -> np.ndarray:
    """Trace column ``name`` as a float64 array (NaN-filled if the column is absent)."""
    trace = record.trace
    if name not in trace.columns:
        return np.full(len(trace), np.nan)
    values = trace[name].to_numpy()
    if values.dtype == object:
        out = np.full(len(values), np.nan)
        for i, v in enumerate(values):
            try:
                out[i] = float(v)
            except (TypeError, ValueError):
                pass
        return out
    return values.astype(np.float64)


def bool_column(record: RunRecord, name: str) -> np.ndarray:
    """Trace column ``name`` as a bool array (False where absent or NaN)."""
    values = column(record, name)
    return np.nan_to_num(values, nan=0.0) != 0.0


def median_time_step_s(record: RunRecord) -> float:
    """Median positive spacing of ``t_s`` [s]; NaN if it cannot be measured."""
    t = column(record, "t_s")
    if t.size >= 2:
        d = np.diff(t)
        d = d[np.isfinite(d) & (d > 0)]
        if d.size:
            return float(np.median(d))
    return float("nan")


def control_period_s(record: RunRecord) -> float:
    """The control period [s]: ``run.json`` ``step_s``, else the median step of ``t_s``."""
    step = record.meta.get("step_s")
    if isinstance(step, int | float) and math.isfinite(step) and step > 0:
        return float(step)
    return median_time_step_s(record)


def step_durations_s(record: RunRecord) -> np.ndarray:
    """Duration [s] each trace row stands for (``t_s`` differences; the first row gets
    the control period). Used to turn per-step flags into times."""
    n = len(record.trace)
    if n == 0:
        return np.zeros(0)
    period = control_period_s(record)
    t = column(record, "t_s")
    dt = np.full(n, period)
    if n >= 2 and np.all(np.isfinite(t)):
        dt[1:] = np.diff(t)
    dt = np.where(np.isfinite(dt) & (dt > 0), dt, period if math.isfinite(period) else 0.0)
    return dt


def _nan_stat(values: np.ndarray, fn: str) -> float:
    values = values[np.isfinite(values)]
    if values.size == 0:
        return float("nan")
    return float(getattr(np, fn)(values))


# --------------------------------------------------------------------------- metrics


def rms_lat_dev_m(record: RunRecord) -> float:
    """RMS of ``lat_dev_m`` (CG offset from the reference centreline) [m]."""
    d = column(record, "lat_dev_m")
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")


def max_abs_lat_dev_m(record: RunRecord) -> float:
    """Maximum |lat_dev_m| [m]."""
    return _nan_stat(np.abs(column(record, "lat_dev_m")), "max")


FINAL_WINDOW_S = 2.0


def final_abs_lat_dev_m(record: RunRecord, window_s: float = FINAL_WINDOW_S) -> float:
    """max |lateral deviation| [m] over the last ``window_s`` of the run: has the car
    settled back on the lane centre (e.g. after passing an obstacle)? NaN if empty."""
    lat = column(record, "lat_dev_m")
    t = column(record, "t_s")
    if lat.size == 0 or t.size != lat.size:
        return math.nan
    return _nan_stat(np.abs(lat[t >= t[-1] - window_s]), "max")


def max_abs_heading_err_rad(record: RunRecord) -> float:
    """Maximum |heading_err_rad| [rad]."""
    return _nan_stat(np.abs(column(record, "heading_err_rad")), "max")


def mean_speed_mps(record: RunRecord) -> float:
    """Mean ego speed over the run [m/s]."""
    return _nan_stat(column(record, "speed_mps"), "mean")


def mean_target_speed_mps(record: RunRecord) -> float:
    """Mean speed set-point given to the controller [m/s] (``run.json`` value if absent)."""
    value = _nan_stat(column(record, "target_speed_mps"), "mean")
    if math.isnan(value) and len(record.trace):
        meta_target = record.meta.get("target_speed_mps")
        if isinstance(meta_target, int | float):
            return float(meta_target)
    return value


def mean_speed_error_mps(record: RunRecord) -> float:
    """Mean of (speed − set-point) [m/s]; negative means slower than asked."""
    target = column(record, "target_speed_mps")
    if not np.any(np.isfinite(target)):
        meta_target = record.meta.get("target_speed_mps")
        target = np.full(len(record.trace), float(meta_target) if isinstance(
            meta_target, int | float) else np.nan)
    return _nan_stat(column(record, "speed_mps") - target, "mean")


def progress_m(record: RunRecord) -> float:
    """Progress along the reference path ``s_m`` (last − first finite value) [m]."""
    s = column(record, "s_m")
    s = s[np.isfinite(s)]
    return float(s[-1] - s[0]) if s.size else float("nan")


def route_remaining_m(record: RunRecord) -> float:
    """Reference-path length left at the start of the run [m] (NaN if unknown)."""
    length = record.road.get("reference_length_m")
    s = column(record, "s_m")
    s = s[np.isfinite(s)]
    if not isinstance(length, int | float) or not s.size:
        return float("nan")
    return max(float(length) - float(s[0]), 0.0)


def route_fraction(record: RunRecord) -> float:
    """Progress as a fraction of the route length remaining at the start [-]."""
    remaining = route_remaining_m(record)
    prog = progress_m(record)
    if not math.isfinite(remaining) or remaining <= 0:
        return float("nan")
    return prog / remaining


def expected_progress_m(record: RunRecord) -> float:
    """Distance the set-point speed would cover over the run, capped by the route [m].

    ∫ target_speed_mps dt over the trace (the set-point the controller was given,
    which the runner lowers when it must follow a blocking obstacle), falling back to
    ``run.json`` ``target_speed_mps`` × run time; then min(that, route remaining),
    so a run longer than the route is not asked to drive past its end.
    """
    n = len(record.trace)
    if n == 0:
        return float("nan")
    dt = step_durations_s(record)
    target = column(record, "target_speed_mps")
    meta_target = record.meta.get("target_speed_mps")
    fallback = float(meta_target) if isinstance(meta_target, int | float) else np.nan
    target = np.where(np.isfinite(target), target, fallback)
    if not np.any(np.isfinite(target)):
        return float("nan")
    # the first row's interval happened before the first recorded s_m: skip it
    expected = float(np.nansum(target[1:] * dt[1:]))
    remaining = route_remaining_m(record)
    if math.isfinite(remaining):
        expected = min(expected, remaining)
    return expected


def progress_ratio(record: RunRecord) -> float:
    """progress_m / expected_progress_m [-] (NaN if nothing was expected)."""
    expected = expected_progress_m(record)
    if not math.isfinite(expected) or expected <= 1e-6:
        return float("nan")
    return progress_m(record) / expected


def tracking_metrics(record: RunRecord) -> dict[str, float]:
    """All tracking/progress metrics by name."""
    return {
        "rms_lat_dev_m": rms_lat_dev_m(record),
        "max_abs_lat_dev_m": max_abs_lat_dev_m(record),
        "final_abs_lat_dev_m": final_abs_lat_dev_m(record),
        "max_abs_heading_err_rad": max_abs_heading_err_rad(record),
        "mean_speed_mps": mean_speed_mps(record),
        "mean_target_speed_mps": mean_target_speed_mps(record),
        "mean_speed_error_mps": mean_speed_error_mps(record),
        "progress_m": progress_m(record),
        "expected_progress_m": expected_progress_m(record),
        "progress_ratio": progress_ratio(record),
        "route_fraction": route_fraction(record),
    }
