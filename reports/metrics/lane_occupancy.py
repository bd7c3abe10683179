"""Which lanes the ego's box corners are in, and whether the ego is within one lane, as
nuPlan decides it for its at-fault collisions (its ``route_extractor``
``extract_common_or_connecting_route_objs``), on the lanes of a record
(``record.road.lanes``, internal junction lanes included).

A lane's polygon is its centreline (M, 2) [m] swept by half its width: the union of one
rectangle per centreline segment (a point is in it when its projection falls on the
segment and its distance to the segment is <= width/2), with round joins at the inner
vertices (within width/2 of one) and flat ends. Points on a boundary belong to both
lanes (a tolerance of ``EDGE_TOL_M`` = 1 mm).

Lanes are linked where one continues another: lane B *follows* lane A when B's first
centreline point lies within ``JOIN_TOL_M`` (0.5 m, a seventh of a lane width) of A's
last one and their directions there differ by less than ``JOIN_MAX_TURN_RAD`` (45 deg):
SUMO's internal junction lanes start where their incoming lane ends and end where their
outgoing lane starts.

The ego (corners front-left, rear-left, rear-right, front-right, as
:func:`reports.geometry.box_corners` gives them) is **within one lane** when
every corner is in some lane and either

* one lane holds all four corners, or
* the rear corners are each in the same lane as, or a lane following, the other's, and
  a lane holding (or preceding) each front corner is the same as, or follows, a lane of
  the opposite rear corner, with one lane common to both front corners' matches
  (nuPlan's ``get_connecting_route_object``: the box straddles a lane's end and its
  continuation, not two side-by-side lanes).

A corner outside every lane (off the road) makes the ego not within one lane, as in
nuPlan (where all corners off the map give an empty set, which counts as not within).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports.record import LaneRecord, RoadRecord

JOIN_TOL_M = 0.5
JOIN_MAX_TURN_RAD = math.pi / 4.0
EDGE_TOL_M = 1e-3

LaneSet = frozenset[int]


@dataclass(frozen=True)
class LaneTopology:
    """The usable lanes of a road (those with a centreline and a width) and, per lane
    (by position in ``lanes``), the lanes that follow it and that it follows."""

    lanes: tuple[LaneRecord, ...]
    outgoing: tuple[LaneSet, ...]
    incoming: tuple[LaneSet, ...]

    @classmethod
    def of(cls, road: RoadRecord) -> LaneTopology:
        lanes = tuple(ln for ln in road.lanes
                      if np.asarray(ln.shape_xy_m).reshape(-1, 2).shape[0] >= 2
                      and ln.width_m > 0)
        ends = [_end_pose(np.asarray(ln.shape_xy_m, dtype=np.float64).reshape(-1, 2))
                for ln in lanes]
        outgoing: list[set[int]] = [set() for _ in lanes]
        incoming: list[set[int]] = [set() for _ in lanes]
        for a, (_, _, end_a, head_a) in enumerate(ends):
            for b, (start_b, head_b, _, _) in enumerate(ends):
                if a == b or np.hypot(*(start_b - end_a)) > JOIN_TOL_M:
                    continue
                turn = abs((head_b - head_a + math.pi) % (2.0 * math.pi) - math.pi)
                if turn < JOIN_MAX_TURN_RAD:
                    outgoing[a].add(b)
                    incoming[b].add(a)
        return cls(lanes, tuple(frozenset(s) for s in outgoing),
                   tuple(frozenset(s) for s in incoming))

    def lanes_of(self, points_xy_m: np.ndarray) -> list[LaneSet]:
        """For each point (P, 2) [m], the set of lanes (indices into ``lanes``) it is in."""
        pts = np.asarray(points_xy_m, dtype=np.float64).reshape(-1, 2)
        inside = np.zeros((pts.shape[0], len(self.lanes)), dtype=bool)
        for j, lane in enumerate(self.lanes):
            inside[:, j] = points_in_lane(pts, lane.shape_xy_m, lane.width_m)
        return [frozenset(int(j) for j in np.flatnonzero(row)) for row in inside]

    def within_one_lane(self, corners_xy_m: np.ndarray) -> bool:
        """Whether a box (corners (4, 2): front-left, rear-left, rear-right, front-right)
        is within one lane (see the module doc)."""
        fl, rl, rr, fr = self.lanes_of(corners_xy_m)
        if not (fl and rl and rr and fr):
            return False
        if fl & rl & rr & fr:
            return True
        return bool(self._connecting(fl, rl, rr, fr))

    def _follow(self, lanes: LaneSet) -> LaneSet:
        return frozenset().union(*(self.outgoing[j] for j in lanes)) if lanes else frozenset()

    def _precede(self, lanes: LaneSet) -> LaneSet:
        return frozenset().union(*(self.incoming[j] for j in lanes)) if lanes else frozenset()

    def _connecting(self, fl: LaneSet, rl: LaneSet, rr: LaneSet, fr: LaneSet) -> LaneSet:
        rr_or_next = rr | self._follow(rr)
        rl_or_next = rl | self._follow(rl)
        rear = (rl & rr_or_next) | (rr & rl_or_next)
        if not rear:
            return frozenset()
        front_left = (fl | self._precede(fl)) & rr_or_next
        front_right = (fr | self._precede(fr)) & rl_or_next
        return front_left & front_right


def _end_pose(shape: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, float]:
    """(first point, heading there [rad], last point, heading there [rad])."""
    d0 = shape[1] - shape[0]
    d1 = shape[-1] - shape[-2]
    return (shape[0], math.atan2(d0[1], d0[0]), shape[-1], math.atan2(d1[1], d1[0]))


def points_in_lane(points_xy_m: np.ndarray, shape_xy_m: np.ndarray,
                   width_m: float) -> np.ndarray:
    """Bool (P,): each point inside the lane polygon (module doc) of a centreline (M, 2)
    and width [m]."""
    pts = np.asarray(points_xy_m, dtype=np.float64).reshape(-1, 2)
    shape = np.asarray(shape_xy_m, dtype=np.float64).reshape(-1, 2)
    half = 0.5 * float(width_m) + EDGE_TOL_M
    if shape.shape[0] < 2 or pts.shape[0] == 0:
        return np.zeros(pts.shape[0], dtype=bool)
    a, b = shape[:-1], shape[1:]
    ab = b - a
    length2 = np.sum(ab * ab, axis=-1)
    keep = length2 > 1e-12
    a, ab, length2 = a[keep], ab[keep], length2[keep]
    if a.shape[0] == 0:
        return np.zeros(pts.shape[0], dtype=bool)
    rel = pts[:, None, :] - a[None, :, :]  # (P, S, 2)
    t = np.sum(rel * ab[None], axis=-1) / length2[None]
    cross = rel[..., 0] * ab[None, :, 1] - rel[..., 1] * ab[None, :, 0]
    dist = np.abs(cross) / np.sqrt(length2)[None]
    on_segment = (t >= -1e-9) & (t <= 1.0 + 1e-9) & (dist <= half)
    inside: np.ndarray = np.any(on_segment, axis=1)
    if shape.shape[0] > 2:
        inner = shape[1:-1]
        near_join = np.hypot(pts[:, None, 0] - inner[None, :, 0],
                             pts[:, None, 1] - inner[None, :, 1]) <= half
        inside |= np.any(near_join, axis=1)
    return inside
