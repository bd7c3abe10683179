"""The independent placement check of issue #31: where the run puts the ego's front bumper
at t = 0, read back against the lane polyline of the ``.net.xml`` itself.

The net file is parsed here with ElementTree (not hwyeval's RoadNetwork nor its
reference): the front bumper is projected onto the shape of lane ``ego.lane`` of the edge
at ``ego.pos_m``, and the projection's arc length becomes SUMO's lane position (the shape's
length is scaled to the lane's ``length`` attribute, as SUMO does). Route position = the
edge's start on the route (edge lengths plus mean junction lengths: the catalog's own
definition) + that lane position.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np

from controllers.plant.vehicle_model import VehicleParams
from suite.catalog.specs import Scenario
from suite.road.network import RoadNetwork
from suite.run.runner import ego_start_state

JUNCTION_REACH_M = 30.0


def _unit(v: np.ndarray) -> np.ndarray:
    out: np.ndarray = v / float(np.hypot(*v))
    return out


@cache
def lane_shapes(net_path: Path) -> dict[str, tuple[np.ndarray, float]]:
    """lane id -> (shape (m, 2) [m], the lane's length attribute [m])."""
    out = {}
    for lane in ET.parse(net_path).getroot().iter("lane"):
        pts = [tuple(map(float, p.split(","))) for p in lane.get("shape", "").split()]
        out[lane.get("id", "")] = (np.asarray(pts, dtype=np.float64), float(lane.get("length", 0)))
    return out


def project_on(shape: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
    """(arc length of p's nearest point on the polyline, its length, p's signed distance
    from it, left of the lane's direction +) [m]."""
    best, at, side, cum = math.inf, 0.0, 0.0, 0.0
    for a, b in zip(shape[:-1], shape[1:], strict=True):
        ab = b - a
        seg = float(np.hypot(*ab))
        t = min(max(float(np.dot(p - a, ab)) / max(seg * seg, 1e-12), 0.0), 1.0)
        d = float(np.hypot(*(a + t * ab - p)))
        if d < best:
            cross = float(ab[0] * (p - a)[1] - ab[1] * (p - a)[0])
            best, at, side = d, cum + t * seg, math.copysign(d, cross)
        cum += seg
    return at, cum, side


@dataclass(frozen=True)
class Placement:
    """along_m: the front bumper's route position minus ``ego.pos_m`` [m]; lateral_m: its
    signed distance from the lane's polyline minus ``ego.lateral_offset_m`` [m]."""

    along_m: float
    lateral_m: float


def placement_error(scenario: Scenario) -> Placement:
    """Where :func:`suite.run.runner.ego_start_state` puts the front bumper, against the
    lane polyline of the net file."""
    network = RoadNetwork.load(scenario.net_path)
    vehicle = VehicleParams(friction_coeff=scenario.friction)
    state = ego_start_state(network, scenario, vehicle)
    d = vehicle.cg_to_front_bumper_m
    bumper = np.array([state[0] + d * math.cos(state[2]), state[1] + d * math.sin(state[2])])
    route = tuple(scenario.route)
    edge, _ = network.locate(route, scenario.ego.pos_m)
    shape, length = lane_shapes(Path(scenario.net_path))[f"{edge}_{scenario.ego.lane}"]
    # A position inside the junction before ``edge`` is the catalog's position on the
    # straight continuation of the lane's first segment back into the junction (the
    # catalog's convention: a junction belongs to the next edge): extend the shape so.
    lead = shape[0] - JUNCTION_REACH_M * _unit(shape[1] - shape[0])
    s, shape_len, side = project_on(np.vstack([lead, shape]), bumper)
    s, shape_len = s - JUNCTION_REACH_M, shape_len - JUNCTION_REACH_M
    pos = network.route_edge_starts_m(route)[edge] + s * length / shape_len
    return Placement(pos - scenario.ego.pos_m, side - (scenario.ego.lateral_offset_m or 0.0))
