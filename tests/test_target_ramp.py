"""Jerk-limited target-speed ramp shared by the outer solvers (no SUMO)."""

from __future__ import annotations

import numpy as np
import pytest

from controllers.two_loop.outer.ocp import TargetSpeedRamp


@pytest.mark.parametrize(("start", "goal"), [(0.0, 22.0), (25.0, 0.0), (20.0, 20.5)])
def test_ramp_respects_accel_and_jerk_and_lands_without_overshoot(start: float,
                                                                   goal: float) -> None:
    ramp = TargetSpeedRamp(accel_mps2=1.5, decel_mps2=3.0, jerk_mps3=2.0)
    ramp.reset(start)
    dt = 0.02
    v = [start] + [ramp.update(goal, dt) for _ in range(3000)]
    a = np.diff(v) / dt
    assert v[-1] == pytest.approx(goal)
    assert a.max() <= 1.5 + 1e-9 and a.min() >= -3.0 - 1e-9
    jerk = np.diff(a) / dt
    assert np.abs(jerk).max() <= 2.0 + 1e-6
    lo, hi = min(start, goal), max(start, goal)
    assert min(v) >= lo - 1e-3 and max(v) <= hi + 1e-3  # no overshoot beyond 1 mm/s


def test_ramp_from_0_to_22_takes_the_time_the_limits_imply() -> None:
    # 0 -> 1.5 m/s^2 in 0.75 s, cruise at 1.5, back to 0 in 0.75 s: ~ 22/1.5 + 0.75 s.
    ramp = TargetSpeedRamp(1.5, 3.0, 2.0)
    ramp.reset(0.0)
    t = 0.0
    while ramp.update(22.0, 0.01) < 22.0:
        t += 0.01
    assert t == pytest.approx(22.0 / 1.5 + 0.75, abs=0.2)
