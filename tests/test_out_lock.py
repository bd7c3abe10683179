"""One writer per output directory (suite.exec.out_lock): a second ``hwyeval run`` into
an --out another one is writing to exits 2 having written nothing, and the lock goes
with its holder."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from suite.exec.out_lock import OutDirBusy, lock_path, out_dir_lock

ROOT = Path(__file__).resolve().parents[1]
CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 20.0
step_s = 0.05
[[scenario]]
name = "slow_one"
net = "straight_2lane"
ego = { lane = 0, pos_m = 60.0, speed_mps = 25.0 }
"""


def test_a_held_lock_is_refused_and_released_with_its_holder(tmp_path: Path) -> None:
    out = tmp_path / "night"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from pathlib import Path; "
        "from suite.exec.out_lock import out_dir_lock\n"
        f"with out_dir_lock(Path({str(out)!r})):\n"
        "    print('held', flush=True); time.sleep(30)")],
        cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(OutDirBusy) as info:
            with out_dir_lock(out):
                pass
        assert str(holder.pid) in str(info.value)
    finally:
        holder.kill()
        holder.wait()
    with out_dir_lock(out) as path:  # the kernel dropped it with the process
        assert path == lock_path(out) and path.parent == tmp_path
    assert not out.exists()  # the lock lives beside the output, never in it


@pytest.mark.sumo
def test_a_second_run_into_the_same_out_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    catalog = tmp_path / "cat.toml"
    catalog.write_text(CATALOG)
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                              str(out), "--no-log"], cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60.0
        while not (out / "manifest.json").is_file() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert (out / "manifest.json").is_file()
        manifest = (out / "manifest.json").read_bytes()
        second = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                                 str(out), "--no-log", "--overwrite"], cwd=ROOT,
                                capture_output=True, text=True, timeout=120)
        assert second.returncode == 2, second.stdout + second.stderr
        assert (out / "manifest.json").read_bytes() == manifest
    finally:
        stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stdout + stderr
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "junit.xml", "manifest.json", "report-runs", "report.html", "results.csv",
        "slow_one", "summary.csv"]
