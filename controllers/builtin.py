"""Registers the controllers that ship with hwyeval (imported lazily by the registry)."""

from __future__ import annotations

import importlib.util

from controllers.baselines.lane_keep import make_lane_keep
from controllers.baselines.sumo_driver import make_sumo_driver
from controllers.registry import register
from controllers.two_loop.controller import make_two_loop

register("lane_keep", make_lane_keep)
register("sumo", make_sumo_driver)
register("two_loop", make_two_loop)

# The Ipopt baseline needs CasADi (the 'baselines' extra); without it the name is absent
# and a catalog naming it gets a clear "unknown controller" error listing what exists.
if importlib.util.find_spec("casadi") is not None:
    from controllers.baselines.ipopt_nmpc import make_ipopt_nmpc

    register("ipopt_nmpc", make_ipopt_nmpc)
