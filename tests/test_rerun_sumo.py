"""A real SUMO run's Rerun log, read back with Rerun's own reader (rerun.chunk.RrdReader)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from rerun.chunk import RrdReader
from rerun_fixtures import read_chunks, render_birdseye, rows_at_step

from suite.rerun.log import application_id_for

pytestmark = pytest.mark.sumo

ROOT = Path(__file__).resolve().parents[1]
CATALOG = """
[defaults]
controller = "two_loop"
duration_s = 14.0
step_s = 0.02
seed = 4
[[scenario]]
name = "rrd_stall_traffic"
net = "straight_3lane"
ego = { lane = 1, pos_m = 80.0, speed_mps = 25.0 }
# close enough that the pass puts an ellipse on it (the tests read one)
stalled = [ { lane = 1, pos_m = 200.0 } ]
traffic = { vehicles_per_hour = 1500, seed = 9, lanes = [0, 2] }
"""


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    base = tmp_path_factory.mktemp("rrd")
    catalog = base / "rrdcat.toml"
    catalog.write_text(CATALOG)
    outs = []
    for label in ("a", "b"):
        out = base / label
        proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                               str(out)], cwd=ROOT, capture_output=True, text=True, timeout=600)
        assert proc.returncode in (0, 1), proc.stdout + proc.stderr
        outs.append(out / "rrd_stall_traffic")
    return outs[0], outs[1]


@pytest.mark.slow
def test_entity_paths_of_a_real_run(two_runs) -> None:
    run_dir, _ = two_runs
    paths = {c.entity_path for c in read_chunks(run_dir / "run.rrd")}
    for p in ("/world/road/lanes", "/world/road/centrelines", "/world/reference_path",
              "/world/ego/box", "/world/vehicles", "/world/stalled", "/world/ellipses",
              "/world/plan", "/world/preview", "/world/detection", "/safety/min_gap_m",
              "/comfort/accel_mps2/lat", "/controller/residual", "/timing/step_ms/outer",
              "/events", "/docs/scenario", "/docs/controller"):
        assert p in paths, p


def test_one_ego_pose_per_step_and_static_road_once(two_runs) -> None:
    run_dir, _ = two_runs
    trace = pd.read_parquet(run_dir / "trace.parquet")
    steps: list[int] = []
    road_static = road_temporal = 0
    for c in read_chunks(run_dir / "run.rrd"):
        if c.entity_path == "/world/ego/box" and not c.is_static:
            steps += c.to_record_batch().column("step").to_pylist()
        if c.entity_path == "/world/road/lanes":
            if c.is_static:
                road_static += c.num_rows
            else:
                road_temporal += c.num_rows
    assert sorted(steps) == trace["step"].tolist()
    assert road_static == 1 and road_temporal == 0
    # The plan drawn at a step is the controller's plan of that step (N+1 points).
    plan = rows_at_step(read_chunks(run_dir / "run.rrd"), "/world/plan", 300,
                        "LineStrips2D:strips")
    assert plan and len(plan[0]) == 21


def test_two_runs_of_one_scenario_are_two_recordings_of_one_application(two_runs) -> None:
    a, b = two_runs
    rec_a = RrdReader(a / "run.rrd").recordings()[0]
    rec_b = RrdReader(b / "run.rrd").recordings()[0]
    print(f"recording ids: {rec_a.recording_id} {rec_b.recording_id}")
    assert rec_a.recording_id != rec_b.recording_id
    assert rec_a.application_id == rec_b.application_id \
        == application_id_for("rrdcat", "rrd_stall_traffic") == "hwyeval:rrdcat:rrd_stall_traffic"


def test_birdseye_picture_from_the_log(two_runs, tmp_path: Path) -> None:
    run_dir, _ = two_runs
    trace = pd.read_parquet(run_dir / "trace.parquet")
    seen = trace.loc[trace["n_obstacles"] > 0, "step"]
    passing = int(seen.iloc[len(seen) // 2])  # a step in the middle of the pass
    png = render_birdseye(run_dir / "run.rrd", passing, tmp_path / "birdseye.png")
    assert png.stat().st_size > 1000


def test_preview_error_reaches_the_trace_and_the_log(two_runs) -> None:
    """Every diagnostic two_loop declares is a trace column; the preview error is logged."""
    import dataclasses

    from controllers.two_loop.diagnostics import TwoLoopDiagnostics

    run_dir, _ = two_runs
    trace = pd.read_parquet(run_dir / "trace.parquet")
    for f in dataclasses.fields(TwoLoopDiagnostics):
        assert f.name in trace.columns, f.name
    for col in ("preview_err_t_m", "preview_err_n_m"):
        values = trace[col].to_numpy()
        assert values.size == len(trace) and (abs(values) > 1e-6).any()
    chunks = read_chunks(run_dir / "run.rrd")
    rows = {c.entity_path: 0 for c in chunks}
    for c in chunks:
        if not c.is_static:
            rows[c.entity_path] += c.num_rows
    logged = {p: n for p, n in rows.items() if p.startswith("/controller/preview_err_m/")}
    assert logged and all(n == len(trace) for n in logged.values()), logged
