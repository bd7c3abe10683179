"""SUMO world adapter: one libsumo simulation per scenario, returned as numpy arrays.

libsumo hosts one simulation per *process* and is not thread-safe, so a
:class:`SumoWorld` must be the only one alive in its process (the executors run
each scenario in its own process).

Conventions
-----------
SUMO reports a vehicle's *front bumper* centre and a heading in navigation
degrees (0 = north, clockwise). Everything leaving this module is in the math
convention of the rest of the suite: box *centre* [m] and heading in radians
counter-clockwise from +X.

The ego is inserted as a normal vehicle of type ``ego`` carrying SUMO's SSM
device. When it is driven externally its speed mode is 32 and its lane-change
mode 0, and each step its pose is pushed with ``moveToXY(..., keepRoute=2)``
(free placement, mapped to the nearest lane) so that the other agents react to
the plant's truth. Stalled vehicles stop on their lane for the whole run with
hazard lights on. Background traffic: vehicles spread over the route at t = 0
with exponential headways (so traffic surrounds the ego from the first step)
plus Poisson flows entering at the route's start, on every lane that admits
passenger cars (or the lanes the catalog names).
"""

from __future__ import annotations

import math
import os
import xml.sax.saxutils as su
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from controllers.plant.vehicle_model import VehicleParams
from suite.road.network import RoadNetwork

EGO_ID = "ego"
STALLED_PREFIX = "stalled"
HAZARD_SIGNAL = 1 << 2  # SUMO VEH_SIGNAL_BLINKER_EMERGENCY
_INSERT_CLEARANCE_M = 30.0
SENSING_RADIUS_M = 300.0  # keep pre-placed traffic this far from the ego and stalled cars


def sumo_binary() -> str:
    import sumo_nets

    home = sumo_nets.sumo_home()
    return os.path.join(home, "bin", "sumo")


def nav_deg_to_math_rad(angle_deg: float | np.ndarray) -> Any:
    """SUMO navigation degrees (0 = north, clockwise) -> radians CCW from +X."""
    return np.deg2rad(90.0 - np.asarray(angle_deg, dtype=np.float64))


def math_rad_to_nav_deg(psi_rad: float) -> float:
    return float((90.0 - math.degrees(psi_rad)) % 360.0)


@dataclass
class Neighbours:
    """Other vehicles at one instant, arrays of shape (n,)."""

    ids: list[str]
    x_m: np.ndarray  # box centre
    y_m: np.ndarray
    heading_rad: np.ndarray
    speed_mps: np.ndarray
    length_m: np.ndarray
    width_m: np.ndarray
    lane_index: np.ndarray  # int
    edge_id: list[str]
    stalled: np.ndarray  # bool

    @property
    def count(self) -> int:
        return len(self.ids)

    @staticmethod
    def empty() -> Neighbours:
        z = np.zeros(0)
        return Neighbours([], z, z, z, z, z, z, np.zeros(0, dtype=np.int64), [],
                          np.zeros(0, dtype=bool))


@dataclass
class EgoSumoState:
    """The ego as SUMO sees it (for the ``sumo`` controller and for checks)."""

    front_x_m: float
    front_y_m: float
    heading_rad: float
    speed_mps: float
    accel_mps2: float
    lane_index: int
    edge_id: str


def _fmt(value: float) -> str:
    return f"{value:.3f}"


class SumoWorld:
    """A running libsumo simulation for one scenario.

    ``scenario`` is a :class:`suite.catalog.Scenario`; ``work_dir`` receives the
    generated route file and SUMO's own outputs (SSM, collisions).
    """

    def __init__(self, scenario: Any, network: RoadNetwork, vehicle: VehicleParams,
                 work_dir: Path, *, externally_driven: bool) -> None:
        self.scenario = scenario
        self.network = network
        self.vehicle = vehicle
        self.work_dir = Path(work_dir)
        self.externally_driven = externally_driven
        self.route = tuple(scenario.route)
        self.stalled_ids: list[str] = []
        self._started = False
        self._libsumo: Any = None
        # Sensing reaches further than what is logged: side choice needs to see the
        # target lane over the whole manoeuvre (planning range + gap window).
        self._radius_m = max(float(scenario.record_radius_m), SENSING_RADIUS_M)
        self.collisions: list[dict[str, Any]] = []

    # ---------------------------------------------------------------- set-up
    def _route_xml(self) -> str:
        sc = self.scenario
        net = self.network
        veh = self.vehicle
        rng = np.random.default_rng(sc.traffic.seed if sc.traffic is not None else sc.seed)
        lines = ["<routes>"]
        lines.append(
            f'  <vType id="ego" length="{_fmt(veh.length_m)}" width="{_fmt(veh.width_m)}" '
            f'vClass="passenger" minGap="2.0" maxSpeed="60" color="0,160,255">'
        )
        lines.append('    <param key="has.ssm.device" value="true"/>')
        lines.append('    <param key="device.ssm.measures" value="TTC DRAC PET"/>')
        lines.append('    <param key="device.ssm.trajectories" value="true"/>')
        ssm_path = su.escape(str(self.ssm_file))
        lines.append(f'    <param key="device.ssm.file" value="{ssm_path}"/>')
        lines.append("  </vType>")
        traffic = sc.traffic
        dev = traffic.speed_factor_dev if traffic is not None else 0.1
        lines.append(
            f'  <vType id="bg" vClass="passenger" length="4.5" width="1.8" speedDev="{_fmt(dev)}" '
            f'lcStrategic="1.0" lcCooperative="1.0" lcSpeedGain="1.0" color="200,200,200"/>'
        )
        lines.append(f'  <route id="main" edges="{" ".join(self.route)}"/>')

        for i, st in enumerate(sc.stalled):
            vid = f"{STALLED_PREFIX}{i}"
            self.stalled_ids.append(vid)
            edge, pos_on_edge = net.locate(self.route, st.pos_m)
            k = self.route.index(edge)
            lines.append(f'  <route id="r_{vid}" edges="{" ".join(self.route[k:])}"/>')
            lines.append(
                f'  <vType id="stalled_{i}" vClass="passenger" color="255,60,60" '
                f'length="{_fmt(st.length_m)}" width="{_fmt(st.width_m)}"/>'
            )
            lane_len = net.edge_length_m(edge)
            pos = min(max(pos_on_edge, st.length_m + 0.1), lane_len - 0.1)
            lines.append(
                f'  <vehicle id="{vid}" type="stalled_{i}" route="r_{vid}" depart="0" '
                f'departLane="{st.lane}" departPos="{_fmt(pos)}" departSpeed="0">'
            )
            # A stop that outlasts any run keeps it on its lane, not parked beside it.
            lines.append(f'    <stop lane="{edge}_{st.lane}" endPos="{_fmt(pos)}" '
                         f'duration="1000000"/>')
            lines.append("  </vehicle>")

        ego = sc.ego
        ego_edge, ego_pos = net.locate(self.route, ego.pos_m)
        k_ego = self.route.index(ego_edge)
        if k_ego > 0:
            lines.append(f'  <route id="r_ego" edges="{" ".join(self.route[k_ego:])}"/>')
        lines.append(
            f'  <vehicle id="{EGO_ID}" type="ego" route="{"r_ego" if k_ego > 0 else "main"}" '
            f'depart="0" departLane="{ego.lane}" departPos="{_fmt(max(ego_pos, veh.length_m))}" '
            f'departSpeed="{_fmt(ego.speed_mps)}"/>'
        )

        if traffic is not None and traffic.vehicles_per_hour > 0:
            lines.extend(self._traffic_xml(rng))
        lines.append("</routes>")
        return "\n".join(lines) + "\n"

    def _traffic_lanes(self) -> list[int]:
        sc = self.scenario
        first = self.route[0]
        if sc.traffic.lanes is not None:
            return list(sc.traffic.lanes)
        infos = [li for li in self.network.lane_info(self.route[:1]) if li.edge_id == first]
        return [li.index for li in infos if li.allows_passenger]

    def _traffic_xml(self, rng: np.random.Generator) -> list[str]:
        sc = self.scenario
        tr = sc.traffic
        net = self.network
        lanes = self._traffic_lanes()
        if not lanes:
            return []
        per_lane_vph = tr.vehicles_per_hour / len(lanes)
        speed_limit = max(li.speed_mps for li in net.lane_info(self.route))
        speed = tr.speed_mps if tr.speed_mps is not None else speed_limit
        lines: list[str] = []
        route_len = net.route_length_m(self.route)
        blocked = [sc.ego.pos_m] + [st.pos_m for st in sc.stalled]
        # Pre-placed vehicles: headways exponential with mean speed/flow (density k = q/v).
        mean_gap_m = speed / (per_lane_vph / 3600.0) if per_lane_vph > 0 else math.inf
        n = 0
        if math.isfinite(mean_gap_m):
            for lane in lanes:
                pos = float(rng.exponential(mean_gap_m)) + 10.0
                while pos < route_len - 20.0:
                    near_ego_or_stalled = any(abs(pos - b) < _INSERT_CLEARANCE_M for b in blocked)
                    edge, pos_on_edge = net.locate(self.route, pos)
                    if not near_ego_or_stalled and net.lane_count(edge) > lane:
                        k = self.route.index(edge)
                        vid = f"pre{n}"
                        lines.append(f'  <route id="r_{vid}" edges="{" ".join(self.route[k:])}"/>')
                        lines.append(
                            f'  <vehicle id="{vid}" type="bg" route="r_{vid}" depart="0" '
                            f'departLane="{lane}" departPos="{_fmt(max(pos_on_edge, 5.0))}" '
                            f'departSpeed="{_fmt(speed)}"/>'
                        )
                        n += 1
                    pos += max(float(rng.exponential(mean_gap_m)), 12.0)
        end_s = float(sc.duration_s) + 1.0
        for lane in lanes:
            if per_lane_vph <= 0:
                continue
            rate = per_lane_vph / 3600.0
            lines.append(
                f'  <flow id="flow_l{lane}" type="bg" route="main" begin="0" end="{_fmt(end_s)}" '
                f'period="exp({rate:.6f})" departLane="{lane}" departSpeed="desired" '
                f'departPos="base"/>'
            )
        return lines

    def start(self) -> None:
        """Write the route file and start libsumo with an explicit seed."""
        import libsumo

        self.work_dir.mkdir(parents=True, exist_ok=True)
        routes = self.work_dir / "routes.rou.xml"
        routes.write_text(self._route_xml())
        sc = self.scenario
        seed = int(sc.traffic.seed) if sc.traffic is not None else int(sc.seed)
        args = [
            sumo_binary(),
            "-n", str(sc.net_path),
            "-r", str(routes),
            "--step-length", repr(float(sc.step_s)),
            "--seed", str(seed),
            "--time-to-teleport", "-1",
            "--collision.mingap-factor", "0",
            "--collision.action", "warn",
            "--collision.check-junctions", "true",
            "--collision-output", str(self.work_dir / "collisions.xml"),
            "--no-step-log", "true",
            "--no-warnings", "true",
            "--duration-log.disable", "true",
            "--default.action-step-length", repr(float(sc.step_s)),
            "--lanechange.duration", "3",
        ]
        libsumo.start(args)
        self._libsumo = libsumo
        self._started = True
        libsumo.simulationStep()  # inserts the vehicles departing at t = 0
        if EGO_ID not in libsumo.vehicle.getIDList():
            raise RuntimeError(
                f"SUMO could not insert the ego at lane {sc.ego.lane}, pos {sc.ego.pos_m} m "
                f"(occupied or invalid); see {routes}")
        for vid in self.stalled_ids:
            if vid in libsumo.vehicle.getIDList():
                libsumo.vehicle.setSignals(vid, HAZARD_SIGNAL)
        if self.externally_driven:
            libsumo.vehicle.setSpeedMode(EGO_ID, 32)
            libsumo.vehicle.setLaneChangeMode(EGO_ID, 0)
        else:
            libsumo.vehicle.setMaxSpeed(EGO_ID, float(sc.ego.target_speed_mps))
        import traci.constants as tc

        self._tc = tc
        libsumo.vehicle.subscribeContext(
            EGO_ID, tc.CMD_GET_VEHICLE_VARIABLE, self._radius_m,
            [tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED, tc.VAR_LENGTH, tc.VAR_WIDTH,
             tc.VAR_LANE_INDEX, tc.VAR_ROAD_ID],
        )

    # ------------------------------------------------------------- stepping
    @property
    def time_s(self) -> float:
        return float(self._libsumo.simulation.getTime())

    def move_ego(self, front_x_m: float, front_y_m: float, heading_rad: float) -> None:
        """Push the plant's pose (front bumper centre, math heading) into SUMO."""
        self._libsumo.vehicle.moveToXY(EGO_ID, "", -1, float(front_x_m), float(front_y_m),
                                       math_rad_to_nav_deg(heading_rad), keepRoute=2)

    def step(self) -> list[dict[str, Any]]:
        """Advance SUMO by one step; return the collisions involving the ego this step."""
        ls = self._libsumo
        ls.simulationStep()
        hits = []
        for c in ls.simulation.getCollisions():
            if EGO_ID in (c.collider, c.victim):
                hit = {"t_s": self.time_s, "collider": c.collider, "victim": c.victim,
                       "type": c.type}
                hits.append(hit)
                self.collisions.append(hit)
        return hits

    def ego_in_sim(self) -> bool:
        return EGO_ID in self._libsumo.vehicle.getIDList()

    def ego_state(self) -> EgoSumoState:
        v = self._libsumo.vehicle
        x, y = v.getPosition(EGO_ID)
        return EgoSumoState(
            front_x_m=float(x), front_y_m=float(y),
            heading_rad=float(nav_deg_to_math_rad(v.getAngle(EGO_ID))),
            speed_mps=float(v.getSpeed(EGO_ID)), accel_mps2=float(v.getAcceleration(EGO_ID)),
            lane_index=int(v.getLaneIndex(EGO_ID)), edge_id=str(v.getRoadID(EGO_ID)),
        )

    def neighbours(self) -> Neighbours:
        """Vehicles within the recording radius of the ego (excluding the ego)."""
        tc = self._tc
        res = self._libsumo.vehicle.getContextSubscriptionResults(EGO_ID)
        ids = [vid for vid in res if vid != EGO_ID]
        if not ids:
            return Neighbours.empty()
        n = len(ids)
        fx = np.empty(n)
        fy = np.empty(n)
        ang = np.empty(n)
        spd = np.empty(n)
        ln = np.empty(n)
        wd = np.empty(n)
        lane = np.empty(n, dtype=np.int64)
        edges = []
        for i, vid in enumerate(ids):
            r = res[vid]
            fx[i], fy[i] = r[tc.VAR_POSITION]
            ang[i] = r[tc.VAR_ANGLE]
            spd[i] = r[tc.VAR_SPEED]
            ln[i] = r[tc.VAR_LENGTH]
            wd[i] = r[tc.VAR_WIDTH]
            lane[i] = r[tc.VAR_LANE_INDEX]
            edges.append(r[tc.VAR_ROAD_ID])
        heading = nav_deg_to_math_rad(ang)
        cx = fx - 0.5 * ln * np.cos(heading)
        cy = fy - 0.5 * ln * np.sin(heading)
        stalled = np.array([vid.startswith(STALLED_PREFIX) for vid in ids], dtype=bool)
        return Neighbours(ids, cx, cy, heading, spd, ln, wd, lane, edges, stalled)

    def stalled_vehicles(self) -> list[dict[str, Any]]:
        """Every stalled vehicle's box (centre, heading) and lane, wherever the ego is."""
        v = self._libsumo.vehicle
        present = set(v.getIDList())
        out = []
        for vid in self.stalled_ids:
            if vid not in present:
                continue
            fx, fy = v.getPosition(vid)
            heading = float(nav_deg_to_math_rad(v.getAngle(vid)))
            length = float(v.getLength(vid))
            out.append({"id": vid, "x_m": fx - 0.5 * length * math.cos(heading),
                        "y_m": fy - 0.5 * length * math.sin(heading), "heading_rad": heading,
                        "length_m": length, "width_m": float(v.getWidth(vid)),
                        "lane_index": int(v.getLaneIndex(vid))})
        return out

    @property
    def ssm_file(self) -> Path:
        """SUMO writes the SSM log when the simulation closes."""
        return self.work_dir / "ssm.xml"

    def lane_context(self) -> list[Any]:
        """Lanes of the edge the ego is on (the next route edge while inside a junction).

        Each item is a :class:`suite.road.network.LaneInfo`: index (0 = rightmost),
        width, centreline shape, allowed vehicle classes, shoulder flag. All lanes of
        one SUMO edge run the same direction; an oncoming carriageway is another edge.
        """
        edge = str(self._libsumo.vehicle.getRoadID(EGO_ID))
        if edge.startswith(":") or edge not in self.route:
            idx = int(self._libsumo.vehicle.getRouteIndex(EGO_ID))
            edge = self.route[min(max(idx, 0) + (1 if edge.startswith(":") else 0),
                                  len(self.route) - 1)]
        return [li for li in self.network.lane_info(self.route) if li.edge_id == edge]

    def close(self) -> None:
        if self._started:
            try:
                self._libsumo.close()
            finally:
                self._started = False

    def __enter__(self) -> SumoWorld:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def parse_ssm(path: Path) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Read SUMO's SSM log of the ego: per-time minimum TTC over its conflicts, and a summary.

    Returns (times_s (n,), ttc_s (n,), summary) where summary has ``min_ttc_s``,
    ``max_drac_mps2``, ``conflicts``. TTC is only defined while a conflict is
    tracked; missing values are NaN. An absent or empty file gives empty arrays.
    """
    import xml.etree.ElementTree as ET

    if not path.is_file() or path.stat().st_size == 0:
        return np.zeros(0), np.zeros(0), {"conflicts": 0}
    root = ET.parse(path).getroot()
    per_time: dict[float, float] = {}
    min_ttc = math.inf
    max_drac = -math.inf
    n = 0
    for conflict in root.iter("conflict"):
        n += 1
        span = conflict.find("timeSpan")
        ttc_span = conflict.find("TTCSpan")
        if span is not None and ttc_span is not None:
            times = span.get("values", "").split()
            ttcs = ttc_span.get("values", "").split()
            for t_txt, v_txt in zip(times, ttcs, strict=False):
                try:
                    t, v = float(t_txt), float(v_txt)
                except ValueError:
                    continue
                if v >= 0:
                    per_time[t] = min(per_time.get(t, math.inf), v)
        for tag, key in (("minTTC", "ttc"), ("maxDRAC", "drac")):
            el = conflict.find(tag)
            if el is None:
                continue
            try:
                value = float(el.get("value", "nan"))
            except ValueError:
                continue
            if key == "ttc" and value >= 0:
                min_ttc = min(min_ttc, value)
            elif key == "drac" and math.isfinite(value):
                max_drac = max(max_drac, value)
    times_arr = np.array(sorted(per_time))
    ttc_arr = np.array([per_time[t] for t in times_arr]) if per_time else np.zeros(0)
    summary: dict[str, Any] = {"conflicts": n,
                               "min_ttc_s": min_ttc if math.isfinite(min_ttc) else None,
                               "max_drac_mps2": max_drac if math.isfinite(max_drac) else None}
    return times_arr, ttc_arr, summary
