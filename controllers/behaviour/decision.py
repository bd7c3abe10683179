"""Lane behaviour: which lane to be in, how fast to go, and the obstacles to plan around.

Per step, from the scene (:mod:`controllers.behaviour.perception`: every vehicle in a lane
relative to the reference lane, leads and followers per lane):

1. **The lane plan** (``_Plan``): keep a lane, or change from one lane into a neighbour.
   * Keeping lane c, a change is *wanted* to pass (a neighbour lane's speed, the speed of
     its lead within the planning range or the cruise speed, beats lane c's by
     ``incentive_mps``: a stopped or slower car ahead; on the right only a stopped or
     crawling one, a moving car is never undertaken), to return towards the home lane
     (the reference lane: the lane the catalog asked for) once the passed vehicle is
     ``pass_after_m`` behind and the home lane is as fast, or because lane c ends. Left is
     tried before right. A wanted change starts when it is safe
     (:func:`controllers.behaviour.lane_change.lane_change_safety`: lead and follower of
     the target lane, MOBIL's bound on the new follower's braking) and the lane has been
     kept for ``hold_s`` (sooner behind a stopped vehicle or a lane that ends).
   * Changing, the change is re-checked with a looser bound until the commit point (half
     the lateral move) and *aborted* (back to the origin lane) if the gap closes; it is
     complete within ``done_tolerance_m`` of the target lane's centre.
2. **The speed target**: the car-following set-point
   (:mod:`controllers.behaviour.following`, with the lead's acceleration estimated from
   its speeds by :mod:`controllers.behaviour.tracking`) behind the lead of the lane kept, or, during
   a change, behind the target lane's lead and, until the ego can clear it, the origin
   lane's; behind the end of a lane that ends. A moving car ahead is always followed by
   the speed target, never by an ellipse alone.
3. **The lateral reference**: the centre of the plan's lane, from the reference lane's.
4. **Obstacles** (:mod:`controllers.behaviour.obstacle_choice`): ellipses
   (:mod:`controllers.behaviour.ellipses`) for the vehicles within the detection
   distance in every lane the ego's box occupies and in the plan's lanes, the leads
   first, never a car behind in the lane kept or left (only the lane moved into counts
   behind the ego); the vehicle being passed shifted away from the pass side; a lead the
   ego must follow made a wall across the carriageway (B of ten lane widths: no way
   round and no sideways push); an ellipse that would contain the ego (a car in the next
   lane alongside) narrowed to leave it outside (its barrier would be undefined there).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from controllers.behaviour.following import follow_speed_mps
from controllers.behaviour.lane_change import (
    change_duration_s,
    decel_needed_mps2,
    lane_change_safety,
)
from controllers.behaviour.lane_plan import BehaviourParams, EgoShape, _Plan, _Want
from controllers.behaviour.obstacle_choice import pass_side, plan_ellipses, select_obstacles
from controllers.behaviour.perception import (
    LaneScene,
    Neighbour,
    project_traffic,
    relative_lanes,
)
from controllers.behaviour.tracking import AccelerationTracker
from controllers.behaviour.types import (
    Decision,
    EgoFrenet,
    LaneCheck,
    LaneContext,
    ObstaclePolicy,
    Reason,
    Traffic,
)
from controllers.path.frenet import FrenetPath

__all__ = ["BehaviourParams", "EgoShape", "LaneBehaviour"]


IntpArray = npt.NDArray[np.intp]


_LANE_CHANGE_RATE_MPS = 1.2  # lateral speed of a change, for "can the ego clear it in time"
_BESIDE_MARGIN_M = 0.3  # lateral room between the boxes of a car the ego is beside [m]


@dataclass
class LaneBehaviour:
    """The :class:`controllers.behaviour.protocol.Behaviour` of hwyeval (module docstring).

    path: the controller's reference path; policy: the controller's obstacle policy;
    ego: its box; lane_width_m: the reference lane's width at the start [m] (lane
    spacing where the lane context has no offsets); params: following and lane changes.
    """

    path: FrenetPath
    policy: ObstaclePolicy
    ego: EgoShape
    lane_width_m: float
    params: BehaviourParams = field(default_factory=BehaviourParams)
    _plan: _Plan | None = field(default=None, init=False)
    _tracker: AccelerationTracker = field(default_factory=AccelerationTracker, init=False)
    _accel: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0), init=False)
    # the lane changes this step weighed: (target lane relative to the ego's, check)
    _checks: list[tuple[int, LaneCheck]] = field(default_factory=list, init=False)

    # ------------------------------------------------------------------ the step
    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        self._checks = []
        self._accel = self._tracker.update(ego.t_s, traffic)
        scene = self._scene(ego, traffic, lanes)
        plan = self._plan or _Plan(scene.ego_lane, scene.ego_lane, -math.inf)
        plan, code, reason, follow = self._update(scene, plan, set_speed_mps)
        self._plan = plan
        target, lead = self._speed(scene, plan, set_speed_mps)
        side = pass_side(plan, follow)
        order = select_obstacles(scene, plan, lead, self.policy)
        obstacles = plan_ellipses(scene, order, plan, side, lead if follow else -1, self.policy,
                                  self.ego.length_m, self.ego.width_m, self.lane_width_m,
                                  self._accel)
        return Decision(obstacles=obstacles, side=side, reason=reason, target_speed_mps=target,
                        lateral_reference_m=scene.offset_m(plan.lane),
                        evasive=plan.changing and plan.evasive, reason_code=code,
                        lane_checks=tuple(self._checks))

    def _scene(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext) -> LaneScene:
        fn = project_traffic(self.path, traffic, ego)
        # lateral speeds only where they are a deliberate motion (tracking.py): what every
        # reader of the scene sees (the cut-in prediction, a ramp car's entry heading,
        # the ellipses' predicted motion), so a recording's jitter is none of these
        fn = replace(fn, v_y_mps=self._tracker.lateral(ego.t_s, traffic.ids, fn.v_y_mps))
        rel = relative_lanes(traffic, fn, lanes, self.lane_width_m)
        scene = LaneScene(ego, self.ego.length_m, self.ego.width_m, traffic, fn, rel, lanes,
                          {}, self.lane_width_m)
        order = sorted(lanes.slots)
        ref = lanes.reference_index
        if ref in order:
            scene.lanes.update({k - order.index(ref): lanes.slots[index]
                                for k, index in enumerate(order)})
        elif lanes.slots:
            scene.lanes[0] = next(iter(lanes.slots.values()))
        return scene

    # ------------------------------------------------------------------ lane plan
    def _update(self, sc: LaneScene, plan: _Plan, set_speed: float
                ) -> tuple[_Plan, Reason, str, bool]:
        """(new plan, why: code and text, following): advance a change, or start one that
        is wanted."""
        lc = self.params.lane_change
        t = sc.ego.t_s
        if plan.changing:
            return self._advance_change(sc, plan)
        want, blocked_by = self._wanted(sc, plan, set_speed)
        if not want:
            lead = blocked_by
            if lead is not None:
                lid = sc.traffic.ids[lead.index]
                return plan, Reason.FOLLOW, f"follow {lid} (no faster lane)", True
            return (plan, Reason.KEEP, "keep lane: free" if plan.lane == 0 else "keep lane",
                    False)
        reasons = []
        for w in want:
            curve = self._curve_acc_mps2(sc, w.end_s_m)
            side = w.target - sc.ego_lane
            if not w.urgent and lc.max_lat_acc_mps2 - curve < lc.change_lat_acc_mps2:
                reasons.append(f"{w.why}: the curve takes {curve:.1f} m/s² lateral")
                self._checks.append((side, LaneCheck.CURVE))
                continue
            bound = lc.evasive_decel_mps2 if w.evasive else lc.safe_decel_mps2
            ok, why, check = lane_change_safety(sc, w.target, w.end_s_m, lc, bound,
                                                self.ego.allow_shoulder)
            if not ok:
                reasons.append(why)
                self._checks.append((side, check))
                continue
            conflict = self._merge_conflict(sc, w.target)
            if conflict:
                reasons.append(conflict)
                self._checks.append((side, LaneCheck.MERGE_CONFLICT))
                continue
            if t - plan.since_s < lc.hold_s and not w.urgent:
                reasons.append(f"{w.why}: holding the lane for {lc.hold_s:g} s")
                self._checks.append((side, LaneCheck.HOLDING))
                continue
            self._checks.append((side, LaneCheck.FREE))
            new = _Plan(w.target, plan.lane, t, w.passing, w.evasive, w.end_s_m)
            tried = f" ({'; '.join(reasons)})" if reasons else ""
            return new, w.kind, f"{w.why}: {why}{tried}", False
        if blocked_by is not None:
            lid = sc.traffic.ids[blocked_by.index]
            return plan, Reason.FOLLOW, f"follow {lid}: " + "; ".join(reasons), True
        return plan, Reason.KEEP, "keep lane: " + "; ".join(reasons), False

    def _advance_change(self, sc: LaneScene, plan: _Plan) -> tuple[_Plan, Reason, str, bool]:
        lc = self.params.lane_change
        t = sc.ego.t_s
        start, goal = sc.offset_m(plan.origin), sc.offset_m(plan.lane)
        span = goal - start
        progress = (sc.ego.lat_m - start) / span if abs(span) > 1e-6 else 1.0
        side = "left" if plan.lane > plan.origin else "right"
        if abs(sc.ego.lat_m - goal) < lc.done_tolerance_m:
            return (_Plan(plan.lane, plan.lane, t, plan.passing), Reason.IN_LANE,
                    f"in the {side} lane", False)
        if progress < lc.commit_fraction:
            # The stretch the change was started on (a new one only for a plan without):
            # a different stretch for the re-check would flip a decision the start
            # check just took (a stopped car beyond the first, inside the second).
            end = plan.end_s_m if math.isfinite(plan.end_s_m) else \
                sc.ego.s_m + self._change_length_m(sc, plan.lane)
            end = max(end, sc.ego.s_m + lc.standstill_m)
            bound = lc.evasive_decel_mps2 if plan.evasive else lc.abort_decel_mps2
            ok, why, check = lane_change_safety(sc, plan.lane, end, lc, bound,
                                                self.ego.allow_shoulder)
            self._checks.append((plan.lane - sc.ego_lane, check))
            if not ok and not self._evasion_beats_abort(sc, plan):
                return (_Plan(plan.origin, plan.origin, t, plan.passing), Reason.ABORT,
                        f"abort {side}: {why}", False)
        if plan.passing:
            return plan, Reason.PASSING, f"passing {plan.passing}", False
        return plan, Reason.CHANGING, f"changing {side}", False

    def _evasion_beats_abort(self, sc: LaneScene, plan: _Plan) -> bool:
        """An evasive change whose gap closes: aborting means stopping for the stopped
        car in the origin lane, carrying on means the new follower brakes. Carry on when
        the ego's stop would need the harder braking (the lesser harm)."""
        if not plan.evasive:
            return False
        lead = sc.lead(plan.origin)
        if lead is None:
            return False
        stop = decel_needed_mps2(sc.ego.speed_mps, lead.gap_m, 1.0)
        rear = sc.follower(plan.lane)
        follower = 0.0 if rear is None else decel_needed_mps2(
            rear.speed_mps - sc.ego.speed_mps, rear.gap_m, 1.0)
        return stop > follower

    def _lane_speed(self, sc: LaneScene, rel: int, set_speed: float
                    ) -> tuple[float, Neighbour | None]:
        """Steady speed in lane ``rel``: its lead's within the planning range, else the
        cruise speed; and that lead."""
        lc = self.params.lane_change
        lead = sc.lead(rel)
        horizon = max(self.policy.detection_distance_m,
                      sc.ego.speed_mps * lc.plan_horizon_s,
                      sc.ego.speed_mps**2 / (2.0 * self.params.follow.comfort_decel_mps2)
                      + self.params.follow.standstill_m + 30.0)
        if lead is None or lead.gap_m > horizon:
            return set_speed, None
        return min(set_speed, max(lead.speed_mps, 0.0)), lead

    def _wanted(self, sc: LaneScene, plan: _Plan, set_speed: float
                ) -> tuple[list[_Want], Neighbour | None]:
        """The changes wanted from the kept lane, in order of preference, and the lead
        that holds the ego back (None if it does not)."""
        lc = self.params.lane_change
        c = plan.lane
        v_here, lead = self._lane_speed(sc, c, set_speed)
        wants: list[_Want] = []
        # A lead blocks when it is slower than the set speed by the margin, or by half
        # the set speed when that is less: at a crawl (0.9 m/s in a jam) a stopped lead
        # could never be 1 m/s slower, and was never followed.
        blocked = lead is not None and v_here < set_speed - min(lc.block_margin_mps,
                                                                 0.5 * set_speed)
        stopped = lead is not None and abs(lead.speed_mps) < 0.5
        if blocked and lead is not None:
            # The pass's stretch: beyond the passed car, and at least a whole change
            # (a stopped car just beyond the first would otherwise only show in the
            # re-check, over the longer stretch, and flip the decision a step later).
            end = max(float(sc.fn.s_m[lead.index] + 0.5 * sc.fn.length_m[lead.index]
                            + lc.pass_after_m),
                      sc.ego.s_m + self._change_length_m(sc, c + 1))
            lid = sc.traffic.ids[lead.index]
            evasive = stopped and self._needs_evasion(sc.ego.speed_mps, lead.gap_m)
            for step, name in ((1, "left"), (-1, "right")):
                if step < 0 and lead.speed_mps >= lc.undertake_below_mps:
                    continue  # never undertake a moving car (keep-right rule)
                v_there, _ = self._lane_speed(sc, c + step, set_speed)
                if v_there - v_here > lc.incentive_mps:
                    wants.append(_Want(c + step, end, f"pass {lid} on the {name}", stopped, lid,
                                       evasive, Reason.PASS))
        wants += self._lane_end_wants(sc, c)
        if c != 0 and not wants and self._passed(sc, plan):
            home = c - int(math.copysign(1, c))
            v_home, _ = self._lane_speed(sc, home, set_speed)
            if v_home >= v_here - 0.5 and not self._merging_into(sc, home):
                name = "right" if home < c else "left"
                wants.append(_Want(home, sc.ego.s_m + self._change_length_m(sc, home),
                                   f"return {name}", False, kind=Reason.RETURN))
        if not wants:
            wants += self._courtesy_wants(sc, c, v_here, set_speed)
        return wants, (lead if blocked else None)

    def _lane_end_wants(self, sc: LaneScene, c: int) -> list[_Want]:
        """Leaving a lane that ends: one direction, towards the reference lane (a through
        lane: the lanes beside an ending lane that continue are on that side), held
        until done; urgent (no hold time) once the end is within 8 s plus 50 m; the
        stretch checked is the move's, or the rest of the lane when that is shorter."""
        slot = sc.slot(c)
        if c == 0 or slot is None or not math.isfinite(slot.continues_m):
            return []
        toward = -1 if c > 0 else 1
        if sc.slot(c + toward) is None:
            return []
        horizon = max(sc.ego.speed_mps, 5.0) * 8.0 + 50.0
        length = min(slot.continues_m, self._change_length_m(sc, c + toward))
        return [_Want(c + toward, sc.ego.s_m + length,
                      f"lane ends in {slot.continues_m:.0f} m",
                      slot.continues_m < horizon, kind=Reason.LANE_ENDS)]

    def _merging_into(self, sc: LaneScene, rel: int) -> list[int]:
        """Vehicles that will merge into lane ``rel`` near the ego: on a lane that ends
        (:meth:`LaneScene.merging_near`), or entering from an on-ramp on a side where
        ``rel`` is the outermost regular lane (:meth:`LaneScene.entering_near`)."""
        lc = self.params.lane_change
        near = sc.merging_near(rel, lc.merge_behind_m, lc.merge_ahead_m)
        return near + [j for j, side in self._entering(sc) if self._outermost(sc, rel, side)]

    def _merge_conflict(self, sc: LaneScene, target: int) -> str:
        """Why a change into relative lane ``target`` would meet a vehicle merging into it
        ('' none): the gap rules of :func:`lane_change_safety` (front and rear time gaps
        over ``standstill_m``) applied to each vehicle merging into that lane (from a
        lane that ends, or an on-ramp, not yet in it: the lane's own gap check does not
        see it) at its position now and 1, 2 and 3 s on, both speeds held."""
        lc = self.params.lane_change
        v = sc.ego.speed_mps
        for j in self._merging_into(sc, target):
            ds, v_j = float(sc.ds_m[j]), float(sc.fn.v_s_mps[j])
            half = 0.5 * (float(sc.fn.length_m[j]) + self.ego.length_m)
            for t_s in (0.0, 1.0, 2.0, 3.0):
                d = ds + (v_j - v) * t_s
                need = lc.standstill_m + (lc.front_time_gap_s * v if d >= 0.0
                                          else lc.rear_time_gap_s * max(v_j, 0.0))
                if abs(d) - half < need:
                    side = "left" if target > sc.ego_lane else "right"
                    return f"{side} lane: {sc.traffic.ids[j]} merging into it"
        return ""

    def _entering(self, sc: LaneScene) -> list[tuple[int, int]]:
        lc = self.params.lane_change
        return sc.entering_near(lc.merge_behind_m, lc.merge_ahead_m)

    @staticmethod
    def _outermost(sc: LaneScene, rel: int, side: int) -> bool:
        """Only shoulders and lanes that end lie beyond relative lane ``rel`` on ``side``
        (+1 left, -1 right): traffic entering there merges into ``rel``."""
        slot = sc.slot(rel)
        if slot is None or slot.is_shoulder:
            return False
        beyond = [r for r in sc.lanes if (r - rel) * side > 0]
        return all(sc.lanes[r].is_shoulder or math.isfinite(sc.lanes[r].continues_m)
                   for r in beyond)

    def _courtesy_wants(self, sc: LaneScene, c: int, v_here: float, set_speed: float
                        ) -> list[_Want]:
        """Make room: traffic merging into the ego's lane near it (from a lane that
        ends beside it, or entering from an on-ramp while nothing but shoulders and
        ending lanes lies between the ego's lane and the ramp) that comes within the
        ego's gap rules in the next 3 s (:meth:`_merge_conflict`), and the lane on the
        far side as fast and continuing: move there, not urgent (the gap rules and the
        hold time apply), and return once they have merged (:meth:`_merging_into`). A
        merger that will be well ahead or behind is no reason to leave the lane."""
        merging = [(j, int(math.copysign(1, float(sc.fn.y_m[j]) - sc.offset_m(c))))
                   for j in self._merging_into(sc, c)]
        if not merging or not self._merge_conflict(sc, c):
            return []  # nobody merges within the gap rules of the ego: no need to move
        sides = {side for _, side in merging}
        if len(sides) != 1:
            return []  # merging from both sides: nowhere to make room
        away = -sides.pop()
        slot = sc.slot(c + away)
        if slot is None or slot.is_shoulder or not math.isinf(slot.continues_m):
            return []
        v_there, _ = self._lane_speed(sc, c + away, set_speed)
        if v_there < v_here - 0.5:
            return []
        first = sc.traffic.ids[merging[0][0]]
        name = "left" if away > 0 else "right"
        return [_Want(c + away, sc.ego.s_m + self._change_length_m(sc, c + away),
                      f"make room for {first} merging: {name}", False,
                      kind=Reason.MAKE_ROOM)]

    def _change_length_m(self, sc: LaneScene, target: int) -> float:
        """Path length [m] of a change into relative lane ``target`` at the ego's speed:
        :func:`change_duration_s` with the curve over the nominal stretch."""
        lc = self.params.lane_change
        v = max(sc.ego.speed_mps, 5.0)
        nominal = v * lc.change_s
        move = abs(sc.offset_m(target) - sc.ego.lat_m)
        curve = self._curve_acc_mps2(sc, sc.ego.s_m + nominal)
        return v * change_duration_s(move, curve, lc)

    def _curve_acc_mps2(self, sc: LaneScene, end_s_m: float) -> float:
        """v² max |kappa| [m/s²] of the reference over [ego s, ``end_s_m``] (at least a
        change's nominal stretch): the lateral acceleration the road itself asks."""
        v = max(sc.ego.speed_mps, 0.0)
        lc = self.params.lane_change
        end = max(end_s_m, sc.ego.s_m + max(v, 5.0) * lc.change_s)
        s = np.linspace(sc.ego.s_m, min(end, self.path.length_m), 16)
        return float(v * v * np.max(np.abs(self.path.kappa(s))))

    def _needs_evasion(self, speed_mps: float, gap_m: float) -> bool:
        """Stopping s0 short of a stopped car ``gap_m`` ahead needs more than the
        comfortable deceleration: passing it is an evasive manoeuvre."""
        fp = self.params.follow
        room = gap_m - fp.standstill_m
        return room <= 0.0 or speed_mps**2 / (2.0 * room) > fp.comfort_decel_mps2 * 1.5

    def _passed(self, sc: LaneScene, plan: _Plan) -> bool:
        """The vehicle being passed is gone or ``pass_after_m`` behind the ego's rear."""
        if not plan.passing or plan.passing not in sc.traffic.ids:
            return True
        j = sc.traffic.ids.index(plan.passing)
        behind = sc.ego.s_m - (float(sc.fn.s_m[j]) + 0.5 * (float(sc.fn.length_m[j])
                                                            + self.ego.length_m))
        return behind >= self.params.lane_change.pass_after_m

    # ------------------------------------------------------------------ speed
    def _speed(self, sc: LaneScene, plan: _Plan, set_speed: float) -> tuple[float, int]:
        """(speed target, index of the lead it follows or -1)."""
        fp = self.params.follow
        v = sc.ego.speed_mps
        target, lead_index = set_speed, -1
        lanes = [plan.lane] if not plan.changing else [plan.lane, plan.origin]
        for rel in lanes:
            lead = sc.lead(rel)
            if lead is None:
                continue
            if rel == plan.origin and plan.changing and (plan.evasive
                                                          or self._clears(sc, plan, lead)):
                continue  # an evasive change goes round it: braking to it only hinders
            vt = follow_speed_mps(lead.gap_m, lead.speed_mps, v, set_speed, fp,
                                  float(self._accel[lead.index]))
            if vt < target:
                target, lead_index = vt, lead.index
        for j in self._merging_into(sc, plan.lane):
            vt = self._let_in_speed_mps(sc, j, set_speed)
            if vt < target:
                target, lead_index = vt, j
        # Keeping a lane that ends: stop before its end unless a change takes the ego out.
        slot = sc.slot(plan.lane)
        if not plan.changing and slot is not None and math.isfinite(slot.continues_m):
            target = min(target, follow_speed_mps(slot.continues_m - 5.0, 0.0, v, set_speed, fp))
        return target, lead_index

    def _let_in_speed_mps(self, sc: LaneScene, j: int, set_speed: float) -> float:
        """Speed target that lets merging vehicle ``j`` in ahead, if it will get there
        first: not yet ahead of the ego's CG (a lead otherwise), at speed v_j with
        ``room`` metres of its lane left, it must merge within tau = room / v_j; with
        both speeds held its centre is then ds + (v_j - v) tau ahead of the ego's. Ahead
        then: the car-following set-point behind it at that predicted gap, so the ego
        eases off early and the gap opens before the merge, instead of braking hard when
        it cuts in. Behind then: no constraint (it merges behind the ego)."""
        ds = float(sc.ds_m[j])
        if ds > 0.0:
            return set_speed  # ahead already: a lead of the lane (LaneScene.merging)
        v, v_j = sc.ego.speed_mps, max(float(sc.fn.v_s_mps[j]), 0.0)
        room = sc.merge_room_m(j)
        if not math.isfinite(room) or v_j < 1.0:
            return set_speed
        tau = max(room, 0.0) / v_j
        ahead = ds + (v_j - v) * tau
        half = 0.5 * (float(sc.fn.length_m[j]) + self.ego.length_m)
        if ahead <= 0.0:
            return set_speed
        return follow_speed_mps(max(ahead - half, 0.0), v_j, v, set_speed, self.params.follow)

    def _clears(self, sc: LaneScene, plan: _Plan, lead: Neighbour) -> bool:
        """During a change: will the ego be out of the origin lane before it reaches the
        origin lane's lead? (Then that lead does not lower the speed target.)"""
        start, goal = sc.offset_m(plan.origin), sc.offset_m(plan.lane)
        width = sc.lanes[plan.origin].width_m if plan.origin in sc.lanes else self.lane_width_m
        clear_at = 0.5 * (width + self.ego.width_m)
        # Clear once out of the origin lane, or beside the lead's box with a margin (a
        # stopped car in the lane's middle leaves the lane's edge 0.5 m further out).
        beside = abs(float(sc.fn.y_m[lead.index]) - start) + 0.5 * (
            float(sc.fn.width_m[lead.index]) + self.ego.width_m) + _BESIDE_MARGIN_M
        left = max(min(clear_at, beside) - abs(sc.ego.lat_m - start), 0.0)
        if left <= 0.0:
            return True  # clear already (t_reach > 0 below never holds beside it)
        t_lateral = left / _LANE_CHANGE_RATE_MPS
        closing = sc.ego.speed_mps - lead.speed_mps
        if closing <= 0.1:
            return True
        t_reach = max(lead.gap_m - 1.0, 0.0) / closing
        return bool(t_reach > t_lateral and abs(goal - start) > 0.0)


