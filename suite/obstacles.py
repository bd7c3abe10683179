"""From SUMO's neighbours and lane context to the controller's obstacle ellipses.

Pipeline per control step (all arrays, no libsumo calls):

1. Project every neighbour's box centre onto the reference path: (s_j, y_j),
   and its velocity onto the path tangent/normal: (v_s, v_y).
2. Keep the vehicles within the policy's detection distance of the ego CG
   (and at most ``rear_range_m`` behind it), nearest first, at most K.
3. Choose the pass side for the nearest *blocking* vehicle (a vehicle whose
   box overlaps the ego's reference lane ahead and which is slower than the
   ego by more than 1 m/s, stalled cars always): a neighbour lane qualifies
   when it exists at the obstacle, belongs to the same edge (so it runs the
   same way; an opposite-direction lane is another edge in SUMO), admits
   passenger cars or is a shoulder the scenario allows, and has a free gap for
   the manoeuvre (see :func:`gap_is_free`). Left is preferred (keep-right
   rule: overtake on the left); if neither side qualifies the ego follows:
   the blocking ellipse is widened across the lane and the target speed drops
   to a gap-keeping speed. A side, once the ego has moved more than
   ``commit_offset_m`` towards it, is kept for that obstacle (no mid-manoeuvre
   flip-flopping).
4. Ellipses: semi-axes and the offset OS away from the pass side from
   :mod:`controllers.behaviour.ellipses` (the ellipse contains the Minkowski sum
   of the two boxes plus margins; METHOD.md §4, Fig. 7).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from controllers.behaviour.ellipses import ellipse_semi_axes, offset_centre_y
from controllers.protocol import ObstaclePolicy, Obstacles
from suite.world.sumo import Neighbours

SIDE_NONE = 0
SIDE_LEFT = 1
SIDE_RIGHT = -1
SIDE_FOLLOW = 2


@dataclass(frozen=True)
class LaneSlot:
    """A lane of the edge under a point of the route, relative to the reference lane."""

    index: int
    width_m: float
    allows_passenger: bool
    is_shoulder: bool


@dataclass(frozen=True)
class GapPolicy:
    """Free-gap rule for a lane change around an obstacle.

    A vehicle in the target lane blocks the manoeuvre if, under constant
    speeds, its box comes closer than ``clearance_m + time_gap_s * v_ego``
    (bumper to bumper) to the ego's box at any time in the window from now
    until the ego is ``pass_after_m`` beyond the obstacle.
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
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"GapPolicy.{name} must be a finite number >= 0, got {v!r}")


def follow_speed_mps(gap_m: float, lead_speed_mps: float, set_speed_mps: float,
                     gap: GapPolicy) -> float:
    """Speed set-point behind a leader that cannot be passed [m/s].

    With the desired gap d* = standstill + time_gap * v_lead, the ego may go at
    v = sqrt(v_lead^2 + 2 b (gap - d*)) while the gap exceeds d* (it can still
    shed the difference at the comfortable deceleration b before reaching d*),
    and at v_lead * gap / d* inside it. Clipped to [0, set speed].
    """
    desired = gap.follow_standstill_m + gap.follow_time_gap_s * lead_speed_mps
    if gap_m >= desired:
        v = math.sqrt(lead_speed_mps**2 + 2.0 * gap.follow_decel_mps2 * (gap_m - desired))
    else:
        v = lead_speed_mps * gap_m / max(desired, 1e-6)
    return float(min(max(v, 0.0), set_speed_mps))


@dataclass
class FrenetNeighbours:
    """Neighbours in the reference-path frame, arrays (n,)."""

    s_m: np.ndarray
    y_m: np.ndarray
    v_s_mps: np.ndarray
    v_y_mps: np.ndarray
    length_m: np.ndarray
    width_m: np.ndarray


@dataclass
class ObstacleDecision:
    obstacles: Obstacles
    side: int
    reason: str
    target_speed_mps: float
    ids: list[str] = field(default_factory=list)
    lateral_reference_m: float = 0.0


def gap_is_free(ego_s: float, ego_v: float, ego_len: float, obs_s: float, obs_len: float,
                lane_s: np.ndarray, lane_v: np.ndarray, lane_len: np.ndarray,
                gap: GapPolicy) -> bool:
    """True when no vehicle in the target lane conflicts with the pass manoeuvre.

    Relative motion is linear, so the minimum bumper distance over the window
    [0, T] (T = time for the ego to get ``pass_after_m`` past the obstacle) is
    attained at an end point or where the relative position crosses zero.
    A (near-)stationary vehicle anywhere in the stretch the ego sweeps, from its
    rear to ``pass_after_m`` beyond the obstacle, blocks whatever the ego's
    speed (a slow ego would otherwise "outwait" it in the time-based test).
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


class ObstacleBuilder:
    """Stateful per run (keeps the committed side per obstacle)."""

    def __init__(self, policy: ObstaclePolicy, ego_length_m: float, ego_width_m: float,
                 reference_lane: int, allow_shoulder: bool, gap: GapPolicy | None = None) -> None:
        self.policy = policy
        self.ego_length_m = ego_length_m
        self.ego_width_m = ego_width_m
        self.reference_lane = reference_lane
        self.allow_shoulder = allow_shoulder
        self.gap = gap or GapPolicy()
        self._committed: dict[str, int] = {}
        # The vehicle being passed: id -> (side, lateral reference [m]); kept until the
        # ego is ``pass_after_m`` beyond its rear so the car does not cut back in early.
        self._passing: dict[str, tuple[int, float]] = {}

    def _side_ok(self, side: int, lanes: dict[int, LaneSlot], fn: FrenetNeighbours,
                 lane_rel: np.ndarray, ego_s: float, ego_v: float, j: int) -> tuple[bool, str]:
        target = self.reference_lane + side
        name = "left" if side > 0 else "right"
        slot = lanes.get(target)
        if slot is None:
            return False, f"no {name} lane"
        if slot.is_shoulder and not self.allow_shoulder:
            return False, f"{name} is a shoulder (not allowed)"
        if not slot.allows_passenger and not slot.is_shoulder:
            return False, f"{name} lane bars passenger cars"
        in_lane = lane_rel == side
        in_lane[j] = False
        free = gap_is_free(ego_s, ego_v, self.ego_length_m, float(fn.s_m[j]), float(fn.length_m[j]),
                           fn.s_m[in_lane], fn.v_s_mps[in_lane], fn.length_m[in_lane], self.gap)
        if not free:
            return False, f"{name} gap occupied"
        kind = "shoulder" if slot.is_shoulder else "lane"
        return True, f"{name} {kind} free"

    def build(self, ego_s: float, ego_y: float, ego_v: float, target_speed_mps: float,
              neighbours: Neighbours, fn: FrenetNeighbours, lanes: dict[int, LaneSlot],
              lane_width_m: float) -> ObstacleDecision:
        """Obstacles for this step. ``lanes`` maps lane index -> slot at the ego's position."""
        pol = self.policy
        n = neighbours.count
        if n == 0 or pol.max_obstacles == 0:
            return ObstacleDecision(Obstacles.empty(), SIDE_NONE, "no obstacle", target_speed_mps)
        ds = fn.s_m - ego_s
        dist = np.hypot(ds, fn.y_m - ego_y)
        lane_rel = np.rint(fn.y_m / lane_width_m).astype(np.int64)
        # Blocking: overlaps the reference lane laterally, ahead within the planning
        # range (longer than the detection distance so that a blocked lane is known
        # early enough to slow down comfortably), and slow or stalled.
        g = self.gap
        plan_range = max(pol.detection_distance_m, ego_v * g.plan_horizon_s,
                         ego_v**2 / (2.0 * g.follow_decel_mps2) + g.follow_standstill_m + 30.0)
        overlap_lat = np.abs(fn.y_m) < 0.5 * (lane_width_m + fn.width_m) - 0.2
        slower = (fn.v_s_mps < ego_v - 1.0) | neighbours.stalled
        blocking = overlap_lat & slower & (ds > 0) & (ds <= plan_range)
        if not pol.moving_obstacles:
            blocking &= neighbours.stalled
        side = SIDE_NONE
        reason = "no obstacle in lane"
        target = target_speed_mps
        blocker = -1
        if np.any(blocking):
            blocker = int(np.flatnonzero(blocking)[np.argmin(ds[blocking])])
            bid = neighbours.ids[blocker]
            committed = self._committed.get(bid)
            if committed in (SIDE_LEFT, SIDE_RIGHT):
                ok, why = self._side_ok(committed, lanes, fn, lane_rel, ego_s, ego_v, blocker)
                if ok or committed * ego_y > self.gap.commit_offset_m:
                    side, reason = committed, (why if ok else "committed " + why)
            if side == SIDE_NONE:
                reasons = []
                for cand in (SIDE_LEFT, SIDE_RIGHT):
                    ok, why = self._side_ok(cand, lanes, fn, lane_rel, ego_s, ego_v, blocker)
                    reasons.append(why)
                    if ok:
                        side = cand
                        reason = why + (f" ({reasons[0]})" if len(reasons) > 1 else "")
                        break
                if side == SIDE_NONE:
                    side = SIDE_FOLLOW
                    reason = "follow: " + "; ".join(reasons)
            if side in (SIDE_LEFT, SIDE_RIGHT) and side * ego_y > self.gap.commit_offset_m:
                self._committed[bid] = side
            if side in (SIDE_LEFT, SIDE_RIGHT):
                self._passing = {bid: (side, self._lane_offset_m(side, lanes, lane_width_m))}
            else:
                self._passing = {}
            if side == SIDE_FOLLOW:
                gap_m = max(float(ds[blocker]) - 0.5 * (fn.length_m[blocker] + self.ego_length_m),
                            0.0)
                target = follow_speed_mps(gap_m, max(float(fn.v_s_mps[blocker]), 0.0),
                                          target_speed_mps, self.gap)

        lat_ref = 0.0
        if blocker < 0 and self._passing:
            bid, (p_side, p_ref) = next(iter(self._passing.items()))
            idx = neighbours.ids.index(bid) if bid in neighbours.ids else -1
            behind_by = ego_s - (fn.s_m[idx] + 0.5 * (fn.length_m[idx] + self.ego_length_m)) \
                if idx >= 0 else math.inf
            if behind_by < self.gap.pass_after_m:
                side, lat_ref = p_side, p_ref
                reason = f"passing {bid}"
                blocker = idx
            else:
                self._passing = {}
        elif self._passing:
            lat_ref = next(iter(self._passing.values()))[1]

        # Ellipses only for vehicles in the lanes the ego occupies or is moving into:
        # a barrier on a car two lanes away only makes the plan sway.
        ego_lane_rel = int(np.rint(ego_y / lane_width_m))
        lanes_of_interest = {0, ego_lane_rel}
        if side in (SIDE_LEFT, SIDE_RIGHT):
            lanes_of_interest.add(side)
        in_lanes = lane_rel == 0
        for lane in lanes_of_interest:
            in_lanes |= lane_rel == lane
        relevant = (dist <= pol.detection_distance_m) & (ds >= -pol.rear_range_m) & in_lanes
        if not pol.moving_obstacles:
            relevant &= neighbours.stalled
        order = np.flatnonzero(relevant)
        order = order[np.argsort(dist[order])][: pol.max_obstacles]
        if blocker >= 0 and blocker not in order and order.size:
            order[-1] = blocker
        axes = np.array([ellipse_semi_axes(fn.length_m[i], fn.width_m[i], self.ego_length_m,
                                           self.ego_width_m, pol) for i in order]).reshape(-1, 2)
        semi_a, semi_b = axes[:, 0], axes[:, 1]
        y = fn.y_m[order].copy()
        if side in (SIDE_LEFT, SIDE_RIGHT):
            y[order == blocker] = offset_centre_y(float(fn.y_m[blocker]), side, pol)
        elif side == SIDE_FOLLOW:
            # Wide enough that no lateral way round exists within the carriageway.
            semi_b = np.where(order == blocker, semi_b + 1.5 * lane_width_m, semi_b)
        obstacles = Obstacles(
            s_m=fn.s_m[order].copy(), y_m=y, speed_s_mps=fn.v_s_mps[order].copy(),
            speed_y_mps=fn.v_y_mps[order].copy(), semi_a_m=semi_a, semi_b_m=semi_b,
        )
        ids = [neighbours.ids[i] for i in order]
        return ObstacleDecision(obstacles, side, reason, target, ids, lateral_reference_m=lat_ref)

    def _lane_offset_m(self, side: int, lanes: dict[int, LaneSlot], lane_width_m: float) -> float:
        """Signed distance from the reference lane's centre to the neighbour lane's [m]."""
        ref = lanes.get(self.reference_lane)
        target = lanes.get(self.reference_lane + side)
        w_ref = ref.width_m if ref is not None else lane_width_m
        w_target = target.width_m if target is not None else lane_width_m
        return side * 0.5 * (w_ref + w_target)


def to_frenet(path: object, neighbours: Neighbours, ego_s: float, ego_x: float,
              ego_y: float) -> FrenetNeighbours:
    """Project neighbours (box centres, velocities) onto the reference path.

    The ego's own projection (s at its CG) seeds every neighbour's, see
    :meth:`controllers.path.frenet.FrenetPath.project_along`.
    """
    if neighbours.count == 0:
        z = np.zeros(0)
        return FrenetNeighbours(z, z, z, z, z, z)
    s, y, gamma = path.project_along(  # type: ignore[attr-defined]
        neighbours.x_m, neighbours.y_m, ego_x, ego_y, ego_s)
    rel = neighbours.heading_rad - gamma
    v_s = neighbours.speed_mps * np.cos(rel)
    v_y = neighbours.speed_mps * np.sin(rel)
    return FrenetNeighbours(s, y, v_s, v_y, neighbours.length_m, neighbours.width_m)


def ellipses_in_world(path: object, obstacles: Obstacles) -> np.ndarray:
    """(K, 6) [cx, cy, heading, A, B, active] for logs; axes along the path tangent."""
    k = obstacles.count
    out = np.zeros((k, 6))
    if k == 0:
        return out
    x, y = path.to_global(obstacles.s_m, obstacles.y_m)  # type: ignore[attr-defined]
    out[:, 0] = x
    out[:, 1] = y
    out[:, 2] = path.gamma(obstacles.s_m)  # type: ignore[attr-defined]
    out[:, 3] = obstacles.semi_a_m
    out[:, 4] = obstacles.semi_b_m
    out[:, 5] = 1.0
    return out
