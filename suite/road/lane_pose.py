"""A pose in a lane's own frame: route position, lane, lateral offset and heading
relative to the lane (the catalog's ``ego`` start keys ``lateral_offset_m`` and
``heading_rad``, docs/catalog.md), to world x, y, heading and back.

**The lane frame** at route position p on lane i: e is the route edge at p
(:meth:`~suite.road.network.RoadNetwork.locate`: a position inside a junction belongs to
the next edge) and u = p - start(e) its position on e (negative inside the junction
before e). SUMO scales lane positions to the lane's shape: with the shape (m, 2) of
length l and the edge length L, u is the shape's arc length a = u l / L. The frame's
origin P is the point at a on the shape (continued straight along the first / last
segment beyond the shape's ends: netconvert cuts lane shapes back at junctions), its
direction theta the heading of the segment holding a, n = (-sin theta, cos theta) its
left normal and ``scale`` = L / l [m of route position per m of shape].

**A pose** (d, delta) in that frame is the point P + d n heading theta + delta: d [m,
left of the lane's centre line +], delta [rad, counter-clockwise from the lane's
direction +]. Its inverse for a point q heading psi (:func:`pose_in_lane`): Newton steps
on the route position, p <- p + ((q - P) . t) scale (t = (cos theta, sin theta)), until
q - P is normal to the lane within :data:`ALONG_TOL_M` (or the iterate that came
nearest, where the frame jumps at a lane's end and the steps cycle); then d = (q - P) .
n and delta = psi - theta wrapped to (-pi, pi]; what is left of (q - P) . t is the
residual. The forward and the inverse use this one frame, so a pose written by the
importer is the pose a run starts from, to rounding.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from suite.road.network import RoadNetwork

__all__ = ["ALONG_TOL_M", "EgoStartKeys", "LaneFrame", "LanePose", "ego_front_pose",
           "lane_frame", "pose_in_lane"]

ALONG_TOL_M = 1e-4
"""The inverse stops once the point lies this close [m] to the frame's normal line."""

MAX_NEWTON_STEPS = 12


@dataclass(frozen=True)
class LaneFrame:
    """The lane frame at a route position (module docstring): origin ``x_m``, ``y_m``
    [m], direction ``heading_rad`` [rad], ``scale`` [m of route position per m of the
    lane's shape], the edge and lane index it is on."""

    x_m: float
    y_m: float
    heading_rad: float
    scale: float
    edge_id: str
    lane: int

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "heading_rad", "scale"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: expected a finite number, got "
                                 f"{getattr(self, name)!r}")
        if not self.scale > 0.0:
            raise ValueError(f"scale: expected > 0, got {self.scale!r}")

    def place(self, lateral_m: float, heading_rad: float) -> tuple[float, float, float]:
        """World (x [m], y [m], heading [rad]) of the pose (lateral_m, heading_rad)."""
        c, s = math.cos(self.heading_rad), math.sin(self.heading_rad)
        return (self.x_m - lateral_m * s, self.y_m + lateral_m * c,
                self.heading_rad + heading_rad)

    def along_m(self, x_m: float, y_m: float) -> float:
        """(q - P) . t [m]: how far ahead of the origin the point lies along the lane."""
        return ((x_m - self.x_m) * math.cos(self.heading_rad)
                + (y_m - self.y_m) * math.sin(self.heading_rad))

    def lateral_m(self, x_m: float, y_m: float) -> float:
        """(q - P) . n [m]: how far left of the origin the point lies."""
        return (-(x_m - self.x_m) * math.sin(self.heading_rad)
                + (y_m - self.y_m) * math.cos(self.heading_rad))


@dataclass(frozen=True)
class LanePose:
    """A point's pose in a lane frame: route position ``pos_m``, lane index ``lane`` (of
    the edge at ``pos_m``), ``lateral_m`` [m, left +], ``heading_rad`` [rad, relative to
    the lane] and the remaining along-lane error ``residual_m`` [m]."""

    pos_m: float
    lane: int
    lateral_m: float
    heading_rad: float
    residual_m: float


def _point_at(shape: np.ndarray, a: float) -> tuple[float, float, float]:
    """(x, y, heading) at arc length ``a`` of ``shape``, straight beyond its ends."""
    seg = np.diff(shape, axis=0)
    lens = np.hypot(seg[:, 0], seg[:, 1])
    keep = lens > 0.0
    seg, lens = seg[keep], lens[keep]
    pts = np.vstack([shape[:1], shape[1:][keep]])
    if len(lens) == 0:
        raise ValueError("a lane shape of zero length")
    cum = np.concatenate([[0.0], np.cumsum(lens)])
    i = int(np.clip(np.searchsorted(cum, a, side="right") - 1, 0, len(lens) - 1))
    t = (a - float(cum[i])) / float(lens[i])  # < 0 before the start, > 1 past the end
    x = float(pts[i, 0] + t * seg[i, 0])
    y = float(pts[i, 1] + t * seg[i, 1])
    return x, y, math.atan2(float(seg[i, 1]), float(seg[i, 0]))


def lane_frame(network: RoadNetwork, route: Sequence[str], pos_m: float,
               lane: int) -> LaneFrame:
    """The frame of lane ``lane`` at route position ``pos_m`` (module docstring);
    ``ValueError`` when the position is off the route or the lane does not exist."""
    edge, _ = network.locate(route, pos_m)
    lanes = network.lane_info((edge,))
    if not 0 <= lane < len(lanes):
        raise ValueError(f"lane {lane} does not exist on edge {edge!r} at {pos_m:g} m "
                         f"({len(lanes)} lanes)")
    shape = np.asarray(lanes[lane].shape_xy_m, dtype=np.float64)
    length = float(np.sum(np.hypot(*np.diff(shape, axis=0).T)))
    edge_len = network.edge_length_m(edge)
    if not (length > 0.0 and edge_len > 0.0):
        raise ValueError(f"lane {lane} of edge {edge!r} has no length")
    u = pos_m - network.route_edge_starts_m(route)[edge]
    x, y, heading = _point_at(shape, u * length / edge_len)
    return LaneFrame(x, y, heading, edge_len / length, edge, lane)


def pose_in_lane(network: RoadNetwork, route: Sequence[str], pos_m: float,
                 lane_at: Callable[[float], int], x_m: float, y_m: float, heading_rad: float
                 ) -> LanePose:
    """The pose of the point (x_m, y_m) heading ``heading_rad`` in the frame of the lane
    ``lane_at(pos)`` chooses, from the first guess ``pos_m`` (module docstring). The
    position stays inside the route: [0, its length)."""
    last = math.nextafter(network.route_length_m(route), 0.0)
    pos = min(max(pos_m, 0.0), last)
    frame = lane_frame(network, route, pos, lane_at(pos))
    best = (abs(frame.along_m(x_m, y_m)), pos, frame)
    for _ in range(MAX_NEWTON_STEPS):
        along = frame.along_m(x_m, y_m)
        if abs(along) <= ALONG_TOL_M:
            break
        pos = min(max(pos + along * frame.scale, 0.0), last)
        frame = lane_frame(network, route, pos, lane_at(pos))
        # where the frame jumps (a lane's end at a junction) the steps can cycle: the
        # nearest iterate is the answer
        best = min(best, (abs(frame.along_m(x_m, y_m)), pos, frame), key=lambda b: b[0])
    _, pos, frame = best
    return LanePose(pos, frame.lane, frame.lateral_m(x_m, y_m),
                    math.remainder(heading_rad - frame.heading_rad, 2.0 * math.pi),
                    frame.along_m(x_m, y_m))


class EgoStartKeys(Protocol):
    """What :func:`ego_front_pose` reads of a catalog's ``ego`` (an ``EgoSpec``)."""

    @property
    def lane(self) -> int: ...

    @property
    def pos_m(self) -> float: ...

    @property
    def start_pose(self) -> tuple[float, float] | None: ...


def ego_front_pose(network: RoadNetwork, route: Sequence[str], ego: EgoStartKeys
                   ) -> tuple[float, float, float] | None:
    """The world pose (front bumper x [m], y [m], heading [rad]) of an ego that gives a
    lateral offset or a heading (``ego.start_pose``, (d, delta)): its front bumper's
    centre at route position ``pos_m``, d left of lane ``lane``'s centre line, heading
    delta from the lane (module docstring); ``None`` for an ego that gives neither (the
    run then starts it on the reference path, as before these keys)."""
    pose = ego.start_pose
    if pose is None:
        return None
    return lane_frame(network, route, ego.pos_m, ego.lane).place(*pose)
