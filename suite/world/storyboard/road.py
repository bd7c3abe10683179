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

import numpy as np

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
class _LaneShape:
    """A lane's shape (n, 2) [m], its cumulative arc length [m] and route metres per
    shape metre (as :func:`suite.road.lane_pose.lane_frame` scales them)."""

    xy: np.ndarray
    cum: np.ndarray
    scale: float

    def point(self, a_m: float) -> tuple[float, float, float]:
        """(x, y, heading) at arc length ``a_m``, straight on beyond the ends."""
        i = int(np.clip(np.searchsorted(self.cum, a_m, side="right") - 1, 0,
                        len(self.cum) - 2))
        seg = self.xy[i + 1] - self.xy[i]
        t = (a_m - float(self.cum[i])) / float(self.cum[i + 1] - self.cum[i])
        return (float(self.xy[i, 0] + t * seg[0]), float(self.xy[i, 1] + t * seg[1]),
                math.atan2(float(seg[1]), float(seg[0])))


@dataclass
class SumoRoad:
    """Lanes and poses along ``route`` of ``network`` (lane widths and shapes cached per
    edge; the frame of :func:`suite.road.lane_pose.lane_frame`)."""

    network: RoadNetwork
    route: tuple[str, ...]
    _widths: dict[str, tuple[float, ...]] = field(default_factory=dict)
    _shapes: dict[str, tuple[_LaneShape, ...]] = field(default_factory=dict)

    def _clip(self, pos_m: float) -> float:
        return min(max(pos_m, 0.0), self.network.route_length_m(self.route) - 1e-6)

    def widths(self, pos_m: float) -> tuple[float, ...]:
        edge, _ = self.network.locate(self.route, self._clip(pos_m))
        if edge not in self._widths:
            self._widths[edge] = tuple(self.network.lane_width_m(edge, i)
                                       for i in range(self.network.lane_count(edge)))
        return self._widths[edge]

    def _lanes(self, edge: str) -> tuple[_LaneShape, ...]:
        if edge not in self._shapes:
            out = []
            for ln in self.network.lane_info((edge,)):
                xy = np.asarray(ln.shape_xy_m, dtype=np.float64)
                seg = np.hypot(*np.diff(xy, axis=0).T)
                keep = np.concatenate([[True], seg > 0.0])
                xy = xy[keep]
                cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
                out.append(_LaneShape(xy, cum, self.network.edge_length_m(edge)
                                      / float(cum[-1])))
            self._shapes[edge] = tuple(out)
        return self._shapes[edge]

    def pose(self, pos_m: float, lane: int, lateral_m: float,
             heading_rad: float) -> tuple[float, float, float]:
        """World front bumper (x, y) [m] and heading [rad]; straight on past the ends."""
        edge, along = self.network.locate(self.route, self._clip(pos_m))
        shapes = self._lanes(edge)
        shape = shapes[min(max(lane, 0), len(shapes) - 1)]
        x, y, h = shape.point((along + pos_m - self._clip(pos_m)) / shape.scale)
        return x - lateral_m * math.sin(h), y + lateral_m * math.cos(h), h + heading_rad
