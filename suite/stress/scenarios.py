"""A planned stress scenario resolved on its built network (:func:`resolve`): lane
indices, positions and speeds as the catalog states them, in typed catalog specs.

* the ego: through lane ``floor(u n)`` at its position; on a real net its position is
  drawn over the route where everything the run can reach lies ahead, and its speed is
  capped at its lane's speed limit;
* stalled cars: ``gap_m`` from the ego's front bumper to their rear, in through lane
  ``floor(u n)`` there, at least 20 m from an edge's ends (moved forward if needed); a
  close stall shares an edge and a lane with the ego (the ego moves forward to an edge
  long enough for both);
* traffic: ``vehicles_per_hour`` on all lanes of the first edge, seeded by the scenario;
  slower traffic in the passing lane as ``lane_speeds_mps`` of the first edge's leftmost
  lane;
* the on-ramp: ``ramp`` on a generated net; on a real one an on-ramp joining from 200 m
  behind to 1000 m ahead of the ego (none there: no ramp traffic).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from suite.catalog import EgoSpec, RampTrafficSpec, StalledSpec, TrafficSpec
from suite.road.network import RoadNetwork
from suite.stress.config import StressConfig
from suite.stress.lanes import JUNCTION_CLEARANCE_M, RouteLanes
from suite.stress.netgen import RAMP_EDGE
from suite.stress.plan import STALLED_LENGTH_M, ScenarioPlan
from suite.stress.real import on_ramps

__all__ = ["RAMP_BEHIND_M", "RAMP_AHEAD_M", "StressScenario", "resolve"]

RAMP_BEHIND_M = 200.0
RAMP_AHEAD_M = 1000.0
REAL_START_M = 500.0  # a real-net ego starts at least this far along the route


@dataclass(frozen=True)
class StressScenario:
    """One scenario of the stress catalog, as its ``[[scenario]]`` table says it."""

    name: str
    net: str  # relative to the catalog file
    route: tuple[str, ...]
    seed: int
    ego: EgoSpec
    stalled: tuple[StalledSpec, ...]
    traffic: TrafficSpec | None
    ramps: tuple[RampTrafficSpec, ...]
    friction: float

    def table(self) -> dict[str, Any]:
        """The ``[[scenario]]`` table (plain TOML values)."""
        out: dict[str, Any] = {
            "name": self.name, "net": self.net, "route": list(self.route), "seed": self.seed,
            "ego": {"lane": self.ego.lane, "pos_m": self.ego.pos_m,
                    "speed_mps": self.ego.speed_mps},
            "stalled": [{"lane": s.lane, "pos_m": s.pos_m} for s in self.stalled],
        }
        if self.traffic is not None:
            traffic: dict[str, Any] = {"vehicles_per_hour": self.traffic.vehicles_per_hour,
                                       "seed": self.traffic.seed}
            if self.traffic.lane_speeds_mps is not None:
                traffic["lane_speeds_mps"] = dict(self.traffic.lane_speeds_mps)
            out["traffic"] = traffic
        if self.ramps:
            out["ramp_traffic"] = [
                {"edge": r.edge, "vehicles_per_hour": r.vehicles_per_hour,
                 **({} if r.speed_mps is None else {"speed_mps": r.speed_mps})}
                for r in self.ramps]
        if self.friction != 1.0:
            out["friction"] = self.friction
        return out


def _real_ego_pos(lanes: RouteLanes, plan: ScenarioPlan, cfg: StressConfig) -> float:
    reach = plan.ego_speed_mps * cfg.duration_s
    hi = lanes.length_m - max(cfg.stalled_ahead_m[1] + 300.0, reach + 600.0)
    if hi <= REAL_START_M:
        raise ValueError(f"{plan.name}: the real route is too short for the scenario")
    return REAL_START_M + plan.ego_pos_u * (hi - REAL_START_M)


def _room_for(lanes: RouteLanes, ego_pos: float, span_m: float) -> float:
    """The first ego position at or after ``ego_pos`` from which ``span_m`` ahead stays on
    one edge, clear of its ends."""
    net, route = lanes.network, lanes.route
    for k in range(lanes.edge_index(ego_pos), len(route)):
        start = lanes.starts[route[k]]
        end = start + net.edge_length_m(route[k]) - JUNCTION_CLEARANCE_M
        pos = max(ego_pos, start + JUNCTION_CLEARANCE_M)
        if pos + span_m <= end and lanes.through(k):
            return pos
    raise ValueError(f"no edge of the route holds the ego and a car {span_m:.0f} m ahead")


def _stalled(lanes: RouteLanes, plan: ScenarioPlan, ego_pos: float, ego_lane: int
             ) -> tuple[StalledSpec, ...]:
    out = []
    for k, st in enumerate(plan.stalled):
        pos = ego_pos + st.gap_m + STALLED_LENGTH_M
        if k == 0 and plan.close_stall:  # same edge, same lane as the ego
            out.append(StalledSpec(lane=ego_lane, pos_m=round(pos, 1)))
            continue
        pos = lanes.clear_of_junctions(pos)
        lane, _ = lanes.lane_at(pos, st.lane_u)
        out.append(StalledSpec(lane=lane, pos_m=round(pos, 1)))
    return tuple(out)


def _traffic(network: RoadNetwork, route: tuple[str, ...], plan: ScenarioPlan
             ) -> TrafficSpec | None:
    if plan.traffic_vph <= 0:
        return None
    speeds = None
    if plan.slow_lane_speed_mps is not None:
        passing = max(li.index for li in network.lane_info(route[:1])
                      if li.allows_passenger and not li.is_shoulder)
        speeds = {str(passing): plan.slow_lane_speed_mps}
    return TrafficSpec(vehicles_per_hour=plan.traffic_vph, seed=plan.seed,
                       lane_speeds_mps=speeds)


def _ramps(lanes: RouteLanes, plan: ScenarioPlan, ego_pos: float
           ) -> tuple[RampTrafficSpec, ...]:
    ramp = plan.ramp
    if ramp is None:
        return ()
    if plan.layout is not None:
        return (RampTrafficSpec(RAMP_EDGE, ramp.vehicles_per_hour, ramp.speed_mps),)
    near = [r for r in on_ramps(lanes.network, lanes.route)
            if ego_pos - RAMP_BEHIND_M <= r.joins_at_m <= ego_pos + RAMP_AHEAD_M]
    if not near:
        return ()
    pick = near[min(int(ramp.pick_u * len(near)), len(near) - 1)]
    return (RampTrafficSpec(pick.edge, ramp.vehicles_per_hour, ramp.speed_mps),)


def resolve(plan: ScenarioPlan, network: RoadNetwork, route: tuple[str, ...], net: str,
            cfg: StressConfig) -> StressScenario:
    """The catalog scenario of ``plan`` on its built ``network`` (module doc); ``net`` is
    the net's path as the catalog names it."""
    lanes = RouteLanes(network, route)
    ego_pos = plan.ego_pos_m if plan.layout is not None else _real_ego_pos(lanes, plan, cfg)
    if plan.close_stall:
        ego_pos = _room_for(lanes, ego_pos, plan.stalled[0].gap_m + STALLED_LENGTH_M)
    ego_lane, _ = lanes.lane_at(ego_pos, plan.ego_lane_u)
    speed = plan.ego_speed_mps
    if plan.layout is None:  # a real motorway: no faster than the ego's lane allows
        edge = route[lanes.edge_index(ego_pos)]
        limit = next(li.speed_mps for li in network.lane_info((edge,))
                     if li.index == ego_lane)
        speed = round(min(speed, limit), 2)
    ego = EgoSpec(lane=ego_lane, pos_m=round(ego_pos, 1), speed_mps=speed)
    ramps = _ramps(lanes, plan, ego.pos_m)
    name = plan.name if ramps or plan.ramp is None else plan.name.replace("_merge", "", 1)
    return StressScenario(
        name=name, net=net, route=route, seed=plan.seed, ego=ego,
        stalled=_stalled(lanes, plan, ego.pos_m, ego_lane),
        traffic=_traffic(network, route, plan), ramps=ramps, friction=plan.friction)
