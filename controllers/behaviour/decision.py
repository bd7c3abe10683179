"""Lane behaviour: which vehicle blocks the ego, which side to pass it on, the obstacles.

Per step (all arrays, no simulator calls):

1. Project every vehicle onto the reference path (:mod:`controllers.behaviour.perception`).
2. The *blocker* is the nearest vehicle ahead that overlaps the reference lane laterally,
   lies within the planning range (the longest of the detection distance, ``v
   plan_horizon_s`` and the comfortable stopping distance + 30 m) and is slower than the
   ego by more than 1 m/s (stalled cars always).
3. Pass side for the blocker: a neighbour lane qualifies when it exists at the ego's
   position, admits passenger cars or is a shoulder the scenario allows, and has a free
   gap (:func:`controllers.behaviour.gap.gap_is_free`). Left is tried first (overtake on
   the left); with no side free the ego follows: the blocker's ellipse is widened across
   the lane and the speed target drops to the follow speed. A side, once the ego has
   moved more than ``commit_offset_m`` towards it, is kept for that blocker.
4. The lateral reference is the pass lane's centre (signed distance between lane
   centres) until the ego is ``pass_after_m`` beyond the passed vehicle.
5. Ellipses (:mod:`controllers.behaviour.ellipses`) for vehicles within the detection
   distance in the lanes the ego occupies or is moving into, nearest first; the blocker
   always among them, its centre offset away from the pass side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from controllers.behaviour.ellipses import ellipse_semi_axes, offset_centre_y
from controllers.behaviour.gap import GapPolicy, follow_speed_mps, gap_is_free
from controllers.behaviour.perception import FrenetTraffic, project_traffic
from controllers.behaviour.types import (
    SIDE_FOLLOW,
    SIDE_LEFT,
    SIDE_NONE,
    SIDE_RIGHT,
    Decision,
    EgoFrenet,
    LaneContext,
    ObstaclePolicy,
    Obstacles,
    Traffic,
)
from controllers.path.frenet import FrenetPath

IntArray = npt.NDArray[np.int64]
_LANE_END_MARGIN_M = 20.0  # a pass lane must continue this far beyond the manoeuvre


@dataclass(frozen=True)
class EgoShape:
    """The ego's box [m] and whether it may use a hard shoulder."""

    length_m: float
    width_m: float
    allow_shoulder: bool = False


@dataclass
class _Scene:
    """One step's inputs, projected (internal to :class:`LaneBehaviour`)."""

    ego: EgoFrenet
    traffic: Traffic
    fn: FrenetTraffic
    lanes: LaneContext
    ds: np.ndarray
    lane_rel: IntArray


@dataclass
class _Pass:
    """The vehicle being passed: side and lateral reference [m], kept until the ego is
    ``pass_after_m`` beyond its rear so the car does not cut back in early."""

    vehicle_id: str
    side: int
    lateral_reference_m: float


@dataclass
class LaneBehaviour:
    """The :class:`controllers.behaviour.protocol.Behaviour` of hwyeval (module docstring).

    path: the controller's reference path; policy: the controller's obstacle policy;
    ego: its box; lane_width_m: the reference lane's width at the start [m] (bins
    vehicles into lanes relative to the reference lane); gap: gap and follow rules.
    """

    path: FrenetPath
    policy: ObstaclePolicy
    ego: EgoShape
    lane_width_m: float
    gap: GapPolicy = field(default_factory=GapPolicy)
    _committed: dict[str, int] = field(default_factory=dict, init=False)
    _passing: _Pass | None = field(default=None, init=False)

    def decide(self, ego: EgoFrenet, traffic: Traffic, lanes: LaneContext,
               set_speed_mps: float) -> Decision:
        if traffic.count == 0 or self.policy.max_obstacles == 0:
            return Decision(side=SIDE_NONE, reason="no obstacle", target_speed_mps=set_speed_mps)
        fn = project_traffic(self.path, traffic, ego)
        scene = _Scene(ego, traffic, fn, lanes, fn.s_m - ego.s_m, self._lanes_of(fn.y_m, lanes))
        blocker = self._blocker(scene)
        side, reason, target = SIDE_NONE, "no obstacle in lane", set_speed_mps
        if blocker >= 0:
            side, reason = self._choose_side(scene, blocker)
            if side == SIDE_FOLLOW:
                target = self._follow_target(scene, blocker, set_speed_mps)
        lat_ref = 0.0
        if blocker < 0 and self._passing is not None:
            side, reason, lat_ref, blocker = self._hold_pass(scene, side, reason)
        elif self._passing is not None:
            lat_ref = self._passing.lateral_reference_m
        order = self._select(scene, side, blocker)
        obstacles = self._ellipses(scene, order, side, blocker)
        return Decision(obstacles=obstacles, side=side, reason=reason, target_speed_mps=target,
                        lateral_reference_m=lat_ref,
                        obstacle_ids=tuple(traffic.ids[i] for i in order))

    # ------------------------------------------------------------------ steps
    def _lanes_of(self, y_m: np.ndarray, lanes: LaneContext) -> IntArray:
        """Lane of each lateral offset relative to the reference lane (0; left +1, right
        -1, ...): the nearest lane centre of the lane context where all offsets are
        known, else multiples of the lane width."""
        order = sorted(lanes.slots)
        offsets = np.array([lanes.slots[i].offset_m for i in order], dtype=np.float64)
        if not order or not np.all(np.isfinite(offsets)) or lanes.reference_index not in order:
            return np.rint(y_m / self.lane_width_m).astype(np.int64)
        nearest = np.argmin(np.abs(np.asarray(y_m)[:, None] - offsets[None, :]), axis=1)
        # Beyond the outermost lanes keep counting in lane widths (a car on a shoulder
        # the context does not list, or a lane the context has not reached yet).
        rel = nearest - order.index(lanes.reference_index)
        left = np.asarray(y_m) > offsets[-1] + 0.5 * self.lane_width_m
        right = np.asarray(y_m) < offsets[0] - 0.5 * self.lane_width_m
        rel = np.where(left, len(order) - 1 - order.index(lanes.reference_index)
                       + np.rint((np.asarray(y_m) - offsets[-1]) / self.lane_width_m), rel)
        rel = np.where(right, -order.index(lanes.reference_index)
                       + np.rint((np.asarray(y_m) - offsets[0]) / self.lane_width_m), rel)
        return rel.astype(np.int64)

    def _reference_offset_m(self, lanes: LaneContext) -> float:
        """The reference lane's centre from the path [m] (0 unless the path crosses
        between lane centres, as it does where netconvert shifts lanes)."""
        ref = lanes.slot(lanes.reference_index)
        return ref.offset_m if ref is not None and math.isfinite(ref.offset_m) else 0.0

    def _blocker(self, sc: _Scene) -> int:
        """Index of the nearest blocking vehicle ahead (-1 if none)."""
        pol, g, v = self.policy, self.gap, sc.ego.speed_mps
        plan_range = max(pol.detection_distance_m, v * g.plan_horizon_s,
                         v**2 / (2.0 * g.follow_decel_mps2) + g.follow_standstill_m + 30.0)
        ref_y = self._reference_offset_m(sc.lanes)
        overlap_lat = np.abs(sc.fn.y_m - ref_y) < 0.5 * (self.lane_width_m + sc.fn.width_m) - 0.2
        slower = (sc.fn.v_s_mps < v - 1.0) | sc.traffic.stalled
        blocking = overlap_lat & slower & (sc.ds > 0) & (sc.ds <= plan_range)
        if not pol.moving_obstacles:
            blocking &= sc.traffic.stalled
        if not np.any(blocking):
            return -1
        return int(np.flatnonzero(blocking)[np.argmin(sc.ds[blocking])])

    def _choose_side(self, sc: _Scene, blocker: int) -> tuple[int, str]:
        """Pass side and reason for ``blocker``; updates the commitment and pass memory."""
        bid = sc.traffic.ids[blocker]
        side = SIDE_NONE
        reason = ""
        committed = self._committed.get(bid)
        if committed in (SIDE_LEFT, SIDE_RIGHT):
            ok, why = self._side_ok(committed, sc, blocker)
            if ok or committed * sc.ego.lat_m > self.gap.commit_offset_m:
                side, reason = committed, (why if ok else "committed " + why)
        if side == SIDE_NONE:
            reasons = []
            for cand in (SIDE_LEFT, SIDE_RIGHT):
                ok, why = self._side_ok(cand, sc, blocker)
                reasons.append(why)
                if ok:
                    side = cand
                    reason = why + (f" ({reasons[0]})" if len(reasons) > 1 else "")
                    break
            if side == SIDE_NONE:
                side, reason = SIDE_FOLLOW, "follow: " + "; ".join(reasons)
        if side in (SIDE_LEFT, SIDE_RIGHT):
            if side * sc.ego.lat_m > self.gap.commit_offset_m:
                self._committed[bid] = side
            self._passing = _Pass(bid, side, self._lane_offset_m(side, sc.lanes))
        else:
            self._passing = None
        return side, reason

    def _side_ok(self, side: int, sc: _Scene, blocker: int) -> tuple[bool, str]:
        name = "left" if side > 0 else "right"
        slot = sc.lanes.slot(sc.lanes.reference_index + side)
        if slot is None:
            return False, f"no {name} lane"
        if slot.is_shoulder and not self.ego.allow_shoulder:
            return False, f"{name} is a shoulder (not allowed)"
        if not slot.allows_passenger and not slot.is_shoulder:
            return False, f"{name} lane bars passenger cars"
        fn = sc.fn
        needed = (float(fn.s_m[blocker]) + 0.5 * float(fn.length_m[blocker])
                  + self.gap.pass_after_m - sc.ego.s_m + _LANE_END_MARGIN_M)
        if slot.continues_m < needed:
            return False, f"{name} lane ends in {slot.continues_m:.0f} m"
        in_lane = sc.lane_rel == side
        in_lane[blocker] = False
        free = gap_is_free(sc.ego.s_m, sc.ego.speed_mps, self.ego.length_m,
                           float(fn.s_m[blocker]), float(fn.length_m[blocker]),
                           fn.s_m[in_lane], fn.v_s_mps[in_lane], fn.length_m[in_lane], self.gap)
        if not free:
            return False, f"{name} gap occupied"
        return True, f"{name} {'shoulder' if slot.is_shoulder else 'lane'} free"

    def _follow_target(self, sc: _Scene, blocker: int, set_speed_mps: float) -> float:
        gap_m = max(float(sc.ds[blocker])
                    - 0.5 * (sc.fn.length_m[blocker] + self.ego.length_m), 0.0)
        return follow_speed_mps(gap_m, max(float(sc.fn.v_s_mps[blocker]), 0.0),
                                set_speed_mps, self.gap)

    def _hold_pass(self, sc: _Scene, side: int, reason: str) -> tuple[int, str, float, int]:
        """No blocker ahead: keep passing the remembered vehicle until it is behind."""
        held = self._passing
        if held is None:  # pragma: no cover - guarded by the caller
            return side, reason, 0.0, -1
        ids = sc.traffic.ids
        idx = ids.index(held.vehicle_id) if held.vehicle_id in ids else -1
        behind_by = (sc.ego.s_m - (sc.fn.s_m[idx] + 0.5 * (sc.fn.length_m[idx]
                                                            + self.ego.length_m))
                     if idx >= 0 else math.inf)
        if behind_by < self.gap.pass_after_m:
            # The pass lane's centre where the ego is now (lanes shift at junctions).
            return (held.side, f"passing {held.vehicle_id}",
                    self._lane_offset_m(held.side, sc.lanes), idx)
        self._passing = None
        return side, reason, 0.0, -1

    def _select(self, sc: _Scene, side: int, blocker: int) -> npt.NDArray[np.intp]:
        """Vehicles that get an ellipse: in the lanes the ego occupies or moves into,
        within the detection distance, nearest first, at most max_obstacles; the
        blocker always (a barrier on a car two lanes away only makes the plan sway)."""
        pol = self.policy
        dist = np.hypot(sc.ds, sc.fn.y_m - sc.ego.lat_m)
        lanes_of_interest = {0, int(np.rint(sc.ego.lat_m / self.lane_width_m))}
        if side in (SIDE_LEFT, SIDE_RIGHT):
            lanes_of_interest.add(side)
        in_lanes = sc.lane_rel == 0
        for lane in lanes_of_interest:
            in_lanes |= sc.lane_rel == lane
        relevant = (dist <= pol.detection_distance_m) & (sc.ds >= -pol.rear_range_m) & in_lanes
        if not pol.moving_obstacles:
            relevant &= sc.traffic.stalled
        order = np.flatnonzero(relevant)
        order = order[np.argsort(dist[order])][: pol.max_obstacles]
        if blocker >= 0 and blocker not in order and order.size:
            order[-1] = blocker
        return order

    def _ellipses(self, sc: _Scene, order: npt.NDArray[np.intp], side: int,
                  blocker: int) -> Obstacles:
        fn = sc.fn
        axes = np.array([ellipse_semi_axes(fn.length_m[i], fn.width_m[i], self.ego.length_m,
                                           self.ego.width_m, self.policy)
                         for i in order]).reshape(-1, 2)
        semi_a, semi_b = axes[:, 0], axes[:, 1]
        y = fn.y_m[order].copy()
        if side in (SIDE_LEFT, SIDE_RIGHT):
            y[order == blocker] = offset_centre_y(float(fn.y_m[blocker]), side, self.policy)
        elif side == SIDE_FOLLOW:
            # Wide enough that no lateral way round exists within the carriageway.
            semi_b = np.where(order == blocker, semi_b + 1.5 * self.lane_width_m, semi_b)
        return Obstacles(s_m=fn.s_m[order].copy(), y_m=y, speed_s_mps=fn.v_s_mps[order].copy(),
                         speed_y_mps=fn.v_y_mps[order].copy(), semi_a_m=semi_a,
                         semi_b_m=semi_b)

    def _lane_offset_m(self, side: int, lanes: LaneContext) -> float:
        """Offset [m] of the neighbour lane's centre on ``side`` from the reference path:
        the lane context's own where known, else the half widths of the two lanes."""
        return lanes.offset_of(lanes.reference_index + side, self.lane_width_m)
