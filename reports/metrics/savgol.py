"""Savitzky–Golay smoothing and derivatives in numpy (what ``scipy.signal.savgol_filter``
computes with ``mode='interp'``), without importing ``scipy.signal``.

Why not scipy: importing ``scipy.signal`` (and the optimize/stats modules it pulls in)
costs ~0.35-0.9 s, paid by every scenario process's preload before the first run of a
catalog can start, for one filter (docs/performance.md, "third pass").

The filter, for an odd window of ``w = 2h + 1`` samples and polynomial order ``p < w``:

* interior samples h <= i < n - h: y_i = sum_k c_k x_{i-h+k}, k = 0..w-1, where c are the
  least-squares weights that evaluate the ``deriv``-th derivative at the window's centre
  of the order-p polynomial fitted to the window: c = pinv(A) e_d d! / delta^d with
  A_kj = (k - h)^j (shape (w, p+1)), e_d the d-th unit vector;
* the first and last h samples (where the window would leave the signal), two choices
  (``ends``):

  - ``"interp"`` (scipy's ``mode='interp'``, the default): the order-p polynomial fitted
    to the first (last) w samples, its ``deriv``-th derivative evaluated at those
    samples, divided by delta^deriv. Ramps and polynomials up to order p are reproduced
    exactly, end samples included. Agreement with scipy is to rounding
    (``tests/test_savgol.py``).
  - ``"hold"``: the value of the first (last) complete window, i.e. of sample h
    (n - h - 1), the centred estimate nearest the end. For a derivative this is what
    the comfort metrics judge: the one-sided fit evaluated h samples from its window's
    centre amplifies noise and extrapolates a kink in the last half window into a
    spike (a jerk of 4.72 m/s³ at a trace's last row where the raw jerk is <= 2.97 and
    the centred filter gives 2.19), whereas a held value is one of the interior ones, so
    it cannot add an extreme. Exact where the derivative is constant over the end
    windows (a ramp's slope, a parabola's second derivative); a derivative that changes
    within the last h samples is seen there only as the last centred window sees it.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

__all__ = ["Ends", "savgol_coefficients", "savgol_filter"]

Ends = Literal["interp", "hold"]


def savgol_coefficients(window: int, polyorder: int, deriv: int = 0,
                        delta: float = 1.0) -> np.ndarray:
    """(window,) weights c with y_i = sum_k c_k x_{i-h+k} (h = window // 2; correlation
    order, the first weight multiplies the oldest sample)."""
    _check(window, polyorder, deriv, delta)
    h = window // 2
    offsets = np.arange(-h, window - h, dtype=np.float64)
    design = offsets[None, :] ** np.arange(polyorder + 1, dtype=np.float64)[:, None]
    rhs = np.zeros(polyorder + 1)
    if deriv <= polyorder:
        rhs[deriv] = math.factorial(deriv) / delta ** deriv
    coeffs, *_ = np.linalg.lstsq(design, rhs, rcond=None)
    out: np.ndarray = coeffs
    return out


def savgol_filter(x: np.ndarray, window: int, polyorder: int, deriv: int = 0,
                  delta: float = 1.0, ends: Ends = "interp") -> np.ndarray:
    """Smoothed signal (deriv 0) or its ``deriv``-th derivative [unit of x / s^deriv for
    delta in s], shape (n,) like ``x``; needs an odd ``window`` <= n. ``ends``: how the
    first and last window // 2 samples are estimated (module doc)."""
    y = np.asarray(x, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError(f"savgol_filter: expected a 1-D signal, got shape {y.shape}")
    n = y.size
    if window > n:
        raise ValueError(f"savgol_filter: window {window} longer than the signal ({n})")
    if ends not in ("interp", "hold"):
        raise ValueError(f"savgol_filter: ends must be 'interp' or 'hold', got {ends!r}")
    coeffs = savgol_coefficients(window, polyorder, deriv, delta)
    h = window // 2
    out = np.empty(n)
    out[h:n - h] = np.correlate(y, coeffs, mode="valid")
    if ends == "hold":
        out[:h] = out[h]
        out[n - h:] = out[n - h - 1]
        return out
    edge = np.arange(h, dtype=np.float64)
    _fit_edge(y[:window], edge, polyorder, deriv, delta, out[:h])
    _fit_edge(y[n - window:], edge + (window - h), polyorder, deriv, delta, out[n - h:])
    return out


def _fit_edge(window_values: np.ndarray, at: np.ndarray, polyorder: int, deriv: int,
              delta: float, out: np.ndarray) -> None:
    """out[:] = the ``deriv``-th derivative, at the window positions ``at``, of the
    order-``polyorder`` polynomial fitted to ``window_values`` (positions 0..w-1)."""
    local = np.arange(window_values.size, dtype=np.float64)
    poly = np.polyfit(local, window_values, polyorder)
    if deriv > 0:
        poly = np.polyder(poly, deriv) if deriv <= polyorder else np.zeros(1)
    out[:] = np.polyval(poly, at) / delta ** deriv


def _check(window: int, polyorder: int, deriv: int, delta: float) -> None:
    if window < 1 or window % 2 != 1:
        raise ValueError(f"savgol: window must be a positive odd number, got {window}")
    if not 0 <= polyorder < window:
        raise ValueError(f"savgol: polyorder must be in [0, window), got {polyorder}")
    if deriv < 0:
        raise ValueError(f"savgol: deriv must be >= 0, got {deriv}")
    if not (math.isfinite(delta) and delta > 0):
        raise ValueError(f"savgol: delta must be a finite number > 0, got {delta}")
