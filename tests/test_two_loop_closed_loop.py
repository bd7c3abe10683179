"""Two-loop controller on the plant alone (no SUMO): configuration, obstacle avoidance,
curves, pass side, follow mode, J1 vs J3 (paper result 1), preview on/off (result 2)."""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from controllers.behaviour.ellipses import FrenetVehicle, build_obstacles, ellipse_semi_axes
from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import ConfigError, Controller, Observation, ObstaclePolicy, Obstacles
from controllers.sim.closed_loop import (
    pass_reference,
    plan_tracking_error,
    simulate,
    steering_chatter,
)
from controllers.two_loop.controller import TwoLoopController, make_two_loop
from controllers.two_loop.diagnostics import TwoLoopDiagnostics
from controllers.two_loop.outer.params import CgmresParams
from controllers.two_loop.outer.protocol import OuterPlan
from controllers.two_loop.params import TwoLoopParams

DT = 0.02
STRAIGHT = np.array([[0.0, 0.0], [1500.0, 0.0]])
_th = np.linspace(0.0, 1.5, 300)
CURVE = np.column_stack([400.0 * np.sin(_th), 400.0 * (1.0 - np.cos(_th))])  # left, R = 400
STALLED = [FrenetVehicle(150.0, 0.0)]

# nuPlan comfort limits.
LAT_ACC = 4.89
LONG_ACC = (-4.05, 2.40)
YAW_RATE = 0.95


def _run(road: np.ndarray = STRAIGHT, pass_side: int = 1, duration: float = 14.0,
         vehicles: list[FrenetVehicle] | None = None, **sections: object) -> dict:
    """Closed loop with ``sections`` as the catalog's nested tables (outer={...}, ...)."""
    ctl = make_two_loop(dict(sections))
    return simulate(ctl, road, STALLED if vehicles is None else vehicles,
                    duration_s=duration, dt=DT, pass_side=pass_side)


def _assert_safe_and_comfortable(tr: dict) -> None:
    assert not tr["box_overlap"].any()
    assert np.min(tr["ellipse_c"]) > 0.0  # CG never inside the margin-free ellipse
    assert np.max(np.abs(tr["lat_acc_mps2"])) <= LAT_ACC
    assert LONG_ACC[0] <= np.min(tr["long_acc_mps2"]) and np.max(tr["long_acc_mps2"]) <= LONG_ACC[1]
    assert np.max(np.abs(tr["yaw_rate_radps"])) <= YAW_RATE
    assert np.all(np.isfinite(tr["steer_rad"])) and np.all(np.isfinite(tr["torque_nm"]))


# ----------------------------------------------------------------------------- config
def test_make_two_loop_validates_options() -> None:
    t0 = time.perf_counter()
    ctl = make_two_loop({"name": "two_loop", "outer": {"cost": "J3", "n_stages": 20,
                                                       "horizon_s": 2.4, "k_max": 16},
                         "inner": {"preview": True}, "policy": {"margin_lat_m": 0.5}})
    assert time.perf_counter() - t0 < 0.05  # cheap: nothing compiled or solved
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
    pol = ObstaclePolicy(margin_long_m=2.0, margin_lat_m=0.4, offset_m=0.3,
                         detection_distance_m=80.0, max_obstacles=2)
    ego = VehicleParams()
    a, b = ellipse_semi_axes(4.0, 1.8, ego.length_m, ego.width_m, pol)
    # The ellipse contains the box-sum rectangle (corner (2.0 + 2.4, 0.9 + 0.95) on it
    # before the margins): see controllers.behaviour.ellipses.
    b0 = 0.9 + 0.95 + 0.4
    a0 = (2.0 + 2.4) / math.sqrt(1.0 - ((0.9 + 0.95) / b0) ** 2)
    assert (a, b) == pytest.approx((a0 + 2.0, b0 + 0.3))
    vehs = [FrenetVehicle(200.0, 0.0), FrenetVehicle(60.0, 0.0), FrenetVehicle(40.0, 3.5),
            FrenetVehicle(-20.0, 0.0), FrenetVehicle(50.0, -3.5, speed_s_mps=20.0)]
    obs = build_obstacles(0.0, 0.0, vehs, pol, ego, pass_side=1)
    assert obs.count == 2  # nearest two within 80 m, not 20 m behind
    assert obs.s_m[0] == 40.0 and obs.y_m[0] == pytest.approx(3.5 - 0.3)
    assert obs.s_m[1] == 50.0 and obs.speed_s_mps[1] == 20.0
    still = build_obstacles(0.0, 0.0, vehs, ObstaclePolicy(moving_obstacles=False), ego, -1)
    assert np.all(still.speed_s_mps == 0.0) and 50.0 not in still.s_m
    assert still.y_m[list(still.s_m).index(60.0)] == pytest.approx(0.3)  # pass right


# ----------------------------------------------------------------------- avoidance
@pytest.mark.parametrize("pass_side", [1, -1])
def test_straight_stalled_car_passed_on_the_requested_side(pass_side: int) -> None:
    tr = _run(pass_side=pass_side)
    _assert_safe_and_comfortable(tr)
    s, y = tr["s_m"], tr["y_m"]
    at_obstacle = np.argmin(np.abs(s - 150.0))
    assert pass_side * y[at_obstacle] > 1.5  # beside the car, on the requested side
    after = s > 150.0 + 100.0
    assert after.any() and np.max(np.abs(y[after])) < 0.3  # back in the lane centre
    assert np.all(tr["fallback"] == 0)
    assert np.max(tr["residual"]) < 5.0
    assert tr["speed_mps"][-1] == pytest.approx(25.0, abs=0.5)


def test_curved_road_with_stalled_car() -> None:
    tr = _run(road=CURVE)
    _assert_safe_and_comfortable(tr)
    s, y = tr["s_m"], tr["y_m"]
    before = s < 90.0
    assert np.max(np.abs(y[(s > 20.0) & before])) < 0.1  # lane keeping on the curve
    assert y[np.argmin(np.abs(s - 150.0))] > 1.5
    assert np.max(np.abs(y[s > 250.0])) < 0.3
    assert np.all(tr["fallback"] == 0)


def test_slower_moving_car_overtaken() -> None:
    lead = [FrenetVehicle(60.0, 0.0, speed_s_mps=15.0)]

    def moving(t: float) -> list[FrenetVehicle]:
        return [FrenetVehicle(v.s_m + v.speed_s_mps * t, v.y_m, speed_s_mps=v.speed_s_mps)
                for v in lead]

    ctl = make_two_loop({})
    tr = simulate(ctl, STRAIGHT, moving, duration_s=14.0, dt=DT, pass_side=1)
    _assert_safe_and_comfortable(tr)
    gap = tr["s_m"] - (60.0 + 15.0 * tr["t_s"])
    assert gap[-1] > 30.0  # overtaken
    assert np.all(tr["fallback"] == 0)


def test_follow_mode_stops_behind_blocking_car() -> None:
    # No side is free (pass_side 0: no offset, the ellipse sits on the lane): the runner
    # lowers the target speed along its comfortable follow profile (behaviour.gap).
    from follow_profiles import stop_behind_profile

    v0 = 20.0
    ctl = make_two_loop({})

    def follow(t: float, s: float) -> float:
        bumper_gap = 150.0 - 2.4 - (s + VehicleParams().cg_to_front_bumper_m)
        return stop_behind_profile(max(bumper_gap, 0.0), 0.0, v0)

    tr = simulate(ctl, STRAIGHT, STALLED, duration_s=20.0, dt=DT, pass_side=0,
                  initial_speed_mps=v0, target_speed_fn=follow)
    assert not tr["box_overlap"].any()
    # CG outside the controller's own ellipse (policy margins). The margin-free one
    # (``ellipse_c``) is 21 m long since the ellipses contain the box-sum rectangle
    # (a 0.05 m lateral margin floor): stopping 1-15 m behind is inside it by design.
    assert np.min(tr["ellipse_c_margin"]) > 0.0
    assert tr["speed_mps"][-1] < 0.1
    assert np.max(np.abs(tr["y_m"])) < 0.2  # stays in its lane
    ego = VehicleParams()
    gap = 150.0 - 2.4 - (tr["s_m"][-1] + ego.cg_to_front_bumper_m)
    assert 1.0 < gap < 15.0
    assert np.min(tr["long_acc_mps2"]) >= LONG_ACC[0]
    assert np.all(np.isfinite(tr["steer_rad"]))


# ---------------------------------------------------------------- paper's results
def test_j1_chatters_more_than_j3() -> None:
    """Paper result 1 (Figs. 9-10): J1 violates the smoothness condition and chatters.

    Chatter measure: RMS of the steering's second difference / dt² [rad/s²] while the
    obstacle is in view (see ``steering_chatter``). E is reported, not asserted: with
    our weights and row scaling J1's residual is *not* larger than J3's (see report).
    """
    out = {}
    for cost in ("J1", "J3"):
        tr = _run(outer={"cost": cost}, duration=10.0)
        in_view = np.abs(150.0 - tr["s_m"]) < 80.0
        out[cost] = (steering_chatter(tr["steer_rad"], DT, in_view), float(np.max(tr["residual"])))
        assert not tr["box_overlap"].any()
    assert out["J3"][0] < 0.25 * out["J1"][0], out


def test_preview_lowers_plan_tracking_error_on_curve() -> None:
    """Paper result 2 (Figs. 11-13): curve (R = 400 m) + obstacle, J3, preview on vs off.

    Lateral tracking error: y_car(t + 0.5 s) - y_plan(t)(0.5 s), RMS (see
    ``plan_tracking_error``). Production setting (feed-forward on): over the whole run,
    and the peak lateral acceleration. Paper's setting (conversion (13) only, no
    feed-forward): on the curve before the obstacle, where the car without preview
    settles 0.86 m outside the lane centre (with the obstacle it then stops in front of
    it instead of passing: a local solution of the nonconvex plan; see the report).
    """
    res = {}
    for ff in (False, True):
        for preview in (False, True):
            tr = _run(road=CURVE, inner={"preview": preview, "feedforward": ff})
            err = plan_tracking_error(tr, 0.5)
            pre = (tr["s_m"] > 20.0) & (tr["s_m"] < 90.0)
            res[(ff, preview)] = {
                "rms": float(np.sqrt(np.nanmean(err**2))),
                "rms_pre": float(np.sqrt(np.nanmean(err[pre] ** 2))),
                "offset_pre": float(np.max(np.abs(tr["y_m"][pre]))),
                "lat": float(np.max(np.abs(tr["lat_acc_mps2"]))),
            }
            assert not tr["box_overlap"].any()
    on, off = res[(True, True)], res[(True, False)]
    assert on["rms"] < 0.75 * off["rms"], res
    assert on["lat"] <= off["lat"], res
    on, off = res[(False, True)], res[(False, False)]
    assert on["rms_pre"] < 0.5 * off["rms_pre"], res
    assert on["offset_pre"] < 0.3 < 0.6 < off["offset_pre"], res


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
    tr = simulate(ctl, STRAIGHT, [], duration_s=1.0, dt=DT)
    assert np.all(np.isfinite(tr["steer_rad"])) and np.all(np.isfinite(tr["torque_nm"]))
    assert np.all(tr["fallback"] == 1.0)
    assert tr["speed_mps"][-1] < 25.0  # it brakes
    assert isinstance(ctl.path, FrenetPath) and isinstance(ctl.planner, _NanOuter)


def test_command_contents() -> None:
    ctl = make_two_loop({"inner": {"n_preview": 8}})
    tr = simulate(ctl, STRAIGHT, [(150.0, 0.0, 4.8, 1.9)], duration_s=0.5, dt=DT)
    for key in ("outer_s", "inner_s", "residual", "fallback", "guard_fired", "steer_outer_rad",
                "steer_corr_rad", "torque_outer_nm", "torque_corr_nm", "planned_speed_mps",
                "preview_err_t_m", "preview_err_n_m", "outer_updates", "lateral_ref_m",
                "lateral_ref_rate_mps", "lateral_weight"):
        assert key in tr and np.all(np.isfinite(tr[key])), key
    assert ctl.plan is not None and ctl.plan.states.shape == (21, 3)
    cmd = ctl.step(Observation(t_s=0.52, state=tr["state"][-1], target_speed_mps=25.0))
    assert isinstance(cmd.diagnostics, TwoLoopDiagnostics)
    assert cmd.plan_xy_m is not None and cmd.plan_xy_m.shape == (21, 2)
    assert cmd.preview_xy_m is not None and cmd.preview_xy_m.shape == (9, 2)
    assert np.all(np.isfinite(cmd.plan_xy_m))



# ------------------------------------------------------------ lateral reference
def test_lateral_reference_step_is_smoothed() -> None:
    """The runner's step in lateral_reference_m reaches the OCP as a smooth ramp: yr is
    continuous with |yr'| <= lateral_ref_rate_mps, C/GMRES's E stays at its stationary
    level (no residual jump), Cy blends to c_y_lateral_ref, and the car settles on yr."""
    params = TwoLoopParams()
    lat = params.lateral

    def lateral(t: float, s: float, y: float) -> tuple[int, float]:
        return 1, (3.5 if 1.0 <= t < 7.0 else 0.0)

    tr = simulate(TwoLoopController(params), STRAIGHT, [], duration_s=13.0, dt=DT,
                  lateral_fn=lateral)
    yr, t = tr["lateral_ref_m"], tr["t_s"]
    rate = np.diff(yr) / DT
    # (<= 1 % over: the semi-implicit Euler sub-steps of the filter)
    assert np.max(np.abs(rate)) <= lat.rate_mps * 1.01
    assert np.max(np.abs(np.diff(rate))) / DT < 3.0 * lat.rate_mps / (
        lat.filter_s)  # yr' continuous (bounded yr'')
    assert yr[t < 1.0].max() == 0.0 and abs(yr[np.argmin(np.abs(t - 6.9))] - 3.5) < 1e-3
    assert abs(yr[-1]) < 1e-3
    assert np.max(tr["residual"]) < 0.03  # a raw step gives E ~ 0.2 (test_cgmres)
    assert tr["lateral_weight"].max() == pytest.approx(lat.c_y_engaged)
    assert tr["lateral_weight"][-1] == pytest.approx(params.outer.c_y)
    y = tr["y_m"]
    assert np.max(np.abs(y[(t > 6.0) & (t < 7.0)] - 3.5)) < 0.1
    assert np.max(np.abs(y[t > 12.0])) < 0.1
    assert np.max(np.abs(tr["lat_acc_mps2"])) < 2.0


# Peak |lateral acceleration| allowed in the pass-with-reference runs: headroom under
# nuPlan's 4.89 m/s² (see the report for the values reached).
LAT_ACC_PASS = 4.0
LANE = 3.5
RELEASE_PAST_M = 15.0


def stretch_s(ctl: object, speed: float, kappa: float) -> float:
    """How much longer [s] the lateral-reference shaper takes for the lane's move on a
    curve of curvature ``kappa`` than on a straight road at ``speed``: its ramp rate is
    bounded by what v² kappa leaves of the lateral acceleration (two_loop/lateral.py),
    so a pass on a curve is stretched and the emulated behaviour holds the pass lane
    that much longer (the behaviour layer plans the stretch the same way)."""
    from controllers.two_loop.lateral import LateralReferenceShaper

    p = ctl.params.lateral  # type: ignore[attr-defined]
    shaper = LateralReferenceShaper(p)
    nominal = min(p.rate_mps, speed * p.heading_rad)
    shaper.update(0.0, None, 0.0, speed, 1.0, curvature_1pm=kappa)
    curved = min(nominal, shaper.move_rate_bound_mps(speed))
    return LANE / curved - LANE / nominal


@pytest.mark.parametrize("road", ["straight", "curve"])
@pytest.mark.parametrize("speed", [20.0, 25.0, 30.0])
def test_pass_stalled_car_with_lateral_reference(road: str, speed: float) -> None:
    """The runner's product fix, emulated: yr = +3.5 m (pass_side +1) from the moment the
    stalled car (in the ego lane, 150 m ahead) is detected until the ego is 15 m past
    it, then 0. No box overlap, CG never inside the margin-free ellipse, comfortable
    (|lat acc| <= 4.0, long acc in nuPlan's range, |yaw rate| <= 0.95), settled within
    0.3 m of the target lane before the reference is reset, back within 0.3 m of the
    lane centre at the end."""
    obstacle_s = 150.0
    ctl = make_two_loop({})
    release_m = RELEASE_PAST_M + speed * stretch_s(ctl, speed, 0.0 if road == "straight"
                                                    else 1.0 / 400.0)
    fn = pass_reference(obstacle_s, 1, LANE, ctl.params.policy.detection_distance_m,
                        release_m)
    duration = (obstacle_s + RELEASE_PAST_M + 8.0 * speed) / speed + 1.0
    tr = simulate(ctl, STRAIGHT if road == "straight" else CURVE,
                  [FrenetVehicle(obstacle_s, 0.0)], duration_s=duration, dt=DT,
                  initial_speed_mps=speed, target_speed_mps=speed, lateral_fn=fn)
    assert not tr["box_overlap"].any()
    assert np.min(tr["ellipse_c"]) > 0.0
    assert np.max(np.abs(tr["lat_acc_mps2"])) <= LAT_ACC_PASS
    assert LONG_ACC[0] <= np.min(tr["long_acc_mps2"]) and np.max(tr["long_acc_mps2"]) <= LONG_ACC[1]
    assert np.max(np.abs(tr["yaw_rate_radps"])) <= YAW_RATE
    assert np.all(tr["fallback"] == 0)
    t, s, y = tr["t_s"], tr["s_m"], tr["y_m"]
    raw = tr["lateral_reference_m"]
    assert raw.max() == LANE and raw[-1] == 0.0
    t_release = t[np.argmax(s > obstacle_s + release_m)]
    hold = (t > t_release - 0.5) & (t <= t_release)
    assert np.max(np.abs(y[hold] - LANE)) <= 0.3
    assert np.max(np.abs(y[t > t[-1] - 1.0])) <= 0.3
    assert tr["speed_mps"][-1] == pytest.approx(speed, abs=0.5)


def test_lateral_reference_waits_for_speed() -> None:
    """At standstill (stopped behind a blocker until the neighbour lane clears) yr does
    not move: its rate is at most V lateral_ref_heading_rad."""
    tr = simulate(make_two_loop({}), STRAIGHT, [], duration_s=1.0, dt=DT,
                  initial_speed_mps=0.0, target_speed_mps=0.0,
                  lateral_fn=lambda t, s, y: (1, 3.5))
    assert np.max(np.abs(tr["lateral_ref_m"])) < 1e-9
    assert np.all(np.isfinite(tr["steer_rad"])) and np.all(tr["fallback"] == 0)
    assert tr["lateral_weight"][-1] == pytest.approx(TwoLoopParams().lateral.c_y_engaged)


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
    # Standing start with a pull-out to the left lane: launch, hand-over, then the
    # two-loop controller with a moving lateral reference and a car in the other lane.
    tr = simulate(make_two_loop({}), STRAIGHT, [FrenetVehicle(120.0, -3.5)], duration_s=8.0,
                  dt=DT, initial_speed_mps=0.0, target_speed_mps=22.0,
                  lateral_fn=lambda t, s, y: (1, 3.5))
    assert given and all(g == names for g in given), names - set.intersection(*given)
    # Defaults are NaN, 0 or False: finite and non-zero at some step is set for real.
    rare = {"fallback", "guard_fired", "mrm", "emergency", "emergency_decel_mps2",
            "emergency_ds_m", "emergency_dy_m"}  # rare events: not expected here
    for name in names - rare:
        values = tr[name]
        assert np.all(np.isfinite(values)), name
        assert np.any(values != 0.0), name
    assert tr["launch"][0] == 1.0 and tr["launch"][-1] == 0.0


def test_parameters_round_trip_through_the_factory() -> None:
    """parameters() is the nested dict of the effective parameters; the factory takes it
    back unchanged, and JSON does not change it."""
    ctl = make_two_loop({"outer": {"c_y": 2}, "inner": {"preview": False},
                         "launch_blend_s": 1.0, "policy": {"margin_lat_m": 0.5}})
    params = ctl.parameters()
    assert params["outer"]["c_y"] == 2.0 and isinstance(params["outer"]["c_y"], float)
    assert params["inner"]["preview"] is False and params["launch"]["blend_s"] == 1.0
    assert set(params) == {"name", "outer", "inner", "lateral", "launch", "policy", "fallback",
                           "jerk"}
    again = make_two_loop(json.loads(json.dumps(params)))
    assert again.params == ctl.params and again.parameters() == params
