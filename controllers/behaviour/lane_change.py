"""Lane changes: whether a move into a neighbour lane is wanted, and whether it is safe.

Safety (gap acceptance, a MOBIL-style criterion): with the ego at v, the target lane's
lead at bumper gap g_f and speed v_f, its follower at gap g_r and speed v_r,

* the target lane admits the ego (passenger cars, or a shoulder the scenario allows) and
  continues beyond the manoeuvre;
* no (near-)stationary vehicle in it over the stretch the manoeuvre sweeps;
* front: g_f >= s0 + T_f v, and closing on the lead (v > v_f) needs at most b_safe to
  match its speed before s0: (v - v_f)² / (2 (g_f - s0)) <= b_safe;
* rear: g_r >= s0 + T_r v_r, and the new follower closing on the ego (v_r > v) needs at
  most b_safe: (v_r - v)² / (2 (g_r - s0)) <= b_safe (MOBIL's bound on the new
  follower's braking).

Before the commit point a manoeuvre is re-checked every step with ``abort_decel_mps2``
(> b_safe: hysteresis, so that a marginal gap does not flip the decision) and aborted
if that fails. Incentive: a change is wanted when the achievable speed in the target lane
(the car-following set-point behind its lead) beats the current lane's by
``incentive_mps`` (passing), or to return to the ego's home lane when that lane is as
fast as the current one (keep right / back to the asked lane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.behaviour.perception import LaneScene, Neighbour
from controllers.behaviour.types import LaneCheck, LaneSlot, require_numbers


@dataclass(frozen=True)
class LaneChangeParams:
    """Gap acceptance and decision timing (units in the names).

    front_time_gap_s, rear_time_gap_s, standstill_m: minimum gaps to the target lane's
    lead and follower; safe_decel_mps2: the braking a change may ask of the ego or of its
    new follower; abort_decel_mps2: the same for aborting an ongoing change (> safe);
    incentive_mps: speed gain that makes a pass worth it; commit_fraction: share of the
    lateral move after which a change is no longer aborted; done_tolerance_m: lateral
    distance to the target lane's centre at which a change is complete; hold_s: time a
    lane is kept after a change before another one (unless the lane ahead is blocked
    by a stopped vehicle); pass_after_m: how far beyond a passed vehicle's rear the ego
    stays in the pass lane; lane_end_margin_m: a target lane must continue this much
    beyond the manoeuvre; plan_horizon_s: how far ahead (at the ego's speed) a slower
    vehicle counts as blocking; block_margin_mps: how much slower it must be;
    undertake_below_mps: a vehicle ahead is passed on the right only while it is slower
    than this (stopped or crawling: a broken-down car, a queue); a moving car is never
    undertaken, the ego follows it or passes on the left (keep-right rule);
    evasive_decel_mps2: the braking an *evasive* change (round a stopped car the ego
    cannot stop for comfortably) may ask of the new follower and of the ego, to start and
    to carry on (a driver behind braking hard beats running into a stopped car).
    max_lat_acc_mps2: the lateral acceleration a change may reach with the road's own
    (v² |kappa| of the curve plus the move's), below the comfort criterion's 4.89 m/s²
    for the tracking's overshoot; change_lat_acc_mps2: a change's own peak on a
    straight road at the nominal duration ``change_s``; a change that is not urgent
    starts only where the curve over its stretch leaves at least that much, and every
    change's stretch (for the gap rules) grows where the curve leaves less (a
    minimum-jerk move of D metres in T seconds peaks at 5.77 D / T²).
    merge_behind_m, merge_ahead_m: vehicles on a lane that ends beside the ego's,
    from this far behind to this far ahead of its CG, make it leave room: no return
    into their target lane, a courtesy change away from it when the far lane is free,
    and a speed that lets in a faster one that will reach the merge first.
    """

    front_time_gap_s: float = 0.6
    rear_time_gap_s: float = 0.5
    standstill_m: float = 4.0
    safe_decel_mps2: float = 2.0
    abort_decel_mps2: float = 3.5
    incentive_mps: float = 2.0
    commit_fraction: float = 0.5
    done_tolerance_m: float = 0.3
    hold_s: float = 3.0
    pass_after_m: float = 15.0
    lane_end_margin_m: float = 20.0
    plan_horizon_s: float = 6.0
    block_margin_mps: float = 1.0
    undertake_below_mps: float = 2.0
    evasive_decel_mps2: float = 4.5
    max_lat_acc_mps2: float = 4.0
    change_lat_acc_mps2: float = 1.5
    change_s: float = 4.0
    merge_behind_m: float = 40.0
    merge_ahead_m: float = 120.0

    def __post_init__(self) -> None:
        require_numbers(self, ("front_time_gap_s", "rear_time_gap_s", "standstill_m",
                               "safe_decel_mps2", "abort_decel_mps2", "incentive_mps",
                               "done_tolerance_m", "hold_s", "pass_after_m",
                               "lane_end_margin_m", "plan_horizon_s", "block_margin_mps",
                               "undertake_below_mps", "evasive_decel_mps2",
                               "max_lat_acc_mps2", "change_lat_acc_mps2", "change_s",
                               "merge_behind_m", "merge_ahead_m"))
        for name in ("max_lat_acc_mps2", "change_lat_acc_mps2", "change_s"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"LaneChangeParams.{name} must be > 0, got "
                                 f"{getattr(self, name)!r}")
        if not 0.0 < self.commit_fraction < 1.0:
            raise ValueError("LaneChangeParams.commit_fraction must be in (0, 1), "
                             f"got {self.commit_fraction!r}")
        if self.abort_decel_mps2 < self.safe_decel_mps2:
            raise ValueError("LaneChangeParams.abort_decel_mps2 must be >= safe_decel_mps2")
        if self.evasive_decel_mps2 < self.abort_decel_mps2:
            raise ValueError("LaneChangeParams.evasive_decel_mps2 must be >= abort_decel_mps2")


MIN_JERK_PEAK = 5.77  # peak |y''| T² / D of a minimum-jerk move (10 t³ - 15 t⁴ + 6 t⁵)


def change_duration_s(move_m: float, curve_acc_mps2: float, p: LaneChangeParams) -> float:
    """Duration [s] of a lateral move of ``move_m`` [m] on a road whose curve already
    asks ``curve_acc_mps2`` (v² |kappa|) of the lateral acceleration: the nominal
    ``change_s`` where a minimum-jerk move of that duration fits under
    ``max_lat_acc_mps2`` with the curve's share, else stretched until it does (with at
    least a tenth of the limit left, so that a change is never planned as endless)."""
    budget = max(p.max_lat_acc_mps2 - abs(curve_acc_mps2), 0.1 * p.max_lat_acc_mps2)
    return max(p.change_s, math.sqrt(MIN_JERK_PEAK * abs(move_m) / budget))


def decel_needed_mps2(closing_mps: float, gap_m: float, standstill_m: float) -> float:
    """Constant deceleration [m/s²] that removes ``closing_mps`` within the gap beyond s0."""
    if closing_mps <= 0.0:
        return 0.0
    room = gap_m - standstill_m
    return math.inf if room <= 0.0 else closing_mps**2 / (2.0 * room)


def lane_change_safety(scene: LaneScene, target: int, end_s_m: float, p: LaneChangeParams,
                       decel_bound_mps2: float, allow_shoulder: bool
                       ) -> tuple[bool, str, LaneCheck]:
    """(safe, why, check) for moving into relative lane ``target`` for a manoeuvre that
    ends at path position ``end_s_m`` (module docstring); ``decel_bound_mps2`` is b_safe,
    or the abort bound when re-checking a change under way."""
    name = _side_name(target - scene.ego_lane)
    slot = scene.slot(target)
    if slot is None:
        return False, f"no {name} lane", LaneCheck.NO_LANE
    kind = "shoulder" if slot.is_shoulder else "lane"
    need = end_s_m - scene.ego.s_m + p.lane_end_margin_m
    problem = _slot_problem(slot, name, kind, need, allow_shoulder)
    if problem is None:
        problem = _traffic_problem(scene, target, end_s_m, p, decel_bound_mps2, name, kind)
    if problem is not None:
        return False, problem[0], problem[1]
    return True, f"{name} {kind} free", LaneCheck.FREE


def _slot_problem(slot: LaneSlot, name: str, kind: str, need_m: float,
                  allow_shoulder: bool) -> tuple[str, LaneCheck] | None:
    """(why, check) when the lane ``slot`` (the ``name`` side's ``kind``: lane or
    shoulder) may not be entered, or does not continue ``need_m`` [m] ahead of the ego;
    None when it may."""
    if slot.is_shoulder and not allow_shoulder:
        return f"{name} is a shoulder (not allowed)", LaneCheck.SHOULDER_NOT_ALLOWED
    if not slot.allows_passenger and not slot.is_shoulder:
        return f"{name} lane bars passenger cars", LaneCheck.BARS_PASSENGER
    if slot.continues_m < need_m:
        return f"{name} {kind} ends in {slot.continues_m:.0f} m", LaneCheck.ENDS
    return None


def _traffic_problem(scene: LaneScene, target: int, end_s_m: float, p: LaneChangeParams,
                     bound: float, name: str, kind: str) -> tuple[str, LaneCheck] | None:
    """(why, check) when traffic in relative lane ``target`` (the ``name`` side's
    ``kind``: lane or shoulder) forbids a manoeuvre ending at ``end_s_m`` [m]: a stopped
    vehicle along it, or a gap to the car ahead or behind too short for deceleration
    ``bound`` [m/s²]; None when it is free."""
    v = scene.ego.speed_mps
    in_lane = scene.rel_lane == target
    stationary = in_lane & (np.abs(scene.fn.v_s_mps) < 0.5)
    reach = 0.5 * (scene.fn.length_m + scene.ego_length_m) + p.standstill_m
    ds = scene.ds_m
    if np.any(stationary & (ds > -reach) & (ds < end_s_m - scene.ego.s_m + reach)):
        return f"{name} {kind} blocked by a stopped vehicle", LaneCheck.STOPPED_VEHICLE
    lead = scene.lead(target)
    if lead is not None:
        why, check = _front_problem(lead, v, p, bound)
        if check is not None:
            return f"{name} gap too short ({why})", check
    rear = scene.follower(target)
    if rear is not None:
        why, check = _rear_problem(rear, v, p, bound)
        if check is not None:
            return f"{name} gap too short ({why})", check
    return None


def _front_problem(lead: Neighbour, v: float, p: LaneChangeParams, bound: float
                   ) -> tuple[str, LaneCheck | None]:
    if lead.gap_m < p.standstill_m + p.front_time_gap_s * v:
        return f"{lead.gap_m:.0f} m to the car ahead", LaneCheck.FRONT_GAP
    if decel_needed_mps2(v - lead.speed_mps, lead.gap_m, p.standstill_m) > bound:
        return "closing on the car ahead", LaneCheck.CLOSING_AHEAD
    return "", None


def _rear_problem(rear: Neighbour, v: float, p: LaneChangeParams, bound: float
                  ) -> tuple[str, LaneCheck | None]:
    if rear.gap_m < p.standstill_m + p.rear_time_gap_s * max(rear.speed_mps, 0.0):
        return f"{rear.gap_m:.0f} m to the car behind", LaneCheck.REAR_GAP
    if decel_needed_mps2(rear.speed_mps - v, rear.gap_m, p.standstill_m) > bound:
        return "a faster car closing from behind", LaneCheck.CLOSING_FROM_BEHIND
    return "", None


def _side_name(step: int) -> str:
    return "left" if step > 0 else ("right" if step < 0 else "own")
