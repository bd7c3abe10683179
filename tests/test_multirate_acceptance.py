"""The acceptance catalog's verdicts with SUMO at 10 Hz (the default) equal those with
SUMO at the control rate (50 Hz): same status and the same failed metrics in every
scenario, and the same stop reason (SUMO test, through the command line)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from suite.bench.catalogs import with_defaults

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]


def _run(catalog: Path, out: Path) -> dict[str, tuple[str, tuple[str, ...], str]]:
    proc = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--jobs", "2", "--no-log"], cwd=ROOT, capture_output=True,
                          text=True, timeout=1800, check=False)
    assert proc.returncode in (0, 1), proc.stderr[-3000:]
    verdicts = {}
    for run_json in sorted(out.glob("*/run.json")):
        info = json.loads(run_json.read_text())
        v = info["verdict"]
        verdicts[run_json.parent.name] = (
            v["status"], tuple(sorted(f["metric"] for f in v["failures"])),
            info["outcome"]["stop_reason"].split(" at t =")[0])
    return verdicts


def test_acceptance_verdicts_at_10_hz_equal_50_hz(tmp_path: Path) -> None:
    source = (ROOT / "catalogs" / "two_loop_acceptance.toml").read_text()
    fast, slow = tmp_path / "acceptance.toml", tmp_path / "acceptance_50hz.toml"
    fast.write_text(source)
    slow.write_text(with_defaults(source, sumo_step_s=0.02))
    ten_hz, fifty_hz = _run(fast, tmp_path / "10hz"), _run(slow, tmp_path / "50hz")
    assert len(ten_hz) == 21 and set(ten_hz) == set(fifty_hz)
    assert ten_hz == fifty_hz
