"""End to end on a real libsumo, through the real CLI (each scenario in its own process)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from reports.record import load_run

pytestmark = pytest.mark.sumo

ROOT = Path(__file__).resolve().parents[1]
# Columns that measure the machine, not the scenario: excluded from determinism checks.
TIMING = re.compile(r"(wall|realtime|_ms_|step_ms|step_var|deadline|time_ms|log_s|_s_p\d\d)")

CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 16.0
step_s = 0.02
seed = 3

[[scenario]]
name = "lane_keep_into_stalled_car"
net = "straight_3lane"
ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 300.0 } ]

[[scenario]]
name = "lane_keep_free_curve_with_traffic"
net = "curve_2lane"
ego = { lane = 0, pos_m = 400.0, speed_mps = 22.0, target_speed_mps = 22.0 }
traffic = { vehicles_per_hour = 1800, seed = 4 }

[[scenario]]
name = "controller_crashes_mid_run"
net = "straight_2lane"
ego = { lane = 0, pos_m = 300.0, speed_mps = 20.0 }
controller = "crash_at_step_50"

[[scenario]]
name = "too_slow_for_its_budget"
net = "straight_2lane"
ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }
duration_s = 600.0
timeout_s = 0.3
"""


# A valid catalog whose run fails at run time: a plug-in controller that drives like
# lane_keep and raises at its 50th step (validation cannot know).
CRASH_PLUGIN = Path(__file__).resolve().parent / "crash_plugin.py"


def hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=600)


@pytest.fixture(scope="module")
def catalog_run(
        tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, subprocess.CompletedProcess[str]]:
    base = tmp_path_factory.mktemp("foundation")
    catalog = base / "foundation.toml"
    catalog.write_text(CATALOG)
    out = base / "out"
    proc = hwyeval("run", str(catalog), "--out", str(out), "--jobs", "2", "--no-log",
                   "--plugin", str(CRASH_PLUGIN))
    return out, proc


def _results(out: Path) -> pd.DataFrame:
    return pd.read_csv(out / "results.csv").set_index("scenario")


@pytest.mark.slow
def test_run_exit_code_is_one_when_anything_fails(catalog_run) -> None:
    out, proc = catalog_run
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert (out / "results.csv").is_file()


def test_results_have_the_required_columns(catalog_run) -> None:
    out, _ = catalog_run
    df = pd.read_csv(out / "results.csv")
    for col in ("scenario", "controller", "status", "collision", "min_gap_m", "progress_m",
                "sim_time_s", "wall_s"):
        assert col in df.columns
    assert set(df["status"]) <= {"pass", "fail", "error", "timeout"}
    assert len(df) == 4


def test_lane_keep_driven_into_stalled_car_collides_and_fails(catalog_run) -> None:
    out, _ = catalog_run
    row = _results(out).loc["lane_keep_into_stalled_car"]
    assert row["status"] == "fail"
    assert row["collision"] == 1
    assert row["min_gap_m"] == 0.0
    # It hit the car: progress stops near stall position minus the ego's start.
    assert 200.0 < row["progress_m"] < 260.0
    rec = load_run(out / "lane_keep_into_stalled_car", trace=False, neighbours=False,
                   arrays=False, series=False)
    assert any("stalled0" in (c.victim, c.collider) for c in rec.outcome.sumo_collisions)


def test_lane_keep_on_free_road_with_traffic_passes(catalog_run) -> None:
    out, _ = catalog_run
    row = _results(out).loc["lane_keep_free_curve_with_traffic"]
    assert row["status"] == "pass", row.get("failed_criteria")
    assert row["collision"] == 0
    assert row["min_gap_m"] > 0.5
    assert row["progress_m"] == pytest.approx(22.0 * 16.0, rel=0.03)


def test_ego_pose_in_sumo_equals_the_plant_every_step(catalog_run) -> None:
    """At every SUMO step (every 5th control step: sumo_step_s 0.1 s, step_s 0.02 s)
    SUMO's ego is the plant's pose pushed before it; in between SUMO's ego is held."""
    out, _ = catalog_run
    trace = pd.read_parquet(out / "lane_keep_free_curve_with_traffic" / "trace.parquet")
    rec = load_run(out / "lane_keep_free_curve_with_traffic", trace=False, neighbours=False,
                   arrays=False, series=False)
    d = rec.info.ego.cg_to_front_bumper_m
    fx = trace["x_m"] + d * np.cos(trace["psi_rad"])
    fy = trace["y_m"] + d * np.sin(trace["psi_rad"])
    err = np.hypot(fx - trace["sumo_front_x_m"], fy - trace["sumo_front_y_m"])
    assert len(trace) == 800
    sumo_rows = (trace["step"] + 1) % 5 == 0  # row k holds control step k + 1
    assert float(err[sumo_rows].max()) < 0.03
    held = trace["sumo_front_x_m"].to_numpy().reshape(-1, 5)
    assert np.all(held[1:, :4] == held[:-1, 4:5])  # held from the last SUMO step
    dpsi = np.angle(np.exp(1j * (trace["psi_rad"] - trace["sumo_heading_rad"])))
    assert float(np.abs(dpsi[sumo_rows]).max()) < 1e-3
    # The curve is driven: the heading turns, so this is not a trivial straight-line check.
    assert float(trace["psi_rad"].max() - trace["psi_rad"].min()) > 0.5


def test_a_crashing_scenario_is_an_error_with_traceback_and_others_go_on(catalog_run) -> None:
    out, _ = catalog_run
    res = _results(out)
    assert res.loc["controller_crashes_mid_run", "status"] == "error"
    tb = (out / "controller_crashes_mid_run" / "traceback.txt").read_text()
    assert "Traceback" in tb and "deliberate crash at step 50" in tb
    assert res.loc["lane_keep_free_curve_with_traffic", "status"] == "pass"


def test_a_scenario_over_its_wall_budget_is_a_timeout(catalog_run) -> None:
    out, _ = catalog_run
    res = _results(out)
    assert res.loc["too_slow_for_its_budget", "status"] == "timeout"
    trace = pd.read_parquet(out / "too_slow_for_its_budget" / "trace.parquet")
    assert 0 < len(trace) < 30000  # what ran before the budget was kept


def test_junit_has_one_testcase_per_scenario(catalog_run) -> None:
    import xml.etree.ElementTree as ET

    out, _ = catalog_run
    cases = ET.parse(out / "junit.xml").getroot().iter("testcase")
    assert len(list(cases)) == 4


@pytest.mark.slow
def test_same_seed_same_catalog_gives_identical_results(catalog_run, tmp_path: Path) -> None:
    out, _ = catalog_run
    catalog = out.parent / "foundation.toml"
    again = tmp_path / "again"
    proc = hwyeval("run", str(catalog), "--out", str(again), "--no-log", "--jobs", "1",
                   "--filter", "lane_keep_*", "--plugin", str(CRASH_PLUGIN))
    assert proc.returncode == 1, proc.stderr
    a = _results(out).loc[["lane_keep_into_stalled_car", "lane_keep_free_curve_with_traffic"]]
    b = _results(again).loc[["lane_keep_into_stalled_car", "lane_keep_free_curve_with_traffic"]]
    timing = [c for c in a.columns if TIMING.search(c)]
    assert timing, "expected timing columns to exclude"
    pd.testing.assert_frame_equal(a.drop(columns=timing), b.drop(columns=timing))
    ta = pd.read_parquet(out / "lane_keep_free_curve_with_traffic" / "trace.parquet")
    tb = pd.read_parquet(again / "lane_keep_free_curve_with_traffic" / "trace.parquet")
    cols = [c for c in ta.columns if not c.endswith("_s") or c in ("t_s", "ssm_ttc_s")]
    pd.testing.assert_frame_equal(ta[cols], tb[cols])


def test_stalled_car_stays_put_and_traffic_passes_it(tmp_path: Path) -> None:
    catalog = tmp_path / "w.toml"
    catalog.write_text("""
[[scenario]]
name = "w"
net = "straight_3lane"
controller = "sumo"
duration_s = 60.0
step_s = 0.05
ego = { lane = 2, pos_m = 900.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 700.0 } ]
traffic = { vehicles_per_hour = 2400, seed = 5 }
""")
    proc = subprocess.run(
        [sys.executable, str(ROOT / "tests" / "sumo_scripts" / "world_traffic_check.py"),
         str(catalog), "w", str(tmp_path / "work")],
        cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    facts = json.loads(proc.stdout.strip().splitlines()[-1])
    assert facts["stall_drift_m"] == 0.0
    assert facts["stall_max_speed"] == 0.0
    assert facts["hazard_always_on"]
    assert facts["passed"] >= 3, facts  # vehicles queued behind it change lane and pass
    lanes = facts["lane_context"]
    assert [lane["index"] for lane in lanes] == [0, 1, 2]
    assert all(lane["passenger"] and not lane["shoulder"] for lane in lanes)
    assert all(lane["width_m"] == pytest.approx(3.5) for lane in lanes)


BAD_CATALOGS = {
    "unknown_key": ("ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0, colour = 1 }", "colour"),
    "wrong_type": ('ego = { lane = "left", pos_m = 50.0, speed_mps = 20.0 }', "lane"),
    "lane_out_of_range": ("ego = { lane = 5, pos_m = 50.0, speed_mps = 20.0 }", "lane"),
    "pos_out_of_range": ("ego = { lane = 0, pos_m = 9000.0, speed_mps = 20.0 }", "pos_m"),
    "unknown_net": ('ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0 }\nnet = "nowhere"', "net"),
    "unknown_controller": (
        'ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0 }\ncontroller = "magic"', "controller"),
    "bad_controller_option": (
        'ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0 }\n'
        'controller = { name = "lane_keep", lookahead_min_m = "far" }', "lookahead_min_m"),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(BAD_CATALOGS))
def test_bad_catalog_exits_2_naming_file_scenario_and_key(case: str, tmp_path: Path) -> None:
    body, key = BAD_CATALOGS[case]
    net_line = "" if "net =" in body else 'net = "straight_2lane"\n'
    catalog = tmp_path / f"{case}.toml"
    catalog.write_text(f'[defaults]\nstep_s = 0.02\nduration_s = 5.0\ncontroller = "lane_keep"\n\n'
                       f'[[scenario]]\nname = "bad_{case}"\n{net_line}{body}\n')
    out = tmp_path / "out"
    proc = hwyeval("run", str(catalog), "--out", str(out))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert str(catalog) in proc.stderr
    assert f"bad_{case}" in proc.stderr
    assert key in proc.stderr
    assert not (out / f"bad_{case}").exists()  # nothing ran


def test_duplicate_names_exit_2(tmp_path: Path) -> None:
    catalog = tmp_path / "dup.toml"
    one = ('[[scenario]]\nname = "twin"\nnet = "straight_2lane"\nstep_s = 0.02\nduration_s = 5.0\n'
           'ego = { lane = 0, pos_m = 50.0, speed_mps = 20.0 }\ncontroller = "lane_keep"\n')
    catalog.write_text(one + one)
    proc = hwyeval("list", str(catalog))
    assert proc.returncode == 2
    assert "twin" in proc.stderr and "name" in proc.stderr and str(catalog) in proc.stderr


def test_list_prints_swept_names(tmp_path: Path) -> None:
    catalog = tmp_path / "sweep.toml"
    catalog.write_text("""
[defaults]
controller = "lane_keep"
duration_s = 5.0
step_s = 0.02
[[scenario]]
name = "s3_stall_mid"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 400.0 } ]
traffic = { vehicles_per_hour = 1500, seed = 7 }
[scenario.sweep]
"stalled.0.pos_m" = [300.0, 500.0]
"traffic.vehicles_per_hour" = [0, 2000]
""")
    proc = hwyeval("list", str(catalog))
    assert proc.returncode == 0, proc.stderr
    names = proc.stdout.split()
    assert names == ["s3_stall_mid__pos300__vph0", "s3_stall_mid__pos300__vph2000",
                     "s3_stall_mid__pos500__vph0", "s3_stall_mid__pos500__vph2000"]
