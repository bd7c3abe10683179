"""The numbers that summarise the paper's figures, computed from a run's arrays.

Pure functions of numpy arrays (one row per trace row unless said otherwise); no run
directory, no HTML. Every function states its formula, the shapes it takes and the
units it returns. The choices behind them (windows, cut-off frequency, look-ahead) are
explained in docs/paper.md.

Conventions: ``t_s`` (T,) simulation time of each trace row [s], rows ``step_s`` apart;
a *window* is a half-open row range ``[start, stop)``; NaN means "not measurable".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.signal import butter, sosfiltfilt

FloatArray = npt.NDArray[np.float64]

STEER_CUTOFF_HZ = 2.0
"""Cut-off of the steering's high-frequency part [Hz]. The single-track plant's yaw mode
at 25 m/s lies near 0.9 Hz (heavily damped) and a highway lane change has its energy
below 0.5 Hz: steering above twice the yaw mode hardly moves the car, it is the
"high-frequency steering" of the paper's Fig. 10."""

HIGHPASS_ORDER = 4
"""Order of the Butterworth high-pass (applied forward and backward: zero phase, the
magnitude response squared)."""

MAD_TO_SIGMA = 1.4826
"""σ / MAD of a normal distribution: 1 / Φ⁻¹(3/4)."""

ENERGY_SHARE = 0.8
"""Share of the high-frequency steering energy whose distance interval is reported
(from the 10th to the 90th percentile of its cumulative sum)."""


@dataclass(frozen=True)
class Window:
    """Trace rows ``[start, stop)`` (stop > start)."""

    start: int
    stop: int

    def __post_init__(self) -> None:
        if not 0 <= self.start < self.stop:
            raise ValueError(f"a window needs 0 <= start < stop, got [{self.start}, {self.stop})")

    def mask(self, n: int) -> npt.NDArray[np.bool_]:
        """(n,) bool: True on the window's rows."""
        out = np.zeros(n, dtype=bool)
        out[self.start:self.stop] = True
        return out


def obstacle_window(n_obstacles: npt.NDArray[np.int64]) -> Window | None:
    """The first contiguous block of rows with at least one obstacle ellipse handed to the
    controller (``decision.n_obstacles > 0``): from the obstacle's entry into the
    planning problem to its exit. None if no row has one."""
    rows = np.flatnonzero(np.asarray(n_obstacles) > 0)
    if rows.size == 0:
        return None
    gaps = np.flatnonzero(np.diff(rows) > 1)
    last = rows[gaps[0]] if gaps.size else rows[-1]
    return Window(int(rows[0]), int(last) + 1)


# --------------------------------------------------------------------- residual (Fig. 9)


@dataclass(frozen=True)
class ResidualStats:
    """The residual E = ‖F‖∞ [-] over an obstacle window: ``rms`` sqrt(mean E²), ``peak``
    max E and the time it occurs after the window's start ``peak_after_s`` [s],
    ``decay_s`` the residual's decay time [s] (:func:`decay_time_s`)."""

    rms: float
    peak: float
    peak_after_s: float
    decay_s: float


def decay_time_s(t_s: FloatArray, residual: FloatArray) -> float:
    """Decay time of a residual that rises at ``t_s[0]`` [s]: twice its E²-weighted mean
    time,

        τ_E = 2 ∫ (t − t_0) E² dt / ∫ E² dt      (trapezoidal rule on the samples),

    which for E(t) = E_0 exp(−(t − t_0)/τ) over a window long against τ is τ itself (the
    weighted mean of t − t_0 under exp(−2 (t − t_0)/τ) is τ/2). A residual that stays up,
    or grows again, through the window gets a longer τ_E; one that dies at once, a short
    one. NaN when E is zero or not finite throughout, or with fewer than two samples."""
    e2 = np.where(np.isfinite(residual), residual, 0.0) ** 2
    if t_s.size < 2:
        return math.nan
    total = float(np.trapezoid(e2, t_s))
    if not total > 0.0:
        return math.nan
    return float(2.0 * np.trapezoid((t_s - t_s[0]) * e2, t_s) / total)


def residual_stats(t_s: FloatArray, residual: FloatArray, window: Window) -> ResidualStats:
    """:class:`ResidualStats` of ``residual`` (T,) [-] on the rows of ``window``."""
    t = t_s[window.start:window.stop]
    e = residual[window.start:window.stop]
    finite = np.isfinite(e)
    if not finite.any():
        return ResidualStats(math.nan, math.nan, math.nan, math.nan)
    k = int(np.nanargmax(e))
    return ResidualStats(rms=float(np.sqrt(np.mean(e[finite] ** 2))), peak=float(e[k]),
                         peak_after_s=float(t[k] - t[0]), decay_s=decay_time_s(t, e))


# --------------------------------------------------------------------- steering (Fig. 10)


def highpass(signal: FloatArray, step_s: float, cutoff_hz: float = STEER_CUTOFF_HZ
             ) -> FloatArray:
    """The part of ``signal`` (T,) above ``cutoff_hz`` [Hz]: a zero-phase Butterworth
    high-pass of order :data:`HIGHPASS_ORDER` (forward-backward, so |H|² of the order-4
    filter), sampled every ``step_s`` [s]. NaN samples are interpolated first; a signal
    too short for the filter's padding comes back as NaN."""
    x = np.asarray(signal, dtype=np.float64)
    finite = np.isfinite(x)
    out = np.full(x.shape, math.nan)
    if finite.sum() < 2:
        return out
    idx = np.arange(x.size)
    x = np.interp(idx, idx[finite], x[finite])
    nyquist = 0.5 / step_s
    if cutoff_hz >= nyquist:
        return np.zeros_like(x)
    sos = butter(HIGHPASS_ORDER, cutoff_hz / nyquist, btype="highpass", output="sos")
    try:
        filtered: FloatArray = sosfiltfilt(sos, x)
    except ValueError:  # shorter than the filter's edge padding
        return out
    return filtered


def mean_square(values: FloatArray, window: Window) -> float:
    """mean(v²) over the window's finite samples [unit²] (NaN if none)."""
    v = values[window.start:window.stop]
    v = v[np.isfinite(v)]
    return float(np.mean(v ** 2)) if v.size else math.nan


def second_difference_rms(signal: FloatArray, step_s: float, window: Window) -> float:
    """RMS of the second difference (x_{i+1} − 2 x_i + x_{i−1}) / dt² over the window's
    interior rows [unit/s²]: for a smooth signal the RMS of its second derivative; a
    command flipping from step to step of amplitude a gives 4 a / dt² (the chatter
    measure of the plant-only tests, ``suite.run.scripted.steering_chatter``)."""
    d2 = np.diff(np.asarray(signal, dtype=np.float64), 2) / step_s ** 2
    rows = np.arange(1, signal.size - 1)
    inside = (rows >= window.start) & (rows < window.stop)
    v = d2[inside]
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else math.nan


def energy_interval(position_m: FloatArray, power: FloatArray, window: Window,
                    share: float = ENERGY_SHARE) -> tuple[float, float]:
    """(from, to) [m]: the positions between which the central ``share`` of
    Σ power lies over the window (its (1 − share)/2 and (1 + share)/2 quantiles along
    the window's rows). (NaN, NaN) when the window holds no power."""
    p = np.where(np.isfinite(power), power, 0.0)[window.start:window.stop]
    x = position_m[window.start:window.stop]
    total = float(np.sum(p))
    if not total > 0.0:
        return math.nan, math.nan
    cum = np.cumsum(p) / total
    lo = x[int(np.searchsorted(cum, 0.5 * (1.0 - share)))]
    hi = x[min(int(np.searchsorted(cum, 0.5 * (1.0 + share))), x.size - 1)]
    return float(lo), float(hi)


# ----------------------------------------------------------- plan vs car (Figs. 12, 13)


def plan_lateral_error(t_s: FloatArray, x_m: FloatArray, y_m: FloatArray,
                       plan_xy_m: FloatArray, step_s: float, tau_s: float) -> FloatArray:
    """Lateral error between each plan and where the car went [m], (T,), left of the plan
    positive.

    The plan of row k (``plan_xy_m[k]``, (N+1, 2) world points of the planned CG, NaN
    padded) starts at the state the controller measured, the car's CG of row k − 1
    (t_k − step_s). The car's CG q at t_k − step_s + τ (linear interpolation on x_m, y_m)
    is projected onto the plan's polyline: the error is the signed distance from q to
    its nearest point on it, + when q lies to the left of the plan's direction. NaN when
    t_k − step_s + τ is past the trace, the plan has fewer than two points, or q's
    nearest point is the plan's far end (the plan does not reach that far). Being a
    distance to the planned *path*, it ignores where along it the car is (a longitudinal
    lag is not a lateral error)."""
    n = t_s.size
    out = np.full(n, math.nan)
    if n == 0 or plan_xy_m.ndim != 3 or plan_xy_m.shape[0] != n or plan_xy_m.shape[1] < 2:
        return out
    tq = t_s - step_s + tau_s
    qx = np.interp(tq, t_s, x_m)
    qy = np.interp(tq, t_s, y_m)
    start = plan_xy_m[:, :-1, :]
    seg = plan_xy_m[:, 1:, :] - start  # (T, N, 2)
    rel = np.stack([qx, qy], axis=1)[:, None, :] - start
    length2 = np.sum(seg ** 2, axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.clip(np.sum(rel * seg, axis=2) / length2, 0.0, 1.0)
    near = start + frac[:, :, None] * seg
    dist = np.hypot(qx[:, None] - near[:, :, 0], qy[:, None] - near[:, :, 1])
    dist = np.where(np.isfinite(dist) & (length2 > 0.0), dist, np.inf)
    j = np.argmin(dist, axis=1)
    rows = np.arange(n)
    best = dist[rows, j]
    n_seg = np.sum(np.isfinite(plan_xy_m[:, 1:, 0]) & np.isfinite(plan_xy_m[:, :-1, 0]), axis=1)
    at_far_end = (j == n_seg - 1) & (frac[rows, j] >= 1.0)
    cross = seg[rows, j, 0] * rel[rows, j, 1] - seg[rows, j, 1] * rel[rows, j, 0]
    ok = np.isfinite(best) & (tq <= t_s[-1]) & ~at_far_end & (n_seg >= 1)
    out[ok] = np.sign(cross[ok]) * best[ok]
    return out


def rms(values: FloatArray, mask: npt.NDArray[np.bool_] | None = None) -> float:
    """sqrt(mean(v²)) over the finite samples (of ``mask``) [unit]; NaN if none."""
    v = values if mask is None else values[mask]
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v ** 2))) if v.size else math.nan


def peak_abs(values: FloatArray, mask: npt.NDArray[np.bool_] | None = None) -> float:
    """max |v| over the finite samples (of ``mask``) [unit]; NaN if none."""
    v = values if mask is None else values[mask]
    v = v[np.isfinite(v)]
    return float(np.max(np.abs(v))) if v.size else math.nan


# ------------------------------------------------------------- horizon entry (Fig. 9)


def horizon_reach_row(plan_xy_m: FloatArray, ellipses: FloatArray) -> int:
    """First row at which the far end of the plan reaches an active obstacle ellipse:
    along the ellipse's heading h, (p_N − c)·(cos h, sin h) ≥ −A, with p_N the plan's
    last finite point and c, A the ellipse's centre and semi-axis along h
    (``ellipses`` (T, K, 6) = [cx, cy, h, A, B, active]). This is the paper's "the
    obstacle enters the optimisation window". −1 if it never does."""
    if plan_xy_m.ndim != 3 or ellipses.ndim != 3 or ellipses.shape[0] != plan_xy_m.shape[0] \
            or ellipses.shape[1] == 0:
        return -1
    finite = np.isfinite(plan_xy_m[:, :, 0])
    last = np.where(finite.any(axis=1), plan_xy_m.shape[1] - 1 - np.argmax(finite[:, ::-1],
                                                                            axis=1), 0)
    end = plan_xy_m[np.arange(plan_xy_m.shape[0]), last]  # (T, 2)
    cx, cy, h, a = (ellipses[:, :, i] for i in range(4))
    along = (end[:, 0:1] - cx) * np.cos(h) + (end[:, 1:2] - cy) * np.sin(h)
    reached = (ellipses[:, :, 5] > 0.5) & np.isfinite(along) & (along >= -a)
    rows = np.flatnonzero(reached.any(axis=1))
    return int(rows[0]) if rows.size else -1


# ----------------------------------------------------------------- timing (Fig. 15)


@dataclass(frozen=True)
class TimingStats:
    """Wall-clock time per control step of one loop [s]: ``mean``, ``var`` (population
    variance [s²]), ``max``, ``p50``, ``p99``; ``var_robust`` [s²] the variance
    estimated from the median absolute deviation, (1.4826 · median |t − p50|)² (equal to
    the variance for normally spread times, and blind to the few steps on which the
    operating system preempted the process: on a shared machine those reach 4-20 ms
    whatever the solver, and they dominate the raw variance of a fast one);
    ``p50_obstacle`` / ``p50_free`` the median over the steps with / without an
    obstacle in the problem (NaN if none; a median, so that a few preempted steps do not
    decide it); ``n`` steps."""

    mean: float
    var: float
    max: float
    p50: float
    p99: float
    var_robust: float
    p50_obstacle: float
    p50_free: float
    n: int


def timing_stats(times_s: FloatArray, with_obstacle: npt.NDArray[np.bool_]) -> TimingStats:
    """:class:`TimingStats` of ``times_s`` (T,) [s] (non-finite samples dropped);
    ``with_obstacle`` (T,) marks the steps with an obstacle in the problem."""
    ok = np.isfinite(times_s)
    v = times_s[ok]
    obs = with_obstacle[ok]
    if v.size == 0:
        nan = math.nan
        return TimingStats(nan, nan, nan, nan, nan, nan, nan, nan, 0)
    p50 = float(np.median(v))
    mad = float(np.median(np.abs(v - p50)))
    return TimingStats(
        mean=float(np.mean(v)), var=float(np.var(v)), max=float(np.max(v)), p50=p50,
        p99=float(np.percentile(v, 99)), var_robust=(MAD_TO_SIGMA * mad) ** 2,
        p50_obstacle=float(np.median(v[obs])) if obs.any() else math.nan,
        p50_free=float(np.median(v[~obs])) if (~obs).any() else math.nan, n=int(v.size))
