"""Controller registry and the Controller protocol (no SUMO)."""

from __future__ import annotations

import numpy as np
import pytest

from controllers import registry
from controllers.plant.vehicle_model import VehicleParams
from controllers.protocol import ConfigError, Controller, Observation, ScenarioContext


def test_builtins_are_registered() -> None:
    assert {"lane_keep", "sumo", "two_loop", "ipopt_nmpc"} <= set(registry.names())


def test_duplicate_names_are_refused() -> None:
    with pytest.raises(ValueError, match="already registered"):
        registry.register("lane_keep", lambda options: registry.make("lane_keep"))


def test_bad_names_are_refused() -> None:
    with pytest.raises(ValueError, match="a-z0-9_"):
        registry.register("Lane-Keep", lambda options: registry.make("lane_keep"))


def test_unknown_controller_names_the_key() -> None:
    with pytest.raises(ConfigError) as info:
        registry.make("no_such_controller")
    assert info.value.key == "controller.name"


@pytest.mark.parametrize("name", ["lane_keep", "sumo", "two_loop", "ipopt_nmpc"])
def test_every_builtin_satisfies_the_protocol(name: str) -> None:
    controller = registry.make(name, {})
    assert isinstance(controller, Controller)
    assert controller.name == name
    params = dict(controller.parameters())
    assert params  # JSON-able parameters for logs


def test_unknown_option_is_a_config_error_naming_it() -> None:
    with pytest.raises(ConfigError) as info:
        registry.make("lane_keep", {"lookahead_gain": 1.0})
    assert info.value.key == "controller.lookahead_gain"
    with pytest.raises(ConfigError) as info:
        registry.make("lane_keep", {"lookahead_min_m": True})
    assert info.value.key == "controller.lookahead_min_m"


def test_lane_keep_tracks_a_straight_lane_from_an_offset() -> None:
    from controllers.plant.vehicle_model import SingleTrackPlant

    vehicle = VehicleParams()
    ref = np.array([[0.0, 0.0], [3000.0, 0.0]])
    state = np.array([10.0, 1.0, 0.0, 20.0, 0.0, 0.0])
    ctrl = registry.make("lane_keep")
    ctrl.reset(ScenarioContext(ref, 3.5, 25.0, 0.02, vehicle, state))
    plant = SingleTrackPlant(vehicle, state)
    for k in range(1000):
        cmd = ctrl.step(Observation(k * 0.02, plant.state.copy(), 25.0))
        plant.step(cmd.steer_rad, cmd.torque_nm, 0.02)
    assert abs(plant.state[1]) < 0.05  # converged onto the lane centre
    assert plant.state[3] == pytest.approx(25.0, abs=0.2)  # PI speed reached the target
