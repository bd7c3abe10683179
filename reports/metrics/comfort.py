"""Comfort metrics (nuPlan-style), from the ego trace.

Signals
-------
long/lat acceleration [m/s²]: the trace's body accelerations ``long_acc_mps2`` (u' − r v)
    and ``lat_acc_mps2`` (v' + r u); where absent they are rebuilt from u, v, r.
yaw rate [rad/s]: ``r_radps`` (else the derivative of the unwrapped yaw).
yaw acceleration [rad/s²]: d(yaw rate)/dt.
longitudinal jerk [m/s³]: d(long acc)/dt.
jerk [m/s³]: |d a⃗/dt| with a⃗ the acceleration vector in the world frame
    (R(ψ)·[a_long, a_lat]); it includes the rotation of a⃗, so a steady turn at
    lateral acceleration a and yaw rate r has |jerk| = a·r.

Smoothing and derivatives: Savitzky–Golay (``scipy.signal.savgol_filter``) as nuPlan
does, polynomial order ``SG_POLYORDER`` = 2 over a window of ``SG_WINDOW_S`` = 0.5 s
(nuPlan: 5 samples at 10 Hz), i.e. ``window = max(5, odd(round(0.5 s / dt)))``
samples, shrunk to the trace length for short traces (np.gradient below 3 samples).
Accelerations and yaw rate are smoothed with the same filter (derivative order 0)
before their extremes are taken; ``mode='interp'`` keeps end samples unbiased for
polynomial-shaped signals, so ramps and constants are reproduced exactly.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import savgol_filter

from reports.metrics.tracking import column, control_period_s, median_time_step_s
from reports.run_record import RunRecord

SG_WINDOW_S = 0.5
SG_POLYORDER = 2
SG_MIN_WINDOW = 5


def sample_period_s(record: RunRecord) -> float:
    """Median spacing of ``t_s`` [s] (the control period if t_s is unusable)."""
    dt = median_time_step_s(record)
    return dt if math.isfinite(dt) else control_period_s(record)


def sg_window(n: int, dt: float) -> int:
    """Savitzky–Golay window length [samples] for n samples at period dt (odd, ≤ n)."""
    if not (math.isfinite(dt) and dt > 0):
        dt = 0.1
    w = max(SG_MIN_WINDOW, int(round(SG_WINDOW_S / dt)))
    if w % 2 == 0:
        w += 1
    if w > n:
        w = n if n % 2 == 1 else n - 1
    return w


def sg(values: np.ndarray, dt: float, deriv: int = 0) -> np.ndarray:
    """Savitzky–Golay smoothing (deriv=0) or derivative (deriv≥1) of a uniformly sampled
    signal. NaNs are linearly interpolated first; all-NaN input gives all-NaN output."""
    y = np.asarray(values, dtype=np.float64)
    n = y.size
    if n == 0:
        return y.copy()
    ok = np.isfinite(y)
    if not np.any(ok):
        return np.full(n, np.nan)
    if not np.all(ok):
        idx = np.arange(n)
        y = np.interp(idx, idx[ok], y[ok])
    if not (math.isfinite(dt) and dt > 0):
        return np.full(n, np.nan)
    w = sg_window(n, dt)
    if w > SG_POLYORDER:
        return savgol_filter(y, window_length=w, polyorder=SG_POLYORDER, deriv=deriv, delta=dt,
                             mode="interp")
    if deriv == 0:
        return y
    if n < 2:
        return np.full(n, np.nan)
    out = y
    for _ in range(deriv):
        out = np.gradient(out, dt)
    return out


def comfort_series(record: RunRecord) -> dict[str, np.ndarray]:
    """Per-step comfort signals: long_acc, lat_acc, yaw_rate, yaw_acc, long_jerk, jerk."""
    n = len(record.trace)
    dt = sample_period_s(record)
    if n == 0:
        z = np.zeros(0)
        return {k: z for k in ("long_acc", "lat_acc", "yaw_rate", "yaw_acc", "long_jerk", "jerk")}
    psi = column(record, "psi_rad")
    psi_unwrapped = np.unwrap(np.where(np.isfinite(psi), psi, 0.0))
    r = column(record, "r_radps")
    if not np.any(np.isfinite(r)):
        r = sg(psi_unwrapped, dt, deriv=1)
    u, v = column(record, "u_mps"), column(record, "v_mps")
    if not np.any(np.isfinite(u)):
        u = column(record, "speed_mps")
    v = np.where(np.isfinite(v), v, 0.0)
    a_long = column(record, "long_acc_mps2")
    if not np.any(np.isfinite(a_long)):
        a_long = sg(u, dt, deriv=1) - r * v
    a_lat = column(record, "lat_acc_mps2")
    if not np.any(np.isfinite(a_lat)):
        a_lat = sg(v, dt, deriv=1) + r * u
    c, s = np.cos(psi_unwrapped), np.sin(psi_unwrapped)
    ax = a_long * c - a_lat * s
    ay = a_long * s + a_lat * c
    jerk = np.hypot(sg(ax, dt, deriv=1), sg(ay, dt, deriv=1))
    return {
        "long_acc": sg(a_long, dt),
        "lat_acc": sg(a_lat, dt),
        "yaw_rate": sg(r, dt),
        "yaw_acc": sg(r, dt, deriv=1),
        "long_jerk": sg(a_long, dt, deriv=1),
        "jerk": jerk,
    }


def _max(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(values.max()) if values.size else float("nan")


def _min(values: np.ndarray) -> float:
    values = values[np.isfinite(values)]
    return float(values.min()) if values.size else float("nan")


def comfort_metrics(record: RunRecord) -> dict[str, float]:
    """Comfort extremes [SI units in the names] (NaN for an empty trace)."""
    s = comfort_series(record)
    lat = s["lat_acc"][np.isfinite(s["lat_acc"])]
    return {
        "min_long_acc_mps2": _min(s["long_acc"]),
        "max_long_acc_mps2": _max(s["long_acc"]),
        "max_abs_lat_acc_mps2": _max(np.abs(s["lat_acc"])),
        "rms_lat_acc_mps2": float(np.sqrt(np.mean(lat * lat))) if lat.size else float("nan"),
        "max_abs_yaw_rate_radps": _max(np.abs(s["yaw_rate"])),
        "max_abs_yaw_acc_radps2": _max(np.abs(s["yaw_acc"])),
        "max_abs_long_jerk_mps3": _max(np.abs(s["long_jerk"])),
        "max_abs_jerk_mps3": _max(s["jerk"]),
    }
