"""Physical lanes of a route for the stress generator: the through lanes at a route
position (regular lanes that reach the end of the route: not a shoulder, an acceleration
lane that ends or an exit), counted from the right, and the geometry of the lane the ego
drives in (its curvature along the route).

Built on :class:`suite.road.lane_graph.RouteLaneGraph`; lane indices are SUMO's, per
edge (0 = rightmost of that edge).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports.geometry import arc_lengths_m
from suite.road.lane_graph import RouteLaneGraph
from suite.road.network import RoadNetwork

__all__ = ["JUNCTION_CLEARANCE_M", "RouteLanes", "lane_curvature"]

JUNCTION_CLEARANCE_M = 20.0
"""Cars are not placed closer than this to either end of an edge (junctions, where lane
indices may change)."""


@dataclass
class RouteLanes:
    """The through lanes of a route on its network."""

    network: RoadNetwork
    route: tuple[str, ...]

    def __post_init__(self) -> None:
        self.graph = RouteLaneGraph(self.network, self.route)
        self.starts = self.network.route_edge_starts_m(self.route)
        self.length_m = self.network.route_length_m(self.route)

    def edge_index(self, pos_m: float) -> int:
        edge, _ = self.network.locate(self.route, pos_m)
        return self.route.index(edge)

    def through(self, k: int) -> list[int]:
        """SUMO indices of the through lanes of route edge k, right to left."""
        lanes = self.graph.lanes(k)
        return sorted(i for i, li in lanes.items()
                      if li.allows_passenger and not li.is_shoulder
                      and self.graph.is_through(k, i))

    def clear_of_junctions(self, pos_m: float) -> float:
        """``pos_m`` moved forward (in 5 m steps, at most 200 m) until it is at least
        :data:`JUNCTION_CLEARANCE_M` from both ends of its edge."""
        pos = pos_m
        for _ in range(40):
            edge, on_edge = self.network.locate(self.route, pos)
            length = self.network.edge_length_m(edge)
            if length < 2 * JUNCTION_CLEARANCE_M + 5.0:
                pos = self.starts[edge] + length + 1.0
            elif on_edge < JUNCTION_CLEARANCE_M:
                pos += JUNCTION_CLEARANCE_M - on_edge
            elif on_edge > length - JUNCTION_CLEARANCE_M:
                pos = self.starts[edge] + length + 1.0
            else:
                return pos
            if pos >= self.length_m - 1.0:
                break
        return pos_m

    def lane_at(self, pos_m: float, lane_u: float) -> tuple[int, int]:
        """(SUMO lane index, number of through lanes) of through lane ``floor(u n)`` at
        ``pos_m``."""
        lanes = self.through(self.edge_index(pos_m))
        if not lanes:
            raise ValueError(f"no through lane at {pos_m:.1f} m on the route")
        return lanes[min(int(lane_u * len(lanes)), len(lanes) - 1)], len(lanes)

    def physical(self, pos_m: float, lane: int) -> list[tuple[int, int]]:
        """The (route edge, lane index) nodes of the physical lane through ``lane`` at
        ``pos_m`` (its chain along the route)."""
        return [(st.k, st.lane.index) for st in self.graph.chain(self.edge_index(pos_m), lane)]

    def same_lane(self, pos_a: float, lane_a: int, pos_b: float, lane_b: int) -> bool:
        """Whether two (position, lane index) placements are on one physical lane."""
        return (self.edge_index(pos_b), lane_b) in set(self.physical(pos_a, lane_a))

    def centreline(self, pos_m: float, lane: int) -> np.ndarray:
        """(M, 2) [m] centreline of the physical lane through ``lane`` at ``pos_m``, its
        lanes and the internal junction lanes between them in driving order."""
        pts: list[np.ndarray] = []
        for st in self.graph.chain(self.edge_index(pos_m), lane):
            pts.append(np.asarray(st.lane.shape_xy_m, dtype=np.float64).reshape(-1, 2))
            if st.link is not None:
                pts += [np.asarray(v, dtype=np.float64).reshape(-1, 2)
                        for v in st.link.via_shapes]
        return np.concatenate(pts, axis=0)


def lane_curvature(xy_m: np.ndarray, spacing_m: float = 5.0, window_m: float = 50.0
                   ) -> tuple[float, float]:
    """(smallest radius [m], total turn [deg]) of a centreline (M, 2): resampled every
    ``spacing_m``, heading unwrapped, curvature = d(heading)/ds over ``window_m``; the
    radius is 1 / the largest |curvature| (inf for a straight line), the turn the net
    heading change end to end."""
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    seg = np.hypot(*np.diff(xy, axis=0).T)
    keep = np.concatenate([[True], seg > 1e-6])
    xy = xy[keep]
    if xy.shape[0] < 3:
        return math.inf, 0.0
    s = arc_lengths_m(xy)
    grid = np.arange(0.0, s[-1], spacing_m)
    x, y = np.interp(grid, s, xy[:, 0]), np.interp(grid, s, xy[:, 1])
    heading = np.unwrap(np.arctan2(np.diff(y), np.diff(x)))
    k = max(1, int(round(window_m / spacing_m)))
    if heading.size <= k:
        return math.inf, float(np.degrees(abs(heading[-1] - heading[0])))
    curvature = np.abs(heading[k:] - heading[:-k]) / (k * spacing_m)
    peak = float(curvature.max())
    radius = 1.0 / peak if peak > 1e-9 else math.inf
    return radius, float(np.degrees(abs(heading[-1] - heading[0])))
