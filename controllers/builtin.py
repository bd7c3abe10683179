"""Registers the controllers that ship with hwyeval (imported lazily by the registry)."""

from __future__ import annotations

from controllers.lane_keep import make_lane_keep
from controllers.registry import register
from controllers.sumo_driver import make_sumo_driver

register("lane_keep", make_lane_keep)
register("sumo", make_sumo_driver)

try:
    from controllers.two_loop import make_two_loop
except ImportError:  # pragma: no cover - during bring-up only
    make_two_loop = None  # type: ignore[assignment]
if make_two_loop is not None:
    register("two_loop", make_two_loop)

try:
    from controllers.baselines.ipopt_nmpc import make_ipopt_nmpc
except ImportError:  # casadi is an optional extra
    make_ipopt_nmpc = None  # type: ignore[assignment]
if make_ipopt_nmpc is not None:
    register("ipopt_nmpc", make_ipopt_nmpc)
