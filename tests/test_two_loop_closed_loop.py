"""Two-loop controller on production's loop without SUMO (suite.run.scripted.run_plant on a
scripted world): configuration, obstacle avoidance, curves, pass side, follow mode, J1 vs
J3 (paper result 1), preview on/off (result 2). The decisions are production's
(LaneBehaviour: lanes, obstacle selection, following); a test picks them through the
road (which lanes exist) and the vehicles."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from plant_runs import CURVE, DT, LANE, STRAIGHT, road, stalled

from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.ellipses import ellipse_semi_axes
from controllers.behaviour.types import EgoFrenet, Reason, Side
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import ConfigError, Controller, Observation, ObstaclePolicy, Obstacles
from controllers.two_loop.controller import TwoLoopController, make_two_loop
from controllers.two_loop.diagnostics import TwoLoopDiagnostics
from controllers.two_loop.outer.params import CgmresParams
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.params import TwoLoopParams
from suite.run.scripted import DecisionSchedule, PlantRun, PlantStart, run_plant, steering_chatter
from suite.world.scripted import ScriptedVehicle, ScriptedWorld

STALLED_S = 150.0
# On the curve the car stands farther: production's behaviour starts a pass as soon as
# the car is within its planning range (~150 m at 25 m/s), and the curve tests measure
# lane keeping on the curve (20 m < s < 90 m) before that.
CURVE_STALLED_S = 300.0

# nuPlan comfort limits.
LAT_ACC = 4.89
LONG_ACC = (-4.05, 2.40)
YAW_RATE = 0.95


def _run(reference: np.ndarray = STRAIGHT, pass_side: int = 1, duration: float = 14.0,
         stalled_s: float = STALLED_S, **sections: object) -> PlantRun:
    """A stalled car ``stalled_s`` ahead in the ego lane, one free lane on the side ``pass_side``
    (+1: the ego in the right lane of two, -1: in the left one), the controller with
    ``sections`` as the catalog's nested tables (outer={...}, ...)."""
    lane = 0 if pass_side > 0 else 1
    return run_plant(make_two_loop(dict(sections)), road(reference, 2, lane),
                     (stalled(stalled_s, lane),), duration_s=duration, step_s=DT)


def _assert_safe_and_comfortable(run: PlantRun) -> None:
    tr = run.trace
    assert not tr.safety.geom_collision.any()
    assert np.min(run.ellipse_values()) > 0.0  # CG never inside the margin-free ellipse
    assert np.max(np.abs(tr.ego.lat_acc_mps2)) <= LAT_ACC
    assert LONG_ACC[0] <= np.min(tr.ego.long_acc_mps2)
    assert np.max(tr.ego.long_acc_mps2) <= LONG_ACC[1]
    assert np.max(np.abs(tr.ego.r_radps)) <= YAW_RATE
    assert np.all(np.isfinite(tr.ego.steer_rad)) and np.all(np.isfinite(tr.ego.torque_nm))


# ----------------------------------------------------------------------------- config
def test_make_two_loop_validates_options() -> None:
    ctl = make_two_loop({"name": "two_loop", "outer": {"cost": "J3", "n_stages": 20,
                                                       "horizon_s": 2.4, "k_max": 16},
                         "inner": {"preview": True}, "policy": {"margin_lat_m": 0.5}})
    assert ctl.planner is None and ctl.path is None  # cheap: nothing built or solved
    assert isinstance(ctl, Controller)
    assert ctl.name == "two_loop" and ctl.diagnostics_type is TwoLoopDiagnostics
    assert ctl.obstacle_policy == ObstaclePolicy(margin_lat_m=0.5, detection_distance_m=100.0)
    assert ctl.params.outer.k_max == 16 and isinstance(ctl.params.outer.horizon_s, float)
    params = ctl.parameters()
    assert json.loads(json.dumps(params))["outer"]["cost"] == "J3"
    cases = [({"bogus": 1}, "controller.bogus"), ({"cost": "J4"}, "controller.outer.cost"),
             ({"outer": {"xyz": 1.0}}, "controller.outer.xyz"),
             ({"outer": {"n_stages": 20.0}}, "controller.outer.n_stages"),
             ({"inner": {"preview": 1}}, "controller.inner.preview"),
             ({"outer": {"horizon_s": -1.0}}, "controller.outer.horizon_s"),
             ({"outer": {"k_max": 0}}, "controller.outer.k_max"),
             ({"outer": "qp"}, "controller.outer"),
             ({"outer": {"zeta": 0.01}}, "controller.outer.z_guard"),
             ({"outer": {"horizon_s": math.nan}}, "controller.outer.horizon_s"),
             ({"policy": {"max_obstacles": -1}}, "controller.policy.max_obstacles"),
             ({"lateral": {"rate_mps": 0.0}}, "controller.lateral.rate_mps"),
             ({"lateral": {"filter_s": -0.1}}, "controller.lateral.filter_s"),
             ({"lateral": {"filter_s": "0.2"}}, "controller.lateral.filter_s"),
             ({"lateral": {"c_y_engaged": -1.0}}, "controller.lateral.c_y_engaged"),
             ({"lateral": {"weight_time_s": 0.0}}, "controller.lateral.weight_time_s"),
             ({"inner": {"lookahead_s": 3.0}}, "controller.inner.lookahead_s"),
             ({"outer": {"c_thetadot": 0.0}}, "controller.outer.c_thetadot")]
    for opts, key in cases:
        with pytest.raises(ConfigError) as err:
            make_two_loop(opts)
        assert err.value.key == key, (opts, err.value)
    with pytest.raises(ValueError):
        CgmresParams(c_thetadot=0.0)  # J3 needs it


def test_ellipse_geometry_and_detection() -> None:
    """The ellipse's known size, and which vehicles production's behaviour makes obstacles
    (controllers.behaviour.obstacle_choice) on three lanes, the ego in the middle one at
    s = 0: a stalled lead 60 m ahead in its lane, a stalled car 40 m ahead on the left,
    one 20 m/s car 50 m ahead on the right, a car 200 m ahead (beyond the 80 m detection)
    and one 20 m behind (beyond the 10 m rear range). The left lane is blocked, the right
    lane's speed beats the stopped lead: pass on the right (allowed past a stopped car),
    with the lane moved into's lead and the passed car as the two obstacles, the passed
    one shifted away from the pass side; the car in the lane left untouched is none.
    Without moving obstacles only the stalled lead, its speed zero."""
    pol = ObstaclePolicy(margin_long_m=2.0, margin_lat_m=0.4, offset_m=0.3,
                         detection_distance_m=80.0, max_obstacles=2)
    ego = VehicleParams()
    a, b = ellipse_semi_axes(4.0, 1.8, ego.length_m, ego.width_m, pol)
    # The ellipse contains the box-sum rectangle (corner (2.0 + 2.4, 0.9 + 0.95) on it
    # before the margins): see controllers.behaviour.ellipses.
    b0 = 0.9 + 0.95 + 0.4
    a0 = (2.0 + 2.4) / math.sqrt(1.0 - ((0.9 + 0.95) / b0) ** 2)
    assert (a, b) == pytest.approx((a0 + 2.0, b0 + 0.3))
    three = road(STRAIGHT, 3, 1)
    world = ScriptedWorld(three, (ScriptedVehicle("far", 200.0, 1),
                                  ScriptedVehicle("lead", 60.0, 1),
                                  ScriptedVehicle("left", 40.0, 2),
                                  ScriptedVehicle("behind", -20.0, 1),
                                  ScriptedVehicle("right", 50.0, 0, speed_mps=20.0)))

    def decide(policy: ObstaclePolicy) -> tuple[Side, Reason, Obstacles]:
        behaviour = LaneBehaviour(FrenetPath.cached(STRAIGHT), policy,
                                  EgoShape(ego.length_m, ego.width_m), LANE)
        d = behaviour.decide(EgoFrenet(0.0, 0.0, 0.0, 0.0, 25.0, 0.0), world.traffic_at(0.0),
                             three.lanes(), 25.0)
        return d.side, d.reason_code, d.obstacles

    side, code, obs = decide(pol)
    assert side == Side.RIGHT and code == Reason.PASS
    assert obs.vehicle_ids == ("right", "lead")  # nearest first, at most two
    assert obs.s_m[0] == 50.0 and obs.y_m[0] == -LANE and obs.speed_s_mps[0] == 20.0
    assert obs.s_m[1] == 60.0 and obs.y_m[1] == pytest.approx(0.3)  # passed on the right
    side, code, still = decide(ObstaclePolicy(moving_obstacles=False))
    assert still.vehicle_ids == ("lead",) and np.all(still.speed_s_mps == 0.0)


# ----------------------------------------------------------------------- avoidance
@pytest.mark.parametrize("pass_side", [1, -1])
def test_straight_stalled_car_passed_on_the_free_side(pass_side: int) -> None:
    run = _run(pass_side=pass_side)
    _assert_safe_and_comfortable(run)
    tr = run.trace
    s = tr.ego.s_m
    y = tr.ego.lat_dev_m  # from the reference: the ego's (home) lane centre
    assert np.all(tr.decision.side[tr.decision.n_obstacles > 0] != Side.FOLLOW)
    at_obstacle = np.argmin(np.abs(s - STALLED_S))
    assert pass_side * y[at_obstacle] > 1.5  # beside the car, on the free side
    assert np.max(np.abs(y[tr.t_s > tr.t_s[-1] - 1.0])) < 0.3  # back in its lane
    assert np.all(tr.controller.fallback == 0)
    assert np.max(tr.controller.residual) < 5.0
    assert tr.ego.speed_mps[-1] == pytest.approx(25.0, abs=0.5)


def test_curved_road_with_stalled_car() -> None:
    run = _run(reference=CURVE, stalled_s=CURVE_STALLED_S, duration=18.0)
    _assert_safe_and_comfortable(run)
    tr = run.trace
    s, y = tr.ego.s_m, tr.ego.lat_dev_m
    before = s < 90.0
    assert np.max(np.abs(y[(s > 20.0) & before])) < 0.1  # lane keeping on the curve
    assert y[np.argmin(np.abs(s - CURVE_STALLED_S))] > 1.5
    assert np.max(np.abs(y[tr.t_s > tr.t_s[-1] - 1.0])) < 0.3
    assert np.all(tr.controller.fallback == 0)


def test_slower_moving_car_overtaken() -> None:
    run = run_plant(make_two_loop({}), road(), (ScriptedVehicle("lead", 60.0, 0, 15.0),),
                    duration_s=14.0, step_s=DT)
    _assert_safe_and_comfortable(run)
    tr = run.trace
    gap = tr.ego.s_m - (60.0 + 15.0 * tr.t_s)
    assert gap[-1] > 30.0  # overtaken
    assert np.all(tr.controller.fallback == 0)


def test_follow_mode_stops_behind_blocking_car() -> None:
    """One lane, a stalled car 150 m ahead: no side is free, production's behaviour
    follows (FOLLOW: no pass side, the car's ellipse a wall across the road, the speed
    target its car-following law) and the ego stops behind it, in its lane."""
    v0 = 20.0
    # 25 s (was 20 s): production's following law closes the last metres to its
    # standstill gap asymptotically (0.14 m/s left at 20 s, 0.05 m/s at 24 s).
    run = run_plant(make_two_loop({}), road(STRAIGHT, 1), (stalled(STALLED_S),),
                    duration_s=25.0, step_s=DT, start=PlantStart(speed_mps=v0),
                    set_speed_mps=v0)
    tr = run.trace
    assert not tr.safety.geom_collision.any()
    assert np.all(tr.decision.side[tr.decision.n_obstacles > 0] == Side.FOLLOW)
    # CG outside the ellipse with the policy's margins. The margin-free one is 21 m
    # long since the ellipses contain the box-sum rectangle (a 0.05 m lateral margin
    # floor): stopping 1-15 m behind is inside it by design.
    assert np.min(run.ellipse_values(margins=True)) > 0.0
    assert tr.ego.speed_mps[-1] < 0.1
    assert np.max(np.abs(tr.ego.lat_dev_m)) < 0.2  # stays in its lane
    gap = STALLED_S - 2.4 - (tr.ego.s_m[-1] + VehicleParams().cg_to_front_bumper_m)
    assert 1.0 < gap < 15.0
    assert np.min(tr.ego.long_acc_mps2) >= LONG_ACC[0]
    assert np.all(np.isfinite(tr.ego.steer_rad))


# ---------------------------------------------------------------- paper's results
def test_j1_chatters_more_than_j3() -> None:
    """Paper result 1 (Figs. 9-10): J1 violates the smoothness condition and chatters.

    Chatter measure: RMS of the steering's second difference / dt² [rad/s²] while the
    obstacle is in view (see ``steering_chatter``). E is reported, not asserted: with
    our weights and row scaling J1's residual is *not* larger than J3's (see report).
    """
    out = {}
    for cost in ("J1", "J3"):
        tr = _run(outer={"cost": cost}, duration=10.0).trace
        in_view = np.abs(STALLED_S - tr.ego.s_m) < 80.0
        out[cost] = (steering_chatter(tr.ego.steer_rad, DT, in_view),
                     float(np.max(tr.controller.residual)))
        assert not tr.safety.geom_collision.any()
    assert out["J3"][0] < 0.25 * out["J1"][0], out


def _preview_runs(feedforward: bool) -> dict[bool, dict[str, float]]:
    """Curve (R = 400 m), stalled car at 300 m, J3, preview off / on: the RMS of the
    lateral tracking error y_car(t + 0.5 s) - y_plan(t)(0.5 s) (``PlantRun.
    plan_tracking_error``) over the run and on the curve before the pass (20-90 m), the
    largest offset there and the peak lateral acceleration."""
    res = {}
    for preview in (False, True):
        run = _run(reference=CURVE, stalled_s=CURVE_STALLED_S, duration=16.0,
                   inner={"preview": preview, "feedforward": feedforward})
        tr = run.trace
        err = run.plan_tracking_error(0.5)
        pre = (tr.ego.s_m > 20.0) & (tr.ego.s_m < 90.0)
        res[preview] = {
            "rms": float(np.sqrt(np.nanmean(err**2))),
            "rms_pre": float(np.sqrt(np.nanmean(err[pre] ** 2))),
            "offset_pre": float(np.max(np.abs(tr.ego.lat_dev_m[pre]))),
            "lat": float(np.max(np.abs(tr.ego.lat_acc_mps2))),
        }
        assert not tr.safety.geom_collision.any()
    return res


def test_preview_lowers_plan_tracking_error_on_curve() -> None:
    """Paper result 2 (Figs. 11-13), the paper's setting (conversion (13) only, no
    feed-forward): on the curve before the obstacle the car without preview settles
    0.86 m outside the lane centre, with preview within 0.3 m, and its tracking error
    there is less than half."""
    res = _preview_runs(feedforward=False)
    on, off = res[True], res[False]
    assert on["rms_pre"] < 0.5 * off["rms_pre"], res
    assert on["offset_pre"] < 0.3 < 0.6 < off["offset_pre"], res


def test_preview_lowers_plan_tracking_error_with_feedforward() -> None:
    """The production setting (feed-forward on), #33 item 6: the preview lowers the
    tracking error on the curve before the pass, does not raise the peak lateral
    acceleration, and the whole run's (pass and return included) plan-tracking RMS is
    that of the run without it (within 3 %: 0.0135 against 0.0133 m, a fifth of a
    millimetre; while the plan moves across the road the corrections act only beyond
    the band). Before the lane-holding weight (tracker docstring) the integral charged
    during the pass kept steering after it: whole run 0.029 against 0.013 m (×2.2),
    peak 3.01 against 2.96 m/s²."""
    res = _preview_runs(feedforward=True)
    on, off = res[True], res[False]
    assert on["rms_pre"] < 0.85 * off["rms_pre"], res
    assert on["lat"] <= off["lat"], res
    assert on["rms"] <= 1.03 * off["rms"], res


def test_the_preview_keeps_a_chattering_plan_on_the_road() -> None:
    """The J1 cost's heading chatters; without the preview the car leaves the road on
    the pass (11 m off its lane, the road is 7 m wide). The lane-holding weight must not
    switch the correction of such a plan off: with the preview it passes within the
    two lanes, no contact (3.5 m off; with the band so wide that the proportional part
    is off during the pass, 10.7 m off, as without the preview: 10.9 m)."""
    run = _run(outer={"cost": "J1"}, duration=10.0)
    tr = run.trace
    assert not tr.safety.geom_collision.any()
    assert float(np.max(np.abs(tr.ego.lat_dev_m))) < 3.5 + 0.6


# ------------------------------------------------------------------ robustness
class _NanOuter:
    """A planner that returns garbage: the controller must never emit NaN."""

    updates_per_period = 1

    def __init__(self, path: FrenetPath, n_slots: int) -> None:
        self.n = TwoLoopParams().outer.n_stages
        self.restarts = 0

    def horizon_growth(self, elapsed_s: float) -> float:
        return 1.0

    def reset(self, x0: np.ndarray, target_speed_mps: float) -> None:
        pass

    def restart(self, x0: np.ndarray, target_speed_mps: float,
                target_accel_mps2: float = 0.0) -> None:
        self.restarts += 1

    def update(self, t_s: float, x0: np.ndarray, obstacles: Obstacles,
               target_speed_mps: float, dt_s: float,
               lateral_reference_m: float = 0.0,
               lateral_weight: float | None = None) -> OuterPlan:
        tau = np.linspace(0.0, 2.4, self.n + 1)
        return OuterPlan(tau, np.full((self.n + 1, 3), np.nan), np.full(self.n, np.nan),
                         np.full(self.n, np.nan), math.nan, False, 0, 0.0)


def test_never_nan_and_custom_planner_factory() -> None:
    ctl = TwoLoopController(TwoLoopParams(), planner_factory=_NanOuter)
    tr = run_plant(ctl, road(), duration_s=1.0, step_s=DT).trace
    assert np.all(np.isfinite(tr.ego.steer_rad)) and np.all(np.isfinite(tr.ego.torque_nm))
    assert np.all(tr.controller.fallback)
    assert tr.ego.speed_mps[-1] < 25.0  # it brakes
    assert type(ctl.planner) is _NanOuter  # the factory's planner, not the default


def test_command_contents() -> None:
    ctl = make_two_loop({"inner": {"n_preview": 8}})
    run = run_plant(ctl, road(), (stalled(STALLED_S),), duration_s=0.5, step_s=DT)
    for key in ("outer_s", "inner_s", "residual", "guard_fired", "steer_outer_rad",
                "steer_corr_rad", "torque_outer_nm", "torque_corr_nm", "planned_speed_mps",
                "preview_err_t_m", "preview_err_n_m", "outer_updates", "lateral_ref_m",
                "lateral_ref_rate_mps", "lateral_weight"):
        assert np.all(np.isfinite(run.diagnostic(key))), key
    assert not run.trace.controller.fallback.any()
    assert ctl.plan is not None and ctl.plan.states.shape == (21, 3)
    e = run.trace.ego
    state = np.array([e.x_m[-1], e.y_m[-1], e.psi_rad[-1], e.u_mps[-1], e.v_mps[-1],
                      e.r_radps[-1]])
    cmd = ctl.step(Observation(t_s=0.52, state=state, target_speed_mps=25.0))
    assert type(cmd.diagnostics) is ctl.diagnostics_type  # what it declares it returns
    assert cmd.plan_xy_m is not None and cmd.plan_xy_m.shape == (21, 2)
    assert cmd.preview_xy_m is not None and cmd.preview_xy_m.shape == (9, 2)
    assert np.all(np.isfinite(cmd.plan_xy_m))
    assert run.arrays.plan_xy_m.shape == (25, 21, 2)  # every step's plan, recorded


# ------------------------------------------------------------ lateral reference
def test_lateral_reference_step_is_smoothed() -> None:
    """A step in lateral_reference_m (empty road, the decision given: 3.5 m from 1 s to
    7 s) reaches the OCP as a smooth ramp: yr is continuous with |yr'| <=
    lateral_ref_rate_mps, C/GMRES's E stays at its stationary level (no residual jump),
    Cy blends to c_y_lateral_ref, and the car settles on yr."""
    params = TwoLoopParams()
    lat = params.lateral
    schedule = DecisionSchedule(lambda t: (Side.LEFT, 3.5 if 1.0 <= t < 7.0 else 0.0))
    run = run_plant(TwoLoopController(params), road(), duration_s=13.0, step_s=DT,
                    decisions=schedule)
    yr, t = run.diagnostic("lateral_ref_m"), run.trace.t_s - DT  # t: when it was decided
    rate = np.diff(yr) / DT
    # (<= 1 % over: the semi-implicit Euler sub-steps of the filter)
    assert np.max(np.abs(rate)) <= lat.rate_mps * 1.01
    assert np.max(np.abs(np.diff(rate))) / DT < 3.0 * lat.rate_mps / (
        lat.filter_s)  # yr' continuous (bounded yr'')
    assert yr[t < 1.0].max() == 0.0 and abs(yr[np.argmin(np.abs(t - 6.9))] - 3.5) < 1e-3
    assert abs(yr[-1]) < 1e-3
    assert np.max(run.trace.controller.residual) < 0.03  # a raw step gives E ~ 0.2
    weight = run.diagnostic("lateral_weight")
    assert weight.max() == pytest.approx(lat.c_y_engaged)
    assert weight[-1] == pytest.approx(params.outer.c_y)
    y = run.trace.ego.lat_dev_m
    assert np.max(np.abs(y[(t > 6.0) & (t < 7.0)] - 3.5)) < 0.1
    assert np.max(np.abs(y[t > 12.0])) < 0.1
    assert np.max(np.abs(run.trace.ego.lat_acc_mps2)) < 2.0


# Peak |lateral acceleration| allowed in the pass runs: headroom under nuPlan's
# 4.89 m/s² (see the report for the values reached).
LAT_ACC_PASS = 4.0


@pytest.mark.parametrize("curve", [False, True], ids=["straight", "curve"])
@pytest.mark.parametrize("speed", [20.0, 25.0, 30.0])
def test_pass_stalled_car_with_lateral_reference(curve: bool, speed: float) -> None:
    """Production's pass: a stalled car in the ego lane 150 m ahead, the left lane free;
    the behaviour sets yr = +3.5 m (the left lane's centre) and back to 0 once the car
    is passed. No box overlap, CG never inside the margin-free ellipse, comfortable
    (|lat acc| <= 4.0, long acc in nuPlan's range, |yaw rate| <= 0.95), settled within
    0.3 m of the target lane before the reference returns, back within 0.3 m of the
    lane centre at the end."""
    # On the curve the car stands at 300 m: production starts the pass as soon as the
    # car is within its planning range, and at 150 m that would be at t = 0, before the
    # car (started with no yaw rate) has settled on the curve (5.3 m/s² at 30 m/s).
    obstacle_s = CURVE_STALLED_S if curve else STALLED_S
    duration = (obstacle_s + 15.0 + 8.0 * speed) / speed + 1.0
    run = run_plant(make_two_loop({}), road(CURVE if curve else STRAIGHT),
                    (stalled(obstacle_s),), duration_s=duration, step_s=DT,
                    start=PlantStart(speed_mps=speed), set_speed_mps=speed)
    tr = run.trace
    assert not tr.safety.geom_collision.any()
    assert np.min(run.ellipse_values()) > 0.0
    assert np.max(np.abs(tr.ego.lat_acc_mps2)) <= LAT_ACC_PASS
    acc = tr.ego.long_acc_mps2
    assert LONG_ACC[0] <= np.min(acc) and np.max(acc) <= LONG_ACC[1]
    assert np.max(np.abs(tr.ego.r_radps)) <= YAW_RATE
    assert np.all(tr.controller.fallback == 0)
    t, y = tr.t_s, tr.ego.lat_dev_m
    raw = tr.decision.lat_ref_m
    assert raw.max() == LANE and raw[-1] == 0.0
    k_out = int(np.argmax(raw == LANE))
    t_release = t[k_out + int(np.argmax(raw[k_out:] == 0.0))]
    hold = (t > t_release - 0.5) & (t <= t_release)
    assert np.max(np.abs(y[hold] - LANE)) <= 0.3
    assert np.max(np.abs(y[t > t[-1] - 1.0])) <= 0.3
    assert tr.ego.speed_mps[-1] == pytest.approx(speed, abs=0.5)


def test_lateral_reference_waits_for_speed() -> None:
    """At standstill (stopped behind a blocker until the neighbour lane clears) yr does
    not move: its rate is at most V lateral_ref_heading_rad."""
    run = run_plant(make_two_loop({}), road(), duration_s=1.0, step_s=DT,
                    start=PlantStart(speed_mps=0.0), set_speed_mps=0.0,
                    decisions=DecisionSchedule(lambda t: (Side.LEFT, 3.5)))
    assert np.max(np.abs(run.diagnostic("lateral_ref_m"))) < 1e-9
    assert np.all(np.isfinite(run.trace.ego.steer_rad))
    assert np.all(run.trace.controller.fallback == 0)
    assert run.diagnostic("lateral_weight")[-1] == pytest.approx(
        TwoLoopParams().lateral.c_y_engaged)


# ------------------------------------------------------------- typed diagnostics
def test_step_sets_every_diagnostic_field(monkeypatch: pytest.MonkeyPatch) -> None:
    """step() names every field of TwoLoopDiagnostics (none left at its default by
    omission), and over a launch + pass run each field other than the rare-event ones
    takes a value other than its default at some step."""
    import dataclasses

    import controllers.two_loop.controller as controller_module

    given: list[set[str]] = []

    def recording(**kwargs: object) -> TwoLoopDiagnostics:
        given.append(set(kwargs))
        return TwoLoopDiagnostics(**kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(controller_module, "TwoLoopDiagnostics", recording)
    names = {f.name for f in dataclasses.fields(TwoLoopDiagnostics)}
    # Standing start behind a stalled car 120 m ahead, the left lane free: launch,
    # hand-over, then the two-loop controller with a moving lateral reference (the
    # behaviour's pull-out to pass) and an obstacle.
    run = run_plant(make_two_loop({}), road(), (stalled(120.0),), duration_s=8.0, step_s=DT,
                    start=PlantStart(speed_mps=0.0), set_speed_mps=22.0)
    assert given and all(g == names for g in given), names - set.intersection(*given)
    # Defaults are NaN, 0 or False: finite and non-zero at some step is set for real.
    rare = {"fallback", "guard_fired", "mrm", "emergency", "emergency_decel_mps2",
            "emergency_ds_m", "emergency_dy_m", "brake_floor_mps2",
            "brake_source"}  # rare events: not expected here
    for name in names - rare:
        values = run.diagnostic(name)
        assert np.all(np.isfinite(values)), name
        assert np.any(values != 0.0), name
    launch = run.diagnostic("launch")
    assert launch[0] == 1.0 and launch[-1] == 0.0


def test_parameters_round_trip_through_the_factory() -> None:
    """parameters() is the nested dict of the effective parameters; the factory takes it
    back unchanged, and JSON does not change it."""
    ctl = make_two_loop({"outer": {"c_y": 2}, "inner": {"preview": False},
                         "launch_blend_s": 1.0, "policy": {"margin_lat_m": 0.5}})
    params = ctl.parameters()
    assert params["outer"]["c_y"] == 2.0 and isinstance(params["outer"]["c_y"], float)
    assert params["inner"]["preview"] is False and params["launch"]["blend_s"] == 1.0
    assert set(params) == {"name", "outer", "inner", "lateral", "launch", "policy", "fallback",
                           "jerk", "threat"}
    again = make_two_loop(json.loads(json.dumps(params)))
    assert again.params == ctl.params and again.parameters() == params
