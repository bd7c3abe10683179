"""The longitudinal jerk limiter (controllers.two_loop.jerk): its rate law, its bypass,
its start and the actuators' range, what it buys on the plant (a stalled car close ahead
at the start, passed within nuPlan's jerk limits, which the unlimited command breaks),
and when its bound is raised: an emergency, for an obstacle only, recorded with it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from plant_runs import CURVE, STRAIGHT, road, stalled

from controllers.behaviour.ellipses import ellipse_semi_axes
from controllers.behaviour.types import ObstaclePolicy, Obstacles
from controllers.params import ParamError
from controllers.path.frenet import FrenetPath
from controllers.two_loop.controller import make_two_loop
from controllers.two_loop.fallback import (
    FallbackParams,
    MinimalRiskManeuver,
    most_urgent_obstacle,
    planner_emergency,
)
from controllers.two_loop.jerk import JerkLimiter, JerkLimitParams
from controllers.two_loop.outer.protocol import OuterPlan
from reports.metrics.comfort import sg
from suite.run.scripted import PlantRun, run_plant

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


def _close_start(jerk: dict[str, object]) -> PlantRun:
    """Two lanes, ego at 25 m/s in the right one, a stalled car 55 m ahead in it at t = 0:
    too close to stop in comfortably, so the behaviour evades to the left."""
    return run_plant(make_two_loop({"jerk": jerk}), road(STRAIGHT), (stalled(55.0),),
                     duration_s=8.0, step_s=DT, set_speed_mps=25.0)


def test_close_stalled_car_is_evaded_within_the_jerk_limit_only_with_the_limiter() -> None:
    limited, raw = _close_start({}).trace, _close_start({"enabled": False}).trace
    for tr in (limited, raw):
        assert not tr.safety.geom_collision.any()
        assert np.all(tr.controller.fallback == 0)
        assert np.max(tr.ego.lat_dev_m) > 3.0  # into the left lane (and back after passing)
    jerk = {k: float(np.max(np.abs(sg(tr.ego.long_acc_mps2, DT, 1))))
            for k, tr in (("limited", limited), ("raw", raw))}
    assert jerk["limited"] <= 4.13 < jerk["raw"], jerk  # nuPlan's longitudinal jerk bound
    assert float(np.max(np.abs(limited.ego.lat_acc_mps2))) <= 4.89


# ------------------------------------------------ start, actuator range, emergencies
def test_first_command_is_limited_from_the_initial_torque_and_the_range_holds() -> None:
    """A run starts from the torque that holds its speed; requests beyond the actuators'
    range are handed out (and remembered) at the range, so the limiter never winds up."""
    lim = JerkLimiter(JerkLimitParams())  # 3 m/s³ both ways
    lim.reset(100.0, (-4500.0, 3000.0))
    step = 3.0 * M_R * DT
    assert lim.limit(-9000.0, DT, M_R) == pytest.approx(100.0 - step)  # not -9000 at once
    out = [lim.limit(-9000.0, DT, M_R) for _ in range(400)]
    assert min(out) == -4500.0 and out[-1] == -4500.0  # 10 m/s² brake, no further
    # Release: from -4500 at once (wound up at -9000 it would take 3.3 s to get there).
    assert lim.limit(0.0, DT, M_R) == pytest.approx(-4500.0 + step)
    assert lim.follow(5000.0) == 3000.0 and lim.last_torque_nm == 3000.0
    assert np.isnan(lim.limit(float("nan"), DT, M_R))
    with pytest.raises(ValueError, match="torque_range_nm"):
        lim.reset(0.0, (10.0, -10.0))


def _plan(v_now: float, decel: float) -> OuterPlan:
    """A 2.4 s plan at constant deceleration from v_now (the plan's V an input)."""
    tau = np.linspace(0.0, 2.4, 21)
    v = np.maximum(v_now - decel * tau[:-1], 0.0)
    states = np.column_stack([100.0 + np.concatenate([[0.0], np.cumsum(v * np.diff(tau))]),
                              np.zeros(21), np.zeros(21)])
    return OuterPlan(tau, states, v, np.zeros(20), 0.0, False, 0, 0.0)


def _stopped_car(ds_m: float, dy_m: float = 0.0) -> Obstacles:
    policy = ObstaclePolicy()
    sa, sb = ellipse_semi_axes(4.8, 1.9, 4.8, 1.9, policy)
    return Obstacles(s_m=np.array([100.0 + ds_m]), y_m=np.array([dy_m]),
                     speed_s_mps=np.zeros(1), speed_y_mps=np.zeros(1),
                     semi_a_m=np.array([sa]), semi_b_m=np.array([sb]))


def test_emergency_needs_both_a_hard_braking_plan_and_an_obstacle() -> None:
    """Known answers at 25 m/s, the ego's CG at s = 100 m: a plan braking at 6 m/s² with
    nothing ahead (a lower set speed, a restart) is no emergency; a stalled car 60 m ahead
    in the lane needs 25² / (2 (60 - A)) m/s² and makes the same plan one, recorded with
    its distance and offset; the same car with a plan that does not brake (it is being
    evaded) is none; a car in the next lane covers nothing."""
    fb = FallbackParams()
    x0 = np.array([100.0, 0.0, 0.0])
    hard, cruise = _plan(25.0, 6.0), _plan(25.0, 0.0)
    assert not planner_emergency(fb, x0, 25.0, hard, Obstacles.empty()).active
    car = _stopped_car(60.0)
    em = planner_emergency(fb, x0, 25.0, hard, car, ObstaclePolicy())
    need = 25.0**2 / (2.0 * (60.0 - float(car.semi_a_m[0])))
    assert em.active and em.decel_mps2 == pytest.approx(need)
    assert em.ds_m == pytest.approx(60.0) and em.dy_m == pytest.approx(0.0)
    assert em.jerk_mps3 == fb.emergency_jerk_mps3
    # the controller hands over the need it found once for the threat floor: the same
    urgent = most_urgent_obstacle(x0, 25.0, car, ObstaclePolicy(), fb.standstill_m)
    assert planner_emergency(fb, x0, 25.0, hard, car, ObstaclePolicy(), urgent=urgent) == em
    assert not planner_emergency(fb, x0, 25.0, cruise, car, ObstaclePolicy()).active
    beside = _stopped_car(60.0, 3.5)
    assert not planner_emergency(fb, x0, 25.0, hard, beside, ObstaclePolicy()).active
    far = _stopped_car(300.0)  # 25² / (2 (300 - A)) ~ 1.1 m/s²: comfortable, none
    assert not planner_emergency(fb, x0, 25.0, hard, far, ObstaclePolicy()).active


def test_minimal_risk_manoeuvre_records_the_obstacle_it_braces_for() -> None:
    fb = FallbackParams()
    mrm = MinimalRiskManeuver(fb, 1.5, ObstaclePolicy())
    mrm.engage(0.0, 25.0, 0.0)
    path = FrenetPath.cached(np.array([[0.0, 0.0], [1500.0, 0.0]]))
    x0 = np.array([100.0, 0.5, 0.0])
    mrm.plan(path, x0, 0.0, 25.0, DT, 2.4, 20, _stopped_car(40.0, 0.2))
    em = mrm.emergency
    assert em.active and em.ds_m == pytest.approx(40.0) and em.dy_m == pytest.approx(-0.3)
    assert mrm.ramp.decel_mps2 == pytest.approx(min(1.2 * em.decel_mps2,
                                                    fb.emergency_decel_mps2))
    mrm.plan(path, x0, 0.0, 25.0, DT, 2.4, 20, Obstacles.empty())
    assert not mrm.emergency.active and mrm.ramp.decel_mps2 == fb.decel_mps2


CAR_S = 70.0


def test_a_stalled_car_still_triggers_emergency_braking_in_closed_loop() -> None:
    """A stalled car 70 m ahead on a one-lane R = 400 m curve at 25 m/s: no side is free
    and it is too close to stop for comfortably, the plan brakes hard in front of it:
    the limiter lets it brake at the emergency rate, and the trace says which car: 70 m
    minus the ego's s ahead, on the ego's line. (Production's behaviour passes a car
    150 m ahead on two lanes and follows it comfortably on one, so the former scenario,
    a pass planned without preview that stopped in front instead, is none of its.)"""
    run = run_plant(make_two_loop({}), road(CURVE, 1), (stalled(CAR_S),), duration_s=10.0,
                    step_s=DT)
    tr = run.trace
    em = run.diagnostic("emergency").astype(bool)
    assert em.any() and not tr.safety.geom_collision.any()
    ds, dy = run.diagnostic("emergency_ds_m"), run.diagnostic("emergency_dy_m")
    assert np.all(np.isnan(ds[~em]))
    # the command of row k was computed from the state of row k - 1
    s_before = np.concatenate([[0.0], tr.ego.s_m[:-1]])
    y_before = np.concatenate([[0.0], tr.ego.lat_dev_m[:-1]])
    np.testing.assert_allclose(ds[em], CAR_S - s_before[em], atol=0.5)
    np.testing.assert_allclose(dy[em], -y_before[em], atol=0.5)
    assert np.all(run.diagnostic("emergency_decel_mps2")[em] * 1.2
                  > FallbackParams().comfort_decel_mps2)
    assert float(np.min(tr.ego.long_acc_mps2)) < -6.0  # it does brake hard
