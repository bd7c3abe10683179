"""Real motorway stretches (OSM via netconvert, ../shared/nets_real) and the bundled nets,
in SUMO: free drives in every through lane, lane identity across index shifts."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import sumo_nets
from reports.record import RunRecord, load_run
from suite.road.lane_graph import RouteLaneGraph
from suite.road.network import RoadNetwork

pytestmark = pytest.mark.sumo

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "nets_real"
# (net, route, start position, speed): a stretch without ramps ahead for 20 s on each
# real net, and the bundled nets at their usual start.
REAL_STARTS = {"a2_helmstedt": 2200.0, "a391_braunschweig": 2160.0, "a36_schladen": 3200.0}
DURATION_S = 16.0


def _real_routes() -> dict[str, tuple[str, tuple[str, ...]]]:
    doc = tomllib.loads((REAL / "catalog.toml").read_text())
    return {sc["net"].removesuffix(".net.xml"): (str(REAL / sc["net"]), tuple(sc["route"]))
            for sc in doc["scenario"]}


def _free_drive_catalog() -> tuple[str, dict[str, tuple[Path, tuple[str, ...], float, int]]]:
    """A catalog of free drives and, per scenario, (net, route, start, asked lane)."""
    lines = ['[defaults]', f'duration_s = {DURATION_S}', 'step_s = 0.02', 'seed = 1', '']
    expected = {}
    nets: list[tuple[str, str, tuple[str, ...], float, float]] = []
    if (REAL / "catalog.toml").is_file():
        for name, (path, route) in _real_routes().items():
            speed = 20.0 if "a391" in name else 30.0
            nets.append((name, path, route, REAL_STARTS[name], speed))
    for name in sumo_nets.available():
        path = str(sumo_nets.net_path(name))
        nets.append((name, path, RoadNetwork.load(path).default_route(), 300.0, 25.0))
    for name, path, route, pos, speed in nets:
        net = RoadNetwork.load(path)
        g = RouteLaneGraph(net, route)
        edge, _ = net.locate(route, pos)
        k = route.index(edge)
        for lane, info in sorted(g.lanes(k).items()):
            if not (g.is_through(k, lane) and info.allows_passenger):
                continue
            for controller in ("two_loop", "lane_keep"):
                scen = f"free_{name}_l{lane}_{controller}"
                expected[scen] = (Path(path), route, pos, lane)
                lines += ["[[scenario]]", f'name = "{scen}"', f'net = "{path}"',
                          f"route = {list(route)!r}".replace("'", '"'),
                          f'controller = "{controller}"',
                          f"ego = {{ lane = {lane}, pos_m = {pos}, speed_mps = {speed} }}", ""]
    return "\n".join(lines), expected


@pytest.fixture(scope="module")
def free_drives(tmp_path_factory: pytest.TempPathFactory
                ) -> tuple[Path, pd.DataFrame, dict[str, tuple[Path, tuple[str, ...], float, int]]]:
    text, expected = _free_drive_catalog()
    base = tmp_path_factory.mktemp("free")
    catalog = base / "free.toml"
    catalog.write_text(text)
    out = base / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out", str(out),
                           "--jobs", "2", "--no-log"], cwd=ROOT, capture_output=True, text=True,
                          timeout=1500)
    assert (out / "results.csv").is_file(), proc.stdout[-3000:] + proc.stderr[-3000:]
    return out, pd.read_csv(out / "results.csv").set_index("scenario"), expected


@pytest.mark.slow
def test_free_drives_in_every_through_lane_pass(free_drives) -> None:
    _, results, expected = free_drives
    assert set(results.index) == set(expected)
    real = [n for n in expected if any(r in n for r in REAL_STARTS)]
    if (REAL / "catalog.toml").is_file():
        assert len(real) >= 12  # 3 + 2 + 2 through lanes, two controllers
    bad = results[(results["status"] != "pass") | (results["offroad_s"] > 0)]
    assert bad.empty, bad[["status", "failed_criteria", "offroad_s"]].to_string()


def test_free_drives_end_in_the_asked_lane(free_drives) -> None:
    out, _, expected = free_drives
    for scen, (net_path, route, pos, lane) in expected.items():
        rec = load_run(out / scen, neighbours=False, arrays=False, series=False)
        net = RoadNetwork.load(net_path)
        chain = RouteLaneGraph(net, route).chain(route.index(net.locate(route, pos)[0]), lane)
        index_on = {route[st.k]: st.lane.index for st in chain}
        tr = rec.trace
        last = len(tr) - 1
        # Within its lane (pure pursuit keeps a steady offset to the inside of a curve).
        assert abs(tr.ego.lat_dev_m[-20:]).max() < 0.8, scen
        # SUMO has the ego in the asked lane's continuation on the edge where it ends up.
        ego_edge = _edge_at(rec, last)
        if ego_edge in index_on and not ego_edge.startswith(":"):
            assert tr.ego.lane_index[last] == index_on[ego_edge], (scen, ego_edge)


def _edge_at(rec: RunRecord, row: int) -> str:
    """The route edge under the ego at a trace row (from the trace's route position)."""
    net = RoadNetwork.load(rec.info.net)
    route = tuple(rec.road.route)
    lanes = [ln for ln in rec.road.lanes if not ln.internal]
    x, y = rec.trace.ego.x_m[row], rec.trace.ego.y_m[row]
    best = min(lanes, key=lambda ln: float(np.min(np.hypot(ln.shape_xy_m[:, 0] - x,
                                                            ln.shape_xy_m[:, 1] - y))))
    assert best.edge_id in route and net.has_edge(best.edge_id)
    return best.edge_id


@pytest.mark.skipif(not (REAL / "catalog.toml").is_file(), reason="../shared/nets_real absent")
def test_lane_numbering_that_shifts_along_the_route(tmp_path: Path) -> None:
    """A 391: the route starts on a 3-lane edge; the ego starts in lane 0 of a 2-lane edge;
    its stalled car sits in the same physical lane, which is lane 1 where an on-ramp adds
    lane 0. The ego stays in its lane until the car, passes on the left (the right lane
    there is an acceleration lane that ends), and comes back."""
    src = tomllib.loads((REAL / "catalog.toml").read_text())
    sc = next(s for s in src["scenario"] if s["name"] == "dev_a391_stall_lane_shift")
    route = [f'"{e}"' for e in sc["route"]]
    catalog = tmp_path / "shift.toml"
    catalog.write_text(f"""
[[scenario]]
name = "shift"
net = "{REAL / sc['net']}"
route = [{", ".join(route)}]
controller = "two_loop"
duration_s = 40.0
step_s = 0.02
ego = {{ lane = 0, pos_m = 1550.0, speed_mps = 20.0, target_speed_mps = 22.0 }}
stalled = [ {{ lane = 1, pos_m = 2080.0 }} ]
""")
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out", str(out),
                           "--no-log"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    rec = load_run(out / "shift", neighbours=False, arrays=False)
    assert rec.verdict is not None, proc.stdout + proc.stderr
    assert rec.verdict.value("collision") == 0.0
    assert rec.verdict.value("offroad_s") == 0.0
    tr = rec.trace
    # Before the stalled car the ego drives its own lane: SUMO has it in lane 0 of the
    # 2-lane edge, not in the lane numbered 0 of the route's first edge.
    assert tr.ego.lane_index[0] == 0 and abs(tr.ego.lat_dev_m[:100]).max() < 0.2
    side = tr.decision.side
    why = tr.decision.side_reason
    # Passed on the left, never on the right: the only moves right are the return.
    passes = [k for k, r in enumerate(why) if str(r).startswith("pass ")]
    assert passes and all(side[k] == 1 for k in passes)
    rights = {str(why[k]) for k in range(len(side)) if side[k] == -1}
    assert all(r.startswith(("return right", "changing right", "in the right lane"))
               for r in rights), rights
    reasons = " ".join(tr.decision.side_reason.tolist())
    assert "left lane free" in reasons
    assert rec.verdict.value("progress_m") > 700.0
