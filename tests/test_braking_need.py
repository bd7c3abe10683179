"""The braking an obstacle ahead needs (controllers.two_loop.fallback.braking_need_mps2),
a lead's own braking included: known answers, and a kinematic simulation independent
of the formula (the gap stays >= 0 at the need and goes negative just below it)."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.two_loop.fallback import braking_need_mps2


def _min_gap(v: float, b: float, v_j: float, b_j: float, d: float, dt: float = 1e-3) -> float:
    """Smallest gap while both brake at constant deceleration to a stop (Euler-exact
    positions on a fine grid until the ego stops)."""
    t = np.arange(0.0, v / b + dt, dt)
    ego = v * t - 0.5 * b * t**2
    if b_j > 0.0:
        t_l = np.minimum(t, v_j / b_j)
        lead = d + v_j * t_l - 0.5 * b_j * t_l**2
    else:
        lead = d + v_j * t
    return float(np.min(lead - ego))


def _need(v: float, v_j: float, d: float, b_j: float) -> float:
    return float(braking_need_mps2(v, np.array([v_j]), np.array([d]), np.array([b_j]))[0])


def test_a_lead_at_constant_speed_needs_the_closing_law() -> None:
    assert _need(30.0, 20.0, 50.0, 0.0) == pytest.approx(1.0)  # 10² / (2 50)
    assert _need(20.0, 25.0, 50.0, 0.0) == 0.0  # nothing closes


def test_a_lead_braking_to_a_stop_first_needs_its_stopping_point() -> None:
    # lead 20 m/s braking at 8 stops 25 m on: the ego stops within 75 m: 30² / 150
    b = _need(30.0, 20.0, 50.0, 8.0)
    assert b == pytest.approx(6.0)
    assert _min_gap(30.0, b, 20.0, 8.0, 50.0) >= -1e-3
    assert _min_gap(30.0, 0.97 * b, 20.0, 8.0, 50.0) < 0.0


def test_speeds_that_match_before_the_lead_stops_need_its_braking_plus_the_closing() -> None:
    b = _need(30.0, 25.0, 10.0, 1.0)
    assert b == pytest.approx(1.0 + 25.0 / 20.0)
    assert _min_gap(30.0, b, 25.0, 1.0, 10.0) >= -1e-3
    assert _min_gap(30.0, 0.97 * b, 25.0, 1.0, 10.0) < 0.0


def test_a_faster_lead_braking_hard_still_needs_braking() -> None:
    # the lead pulls away now but stops within 18.3² / (2 8.3) = 20.2 m: the old law
    # (nothing closes: 0) saw no need at all
    b = _need(25.0, 28.0, 30.0, 8.3)
    assert b > 0.0
    assert _min_gap(25.0, b, 28.0, 8.3, 30.0) >= -1e-3
    assert _min_gap(25.0, 0.97 * b, 28.0, 8.3, 30.0) < 0.0


@pytest.mark.parametrize("seed", range(5))
def test_the_need_is_the_least_braking_that_keeps_the_gap(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(20):
        v, v_j = rng.uniform(5.0, 35.0), rng.uniform(0.0, 35.0)
        d, b_j = rng.uniform(2.0, 80.0), rng.choice([0.0, rng.uniform(0.5, 9.0)])
        b = _need(v, v_j, d, b_j)
        if b <= 0.0:  # only a lead that neither brakes nor is slower
            assert b_j == 0.0 and v <= v_j
            continue
        assert _min_gap(v, b, v_j, b_j, d) >= -2e-3 * max(1.0, d)
        assert _min_gap(v, 0.97 * b, v_j, b_j, d) < 0.0
