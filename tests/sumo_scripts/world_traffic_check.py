"""Run a SumoWorld with a stalled car and traffic; print JSON facts (own process: libsumo)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from controllers.path.frenet import FrenetPath
from controllers.plant.vehicle_model import VehicleParams
from suite.catalog import load_catalog
from suite.road.lanes import LaneContextMap
from suite.road.network import RoadNetwork
from suite.road.route_reference import build_reference
from suite.world.sumo import SumoWorld


def main() -> None:
    catalog, name, work = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
    sc = {s.name: s for s in load_catalog(catalog).scenarios}[name]
    net = RoadNetwork.load(sc.net_path)
    world = SumoWorld(sc, net, VehicleParams(), work, externally_driven=False)
    world.start(None)
    import libsumo

    stall_xy = []
    behind: set[str] = set()
    passed: set[str] = set()
    signals = []
    speeds = []
    sx0 = None
    for _ in range(int(sc.duration_s / sc.step_s)):
        world.step(None)
        sx, sy = libsumo.vehicle.getPosition("stalled0")
        sx0 = sx if sx0 is None else sx0
        stall_xy.append((sx, sy))
        speeds.append(libsumo.vehicle.getSpeed("stalled0"))
        signals.append(libsumo.vehicle.getSignals("stalled0"))
        stall_lane = libsumo.vehicle.getLaneID("stalled0")
        for vid in libsumo.vehicle.getIDList():
            if vid in ("stalled0", "ego"):
                continue
            x, _ = libsumo.vehicle.getPosition(vid)
            if libsumo.vehicle.getLaneID(vid) == stall_lane and x < sx - 5:
                behind.add(vid)
            if vid in behind and x > sx + 5:
                passed.add(vid)
    ego_edge = libsumo.vehicle.getRoadID("ego")
    ego_pos = net.route_edge_starts_m(sc.route)[ego_edge] + libsumo.vehicle.getLanePosition("ego")
    ref = build_reference(net, tuple(sc.route), sc.ego.pos_m, sc.ego.lane)
    path = FrenetPath.cached(ref.points_xy_m, smoothing_m=0.5)
    lanes = LaneContextMap(net, sc.route, ref, path).at(ref.path_s(ego_pos))
    xy = np.array(stall_xy)
    world.close()
    print(json.dumps({
        "stall_drift_m": float(np.max(np.hypot(xy[:, 0] - xy[0, 0], xy[:, 1] - xy[0, 1]))),
        "stall_max_speed": float(max(speeds)),
        "hazard_always_on": all(s & 4 for s in signals),
        "behind": len(behind), "passed": len(passed),
        "lane_context": [{"index": li.index, "width_m": li.width_m, "shoulder": li.is_shoulder,
                          "passenger": li.allows_passenger}
                         for _, li in sorted(lanes.slots.items())],
    }))


if __name__ == "__main__":
    main()
