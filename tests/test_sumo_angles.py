"""SUMO's navigation degrees (0 = north, clockwise) and the suite's radians (CCW from +X):
known answers, the round trip, and the scalar form equal to the array form bit for bit
(the ego's heading, every SUMO step, goes the scalar way)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from suite.world.sumo import math_rad_to_nav_deg, nav_deg_to_math_rad, nav_deg_to_math_rad_scalar


@pytest.mark.parametrize(("nav_deg", "rad"), [(0.0, math.pi / 2), (90.0, 0.0),
                                              (180.0, -math.pi / 2), (270.0, -math.pi)])
def test_known_answers(nav_deg: float, rad: float) -> None:
    assert nav_deg_to_math_rad_scalar(nav_deg) == pytest.approx(rad, abs=1e-15)
    assert math_rad_to_nav_deg(rad) == pytest.approx(nav_deg % 360.0, abs=1e-12)


def test_the_scalar_form_equals_the_array_form_bit_for_bit() -> None:
    angles = np.concatenate([np.random.default_rng(0).uniform(-720.0, 720.0, 50_000),
                             [0.0, -0.0, 90.0, 359.999999999, 1e-300]])
    scalar = np.array([nav_deg_to_math_rad_scalar(float(a)) for a in angles])
    assert np.array_equal(scalar, nav_deg_to_math_rad(angles))
