"""A vehicle's position along the run's route as SUMO has it: the one definition the
world's actor triggers and the storyboard's ego both read."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["route_position_m"]


def route_position_m(vehicle: Any, vid: str, edge_starts_m: Mapping[str, float]) -> float:
    """Vehicle ``vid``'s front bumper route position [m]: the start of its edge on the
    route (``edge_starts_m``: route edge id -> its start [m] along the route) plus its
    lane position (SUMO's, the front bumper's); NaN on an edge off the route or on a
    junction's internal lane. ``vehicle``: libsumo's (or TraCI's) vehicle domain."""
    start = edge_starts_m.get(str(vehicle.getRoadID(vid)))
    return math.nan if start is None else start + float(vehicle.getLanePosition(vid))
