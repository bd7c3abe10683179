"""Per-step safety checks of the ego against every other vehicle (oriented boxes)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.plant.vehicle_model import VehicleParams
from reports.metrics.geometry import box_corners, box_distance, boxes_overlap, ego_box_centre
from suite.run.ego import EgoState
from suite.world.protocol import Scene


@dataclass(frozen=True)
class SafetySample:
    """min_gap_m: ego box to the nearest other box [m] (0 on contact, inf if none);
    gap_vehicle: its id; geom_collision: the boxes overlap; sumo_collision: SUMO reported
    a collision of the ego this step."""

    min_gap_m: float
    gap_vehicle: str
    geom_collision: bool
    sumo_collision: bool

    @property
    def collided(self) -> bool:
        return self.geom_collision or self.sumo_collision


class SafetyMonitor:
    """Geometric gap and overlap of the ego's box with the scene's vehicles."""

    def __init__(self, vehicle: VehicleParams) -> None:
        self.vehicle = vehicle

    def check(self, ego: EgoState, scene: Scene) -> SafetySample:
        hit = bool(scene.collisions)
        tr = scene.traffic
        if tr.count == 0:
            return SafetySample(math.inf, "", False, hit)
        st = ego.state
        cx, cy = ego_box_centre(st[0], st[1], st[2], self.vehicle.cg_to_box_centre_m)
        ego_box = box_corners(cx, cy, st[2], self.vehicle.length_m, self.vehicle.width_m)
        boxes = box_corners(tr.x_m, tr.y_m, tr.heading_rad, tr.length_m, tr.width_m)
        dist = box_distance(ego_box[None], boxes)
        i = int(np.argmin(dist))
        overlap = bool(np.any(boxes_overlap(ego_box[None], boxes)))
        return SafetySample(float(dist[i]), tr.ids[i], overlap, hit)
