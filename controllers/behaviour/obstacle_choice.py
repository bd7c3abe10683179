"""Which vehicles the outer loop plans around, and their ellipses (the lane behaviour's step 4).

From the scene (:class:`controllers.behaviour.perception.LaneScene`) and the lane plan of
:class:`controllers.behaviour.decision.LaneBehaviour`:

* :func:`pass_side`: the side the plan passes on (a lane change's direction, FOLLOW when
  the speed target follows a lead, else the side of the plan's lane, none in the
  reference lane);
* :func:`select_obstacles`: the vehicles within the detection distance in every lane the
  ego's box occupies and in the plan's lanes, the leads first, never a car behind in the
  lane kept or left, at most ``max_obstacles``;
* :func:`plan_ellipses`: their ellipses (:mod:`controllers.behaviour.ellipses`), the
  vehicle being passed shifted away from the pass side, a lead the ego must follow made a
  wall across the carriageway (B of ten lane widths), an ellipse that would contain the
  ego narrowed to leave it outside.
"""

from __future__ import annotations

import math
from typing import Protocol

import numba
import numpy as np
import numpy.typing as npt

from controllers.behaviour.ellipses import ellipse_semi_axes, offset_centre_y
from controllers.behaviour.perception import LaneScene
from controllers.behaviour.types import FloatArray, ObstaclePolicy, Obstacles, Side

__all__ = ["LanePlan", "pass_side", "plan_ellipses", "select_obstacles"]

IntpArray = npt.NDArray[np.intp]
_FOLLOW_WALL_LANES = 10.0  # semi-axis B of a followed lead's ellipse, in lane widths


class LanePlan(Protocol):
    """What these functions read of the lane plan: the lane held or moved into, the
    origin lane (relative to the reference lane) and whether it is a change."""

    @property
    def lane(self) -> int: ...

    @property
    def origin(self) -> int: ...

    @property
    def changing(self) -> bool: ...


def pass_side(plan: LanePlan, follow: bool) -> Side:
    """The plan's :class:`Side`: LEFT / RIGHT / FOLLOW / KEEP (module docstring)."""
    if plan.changing:
        return Side.LEFT if plan.lane > plan.origin else Side.RIGHT
    if follow:
        return Side.FOLLOW
    if plan.lane != 0:
        return Side.LEFT if plan.lane > 0 else Side.RIGHT
    return Side.KEEP


def select_obstacles(sc: LaneScene, plan: LanePlan, lead: int,
                     pol: ObstaclePolicy) -> IntpArray:
    """Vehicles that get an ellipse (module docstring), nearest first: indices into
    ``sc.traffic``; ``lead``: the followed lead's index (-1 none)."""
    if sc.traffic.count == 0 or pol.max_obstacles == 0:
        return np.zeros(0, dtype=np.intp)
    lanes = sc.lanes_occupied() | {plan.lane, plan.origin}
    leads = {n.index for r in lanes if (n := sc.lead(r)) is not None}
    if lead >= 0:
        leads.add(lead)
    home_lane = plan.origin if plan.changing else plan.lane
    return _select_obstacles(sc.ds_m, sc.fn.y_m, sc.ego.lat_m, sc.rel_lane,
                             np.array(sorted(lanes), dtype=np.int64),
                             np.array(sorted(leads), dtype=np.int64), home_lane,
                             sc.traffic.stalled, pol.moving_obstacles,
                             pol.detection_distance_m, pol.rear_range_m,
                             pol.max_obstacles)


def plan_ellipses(sc: LaneScene, order: IntpArray, plan: LanePlan, side: int,  # noqa: PLR0913 - one decision step's scene, plan and ego box
                  follow_lead: int, pol: ObstaclePolicy, ego_length_m: float,
                  ego_width_m: float, lane_width_m: float,
                  accel_mps2: FloatArray | None = None) -> Obstacles:
    """The ellipses of the vehicles ``order`` (module docstring), in the path's Frenet
    frame, each with its vehicle's id; ``follow_lead``: the index of the lead made a wall
    (-1 none); ``accel_mps2``: every vehicle's estimated acceleration [m/s²] (indexed
    like ``sc.traffic``; None: not known), handed on as each ellipse's."""
    fn = sc.fn
    axes = np.array([ellipse_semi_axes(fn.length_m[i], fn.width_m[i], ego_length_m,
                                       ego_width_m, pol)
                     for i in order]).reshape(-1, 2)
    semi_a, semi_b = axes[:, 0].copy(), axes[:, 1].copy()
    y = fn.y_m[order].copy()
    if side in (Side.LEFT, Side.RIGHT):
        # Shift the vehicles of the lane being left away from the pass side.
        origin = plan.origin if plan.changing else 0
        for k, i in enumerate(order):
            if sc.rel_lane[i] == origin and (plan.changing or plan.lane != 0):
                y[k] = offset_centre_y(float(fn.y_m[i]), side, pol)
    for k, i in enumerate(order):
        if i == follow_lead:
            # A wall across the carriageway: no lateral way round, and (B >> the
            # ego's offset) no lateral gradient that would push the ego sideways
            # while it waits at standstill distance (dc/dy = 2 dy / B²).
            semi_b[k] = max(semi_b[k], _FOLLOW_WALL_LANES * lane_width_m)
    return Obstacles(s_m=fn.s_m[order].copy(), y_m=y, speed_s_mps=fn.v_s_mps[order].copy(),
                     speed_y_mps=fn.v_y_mps[order].copy(), semi_a_m=semi_a,
                     semi_b_m=semi_b, vehicle_ids=tuple(sc.traffic.ids[i] for i in order),
                     half_length_m=0.5 * (fn.length_m[order] + ego_length_m),
                     accel_s_mps2=(np.zeros(0) if accel_mps2 is None
                                   or accel_mps2.shape[0] != sc.traffic.count
                                   else accel_mps2[order].astype(float))
                     ).around_ego(float(sc.ego.s_m), float(sc.ego.lat_m))


@numba.njit(cache=True)
def _select_obstacles(ds_m: npt.NDArray[np.float64], y_m: npt.NDArray[np.float64],
                      ego_lat_m: float, rel_lane: npt.NDArray[np.int64],
                      lanes: npt.NDArray[np.int64], leads: npt.NDArray[np.int64],
                      home_lane: int, stalled: npt.NDArray[np.bool_], moving: bool,
                      detection_m: float, rear_range_m: float, max_obstacles: int
                      ) -> IntpArray:
    """:func:`select_obstacles` in one pass: the vehicles within ``detection_m``
    (distance hypot(ds, y - ego lat) [m]) and at most ``rear_range_m`` behind, in
    ``lanes`` (relative) or one of ``leads``, not behind the ego in ``home_lane``, stalled
    ones only unless ``moving``; leads first, then by distance (ties in index order),
    at most ``max_obstacles``."""
    n = ds_m.shape[0]
    is_lead = np.zeros(n, dtype=np.bool_)
    for k in range(leads.shape[0]):
        is_lead[leads[k]] = True
    dist = np.empty(n)
    relevant = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        dist[i] = math.hypot(ds_m[i], y_m[i] - ego_lat_m)
        in_lanes = is_lead[i]  # a lead by intrusion or merging, whatever its lane
        for k in range(lanes.shape[0]):
            if rel_lane[i] == lanes[k]:
                in_lanes = True
        ok = dist[i] <= detection_m and ds_m[i] >= -rear_range_m and in_lanes
        # A car behind in the lane the ego keeps (or leaves) is its follower's business:
        # as an ellipse it only pushes the ego forward and, squeezed against the lead's,
        # sideways out of its lane. Behind the ego only the lane moved into counts.
        if rel_lane[i] == home_lane and ds_m[i] < 0.0:
            ok = False
        if not moving and not stalled[i]:
            ok = False
        relevant[i] = ok
    first = np.flatnonzero(relevant & is_lead)
    second = np.flatnonzero(relevant & ~is_lead)
    order = np.concatenate((first[np.argsort(dist[first], kind="mergesort")],
                            second[np.argsort(dist[second], kind="mergesort")]))
    return order[:max_obstacles].astype(np.intp)

