"""Two-loop controller: low-speed launch / standstill handling (controllers.two_loop.launch,
docs/two_loop.md "Launch"), closed loop on the plant (no SUMO).

The SUMO case: the ego follows and stops behind a stalled car (no side free); later a
side frees up, the runner sets pass_side +1, lateral_reference_m +3.5 m and the target
speed back up. Without the launch handling C/GMRES at standstill planned negative
speeds (the barrier pushed the plan back), E grew to 15-40 and the car leapt away
(torque saturated, long acc 6.3 m/s², jerk 28 m/s³).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from follow_profiles import stop_behind_profile
from scipy.signal import savgol_filter

from controllers.behaviour.ellipses import FrenetVehicle
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import ConfigError
from controllers.sim.closed_loop import FOLLOW_SIDE, simulate
from controllers.two_loop.controller import make_two_loop
from controllers.two_loop.params import TwoLoopParams

DT = 0.02
STRAIGHT = np.array([[0.0, 0.0], [1500.0, 0.0]])
_th = np.linspace(0.0, 1.5, 300)
CURVE = np.column_stack([400.0 * np.sin(_th), 400.0 * (1.0 - np.cos(_th))])  # left, R = 400
# nuPlan comfort limits.
LAT_ACC = 4.89
LONG_ACC = (-4.05, 2.40)
LONG_JERK = 4.13
OBSTACLE_S = 150.0
T_FREE = 20.0
LANE = 3.5
EGO = VehicleParams()


def sg_jerk(long_acc: np.ndarray) -> np.ndarray:
    """Longitudinal jerk as the metrics measure it: Savitzky-Golay, order 2, 0.5 s."""
    return savgol_filter(long_acc, 25, 2, deriv=1, delta=DT)


def _bumper_gap(s_cg: np.ndarray | float) -> np.ndarray:
    return OBSTACLE_S - 2.4 - (np.asarray(s_cg) + EGO.cg_to_front_bumper_m)


def _stop_then_pass(road: np.ndarray, duration: float = 45.0, **options: object) -> dict:
    """Follow (no side free, the runner's follow profile) until T_FREE, then pass left."""

    def target(t: float, s: float) -> float:
        if t >= T_FREE:
            return 22.0
        return stop_behind_profile(max(float(_bumper_gap(s)), 0.0), 0.0, 20.0)

    def lateral(t: float, s: float, y: float) -> tuple[int, float]:
        return (1, LANE) if t >= T_FREE else (FOLLOW_SIDE, 0.0)

    return simulate(make_two_loop(dict(options)), road, [FrenetVehicle(OBSTACLE_S, 0.0)],
                    duration_s=duration, dt=DT, initial_speed_mps=20.0, target_speed_mps=22.0,
                    target_speed_fn=target, lateral_fn=lateral)


@pytest.mark.parametrize("road", ["straight", "curve"])
def test_stop_behind_stalled_car_then_launch_and_pass(road: str) -> None:
    tr = _stop_then_pass(STRAIGHT if road == "straight" else CURVE)
    t, s, y, v = tr["t_s"], tr["s_m"], tr["y_m"], tr["speed_mps"]
    acc, lat = tr["long_acc_mps2"], tr["lat_acc_mps2"]
    jerk = sg_jerk(acc)
    launch = tr["launch"]
    assert np.all(np.isfinite(tr["steer_rad"])) and np.all(np.isfinite(tr["torque_nm"]))
    # The stop: behind the car, in the lane, comfortable, the two-loop controller in charge.
    stop = t < T_FREE
    k_stop = np.argmin(np.abs(t - (T_FREE - 0.1)))
    assert v[k_stop] < 0.1
    assert 1.0 < float(_bumper_gap(s[k_stop])) < 15.0
    assert np.max(np.abs(y[stop])) < 0.3
    assert np.min(acc[stop]) >= LONG_ACC[0]
    assert np.max(np.abs(jerk[stop])) <= LONG_JERK
    assert np.all(launch[stop] == 0.0)
    # The launch: engaged at once, handed back to C/GMRES, never again.
    assert launch[np.argmax(t >= T_FREE)] == 1.0
    engaged = np.flatnonzero(launch > 0.5)
    assert np.all(np.diff(engaged) == 1)  # one contiguous launch
    t_handover = t[engaged[-1] + 1]
    assert t_handover < T_FREE + 8.0
    # The whole run: no contact, comfortable, no fallback, never NaN.
    assert not tr["box_overlap"].any()
    assert LONG_ACC[0] <= np.min(acc) and np.max(acc) <= LONG_ACC[1]
    assert np.max(np.abs(jerk)) <= LONG_JERK
    assert np.max(np.abs(lat)) <= LAT_ACC
    assert np.all(tr["fallback"] == 0)
    # C/GMRES restarted at the measured state: E small from the hand-over on.
    after = t >= t_handover
    assert tr["residual"][after][0] < 0.1
    assert np.max(tr["residual"][after]) < 2.0
    # Smooth hand-over (blend): no torque or steering step.
    k = engaged[-1] + 1
    window = slice(k - 5, k + int(TwoLoopParams().launch.blend_s / DT) + 5)
    assert np.max(np.abs(np.diff(tr["torque_nm"][window]))) < 100.0  # N m per 20 ms
    assert np.max(np.abs(np.diff(tr["steer_rad"][window]))) < 0.02
    # Back to speed, settled in the target lane.
    assert v[np.argmin(np.abs(t - 40.0))] >= 15.0
    assert np.max(np.abs(y[t > t[-1] - 2.0] - LANE)) <= 0.3


def test_launch_from_rest_on_open_road() -> None:
    """Standing start, target 22 m/s, no obstacle: launch, restart, hand-over; the
    ramp's jerk and acceleration limits hold and the car reaches the target."""
    tr = simulate(make_two_loop({}), STRAIGHT, [], duration_s=20.0, dt=DT,
                  initial_speed_mps=0.0, target_speed_mps=22.0)
    acc = tr["long_acc_mps2"]
    assert tr["launch"][0] == 1.0 and tr["launch"][-1] == 0.0
    assert np.max(acc) <= LONG_ACC[1] and np.min(acc) >= -0.5
    assert np.max(np.abs(sg_jerk(acc))) <= LONG_JERK
    assert np.max(np.abs(tr["y_m"])) < 0.05
    assert np.all(tr["fallback"] == 0) and np.max(tr["residual"]) < 0.5
    assert tr["speed_mps"][-1] == pytest.approx(22.0, abs=0.5)


def test_launch_holds_brakes_when_target_drops() -> None:
    """Target up (launch engaged), then back to ~0 before the hand-over: the launch ramp
    brakes to a stop and holds it with a negative torque; no creeping."""
    tr = simulate(make_two_loop({}), STRAIGHT, [], duration_s=6.0, dt=DT,
                  initial_speed_mps=0.0, target_speed_mps=22.0,
                  target_speed_fn=lambda t, s: 22.0 if t < 0.6 else 0.0)
    t, v = tr["t_s"], tr["speed_mps"]
    assert np.all(tr["launch"] == 1.0)  # never reached the hand-over speed
    late = t > 4.0
    assert np.max(v[late]) < 1e-6
    assert np.all(tr["torque_nm"][late] < 0.0)
    assert np.min(tr["long_acc_mps2"]) >= LONG_ACC[0]


def test_launch_not_engaged_at_speed_or_when_disabled() -> None:
    """Cruising is the paper's controller: the launch never engages above standstill."""
    tr = simulate(make_two_loop({}), STRAIGHT, [], duration_s=2.0, dt=DT,
                  initial_speed_mps=20.0, target_speed_mps=25.0)
    assert np.all(tr["launch"] == 0.0) and np.all(tr["launch_weight"] == 0.0)
    tr = simulate(make_two_loop({"launch": {"enabled": False}}), STRAIGHT, [], duration_s=1.0,
                  dt=DT,
                  initial_speed_mps=0.0, target_speed_mps=22.0)
    assert np.all(tr["launch"] == 0.0)


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
