"""The identity of a run (:class:`reports.record.RunInfo`) from its scenario."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controllers.plant.vehicle_model import VehicleParams
from reports.record import EgoBox, RunInfo
from suite import __version__
from suite.catalog import Scenario


def ego_box(vehicle: VehicleParams) -> EgoBox:
    return EgoBox(length_m=vehicle.length_m, width_m=vehicle.width_m,
                  cg_to_front_bumper_m=vehicle.cg_to_front_bumper_m,
                  cg_to_box_centre_m=vehicle.cg_to_box_centre_m,
                  cg_to_rear_axle_m=vehicle.cg_to_rear_axle_m)


def scenario_info(scenario: Scenario, catalog_name: str, vehicle: VehicleParams,
                  controller_params: Mapping[str, Any] | None = None) -> RunInfo:
    """Everything about the run known before it starts (controller parameters once built)."""
    return RunInfo(
        scenario=scenario.name, family=scenario.family, controller=scenario.controller.name,
        catalog=str(scenario.catalog_path), catalog_name=catalog_name, seed=int(scenario.seed),
        net=str(scenario.net_path), net_name=scenario.net, duration_s=float(scenario.duration_s),
        step_s=float(scenario.step_s), target_speed_mps=float(scenario.ego.target_speed_mps),
        allow_shoulder=bool(scenario.allow_shoulder), ego=ego_box(vehicle),
        controller_options=scenario.controller.options_dict(),
        controller_params=dict(controller_params or {}),
        criteria={k: float(v) for k, v in scenario.criteria.items()},
        scenario_spec=scenario.as_dict(), record_radius_m=float(scenario.record_radius_m),
        hwyeval_version=__version__, friction=float(scenario.friction))
