"""The threat floor (controllers.two_loop.threat) and the fallback's steering-rate bound
(controllers.two_loop.steer_rate), on known sequences; the obstacles' box-sum half length
against the need it gives (controllers.two_loop.fallback.most_urgent_obstacle)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.behaviour.tracking import AccelerationTracker, TrackingParams
from controllers.behaviour.types import ObstaclePolicy, Obstacles
from controllers.plant.vehicle_model import VehicleParams
from controllers.two_loop.fallback import most_urgent_obstacle
from controllers.two_loop.steer_rate import SteerRateLimiter
from controllers.two_loop.threat import ThreatBrakeParams, ThreatFloor


def test_the_floor_never_falls_while_the_need_rises_and_releases_below_comfort() -> None:
    p = ThreatBrakeParams(margin=1.2, release_decel_mps2=2.0, max_decel_mps2=9.0)
    floor = ThreatFloor(p)
    assert floor.update(5.0, emergency=False) == 0.0  # no emergency: nothing engages
    assert floor.update(4.0, emergency=True) == pytest.approx(4.8)  # engaged at 1.2 b
    assert floor.update(3.0, emergency=False) == pytest.approx(3.6)  # falling: follows
    assert floor.update(3.1, emergency=False) == pytest.approx(3.72)  # rising: max
    assert floor.update(3.05, emergency=False) == pytest.approx(3.66)
    assert floor.update(2.0, emergency=False) == pytest.approx(2.4)  # above release
    assert floor.update(1.6, emergency=False) == 0.0  # 1.92 < 2.0: released
    assert not floor.active
    assert floor.update(1.0, emergency=False) == 0.0  # stays released without emergency


def test_a_rising_need_keeps_the_highest_floor_and_the_cap_holds() -> None:
    floor = ThreatFloor(ThreatBrakeParams(max_decel_mps2=9.0))
    values = [floor.update(b, emergency=True) for b in (4.0, 3.0, 3.5, 5.0, 20.0, math.inf)]
    assert values == pytest.approx([4.8, 3.6, 4.2, 6.0, 9.0, 9.0])
    assert all(v <= 9.0 for v in values)


def test_disabled_floor_is_zero() -> None:
    floor = ThreatFloor(ThreatBrakeParams(enabled=False))
    assert floor.update(10.0, emergency=True) == 0.0


def test_params_are_validated() -> None:
    with pytest.raises(ValueError):
        ThreatBrakeParams(margin=0.9)
    with pytest.raises(ValueError):
        ThreatBrakeParams(release_decel_mps2=5.0, max_decel_mps2=4.0)


def test_steering_is_blended_from_what_the_car_does_at_the_bounded_rate() -> None:
    vp = VehicleParams()
    lim = SteerRateLimiter(lat_jerk_mps3=5.0, blend_s=1.0, speed_floor_mps=5.0)
    lim.reset(vp)
    v = 27.0
    rate = 5.0 * (vp.wheelbase_m + vp.understeer_gradient_rad_per_mps2 * v * v) / (v * v)
    assert lim.rate_radps(v) == pytest.approx(rate)
    # unbounded: passes through
    assert lim.limit(0.05, 0.0, 0.02, v, 0.0, bounded=False) == (0.05, False)
    # engaged: starts from the steady-state steering of the yaw rate (0 here), not 0.05
    out, acted = lim.limit(-0.2, 0.02, 0.02, v, 0.0, bounded=True)
    assert acted and out == pytest.approx(-rate * 0.02)
    outs = [lim.limit(-0.2, 0.02 * k, 0.02, v, 0.0, bounded=True)[0] for k in range(2, 50)]
    assert np.all(np.abs(np.diff([out, *outs])) <= rate * 0.02 + 1e-12)
    # hand-back: still bounded for blend_s, free afterwards
    t_back = 0.02 * 50
    held, acted = lim.limit(0.3, t_back + 0.5, 0.02, v, 0.0, bounded=False)
    assert acted and held == pytest.approx(outs[-1] + rate * 0.02)
    assert lim.limit(0.3, t_back + 1.5, 0.02, v, 0.0, bounded=False) == (0.3, False)


def test_steady_state_steering_of_a_yaw_rate() -> None:
    vp = VehicleParams()
    lim = SteerRateLimiter(5.0, 1.0, 5.0)
    lim.reset(vp)
    v, radius = 20.0, 200.0
    expected = (vp.wheelbase_m + vp.understeer_gradient_rad_per_mps2 * v * v) / radius
    assert lim.steady_state_rad(v, v / radius) == pytest.approx(expected)


def _wall(gap_m: float, half_m: float | None) -> Obstacles:
    """A followed lead's wall 1 lane wide (B = 35 m), its semi-axis A shrunk to the
    distance, its centre gap_m + half ahead of the ego's CG at s = 100 m."""
    ds = gap_m + 4.65
    return Obstacles(s_m=np.array([100.0 + ds]), y_m=np.zeros(1), speed_s_mps=np.array([20.7]),
                     speed_y_mps=np.zeros(1), semi_a_m=np.array([ds + 0.2]),
                     semi_b_m=np.array([35.0]),
                     half_length_m=np.zeros(0) if half_m is None else np.array([half_m]))


def test_the_need_of_a_wall_is_measured_on_the_boxes_not_the_ellipse() -> None:
    """A cut-in 4 m ahead closing at 6 m/s needs 6² / (2 (4 - 1)) = 6 m/s² (standstill
    1 m); inferred from a wall's semi-axes the box-sum half length came out ~0.5 m and
    the need ~1.5 m/s²."""
    x0 = np.array([100.0, 0.0, 0.0])
    pol = ObstaclePolicy()
    need, j = most_urgent_obstacle(x0, 26.7, _wall(4.0, 4.65), pol, 1.0)
    assert j == 0 and need == pytest.approx(6.0**2 / (2 * 3.0), rel=1e-6)
    inferred, _ = most_urgent_obstacle(x0, 26.7, _wall(4.0, None), pol, 1.0)
    assert inferred < 0.5 * need


def test_half_lengths_must_match_the_obstacles() -> None:
    with pytest.raises(ValueError):
        Obstacles(np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(2), np.ones(2), np.ones(2),
                  half_length_m=np.ones(3))


def _gate(v_y: list[float], dt: float = 0.02) -> list[float]:
    tracker = AccelerationTracker(TrackingParams(lateral_tau_s=0.3, lateral_enter_mps=0.35,
                                                 lateral_exit_mps=0.15))
    return [float(tracker.lateral(k * dt, ("car",), np.array([v]))[0])
            for k, v in enumerate(v_y)]


def test_a_lateral_motion_counts_once_its_filtered_speed_reaches_the_threshold() -> None:
    """w_k = w + (v - w) dt / (tau + dt): a steady 1.2 m/s reaches 0.35 m/s after
    k = ceil(log(1 - 0.35/1.2) / log(1 - dt/(tau + dt))) steps, then v itself is given."""
    out = _gate([0.0] + [1.2] * 20)
    alpha = 0.02 / 0.32
    k = int(np.ceil(np.log(1 - 0.35 / 1.2) / np.log(1 - alpha)))
    assert out[1:k] == [0.0] * (k - 1) and out[k] == 1.2
    assert out[k + 1:] == [1.2] * (20 - k)


def test_the_gate_holds_between_the_thresholds_and_closes_below_exit() -> None:
    out = _gate([0.0] + [1.0] * 30 + [0.25] * 60 + [0.0] * 40)
    assert out[30] == 1.0
    # w decays toward 0.25 (> exit 0.15): the gate stays open, the speed is given
    assert all(v == 0.25 for v in out[31:91])
    assert out[-1] == 0.0


def test_jitter_never_opens_the_gate() -> None:
    rng = np.random.default_rng(0)
    jitter = np.clip(rng.normal(0.0, 0.36, 500), -0.9, 0.9)  # 0.08 rad at 4.5 m/s x noise
    assert not any(_gate([float(v) for v in jitter], dt=0.04))
