"""Lane ends, curves and on-ramps in real SUMO, on nets built here from plain XML
(tests/feature_nets.py; suite.stress.netgen for the curve and the on-ramp): the
two-loop controller leaves an ending lane once, towards the through lanes; changes lane
on a curve within the lateral budget; and lets on-ramp traffic in. Each case is read
back from the run directory (trace, verdict)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from catalog_runs import run_catalog
from feature_nets import lane_drop_net, taper_net

from reports.record import load_run
from suite.stress.netgen import NetLayout, build_net, route_of

pytestmark = [pytest.mark.sumo, pytest.mark.slow]
LAT_BUDGET_MPS2 = 4.0  # LaneChangeParams / LateralRefParams max_lat_acc_mps2


def reversals(t: np.ndarray, side: np.ndarray, window_s: float = 1.0) -> int:
    """Switches of the pass side to the opposite sign within ``window_s`` of the start
    of the previous direction."""
    count, current, start = 0, 0, -np.inf
    for ti, s in zip(t, side, strict=True):
        if s in (1, -1) and s != current:
            if current and ti - start < window_s:
                count += 1
            current, start = int(s), float(ti)
    return count


@pytest.fixture(scope="module")
def lane_end_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("lane_ends")
    nets = [lane_drop_net(base, name="drop_r"), lane_drop_net(base, spread="center",
                                                              name="drop_c"),
            taper_net(base, name="taper_r"), taper_net(base, spread="center", name="taper_c")]
    text = '[defaults]\ncontroller = "two_loop"\nduration_s = 30.0\nstep_s = 0.02\n'
    for net in nets:
        for vph in (0, 1800):
            text += (f'[[scenario]]\nname = "{net.stem.split(".")[0]}_{vph}"\n'
                     f'net = "{net.name}"\nego = {{ lane = 0, pos_m = 150.0, '
                     f'speed_mps = 28.0 }}\ntraffic = {{ vehicles_per_hour = {vph}, seed = 5 }}\n')
    return run_catalog(base, text)


def test_an_ending_lane_is_left_once_towards_the_through_lanes(lane_end_runs: Path) -> None:
    runs = sorted(p for p in lane_end_runs.iterdir() if (p / "run.json").is_file())
    assert len(runs) == 8
    for run_dir in runs:
        record = load_run(run_dir)
        tr = pd.read_parquet(run_dir / "trace.parquet")
        side = tr["side"].to_numpy()
        assert record.status == "pass", (run_dir.name, record.verdict)
        # the ego starts in the lane the catalog named: the ending one, right of the
        # reference (a through lane)
        assert tr["lat_dev_m"].iloc[0] == pytest.approx(-3.5, abs=0.3), run_dir.name
        assert not np.any(side == -1), run_dir.name  # never further right
        assert reversals(tr["t_s"].to_numpy(), side) == 0, run_dir.name
        assert abs(tr["lat_dev_m"].iloc[-1]) < 0.5, run_dir.name  # in a through lane
        first = tr["side_reason"][side == 1].iloc[0]
        assert "lane ends" in first, (run_dir.name, first)


@pytest.fixture(scope="module")
def curve_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("curves")
    text = '[defaults]\ncontroller = "two_loop"\nduration_s = 30.0\nstep_s = 0.02\n'
    for radius in (400, 600, 800):
        layout = NetLayout(name=f"curve3_r{radius}", lanes=3, shoulder=False, lead_in_m=300.0,
                           radius_m=float(radius), angle_deg=60.0, lead_out_m=600.0)
        net = build_net(layout, base)
        route = ", ".join(f'"{e}"' for e in route_of(layout))
        for stall in (420.0, 500.0):
            text += (f'[[scenario]]\nname = "r{radius}_{int(stall)}"\nnet = "{net.name}"\n'
                     f'route = [{route}]\nego = {{ lane = 0, pos_m = 100.0, speed_mps = 33.0 }}\n'
                     f'stalled = [ {{ lane = 0, pos_m = {stall} }} ]\n')
    return run_catalog(base, text)


def test_lane_changes_on_curves_keep_the_lateral_budget(curve_runs: Path) -> None:
    runs = sorted(p for p in curve_runs.iterdir() if (p / "run.json").is_file())
    assert len(runs) == 6
    for run_dir in runs:
        record = load_run(run_dir)
        tr = pd.read_parquet(run_dir / "trace.parquet")
        assert record.status == "pass", (run_dir.name, record.verdict)
        assert (tr["side"] == 1).any() and (tr["side"] == -1).any(), run_dir.name  # out, back
        assert record.verdict is not None
        assert record.verdict.value("max_abs_lat_acc_mps2") <= LAT_BUDGET_MPS2, run_dir.name


@pytest.fixture(scope="module")
def ramp_runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An on-ramp into a 2-lane motorway with a shoulder (suite.stress.netgen), ramp
    traffic, the ego in the right lane; in one case a stalled car in the left lane just
    after the entry (the lane it would make room in), in another on the right lane."""
    base = tmp_path_factory.mktemp("ramps")
    layout = NetLayout(name="ramp2", lanes=2, shoulder=True, lead_in_m=1030.0,
                       radius_m=900.0, angle_deg=50.0, lead_out_m=300.0, merge_at_m=750.0)
    net = build_net(layout, base)
    route = ", ".join(f'"{e}"' for e in route_of(layout))
    text = '[defaults]\ncontroller = "two_loop"\nduration_s = 40.0\nstep_s = 0.02\n'
    cases = {"ramp_free": "", "ramp_stall_left": "stalled = [ { lane = 2, pos_m = 790.0 } ]\n",
             "ramp_stall_right": "stalled = [ { lane = 1, pos_m = 1100.0 } ]\n"}
    for name, stalled in cases.items():
        for seed, vph in ((1, 630), (2, 900)):
            text += (f'[[scenario]]\nname = "{name}_{seed}"\nnet = "{net.name}"\n'
                     f'route = [{route}]\nseed = {seed}\n'
                     'ego = { lane = 1, pos_m = 250.0, speed_mps = 19.7 }\n' + stalled
                     + f'ramp_traffic = [ {{ edge = "ramp", vehicles_per_hour = {vph}, '
                     'speed_mps = 23.0 } ]\n')
    return run_catalog(base, text)


def test_on_ramp_traffic_is_let_in(ramp_runs: Path) -> None:
    runs = sorted(p for p in ramp_runs.iterdir() if (p / "run.json").is_file())
    assert len(runs) == 6
    for run_dir in runs:
        record = load_run(run_dir)
        assert record.verdict is not None, run_dir.name
        assert record.status == "pass", (run_dir.name, [f.line for f in
                                                          record.verdict.failures])
        assert record.verdict.value("min_ttc_s") >= 0.95
