"""`hwyeval report`, `compare` and `view` through the real CLI (synthetic run directories)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd

import tests.synthetic_runs as sr
from suite.rerun.viewer import run_status

ROOT = Path(__file__).resolve().parents[1]


def hwyeval(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, env=env)


def test_report_regenerates_every_file(tmp_path: Path) -> None:
    out = tmp_path / "runs"
    sr.make_catalog(out)
    proc = hwyeval("report", str(out))
    assert proc.returncode == 0, proc.stderr
    for name in ("results.csv", "summary.csv", "junit.xml", "report.html"):
        assert (out / name).stat().st_size > 0
    results = pd.read_csv(out / "results.csv")
    assert {"pass", "fail", "error", "timeout"} <= set(results["status"])


def test_report_on_a_missing_directory_is_invalid_input(tmp_path: Path) -> None:
    proc = hwyeval("report", str(tmp_path / "nowhere"))
    assert proc.returncode == 2
    assert "nowhere" in proc.stderr


def test_compare_gate_exit_codes(tmp_path: Path) -> None:
    base = tmp_path / "base"
    sr.make_catalog(base)
    same = tmp_path / "same"
    shutil.copytree(base, same)
    ok = hwyeval("compare", str(base), str(same), "--out", str(tmp_path / "cmp_same"))
    assert ok.returncode == 0, ok.stdout + ok.stderr
    slower = tmp_path / "slower"
    sr.make_catalog(slower, speedup=3.0)
    bad = hwyeval("compare", str(base), str(slower), "--out", str(tmp_path / "cmp_slow"))
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert "step_ms" in bad.stdout
    assert (tmp_path / "cmp_slow" / "compare.csv").is_file()
    assert (tmp_path / "cmp_slow" / "compare.html").is_file()


def test_view_without_display_prints_the_command(tmp_path: Path) -> None:
    out = tmp_path / "runs"
    sr.make_catalog(out)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = hwyeval("view", str(out), "--failed", env=env)
    assert proc.returncode == 0, proc.stderr
    assert "rerun" in proc.stdout
    statuses = {d.name: run_status(d) for d in out.iterdir() if (d / "run.json").is_file()}
    failed = [name for name, status in statuses.items() if status != "pass"]
    passed = [name for name, status in statuses.items() if status == "pass"]
    assert failed and passed
    # Every non-passing run's log is named in the printed command, no passing one.
    for name in failed:
        assert f"/{name}/run.rrd" in proc.stdout
    for name in passed:
        assert f"/{name}/run.rrd" not in proc.stdout
