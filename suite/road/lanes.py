"""Lane context along a route: the lanes under a point of the reference path.

For a position s on the reference path, :meth:`LaneContextMap.at` gives the lanes of the
route edge there (route position from the reference's own mapping, so lane index shifts
and lane-length differences along a long route do not accumulate), each with

* its centre's offset from the reference path at s [m, left +]: the lane's polyline
  projected onto the path, so a lane that netconvert shifts by half a lane at a
  junction, or the reference crossing between lane centres in a jog zone, is where it
  really is;
* how far along the route it continues [m]: infinite for a through lane, up to its end
  for a lane that ends or leaves the route (an acceleration lane, an exit);

and the index of the lane the reference follows on that edge.

Everything but the two numbers that move with s (offset, continuation) is prepared once
per route edge (:class:`_EdgeLanes`); the offsets are scalar interpolations on Python
lists (:func:`suite.road.interp.interp_scalar`, numpy.interp's numbers bit for bit), so a
lookup costs a few microseconds a lane.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from controllers.behaviour.types import LaneContext, LaneSlot
from controllers.path.frenet import FrenetPath
from suite.road.interp import interp_scalar
from suite.road.lane_graph import RouteLaneGraph
from suite.road.network import RoadNetwork
from suite.road.route_reference import RouteReference

FloatArray = npt.NDArray[np.float64]
_SAMPLE_M = 5.0  # lane polylines are sampled this densely for their offset profile


def _resample_shape(shape: FloatArray, step_m: float) -> FloatArray:
    seg = np.hypot(*np.diff(shape, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    if cum[-1] <= 0.0:
        return shape[:1]
    s = np.linspace(0.0, cum[-1], max(int(math.ceil(cum[-1] / step_m)), 1) + 1)
    return np.column_stack([np.interp(s, cum, shape[:, 0]), np.interp(s, cum, shape[:, 1])])


@dataclass(frozen=True)
class _LaneProfile:
    """One lane of a route edge, prepared for :meth:`LaneContextMap.at`: its fixed slot
    fields, its offset profile as lists (s on the path ascending [m], offset [m]) with
    the window [s_lo_m, s_hi_m] where it is known (1 m beyond the samples), and the route
    position where it ends [m] (inf through)."""

    index: int
    width_m: float
    allows_passenger: bool
    is_shoulder: bool
    s_m: list[float]
    offset_m: list[float]
    s_lo_m: float
    s_hi_m: float
    end_m: float

    def slot(self, s_m: float, route_pos_m: float) -> LaneSlot:
        ys = self.offset_m
        # no samples: the window is empty (s_lo_m = inf > s_hi_m = -inf)
        offset = interp_scalar(s_m, self.s_m, ys, ys[0], ys[-1]) \
            if self.s_lo_m <= s_m <= self.s_hi_m else math.nan
        return LaneSlot(self.index, self.width_m, self.allows_passenger, self.is_shoulder,
                        offset_m=offset, continues_m=max(self.end_m - route_pos_m, 0.0))


@dataclass(frozen=True)
class _EdgeLanes:
    """Route edge k's lanes (in the lane graph's order) and the reference's lane index on
    it (None: outside the reference's window)."""

    lanes: tuple[_LaneProfile, ...]
    reference_index: int | None


class LaneContextMap:
    """See the module docstring. Every route edge's lanes are prepared on construction."""

    def __init__(self, network: RoadNetwork, route: Sequence[str], reference: RouteReference,
                 path: FrenetPath) -> None:
        self._network = network
        self._route = tuple(route)
        self._reference = reference
        self._path = path
        self._graph = RouteLaneGraph(network, self._route)
        self._length_m = network.route_length_m(self._route)
        self._starts = network.route_edge_starts_m(self._route)
        self._ending = self._ending_lanes()
        # Every edge at build time, at its first place on the route (the one a route
        # position maps to): prepared on first use, an edge's lane profiles (its lanes'
        # shapes projected onto the path, ~1.5 ms) landed in the control step the ego
        # entered it, one of the longest steps of a run.
        self._edges: dict[str, _EdgeLanes] = {}
        for k, edge in enumerate(self._route):
            if edge not in self._edges:
                self._edges[edge] = self._edge_lanes(k)

    def _ending_lanes(self) -> dict[str, dict[int, tuple[float, int]]]:
        """Route edge -> lane index -> (route position where the lane ends, merge side)
        for lanes that end on the route without leaving it (not through, not an exit);
        the side is towards the neighbour that reaches further (+1 left, -1 right)."""
        g = self._graph
        out: dict[str, dict[int, tuple[float, int]]] = {}
        for k, edge in enumerate(self._route):
            lanes = g.lanes(k)
            for i in lanes:
                if g.is_through(k, i) or g.is_exit(k, i):
                    continue
                reach = {d: g.reach(k, i + d) for d in (1, -1) if i + d in lanes}
                if not reach:
                    continue
                side = max(reach, key=lambda d: (reach[d], d))  # left on a tie
                if reach[side] <= g.reach(k, i):
                    continue
                out.setdefault(edge, {})[i] = (self._end_m(k, i), side)
        return out

    def _profile(self, k: int) -> dict[int, tuple[FloatArray, FloatArray]]:
        """Lane index -> (s on the path, offset) along that lane of route edge k."""
        out: dict[int, tuple[FloatArray, FloatArray]] = {}
        for i, lane in self._graph.lanes(k).items():
            pts = _resample_shape(np.asarray(lane.shape_xy_m, dtype=np.float64), _SAMPLE_M)
            s, y = self._path.project(pts[:, 0], pts[:, 1])
            order = np.argsort(s)
            out[i] = (np.asarray(s, dtype=np.float64)[order],
                      np.asarray(y, dtype=np.float64)[order])
        return out

    def _end_m(self, k: int, i: int) -> float:
        """Route position where lane (k, i) ends (inf for a through lane)."""
        if self._graph.is_through(k, i):
            return math.inf
        last = self._graph.reach(k, i)
        edge = self._route[last]
        return self._starts[edge] + self._network.edge_length_m(edge)

    def _edge_lanes(self, k: int) -> _EdgeLanes:
        """Route edge k prepared for :meth:`at`."""
        profiles = self._profile(k)
        lanes = []
        for lane in self._graph.lanes(k).values():
            s_prof, y_prof = profiles[lane.index]
            lo, hi = (float(s_prof[0] - 1.0), float(s_prof[-1] + 1.0)) if s_prof.size \
                else (math.inf, -math.inf)
            lanes.append(_LaneProfile(lane.index, lane.width_m, lane.allows_passenger,
                                      lane.is_shoulder, s_prof.tolist(), y_prof.tolist(), lo,
                                      hi, self._end_m(k, lane.index)))
        return _EdgeLanes(tuple(lanes), self._reference.lane_index_by_edge.get(self._route[k]))

    def route_pos(self, s_m: float) -> float:
        """Route position [m] of arc length ``s_m`` on the reference."""
        return self._reference.route_pos(s_m)

    def at(self, s_m: float) -> LaneContext:
        pos = min(max(self._reference.route_pos(s_m), 0.0), self._length_m - 1e-3)
        edge, _ = self._network.locate(self._route, pos)
        prepared = self._edges[edge]
        slots = {p.index: p.slot(s_m, pos) for p in prepared.lanes}
        ref = prepared.reference_index
        if ref is None:  # outside the reference's window: the lane nearest the path
            known = {i: abs(sl.offset_m) for i, sl in slots.items() if math.isfinite(sl.offset_m)}
            ref = min(known, key=known.__getitem__) if known else min(slots)
        return LaneContext(slots, ref, self._reference.lane_index_by_edge, self._ending, pos)
