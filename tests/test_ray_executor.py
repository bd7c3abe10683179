"""The Ray executor on a real local Ray instance (one scenario per fresh worker process)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

pytestmark = [pytest.mark.sumo, pytest.mark.slow]
ray = pytest.importorskip("ray", reason="the 'cluster' extra is not installed")

ROOT = Path(__file__).resolve().parents[1]


def test_ray_executor_runs_a_catalog_and_ships_runs_back(tmp_path: Path) -> None:
    catalog = tmp_path / "cat" / "ray.toml"
    catalog.parent.mkdir()
    catalog.write_text("""
[defaults]
controller = "lane_keep"
duration_s = 4.0
step_s = 0.05
[[scenario]]
name = "ray_free"
net = "straight_2lane"
ego = { lane = 0, pos_m = 60.0, speed_mps = 20.0 }
[[scenario]]
name = "ray_crash"
net = "straight_2lane"
ego = { lane = 0, pos_m = 300.0, speed_mps = 20.0 }
controller = "crash_at_step_50"
""")
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "suite", "run", str(catalog), "--out", str(out), "--executor",
         "ray", "--no-log", "--jobs", "1", "--plugin", str(ROOT / "tests" / "crash_plugin.py")],
        cwd=ROOT,
        capture_output=True, text=True, timeout=600)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    res = pd.read_csv(out / "results.csv").set_index("scenario")
    assert res.loc["ray_free", "status"] == "pass"
    assert res.loc["ray_free", "progress_m"] == pytest.approx(80.0, rel=0.02)
    assert res.loc["ray_crash", "status"] == "error"
    assert (out / "ray_free" / "trace.parquet").is_file()  # shipped back as an archive
    assert "deliberate crash at step 50" in (out / "ray_crash" / "traceback.txt").read_text()
    # the manifest (and the first line) count the actors started, not the scenarios
    assert json.loads((out / "manifest.json").read_text())["jobs"] == 1
