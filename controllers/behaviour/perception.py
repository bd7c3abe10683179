"""Perception: other vehicles on the reference path, in lanes relative to the ego's.

Every vehicle gets Frenet coordinates along the reference path (s, y, and its velocity
along and across it) and a *relative lane*: 0 is the reference lane (the lane the catalog
asked for, followed along the route), +1 the lane to its left, -1 to its right, and so on.
Where the world reports a vehicle's road and lane index, and the lane context knows the
reference lane's index on that road, the relative lane is their difference (SUMO's own
lane assignment, exact across index shifts); elsewhere (inside junctions, in the
plant-only simulator) it is the lane whose centre is nearest the vehicle's offset.

:class:`LaneScene` then answers the behaviour's questions per relative lane: the lead
(nearest vehicle ahead) and the follower (nearest behind), with bumper gaps. A vehicle
counts in a lane by its relative lane *or* because its box reaches into the lane (a car
straddling the line) or, ahead of the ego, will within a second at its lateral speed (a
cut-in is followed from its start, not from when the world moves it into the lane), or
because its own lane ends within 6 s of its driving next to this one (a car on an
acceleration lane must merge: it leads the lane it merges into).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numba
import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import EgoFrenet, LaneContext, LaneSlot, Traffic
from controllers.cached import cached_property
from controllers.path.frenet import FrenetPath

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]
INTRUSION_M = 0.3  # a box reaching this far past a lane's edge is in that lane
CUT_IN_HORIZON_S = 1.0  # a car whose sideways motion brings it into a lane this soon leads
# The fastest sideways motion a cut-in is predicted with [m/s]: lane changes peak at 1-3
# m/s; a steeper heading is the road's (a car on an on-ramp's junction lane, joining at
# 25 deg two lanes away), not a move across the lanes.
CUT_IN_MAX_LATERAL_MPS = 3.0
MERGE_HORIZON_S = 6.0  # a car whose lane ends within this much of its driving must merge
ENTRY_HEADING_RAD = 0.6  # an on-ramp car heads along the carriageway within this [rad]


@dataclass(frozen=True)
class FrenetTraffic:
    """Vehicles in the reference-path frame, arrays (n,): box centre (s_m, y_m) [m],
    velocity along / across the path (v_s_mps, v_y_mps) [m/s], box size [m]."""

    s_m: FloatArray
    y_m: FloatArray
    v_s_mps: FloatArray
    v_y_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray

    @staticmethod
    def empty() -> FrenetTraffic:
        z = np.zeros(0)
        return FrenetTraffic(z, z, z, z, z, z)


def project_traffic(path: FrenetPath, traffic: Traffic, ego: EgoFrenet) -> FrenetTraffic:
    """Box centres and velocities of ``traffic`` in the frame of ``path``.

    The ego's own projection (s at its CG) seeds every vehicle's Newton projection
    (:meth:`FrenetPath.project_along`); the velocity (speed along the heading) is split
    along the path tangent gamma(s_j) and its normal.
    """
    if traffic.count == 0:
        return FrenetTraffic.empty()
    s, y, gamma = path.project_along(traffic.x_m, traffic.y_m, ego.x_m, ego.y_m, ego.s_m)
    rel = traffic.heading_rad - gamma
    return FrenetTraffic(s, y, traffic.speed_mps * np.cos(rel), traffic.speed_mps * np.sin(rel),
                         traffic.length_m, traffic.width_m)


@dataclass(frozen=True)
class Neighbour:
    """A vehicle next to the ego in one lane: its index in the traffic arrays, bumper gap
    [m] (>= 0 ahead: its rear to the ego's front; behind: the ego's rear to its front) and
    speed along the path [m/s]."""

    index: int
    gap_m: float
    speed_mps: float


@dataclass(frozen=True)
class LaneScene:
    """One step's view: the ego, the vehicles in Frenet coordinates with their relative
    lanes, the lane context and the lanes by relative number (``lanes[rel]``)."""

    ego: EgoFrenet
    ego_length_m: float
    ego_width_m: float
    traffic: Traffic
    fn: FrenetTraffic
    rel_lane: IntArray
    context: LaneContext
    lanes: dict[int, LaneSlot]
    lane_width_m: float

    @cached_property
    def ds_m(self) -> FloatArray:
        """Arc-length offset of every vehicle's centre from the ego's CG [m] (n,)."""
        return self.fn.s_m - self.ego.s_m

    @cached_property
    def _half_lengths_m(self) -> FloatArray:
        return 0.5 * (self.fn.length_m + self.ego_length_m)

    @cached_property
    def _order(self) -> list[int]:
        return sorted(self.context.slots)

    @cached_property
    def _neighbours(self) -> dict[tuple[int, bool], Neighbour | None]:
        return {}

    @cached_property
    def _offsets(self) -> dict[int, float]:
        return {}

    @cached_property
    def _merging_cache(self) -> dict[int, BoolArray]:
        return {}

    @cached_property
    def _merging_lists(self) -> dict[int, list[int]]:
        return {}

    @cached_property
    def _entering_cache(self) -> dict[tuple[float, float], list[tuple[int, int]]]:
        return {}

    def offset_m(self, rel: int) -> float:
        """Centre of relative lane ``rel`` from the reference lane's centre [m, left +]:
        lanes shift together where netconvert moves them, so this is the lane spacing."""
        cache = self._offsets
        if rel not in cache:
            cache[rel] = self._offset_m(rel)
        return cache[rel]

    def _offset_m(self, rel: int) -> float:
        ref = self.context.reference_index
        slots = self.context.slots
        index = self._index_of(rel)
        if index is not None and index in slots and ref in slots:
            a, b = slots[index].offset_m, slots[ref].offset_m
            if math.isfinite(a) and math.isfinite(b):
                return a - b
        return self.context.offset_of(ref + rel, self.lane_width_m) \
            - self.context.offset_of(ref, self.lane_width_m)

    def _index_of(self, rel: int) -> int | None:
        order = self._order
        ref = self.context.reference_index
        if ref not in order:
            return None
        k = order.index(ref) + rel
        return order[k] if 0 <= k < len(order) else None

    def slot(self, rel: int) -> LaneSlot | None:
        index = self._index_of(rel)
        return self.context.slots.get(index) if index is not None else None

    @property
    def ego_lane(self) -> int:
        """The relative lane whose centre is nearest the ego's CG."""
        return self.lane_at(self.ego.lat_m)

    def lane_at(self, y_m: float) -> int:
        rels = [r for r in self.lanes]
        if not rels:
            return int(round(y_m / self.lane_width_m))
        return min(rels, key=lambda r: abs(y_m - self.offset_m(r)))

    def lanes_occupied(self) -> set[int]:
        """Relative lanes the ego's box overlaps laterally (straight box, CG offset)."""
        half = 0.5 * self.ego_width_m
        out = set()
        for r in self.lanes:
            c = self.offset_m(r)
            w = self.lanes[r].width_m
            if abs(self.ego.lat_m - c) < 0.5 * w + half:
                out.add(r)
        return out or {self.ego_lane}

    def lead(self, rel: int) -> Neighbour | None:
        """The nearest vehicle ahead in relative lane ``rel`` (its rear ahead of the ego's
        CG), counting a car about to cut in (:meth:`intruding` within
        ``CUT_IN_HORIZON_S``)."""
        return self._nearest(rel, ahead=True)

    def follower(self, rel: int) -> Neighbour | None:
        """The nearest vehicle behind in relative lane ``rel`` (or reaching into it)."""
        return self._nearest(rel, ahead=False)

    def intruding(self, rel: int, horizon_s: float = 0.0) -> BoolArray:
        """Vehicles whose box reaches more than ``INTRUSION_M`` into relative lane ``rel``
        now or, moving sideways at their lateral speed, within ``horizon_s`` [s] (a car
        cutting in, or straddling the line), whatever lane the world assigns them; the
        lateral speed is clipped to ``CUT_IN_MAX_LATERAL_MPS``."""
        if rel not in self.lanes or self.traffic.count == 0:
            return np.zeros(self.traffic.count, dtype=bool)
        centre = self.offset_m(rel)
        reach = 0.5 * (self.lanes[rel].width_m + self.fn.width_m) - INTRUSION_M
        y_now = self.fn.y_m - centre
        y_then = y_now + np.clip(self.fn.v_y_mps, -CUT_IN_MAX_LATERAL_MPS,
                                 CUT_IN_MAX_LATERAL_MPS) * horizon_s
        # The box is in the corridor at some time in [0, horizon] if the segment between
        # y_now and y_then meets [-reach, reach].
        lo, hi = np.minimum(y_now, y_then), np.maximum(y_now, y_then)
        return np.asarray((hi > -reach) & (lo < reach), dtype=bool)

    def merging(self, rel: int) -> BoolArray:
        """Vehicles whose lane ends (an acceleration lane, a lane drop:
        ``LaneContext.ending_lanes_by_road``) within ``MERGE_HORIZON_S`` of their driving
        and whose traffic merges into relative lane ``rel``: they must move into it soon
        (on whichever road they are, ahead of the ego's own). Computed once per scene
        and lane (the lead search and the merge rules ask for it several times a step)."""
        cache = self._merging_cache
        if rel not in cache:
            cache[rel] = self._merging(rel)
        return cache[rel]

    def _merging(self, rel: int) -> BoolArray:
        out = np.zeros(self.traffic.count, dtype=bool)
        ends = self.context.ending_lanes_by_road
        pos = self.context.route_pos_m
        if not ends or not math.isfinite(pos):
            return out
        tr = self.traffic
        for j in range(tr.count):
            end = ends.get(tr.road_id[j], {}).get(int(tr.lane_index[j]))
            if end is None or int(self.rel_lane[j]) + end[1] != rel:
                continue
            left_m = end[0] - (pos + float(self.fn.s_m[j] - self.ego.s_m))
            out[j] = left_m < MERGE_HORIZON_S * max(float(self.fn.v_s_mps[j]), 5.0)
        return out

    def merge_room_m(self, j: int) -> float:
        """Road left [m] before vehicle ``j``'s lane ends, along the route from its
        position (inf when its lane does not end: a through lane, or unknown)."""
        ends = self.context.ending_lanes_by_road
        pos = self.context.route_pos_m
        if not ends or not math.isfinite(pos):
            return math.inf
        end = ends.get(self.traffic.road_id[j], {}).get(int(self.traffic.lane_index[j]))
        if end is None:
            return math.inf
        return end[0] - (pos + float(self.fn.s_m[j] - self.ego.s_m))

    def merging_near(self, rel: int, behind_m: float, ahead_m: float) -> list[int]:
        """Indices of the vehicles merging into relative lane ``rel`` (:meth:`merging`)
        whose centre is within [-behind_m, ahead_m] of the ego's CG along the path."""
        cache = self._merging_lists
        if rel not in cache:
            cache[rel] = np.flatnonzero(self.merging(rel)).tolist()
        ds = self.ds_m
        return [j for j in cache[rel] if -behind_m <= float(ds[j]) <= ahead_m]

    def entering_near(self, behind_m: float, ahead_m: float) -> list[tuple[int, int]]:
        """(index, side: -1 right, +1 left) of the vehicles about to enter the
        carriageway from a road off the route (an on-ramp): on a road the lane context
        does not place on the route (known, not empty), within [-behind_m, ahead_m] of
        the ego's CG along the path, beyond the outer edge of the outermost lane on that
        side, heading along the path (within ENTRY_HEADING_RAD of it, moving forward):
        they merge into the lanes on that side, whatever their road is called. Computed
        once per scene and window."""
        cache = self._entering_cache
        key = (behind_m, ahead_m)
        if key not in cache:
            cache[key] = self._entering_near(behind_m, ahead_m)
        return cache[key]

    def _entering_near(self, behind_m: float, ahead_m: float) -> list[tuple[int, int]]:
        if self.traffic.count == 0 or not self.lanes:
            return []
        on_route = self.context.reference_index_by_road
        candidates = _OFF_ROUTE.indices(self.traffic.road_id, on_route)
        if not candidates:
            return []
        edges = [(self.offset_m(r) - 0.5 * slot.width_m, self.offset_m(r) + 0.5 * slot.width_m)
                 for r, slot in self.lanes.items()]
        right, left = min(e[0] for e in edges), max(e[1] for e in edges)
        ds, fn = self.ds_m, self.fn
        out = []
        for j in candidates:
            if not -behind_m <= float(ds[j]) <= ahead_m or fn.v_s_mps[j] < 1.0:
                continue
            if abs(math.atan2(float(fn.v_y_mps[j]), float(fn.v_s_mps[j]))) > ENTRY_HEADING_RAD:
                continue
            y = float(fn.y_m[j])
            if y < right:
                out.append((j, -1))
            elif y > left:
                out.append((j, 1))
        return out

    def _nearest(self, rel: int, ahead: bool) -> Neighbour | None:
        """Lead or follower of lane ``rel``, computed once per scene."""
        key = (rel, ahead)
        cache = self._neighbours
        if key not in cache:
            cache[key] = self._find_nearest(rel, ahead)
        return cache[key]

    def _find_nearest(self, rel: int, ahead: bool) -> Neighbour | None:
        """The nearest vehicle ahead (the smallest ds > 0) or behind
        (largest ds <= 0) among those in lane ``rel`` by relative lane, by
        :meth:`intruding` (with ``CUT_IN_HORIZON_S`` ahead, 0 behind) or, ahead, by
        :meth:`merging`; the first of equals. One compiled pass over the vehicles."""
        n = self.traffic.count
        if n == 0:
            return None
        known = rel in self.lanes
        centre = self.offset_m(rel) if known else 0.0
        width = self.lanes[rel].width_m if known else 0.0
        merging = self.merging(rel) if ahead else np.zeros(n, dtype=bool)
        fn = self.fn
        j = _nearest_in_lane(self.rel_lane, fn.y_m, fn.v_y_mps, fn.width_m, self.ds_m,
                             merging, rel, known, centre, width,
                             CUT_IN_HORIZON_S if ahead else 0.0, INTRUSION_M, ahead,
                             CUT_IN_MAX_LATERAL_MPS)
        if j < 0:
            return None
        half = self._half_lengths_m
        ds = self.ds_m
        gap = (ds[j] - half[j]) if ahead else (-ds[j] - half[j])
        return Neighbour(j, float(gap), float(fn.v_s_mps[j]))


@numba.njit(cache=True)
def _nearest_in_lane(rel_lane: IntArray, y_m: FloatArray, v_y_mps: FloatArray,
                     width_m: FloatArray, ds_m: FloatArray, merging: BoolArray, rel: int,
                     lane_known: bool, centre_m: float, lane_width_m: float,
                     horizon_s: float, intrusion_m: float, ahead: bool,
                     max_lateral_mps: float) -> int:
    """Index of the vehicle :meth:`LaneScene._find_nearest` picks, -1 if none: in the
    lane when rel_lane == rel, or merging, or (lane known) its box's lateral span
    [y - centre, y - centre + v_y horizon] (v_y clipped to ±max_lateral_mps) meets
    [-reach, reach] with reach =
    (lane width + its width) / 2 - intrusion; then ds > 0 smallest (ahead) or ds <= 0
    largest (behind), the first of equals."""
    best = -1
    for j in range(rel_lane.shape[0]):
        inside = rel_lane[j] == rel or merging[j]
        if not inside and lane_known:
            reach = 0.5 * (lane_width_m + width_m[j]) - intrusion_m
            y_now = y_m[j] - centre_m
            v_y = min(max(v_y_mps[j], -max_lateral_mps), max_lateral_mps)
            y_then = y_now + v_y * horizon_s
            lo = y_now if y_now < y_then else y_then
            hi = y_now if y_now > y_then else y_then
            inside = hi > -reach and lo < reach
        if not inside:
            continue
        if ahead:
            if ds_m[j] > 0.0 and (best < 0 or ds_m[j] < ds_m[best]):
                best = j
        elif ds_m[j] <= 0.0 and (best < 0 or ds_m[j] > ds_m[best]):
            best = j
    return best


class _OffRouteRoads:
    """The vehicles on a known road off the route (not empty, not a junction's, not
    one the lane context places on the route): :meth:`LaneScene._entering_near`'s first
    test, which depends on the roads only. The roads are SUMO's last step's (the same
    tuple object between SUMO steps, :func:`suite.world.multirate.extrapolate_traffic`),
    so the last answer is kept for that tuple and an equal route mapping."""

    def __init__(self) -> None:
        self._roads: tuple[str, ...] | None = None
        self._on_route: dict[str, int] = {}
        self._indices: list[int] = []

    def indices(self, roads: tuple[str, ...], on_route: Mapping[str, int]) -> list[int]:
        """Indices j (ascending) of ``roads[j]`` off the route."""
        if roads is not self._roads or on_route != self._on_route:
            self._indices = [j for j, road in enumerate(roads)
                             if road and road not in on_route and not road.startswith(":")]
            self._roads, self._on_route = roads, dict(on_route)
        return self._indices


class _ExactLanes:
    """The last :func:`relative_lanes` answer that came from the world's road and lane
    indices alone (every vehicle on a road of the route, lane known): it holds while the
    roads and lane indices are the same objects (SUMO's last step's, shared by the
    extrapolated scenes in between) and the route mapping is equal."""

    def __init__(self) -> None:
        self._key: tuple[object, object] | None = None
        self._by_road: dict[str, int] = {}
        self._out = np.zeros(0, dtype=np.int64)

    def get(self, traffic: Traffic, by_road: Mapping[str, int]) -> IntArray | None:
        key = self._key
        if key is None or key[0] is not traffic.road_id or key[1] is not traffic.lane_index \
                or by_road != self._by_road:
            return None
        return self._out.copy()

    def put(self, traffic: Traffic, by_road: Mapping[str, int], out: IntArray) -> None:
        self._key = (traffic.road_id, traffic.lane_index)
        self._by_road = dict(by_road)
        self._out = out.copy()


_OFF_ROUTE = _OffRouteRoads()
_EXACT_LANES = _ExactLanes()


def relative_lanes(traffic: Traffic, fn: FrenetTraffic, context: LaneContext,
                   lane_width_m: float) -> IntArray:
    """Relative lane of every vehicle (module docstring)."""
    n = traffic.count
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    by_road = context.reference_index_by_road
    known = _EXACT_LANES.get(traffic, by_road)
    if known is not None:
        return known
    out = np.zeros(n, dtype=np.int64)
    exact = True
    order = sorted(context.slots)
    ref = context.reference_index
    ref_ok = ref in context.slots and math.isfinite(context.slots[ref].offset_m)
    offset_list = [context.slots[i].offset_m for i in order]
    geometric = bool(order) and ref_ok and all(math.isfinite(o) for o in offset_list)
    offsets = np.array(offset_list, dtype=np.float64)
    # Python ints and lists in the loop: indexing numpy arrays one element at a time
    # costs more than the work (the loop runs over every vehicle, every step).
    for j, (road, lane) in enumerate(zip(traffic.road_id, traffic.lane_index.tolist(),
                                         strict=True)):
        ref_lane = by_road.get(road)
        if ref_lane is not None and lane >= 0:
            out[j] = lane - ref_lane
            continue
        exact = False
        if geometric:
            k = int(np.argmin(np.abs(fn.y_m[j] - offsets)))
            extra = 0.0
            if fn.y_m[j] > offsets[-1] + 0.5 * lane_width_m:
                extra = round((fn.y_m[j] - offsets[-1]) / lane_width_m)
            elif fn.y_m[j] < offsets[0] - 0.5 * lane_width_m:
                extra = round((fn.y_m[j] - offsets[0]) / lane_width_m)
            out[j] = k - order.index(ref) + int(extra)
        else:
            out[j] = int(round(fn.y_m[j] / lane_width_m))
    if exact:
        _EXACT_LANES.put(traffic, by_road, out)
    return out
