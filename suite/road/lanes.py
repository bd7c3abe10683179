"""Lane context along a route: the lanes of the road under a route position."""

from __future__ import annotations

from collections.abc import Sequence

from controllers.behaviour.types import LaneContext, LaneSlot
from suite.road.network import RoadNetwork


class LaneContextMap:
    """:meth:`at` gives the :class:`LaneContext` at a route position [m]: the lanes of the
    edge there (a position inside a junction maps to the next edge) with the reference
    lane's index."""

    def __init__(self, network: RoadNetwork, route: Sequence[str], reference_index: int) -> None:
        self._network = network
        self._route = tuple(route)
        self._length_m = network.route_length_m(self._route)
        self._by_edge: dict[str, LaneContext] = {}
        slots: dict[str, dict[int, LaneSlot]] = {}
        for li in network.lane_info(self._route):
            slots.setdefault(li.edge_id, {})[li.index] = LaneSlot(
                li.index, li.width_m, li.allows_passenger, li.is_shoulder)
        for edge, by_index in slots.items():
            self._by_edge[edge] = LaneContext(by_index, reference_index)
        self._empty = LaneContext({}, reference_index)

    def at(self, s_m: float) -> LaneContext:
        edge, _ = self._network.locate(self._route, min(max(s_m, 0.0), self._length_m - 1e-3))
        return self._by_edge.get(edge, self._empty)
