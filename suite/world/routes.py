"""The SUMO route file of a scenario: vehicle types, the ego, stalled cars, scripted
actors, traffic.

Stalled vehicles stop on their lane for the whole run. Scripted actors (``actors``)
depart at t = 0 at their catalog speed under a type of their own (no dawdling,
accelerations a scripted ramp can ask for); :class:`suite.world.actors.ActorScript`
drives them. Background traffic: vehicles
spread over the route at t = 0 with exponential headways (mean speed/flow, so traffic
surrounds the ego from the first step) plus Poisson flows entering at the route's start,
on every lane of the first route edge that admits passenger cars (or the lanes the
catalog names); a pre-placed car follows its lane across the route's index shifts and
is only placed where that lane continues far enough for it. A lane with its own traffic
speed (``traffic.lane_speeds_mps``) gets its own vehicle type: that speed as maximum,
no speed-gain, keep-right or cooperative lane changes (it keeps its lane, e.g. slower
traffic in the passing lane; strategic changes where its lane ends remain). On-ramp
traffic (``ramp_traffic``): a Poisson flow from the ramp edge along
:func:`suite.catalog.traffic_checks.ramp_route` onto the route, plus cars spread over the
ramp's own edges at t = 0. All randomness comes from one generator seeded by the
scenario (main traffic first, then the ramps, so adding a ramp leaves the main traffic
as it was).
"""

from __future__ import annotations

import xml.sax.saxutils as su
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from controllers.plant.vehicle_model import VehicleParams
from suite.catalog import RampTrafficSpec, Scenario
from suite.catalog.traffic_checks import ramp_route
from suite.road.lane_graph import RouteLaneGraph
from suite.road.network import RoadNetwork

EGO_ID = "ego"
STALLED_PREFIX = "stalled"
RAMP_PREFIX = "ramp"
# Scripted actors: no dawdling (sigma 0), and the accelerations a scripted ramp may ask.
ACTOR_ACCEL_MPS2 = 6.0
ACTOR_DECEL_MPS2 = 8.0
INSERT_CLEARANCE_M = 30.0  # no pre-placed traffic this close to the ego or a stalled car
# A pre-placed car needs this much of its lane ahead: 2 s at its speed plus a stop at
# 4 m/s² (SUMO refuses a departure that cannot stop before the lane ends).
PRE_PLACE_HEADWAY_S = 2.0
PRE_PLACE_DECEL_MPS2 = 4.0


def _fmt(value: float) -> str:
    return f"{value:.3f}"


@dataclass
class RouteFile:
    """Builds the route XML of ``scenario``; ``stalled_ids`` lists the stalled cars."""

    scenario: Scenario
    network: RoadNetwork
    vehicle: VehicleParams
    ssm_file: Path
    externally_driven: bool = True
    stalled_ids: list[str] = field(default_factory=list)

    @property
    def route(self) -> tuple[str, ...]:
        return tuple(self.scenario.route)

    def xml(self) -> str:
        sc = self.scenario
        rng = np.random.default_rng(sc.traffic.seed if sc.traffic is not None else sc.seed)
        main = f'  <route id="main" edges="{" ".join(self.route)}"/>'
        lines = ["<routes>", *self._vtypes(), main]
        self.stalled_ids = []
        for i in range(len(sc.stalled)):
            lines.extend(self._stalled(i))
        for i in range(len(sc.actors)):
            lines.extend(self._actor(i))
        lines.append(self._ego())
        if sc.traffic is not None and sc.traffic.vehicles_per_hour > 0:
            lines.extend(self._traffic(rng))
        for i, ramp in enumerate(sc.ramp_traffic):
            lines.extend(self._ramp(rng, i, ramp))
        lines.append("</routes>")
        return "\n".join(lines) + "\n"

    def _vtypes(self) -> list[str]:
        veh = self.vehicle
        dev = self.scenario.traffic.speed_factor_dev if self.scenario.traffic is not None else 0.1
        ssm_path = su.escape(str(self.ssm_file))
        # SUMO's driver departs at the fastest safe speed up to its type's maximum: the
        # catalog's start speed (its set speed is applied after insertion).
        max_speed = 60.0 if self.externally_driven else max(self.scenario.ego.speed_mps, 0.1)
        return [
            f'  <vType id="ego" length="{_fmt(veh.length_m)}" width="{_fmt(veh.width_m)}" '
            f'vClass="passenger" minGap="2.0" maxSpeed="{_fmt(max_speed)}" color="0,160,255">',
            '    <param key="has.ssm.device" value="true"/>',
            '    <param key="device.ssm.measures" value="TTC DRAC PET"/>',
            '    <param key="device.ssm.trajectories" value="true"/>',
            f'    <param key="device.ssm.file" value="{ssm_path}"/>',
            "  </vType>",
            f'  <vType id="bg" vClass="passenger" length="4.5" width="1.8" speedDev="{_fmt(dev)}" '
            f'lcStrategic="1.0" lcCooperative="1.0" lcSpeedGain="1.0" color="200,200,200"/>',
            *self._lane_vtypes(dev),
        ]

    def _lane_vtypes(self, dev: float) -> list[str]:
        """A type per lane with its own traffic speed, and per on-ramp with a speed."""
        tr = self.scenario.traffic
        out = []
        for lane in self.traffic_lanes() if tr is not None else []:
            speed = tr.lane_speed_mps(lane) if tr is not None else None
            if speed is not None:
                out.append(
                    f'  <vType id="bg_l{lane}" vClass="passenger" length="4.5" width="1.8" '
                    f'speedDev="{_fmt(dev)}" maxSpeed="{_fmt(speed)}" lcStrategic="1.0" '
                    'lcCooperative="0" lcSpeedGain="0" lcKeepRight="0" color="160,120,220"/>')
        for i, ramp in enumerate(self.scenario.ramp_traffic):
            if ramp.speed_mps is not None:
                out.append(
                    f'  <vType id="bg_{RAMP_PREFIX}{i}" vClass="passenger" length="4.5" '
                    f'width="1.8" speedDev="{_fmt(dev)}" maxSpeed="{_fmt(ramp.speed_mps)}" '
                    'lcStrategic="1.0" lcCooperative="1.0" lcSpeedGain="1.0" '
                    'color="220,180,80"/>')
        return out

    def _lane_type(self, lane: int) -> tuple[str, float | None]:
        """(vehicle type, own speed [m/s] or None) of the traffic of a first-edge lane."""
        tr = self.scenario.traffic
        speed = tr.lane_speed_mps(lane) if tr is not None else None
        return ("bg" if speed is None else f"bg_l{lane}"), speed

    def _place(self, route_pos_m: float, length_m: float) -> tuple[str, int, float]:
        """(edge, its index on the route, departPos on it [m]) of a car placed at a route
        position: its front kept 0.1 m inside the edge, its rear on it."""
        edge, pos_on_edge = self.network.locate(self.route, route_pos_m)
        pos = min(max(pos_on_edge, length_m + 0.1), self.network.edge_length_m(edge) - 0.1)
        return edge, self.route.index(edge), pos

    def _stalled(self, i: int) -> list[str]:
        st = self.scenario.stalled[i]
        vid = f"{STALLED_PREFIX}{i}"
        self.stalled_ids.append(vid)
        edge, k, pos = self._place(st.pos_m, st.length_m)
        return [
            f'  <route id="r_{vid}" edges="{" ".join(self.route[k:])}"/>',
            f'  <vType id="stalled_{i}" vClass="passenger" color="255,60,60" '
            f'length="{_fmt(st.length_m)}" width="{_fmt(st.width_m)}"/>',
            f'  <vehicle id="{vid}" type="stalled_{i}" route="r_{vid}" depart="0" '
            f'departLane="{st.lane}" departPos="{_fmt(pos)}" departSpeed="0">',
            # A stop that outlasts any run keeps it on its lane, not parked beside it.
            f'    <stop lane="{edge}_{st.lane}" endPos="{_fmt(pos)}" duration="1000000"/>',
            "  </vehicle>",
        ]

    def _actor(self, i: int) -> list[str]:
        actor = self.scenario.actors[i]
        vid = actor.sumo_id
        edge, k, pos = self._place(actor.pos_m, actor.length_m)
        return [
            f'  <route id="r_{vid}" edges="{" ".join(self.route[k:])}"/>',
            f'  <vType id="t_{vid}" vClass="passenger" color="255,160,0" sigma="0" '
            f'length="{_fmt(actor.length_m)}" width="{_fmt(actor.width_m)}" maxSpeed="70" '
            f'accel="{_fmt(ACTOR_ACCEL_MPS2)}" decel="{_fmt(ACTOR_DECEL_MPS2)}" '
            # speedFactor 2: a scripted speed may exceed the lane's limit.
            f'emergencyDecel="9.0" speedFactor="2" speedDev="0"/>',
            f'  <vehicle id="{vid}" type="t_{vid}" route="r_{vid}" depart="0" '
            f'departLane="{actor.lane}" departPos="{_fmt(pos)}" '
            f'departSpeed="{_fmt(actor.speed_mps)}"/>',
        ]

    def _ego(self) -> str:
        """The ego's vehicle. Driven from outside, it is inserted at rest: SUMO refuses an
        insertion at a speed it could not stop from before the car ahead (a stalled car 50
        m ahead of a 25 m/s ego), and the ego's speed in SUMO is the plant's from its
        first pushed pose on. Driven by SUMO, it departs at the catalog's speed or, where
        that is not safe, at the fastest speed SUMO deems safe (``departSpeed="max"``
        under a type whose maximum is the catalog's speed)."""
        ego = self.scenario.ego
        edge, pos = self.network.locate(self.route, ego.pos_m)
        k = self.route.index(edge)
        route_ref = "main"
        extra = ""
        if k > 0:
            extra = f'  <route id="r_ego" edges="{" ".join(self.route[k:])}"/>\n'
            route_ref = "r_ego"
        speed = "0" if self.externally_driven else "max"
        return (f'{extra}  <vehicle id="{EGO_ID}" type="ego" route="{route_ref}" depart="0" '
                f'departLane="{ego.lane}" departPos="{_fmt(max(pos, self.vehicle.length_m))}" '
                f'departSpeed="{speed}"/>')

    def traffic_lanes(self) -> list[int]:
        """Lanes of the first route edge that get traffic."""
        tr = self.scenario.traffic
        if tr is not None and tr.lanes is not None:
            return list(tr.lanes)
        first = self.route[0]
        return [li.index for li in self.network.lane_info(self.route[:1])
                if li.edge_id == first and li.allows_passenger]

    def _traffic(self, rng: np.random.Generator) -> list[str]:
        tr = self.scenario.traffic
        lanes = self.traffic_lanes()
        if tr is None:
            return []
        if not lanes:
            return []
        per_lane_vph = tr.vehicles_per_hour / len(lanes)
        speed_limit = max(li.speed_mps for li in self.network.lane_info(self.route))
        speed = tr.speed_mps if tr.speed_mps is not None else speed_limit
        lines = self._pre_placed(rng, lanes, per_lane_vph, speed)
        end_s = float(self.scenario.duration_s) + 1.0
        for lane in lanes:
            if per_lane_vph <= 0:
                continue
            rate = per_lane_vph / 3600.0
            vtype, _ = self._lane_type(lane)
            lines.append(
                f'  <flow id="flow_l{lane}" type="{vtype}" route="main" begin="0" '
                f'end="{_fmt(end_s)}" period="exp({rate:.6f})" departLane="{lane}" '
                f'departSpeed="desired" departPos="base"/>')
        return lines

    def _pre_placed(self, rng: np.random.Generator, lanes: list[int], per_lane_vph: float,
                    speed: float) -> list[str]:
        """Vehicles at t = 0 with exponential headways (density k = q / v), along each
        traffic lane followed across the route by its connections (its index shifts where
        lanes are added or dropped), and only where that lane continues far enough for a
        driver at ``speed`` to move over before it ends (SUMO refuses such departures)."""
        sc, net = self.scenario, self.network
        if per_lane_vph <= 0:
            return []
        graph = RouteLaneGraph(net, self.route)
        starts = net.route_edge_starts_m(self.route)
        route_len = net.route_length_m(self.route)
        blocked = ([sc.ego.pos_m] + [st.pos_m for st in sc.stalled]
                   + [a.pos_m for a in sc.actors])
        lines: list[str] = []
        n = 0
        for lane in lanes:
            vtype, own = self._lane_type(lane)
            lane_speed = speed if own is None else min(own, speed)
            mean_gap_m = lane_speed / (per_lane_vph / 3600.0)  # density k = q / v
            needed = (lane_speed * PRE_PLACE_HEADWAY_S
                      + lane_speed**2 / (2.0 * PRE_PLACE_DECEL_MPS2))
            index_on = {st.k: st.lane.index for st in graph.chain(0, lane)}
            pos = float(rng.exponential(mean_gap_m)) + 10.0
            while pos < route_len - 20.0:
                edge, pos_on_edge = net.locate(self.route, pos)
                k = self.route.index(edge)
                i = index_on.get(k)
                near = any(abs(pos - b) < INSERT_CLEARANCE_M for b in blocked)
                if not near and i is not None:
                    last = self.route[graph.reach(k, i)]
                    left_m = starts[last] + net.edge_length_m(last) - pos
                    if graph.is_through(k, i) or left_m >= needed:
                        vid = f"pre{n}"
                        lines.append(f'  <route id="r_{vid}" edges="{" ".join(self.route[k:])}"/>')
                        lines.append(
                            f'  <vehicle id="{vid}" type="{vtype}" route="r_{vid}" depart="0" '
                            f'departLane="{i}" departPos="{_fmt(max(pos_on_edge, 5.0))}" '
                            f'departSpeed="{_fmt(lane_speed)}"/>')
                        n += 1
                pos += max(float(rng.exponential(mean_gap_m)), 12.0)
        return lines

    def ramp_edges(self, ramp: RampTrafficSpec) -> tuple[str, ...]:
        """The edges a car from ``ramp`` drives: the ramp's own, then the route's."""
        edges = ramp_route(self.network, ramp.edge, self.route)
        if edges is None:  # the catalog checks this; a hand-built Scenario may not
            raise ValueError(f"ramp_traffic edge {ramp.edge!r} does not lead onto the route")
        return edges

    def _ramp(self, rng: np.random.Generator, i: int, ramp: RampTrafficSpec) -> list[str]:
        """On-ramp ``i``: its route, cars spread over its own edges at t = 0 (exponential
        headways, density q / v per lane) and a Poisson flow entering at its edge."""
        if ramp.vehicles_per_hour <= 0:
            return []
        net = self.network
        edges = self.ramp_edges(ramp)
        own = [e for e in edges if e not in self.route]
        speed = ramp.speed_mps if ramp.speed_mps is not None else max(
            li.speed_mps for li in net.lane_info(tuple(own)))
        vtype = f"bg_{RAMP_PREFIX}{i}" if ramp.speed_mps is not None else "bg"
        rid = f"r_{RAMP_PREFIX}{i}"
        lines = [f'  <route id="{rid}" edges="{" ".join(edges)}"/>']
        for k, edge in enumerate(own):
            lanes = [li.index for li in net.lane_info((edge,)) if li.allows_passenger]
            mean_gap_m = speed * len(lanes) / (ramp.vehicles_per_hour / 3600.0)
            for lane in lanes:
                pos = float(rng.exponential(mean_gap_m)) + 10.0
                n = 0
                while pos < net.edge_length_m(edge) - 10.0:
                    vid = f"{RAMP_PREFIX}{i}_pre{k}_{lane}_{n}"
                    lines.append(f'  <route id="r_{vid}" edges="{" ".join(edges[k:])}"/>')
                    lines.append(
                        f'  <vehicle id="{vid}" type="{vtype}" route="r_{vid}" depart="0" '
                        f'departLane="{lane}" departPos="{_fmt(pos)}" '
                        f'departSpeed="{_fmt(speed)}"/>')
                    n += 1
                    pos += max(float(rng.exponential(mean_gap_m)), 12.0)
        rate = ramp.vehicles_per_hour / 3600.0
        end_s = float(self.scenario.duration_s) + 1.0
        lines.append(
            f'  <flow id="{RAMP_PREFIX}{i}" type="{vtype}" route="{rid}" begin="0" '
            f'end="{_fmt(end_s)}" period="exp({rate:.6f})" departLane="best" '
            f'departSpeed="desired" departPos="base"/>')
        return lines
