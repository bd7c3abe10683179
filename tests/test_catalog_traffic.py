"""Catalog keys for the road and its traffic: ``friction``, ``traffic.lane_speeds_mps``
(per-lane traffic speeds) and ``ramp_traffic`` (traffic entering from an on-ramp edge off
the route): validation messages, the Scenario they build, the route file they write, and
(SUMO) what the traffic then does."""

from __future__ import annotations

import pickle
import subprocess
import textwrap
import xml.etree.ElementTree as ET
from dataclasses import replace
from pathlib import Path

import pytest

from controllers.plant.vehicle_model import VehicleParams
from suite.catalog import CatalogError, RampTrafficSpec, TrafficSpec, load_catalog
from suite.catalog.traffic_checks import ramp_route
from suite.road.network import RoadNetwork
from suite.world.routes import RouteFile
from tests.plain_nets import PlainNet

KNOWN = {"lane_keep", "sumo"}

# e0 (3 lanes) -> e1 (4 lanes: lane 0 an acceleration lane fed by the on-ramp "ramp",
# ending there) -> e2 (3 lanes) -> exit "off" at the end; "x" is not connected at all.
# spreadType right: the left edge of the carriageway is the edge line, so the through
# lanes stay in place where a lane is added on the right.
NODES = """<nodes>
  <node id="a" x="0" y="0"/> <node id="b" x="600" y="0"/> <node id="c" x="850" y="0"/>
  <node id="d" x="1700" y="0"/> <node id="o" x="1900" y="-60"/>
  <node id="r" x="350" y="-40"/> <node id="p" x="0" y="300"/> <node id="q" x="200" y="300"/>
</nodes>"""
EDGES = """<edges>
  <edge id="e0" from="a" to="b" numLanes="3" speed="33.33" spreadType="right"/>
  <edge id="e1" from="b" to="c" numLanes="4" speed="33.33" spreadType="right"/>
  <edge id="e2" from="c" to="d" numLanes="3" speed="33.33" spreadType="right"/>
  <edge id="ramp" from="r" to="b" numLanes="1" speed="22.22"
        shape="350,-40 600,-12.25"/>
  <edge id="off" from="d" to="o" numLanes="1" speed="22.22"/>
  <edge id="x" from="p" to="q" numLanes="1" speed="22.22"/>
</edges>"""
CONNECTIONS = """<connections>
  <connection from="e0" to="e1" fromLane="0" toLane="1"/>
  <connection from="e0" to="e1" fromLane="1" toLane="2"/>
  <connection from="e0" to="e1" fromLane="2" toLane="3"/>
  <connection from="ramp" to="e1" fromLane="0" toLane="0"/>
  <connection from="e1" to="e2" fromLane="1" toLane="0"/>
  <connection from="e1" to="e2" fromLane="2" toLane="1"/>
  <connection from="e1" to="e2" fromLane="3" toLane="2"/>
  <connection from="e2" to="off" fromLane="0" toLane="0"/>
</connections>"""

HEADER = """
[defaults]
controller = "lane_keep"
duration_s = 30.0
step_s = 0.05
seed = 3
"""
BASE = """
[[scenario]]
name = "merge"
net = "nets/merge.net.xml"
route = ["e0", "e1", "e2"]
ego = { lane = 1, pos_m = 100.0, speed_mps = 25.0 }
"""


@pytest.fixture(scope="module")
def net_dir(tmp_path_factory: pytest.TempPathFactory, plain_net: PlainNet) -> Path:
    root = tmp_path_factory.mktemp("traffic_catalog")
    plain_net(root / "nets", "merge", NODES, EDGES, CONNECTIONS, ("--no-turnarounds", "true"))
    return root


_counter = [0]


def write(root: Path, body: str) -> Path:
    _counter[0] += 1
    path = root / f"cat{_counter[0]}.toml"
    path.write_text(textwrap.dedent(HEADER) + textwrap.dedent(body))
    return path


def issues(path: Path) -> list[str]:
    """One line per problem: ``<file>: <key> (scenario '<name>'): expected ..., got ...``."""
    with pytest.raises(CatalogError) as info:
        load_catalog(path, known_controllers=KNOWN)
    return [issue.line(path) for issue in info.value.issues]


def one(path: Path):  # type: ignore[no-untyped-def]
    return load_catalog(path, known_controllers=KNOWN).scenarios[0]


# ------------------------------------------------------------------ friction


def test_friction_defaults_to_dry_asphalt_and_is_carried(net_dir: Path) -> None:
    assert one(write(net_dir, BASE)).friction == 1.0
    sc = one(write(net_dir, BASE + "friction = 0.6\n"))
    assert sc.friction == 0.6 and isinstance(sc.friction, float)
    assert sc.as_dict()["friction"] == 0.6


def test_friction_from_defaults_and_swept(net_dir: Path) -> None:
    body = BASE + '[scenario.sweep]\nfriction = [1.0, 0.5]\n'
    cat = load_catalog(write(net_dir, body), known_controllers=KNOWN)
    assert cat.names() == ["merge__friction1", "merge__friction0p5"]
    assert [s.friction for s in cat] == [1.0, 0.5]


@pytest.mark.parametrize("value", ["0.0", "-0.3", "2.5", '"wet"', "true", "nan"])
def test_bad_friction_is_reported_at_its_key(net_dir: Path, value: str) -> None:
    lines = issues(write(net_dir, BASE + f"friction = {value}\n"))
    assert len(lines) == 1
    assert lines[0].startswith(f"{net_dir}/cat")
    assert ": scenario[0].friction (scenario 'merge'): expected a friction coefficient in " \
        "(0, 2]" in lines[0]


# ------------------------------------------------------------------ per-lane speeds


def test_lane_speeds_build_an_int_keyed_map(net_dir: Path) -> None:
    sc = one(write(net_dir, BASE + "traffic = { vehicles_per_hour = 1200, "
                   "lane_speeds_mps = { 2 = 20.0, \"0\" = 25 } }\n"))
    assert dict(sc.traffic.lane_speeds_mps) == {"0": 25.0, "2": 20.0}
    assert sc.traffic.own_speed_lanes() == (0, 2)
    assert sc.traffic.lane_speed_mps(2) == 20.0 and sc.traffic.lane_speed_mps(1) is None
    # what the executors send to the worker processes reads back the same
    assert pickle.loads(pickle.dumps(sc)).traffic.lane_speed_mps(2) == 20.0
    direct = TrafficSpec(vehicles_per_hour=10.0, seed=0, lane_speeds_mps={"02": 9, "1": 8.0})
    assert dict(direct.lane_speeds_mps or {}) == {"1": 8.0, "2": 9.0}
    assert sc.as_dict()["traffic"]["lane_speeds_mps"] == {"0": 25.0, "2": 20.0}


@pytest.mark.parametrize("table, key, expected", [
    ("{ 3 = 20.0 }", "traffic.lane_speeds_mps.3", "a lane index in 0..2"),
    ("{ 2 = 0.0 }", "traffic.lane_speeds_mps", "null or a non-empty table"),
    ("{ a = 20.0 }", "traffic.lane_speeds_mps", "null or a non-empty table"),
    ("{ }", "traffic.lane_speeds_mps", "null or a non-empty table"),
    ("20.0", "traffic.lane_speeds_mps", "null or a non-empty table"),
])
def test_bad_lane_speeds(net_dir: Path, table: str, key: str, expected: str) -> None:
    lines = issues(write(net_dir, BASE + f"traffic = {{ vehicles_per_hour = 900, "
                         f"lane_speeds_mps = {table} }}\n"))
    assert len(lines) == 1, lines
    assert f"scenario[0].{key} (scenario 'merge'): expected {expected}" in lines[0]


def test_lane_speed_on_a_lane_without_traffic(net_dir: Path) -> None:
    lines = issues(write(net_dir, BASE + "traffic = { vehicles_per_hour = 900, lanes = [0, 1], "
                         "lane_speeds_mps = { 2 = 20.0 } }\n"))
    assert lines == [lines[0]]
    assert "traffic.lane_speeds_mps.2 (scenario 'merge'): expected a lane that gets " \
        "traffic (one of traffic.lanes [0, 1]), got 2" in lines[0]


def test_traffic_spec_checks_its_own_lane_speeds() -> None:
    with pytest.raises(Exception, match="lane_speeds_mps"):
        TrafficSpec(vehicles_per_hour=100.0, seed=0, lane_speeds_mps={"-1": 20.0})
    with pytest.raises(Exception, match="distinct lane indices"):
        TrafficSpec(vehicles_per_hour=100.0, seed=0, lane_speeds_mps={"1": 20.0, "01": 21.0})


# ------------------------------------------------------------------ on-ramp traffic


def test_ramp_route_joins_the_route(net_dir: Path) -> None:
    net = RoadNetwork.load(net_dir / "nets" / "merge.net.xml")
    assert ramp_route(net, "ramp", ("e0", "e1", "e2")) == ("ramp", "e1", "e2")
    assert ramp_route(net, "ramp", ("e1", "e2")) == ("ramp", "e1", "e2")
    assert ramp_route(net, "off", ("e0", "e1", "e2")) is None  # leads away
    assert ramp_route(net, "x", ("e0", "e1", "e2")) is None  # not connected
    assert ramp_route(net, "e1", ("e0", "e1", "e2")) is None  # on the route


def test_ramp_traffic_is_carried(net_dir: Path) -> None:
    sc = one(write(net_dir, BASE + 'ramp_traffic = [ { edge = "ramp", vehicles_per_hour = 600, '
                   'speed_mps = 20 } ]\n'))
    assert sc.ramp_traffic == (RampTrafficSpec("ramp", 600.0, 20.0),)
    assert sc.as_dict()["ramp_traffic"] == [
        {"edge": "ramp", "vehicles_per_hour": 600.0, "speed_mps": 20.0}]
    swept = load_catalog(write(net_dir, BASE + 'ramp_traffic = [ { edge = "ramp", '
                               'vehicles_per_hour = 600 } ]\n[scenario.sweep]\n'
                               '"ramp_traffic.0.vehicles_per_hour" = [0, 900]\n'
                               '"ramp_traffic.0.speed_mps" = [18.0]\n'),
                         known_controllers=KNOWN)
    assert swept.names() == ["merge__vph0__speed18", "merge__vph900__speed18"]
    assert [s.ramp_traffic[0].speed_mps for s in swept] == [18.0, 18.0]


@pytest.mark.parametrize("entry, key, expected", [
    ('{ edge = "nope", vehicles_per_hour = 100 }', "ramp_traffic.0.edge",
     "an edge of merge.net.xml off the route"),
    ('{ edge = "e1", vehicles_per_hour = 100 }', "ramp_traffic.0.edge",
     "an edge off the route (traffic on the route is 'traffic')"),
    ('{ edge = "off", vehicles_per_hour = 100 }', "ramp_traffic.0.edge",
     "an edge whose lanes lead onto the route within 8 edges (an on-ramp)"),
    ('{ edge = "x", vehicles_per_hour = 100 }', "ramp_traffic.0.edge",
     "an edge whose lanes lead onto the route"),
    ('{ edge = "ramp" }', "ramp_traffic.0.vehicles_per_hour", "this required key"),
    ('{ edge = "ramp", vehicles_per_hour = -5 }', "ramp_traffic.0.vehicles_per_hour",
     "a finite number >= 0"),
    ('{ edge = "ramp", vehicles_per_hour = 5, speed_mps = 0 }', "ramp_traffic.0.speed_mps",
     "a finite number > 0"),
    ('{ edge = "", vehicles_per_hour = 5 }', "ramp_traffic.0.edge", "an edge id"),
    ('{ edge = "ramp", vehicles_per_hour = 5, lane = 0 }', "ramp_traffic.0.lane",
     "one of the keys"),
])
def test_bad_ramp_traffic(net_dir: Path, entry: str, key: str, expected: str) -> None:
    lines = issues(write(net_dir, BASE + f"ramp_traffic = [ {entry} ]\n"))
    assert len(lines) == 1, lines
    assert f"scenario[0].{key} (scenario 'merge'): expected {expected}" in lines[0]


def test_ramp_traffic_must_be_a_list(net_dir: Path) -> None:
    lines = issues(write(net_dir, BASE + 'ramp_traffic = { edge = "ramp" }\n'))
    assert "scenario[0].ramp_traffic (scenario 'merge'): expected a list of tables" in lines[0]


# ------------------------------------------------------------------ the route file


def _routes(net_dir: Path, body: str) -> tuple[RouteFile, ET.Element]:
    sc = one(write(net_dir, body))
    net = RoadNetwork.load(sc.net_path)
    rf = RouteFile(sc, net, VehicleParams(), net_dir / "ssm.xml")
    return rf, ET.fromstring(rf.xml())


TRAFFIC = ("traffic = { vehicles_per_hour = 2400, seed = 4, lane_speeds_mps = { 2 = 19.0 } }\n"
           'ramp_traffic = [ { edge = "ramp", vehicles_per_hour = 900, speed_mps = 20.0 } ]\n')


def test_route_file_gives_the_slow_lane_its_own_type(net_dir: Path) -> None:
    _, root = _routes(net_dir, BASE + TRAFFIC)
    vtypes = {v.get("id"): v for v in root.iter("vType")}
    slow = vtypes["bg_l2"]
    assert slow.get("maxSpeed") == "19.000"
    assert (slow.get("lcKeepRight"), slow.get("lcSpeedGain"), slow.get("lcCooperative")) \
        == ("0", "0", "0")
    flows = {f.get("id"): f for f in root.iter("flow")}
    assert flows["flow_l2"].get("type") == "bg_l2"
    assert flows["flow_l0"].get("type") == "bg" and flows["flow_l1"].get("type") == "bg"
    pre = [v for v in root.iter("vehicle") if v.get("id", "").startswith("pre")]
    on_slow = [v for v in pre if v.get("type") == "bg_l2"]
    assert on_slow and all(float(v.get("departSpeed", "0")) == 19.0 for v in on_slow)
    assert all(v.get("departLane") in ("2", "3") for v in on_slow)  # lane 2 of e0 is 3 on e1


def test_route_file_feeds_the_on_ramp(net_dir: Path) -> None:
    rf, root = _routes(net_dir, BASE + TRAFFIC)
    routes = {r.get("id"): r.get("edges") for r in root.iter("route")}
    assert routes["r_ramp0"] == "ramp e1 e2"
    flow = next(f for f in root.iter("flow") if f.get("id") == "ramp0")
    assert (flow.get("route"), flow.get("type")) == ("r_ramp0", "bg_ramp0")
    assert flow.get("period") == "exp(0.250000)"
    vtypes = {v.get("id"): v for v in root.iter("vType")}
    assert vtypes["bg_ramp0"].get("maxSpeed") == "20.000"
    on_ramp = [v for v in root.iter("vehicle") if v.get("id", "").startswith("ramp0_pre")]
    assert on_ramp  # 900 veh/h at 20 m/s: one car per 80 m of the 250 m ramp on average
    for v in on_ramp:
        assert routes[v.get("route")] == "ramp e1 e2"
        assert 10.0 <= float(v.get("departPos", "0")) < rf.network.edge_length_m("ramp") - 10.0
    assert rf.xml() == rf.xml()  # deterministic


def test_adding_a_ramp_leaves_the_main_traffic_as_it_was(net_dir: Path) -> None:
    main = "traffic = { vehicles_per_hour = 2400, seed = 4 }\n"
    _, without = _routes(net_dir, BASE + main)
    _, with_ramp = _routes(net_dir, BASE + main + 'ramp_traffic = [ { edge = "ramp", '
                           'vehicles_per_hour = 900 } ]\n')

    def main_vehicles(root: ET.Element) -> list[dict[str, str]]:
        return [dict(v.attrib) for v in root.iter("vehicle")
                if not v.get("id", "").startswith("ramp")]

    assert main_vehicles(without) == main_vehicles(with_ramp)


def test_hand_built_scenario_with_a_bad_ramp_is_refused(net_dir: Path) -> None:
    sc = one(write(net_dir, BASE + TRAFFIC))
    bad = replace(sc, ramp_traffic=(RampTrafficSpec("off", 100.0),))
    rf = RouteFile(bad, RoadNetwork.load(sc.net_path), VehicleParams(), net_dir / "ssm.xml")
    with pytest.raises(ValueError, match="does not lead onto the route"):
        rf.xml()


# ------------------------------------------------------------------ in SUMO


def _fcd(net_dir: Path, body: str, end_s: float) -> ET.Element:
    import sumo_nets

    rf, _ = _routes(net_dir, body)
    routes = net_dir / "routes_fcd.rou.xml"
    routes.write_text(rf.xml())
    fcd = net_dir / "fcd.xml"
    subprocess.run([str(Path(sumo_nets.sumo_home()) / "bin" / "sumo"), "-n",
                    str(rf.scenario.net_path), "-r", str(routes), "--end", str(end_s),
                    "--step-length", "0.5", "--fcd-output", str(fcd), "--no-step-log",
                    "--seed", "1"], check=True, capture_output=True)
    return ET.parse(fcd).getroot()


@pytest.mark.sumo
def test_in_sumo_the_slow_lane_stays_slow_and_the_ramp_merges(net_dir: Path) -> None:
    root = _fcd(net_dir, BASE + TRAFFIC, 120.0)
    slow: dict[str, set[str]] = {}
    max_slow_speed = 0.0
    merged: set[str] = set()
    ramp_seen: set[str] = set()
    for step in root.iter("timestep"):
        for v in step.iter("vehicle"):
            vid, lane = v.get("id", ""), v.get("lane", "")
            if v.get("type") == "bg_l2":
                slow.setdefault(vid, set()).add(lane)
                max_slow_speed = max(max_slow_speed, float(v.get("speed", "0")))
            if vid.startswith("ramp0"):
                ramp_seen.add(vid)
                if lane.startswith("e2_"):
                    merged.add(vid)
    assert len(slow) > 10
    assert max_slow_speed <= 19.0 + 1e-6
    # the passing lane's slow traffic keeps the passing lane (lane 2 on e0/e2, 3 on e1)
    allowed = {"e0_2", "e1_3", "e2_2"}
    assert all(lanes <= allowed | {ln for ln in lanes if ln.startswith(":")}
               for lanes in slow.values())
    assert len(ramp_seen) > 10 and len(merged) >= 0.6 * len(ramp_seen)
