"""Scripted speed profiles for controller tests (not the product's behaviour layer)."""

from __future__ import annotations

import math


def stop_behind_profile(gap_m: float, lead_speed_mps: float, set_speed_mps: float,
                        standstill_m: float = 6.0, time_gap_s: float = 1.8,
                        decel_mps2: float = 2.0) -> float:
    """A comfortable follow profile: v = sqrt(v_lead² + 2 b (gap - d*)) outside the
    desired gap d* = standstill + time_gap v_lead, v_lead gap / d* inside; clipped to
    [0, set speed] (what the behaviour layer commanded before it followed a time-gap law)."""
    desired = standstill_m + time_gap_s * lead_speed_mps
    if gap_m >= desired:
        v = math.sqrt(lead_speed_mps**2 + 2.0 * decel_mps2 * (gap_m - desired))
    else:
        v = lead_speed_mps * gap_m / max(desired, 1e-6)
    return float(min(max(v, 0.0), set_speed_mps))
