"""Per-step safety checks of the ego against every other vehicle (oriented boxes).

One compiled call per step (:func:`reports.geometry.nearest_box`): the ego's
box against all the scene's vehicles at once, far ones culled by their bounding
circles, giving the nearest box, its distance and whether any box overlaps.

Importing this module loads the geometry kernels (the loop's and the metrics'): the
executors' forkserver imports the runner, hence this module, before it forks the
scenario processes, so they inherit the compiled code instead of each loading it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from controllers.plant.vehicle_model import VehicleParams
from reports.geometry import load_kernels, nearest_box, point_ahead
from suite.run.ego import EgoState
from suite.world.protocol import Scene

load_kernels()


@dataclass(frozen=True)
class SafetySample:
    """min_gap_m: ego box to the nearest other box [m] (0 on contact, inf if none);
    gap_vehicle: its id; geom_collision: the boxes overlap; sumo_collision: SUMO reported
    a collision of the ego this step (recorded beside it: SUMO without its sublane model
    judges along the lane only, docs/metrics.md)."""

    min_gap_m: float
    gap_vehicle: str
    geom_collision: bool
    sumo_collision: bool

    @property
    def collided(self) -> bool:
        """The ego is in contact with another vehicle: the 2-D boxes overlap. SUMO's
        report alone is no contact (it neither stops a run nor changes what follows)."""
        return self.geom_collision


class SafetyMonitor:
    """Geometric gap and overlap of the ego's box with the scene's vehicles."""

    def __init__(self, vehicle: VehicleParams) -> None:
        self.vehicle = vehicle
        self._offset_m = float(vehicle.cg_to_box_centre_m)
        self._length_m = float(vehicle.length_m)
        self._width_m = float(vehicle.width_m)

    def check(self, ego: EgoState, scene: Scene) -> SafetySample:
        hit = bool(scene.collisions)
        tr = scene.traffic
        if tr.count == 0:
            return SafetySample(math.inf, "", False, hit)
        st = ego.state
        psi = float(st[2])
        cx, cy = point_ahead(float(st[0]), float(st[1]), psi, self._offset_m)
        i, gap, overlap = nearest_box(cx, cy, psi, self._length_m, self._width_m, tr.x_m, tr.y_m,
                                      tr.heading_rad, tr.length_m, tr.width_m)
        return SafetySample(gap, tr.ids[i], overlap, hit)
