"""Two-loop controller: low-speed launch / standstill handling (controllers.two_loop.launch,
docs/two_loop.md "Launch"), closed loop on the plant (no SUMO).

The SUMO case: the ego follows and stops behind a stalled car (no side free); later a
side frees up, the behaviour passes (pass side +1, lateral reference +3.5 m, the target
speed back up). Here on production's loop without SUMO (suite.run.scripted), the
decisions production's. Without the launch handling C/GMRES at standstill planned negative
speeds (the barrier pushed the plan back), E grew to 15-40 and the car leapt away
(torque saturated, long acc 6.3 m/s², jerk 28 m/s³).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from plant_runs import CURVE, DT, STRAIGHT, road, stalled
from scipy.signal import savgol_filter

from controllers.behaviour.types import Side
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import ConfigError
from controllers.two_loop.controller import make_two_loop
from controllers.two_loop.params import TwoLoopParams
from suite.run.scripted import PlantRun, PlantStart, run_plant

# nuPlan comfort limits.
LAT_ACC = 4.89
LONG_ACC = (-4.05, 2.40)
LONG_JERK = 4.13
OBSTACLE_S = 150.0
# The left lane frees up at 25 s (20 s with the former scripted follow profile):
# production's following law closes the last metres to its standstill gap slowly.
T_FREE = 25.0
LANE = 3.5
EGO = VehicleParams()


def sg_jerk(long_acc: np.ndarray) -> np.ndarray:
    """Longitudinal jerk as the metrics measure it: Savitzky-Golay, order 2, 0.5 s."""
    return savgol_filter(long_acc, 25, 2, deriv=1, delta=DT)


def _bumper_gap(s_cg: np.ndarray | float) -> np.ndarray:
    return OBSTACLE_S - 2.4 - (np.asarray(s_cg) + EGO.cg_to_front_bumper_m)


def _stop_then_pass(reference: np.ndarray, duration: float = 50.0,
                    **options: object) -> PlantRun:
    """Two lanes, both blocked 150 m ahead by stalled cars: production's behaviour
    follows and stops behind the one in the ego lane; at T_FREE the one on the left is
    gone (removed from the scene) and the behaviour passes on the left."""
    cars = (stalled(OBSTACLE_S), stalled(OBSTACLE_S, 1, "blocker", leaves_at_s=T_FREE))
    return run_plant(make_two_loop(dict(options)), road(reference), cars,
                     duration_s=duration, step_s=DT, start=PlantStart(speed_mps=20.0),
                     set_speed_mps=22.0)


@pytest.mark.parametrize("curve", [False, True], ids=["straight", "curve"])
def test_stop_behind_stalled_car_then_launch_and_pass(curve: bool) -> None:
    run = _stop_then_pass(CURVE if curve else STRAIGHT)
    tr = run.trace
    t, s, y, v = tr.t_s, tr.ego.s_m, tr.ego.lat_dev_m, tr.ego.speed_mps
    acc, lat = tr.ego.long_acc_mps2, tr.ego.lat_acc_mps2
    jerk = sg_jerk(acc)
    launch = run.diagnostic("launch")
    assert np.all(np.isfinite(tr.ego.steer_rad)) and np.all(np.isfinite(tr.ego.torque_nm))
    # The stop: behind the car, in the lane, comfortable, the two-loop controller in charge.
    stop = t < T_FREE
    assert np.all(tr.decision.side[stop & (tr.decision.n_obstacles > 0)] == Side.FOLLOW)
    k_stop = np.argmin(np.abs(t - (T_FREE - 0.1)))
    assert v[k_stop] < 0.1
    assert 1.0 < float(_bumper_gap(s[k_stop])) < 15.0
    assert np.max(np.abs(y[stop])) < 0.3
    assert np.min(acc[stop]) >= LONG_ACC[0]
    assert np.max(np.abs(jerk[stop])) <= LONG_JERK
    assert np.all(launch[stop] == 0.0)
    # The launch: engaged at once, handed back to C/GMRES, never again.
    assert launch[np.argmax(t > T_FREE)] == 1.0
    engaged = np.flatnonzero(launch > 0.5)
    assert np.all(np.diff(engaged) == 1)  # one contiguous launch
    t_handover = t[engaged[-1] + 1]
    assert t_handover < T_FREE + 8.0
    # The whole run: no contact, comfortable, no fallback, never NaN.
    assert not tr.safety.geom_collision.any()
    assert LONG_ACC[0] <= np.min(acc) and np.max(acc) <= LONG_ACC[1]
    assert np.max(np.abs(jerk)) <= LONG_JERK
    assert np.max(np.abs(lat)) <= LAT_ACC
    assert np.all(tr.controller.fallback == 0)
    # C/GMRES restarted at the measured state: E small from the hand-over on.
    residual = tr.controller.residual
    after = t >= t_handover
    assert residual[after][0] < 0.1
    assert np.max(residual[after]) < 2.0
    # Smooth hand-over (blend): no torque or steering step.
    k = engaged[-1] + 1
    window = slice(k - 5, k + int(TwoLoopParams().launch.blend_s / DT) + 5)
    assert np.max(np.abs(np.diff(tr.ego.torque_nm[window]))) < 100.0  # N m per 20 ms
    assert np.max(np.abs(np.diff(tr.ego.steer_rad[window]))) < 0.02
    # Back to speed; passed and back in its lane (production returns to the home lane
    # once the car is behind: the scripted decision held the left lane).
    assert v[np.argmin(np.abs(t - (T_FREE + 20.0)))] >= 15.0
    assert np.max(y) > LANE - 0.3
    assert np.max(np.abs(y[t > t[-1] - 2.0])) <= 0.3


def test_launch_from_rest_on_open_road() -> None:
    """Standing start, target 22 m/s, no obstacle: launch, restart, hand-over; the
    ramp's jerk and acceleration limits hold and the car reaches the target."""
    run = run_plant(make_two_loop({}), road(), duration_s=20.0, step_s=DT,
                    start=PlantStart(speed_mps=0.0), set_speed_mps=22.0)
    tr = run.trace
    acc = tr.ego.long_acc_mps2
    assert run.diagnostic("launch")[0] == 1.0 and run.diagnostic("launch")[-1] == 0.0
    assert np.max(acc) <= LONG_ACC[1] and np.min(acc) >= -0.5
    assert np.max(np.abs(sg_jerk(acc))) <= LONG_JERK
    assert np.max(np.abs(tr.ego.lat_dev_m)) < 0.05
    assert np.all(tr.controller.fallback == 0) and np.max(tr.controller.residual) < 0.5
    assert tr.ego.speed_mps[-1] == pytest.approx(22.0, abs=0.5)


def test_launch_holds_brakes_when_target_drops() -> None:
    """Target up (launch engaged), then back to ~0 before the hand-over: the launch ramp
    brakes to a stop and holds it with a negative torque; no creeping."""
    run = run_plant(make_two_loop({}), road(), duration_s=6.0, step_s=DT,
                    start=PlantStart(speed_mps=0.0), set_speed_mps=22.0,
                    set_speed_fn=lambda t: 22.0 if t < 0.6 else 0.0)
    tr = run.trace
    t, v = tr.t_s, tr.ego.speed_mps
    assert np.all(run.diagnostic("launch") == 1.0)  # never reached the hand-over speed
    late = t > 4.0
    assert np.max(v[late]) < 1e-6
    assert np.all(tr.ego.torque_nm[late] < 0.0)
    assert np.min(tr.ego.long_acc_mps2) >= LONG_ACC[0]


def test_launch_not_engaged_at_speed_or_when_disabled() -> None:
    """Cruising is the paper's controller: the launch never engages above standstill."""
    run = run_plant(make_two_loop({}), road(), duration_s=2.0, step_s=DT,
                    start=PlantStart(speed_mps=20.0), set_speed_mps=25.0)
    assert np.all(run.diagnostic("launch") == 0.0)
    assert np.all(run.diagnostic("launch_weight") == 0.0)
    run = run_plant(make_two_loop({"launch": {"enabled": False}}), road(), duration_s=1.0,
                    step_s=DT, start=PlantStart(speed_mps=0.0), set_speed_mps=22.0)
    assert np.all(run.diagnostic("launch") == 0.0)


def test_launch_parameters_validated() -> None:
    cases: list[tuple[dict[str, object], str]] = [
             ({"handover_speed_mps": 0.0}, "controller.launch.handover_speed_mps"),
             ({"engage_speed_mps": 2.0}, "controller.launch.engage_speed_mps"),
             ({"hold_target_mps": 1.6}, "controller.launch.hold_target_mps"),
             ({"max_speed_mps": 1.0}, "controller.launch.max_speed_mps"),
             ({"blend_s": 0.0}, "controller.launch.blend_s"),
             ({"clearance_m": -0.1}, "controller.launch.clearance_m"),
             ({"k_pv": math.nan}, "controller.launch.k_pv"),
             ({"enabled": 1}, "controller.launch.enabled")]
    for opts, key in cases:
        with pytest.raises(ConfigError) as err:
            make_two_loop({"launch": opts})
        assert err.value.key == key, (opts, err.value)
    # The former flat names are aliases of the same options.
    with pytest.raises(ConfigError) as err:
        make_two_loop({"launch": 1})
    assert err.value.key == "controller.launch.enabled"
    ctl = make_two_loop({"launch_speed_mps": 2.5, "launch_blend_s": 1.0})
    assert ctl.parameters()["launch"]["handover_speed_mps"] == 2.5
    assert ctl.params.launch == make_two_loop(
        {"launch": {"handover_speed_mps": 2.5, "blend_s": 1.0}}).params.launch
