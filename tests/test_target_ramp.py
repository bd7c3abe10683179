"""Jerk-limited target-speed ramp shared by the outer solvers, and what it buys the
two-loop controller on the plant (no SUMO): a set speed away from the car's speed, up
or down, at the start or later, is a comfortable ramp, never an emergency brake."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from controllers.two_loop.controller import make_two_loop
from controllers.two_loop.outer.params import OcpParams
from controllers.two_loop.outer.target_ramp import TargetSpeedRamp
from reports.metrics.comfort import sg
from suite.run.scripted import PlantRun, PlantStart, run_plant
from suite.world.scripted import ScriptedRoad

DT = 0.02
STRAIGHT = np.array([[0.0, 0.0], [3000.0, 0.0]])
LONG_ACC = (-4.05, 2.40)  # nuPlan's comfort bounds [m/s²]
LONG_JERK = 4.13  # [m/s³]


def ramp_time_s(dv_mps: float, accel_mps2: float, jerk_mps3: float) -> float:
    """Duration of a time-optimal jerk-limited change of speed by |dv| from rest to rest:
    a trapezoid in acceleration |dv| / a + a / j when |dv| >= a² / j, else a triangle
    2 sqrt(|dv| / j)."""
    dv = abs(dv_mps)
    if dv >= accel_mps2**2 / jerk_mps3:
        return dv / accel_mps2 + accel_mps2 / jerk_mps3
    return 2.0 * math.sqrt(dv / jerk_mps3)


def _run_ramp(ramp: TargetSpeedRamp, start: float, goal: float, n: int = 3000
              ) -> tuple[np.ndarray, float]:
    """(V_t samples, first time V_t == goal [s]) from ``start`` toward ``goal``."""
    ramp.reset(start)
    v = [start] + [ramp.update(goal, DT) for _ in range(n)]
    arr = np.array(v)
    hit = np.flatnonzero(arr == goal)
    return arr, float(hit[0]) * DT if hit.size else math.inf


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


@pytest.mark.parametrize(("start", "goal", "limit"), [
    (33.0, 27.0, "set"),    # a set speed below the start: the comfortable deceleration
    (36.0, 18.0, "set"),
    (18.0, 36.0, "accel"),  # above it: the acceleration limit
    (27.0, 27.5, "accel"),  # a small step: a triangle in acceleration
    (27.0, 26.6, "set"),
    (33.0, 20.0, "follow"),  # below the cruise set-point: the behaviour's, firmer
])
def test_ramp_duration_and_bounds_are_the_known_answer(start: float, goal: float,
                                                       limit: str) -> None:
    """A set point at or above the cruise set-point is the driver's set speed (ramped
    down at the comfortable limit), one below it the behaviour lowered to follow (the
    firmer one): the ramp's peak acceleration, its jerk and its duration are those of
    the time-optimal profile."""
    accel, follow_decel, set_decel, jerk = 1.5, 3.0, 1.5, 2.0
    ramp = TargetSpeedRamp(accel, follow_decel, jerk, set_decel)
    ramp.cruise_speed_mps = start if limit == "follow" else goal
    a_lim = {"set": set_decel, "accel": accel, "follow": follow_decel}[limit]
    v, t_hit = _run_ramp(ramp, start, goal)
    a = np.diff(v) / DT
    expected_peak = min(a_lim, math.sqrt(abs(goal - start) * jerk))
    assert np.max(np.abs(a)) == pytest.approx(expected_peak, rel=0.05)
    assert np.max(np.abs(np.diff(a) / DT)) <= jerk + 1e-6
    assert t_hit == pytest.approx(ramp_time_s(goal - start, a_lim, jerk), abs=0.1)
    lo, hi = min(start, goal), max(start, goal)
    assert v.min() >= lo - 1e-3 and v.max() <= hi + 1e-3  # no overshoot beyond 1 mm/s


def test_ramp_without_a_cruise_speed_uses_the_firm_limit_everywhere() -> None:
    ramp = TargetSpeedRamp(1.5, 3.0, 2.0, set_speed_decel_mps2=1.5)  # cruise not given
    v, t_hit = _run_ramp(ramp, 33.0, 27.0)
    assert np.min(np.diff(v) / DT) == pytest.approx(-3.0, rel=1e-6)
    assert t_hit == pytest.approx(ramp_time_s(6.0, 3.0, 2.0), abs=0.1)
    assert ramp.decel_for_mps2(27.0) == 3.0
    ramp.cruise_speed_mps = 27.0
    assert ramp.decel_for_mps2(27.0) == 1.5 and ramp.decel_for_mps2(26.9) == 3.0


def test_set_speed_deceleration_is_validated() -> None:
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="set_speed_decel_mps2"):
            OcpParams(set_speed_decel_mps2=bad)


# ------------------------------------------------------- on the plant, two-loop
def _drive(v0: float, set_speed: float, duration_s: float,
           target_fn: Callable[[float], float] | None = None,
           controller: Any = None) -> PlantRun:
    """Empty straight road (production's loop, no SUMO); ``target_fn(t)``: the driver's
    set speed over time."""
    ctl = controller if controller is not None else make_two_loop({})
    return run_plant(ctl, ScriptedRoad(STRAIGHT), duration_s=duration_s, step_s=DT,
                     start=PlantStart(speed_mps=v0), set_speed_mps=set_speed,
                     set_speed_fn=target_fn)


def _assert_comfortable_ramp(run: PlantRun, v_from: float, v_to: float, t0_s: float,
                             a_lim: float, t1_s: float = math.inf) -> None:
    """Within nuPlan's bounds over the run; in [t0_s, t1_s): at most the ramp's own
    acceleration a_lim (plus a margin for tracking), no emergency, no fallback, and v_to
    reached (within 0.5 m/s) by the ramp's time + 2 s, not before the fastest the
    limits allow, and held at the window's end."""
    t = run.trace.t_s - DT  # when each command was computed
    acc = run.trace.ego.long_acc_mps2
    win = (t >= t0_s) & (t < t1_s)
    assert LONG_ACC[0] <= acc.min() and acc.max() <= LONG_ACC[1]
    assert np.max(np.abs(acc[win])) <= a_lim + 0.25
    assert np.max(np.abs(sg(acc, DT, 1))) <= LONG_JERK
    assert not np.any(run.diagnostic("emergency")[win])
    assert not np.any(run.trace.controller.fallback[win])
    v = run.trace.ego.speed_mps
    near = win & (np.abs(v - v_to) <= 0.5)
    assert near.any()
    t_reach = float(t[near][0]) - t0_s
    dv = abs(v_to - v_from)
    assert (dv - 0.5) / (a_lim + 0.25) <= t_reach <= ramp_time_s(dv, a_lim, 2.0) + 2.0
    assert abs(v[win][-1] - v_to) <= 0.5


@pytest.mark.parametrize(("v0", "set_speed"), [(33.0, 27.0), (33.0, 30.0), (18.0, 24.0),
                                               (36.0, 18.0)])
def test_set_speed_away_from_the_start_speed_is_a_comfortable_ramp(v0: float,
                                                                  set_speed: float) -> None:
    """Empty straight road: before, the OCP's ramp started at min(v0, set speed), the
    closed-form start put the plan's V there and the first command (unlimited) braked
    at 10 m/s²; now the ramp starts at the car's speed."""
    o = OcpParams()
    a_lim = o.target_accel_mps2 if set_speed > v0 else o.set_speed_decel_mps2
    duration = ramp_time_s(set_speed - v0, a_lim, o.target_jerk_mps3) + 4.0
    run = _drive(v0, set_speed, duration)
    _assert_comfortable_ramp(run, v0, set_speed, 0.0, a_lim)
    first = run.trace.ego.torque_nm[0]  # the first command: close to holding the speed
    assert abs(first) <= 0.5 * 1500.0 * 0.3


def test_a_set_speed_changed_later_is_a_ramp_both_ways() -> None:
    """Cruising at 25 m/s, the set speed goes to 30 m/s at 2 s and back to 25 at 10 s
    (both at or above the run's cruise set-point: the driver's, not a follow target)."""
    o = OcpParams()

    def target(t: float) -> float:
        return 30.0 if 2.0 <= t < 10.0 else 25.0

    run = _drive(25.0, 25.0, 18.0, target_fn=target)
    _assert_comfortable_ramp(run, 25.0, 30.0, 2.0, o.target_accel_mps2, t1_s=10.0)
    _assert_comfortable_ramp(run, 30.0, 25.0, 10.0, o.set_speed_decel_mps2)
    assert run.diagnostic("ocp_target_speed_mps")[0] == pytest.approx(25.0)


@pytest.mark.slow
def test_ipopt_baseline_ramps_the_same_way() -> None:
    pytest.importorskip("casadi")
    from controllers.baselines.ipopt_nmpc import make_ipopt_nmpc

    o = OcpParams()
    run = _drive(33.0, 27.0, 8.0, controller=make_ipopt_nmpc({}))
    _assert_comfortable_ramp(run, 33.0, 27.0, 0.0, o.set_speed_decel_mps2)
