"""Comfort signals and metrics (nuPlan-style), from the ego trace.

Signals (each (T,), aligned with the trace rows)
------------------------------------------------
long/lat acceleration [m/s²]: the trace's body accelerations ``long_acc_mps2``
    (u' − r v) and ``lat_acc_mps2`` (v' + r u); where a column has no finite sample it
    is rebuilt from u, v, r.
yaw rate [rad/s]: ``r_radps`` (else the derivative of the unwrapped yaw).
yaw acceleration [rad/s²]: d(yaw rate)/dt.
longitudinal jerk [m/s³]: d(long acc)/dt.
jerk [m/s³]: |d a⃗/dt| with a⃗ = R(ψ)·[a_long, a_lat] the acceleration in the world
    frame; it includes the rotation of a⃗, so a steady turn at lateral acceleration a
    and yaw rate r has |jerk| = a·r.

Smoothing and derivatives: Savitzky–Golay (:mod:`reports.metrics.savgol`, what
``scipy.signal.savgol_filter`` computes with ``mode='interp'``) as nuPlan does,
polynomial order ``SG_POLYORDER`` = 2 over ``SG_WINDOW_S`` = 0.5 s, i.e.
``window = max(5, odd(round(0.5 s / dt)))`` samples, shrunk to the trace length for short
traces (np.gradient below 3 samples). Accelerations and the yaw rate are
smoothed with the same filter (derivative order 0) before their extremes are taken;
``mode='interp'`` reproduces ramps and constants exactly, end samples included.

Derivatives at the ends: every derivative here (jerks, yaw acceleration, and the yaw
rate and accelerations rebuilt from yaw, u and v) takes, in the first and last half
window (window // 2 samples, 0.24 s at 50 Hz), the value of the first and last
*complete* window, i.e. the centred estimate nearest the end (``ends="hold"`` of
:func:`reports.metrics.savgol.savgol_filter`), never the one-sided fit evaluated at the
end samples. That fit extrapolates: a kink in the last half second became a jerk of
4.72 m/s³ (fail) at a trace's last row where the raw jerk is <= 2.97 and the centred
filter gives 2.19, and 8.99 at another run's last row where the raw signal is <= 3. A
held value is one of the centred ones, so the ends add no extreme of their own; a
constant jerk (a ramp of acceleration) is still exact up to the ends, and a change of
it within the last half window counts as much as the last centred window sees of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.savgol import savgol_filter
from reports.metrics.values import Measured, extreme, measured
from reports.record.columns import FloatColumn

SG_WINDOW_S = 0.5
SG_POLYORDER = 2
SG_MIN_WINDOW = 5


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


def sg(values: np.ndarray, dt: float, deriv: int = 0) -> FloatColumn:
    """Savitzky–Golay smoothing (deriv=0) or derivative (deriv≥1) of a uniformly sampled
    signal (T,) at period dt [s]. NaNs are linearly interpolated first; all-NaN input
    gives all-NaN output. Smoothing fits the ends (scipy's ``mode='interp'``); a
    derivative holds the first and last complete window's value there (module doc)."""
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
    return _sg_finite(y, dt, deriv)


def _sg_finite(y: FloatColumn, dt: float, deriv: int) -> FloatColumn:
    """:func:`sg` of a finite, non-empty signal ``y`` at a valid period ``dt`` [s]: the
    filter when its window exceeds the polynomial order; else ``y`` itself (deriv=0) or
    its ``deriv``-th finite-difference derivative (NaN for a single sample)."""
    n = y.size
    w = sg_window(n, dt)
    if w > SG_POLYORDER:
        out: FloatColumn = savgol_filter(y, w, SG_POLYORDER, deriv=deriv, delta=dt,
                                         ends="hold" if deriv > 0 else "interp")
        return out
    if deriv == 0:
        return y
    if n < 2:
        return np.full(n, np.nan)
    grad = y
    for _ in range(deriv):
        grad = np.gradient(grad, dt)
    return grad


@dataclass(frozen=True)
class ComfortSeries:
    """The comfort signals of a run (see the module doc), each (T,)."""

    long_acc_mps2: FloatColumn
    lat_acc_mps2: FloatColumn
    yaw_rate_radps: FloatColumn
    yaw_acc_radps2: FloatColumn
    long_jerk_mps3: FloatColumn
    jerk_mps3: FloatColumn
    lat_jerk_mps3: FloatColumn


def comfort_series(ctx: RunContext) -> ComfortSeries:
    """The per-step comfort signals of a run (empty arrays for an empty trace)."""
    n = ctx.n
    if n == 0:
        z = np.zeros(0)
        return ComfortSeries(z, z, z, z, z, z, z)
    dt = ctx.sample_period_s
    ego = ctx.record.trace.ego
    psi = ego.psi_rad
    psi_unwrapped = np.unwrap(np.where(np.isfinite(psi), psi, 0.0))
    r = ego.r_radps
    if not np.any(np.isfinite(r)):
        r = sg(psi_unwrapped, dt, deriv=1)
    u, v = ego.u_mps, ego.v_mps
    if not np.any(np.isfinite(u)):
        u = ego.speed_mps
    v = np.where(np.isfinite(v), v, 0.0)
    a_long = ego.long_acc_mps2
    if not np.any(np.isfinite(a_long)):
        a_long = sg(u, dt, deriv=1) - r * v
    a_lat = ego.lat_acc_mps2
    if not np.any(np.isfinite(a_lat)):
        a_lat = sg(v, dt, deriv=1) + r * u
    c, s = np.cos(psi_unwrapped), np.sin(psi_unwrapped)
    ax = a_long * c - a_lat * s
    ay = a_long * s + a_lat * c
    return ComfortSeries(
        long_acc_mps2=sg(a_long, dt),
        lat_acc_mps2=sg(a_lat, dt),
        yaw_rate_radps=sg(r, dt),
        yaw_acc_radps2=sg(r, dt, deriv=1),
        long_jerk_mps3=sg(a_long, dt, deriv=1),
        jerk_mps3=np.hypot(sg(ax, dt, deriv=1), sg(ay, dt, deriv=1)),
        lat_jerk_mps3=sg(a_lat, dt, deriv=1),
    )


def _peak(name: str, values: np.ndarray, how: str) -> Measured:
    value, row = extreme(values, how)
    return measured(name, value, worst_step=row)


def comfort_metrics(s: ComfortSeries) -> list[Measured]:
    """Extremes of the comfort signals (NaN for an empty trace); ``max_abs_*`` are
    extremes of |signal|, ``rms_lat_acc_mps2`` is an aggregate."""
    lat = s.lat_acc_mps2[np.isfinite(s.lat_acc_mps2)]
    rms = float(np.sqrt(np.mean(lat * lat))) if lat.size else float("nan")
    return [
        _peak("min_long_acc_mps2", s.long_acc_mps2, "min"),
        _peak("max_long_acc_mps2", s.long_acc_mps2, "max"),
        _peak("max_abs_lat_acc_mps2", np.abs(s.lat_acc_mps2), "max"),
        measured("rms_lat_acc_mps2", rms),
        _peak("max_abs_yaw_rate_radps", np.abs(s.yaw_rate_radps), "max"),
        _peak("max_abs_yaw_acc_radps2", np.abs(s.yaw_acc_radps2), "max"),
        _peak("max_abs_long_jerk_mps3", np.abs(s.long_jerk_mps3), "max"),
        _peak("max_abs_jerk_mps3", s.jerk_mps3, "max"),
    ]


def fallback_metrics(s: ComfortSeries, fallback: np.ndarray) -> list[Measured]:
    """``fallback_max_abs_lat_jerk_mps3``: the largest |d a_lat / dt| [m/s³] (the
    Savitzky-Golay derivative of the lateral acceleration, as every jerk here) over the
    steps where a safe fallback replaced the plan (``fallback`` (T,) bool; the
    ``fallbacks`` metric counts them); NaN when there were none. A fallback that steps
    its steering shows here (0.38 rad in one period at 28 m/s: lateral acceleration
    -0.5 -> -5.3 m/s² in 20 ms)."""
    mask = np.asarray(fallback, dtype=bool)
    jerk = np.where(mask, np.abs(s.lat_jerk_mps3), np.nan) if mask.shape == \
        s.lat_jerk_mps3.shape else np.full(s.lat_jerk_mps3.shape, np.nan)
    value, row = extreme(jerk, "max")
    return [measured("fallback_max_abs_lat_jerk_mps3", value, worst_step=row)]
