"""`hwyeval import commonroad`: real commonroad-io parsing of the shared CommonRoad files
(../shared/commonroad, never copied here), real netconvert, hwyeval's RoadNetwork."""

from __future__ import annotations

import json
import math
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from controllers.plant.vehicle_model import VehicleParams
from suite.catalog.tracks import read_tracks
from suite.importers.commonroad import FileResult, ImportFailure, import_file, import_files
from suite.importers.commonroad.checks import StepParams
from suite.importers.commonroad.geometry import project
from suite.importers.commonroad.net_build import NetParams
from suite.importers.commonroad.pipeline import ImportParams
from suite.road.network import RoadNetwork

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "commonroad"
FILES = ("USA_US101-3_3_T-1", "USA_US101-4_1_T-1", "DEU_A9-3_1_T-1")

pytestmark = pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} (the shared "
                                "CommonRoad development files) is absent")


def _src(stem: str) -> Path:
    return SHARED / f"{stem}.xml"


@pytest.fixture(scope="module")
def imported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, FileResult]]:
    out = tmp_path_factory.mktemp("cr_import")
    outcome = import_files([_src(s) for s in FILES], out)
    assert not outcome.failures
    return out, {r.source.name[:-4]: r for r in outcome.results}


def _lanelets(stem: str) -> dict[int, object]:
    from commonroad.common.reader.file_reader_xml import XMLFileReader

    scenario, _ = XMLFileReader(str(_src(stem))).open()
    return {ll.lanelet_id: ll for ll in scenario.lanelet_network.lanelets}


def _lane_map(stem: str, network: RoadNetwork) -> dict[int, tuple[str, int]]:
    """lanelet id -> (edge, lane index), from commonroad-io's adjacency (lane 0 = the
    lanelet the edge is named after, then adjacentLeft)."""
    lls = _lanelets(stem)
    out = {}
    for eid in network.edge_ids():
        if "-" in eid:
            continue  # extension edges
        lid: int | None = int(eid[1:])
        for i in range(network.lane_count(eid)):
            assert lid is not None
            out[lid] = (eid, i)
            lid = lls[lid].adj_left if lls[lid].adj_left_same_direction else None
    return out


def _scenario(out: Path, stem: str) -> dict[str, object]:
    data = json.loads((out / f"{stem}.scenario.json").read_text())
    table: dict[str, object] = data["scenario"]
    return table


@pytest.mark.parametrize("stem", FILES)
def test_each_file_imports(imported: tuple[Path, dict[str, FileResult]], stem: str) -> None:
    # how fast is the import's own line (wall_s) and hwyeval bench's business, not a
    # test's: under a busy second core the same file took 1.1 or 4.1 s
    out, results = imported
    r = results[stem]
    assert r.wall_s > 0.0
    assert (out / f"{stem}.net.xml").is_file() and (out / f"{stem}.tracks.parquet").is_file()
    assert not list(out.glob("*.partial"))


@pytest.mark.parametrize("stem", FILES)
def test_lane_shapes_lie_on_lanelet_centre_lines(imported: tuple[Path, dict[str, FileResult]],
                                                 stem: str) -> None:
    out, _ = imported
    network = RoadNetwork.load(out / f"{stem}.net.xml")
    lls = _lanelets(stem)
    dists, interior = [], []
    for lid, (eid, i) in _lane_map(stem, network).items():
        centre = np.asarray(lls[lid].center_vertices)
        shape = network.lane_info((eid,))[i].shape_xy_m
        cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(shape, axis=0).T))])
        for s, (x, y) in zip(cum, shape, strict=True):
            d = project(centre, float(x), float(y)).distance_m
            dists.append(d)
            if 1.0 < s < cum[-1] - 1.0:
                interior.append(d)
    assert float(np.median(dists)) <= 0.05
    assert max(interior) <= 0.5


@pytest.mark.parametrize("stem", FILES)
def test_coordinates_are_commonroads(imported: tuple[Path, dict[str, FileResult]],
                                     stem: str) -> None:
    """No offset: an interior lane shape vertex is a lanelet centre-line vertex (1 mm)."""
    out, _ = imported
    network = RoadNetwork.load(out / f"{stem}.net.xml")
    lls = _lanelets(stem)
    for lid, (eid, i) in _lane_map(stem, network).items():
        centre = np.asarray(lls[lid].center_vertices)
        shape = network.lane_info((eid,))[i].shape_xy_m
        if len(centre) < 3 or len(shape) < 3:
            continue
        gaps = np.min(np.hypot(*(shape[1:-1, None, :] - centre[None, 1:-1, :]).T), axis=0)
        assert float(gaps.min()) < 1e-3
        return
    pytest.fail("no lane with an interior vertex")


@pytest.mark.parametrize("stem", FILES)
def test_every_successor_is_a_connection(imported: tuple[Path, dict[str, FileResult]],
                                         stem: str) -> None:
    out, _ = imported
    network = RoadNetwork.load(out / f"{stem}.net.xml")
    where = _lane_map(stem, network)
    lls = _lanelets(stem)
    links = {(eid, ln.from_index, ln.to_edge_id, ln.to_index)
             for eid in network.edge_ids() for ln in network.lane_links(eid)}
    n = 0
    for lid, (eid, i) in where.items():
        for s in lls[lid].successor:
            assert (eid, i, *where[s]) in links
            n += 1
    assert n > 0


def test_a9_edges_lanes_links_and_extension(imported: tuple[Path, dict[str, FileResult]]
                                            ) -> None:
    out, results = imported
    network = RoadNetwork.load(out / "DEU_A9-3_1_T-1.net.xml")
    assert network.lane_count("L436") == 4  # 4 lanes
    assert network.lane_count("L444") == 5  # + the exit lane
    assert network.lane_count("L464") == 6
    assert network.lane_count("L480") == 4  # the exit's 2 lanes have left
    assert network.lane_count("L4221") == 5  # + the on-ramp's lane
    assert network.is_link("L476") and network.is_link("L3990")  # exit, on-ramp
    assert not network.is_link("L4221")
    route = results["DEU_A9-3_1_T-1"].route
    assert route[-1] == "L4221-extension" and not network.link_edges(route)
    assert network.edge_length_m("L4221-extension") == pytest.approx(1000.0, abs=1.0)
    assert network.default_route() == route
    us = RoadNetwork.load(out / "USA_US101-4_1_T-1.net.xml")
    assert us.lane_count("L12") == 5 and us.lane_count("L16") == 6 and us.is_link("L15")
    us3 = RoadNetwork.load(out / "USA_US101-3_3_T-1.net.xml")
    assert us3.lane_count("L23") == 6 and us3.lane_count("L24") == 5 and us3.is_link("L22")


@pytest.mark.parametrize("stem", FILES)
def test_ego_round_trip(imported: tuple[Path, dict[str, FileResult]], stem: str) -> None:
    """The net position of the front bumper minus half the ego's length is the
    CommonRoad centre (0.5 m); the catalog's lane is the lane there."""
    from commonroad.common.reader.file_reader_xml import XMLFileReader

    out, _ = imported
    sc = _scenario(out, stem)
    ego = sc["ego"]
    assert isinstance(ego, dict)
    route = tuple(sc["route"])  # type: ignore[arg-type]
    network = RoadNetwork.load(out / str(sc["net"]))
    _, problems = XMLFileReader(str(_src(stem))).open()
    init = next(iter(problems.planning_problem_dict.values())).initial_state
    cx, cy = (float(v) for v in init.position)
    length = VehicleParams().length_m

    def along(pos_m: float, lane: int | None, x: float, y: float) -> tuple[float, float,
                                                                          float]:
        """(longitudinal gap [m] between route position ``pos_m`` and (x, y) projected
        on the lane, the lateral distance, the lane width), on the nearest lane of the
        edge at ``pos_m`` (or on lane ``lane``)."""
        edge, p = network.locate(route, pos_m)
        frac = p / network.edge_length_m(edge)
        best = None
        for ln in network.lane_info((edge,)):
            if lane is not None and ln.index != lane:
                continue
            pr = project(ln.shape_xy_m, x, y)
            cand = (abs(pr.s_m - frac * pr.length_m), pr.distance_m, ln.width_m)
            if best is None or cand[1] < best[1]:
                best = cand
        assert best is not None
        return best

    gap, lateral, width = along(float(ego["pos_m"]) - 0.5 * length, None, cx, cy)
    assert gap <= 0.5 and lateral <= 0.5 * width
    fx = cx + 0.5 * length * math.cos(init.orientation)
    fy = cy + 0.5 * length * math.sin(init.orientation)
    gap, lateral, width = along(float(ego["pos_m"]), int(ego["lane"]), fx, fy)
    assert gap <= 0.5 and lateral <= 0.5 * width
    assert ego["speed_mps"] == pytest.approx(float(init.velocity))
    assert ego["target_speed_mps"] == ego["speed_mps"]


@pytest.mark.parametrize("stem", FILES)
def test_tracks_are_the_recording(imported: tuple[Path, dict[str, FileResult]],
                                  stem: str) -> None:
    """Every recorded vehicle kept (none is off the road in these files), ids
    rec_<id>, run time 0 at the initial time step, first sample on a lane of the net
    within half its width."""
    from commonroad.common.reader.file_reader_xml import XMLFileReader

    out, results = imported
    ts = read_tracks(out / f"{stem}.tracks.parquet")
    scenario, _ = XMLFileReader(str(_src(stem))).open()
    assert {t.track_id for t in ts.tracks} == {f"rec_{o.obstacle_id}"
                                               for o in scenario.dynamic_obstacles}
    assert ts.dt_s == pytest.approx(scenario.dt) and ts.notes
    assert results[stem].duration_s == pytest.approx(max(t.end_s for t in ts.tracks))
    network = RoadNetwork.load(out / f"{stem}.net.xml")
    lanes = [(ln.shape_xy_m, ln.width_m) for eid in network.edge_ids()
             for ln in network.lane_info((eid,))]
    lanes += [(shape, w) for eid in network.edge_ids() for link in network.lane_links(eid)
              for shape, w in zip(link.via_shapes, link.via_widths_m, strict=True)
              if len(shape) >= 2]
    by_id = {f"rec_{o.obstacle_id}": o for o in scenario.dynamic_obstacles}
    for t in ts.tracks:
        assert t.time_s[0] == pytest.approx(by_id[t.track_id].initial_state.time_step * ts.dt_s)
        assert np.all(np.abs(np.diff(t.heading_rad)) < math.pi)
        margin = min(project(xy, t.x_m[0], t.y_m[0]).distance_m - 0.5 * w for xy, w in lanes)
        assert margin <= 1e-6


def test_uncertain_states_take_centres(imported: tuple[Path, dict[str, FileResult]]) -> None:
    _, results = imported
    assert results["DEU_A9-3_1_T-1"].uncertain_states > 0  # 2018b intervals / rectangles
    assert results["USA_US101-4_1_T-1"].uncertain_states == 0


def test_mislabelled_time_step_is_corrected(tmp_path: Path) -> None:
    """The A9 file moves at 0.2 s; a header saying 0.1 s is detected and corrected."""
    text = _src("DEU_A9-3_1_T-1").read_text()
    assert 'timeStepSize="0.2"' in text
    bad = tmp_path / "a9_dt.xml"
    bad.write_text(text.replace('timeStepSize="0.2"', 'timeStepSize="0.1"'))
    r = import_file(bad, tmp_path / "out", ImportParams())
    assert r.step.corrected and r.step.header_dt_s == pytest.approx(0.1)
    assert r.step.dt_s == pytest.approx(0.2)
    ts = read_tracks(r.tracks_path)
    assert ts.dt_s == pytest.approx(0.2) and r.duration_s == pytest.approx(6.0)
    good = import_file(_src("DEU_A9-3_1_T-1"), tmp_path / "good", ImportParams())
    assert not good.step.corrected


def _edit(stem: str, tmp_path: Path, name: str) -> tuple[ET.ElementTree, Path]:
    tree = ET.parse(_src(stem))
    return tree, tmp_path / f"{name}.xml"


def test_opposite_and_off_road_vehicles_are_dropped(tmp_path: Path) -> None:
    tree, path = _edit("USA_US101-4_1_T-1", tmp_path, "us101_edit")
    obstacles = tree.getroot().findall("dynamicObstacle")
    turned, moved = obstacles[0], obstacles[1]
    for ex in turned.iter("orientation"):
        e = ex.find("exact")
        assert e is not None and e.text is not None
        e.text = str(float(e.text) + math.pi)
    for pt in moved.iter("point"):
        x = pt.find("x")
        assert x is not None and x.text is not None
        x.text = str(float(x.text) + 500.0)
    tree.write(path)
    r = import_file(path, tmp_path / "out", ImportParams())
    assert r.dropped["opposite"] == (int(turned.get("id", "0")),)
    assert r.dropped["off_road"] == (int(moved.get("id", "0")),)
    assert r.kept == len(obstacles) - 2
    ids = {t.track_id for t in read_tracks(r.tracks_path).tracks}
    assert f"rec_{turned.get('id')}" not in ids


def test_static_obstacle_becomes_stalled_car(tmp_path: Path) -> None:
    tree, path = _edit("USA_US101-4_1_T-1", tmp_path, "us101_static")
    root = tree.getroot()
    pp = root.find("planningProblem/initialState")
    assert pp is not None
    x0 = float(pp.findtext("position/point/x") or 0.0)
    y0 = float(pp.findtext("position/point/y") or 0.0)
    h0 = float(pp.findtext("orientation/exact") or 0.0)
    x, y = x0 + 60.0 * math.cos(h0), y0 + 60.0 * math.sin(h0)
    xml = (f'<staticObstacle id="9001"><type>parkedVehicle</type><shape><rectangle>'
           f'<length>4.5</length><width>1.8</width></rectangle></shape><initialState>'
           f'<position><point><x>{x}</x><y>{y}</y></point></position><orientation><exact>'
           f'{h0}</exact></orientation><time><exact>0</exact></time></initialState>'
           '</staticObstacle>')
    root.insert(list(root).index(root.findall("dynamicObstacle")[0]), ET.fromstring(xml))
    tree.write(path)
    r = import_file(path, tmp_path / "out", ImportParams())
    assert r.stalled == 1
    sc = _scenario(tmp_path / "out", "us101_static")
    (stalled,) = sc["stalled"]  # type: ignore[misc]
    assert stalled["lane"] == sc["ego"]["lane"]  # type: ignore[index]
    assert stalled["pos_m"] == pytest.approx(sc["ego"]["pos_m"] + 60.0, abs=0.5)  # type: ignore[index]


def test_inconsistent_adjacency_names_the_lanelet(tmp_path: Path) -> None:
    tree, path = _edit("USA_US101-3_3_T-1", tmp_path, "bad_adjacency")
    ll = next(e for e in tree.getroot().findall("lanelet") if e.get("id") == "33")
    right = ll.find("adjacentRight")
    assert right is not None
    right.set("ref", "37")  # 35 says 33 is its left neighbour
    tree.write(path)
    with pytest.raises(ImportFailure) as info:
        import_file(path, tmp_path / "out", ImportParams())
    assert info.value.path == str(path) and info.value.element.startswith("lanelet ")


def test_missing_planning_problem_and_bad_xml(tmp_path: Path) -> None:
    tree, path = _edit("USA_US101-3_3_T-1", tmp_path, "no_problem")
    root = tree.getroot()
    for pp in root.findall("planningProblem"):
        root.remove(pp)
    tree.write(path)
    with pytest.raises(ImportFailure) as info:
        import_file(path, tmp_path / "out", ImportParams())
    assert info.value.element == "planningProblem"
    broken = tmp_path / "broken.xml"
    broken.write_text(_src("USA_US101-3_3_T-1").read_text()[:5000])
    with pytest.raises(ImportFailure) as info:
        import_file(broken, tmp_path / "out", ImportParams())
    assert info.value.element.startswith("XML line")
    assert not (tmp_path / "out" / "broken.net.xml").exists()


def test_cli_second_file_corrupt_exits_2_and_keeps_the_first(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from suite.cli import main

    corrupt = tmp_path / "corrupt.xml"
    corrupt.write_text("<commonRoad><lanelet id='1'>")
    out = tmp_path / "out"
    code = main(["import", "commonroad", str(_src("USA_US101-4_1_T-1")), str(corrupt),
                 "--out", str(out)])
    assert code == 2
    captured = capsys.readouterr()
    assert "corrupt.xml" in captured.err
    assert "USA_US101-4_1_T-1" in captured.out
    for suffix in (".net.xml", ".tracks.parquet", ".scenario.json"):
        assert (out / f"USA_US101-4_1_T-1{suffix}").is_file()
    catalog = tomllib.loads((out / "catalog.toml").read_text())
    assert [s["name"] for s in catalog["scenario"]] == ["usa_us101_4_1_t_1"]
    assert not (out / "corrupt.net.xml").exists()
    # a later import of another file keeps the first in the catalog
    assert main(["import", "commonroad", str(_src("USA_US101-3_3_T-1")), "--out",
                 str(out)]) == 0
    catalog = tomllib.loads((out / "catalog.toml").read_text())
    assert len(catalog["scenario"]) == 2


def test_catalog_loads_with_replay(imported: tuple[Path, dict[str, FileResult]]) -> None:
    from suite.catalog import keys, load_catalog

    if "replay" not in keys.SCENARIO_KEYS:
        pytest.skip("the catalog loader has no `replay` key yet")
    out, _ = imported
    cat = load_catalog(out / "catalog.toml")
    assert sorted(s.name for s in cat.scenarios) == ["deu_a9_3_1_t_1", "usa_us101_3_3_t_1",
                                                     "usa_us101_4_1_t_1"]
    for s in cat.scenarios:
        assert s.replay is not None and s.replay.mode == "replay"
        assert s.route[-1].endswith("-extension") and s.step_s == pytest.approx(0.02)


def test_parameters_are_validated() -> None:
    with pytest.raises(ValueError):
        NetParams(downstream_extension_m=0.0)
    with pytest.raises(ValueError):
        NetParams(upstream_extension_m=float("nan"))
    with pytest.raises(ValueError):
        StepParams(tolerance=1.5)


def test_running_an_imported_catalog_needs_no_commonroad(
        imported: tuple[Path, dict[str, FileResult]]) -> None:
    """Loading the catalog (nets, tracks) and the CLI never import commonroad-io."""
    import subprocess
    import sys

    out, _ = imported
    code = ("import sys; import suite.cli; from suite.catalog import load_catalog; "
            f"load_catalog({str(out / 'catalog.toml')!r}, known_controllers=['two_loop']); "
            "sys.exit(1 if any(m.startswith('commonroad') for m in sys.modules) else 0)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=Path(__file__).resolve().parents[1])
    assert res.returncode == 0, res.stderr[-2000:]
