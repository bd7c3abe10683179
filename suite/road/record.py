"""The lanes ``road.json`` keeps for a route: what the drivable-area metric is built from.

:func:`route_lane_records` gives every lane of every route edge (netconvert's shape and
width, permissions, speed) and the internal junction lanes (``:node_...``) of every
lane connection between consecutive route edges (``internal``; they take the
permissions of the lane they leave). Lanes of edges off the route (an exit ramp after
its split, an on-ramp before its merge) and internal lanes towards them are not kept:
the drivable area is the route's road, and the wedge where a lane ends or begins beside
another is built by the metric from these lanes' ends and starts
(:mod:`reports.metrics.drivable`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from reports.record import LaneRecord
from suite.road.network import RoadNetwork


def route_lane_records(network: RoadNetwork, route: Sequence[str]) -> tuple[LaneRecord, ...]:
    """The route's lanes, then the internal junction lanes between consecutive route
    edges in route order (each once; see the module doc)."""
    route = tuple(route)
    lanes = [LaneRecord(id=li.id, edge_id=li.edge_id, index=li.index, width_m=li.width_m,
                        shape_xy_m=np.asarray(li.shape_xy_m, dtype=np.float64),
                        allowed=li.allowed, is_shoulder=li.is_shoulder,
                        allows_passenger=li.allows_passenger, speed_mps=li.speed_mps)
             for li in network.lane_info(route)]
    seen = {lane.id for lane in lanes}
    by_id = {lane.id: lane for lane in lanes}
    for k, edge in enumerate(route[:-1]):
        for link in network.lane_links(edge):
            source = by_id.get(f"{edge}_{link.from_index}")
            if link.to_edge_id != route[k + 1] or source is None:
                continue
            for via_id, shape, width in zip(link.via_ids, link.via_shapes, link.via_widths_m,
                                            strict=True):
                if via_id in seen:
                    continue
                seen.add(via_id)
                lanes.append(LaneRecord(
                    id=via_id, edge_id=via_id.rsplit("_", 1)[0], index=link.from_index,
                    width_m=width, shape_xy_m=np.asarray(shape, dtype=np.float64),
                    allowed=source.allowed, is_shoulder=source.is_shoulder,
                    allows_passenger=source.allows_passenger, speed_mps=source.speed_mps,
                    internal=True))
    return tuple(lanes)
