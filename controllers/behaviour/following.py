"""Car following: the speed set-point behind a lead vehicle (a constant-time-gap law).

With the ego at v, the lead at v_l and the bumper gap g, the desired gap is
d* = s0 + T v (time gap T, standstill distance s0). The set-point is the least of

    v_gap  = v_p + (g - d*) / tau                 (close the gap error in tau seconds)
    v_safe = sqrt(v_l² b / max(b_l, b) + 2 b (g - s0))

and the cruise speed, clipped at 0. v_p = max(v_l + min(a_l, 0) t_a, 0) is the lead's
speed ``anticipation_s`` ahead when it brakes (a_l its estimated acceleration, b_l =
max(-a_l, 0) its braking). At the desired gap behind a steady lead v_gap = v_l (follow at
its speed); a closing gap lowers the set-point smoothly. v_safe is the fastest speed from
which braking at the comfortable b still stops s0 behind the point where the lead, braking
at b_l, stops (Gipps' bound; for b_l <= b it is v_l² + 2 b (g - s0), slowing to the lead's
speed). A lead that brakes hard therefore lowers the set-point at once, even while it is
still faster than the ego and the gap still grows. The outer planner tracks this
set-point through its own jerk-limited ramp, so the law never commands a step in
acceleration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from controllers.behaviour.types import require_numbers


@dataclass(frozen=True)
class FollowParams:
    """time_gap_s [s] (>= 1.5), standstill_m [m], gap_close_s [s]: the time-gap law;
    comfort_decel_mps2 [m/s²]: the braking that v_safe allows; anticipation_s [s]: how
    far ahead a braking lead's speed is predicted."""

    time_gap_s: float = 1.8
    standstill_m: float = 6.0
    gap_close_s: float = 3.0
    comfort_decel_mps2: float = 2.0
    anticipation_s: float = 1.0

    def __post_init__(self) -> None:
        require_numbers(self, ("time_gap_s", "standstill_m", "gap_close_s",
                               "comfort_decel_mps2", "anticipation_s"), strict=True)
        if self.time_gap_s < 1.5:
            raise ValueError(f"FollowParams.time_gap_s must be >= 1.5 s, got {self.time_gap_s}")


def follow_speed_mps(gap_m: float, lead_speed_mps: float, ego_speed_mps: float,
                     set_speed_mps: float, params: FollowParams,
                     lead_accel_mps2: float = 0.0) -> float:
    """Speed set-point [m/s] behind a lead at bumper gap ``gap_m`` [m] moving at
    ``lead_speed_mps`` with acceleration ``lead_accel_mps2`` [m/s²] (module docstring)."""
    v_lead = max(lead_speed_mps, 0.0)
    braking = max(-lead_accel_mps2, 0.0) if math.isfinite(lead_accel_mps2) else 0.0
    b = params.comfort_decel_mps2
    v_pred = max(v_lead - braking * params.anticipation_s, 0.0)
    desired = params.standstill_m + params.time_gap_s * max(ego_speed_mps, 0.0)
    v_gap = v_pred + (gap_m - desired) / params.gap_close_s
    spare = gap_m - params.standstill_m
    v_safe = math.sqrt(max(v_lead**2 * b / max(braking, b) + 2.0 * b * spare, 0.0)) \
        if spare > 0 else 0.0
    return float(min(max(min(v_gap, v_safe), 0.0), set_speed_mps))
