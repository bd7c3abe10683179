"""The two-loop controller's parameters: one section per stage, and the catalog aliases.

``TwoLoopParams(outer=CgmresParams, inner=PreviewParams, lateral=LateralRefParams,
launch=LaunchParams, policy=ObstaclePolicy, fallback=FallbackParams,
jerk=JerkLimitParams)`` is ``two_loop``;
:class:`IpoptNmpcParams` is the same with ``outer=IpoptParams`` (``ipopt_nmpc``). A
catalog sets them with nested tables (``controller.outer.c_y``) through
:func:`controllers.params.build`; the flat names of the former flat parameter class
stay accepted as documented aliases (:data:`FLAT_ALIASES`, docs/two_loop.md).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from controllers.behaviour.types import ObstaclePolicy
from controllers.params import ParamError, build, section
from controllers.protocol import ConfigError
from controllers.two_loop.fallback import FallbackParams
from controllers.two_loop.jerk import JerkLimitParams
from controllers.two_loop.lateral import LateralRefParams
from controllers.two_loop.launch import LaunchParams
from controllers.two_loop.outer.params import CgmresParams, IpoptParams, OcpParams
from controllers.two_loop.threat import ThreatBrakeParams
from controllers.two_loop.tracker import PreviewParams


@dataclass(frozen=True)
class TwoLoopParamsBase:
    """The sections every two-loop controller has; ``outer`` is narrowed by the
    concrete classes to the planner's own parameters. Cross-section checks here."""

    outer: OcpParams = section(OcpParams, "outer loop: the OCP and its solver")
    inner: PreviewParams = section(PreviewParams, "inner loop: conversion and preview")
    lateral: LateralRefParams = section(LateralRefParams, "lateral-reference shaping")
    launch: LaunchParams = section(LaunchParams, "standstill launch and hand-over")
    policy: ObstaclePolicy = section(ObstaclePolicy, "other vehicles -> ellipses (K slots = "
                                     "max_obstacles)")
    fallback: FallbackParams = section(FallbackParams, "minimal-risk manoeuvre when the "
                                       "planner fails")
    jerk: JerkLimitParams = section(JerkLimitParams, "rate limit of the longitudinal "
                                    "command (the last stage)")
    threat: ThreatBrakeParams = section(ThreatBrakeParams, "braking held at an obstacle's "
                                        "need until it is gone")

    def __post_init__(self) -> None:
        horizon = self.outer.horizon_s
        if self.inner.lookahead_s > horizon:
            raise ParamError("inner.lookahead_s", f"a number <= outer.horizon_s = {horizon}",
                             self.inner.lookahead_s)
        if self.inner.n_preview * self.inner.preview_dt_s > horizon:
            raise ParamError("inner.n_preview", "n_preview * preview_dt_s <= outer.horizon_s "
                             f"= {horizon}", self.inner.n_preview)


@dataclass(frozen=True)
class TwoLoopParams(TwoLoopParamsBase):
    """``two_loop``: the paper's controller, C/GMRES outer loop."""

    outer: CgmresParams = section(CgmresParams, "outer loop: the OCP and C/GMRES")


@dataclass(frozen=True)
class IpoptNmpcParams(TwoLoopParamsBase):
    """``ipopt_nmpc``: the same controller with the Ipopt outer loop (J3 only)."""

    outer: IpoptParams = section(IpoptParams, "outer loop: the OCP (J3) and Ipopt")


def _identity(section_name: str, names: tuple[str, ...]) -> dict[str, str]:
    return {name: f"{section_name}.{name}" for name in names}


# Flat name of the former flat parameter class -> dotted path (docs/two_loop.md).
# Outer, inner and policy keep their names; lateral and launch drop their prefix.
FLAT_ALIASES: Mapping[str, str] = {
    **_identity("outer", (
        "cost", "horizon_s", "n_stages", "chebyshev", "c_y", "c_ydot", "c_sdot", "c_thetadot",
        "c_theta", "c_v", "c_z", "zeta", "c_y_terminal", "c_e_terminal", "target_accel_mps2",
        "target_decel_mps2", "target_jerk_mps3", "fallback_decel_mps2",
        # C/GMRES only (an unknown key of ipopt_nmpc's outer section)
        "k_max", "zeta_s", "fd_step", "sub_updates", "horizon_growth_rate", "z_guard",
        "row_scaling", "obstacle_fade_s", "fallback_residual", "fallback_hold_s")),
    **_identity("inner", (
        "preview", "n_preview", "preview_dt_s", "lookahead_s", "k_ps", "k_pv", "k_pvc", "k_psc",
        "k_isc", "integral_limit_ms", "feedforward")),
    **_identity("policy", (
        "detection_distance_m", "rear_range_m", "margin_long_m", "margin_lat_m", "offset_m",
        "max_obstacles", "moving_obstacles")),
    "lateral_ref_rate_mps": "lateral.rate_mps",
    "lateral_ref_filter_s": "lateral.filter_s",
    "lateral_ref_heading_rad": "lateral.heading_rad",
    "c_y_lateral_ref": "lateral.c_y_engaged",
    "lateral_weight_time_s": "lateral.weight_time_s",
    "launch": "launch.enabled",
    "launch_speed_mps": "launch.handover_speed_mps",
    **{f"launch_{name}": f"launch.{name}" for name in (
        "engage_speed_mps", "blend_s", "k_pv", "max_speed_mps", "k_heading", "lookahead_m",
        "max_heading_rad", "steer_speed_mps", "clearance_m", "guard_decel_mps2",
        "handover_free_m", "hold_target_mps", "hold_decel_mps2")},
}

# ipopt_nmpc: the same, plus its solver's former flat names.
IPOPT_FLAT_ALIASES: Mapping[str, str] = {
    **FLAT_ALIASES, "formulation": "outer.formulation", "max_iter": "outer.max_iter",
    "ipopt_tol": "outer.tol",
}


def _options_without_name(options: Mapping[str, Any], name: str) -> dict[str, Any]:
    opts = dict(options)
    given = opts.pop("name", name)
    if given != name:
        raise ConfigError("controller.name", f"{name!r}", given)
    return opts


def two_loop_params(options: Mapping[str, Any]) -> TwoLoopParams:
    """``two_loop``'s parameters from catalog options (nested tables or flat aliases;
    an optional ``name`` must be 'two_loop'); raises ConfigError naming the dotted key."""
    return build(TwoLoopParams, _options_without_name(options, "two_loop"),
                 aliases=FLAT_ALIASES)


def ipopt_nmpc_params(options: Mapping[str, Any]) -> IpoptNmpcParams:
    """``ipopt_nmpc``'s parameters (as :func:`two_loop_params`, the name 'ipopt_nmpc')."""
    return build(IpoptNmpcParams, _options_without_name(options, "ipopt_nmpc"),
                 aliases=IPOPT_FLAT_ALIASES)
