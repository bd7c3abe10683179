"""The longitudinal jerk limiter (controllers.two_loop.jerk): its rate law, its bypass,
and what it buys on the plant: a stalled car close ahead at the start, passed within
nuPlan's jerk limits, which the unlimited command breaks."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from controllers.behaviour.ellipses import FrenetVehicle
from controllers.behaviour.types import LaneContext, LaneSlot
from controllers.params import ParamError
from controllers.sim.closed_loop import simulate
from controllers.two_loop.controller import make_two_loop
from controllers.two_loop.jerk import JerkLimiter, JerkLimitParams
from reports.metrics.comfort import sg

M_R = 1500.0 * 0.3  # torque per unit acceleration [N m / (m/s²)]
DT = 0.02


def test_a_torque_step_becomes_a_ramp_at_the_jerk_bound() -> None:
    lim = JerkLimiter(JerkLimitParams(jerk_up_mps3=3.0, jerk_down_mps3=5.0, max_accel_mps2=10.0))
    assert lim.limit(100.0, DT, M_R) == 100.0  # the first command passes
    out = [lim.limit(2000.0, DT, M_R) for _ in range(200)]
    accel = np.array([100.0, *out]) / M_R
    rate = np.diff(accel) / DT
    assert np.max(rate) == pytest.approx(3.0)  # 3 m/s³ until the request is reached
    n_ramp = int(np.ceil((2000.0 - 100.0) / (3.0 * M_R * DT)))
    assert out[n_ramp - 2] < 2000.0 and out[n_ramp - 1] == 2000.0
    assert lim.limited is False  # reached: the request passes again
    down = [lim.limit(-2000.0, DT, M_R) for _ in range(5)]
    assert np.diff([2000.0, *down]) == pytest.approx(np.full(5, -5.0 * M_R * DT))
    assert lim.limited is True


def test_commanded_acceleration_is_capped() -> None:
    lim = JerkLimiter(JerkLimitParams(max_accel_mps2=2.0))
    lim.limit(0.0, DT, M_R)
    out = [lim.limit(3.0 * M_R, DT, M_R) for _ in range(100)]  # ask for 3 m/s²
    assert max(out) == pytest.approx(2.0 * M_R) and out[-1] == pytest.approx(2.0 * M_R)
    assert lim.limit(-1.0 * M_R, DT, M_R) == pytest.approx((2.0 - 3.0 * DT) * M_R)


def test_bypass_is_bumpless_and_disabled_passes_everything() -> None:
    lim = JerkLimiter(JerkLimitParams())
    lim.limit(0.0, DT, M_R)
    assert lim.follow(-3000.0) == -3000.0  # another stage (the MRM) brakes hard
    # limiting resumes from what was handed out, not from before the bypass
    assert lim.limit(-3000.0, DT, M_R) == -3000.0
    assert lim.limit(0.0, DT, M_R) == pytest.approx(-3000.0 + 3.0 * M_R * DT)
    off = JerkLimiter(JerkLimitParams(enabled=False))
    off.limit(0.0, DT, M_R)
    assert off.limit(5000.0, DT, M_R) == 5000.0
    lim.reset()
    assert lim.limit(777.0, DT, M_R) == 777.0
    assert np.isnan(lim.limit(float("nan"), DT, M_R))  # never hides a fault


@pytest.mark.parametrize("name", ["jerk_up_mps3", "jerk_down_mps3", "max_accel_mps2"])
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan")])
def test_bounds_must_be_positive(name: str, value: float) -> None:
    with pytest.raises(ParamError, match=name):
        changes: dict[str, Any] = {name: value}
        JerkLimitParams(**changes)


def _close_start(jerk: dict[str, object]) -> dict[str, Any]:
    """Two lanes, ego at 25 m/s in the right one, a stalled car 55 m ahead in it at t = 0:
    too close to stop in comfortably, so the behaviour evades to the left."""
    lanes = LaneContext({0: LaneSlot(0, 3.5, True, False), 1: LaneSlot(1, 3.5, True, False)}, 0)
    road = np.array([[0.0, 0.0], [1500.0, 0.0]])
    return simulate(make_two_loop({"jerk": jerk}), road, [FrenetVehicle(55.0, 0.0)],
                    duration_s=8.0, dt=DT, initial_speed_mps=25.0, target_speed_mps=25.0,
                    lanes=lanes)


def test_close_stalled_car_is_evaded_within_the_jerk_limit_only_with_the_limiter() -> None:
    limited, raw = _close_start({}), _close_start({"enabled": False})
    for tr in (limited, raw):
        assert not tr["box_overlap"].any()
        assert np.all(tr["fallback"] == 0)
        assert np.max(tr["y_m"]) > 3.0  # into the left lane (and back after passing)
    jerk = {k: float(np.max(np.abs(sg(tr["long_acc_mps2"], DT, 1))))
            for k, tr in (("limited", limited), ("raw", raw))}
    assert jerk["limited"] <= 4.13 < jerk["raw"], jerk  # nuPlan's longitudinal jerk bound
    assert float(np.max(np.abs(limited["lat_acc_mps2"]))) <= 4.89
