"""STVM plant: known answers (no SUMO)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.plant.limited import plant_derivative
from controllers.plant.vehicle_model import SingleTrackPlant, VehicleParams

# Kinematics without drag and rolling resistance: the car coasts at constant speed.
NO_RESISTANCE = VehicleParams(drag_coeff=0.0, rolling_resistance_coeff=0.0)


def test_constant_speed_straight_line_is_distance_speed_times_time() -> None:
    # 20 m/s for 2 s on a straight road is 40 m.
    plant = SingleTrackPlant(NO_RESISTANCE, np.array([0.0, 0.0, 0.0, 20.0, 0.0, 0.0]))
    for _ in range(100):
        plant.step(0.0, 0.0, 0.02)
    assert plant.state[0] == pytest.approx(40.0, abs=1e-9)
    assert plant.state[1] == pytest.approx(0.0, abs=1e-12)
    assert plant.state[3] == pytest.approx(20.0, abs=1e-12)


def test_heading_rotates_the_motion() -> None:
    psi = math.radians(30.0)
    plant = SingleTrackPlant(NO_RESISTANCE, np.array([5.0, -3.0, psi, 20.0, 0.0, 0.0]))
    for _ in range(100):
        plant.step(0.0, 0.0, 0.02)
    assert plant.state[0] == pytest.approx(5.0 + 40.0 * math.cos(psi), abs=1e-9)
    assert plant.state[1] == pytest.approx(-3.0 + 40.0 * math.sin(psi), abs=1e-9)


@pytest.mark.parametrize("speed_mps", [15.0, 25.0, 30.0])
def test_steady_turn_matches_understeer_gradient_formula(speed_mps: float) -> None:
    """r_ss = u delta / (L + K_us u^2) for the linear-tyre single-track model; the plant
    (drag, rolling resistance, friction and power limits) has it too at low lateral
    acceleration (here <= 0.3 g)."""
    params = VehicleParams()
    delta = 0.01
    plant = SingleTrackPlant(params, np.array([0.0, 0.0, 0.0, speed_mps, 0.0, 0.0]))
    for _ in range(400):  # 8 s: yaw transients die out (time constant well under 1 s)
        d = plant_derivative(plant.state, delta, 0.0, params.plant_array())
        # Cancel the longitudinal deceleration (the front tyre's lateral force component,
        # drag, rolling) with drive torque: T = -m du/dt R / (1 + cos delta) * 2
        torque = -d[3] * params.mass_kg * 2.0 * params.wheel_radius_m / (1.0 + math.cos(delta))
        plant.step(delta, torque, 0.02)
    u = plant.state[3]
    expected = u * delta / (params.wheelbase_m + params.understeer_gradient_rad_per_mps2 * u * u)
    assert plant.state[5] == pytest.approx(expected, rel=0.02)
    assert u == pytest.approx(speed_mps, rel=0.01)


def test_braking_stops_without_reversing() -> None:
    plant = SingleTrackPlant(VehicleParams(), np.array([0.0, 0.0, 0.0, 5.0, 0.0, 0.0]))
    for _ in range(300):
        plant.step(0.0, -4500.0, 0.02)
    assert plant.state[3] == 0.0
    assert 0.0 < plant.state[0] < 5.0
    # Held by the brakes: standing still, steering or not, it does not creep.
    x_stop = plant.state.copy()
    for _ in range(100):
        plant.step(0.3, -500.0, 0.02)
    np.testing.assert_array_equal(plant.state[:3], x_stop[:3])


def test_params_are_validated() -> None:
    with pytest.raises(ValueError, match="mass_kg"):
        VehicleParams(mass_kg=-1.0)
    with pytest.raises(ValueError, match="front_overhang_m"):
        VehicleParams(front_overhang_m=-0.5)


def test_non_finite_command_is_rejected() -> None:
    plant = SingleTrackPlant(VehicleParams(), np.array([0.0, 0.0, 0.0, 20.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="non-finite"):
        plant.step(math.nan, 0.0, 0.02)
