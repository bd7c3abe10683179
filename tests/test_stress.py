"""The stress-catalog generator (suite.stress): its distributions and schedule, the nets
it builds, determinism, the coverage of a small catalog measured on what it wrote, and
(slow, SUMO) a small catalog run through the CLI."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tomllib
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from suite.catalog import load_catalog
from suite.catalog.toml_write import dumps_catalog, toml_value
from suite.road.lane_graph import RouteLaneGraph
from suite.road.network import RoadNetwork
from suite.stress import FEATURES, StressConfig, generate
from suite.stress.__main__ import main as stress_main
from suite.stress.coverage import Coverage, measure_catalog
from suite.stress.lanes import RouteLanes, lane_curvature
from suite.stress.netgen import RAMP_EDGE, NetLayout, build_net, route_of
from suite.stress.plan import BLOCK, STALLED_LENGTH_M, plan_scenarios
from suite.stress.real import default_real_dir, on_ramps, real_nets

REPO = Path(__file__).resolve().parents[1]
REAL_DIR = default_real_dir()
REAL = tuple(r.name for r in real_nets(REAL_DIR))
FAKE_REAL = ("a2_helmstedt.net.xml", "a36_schladen.net.xml", "a391_braunschweig.net.xml")
CFG = StressConfig()


# ------------------------------------------------------------------ the plan (no nets)


def test_plans_follow_the_distribution_of_the_issue() -> None:
    plans = plan_scenarios(CFG, 11, 300, FAKE_REAL)
    generated = [p for p in plans if p.layout is not None]
    for p in plans:
        far = p.stalled[int(p.close_stall):]
        assert all(250.0 <= s.gap_m <= 1500.0 for s in far)
        gaps = sorted(s.gap_m for s in p.stalled)
        assert all(b - a >= 120.0 - 1e-9 for a, b in zip(gaps, gaps[1:], strict=False))
        assert 1 <= len(far) <= 6
        lo, hi = (20.0, 27.0) if p.close_stall else (18.0, 31.0)
        assert lo <= p.ego_speed_mps <= hi
        assert p.traffic_vph == 0.0 or 100.0 <= p.traffic_vph <= 2400.0
        if p.slow_lane_speed_mps is not None:
            assert p.traffic_vph >= 600.0
            assert 12.0 <= p.slow_lane_speed_mps <= p.ego_speed_mps - 4.0 + 1e-9
        if p.ramp is not None:
            assert 200.0 <= p.ramp.vehicles_per_hour <= 900.0
            assert 18.0 <= p.ramp.speed_mps <= 25.0
        assert p.friction == 1.0  # wet_share is 0 by default
    for p in generated:
        lay = p.layout
        assert lay is not None
        assert 300.0 <= lay.radius_m <= 1500.0 and 25.0 <= abs(lay.angle_deg) <= 70.0
        assert 200.0 <= p.ego_pos_m <= 400.0
        assert lay.lead_in_m - p.ego_pos_m >= 100.0  # the curve is ahead of the ego
        assert lay.length_m >= p.ego_pos_m + 1800.0 - 1e-6
    # both turning directions, every lane count and shoulder
    assert {math.copysign(1.0, p.layout.angle_deg) for p in generated if p.layout} == {-1.0, 1.0}
    pairs = Counter((p.layout.lanes, p.layout.shoulder) for p in generated if p.layout)
    assert set(pairs) == {(n, s) for n in (2, 3, 4) for s in (True, False)}
    assert max(pairs.values()) - min(pairs.values()) <= 1  # every pair every six


def test_shares_are_exact_to_one_scenario() -> None:
    plans = plan_scenarios(CFG, 4, 300, FAKE_REAL)
    counts = {
        "real": sum(p.real_net is not None for p in plans),
        "merge": sum(p.ramp is not None for p in plans),
        "slow": sum(p.slow_lane_speed_mps is not None for p in plans),
        "close": sum(p.close_stall for p in plans),
        "several": sum(len(p.stalled) - p.close_stall > 3 for p in plans),
        "free": sum(p.traffic_vph == 0 for p in plans),
    }
    shares = {"real": CFG.real_share, "merge": CFG.merge_share, "slow": CFG.slow_passing_share,
              "close": CFG.close_stall_share, "several": CFG.several_stalled_share,
              "free": CFG.free_road_share}
    for name, count in counts.items():
        assert abs(count - 300 * shares[name]) <= 1.0, (name, count)
    stalled = Counter(len(p.stalled) - p.close_stall for p in plans
                      if len(p.stalled) - p.close_stall <= 3)
    assert max(stalled.values()) - min(stalled.values()) <= 1  # 1, 2, 3 cycle
    # the features do not ride together: merge and slow overlap about as if independent
    both = sum(p.ramp is not None and p.slow_lane_speed_mps is not None for p in plans)
    assert 5 <= both <= 35  # independent: 300 * 0.25 * 0.25 = 19
    assert not any(p.slow_lane_speed_mps is not None and p.traffic_vph == 0 for p in plans)


@pytest.mark.parametrize("seed", range(25))
def test_every_block_of_eight_from_the_first_covers_every_feature(seed: int) -> None:
    plans = plan_scenarios(CFG, seed, BLOCK, FAKE_REAL)
    assert any(p.real_net for p in plans) and any(p.ramp and p.layout for p in plans)
    assert any(p.slow_lane_speed_mps for p in plans) and any(p.close_stall for p in plans)
    assert any(len(p.stalled) - p.close_stall >= 4 for p in plans)
    assert any(p.traffic_vph == 0 for p in plans) and any(p.traffic_vph > 0 for p in plans)
    assert {len(p.stalled) - p.close_stall for p in plans} >= {1, 2, 3}
    gen = {(p.layout.lanes, p.layout.shoulder) for p in plans if p.layout}
    assert {n for n, _ in gen} == {2, 3, 4} and {s for _, s in gen} == {True, False}


def test_plans_are_deterministic_and_prefix_stable() -> None:
    a = plan_scenarios(CFG, 5, 40, FAKE_REAL)
    assert a == plan_scenarios(CFG, 5, 40, FAKE_REAL)
    assert plan_scenarios(CFG, 5, 13, FAKE_REAL) == a[:13]
    assert plan_scenarios(CFG, 6, 40, FAKE_REAL) != a
    assert all(p.real_net is None for p in plan_scenarios(CFG, 5, 40, ()))
    assert len({p.name for p in a}) == 40


def test_config_is_validated() -> None:
    with pytest.raises(ValueError, match="merge_share"):
        StressConfig(merge_share=1.5)
    with pytest.raises(ValueError, match="curve_radius_m"):
        StressConfig(curve_radius_m=(1500.0, 300.0))
    with pytest.raises(ValueError, match="lanes"):
        StressConfig(lanes=())
    with pytest.raises(ValueError, match="several_stalled_count"):
        StressConfig(several_stalled_count=(4, 20))
    with pytest.raises(ValueError, match="controllers"):
        StressConfig(controllers=())
    with pytest.raises(ValueError, match="duration_s"):
        StressConfig(duration_s=0.0)


# ------------------------------------------------------------------ nets


def test_layout_is_validated() -> None:
    with pytest.raises(ValueError, match="merge_at_m"):
        NetLayout("x", 3, False, 500.0, 400.0, 30.0, 800.0, merge_at_m=450.0)  # runs into it
    with pytest.raises(ValueError, match="lanes"):
        NetLayout("x", 0, False, 500.0, 400.0, 30.0, 800.0)
    with pytest.raises(ValueError, match="angle_deg"):
        NetLayout("x", 2, False, 500.0, 400.0, 0.0, 800.0)


@pytest.mark.parametrize("lanes, shoulder, angle", [(2, False, 40.0), (3, True, -60.0),
                                                    (4, True, 25.0)])
def test_built_net_has_its_curve_lanes_and_merge(tmp_path: Path, lanes: int, shoulder: bool,
                                                 angle: float) -> None:
    lay = NetLayout("t", lanes, shoulder, 700.0, 450.0, angle, 900.0, merge_at_m=300.0)
    net = RoadNetwork.load(build_net(lay, tmp_path))
    route = route_of(lay)
    assert net.route_length_m(route) == pytest.approx(lay.length_m, abs=10.0)
    rl = RouteLanes(net, route)
    graph = RouteLaneGraph(net, route)
    for k in range(len(route)):
        assert len(rl.through(k)) == lanes  # the acceleration lane is not a through lane
    accel = route.index("e1")
    assert net.lane_count("e1") == lanes + int(shoulder) + 1
    assert not graph.is_through(accel, int(shoulder))  # it ends
    assert any(li.is_shoulder for li in net.lane_info(route)) == shoulder
    links = net.lane_links(RAMP_EDGE)
    assert [(ln.to_edge_id, ln.to_index) for ln in links] == [("e1", int(shoulder))]
    # through lanes keep their place where the acceleration lane is added
    for j, (i0, i1) in enumerate(zip(rl.through(0), rl.through(accel), strict=True)):
        y0 = net.lane_info(("e0",))[i0].shape_xy_m[-1]
        y1 = net.lane_info(("e1",))[i1].shape_xy_m[0]
        assert abs(y0[1] - y1[1]) < 0.05, j
    # every through lane turns by the angle; the carriageway's centre has the radius
    radii = []
    for lane in rl.through(0):
        r, turn = lane_curvature(rl.centreline(10.0, lane))
        assert turn == pytest.approx(abs(angle), abs=0.5)
        radii.append(r)
    offsets = (np.arange(lanes) - (lanes - 1) / 2) * 3.5 * (1 if angle > 0 else -1)
    np.testing.assert_allclose(radii, 450.0 - offsets, rtol=0.02)


def test_same_layout_same_bytes(tmp_path: Path) -> None:
    lay = NetLayout("same", 3, True, 600.0, 800.0, -35.0, 900.0, merge_at_m=200.0)
    a = build_net(lay, tmp_path / "a").read_bytes()
    b = build_net(lay, tmp_path / "b").read_bytes()
    assert a == b and b"Warning" not in a


# ------------------------------------------------------------------ the catalog


def test_toml_writer_round_trips() -> None:
    text = dumps_catalog("a\nb", {"controller": "two_loop", "duration_s": 40.0}, [
        {"name": "x", "route": ["e0", "1-2#3"], "ego": {"lane": 1, "pos_m": 10.0},
         "traffic": {"lane_speeds_mps": {"2": 19.5}}, "sweep": {"controller": ["a", "b"]}}])
    doc = tomllib.loads(text)
    assert doc["defaults"]["duration_s"] == 40.0
    sc = doc["scenario"][0]
    assert sc["traffic"]["lane_speeds_mps"] == {"2": 19.5} and sc["sweep"]["controller"] == [
        "a", "b"]
    assert toml_value(25.0) == "25.0" and toml_value(1e-5) == "1e-05"
    with pytest.raises(ValueError):
        toml_value(math.inf)


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != "stress.json"}


@pytest.mark.slow
def test_small_catalog_is_valid_covers_everything_and_is_deterministic(tmp_path: Path
                                                                       ) -> None:
    real_dir = REAL_DIR if REAL else None
    first = generate(BLOCK, 21, tmp_path / "a", real_dir=real_dir, command="test")
    again = generate(BLOCK, 21, tmp_path / "b", real_dir=real_dir, command="test")
    assert _files(tmp_path / "a") == _files(tmp_path / "b")
    other = generate(BLOCK, 22, tmp_path / "c", real_dir=real_dir, command="test")
    assert _files(tmp_path / "c")["catalog.toml"] != _files(tmp_path / "a")["catalog.toml"]
    del again, other
    # what hwyeval run reads, with the real registry checking the controllers
    cat = load_catalog(first.path)
    assert len(cat) == BLOCK and cat.names() == [s.name for s in first.scenarios]
    cov = Coverage.of(measure_catalog(cat, CFG), CFG)
    assert cov.missing(expect_real=bool(REAL)) == [], cov.lines()
    assert set(cov.counts) == set(FEATURES)
    for sc, feat in zip(cat, first.features, strict=True):
        assert feat.name == sc.name
        net = RoadNetwork.load(sc.net_path)
        length = net.route_length_m(sc.route)
        for st in sc.stalled:  # every stalled car ahead of the ego, on the route
            assert sc.ego.pos_m < st.pos_m - STALLED_LENGTH_M < length
        if feat.close_stall:
            close = min(st.pos_m - STALLED_LENGTH_M - sc.ego.pos_m for st in sc.stalled)
            assert 40.0 - 1e-6 <= close <= 90.0 + 1e-6
        if feat.merge and not feat.real:
            assert sc.ramp_traffic[0].edge == RAMP_EDGE
    if REAL:
        assert (tmp_path / "a" / "nets" / "real").is_dir()
        assert all(not Path(sc.net_path).is_relative_to(REAL_DIR) for sc in cat)


@pytest.mark.skipif(not REAL, reason="../shared/nets_real is not there")
def test_real_nets_offer_on_ramps_ahead() -> None:
    for net in real_nets(REAL_DIR):
        network = RoadNetwork.load(net.path)
        ramps = on_ramps(network, net.route)
        assert ramps, net.name
        assert all(r.joins_at_m > 0 and r.edge not in net.route for r in ramps)


def test_command_line_writes_and_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                         ) -> None:
    code = stress_main(["--n", "8", "--seed", "3", "--out", str(tmp_path / "cli"),
                        "--no-real", "--duration-s", "12", "--controller", "two_loop",
                        "--controller", "sumo"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "wrote" in out and "merge" in out and "real_net" in out
    cat = load_catalog(tmp_path / "cli" / "catalog.toml")
    assert len(cat) == 16  # each scenario swept over both controllers
    assert {s.controller.name for s in cat} == {"two_loop", "sumo"}
    assert all(s.duration_s == 12.0 for s in cat)
    assert stress_main(["--n", "-1", "--seed", "0", "--out", str(tmp_path / "x")]) == 2


# ------------------------------------------------------------------ run through the CLI


@pytest.mark.slow
@pytest.mark.sumo
def test_a_small_stress_catalog_runs_through_the_cli(tmp_path: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    out = tmp_path / "stress"
    args = [sys.executable, "-m", "suite.stress", "--n", str(BLOCK), "--seed", "9",
            "--out", str(out), "--duration-s", "6"]
    if not REAL:
        args.append("--no-real")
    subprocess.run(args, check=True, cwd=REPO, env=env, capture_output=True, text=True)
    cat = load_catalog(out / "catalog.toml")
    cov = Coverage.of(measure_catalog(cat, CFG), CFG)
    assert cov.missing(expect_real=bool(REAL)) == [], cov.lines()
    runs = tmp_path / "runs"
    res = subprocess.run([sys.executable, "-m", "suite", "run", str(out / "catalog.toml"),
                          "--out", str(runs), "--jobs", "2", "--no-log"], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode in (0, 1), res.stderr[-3000:]
    results = pd.read_csv(runs / "results.csv")
    assert sorted(results["scenario"]) == sorted(cat.names())
    assert set(results["status"]) <= {"pass", "fail"}, results[["scenario", "status"]]
    assert (results["steps"] > 0).all() if "steps" in results else True
