"""Gap acceptance for a lane change around an obstacle, and the follow speed behind one.

Both are pure functions of Frenet positions and speeds along the reference path
(arrays of shape (n,), metres and metres per second).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class GapPolicy:
    """Free-gap and follow rules of the behaviour layer.

    clearance_m [m], time_gap_s [s]: a vehicle in the target lane blocks the pass if,
        under constant speeds, its box comes closer than clearance + time_gap * v_ego
        (bumper to bumper) to the ego's box at any time until the ego is
        ``pass_after_m`` [m] beyond the obstacle.
    commit_offset_m [m]: once the ego is this far towards a side, that side is kept for
        the obstacle (no mid-manoeuvre flip-flop).
    follow_time_gap_s [s], follow_standstill_m [m], follow_decel_mps2 [m/s²]: the desired
        gap behind a leader that cannot be passed and the comfortable braking used to
        reach it (see :func:`follow_speed_mps`).
    plan_horizon_s [s]: how far ahead (at the ego's speed) a blocking vehicle is looked
        for, beside the detection distance and the comfortable stopping distance.
    """

    clearance_m: float = 4.0
    time_gap_s: float = 0.6
    pass_after_m: float = 15.0
    commit_offset_m: float = 1.0
    follow_time_gap_s: float = 1.8
    follow_standstill_m: float = 6.0
    follow_decel_mps2: float = 2.0
    plan_horizon_s: float = 6.0

    def __post_init__(self) -> None:
        for name in ("clearance_m", "time_gap_s", "pass_after_m", "commit_offset_m",
                     "follow_time_gap_s", "follow_standstill_m", "follow_decel_mps2",
                     "plan_horizon_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, int | float) and math.isfinite(v)
                                           and v >= 0):
                raise ValueError(f"GapPolicy.{name} must be a finite number >= 0, got {v!r}")


def follow_speed_mps(gap_m: float, lead_speed_mps: float, set_speed_mps: float,
                     gap: GapPolicy) -> float:
    """Speed set-point behind a leader that cannot be passed [m/s].

    With the desired gap d* = standstill + time_gap v_lead, the ego may go at
    v = sqrt(v_lead² + 2 b (gap - d*)) while the gap exceeds d* (it can still shed the
    difference at the comfortable deceleration b before reaching d*), and at
    v_lead gap / d* inside it. Clipped to [0, set speed].
    """
    desired = gap.follow_standstill_m + gap.follow_time_gap_s * lead_speed_mps
    if gap_m >= desired:
        v = math.sqrt(lead_speed_mps**2 + 2.0 * gap.follow_decel_mps2 * (gap_m - desired))
    else:
        v = lead_speed_mps * gap_m / max(desired, 1e-6)
    return float(min(max(v, 0.0), set_speed_mps))


def gap_is_free(ego_s: float, ego_v: float, ego_len: float, obs_s: float, obs_len: float,
                lane_s: FloatArray, lane_v: FloatArray, lane_len: FloatArray,
                gap: GapPolicy) -> bool:
    """True when no vehicle in the target lane conflicts with the pass manoeuvre.

    Relative motion is linear, so the minimum bumper distance over the window [0, T]
    (T = time for the ego to get ``pass_after_m`` past the obstacle) is attained at an
    end point or where the relative position crosses zero. A (near-)stationary vehicle
    anywhere in the stretch the ego sweeps, from its rear to ``pass_after_m`` beyond the
    obstacle, blocks whatever the ego's speed (a slow ego would otherwise "outwait" it
    in the time-based test).
    """
    if lane_s.size == 0:
        return True
    end_s = obs_s + 0.5 * obs_len + gap.pass_after_m
    stationary = np.abs(lane_v) < 0.5
    reach = 0.5 * (lane_len + ego_len) + gap.clearance_m
    if np.any(stationary & (lane_s > ego_s - reach) & (lane_s < end_s + reach)):
        return False
    horizon_s = max(end_s - ego_s, 0.0) / max(ego_v, 1.0)
    need = gap.clearance_m + gap.time_gap_s * ego_v
    rel0 = lane_s - ego_s
    rel_v = lane_v - ego_v
    half = 0.5 * (lane_len + ego_len)
    ts = [np.zeros_like(rel0), np.full_like(rel0, horizon_s)]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cross = np.where(np.abs(rel_v) > 1e-9, -rel0 / rel_v, 0.0)
    ts.append(np.clip(t_cross, 0.0, horizon_s))
    closest = np.min(np.stack([np.abs(rel0 + rel_v * t) for t in ts]), axis=0)
    return bool(np.all(closest - half >= need))
