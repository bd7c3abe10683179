"""Per-step diagnostics of the two-loop controller (one trace column per field)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from controllers.protocol import StepDiagnostics
from controllers.two_loop.threat import BrakeSource


@dataclass(frozen=True, slots=True)
class TwoLoopDiagnostics(StepDiagnostics):
    """What :meth:`TwoLoopController.step` reports every period, beyond the common
    health and timing (outer_s: projection, shaping, launch and outer loop; inner_s:
    inner loop and command; residual: E, 0 in launch mode; fallback; guard_fired).

    steer_outer_rad, torque_outer_nm: conversion (13)(14) with feed-forward [rad, N m];
    steer_corr_rad, torque_corr_nm: preview corrections (38)(39) [rad, N m];
    steer_corr_integral_rad: the integral's part of steer_corr_rad, K_Isc I [rad];
    preview_weight: the corrections' lane-holding weight w (1 while the plan holds its
        lane, towards 0 while it moves across the road;
        :mod:`controllers.two_loop.tracker`) [-];
    planned_speed_mps: the plan's V at stage 0 [m/s]; planned_speed_min_mps: the least V
        over the plan's stages [m/s];
    preview_err_t_m, preview_err_n_m: preview error PE along the path's tangent and
        normal [m] (0 in launch mode);
    outer_updates: planner updates this period (0 in launch mode) [-];
    lateral_ref_m, lateral_ref_rate_mps: the shaped reference yr and yr' [m, m/s];
    lateral_weight: Cy of this period [1/(m² s)];
    lane_corridor_lo_m, lane_corridor_hi_m: the lane corridor [y_lo, y_hi] the plan is
        kept in [m, left +] (-inf/+inf: none);
    launch: the launch law drives; launch_weight: its share of the command [-] (1 in
        launch, easing to 0 after the hand-over); launch_ramp_speed_mps: the launch
        ramp's speed [m/s];
    mrm: the minimal-risk manoeuvre drives (the planner failed); mrm_hold_s: its current
        hold [s] (doubled after repeated failures);
    ocp_target_speed_mps: the speed reference of this step's plan [m/s]: the OCP's Vt,
        the set-point through the jerk-limited ramp (the manoeuvre's or the launch law's
        ramp while they drive);
    emergency: braking beyond comfort for an obstacle (the jerk limiter's bound raised
        for it, or the manoeuvre braced beyond comfort for it); emergency_decel_mps2: the
        braking that obstacle needs [m/s²]; emergency_ds_m, emergency_dy_m: its ellipse
        centre from the ego's CG along and across the path [m] (all NaN without an
        emergency);
    threat_need_mps2: the braking the nearest obstacle ahead needs, b = closing² / (2 d),
        a braking lead's own braking counted
        (:func:`controllers.two_loop.fallback.most_urgent_obstacle`) [m/s²];
    brake_floor_mps2: the threat floor's deceleration, 0 when it is not active [m/s²];
    brake_source: which stage set the command
        (:class:`controllers.two_loop.threat.BrakeSource`: 0 plan, 1 threat floor,
        2 minimal-risk manoeuvre, 3 launch, 4 safe stop).
    """

    steer_outer_rad: float = math.nan
    steer_corr_rad: float = math.nan
    steer_corr_integral_rad: float = math.nan
    preview_weight: float = math.nan
    torque_outer_nm: float = math.nan
    torque_corr_nm: float = math.nan
    planned_speed_mps: float = math.nan
    planned_speed_min_mps: float = math.nan
    preview_err_t_m: float = math.nan
    preview_err_n_m: float = math.nan
    outer_updates: int = 0
    lateral_ref_m: float = math.nan
    lateral_ref_rate_mps: float = math.nan
    lateral_weight: float = math.nan
    lane_corridor_lo_m: float = math.nan
    lane_corridor_hi_m: float = math.nan
    launch: bool = False
    launch_weight: float = math.nan
    launch_ramp_speed_mps: float = math.nan
    mrm: bool = False
    mrm_hold_s: float = math.nan
    ocp_target_speed_mps: float = math.nan
    emergency: bool = False
    emergency_decel_mps2: float = math.nan
    emergency_ds_m: float = math.nan
    emergency_dy_m: float = math.nan
    threat_need_mps2: float = math.nan
    brake_floor_mps2: float = math.nan
    brake_source: int = 0


class StepReferences(NamedTuple):
    """This period's lateral reference [m], its weight C_y and the lane corridor [m]
    (these three are named tuples, not frozen dataclasses: one of each is made a period)."""

    y_ref_m: float
    c_y: float
    y_lo_m: float
    y_hi_m: float


class StepTimes(NamedTuple):
    """perf_counter stamps [s]: the step's start, the inner loop's start, the end."""

    outer0: float
    inner0: float
    end: float


class StepBraking(NamedTuple):
    """The threat floor's need and floor [m/s²] and the stage that set the braking."""

    need_mps2: float
    floor_mps2: float
    source: BrakeSource
