"""``sumo``: the ego is driven by SUMO's own driver model (Krauss + LC2013).

This controller computes nothing: the runner sees ``simulated_by_sumo`` and lets
SUMO move the ego (speed capped at the target speed), reading its pose back and
recording it exactly like the other controllers' runs.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controllers.protocol import Command, Observation, ScenarioContext
from controllers.registry import check_options


class SumoDriverController:
    name = "sumo"
    simulated_by_sumo = True
    obstacle_policy = None

    def reset(self, context: ScenarioContext) -> None:
        del context

    def step(self, observation: Observation) -> Command:
        del observation
        return Command(steer_rad=0.0, torque_nm=0.0)

    def parameters(self) -> Mapping[str, Any]:
        return {"controller": self.name, "car_following": "Krauss", "lane_change": "LC2013"}


def make_sumo_driver(options: Mapping[str, Any]) -> SumoDriverController:
    check_options(options, {})
    return SumoDriverController()
