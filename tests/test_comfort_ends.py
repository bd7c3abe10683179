"""Jerk and yaw acceleration at the ends of a trace (issue #31 item 5): the first and last
half window take the value of the first and last complete Savitzky–Golay window, never
the one-sided fit evaluated at the end samples (reports.metrics.comfort.sg,
reports.metrics.savgol ``ends="hold"``)."""

from __future__ import annotations

import numpy as np
import pytest

import tests.synthetic_runs as sr
from reports.metrics import evaluate
from reports.metrics.comfort import sg, sg_window
from reports.metrics.savgol import savgol_filter
from reports.record import Verdict

DT = 0.02
T = sr.times(10.0, DT)  # 500 samples, 0.02 .. 10 s
JERK = 1.5  # [m/s³] the known jerk: a(t) = A0 + JERK t
A0 = -0.8
KINK_JERK = -1.0  # [m/s³] the slope after the kink, smaller in magnitude


def _kinked(t_kink: float, at_end: bool) -> np.ndarray:
    """a(t) = A0 + JERK t, its slope turned to KINK_JERK after ``t_kink`` (at_end) or
    before it (at the start): a raw jerk never beyond |JERK|."""
    a = A0 + JERK * T
    if at_end:
        return np.where(T > t_kink, A0 + JERK * t_kink + KINK_JERK * (T - t_kink), a)
    return np.where(T < t_kink, A0 + JERK * t_kink + KINK_JERK * (T - t_kink), a)


def _judged(long_acc: np.ndarray, yaw_rate: np.ndarray) -> tuple[Verdict, np.ndarray,
                                                                   np.ndarray, np.ndarray]:
    """Judge a straight trace (yaw 0, no lateral acceleration) recording ``long_acc`` and
    ``yaw_rate``: (verdict, long jerk, jerk magnitude, yaw acceleration series)."""
    n = T.size
    trace = sr.kinematic_trace(T, 20.0 * T, np.zeros(n), np.zeros(n), np.full(n, 20.0),
                               r=yaw_rate, long_acc=long_acc, lat_acc=np.zeros(n))
    ev = evaluate(sr.make_record(trace, info=sr.base_info("ends", step_s=DT)))
    return (ev.verdict, ev.series.long_jerk_mps3, ev.series.jerk_mps3,
            ev.series.yaw_acc_radps2)


# a kink 0.2-0.3 s from an end: inside the end window, before its last half, where the
# one-sided fit extrapolates it furthest (-2.2 m/s³ where the raw jerk is -1 and 1.5)
@pytest.mark.parametrize(("t_kink", "at_end"), [(9.7, True), (9.76, True), (0.3, False)])
def test_the_judged_jerk_is_the_known_one_without_an_end_artefact(t_kink: float,
                                                                   at_end: bool) -> None:
    a = _kinked(t_kink, at_end)
    raw = np.diff(a) / DT
    assert float(np.max(np.abs(raw))) == pytest.approx(JERK)
    verdict, long_jerk, jerk, _ = _judged(a, np.zeros(T.size))
    assert verdict.value("max_abs_long_jerk_mps3") == pytest.approx(JERK, abs=1e-6)
    assert verdict.value("max_abs_jerk_mps3") == pytest.approx(JERK, abs=1e-6)
    # every sample lies between the two slopes, the end samples included
    assert np.all(long_jerk >= KINK_JERK - 1e-6) and np.all(long_jerk <= JERK + 1e-6)
    # the one-sided fit at the end samples (scipy's mode='interp') overshoots the kink
    h = sg_window(T.size, DT) // 2
    fitted = savgol_filter(a, 2 * h + 1, 2, deriv=1, delta=DT, ends="interp")
    end = slice(T.size - h, None) if at_end else slice(0, h)
    assert float(np.min(fitted[end])) < KINK_JERK - 0.5
    np.testing.assert_allclose(long_jerk[end], long_jerk[T.size - h - 1] if at_end
                               else long_jerk[h])
    np.testing.assert_allclose(jerk, np.abs(long_jerk), atol=1e-9)


def test_the_judged_yaw_acceleration_is_the_known_one_without_an_end_artefact() -> None:
    # r(t) = 0.05 + 0.3 t, the slope turned to -0.2 rad/s² after 9.7 s
    alpha = 0.3
    r = np.where(T > 9.7, 0.05 + alpha * 9.7 - 0.2 * (T - 9.7), 0.05 + alpha * T)
    verdict, _, _, yaw_acc = _judged(np.zeros(T.size), r)
    assert verdict.value("max_abs_yaw_acc_radps2") == pytest.approx(alpha, abs=1e-6)
    assert np.all(yaw_acc >= -0.2 - 1e-6) and np.all(yaw_acc <= alpha + 1e-6)
    h = sg_window(T.size, DT) // 2
    fitted = savgol_filter(r, 2 * h + 1, 2, deriv=1, delta=DT, ends="interp")
    assert float(np.min(fitted[-h:])) < -0.4  # what the one-sided fit judged


def test_a_ramp_of_acceleration_keeps_its_exact_jerk_up_to_both_ends() -> None:
    a = A0 + JERK * T
    np.testing.assert_allclose(sg(a, DT, deriv=1), JERK, atol=1e-9)
    # smoothing still fits the ends: the ramp itself is reproduced exactly
    np.testing.assert_allclose(sg(a, DT), a, atol=1e-9)


def test_hold_takes_the_first_and_last_complete_windows() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=60).cumsum()
    window, h = 11, 5
    held = savgol_filter(x, window, 2, deriv=1, delta=0.1, ends="hold")
    fitted = savgol_filter(x, window, 2, deriv=1, delta=0.1)
    np.testing.assert_array_equal(held[h:-h], fitted[h:-h])  # the interior is the filter
    np.testing.assert_array_equal(held[:h], fitted[h])
    np.testing.assert_array_equal(held[-h:], fitted[-h - 1])
    # a window as long as the signal: one complete window, its centre everywhere
    one = savgol_filter(x[:11], 11, 2, deriv=1, delta=0.1, ends="hold")
    np.testing.assert_array_equal(one, np.full(11, one[5]))
    with pytest.raises(ValueError, match="ends"):
        savgol_filter(x, window, 2, ends="wrap")  # type: ignore[arg-type]
