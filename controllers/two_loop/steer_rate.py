"""Steering rate bound across a change of plan: the minimal-risk manoeuvre's engagement
and its hand-back to the planner.

When the planner fails mid-manoeuvre, the tracker switches from the last valid plan to
the manoeuvre's lane-keeping plan in one period; its steering request can step by a
large angle (0.38 rad in 20 ms at highway speed: lateral acceleration -0.5 -> -5.3
m/s² in one period). While the manoeuvre drives, and for ``blend_s`` after it hands
back (the planner's first plans step the other way), the command is blended at a
bounded rate instead, starting from what the car does: at the engagement, from the
steady-state steering of its measured yaw rate r, delta_ss = r (L + K_us v²) / v (the
last command is the failing planner's, which may already be the step: a diverging
C/GMRES solution asked 0.05 rad at 28 m/s, 2.7 m/s² toward the next lane, in the period
before it was declared failed), afterwards from the last command handed out:

    |delta_k - delta_{k-1}| <= rate(v) dt,   rate(v) = j (L + K_us v²) / max(v, v_min)²

the steady-state steering rate at which the lateral acceleration a_y = v² delta /
(L + K_us v²) changes at the lateral jerk j = ``lat_jerk_mps3`` (L the wheelbase, K_us
the understeer gradient, v_min = ``rate_speed_floor_mps`` so that the bound stays finite
at a standstill; :class:`controllers.two_loop.fallback.FallbackParams`): both are
:meth:`VehicleParams.steady_state_steer_rad`, of the curvature j / v² and r / v.
"""

from __future__ import annotations

import math

from controllers.plant.vehicle_model import VehicleParams


class SteerRateLimiter:
    """State: the last steering handed out [rad] and until when the bound holds [s]."""

    def __init__(self, lat_jerk_mps3: float, blend_s: float, speed_floor_mps: float) -> None:
        self.lat_jerk_mps3 = lat_jerk_mps3
        self.blend_s = blend_s
        self.speed_floor_mps = speed_floor_mps
        self._vehicle = VehicleParams()
        self._last: float | None = None
        self._until_s = -math.inf

    def reset(self, vehicle: VehicleParams) -> None:
        self._vehicle = vehicle
        self._last = None
        self._until_s = -math.inf

    def rate_radps(self, speed_mps: float) -> float:
        """The bound rate(v) [rad/s] (module docstring)."""
        v = max(abs(speed_mps), self.speed_floor_mps)
        return self._vehicle.steady_state_steer_rad(v, self.lat_jerk_mps3 / (v * v))

    def steady_state_rad(self, speed_mps: float, yaw_rate_radps: float) -> float:
        """delta_ss [rad] that holds the yaw rate r at speed v (module docstring)."""
        v = max(abs(speed_mps), self.speed_floor_mps)
        return self._vehicle.steady_state_steer_rad(v, yaw_rate_radps / v)

    def limit(self, steer_rad: float, t_s: float, dt_s: float, speed_mps: float,
              yaw_rate_radps: float, bounded: bool) -> tuple[float, bool]:
        """(steering to hand out [rad], whether the bound acted): ``steer_rad`` itself
        unless ``bounded`` (the manoeuvre drives) or within ``blend_s`` of the last
        bounded period, then moved toward it by at most rate(v) dt from the last one
        (from delta_ss of the measured yaw rate [rad/s] at the engagement)."""
        last = self._last
        if bounded:
            if t_s > self._until_s:  # engaged now: start from what the car does
                last = self.steady_state_rad(speed_mps, yaw_rate_radps)
            self._until_s = t_s + self.blend_s
        out = steer_rad
        if last is not None and t_s <= self._until_s and math.isfinite(steer_rad):
            step = self.rate_radps(speed_mps) * max(dt_s, 0.0)
            out = min(max(steer_rad, last - step), last + step)
        self._last = out
        return out, out != steer_rad
