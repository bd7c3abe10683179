"""Inner loop: plan interpolation, conversion (13)(14) + feed-forward, STVM preview."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import VehicleParams, stvm_rk4
from controllers.two_loop.preview import convert, inner_step, plan_reference

VP = VehicleParams()


def _gains(k_ps: float = 1.0, ff: bool = True, lookahead: float = 0.15) -> np.ndarray:
    return np.array([k_ps, 1500.0, 500.0, 0.1, 0.05, 1.0 if ff else 0.0, lookahead,
                     VP.understeer_gradient_rad_per_mps2])


def _straight_plan(x0: float, y: float, v: float, n: int = 20, horizon: float = 2.4,
                   heading: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tau = np.linspace(0.0, horizon, n + 1)
    states = np.column_stack([x0 + v * tau, np.full(n + 1, y), np.full(n + 1, heading)])
    return tau, states, np.full(n, v)


def test_plan_reference_interpolates() -> None:
    tau = np.array([0.0, 0.1, 0.3, 0.6])
    states = np.array([[0.0, 0.0, 0.0], [2.0, 0.1, 0.01], [6.0, 0.3, 0.05], [12.0, 0.6, 0.08]])
    speeds = np.array([20.0, 21.0, 22.0])
    s, y, th, v, om, acc = plan_reference(tau, states, speeds, 0.2)
    assert (s, y, th) == pytest.approx((4.0, 0.2, 0.03))
    assert v == 21.0
    assert om == pytest.approx(0.2)  # (0.05 - 0.01) / 0.2
    assert acc == pytest.approx((22.0 - 21.0) / 0.25)
    assert plan_reference(tau, states, speeds, 5.0)[0] == pytest.approx(12.0)  # clamped


def test_conversion_signs_and_feedforward() -> None:
    vp = VP.as_array()
    state = np.array([0.0, 0.0, 0.1, 20.0, 0.0, 0.0])
    d, t = convert(state, 0.15, 22.0, 0.0, 0.0, _gains(ff=False), vp)
    assert d == pytest.approx(0.05)  # K_Ps (theta* - theta_a)
    assert t == pytest.approx(1500.0 * 2.0)
    # theta_a includes the body slip: psi + atan2(v, u).
    state2 = np.array([0.0, 0.0, 0.1, 20.0, 1.0, 0.0])
    d2, _ = convert(state2, 0.1 + math.atan2(1.0, 20.0), 20.0, 0.0, 0.0, _gains(ff=False), vp)
    assert d2 == pytest.approx(0.0, abs=1e-12)
    # Feed-forward: (L + K_us V²) omega / V and m R a.
    om = 25.0 / 400.0
    d3, t3 = convert(np.array([0, 0, 0, 25.0, 0, 0.0]), 0.0, 25.0, om, 1.0, _gains(), vp)
    assert d3 == pytest.approx((VP.wheelbase_m + VP.understeer_gradient_rad_per_mps2 * 625)
                               * om / 25.0)
    assert t3 == pytest.approx(VP.mass_kg * VP.wheel_radius_m * 1.0)


def test_feedforward_steer_gives_the_planned_turn_on_the_stvm() -> None:
    """Steady state: delta = (L + K_us V²) kappa makes the STVM turn with curvature kappa."""
    vp = VP.as_array()
    v, kappa = 25.0, 1.0 / 400.0
    delta, _ = convert(np.array([0, 0, 0, v, 0, 0.0]), 0.0, v, v * kappa, 0.0, _gains(), vp)
    x = np.array([0.0, 0.0, 0.0, v, 0.0, 0.0])
    for _ in range(400):
        x = stvm_rk4(x, delta, 0.0, vp, 0.02, 4)
    speed = math.hypot(x[3], x[4])
    assert x[5] / speed == pytest.approx(kappa, rel=0.01)


def _run_inner(plan: tuple[np.ndarray, np.ndarray, np.ndarray], state: np.ndarray,
               path: FrenetPath) -> tuple[np.ndarray, np.ndarray]:
    meta, coef, knots = path.tables()
    prev = np.zeros((11, 2))
    out = np.zeros(6)
    limits = np.array([VP.max_steer_rad, VP.max_drive_torque_nm, VP.max_brake_torque_nm])
    inner_step(state, plan[0], plan[1], plan[2], _gains(), VP.as_array(), limits, 10, 0.05,
               meta, coef, knots, prev, out)
    return out, prev


def test_preview_error_zero_on_consistent_plan_and_signed_otherwise() -> None:
    path = FrenetPath.cached(np.array([[0.0, 0.0], [1000.0, 0.0]]))
    state = np.array([100.0, 0.0, 0.0, 25.0, 0.0, 0.0])
    out, prev = _run_inner(_straight_plan(100.0, 0.0, 25.0), state, path)
    assert abs(out[2]) < 0.01 and abs(out[3]) < 0.01
    assert prev[-1, 0] == pytest.approx(100.0 + 25.0 * 0.5, abs=0.01)
    # Plan 0.5 m to the left: PE_n > 0 (steer left), and the conversion already steers left.
    out_l, _ = _run_inner(_straight_plan(100.0, 0.5, 25.0), state, path)
    assert out_l[3] > 0.05
    # Plan 2 m ahead at the same speed: PE_t > 0 (more torque).
    out_a, _ = _run_inner(_straight_plan(102.0, 0.0, 25.0), state, path)
    assert out_a[2] == pytest.approx(2.0, abs=0.05)
    # Plan heading to the right: negative steer from the conversion; the preview sees the
    # car end up right of the (straight-ahead) plan points and asks for a left correction.
    out_r, _ = _run_inner(_straight_plan(100.0, 0.0, 25.0, heading=-0.05), state, path)
    assert out_r[0] < 0.0 and out_r[3] > 0.0


def test_preview_finite_at_standstill() -> None:
    path = FrenetPath.cached(np.array([[0.0, 0.0], [1000.0, 0.0]]))
    state = np.array([100.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    out, prev = _run_inner(_straight_plan(100.0, 0.0, 0.0), state, path)
    assert np.all(np.isfinite(out)) and np.all(np.isfinite(prev))
    state = np.array([100.0, 0.0, 0.0, 0.3, 0.05, 0.2])
    out, prev = _run_inner(_straight_plan(100.0, 0.3, 2.0), state, path)
    assert np.all(np.isfinite(out)) and np.all(np.isfinite(prev))
