"""Positions: OpenSCENARIO positions of an entity's reference point -> places on the
SUMO route (:class:`~suite.catalog.storyboard.RoutePosition`), and back.

* Lane position (road, lane id, s, offset): the lane's SUMO edge of the lane section
  holding s, at the same *fraction* of that edge as s is of the section (the reference
  line's and the lane's lengths differ on a curve by the same factor for a constant
  radius); lanes with positive ids drive against the reference line, so their
  fraction and offset are mirrored. The offset [m] is kept (left of the driving
  direction +).
* Road position (road, s, t): the lane whose band holds t at s
  (:mod:`~suite.importers.openscenario.lane_bands`), then as a lane position.
* World position (x, y, h): the nearest route lane, then its lane frame.
* Relative lane (entity, dLane, ds, offset), relative road (entity, ds, dt), relative
  object (entity, dx, dy in its frame), relative world (entity, dx, dy): from the
  entity's place, through the same conversions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from suite.catalog.storyboard import RoutePosition
from suite.importers.openscenario.errors import fail_at
from suite.importers.openscenario.lane_bands import RoadBands
from suite.importers.openscenario.road import LaneMap
from suite.road.lane_pose import lane_frame, pose_in_lane
from suite.road.network import RoadNetwork

__all__ = ["MAX_OFF_ROUTE_M", "OdrPlace", "Placer", "nearest_lane"]

MAX_OFF_ROUTE_M = 5.0  # a world position farther than this [m] from every route lane


def nearest_lane(network: RoadNetwork, route: tuple[str, ...], x_m: float,
                 y_m: float) -> tuple[float, float, int]:
    """(distance [m], route position [m], lane index) of the route lane whose centre
    line passes nearest (x, y); the position scaled from the lane's arc length to its
    edge's length, as SUMO's lane positions are."""
    starts = network.route_edge_starts_m(route)
    best = (math.inf, 0.0, 0)
    p = np.array([x_m, y_m])
    for lane in network.lane_info(route):
        xy = np.asarray(lane.shape_xy_m, dtype=np.float64)
        a, seg = xy[:-1], np.diff(xy, axis=0)
        seg_len2 = np.maximum(np.sum(seg * seg, axis=1), 1e-12)
        t = np.clip(np.sum((p - a) * seg, axis=1) / seg_len2, 0.0, 1.0)
        foot = a + t[:, None] * seg
        d = np.hypot(*(foot - p).T)
        k = int(np.argmin(d))
        cum = np.concatenate([[0.0], np.cumsum(np.sqrt(seg_len2))])
        along = (float(cum[k]) + float(t[k]) * math.sqrt(float(seg_len2[k])))
        pos = starts[lane.edge_id] + along / float(cum[-1]) \
            * network.edge_length_m(lane.edge_id)
        if float(d[k]) < best[0] - 1e-9:
            best = (float(d[k]), pos, lane.index)
    return best


@dataclass(frozen=True)
class OdrPlace:
    """An OpenDRIVE place: road, lane id, s [m], offset [m, towards +t]."""

    road: str
    lane: int
    s_m: float
    offset_m: float


@dataclass
class Placer:
    """Converts positions on one scenario's route (module docstring)."""

    lane_map: LaneMap
    bands: dict[str, RoadBands]
    network: RoadNetwork
    route: tuple[str, ...]
    places: dict[str, RoutePosition] = field(default_factory=dict)  # entity -> ref point

    # ---------------------------------------------------------------- OpenDRIVE <-> route
    def _span(self, el: Any, road: str, side: int) -> tuple[float, float]:
        """Route positions [m] where the road's edges of one side begin and end (their
        junctions between lane sections included)."""
        edges = self.lane_map.edges.get((road, side), ())
        starts = self.network.route_edge_starts_m(self.route)
        on = [e for e in edges if e in starts]
        if not on:
            raise fail_at(el, f"road {road} ({'right' if side < 0 else 'left'} lanes) is not "
                          f"on the ego's route {list(self.route)}")
        return starts[on[0]], starts[on[-1]] + self.network.edge_length_m(on[-1])

    def from_lane(self, el: Any, road: str, lane: int, s_m: float, offset_m: float,
                  heading_rad: float = 0.0) -> RoutePosition:
        """A lane position as a route position (``el`` names the element on error):
        s scaled from the road's length to its edges' span on the route (their lengths
        and the junctions between lane sections: netconvert cuts an edge back at a
        section's end)."""
        if road not in self.lane_map.roads:
            raise fail_at(el, f"road {road!r} is not in the road network")
        pairs = self.lane_map.lanes.get((road, lane))
        if not pairs:
            raise fail_at(el, f"lane {lane} of road {road} has no SUMO lane (netconvert "
                          "imports driving-type lanes only, or the lane does not exist)")
        side = -1 if lane < 0 else 1
        a, b = self._span(el, road, side)
        length = self.lane_map.roads[road].length_m
        frac = min(max(s_m / length, 0.0), 1.0) if length > 0 else 0.0
        pos = a + (frac if side < 0 else 1.0 - frac) * (b - a)
        pos = min(pos, b - 1e-6)
        edge, _ = self.network.locate(self.route, pos)
        index = next((i for e, i in pairs if e == edge), None)
        if index is None:
            raise fail_at(el, f"road {road} lane {lane} has no SUMO lane at s = {s_m:g} m "
                          f"(edge {edge})")
        sign = 1.0 if side < 0 else -1.0
        return RoutePosition(pos, index, sign * offset_m, heading_rad)

    def to_lane(self, p: RoutePosition) -> OdrPlace:
        """The OpenDRIVE place of a route position (the inverse of :meth:`from_lane`)."""
        edge, _ = self.network.locate(self.route, p.pos_m)
        for (road, lane), pairs in self.lane_map.lanes.items():
            if (edge, p.lane) not in pairs:
                continue
            side = -1 if lane < 0 else 1
            a, b = self._span(None, road, side)
            frac = (p.pos_m - a) / (b - a) if b > a else 0.0
            frac = frac if side < 0 else 1.0 - frac
            return OdrPlace(road, lane, frac * self.lane_map.roads[road].length_m,
                            p.lateral_m if side < 0 else -p.lateral_m)
        raise ValueError(f"edge {edge} lane {p.lane} has no OpenDRIVE lane")

    def from_road(self, el: Any, road: str, s_m: float, t_m: float,
                  heading_rad: float = 0.0) -> RoutePosition:
        bands = self.bands.get(road)
        hit = None if bands is None else bands.lane_at(s_m, t_m)
        if hit is None:
            raise fail_at(el, f"road {road} has no lane at s = {s_m:g} m, t = {t_m:g} m")
        return self.from_lane(el, road, hit[0], s_m, hit[1], heading_rad)

    # ---------------------------------------------------------------- world
    def xy(self, p: RoutePosition) -> tuple[float, float, float]:
        """World x, y [m] and heading [rad] of a route position."""
        frame = lane_frame(self.network, self.route, p.pos_m, p.lane)
        return frame.place(p.lateral_m, p.heading_rad)

    def from_xy(self, el: Any, x_m: float, y_m: float, heading_rad: float) -> RoutePosition:
        """The pose of world point (x, y) heading ``heading_rad`` in the frame of the
        nearest route lane (:func:`nearest_lane`)."""
        distance, pos, lane = nearest_lane(self.network, self.route, x_m, y_m)
        if distance > MAX_OFF_ROUTE_M:
            raise fail_at(el, f"({x_m:g}, {y_m:g}) is {distance:.1f} m from the route")
        pose = pose_in_lane(self.network, self.route, pos, lambda _p: lane, x_m, y_m,
                            heading_rad)
        return RoutePosition(pose.pos_m, pose.lane, pose.lateral_m, pose.heading_rad)

    # ---------------------------------------------------------------- relative
    def ref(self, el: Any, name: str) -> RoutePosition:
        if name not in self.places:
            raise fail_at(el, f"entity {name!r} has no position yet (place it first)")
        return self.places[name]

    def relative_lane(self, el: Any, name: str, dlane: int, ds_m: float,
                      offset_m: float) -> RoutePosition:
        base = self.to_lane(self.ref(el, name))
        lane = base.lane + dlane
        if base.lane * lane <= 0:  # across the reference line: lane 0 has no id
            lane += 1 if dlane > 0 else -1
        return self.from_lane(el, base.road, lane, base.s_m + ds_m, offset_m)

    def relative_road(self, el: Any, name: str, ds_m: float, dt_m: float) -> RoutePosition:
        base = self.to_lane(self.ref(el, name))
        t = self.bands[base.road].centre_t(base.s_m, base.lane) + base.offset_m
        return self.from_road(el, base.road, base.s_m + ds_m, t + dt_m)

    def relative_xy(self, el: Any, name: str, dx_m: float, dy_m: float,
                    local: bool) -> RoutePosition:
        x, y, h = self.xy(self.ref(el, name))
        if local:
            dx_m, dy_m = (dx_m * math.cos(h) - dy_m * math.sin(h),
                          dx_m * math.sin(h) + dy_m * math.cos(h))
        return self.from_xy(el, x + dx_m, y + dy_m, h)
