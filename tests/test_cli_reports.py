"""`hwyeval report`, `compare` and `view` through the real CLI (synthetic run directories)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

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


@pytest.mark.slow
def test_compare_gate_exit_codes(tmp_path: Path) -> None:
    base = tmp_path / "base"
    sr.make_catalog(base)
    same = tmp_path / "same"
    shutil.copytree(base, same)
    ok = hwyeval("compare", str(base), str(same), "--out", str(tmp_path / "cmp_same"))
    assert ok.returncode == 0, ok.stdout + ok.stderr
    slower = tmp_path / "slower"
    sr.make_catalog(slower, speedup=3.0)
    # timing alone warns (base → new with units) and passes ...
    warn = hwyeval("compare", str(base), str(slower), "--out", str(tmp_path / "cmp_slow"))
    assert warn.returncode == 0, warn.stdout + warn.stderr
    assert "step_ms_p99" in warn.stdout and "median ×3.00" in warn.stdout
    assert " ms → " in warn.stdout and "OK: no behaviour regression" in warn.stdout
    assert (tmp_path / "cmp_slow" / "compare.csv").is_file()
    assert (tmp_path / "cmp_slow" / "compare.html").is_file()
    # ... and fails with the timing gate
    gated = hwyeval("compare", str(base), str(slower), "--timing-gate", "--out",
                    str(tmp_path / "cmp_gate"))
    assert gated.returncode == 1, gated.stdout + gated.stderr
    assert "FAIL: timing slower" in gated.stdout
    js = hwyeval("compare", str(base), str(slower), "--json", "--out", str(tmp_path / "cmp_j"))
    doc = json.loads(js.stdout)
    assert doc["exit_code"] == 0 and doc["warnings"] and not doc["regressions"]


def test_compare_against_an_empty_baseline_exits_2(tmp_path: Path) -> None:
    empty = tmp_path / "EMPTY"
    empty.mkdir()
    new = sr.make_catalog(tmp_path / "NEW")
    proc = hwyeval("compare", str(empty), str(new))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "holds no run directory" in proc.stderr and "Traceback" not in proc.stderr
    missing = hwyeval("compare", str(tmp_path / "nowhere"), str(new))
    assert missing.returncode == 2 and "nowhere" in missing.stderr


def test_view_without_display_prints_a_portable_command(tmp_path: Path) -> None:
    out = tmp_path / "runs"
    sr.make_catalog(out)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run([sys.executable, "-m", "suite", "view", "runs", "--failed"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          env=dict(env, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 0, proc.stderr
    command = next(li.strip() for li in proc.stdout.splitlines()
                   if li.strip().startswith("rerun "))
    statuses = {d.name: run_status(d) for d in out.iterdir() if (d / "run.json").is_file()}
    failed = [name for name, status in statuses.items() if status != "pass"]
    passed = [name for name, status in statuses.items() if status == "pass"]
    assert failed and passed
    # every non-passing run's log by a path relative to here, no passing one, and
    # nothing of this host: no interpreter path, no absolute path
    assert sorted(command.split()[1:]) == sorted(f"runs/{name}/run.rrd" for name in failed)
    assert str(tmp_path) not in proc.stdout and sys.executable not in proc.stdout
    assert "--web" in proc.stdout


def test_view_of_a_missing_path_exits_2(tmp_path: Path) -> None:
    proc = hwyeval("view", str(tmp_path / "nowhere"))
    assert proc.returncode == 2 and "nowhere" in proc.stderr and "Traceback" not in proc.stderr


def test_view_web_serves_rerun_web_viewer(tmp_path: Path) -> None:
    import socket
    import urllib.request

    out = tmp_path / "runs"
    sr.make_catalog(out)
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    proc = subprocess.Popen([sys.executable, "-m", "suite", "view", str(out / "rear_end__ctrl_a"),
                             "--web", "--port", str(port)], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        page = ""
        for _ in range(60):
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2) as resp:
                    page = resp.read().decode()
                break
            except OSError:
                time.sleep(0.5)
        assert "Rerun" in page and "web viewer" in page.lower()
    finally:
        proc.terminate()
        text = proc.communicate(timeout=30)[0]
    assert f"http://localhost:{port}/?url=rerun" in text
