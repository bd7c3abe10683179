"""The lanes of a route as a graph: each lane followed across edges by its connections.

Nodes are (k, i): lane i (SUMO's per-edge index, 0 = rightmost of that edge) of the k-th
route edge. A node links to the lanes of edge k+1 it has connections to (through the
internal junction lanes). From that:

* ``reach(k, i)``: the last route edge a vehicle in that lane can get to without a lane
  change. A *through* lane reaches the route's last edge; a lane that *ends* has no
  connection on (an acceleration lane); an *exit* lane connects only off the route.
* ``continuation(k, i)``: where the physical lane goes next: among its links, the one
  that reaches furthest, then the one with the smallest lateral jump at the junction
  (the lane straight ahead, whatever its index there). Lane indices shift along a route
  wherever a lane is added or dropped on the right; following connections keeps the
  lane's identity.
* ``chain(k, i)``: the physical lane through (k, i), followed back to where it starts and
  forward to where it ends (backwards, among the lanes feeding it, the one straight
  behind).
* ``reference_chain(k, i)``: the lane the controller's reference follows for an ego in
  (k, i): that lane's chain if it is a through lane, else the chain of the nearest
  through lane of edge k (the lane the ego's lane merges into or leaves from). It never
  follows an exit or a lane that ends unless the route itself ends there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from reports.geometry import polyline_length_m
from suite.road.network import LaneInfo, LaneLink, RoadNetwork

Node = tuple[int, int]


@dataclass(frozen=True)
class ChainStep:
    """One lane of a chain and the link that leaves it (None on the chain's last lane)."""

    k: int
    lane: LaneInfo
    link: LaneLink | None


class RouteLaneGraph:
    """The lane graph of ``route`` on ``network`` (see the module docstring)."""

    def __init__(self, network: RoadNetwork, route: tuple[str, ...]) -> None:
        self.network = network
        self.route = tuple(route)
        infos = network.lane_info(self.route)
        self._lanes: list[dict[int, LaneInfo]] = [{} for _ in self.route]
        k_of = {eid: k for k, eid in enumerate(self.route)}
        for li in infos:
            self._lanes[k_of[li.edge_id]][li.index] = li
        self._links: dict[Node, list[LaneLink]] = {}
        self._off_route: dict[Node, int] = {}
        for k, eid in enumerate(self.route):
            nxt = self.route[k + 1] if k + 1 < len(self.route) else None
            for link in network.lane_links(eid):
                node = (k, link.from_index)
                if link.to_edge_id == nxt and link.direction != "t":
                    self._links.setdefault(node, []).append(link)
                else:
                    self._off_route[node] = self._off_route.get(node, 0) + 1
        self._reach: dict[Node, int] = {}
        for k in range(len(self.route) - 1, -1, -1):
            for i in self._lanes[k]:
                links = self._links.get((k, i), [])
                self._reach[(k, i)] = max((self._reach[(k + 1, ln.to_index)] for ln in links
                                           if (k + 1, ln.to_index) in self._reach), default=k)

    # ------------------------------------------------------------------ queries
    @property
    def last(self) -> int:
        return len(self.route) - 1

    def lanes(self, k: int) -> dict[int, LaneInfo]:
        """The lanes of the k-th route edge by index."""
        return self._lanes[k]

    def reach(self, k: int, i: int) -> int:
        return self._reach[(k, i)]

    def is_through(self, k: int, i: int) -> bool:
        return self._reach[(k, i)] == self.last

    def is_exit(self, k: int, i: int) -> bool:
        """The lane leaves the route (connects only off it) before the route ends."""
        return self._reach[(k, i)] < self.last and self._off_route.get(
            (self._reach[(k, i)], self.chain_end_index(k, i)), 0) > 0

    def chain_end_index(self, k: int, i: int) -> int:
        """The lane index at the end of the chain from (k, i) forward."""
        node = (k, i)
        while True:
            nxt = self.continuation(*node)
            if nxt is None:
                return node[1]
            node = (node[0] + 1, nxt.to_index)

    def _jump_m(self, k: int, link: LaneLink) -> float:
        """Distance from the end of lane (k, from) to the start of its target lane [m]:
        0 for a lane straight ahead, about a lane width for a merge or a split."""
        end = np.asarray(self._lanes[k][link.from_index].shape_xy_m[-1])
        start = np.asarray(self._lanes[k + 1][link.to_index].shape_xy_m[0])
        return float(np.hypot(*(start - end)))

    def continuation(self, k: int, i: int) -> LaneLink | None:
        """The link the physical lane (k, i) follows into edge k+1 (None: it ends)."""
        links = [ln for ln in self._links.get((k, i), []) if ln.to_index in self._lanes[k + 1]]
        if not links:
            return None
        return min(links, key=lambda ln: (-self._reach[(k + 1, ln.to_index)],
                                          self._jump_m(k, ln), ln.to_index))

    def predecessor(self, k: int, i: int) -> tuple[int, LaneLink] | None:
        """(lane index on edge k-1, link) of the lane straight behind (k, i), if any."""
        if k == 0:
            return None
        feeding = [(j, ln) for j in self._lanes[k - 1] for ln in self._links.get((k - 1, j), [])
                   if ln.to_index == i]
        if not feeding:
            return None
        return min(feeding, key=lambda jl: (self._jump_m(k - 1, jl[1]), jl[0]))

    def chain(self, k: int, i: int) -> list[ChainStep]:
        """The physical lane through (k, i), first lane to last (module docstring)."""
        if i not in self._lanes[k]:
            raise KeyError(f"route edge {k} ({self.route[k]!r}) has no lane {i}")
        back: list[ChainStep] = []
        node = (k, i)
        while (prev := self.predecessor(*node)) is not None:
            j, feeding = prev
            node = (node[0] - 1, j)
            back.append(ChainStep(node[0], self._lanes[node[0]][j], feeding))
        steps = back[::-1]
        node = (k, i)
        while True:
            link = self.continuation(*node)
            steps.append(ChainStep(node[0], self._lanes[node[0]][node[1]], link))
            if link is None:
                return steps
            node = (node[0] + 1, link.to_index)

    def reference_lane(self, k: int, i: int) -> int:
        """The lane of edge k the reference follows for an ego in (k, i)."""
        if self.is_through(k, i):
            return i
        through = [j for j in self._lanes[k] if self.is_through(k, j)
                   and self._lanes[k][j].allows_passenger]
        if not through:  # nothing continues to the route's end: the furthest-reaching lane
            return max(self._lanes[k], key=lambda j: (self._reach[(k, j)], -abs(j - i)))
        # The nearest through lane; to the left first (a lane that ends on the right
        # merges left, an exit on the right leaves the through lanes on its left).
        return min(through, key=lambda j: (abs(j - i), 0 if j > i else 1))

    def reference_chain(self, k: int, i: int) -> list[ChainStep]:
        return self.chain(k, self.reference_lane(k, i))

    @cached_property
    def through_counts(self) -> list[int]:
        """Number of through lanes on each route edge."""
        return [sum(1 for i in lanes if self.is_through(k, i))
                for k, lanes in enumerate(self._lanes)]


def lane_lateral_order(lanes: dict[int, LaneInfo]) -> list[int]:
    """Lane indices of one edge right to left (SUMO's index order)."""
    return sorted(lanes)


__all__ = ["ChainStep", "RouteLaneGraph", "lane_lateral_order", "math", "polyline_length_m"]
