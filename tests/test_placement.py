"""Issue #31's placement check: the ego's front bumper at t = 0, projected onto its lane's
polyline in the net file, lies at the catalog's ``pos_m`` (within 0.05 m along the lane
and laterally), on every kind of net: the bundled ones, netconvert nets with a curve, a
digitising kink and a lane gain at an exit, the shared OpenStreetMap motorways, and the
imported recordings (tests/placement_check.py has the independent measurement)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from feature_nets import curve_exit_net, kinked_net, lane_drop_net
from placement_check import placement_error

import sumo_nets
from suite.catalog import load_catalog
from suite.catalog.specs import Scenario
from suite.road.lane_graph import RouteLaneGraph
from suite.road.network import RoadNetwork

REAL = Path(__file__).resolve().parents[2] / "shared" / "nets_real"
RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "commonroad"
TOLERANCE_M = 0.05


def scenarios(tmp: Path, net: Path, route: tuple[str, ...], cases: list[tuple[int, float]]
              ) -> list[Scenario]:
    """One lane_keep scenario per (lane, pos_m) on ``net`` along ``route``."""
    body = ['[defaults]\ncontroller = "lane_keep"\nduration_s = 10.0\nstep_s = 0.02\n']
    for k, (lane, pos) in enumerate(cases):
        body.append(f'[[scenario]]\nname = "p{k}"\nnet = "{net}"\nroute = {list(route)!r}\n'
                    f"ego = {{ lane = {lane}, pos_m = {pos}, speed_mps = 20.0 }}\n")
    path = tmp / f"{net.stem}.toml"
    path.write_text("\n".join(body).replace("'", '"'))
    return list(load_catalog(path).scenarios)


def through_cases(net: Path, route: tuple[str, ...], positions: list[float]
                  ) -> list[tuple[int, float]]:
    """(lane, pos) for every lane of the edge at each position that allows cars."""
    network = RoadNetwork.load(net)
    graph = RouteLaneGraph(network, route)
    out = []
    for pos in positions:
        edge, _ = network.locate(route, pos)
        k = route.index(edge)
        out += [(i, pos) for i, lane in graph.lanes(k).items() if lane.allows_passenger]
    return out


def assert_placed(cases: list[Scenario]) -> None:
    errors = {sc.name: placement_error(sc) for sc in cases}
    worst_along = max(abs(e.along_m) for e in errors.values())
    worst_lateral = max(abs(e.lateral_m) for e in errors.values())
    assert worst_along <= TOLERANCE_M, {n: e for n, e in errors.items()
                                        if abs(e.along_m) > TOLERANCE_M}
    assert worst_lateral <= TOLERANCE_M, {n: e for n, e in errors.items()
                                          if abs(e.lateral_m) > TOLERANCE_M}


@pytest.mark.parametrize("name", sumo_nets.available())
def test_bundled_nets(tmp_path: Path, name: str) -> None:
    net = sumo_nets.net_path(name)
    route = RoadNetwork.load(net).default_route()
    length = RoadNetwork.load(net).route_length_m(route)
    cases = through_cases(net, route, [6.0, 50.0, 333.3, length / 2, length - 320.0])
    assert_placed(scenarios(tmp_path, net, route, cases))


def test_netconvert_nets_with_a_kink_a_curve_and_an_exit(tmp_path: Path) -> None:
    kinked = kinked_net(tmp_path)
    exit_net = curve_exit_net(tmp_path)
    drop = lane_drop_net(tmp_path, spread="center")
    cases = (scenarios(tmp_path, kinked, ("a",), through_cases(
                 kinked, ("a",), [10.0, 640.0, 672.5, 700.0, 1000.0]))
             + scenarios(tmp_path, exit_net, ("a", "b", "c"), through_cases(
                 exit_net, ("a", "b", "c"), [100.0, 520.0, 650.0, 790.0, 900.0]))
             + scenarios(tmp_path, drop, ("a", "b"), through_cases(
                 drop, ("a", "b"), [400.0, 590.0, 700.0])))
    assert_placed(cases)


@pytest.mark.skipif(not (REAL / "catalog.toml").is_file(), reason="../shared/nets_real absent")
def test_the_shared_motorways(tmp_path: Path) -> None:
    doc = tomllib.loads((REAL / "catalog.toml").read_text())
    cases = list(load_catalog(REAL / "catalog.toml").scenarios)
    for sc in {s["net"]: s for s in doc["scenario"]}.values():
        net, route = REAL / sc["net"], tuple(sc["route"])
        length = RoadNetwork.load(net).route_length_m(route)
        positions = [length * f for f in (0.05, 0.21, 0.37, 0.52, 0.68, 0.83)]
        cases += scenarios(tmp_path, net, route, through_cases(net, route, positions))
    assert_placed(cases)


@pytest.mark.slow
@pytest.mark.skipif(not RECORDINGS.is_dir(), reason="../shared/commonroad absent")
def test_imported_recordings(tmp_path: Path) -> None:
    from suite.importers.commonroad import import_files

    import_files(sorted(RECORDINGS.glob("*.xml")), tmp_path / "imported")
    cases = list(load_catalog(tmp_path / "imported" / "catalog.toml").scenarios)
    assert len(cases) >= 3
    assert_placed(cases)
