"""The controllers that ship with hwyeval: tables of factories and parameter classes.

Each factory maps catalog options to a ready controller (or, for ``sumo``, to
:class:`controllers.protocol.SumoDriverModel`, for ``recorded`` to
:class:`controllers.baselines.recorded_driver.RecordedDriverModel`: not controllers, the
run's dynamics drive the ego); it is cheap (no compilation, no solver
set-up) and raises :class:`controllers.protocol.ConfigError` naming the dotted key of
a bad option. :data:`PARAMETERS` names each controller's parameter dataclass (its
options, for ``controllers.params.describe``). The registry reads both tables; this
module imports nothing of the registry (no import cycle).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable, Mapping
from typing import Any

from controllers.baselines.lane_keep import LaneKeepParams, make_lane_keep
from controllers.baselines.r157_reference import R157ReferenceParams, make_r157_reference
from controllers.baselines.recorded_driver import RecordedDriverModel, make_recorded_driver
from controllers.baselines.sumo_driver import make_sumo_driver
from controllers.protocol import Controller, SumoDriverModel
from controllers.two_loop.controller import make_two_loop
from controllers.two_loop.params import IpoptNmpcParams, TwoLoopParams

ControllerFactory = Callable[[Mapping[str, Any]],
                             Controller | SumoDriverModel | RecordedDriverModel]


def _factories() -> dict[str, ControllerFactory]:
    table: dict[str, ControllerFactory] = {
        "lane_keep": make_lane_keep,
        "r157_reference": make_r157_reference,
        "recorded": make_recorded_driver,
        "sumo": make_sumo_driver,
        "two_loop": make_two_loop,
    }
    # The Ipopt baseline needs CasADi (the 'baselines' extra); without it the name is
    # absent and a catalog naming it gets a clear "unknown controller" error.
    if importlib.util.find_spec("casadi") is not None:
        from controllers.baselines.ipopt_nmpc import make_ipopt_nmpc

        table["ipopt_nmpc"] = make_ipopt_nmpc
    return table


FACTORIES: Mapping[str, ControllerFactory] = _factories()

# name -> the parameter dataclass its options build (``sumo``, ``recorded`` have none).
PARAMETERS: Mapping[str, type] = {
    "lane_keep": LaneKeepParams, "two_loop": TwoLoopParams, "ipopt_nmpc": IpoptNmpcParams,
    "r157_reference": R157ReferenceParams,
}
