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
* the first and last h samples (where the window would leave the signal): the order-p
  polynomial fitted to the first (last) w samples, its ``deriv``-th derivative evaluated
  at those samples, divided by delta^deriv.

Ramps and polynomials up to order p are reproduced exactly, end samples included.
Agreement with scipy is to rounding (``tests/test_savgol.py``).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["savgol_coefficients", "savgol_filter"]


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
                  delta: float = 1.0) -> np.ndarray:
    """Smoothed signal (deriv 0) or its ``deriv``-th derivative [unit of x / s^deriv for
    delta in s], shape (n,) like ``x``; needs an odd ``window`` <= n (module doc)."""
    y = np.asarray(x, dtype=np.float64)
    if y.ndim != 1:
        raise ValueError(f"savgol_filter: expected a 1-D signal, got shape {y.shape}")
    n = y.size
    if window > n:
        raise ValueError(f"savgol_filter: window {window} longer than the signal ({n})")
    coeffs = savgol_coefficients(window, polyorder, deriv, delta)
    h = window // 2
    out = np.empty(n)
    out[h:n - h] = np.correlate(y, coeffs, mode="valid")
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
