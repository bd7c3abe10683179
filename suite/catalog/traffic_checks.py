"""Traffic against the network: per-lane traffic speeds (``traffic.lane_speeds_mps``) on
lanes that get traffic, and on-ramp traffic (``ramp_traffic``) from edges off the route
whose lanes lead onto it (:func:`ramp_route` is also the route those vehicles drive)."""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

from suite.catalog.report import Report
from suite.catalog.specs import RampTrafficSpec, TrafficSpec
from suite.road.network import RoadNetwork

__all__ = ["MAX_RAMP_EDGES", "check_traffic", "ramp_route"]

MAX_RAMP_EDGES = 8
"""An on-ramp reaches the route within this many edges (the search stops there)."""


def ramp_route(network: RoadNetwork, edge: str, route: Sequence[str]) -> tuple[str, ...] | None:
    """The edges a vehicle entering at ``edge`` drives: the shortest chain of lane
    connections (no turnarounds) from ``edge`` to the first route edge it reaches, then
    the route to its end. None if no route edge is reachable within
    :data:`MAX_RAMP_EDGES` edges (or ``edge`` is on the route)."""
    on_route = {e: k for k, e in enumerate(route)}
    if edge in on_route or not network.has_edge(edge):
        return None
    parent: dict[str, str | None] = {edge: None}
    queue: deque[tuple[str, int]] = deque([(edge, 1)])
    while queue:
        current, depth = queue.popleft()
        if depth > MAX_RAMP_EDGES:
            continue
        for nxt in sorted({link.to_edge_id for link in network.lane_links(current)
                           if link.direction != "t"}):
            if nxt in parent or not network.has_edge(nxt):
                continue
            parent[nxt] = current
            if nxt in on_route:
                chain: list[str] = []
                node: str | None = current
                while node is not None:
                    chain.append(node)
                    node = parent[node]
                return (*reversed(chain), *route[on_route[nxt]:])
            queue.append((nxt, depth + 1))
    return None


def _allows_passenger(network: RoadNetwork, edge: str, lane: int | None = None) -> bool:
    return any(info.allows_passenger and (lane is None or info.index == lane)
               for info in network.lane_info((edge,)))


def _check_lane_speeds(network: RoadNetwork, route: Sequence[str], traffic: TrafficSpec,
                       report: Report) -> None:
    if traffic.lane_speeds_mps is None:
        return
    first = route[0]
    count = network.lane_count(first)
    for lane in traffic.own_speed_lanes():
        key = f"traffic.lane_speeds_mps.{lane}"
        if lane >= count:
            report.add(key, f"a lane index in 0..{count - 1} (lanes of the first route edge "
                       f"{first!r})", lane)
        elif not _allows_passenger(network, first, lane):
            report.add(key, f"a lane open to passenger cars (lane {lane} of {first!r} is "
                       "not)", lane)
        elif traffic.lanes is not None and lane not in traffic.lanes:
            report.add(key, f"a lane that gets traffic (one of traffic.lanes "
                       f"{list(traffic.lanes)})", lane)


def _check_ramp(network: RoadNetwork, route: Sequence[str], i: int, ramp: RampTrafficSpec,
                report: Report) -> None:
    key = f"ramp_traffic.{i}.edge"
    if not network.has_edge(ramp.edge):
        edges = [e for e in network.edge_ids() if e not in route]
        shown = edges if len(edges) <= 20 else [*edges[:20], "..."]
        report.add(key, f"an edge of {network.path.name} off the route (one of {shown})",
                   ramp.edge)
    elif ramp.edge in route:
        report.add(key, "an edge off the route (traffic on the route is 'traffic')",
                   ramp.edge)
    elif not _allows_passenger(network, ramp.edge):
        report.add(key, "an edge with a lane open to passenger cars", ramp.edge)
    elif ramp_route(network, ramp.edge, route) is None:
        report.add(key, f"an edge whose lanes lead onto the route within {MAX_RAMP_EDGES} "
                   "edges (an on-ramp)", ramp.edge)


def check_traffic(network: RoadNetwork, route: Sequence[str], traffic: TrafficSpec | None,
                  ramps: Sequence[RampTrafficSpec | None], report: Report) -> None:
    """Report lane speeds on lanes without traffic and ramps that do not lead onto the
    route (``None`` entries of ``ramps`` were invalid already and are skipped)."""
    if traffic is not None:
        _check_lane_speeds(network, route, traffic, report)
    for i, ramp in enumerate(ramps):
        if ramp is not None:
            _check_ramp(network, route, i, ramp, report)
