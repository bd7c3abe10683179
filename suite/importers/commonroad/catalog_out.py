"""The catalog side: the route, the ego and stalled cars resolved on the built net (with
hwyeval's own :class:`~suite.road.network.RoadNetwork`), one scenario per file, and
``catalog.toml``.

* **Route.** Upstream from the ego's edge: the predecessor that is not a link, then with
  the most lanes (to the upstream extension). Downstream: among every path to a net end,
  the first that reaches a goal edge (the goal's lanelets, or the edges its goal
  positions lie on), then with the fewest link edges, then the longest.
* **Ego.** CommonRoad's initial state is the vehicle centre c heading h at speed v;
  hwyeval's ego is a box of length L = :class:`controllers.plant.vehicle_model.
  VehicleParams`'s ``length_m``, so its front bumper's centre is F = c + L/2 (cos h,
  sin h). The catalog's ego is F's pose in its lane's frame (:mod:`suite.road.lane_pose`):
  ``pos_m`` its route position (SUMO's lane positions: edge start + arc length on the
  lane shape x edge length / shape length), ``lane`` the lane, of the edge at pos,
  nearest F, ``lateral_offset_m`` F's offset from that lane's centre line (left > 0),
  ``heading_rad`` h minus the lane's direction; found by
  :func:`suite.road.lane_pose.pose_in_lane` from F's projection on the nearest route
  lane. The run places the ego there (``suite.run.runner.initial_state``): an ego
  recorded mid lane change starts mid lane change. c's signed offset from the centre
  line of the route lane nearest it is noted (:func:`ego_offset_note`, a warning above
  :data:`LATERAL_WARN_M`: the run starts off its lane's centre).
* **Stalled.** A static obstacle on a route lane becomes ``stalled`` with its box
  (pos = s(centre) + length/2, as the ego); elsewhere it is dropped with a note.
* **Files.** Each imported file leaves ``<stem>.scenario.json`` (its scenario table and
  notes); ``catalog.toml`` is rebuilt from every such file in DIR, marked generated
  (:mod:`suite.importers.common.catalog`, shared with ``import openscenario``:
  :data:`OUTPUTS` says what this import writes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from controllers.plant.vehicle_model import VehicleParams
from reports.geometry import box_front
from suite.catalog.specs import MAX_EGO_HEADING_RAD, MAX_EGO_LATERAL_OFFSET_M
from suite.importers.common import catalog
from suite.importers.common.catalog import (
    DEFAULT_CONTROLLER,
    FRAGMENT_SUFFIX,
    STEP_S,
    write_fragment,
)
from suite.importers.common.outputs import Outputs
from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import project
from suite.importers.commonroad.net_build import BuiltNet
from suite.importers.commonroad.records import EgoStart, ObstacleRecord
from suite.road.lane_pose import LanePose, pose_in_lane
from suite.road.network import RoadNetwork

__all__ = ["DEFAULT_CONTROLLER", "FRAGMENT_SUFFIX", "LATERAL_WARN_M", "OUTPUTS",
           "STEP_S", "RoutePoint", "choose_route",
           "ego_offset_note", "ego_table",
           "locate_on_route", "scenario_name", "stalled_tables",
           "write_fragment"]

OUTPUTS = Outputs(
    command="commonroad", input_suffix=".xml",
    per_input=(".net.xml", ".tracks.parquet", FRAGMENT_SUFFIX), doc="docs/recorded.md",
    header=("Recorded scenarios imported from CommonRoad by `hwyeval import commonroad`",
            "(docs/recorded.md). Rebuilt from the *.scenario.json files of this folder.",
            "Positions: ego.pos_m / stalled pos_m are front bumpers along the route;",
            "lane 0 = rightmost lane of the edge at that position."),
    fallback_name="recording")
"""What the import writes (:mod:`suite.importers.common`): per file ``<stem>.net.xml``,
``<stem>.tracks.parquet``, ``<stem>.scenario.json``; and ``catalog.toml``."""
MAX_PATHS = 20000
LATERAL_WARN_M = 0.5
"""An ego centre farther than this [m] from its lane's centre line is a warning: the run
starts it there, off its lane's centre (mid lane change?)."""

ALONG_TOL_M = 0.05
"""The ego's front bumper must lie this close [m] to the normal of its lane frame at the
catalog's ``pos_m`` (:func:`suite.road.lane_pose.pose_in_lane` converged; it does to
1e-4 m but where a lane's shape jumps at a junction): else the file is refused rather
than started elsewhere than recorded."""


@dataclass(frozen=True)
class RoutePoint:
    """A point projected on the route: edge, lane index, route position [m], distance
    from that lane's centre line, the lane's width and the signed lateral offset from
    the centre line (left of the direction of travel > 0) [m]; for the ego, its heading
    relative to the lane [rad, counter-clockwise +]."""

    edge_id: str
    lane: int
    pos_m: float
    distance_m: float
    width_m: float
    lateral_m: float = 0.0
    heading_rad: float = 0.0


def scenario_name(stem: str) -> str:
    """A catalog name ``[a-z0-9_]+`` from a file stem."""
    return catalog.scenario_name(stem, OUTPUTS.fallback_name)


def _forward_paths(net: BuiltNet, start: str) -> list[tuple[str, ...]]:
    out: list[tuple[str, ...]] = []
    stack: list[tuple[str, ...]] = [(start,)]
    while stack and len(out) < MAX_PATHS:
        path = stack.pop()
        nxt = [s for s in net.successors(path[-1]) if s not in path]
        if not nxt:
            out.append(path)
        stack.extend((*path, s) for s in nxt)
    return out


def choose_route(net: BuiltNet, network: RoadNetwork, ego_edge: str,
                 goal_edges: Sequence[str]) -> tuple[str, ...]:
    """The scenario's route (module docstring)."""
    back: list[str] = []
    edge = ego_edge
    while True:
        preds = [p for p in net.predecessors(edge) if p not in back and p != ego_edge]
        if not preds:
            break
        edge = min(preds, key=lambda p: (net.edges[p].link, -network.lane_count(p), p))
        back.append(edge)
    goals = set(goal_edges)

    def key(path: tuple[str, ...]) -> tuple[bool, int, float, tuple[str, ...]]:
        length = sum(network.edge_length_m(e) for e in path)
        return (not (goals & set(path)) if goals else False,
                sum(net.edges[e].link for e in path), -length, path)

    forward = min(_forward_paths(net, ego_edge), key=key)
    return (*back[::-1], *forward)


def locate_on_route(network: RoadNetwork, route: Sequence[str], x_m: float,
                    y_m: float) -> RoutePoint:
    """The route lane nearest (x_m, y_m) and the point's route position (docstring)."""
    starts = network.route_edge_starts_m(route)
    best: RoutePoint | None = None
    for lane in network.lane_info(route):
        pr = project(lane.shape_xy_m, x_m, y_m)
        if pr.length_m <= 0.0:
            continue
        pos = starts[lane.edge_id] + pr.s_m / pr.length_m * network.edge_length_m(lane.edge_id)
        cand = RoutePoint(lane.edge_id, lane.index, pos, pr.distance_m, lane.width_m,
                          pr.lateral_m)
        if best is None or cand.distance_m < best.distance_m - 1e-9:
            best = cand
    if best is None:  # pragma: no cover - a route has lanes
        raise ValueError("a route without lanes")
    return best


def _lane_at(network: RoadNetwork, route: Sequence[str], pos_m: float, x_m: float,
             y_m: float) -> int:
    """The lane, of the edge at route position ``pos_m``, nearest (x_m, y_m)."""
    edge, _ = network.locate(route, pos_m)
    lanes = [ln for ln in network.lane_info((edge,))]
    return min(lanes, key=lambda ln: (project(ln.shape_xy_m, x_m, y_m).distance_m,
                                      ln.index)).index


def ego_table(path: str, network: RoadNetwork, route: Sequence[str], ego: EgoStart,
              vehicle: VehicleParams) -> tuple[dict[str, Any], RoutePoint]:
    """The catalog's ``ego`` table (the front bumper's pose in its lane's frame, speeds;
    module docstring) and the ego centre's place on the route (with the heading relative
    to its lane)."""
    element = f"planningProblem {ego.problem_id} initialState"
    centre = locate_on_route(network, route, ego.x_m, ego.y_m)
    if centre.distance_m > 0.5 * centre.width_m:
        raise ImportFailure(path, element, f"the ego is {centre.distance_m:.2f} m from the "
                            "nearest lane of its route")
    half = 0.5 * vehicle.length_m
    fx, fy = box_front(ego.x_m, ego.y_m, ego.heading_rad, vehicle.length_m)
    total = network.route_length_m(route)
    first = locate_on_route(network, route, fx, fy).pos_m
    if not centre.pos_m + half < total or not first < total:
        raise ImportFailure(path, element, "the ego is at the end of the road")
    pose = pose_in_lane(network, route, first, lambda p: _lane_at(network, route, p, fx, fy),
                        fx, fy, ego.heading_rad)
    problem = _pose_problem(pose)
    if problem is not None:
        raise ImportFailure(path, element, problem)
    speed = round(float(ego.speed_mps), 4)
    table = {"lane": pose.lane, "pos_m": round(pose.pos_m, 3), "speed_mps": speed,
             "target_speed_mps": speed, "lateral_offset_m": round(pose.lateral_m, 4),
             "heading_rad": round(pose.heading_rad, 5)}
    return table, replace(centre, heading_rad=pose.heading_rad)


def _pose_problem(pose: LanePose) -> str | None:
    """Why the ego's pose cannot be a catalog's (None: it can)."""
    if abs(pose.residual_m) > ALONG_TOL_M:
        return (f"its front bumper cannot be placed on lane {pose.lane} ({pose.residual_m:.3f} "
                "m along the lane from the nearest point of the route)")
    if abs(pose.lateral_m) > MAX_EGO_LATERAL_OFFSET_M:
        return (f"its front bumper is {pose.lateral_m:+.2f} m from the centre line of lane "
                f"{pose.lane} (at most {MAX_EGO_LATERAL_OFFSET_M:g} m)")
    if not abs(pose.heading_rad) < MAX_EGO_HEADING_RAD:
        return (f"it heads {math.degrees(pose.heading_rad):+.1f} deg from its lane's "
                "direction (not along the road)")
    return None


def ego_offset_note(centre: RoutePoint) -> str:
    """The note on the ego's lateral offset and heading (module docstring), ``WARNING``
    above :data:`LATERAL_WARN_M`."""
    side = "left" if centre.lateral_m > 0 else "right"
    text = (f"ego lateral offset {centre.lateral_m:+.2f} m ({abs(centre.lateral_m):.2f} m "
            f"{side} of the centre line of {centre.edge_id} lane {centre.lane}), heading "
            f"{centre.heading_rad:+.4f} rad from its lane: the run starts it there "
            "(ego.lateral_offset_m, ego.heading_rad)")
    return f"WARNING {text}" if abs(centre.lateral_m) > LATERAL_WARN_M else text


def stalled_tables(network: RoadNetwork, route: Sequence[str],
                   statics: Sequence[ObstacleRecord]) -> tuple[list[dict[str, Any]], list[str]]:
    """Stalled cars from static obstacles on the route (module docstring), and notes."""
    tables: list[dict[str, Any]] = []
    notes: list[str] = []
    for ob in statics:
        x, y, h = float(ob.x_m[0]), float(ob.y_m[0]), float(ob.heading_rad[0])
        at = locate_on_route(network, route, x, y)
        pos = at.pos_m + 0.5 * ob.length_m
        if at.distance_m > 0.5 * at.width_m or not pos < network.route_length_m(route):
            notes.append(f"static obstacle {ob.obstacle_id} is not on the ego's route: dropped")
            continue
        fx, fy = box_front(x, y, h, ob.length_m)
        tables.append({"lane": _lane_at(network, route, pos, fx, fy), "pos_m": round(pos, 3),
                       "length_m": round(ob.length_m, 3), "width_m": round(ob.width_m, 3)})
    if tables:
        notes.append(f"{len(tables)} static obstacles became stalled cars")
    return tables, notes
