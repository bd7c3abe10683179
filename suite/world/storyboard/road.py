"""The road as the storyboard runtime sees it: lanes across the route at a route
position, and world poses. :class:`SumoRoad` reads them from the scenario's SUMO net.

The lateral place ``y`` [m, left +] is measured from the left border of the leftmost
lane of the edge at the position (as OpenDRIVE's t from a reference line on the left of
right-hand traffic): lane i's centre lies at -(the widths of the lanes left of it + half
its own). A lane added or dropped on the right (a ramp) keeps every other lane's y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

from suite.road.lane_pose import lane_frame
from suite.road.network import RoadNetwork

__all__ = ["LaneRoad", "SumoRoad"]


class LaneRoad(Protocol):
    def widths(self, pos_m: float) -> tuple[float, ...]: ...

    def pose(self, pos_m: float, lane: int, lateral_m: float,
             heading_rad: float) -> tuple[float, float, float]: ...


def lane_centre_y(road: LaneRoad, pos_m: float, lane: int) -> float:
    """y [m] of lane ``lane``'s centre at ``pos_m`` (module docstring)."""
    w = road.widths(pos_m)
    lane = min(max(lane, 0), len(w) - 1)
    return -(sum(w[lane + 1:]) + 0.5 * w[lane])


def lane_of(road: LaneRoad, pos_m: float, y_m: float) -> tuple[int, float]:
    """(lane whose band holds ``y_m``, offset from its centre [m]) at ``pos_m``; beyond
    the outer lanes the outer lane."""
    w = road.widths(pos_m)
    edge = 0.0  # the left border of lane i, going right from the leftmost lane
    for i in range(len(w) - 1, -1, -1):
        if y_m > edge - w[i] or i == 0:
            return i, y_m - (edge - 0.5 * w[i])
        edge -= w[i]
    return 0, 0.0  # pragma: no cover


@dataclass
class SumoRoad:
    """Lanes and poses along ``route`` of ``network`` (lane widths cached per edge; poses
    in the frame of :func:`suite.road.lane_pose.lane_frame`)."""

    network: RoadNetwork
    route: tuple[str, ...]
    _widths: dict[str, tuple[float, ...]] = field(default_factory=dict)

    def _clip(self, pos_m: float) -> float:
        return min(max(pos_m, 0.0), self.network.route_length_m(self.route) - 1e-6)

    def widths(self, pos_m: float) -> tuple[float, ...]:
        edge, _ = self.network.locate(self.route, self._clip(pos_m))
        if edge not in self._widths:
            self._widths[edge] = tuple(self.network.lane_width_m(edge, i)
                                       for i in range(self.network.lane_count(edge)))
        return self._widths[edge]

    def pose(self, pos_m: float, lane: int, lateral_m: float,
             heading_rad: float) -> tuple[float, float, float]:
        """World front bumper (x, y) [m] and heading [rad]: the pose in the frame of lane
        ``lane`` (clamped to the edge's lanes) at ``pos_m``
        (:func:`suite.road.lane_pose.lane_frame`, where a run starts its ego), straight
        on along the frame past the route's ends."""
        clipped = self._clip(pos_m)
        edge, _ = self.network.locate(self.route, clipped)
        last = self.network.lane_count(edge) - 1
        frame = lane_frame(self.network, self.route, clipped, min(max(lane, 0), last))
        beyond_m = (pos_m - clipped) / frame.scale  # lane-shape metres past the end
        x, y, h = frame.place(lateral_m, heading_rad)
        return (x + beyond_m * math.cos(frame.heading_rad),
                y + beyond_m * math.sin(frame.heading_rad), h)
