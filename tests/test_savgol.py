"""reports.metrics.savgol: known answers, and agreement with scipy.signal.savgol_filter
(mode='interp'), which it replaces in the metrics to keep scipy.signal out of every
scenario process."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter as scipy_savgol

from reports.metrics.savgol import savgol_coefficients, savgol_filter

SIZES = [(n, w) for n in (3, 5, 26, 101, 1000) for w in (1, 3, 5, 11, 25) if w <= n]


@pytest.mark.parametrize(("n", "window"), SIZES)
@pytest.mark.parametrize("deriv", [0, 1, 2, 3])
def test_agrees_with_scipy_interp_mode(n: int, window: int, deriv: int) -> None:
    rng = np.random.default_rng(n * 100 + window * 10 + deriv)
    x = rng.normal(size=n).cumsum()
    for polyorder in range(min(window, 5)):
        want = scipy_savgol(x, window, polyorder, deriv=deriv, delta=0.02, mode="interp")
        got = savgol_filter(x, window, polyorder, deriv=deriv, delta=0.02)
        scale = max(1.0, float(np.max(np.abs(want))))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10 * scale)


def test_a_quadratic_and_its_derivatives_are_exact_end_samples_included() -> None:
    dt = 0.02
    t = np.arange(200) * dt
    x = 3.0 - 2.0 * t + 0.75 * t**2  # x' = -2 + 1.5 t, x'' = 1.5
    np.testing.assert_allclose(savgol_filter(x, 25, 2, 0, dt), x, atol=1e-9)
    np.testing.assert_allclose(savgol_filter(x, 25, 2, 1, dt), -2.0 + 1.5 * t, atol=1e-8)
    np.testing.assert_allclose(savgol_filter(x, 25, 2, 2, dt), np.full_like(t, 1.5),
                               atol=1e-6)
    np.testing.assert_allclose(savgol_filter(x, 25, 2, 3, dt), 0.0, atol=1e-12)


def test_smoothing_weights_sum_to_one_and_derivative_weights_to_zero() -> None:
    assert savgol_coefficients(11, 2).sum() == pytest.approx(1.0, abs=1e-14)
    c1 = savgol_coefficients(11, 2, deriv=1, delta=0.1)
    assert c1.sum() == pytest.approx(0.0, abs=1e-12)
    # the first weight multiplies the oldest sample: a rising ramp has a positive slope
    assert float(c1 @ np.arange(11.0)) == pytest.approx(10.0)  # 1 per sample / 0.1 s


@pytest.mark.parametrize(("window", "polyorder", "deriv", "delta"),
                         [(4, 2, 0, 1.0), (0, 0, 0, 1.0), (5, 5, 0, 1.0), (5, 2, -1, 1.0),
                          (5, 2, 0, 0.0), (5, 2, 0, float("nan"))])
def test_bad_arguments_are_refused(window: int, polyorder: int, deriv: int,
                                   delta: float) -> None:
    with pytest.raises(ValueError, match="savgol"):
        savgol_filter(np.zeros(10), window, polyorder, deriv, delta)


def test_a_window_longer_than_the_signal_is_refused() -> None:
    with pytest.raises(ValueError, match="longer than the signal"):
        savgol_filter(np.zeros(4), 5, 2)
