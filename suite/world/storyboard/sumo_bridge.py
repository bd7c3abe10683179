"""The storyboard in a running libsumo: its scripted entities are SUMO vehicles moved
to their poses with ``moveToXY(..., keepRoute=2)`` before every SUMO step (as replayed
vehicles are: speed mode 32, lane-change mode 0, blind to everyone), the ego is read
from SUMO for the conditions.

Each entity is a vehicle ``osc_<name>`` of its own type with the entity's box (a
pedestrian or misc object too: an obstacle of its size on its path; a stopped one is a
stalled obstacle). Timing: :meth:`StoryRunner.apply` before the SUMO step that ends at
run time t + dt evaluates the storyboard at t (the ego as SUMO has it) and pushes every
entity's pose at t + dt. :meth:`StoryRunner.write_log` keeps the storyboard's
transitions (the world writes them to ``sumo/storyboard.json`` of the run).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from reports.geometry import math_rad_to_nav_deg, nav_deg_to_math_rad_scalar
from suite.catalog import storyboard as sb
from suite.road.lane_pose import lane_frame, pose_in_lane
from suite.road.network import RoadNetwork
from suite.world.route_position import route_position_m
from suite.world.storyboard.engine import StoryEngine
from suite.world.storyboard.road import SumoRoad, lane_centre_y
from suite.world.storyboard.state import EntityView

__all__ = ["StoryRunner", "sumo_id"]

SPEED_MODE = 32
EGO_ID = "ego"  # suite.world.routes.EGO_ID


def sumo_id(name: str) -> str:
    """The SUMO vehicle id of entity ``name``."""
    return "osc_" + re.sub(r"[^A-Za-z0-9_]", "_", name)


@dataclass
class StoryRunner:
    """One run's storyboard: :meth:`start` once SUMO runs, :meth:`apply` before every
    SUMO step. ``ego_pos_m``: the ego's start route position [m]."""

    story: sb.Storyboard
    network: RoadNetwork
    route: tuple[str, ...]
    ego_pos_m: float
    engine: StoryEngine = field(init=False)
    _ego_pos: float = field(init=False)
    _travelled: float = 0.0
    _last_xy: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        self.engine = StoryEngine(self.story, SumoRoad(self.network, self.route))
        self._ego_pos = self.ego_pos_m

    def start(self, ls: Any) -> None:
        """Vehicle types, the entities' vehicles at their start poses."""
        ls.route.add("osc_route", list(self.route))
        for name, m in self.engine.motions.items():
            vid, e = sumo_id(name), m.entity
            ls.vehicletype.copy("DEFAULT_VEHTYPE", f"{vid}_type")
            ls.vehicletype.setLength(f"{vid}_type", e.length_m)
            ls.vehicletype.setWidth(f"{vid}_type", e.width_m)
            ls.vehicletype.setMinGap(f"{vid}_type", 0.5)
            ls.vehicle.add(vid, "osc_route", f"{vid}_type", depart="now",
                           departSpeed=repr(float(m.speed_mps)))
            ls.vehicle.setSpeedMode(vid, SPEED_MODE)
            ls.vehicle.setLaneChangeMode(vid, 0)
            self._push(ls, vid, m.view(self.engine.road))

    def _push(self, ls: Any, vid: str, v: EntityView) -> None:
        ls.vehicle.moveToXY(vid, "", -1, v.x_m, v.y_world_m,
                            math_rad_to_nav_deg(v.heading_rad), keepRoute=2)
        ls.vehicle.setSpeed(vid, max(v.speed_mps, 0.0))

    def _ego(self, ls: Any) -> EntityView | None:
        """The ego as SUMO has it: its route position from its edge and lane position
        (on a junction's internal lane: from its pose in the nearest route lane)."""
        if EGO_ID not in ls.vehicle.getIDList():
            return None
        v = ls.vehicle
        x, y = v.getPosition(EGO_ID)
        h = nav_deg_to_math_rad_scalar(float(v.getAngle(EGO_ID)))
        lane = int(v.getLaneIndex(EGO_ID))
        pos = route_position_m(v, EGO_ID, self.network.route_edge_starts_m(self.route))
        if math.isfinite(pos):
            lateral = float(v.getLateralLanePosition(EGO_ID))
        else:
            pose = pose_in_lane(self.network, self.route, self._ego_pos,
                                lambda p: self._nearest_lane(p, float(x), float(y)),
                                float(x), float(y), h)
            pos, lane, lateral = pose.pos_m, pose.lane, pose.lateral_m
        self._ego_pos = pos
        if self._last_xy is not None:
            self._travelled += math.hypot(x - self._last_xy[0], y - self._last_xy[1])
        self._last_xy = (float(x), float(y))
        y_lat = lane_centre_y(self.engine.road, pos, lane) + lateral
        return EntityView(self.story.ego, pos, y_lat, float(x), float(y), h,
                          float(v.getSpeed(EGO_ID)), self._travelled)

    def _nearest_lane(self, pos_m: float, x_m: float, y_m: float) -> int:
        """The lane, of the edge at ``pos_m``, whose frame there is nearest (x, y)."""
        p = min(max(pos_m, 0.0), self.network.route_length_m(self.route) - 1e-6)
        n = len(self.engine.road.widths(p))
        return min(range(n), key=lambda i: abs(
            lane_frame(self.network, self.route, p, i).lateral_m(x_m, y_m)))

    def write_log(self, path: Path) -> None:
        """The storyboard's transitions (run time [s], element type, name, transition)
        and when its stop trigger fired (null: never), as JSON."""
        eng = self.engine
        path.write_text(json.dumps({
            "source": self.story.source, "stopped_at_s": eng.stopped_at_s,
            "transitions": [[round(x.t_s, 6), x.element_type, x.name, x.transition]
                            for x in eng.log]}, indent=0) + "\n", encoding="utf-8")

    def apply(self, ls: Any, t_s: float, dt_s: float) -> None:
        """Before the SUMO step from run time ``t_s`` to ``t_s + dt_s`` [s]."""
        self.engine.step(t_s, dt_s, self._ego(ls))
        present = set(ls.vehicle.getIDList())
        for name, m in self.engine.motions.items():
            vid = sumo_id(name)
            if vid in present:
                self._push(ls, vid, m.view(self.engine.road))
