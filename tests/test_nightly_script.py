"""docs/nightly.md's nightly job, run exactly as printed (the first ```sh block of the
page) over three nights of a small catalog in real SUMO runs: the first night has
nothing to compare against and passes; the second tightens a limit (labelled, does not
gate); the third swaps the stalled-car scenario's controller for one that runs into the
stalled car, and the job fails at ``compare`` (``set -e``). ``date`` is the only thing
replaced (a script earlier on PATH) so that the three nights get three days."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "nightly.md"
CATALOG = """
[catalog]
name = "nightly"

[defaults]
duration_s = 8.0
step_s = 0.02
net = "straight_3lane"

[[scenario]]
name = "free_lane_keep"
ego = {{ lane = 0, pos_m = 60.0, speed_mps = 25.0 }}
controller = "lane_keep"
duration_s = 3.0

[[scenario]]
name = "stall"
ego = {{ lane = 1, pos_m = 60.0, speed_mps = 25.0 }}
stalled = [ {{ lane = 1, pos_m = 220.0 }} ]
controller = "{controller}"
{criteria}
"""
# (the day, the stalled-car scenario's controller and criteria, the job's exit code)
NIGHTS = (("2026-11-01", "two_loop", "", 0),
          ("2026-11-02", "two_loop", "criteria = { min_ttc_s = 1.2 }", 0),
          ("2026-11-03", "lane_keep", "criteria = { min_ttc_s = 1.2 }", 1))


def nightly_script() -> str:
    """The first ```sh block of docs/nightly.md, as printed."""
    found = re.search(r"^```sh\n(.*?)^```", DOC.read_text(encoding="utf-8"), re.S | re.M)
    assert found is not None, f"{DOC}: no ```sh block"
    return found.group(1)


def test_the_nightly_script_over_three_nights(tmp_path: Path) -> None:
    work = tmp_path / "ci"
    (work / "catalogs").mkdir(parents=True)
    script = work / "nightly.sh"
    script.write_text(nightly_script())
    shims = tmp_path / "bin"
    shims.mkdir()
    date = shims / "date"
    env = dict(os.environ, PATH=f"{shims}:{Path(sys.executable).parent}:{os.environ['PATH']}")
    db = work / "runs" / "history.duckdb"
    for k, (day, controller, criteria, expected) in enumerate(NIGHTS, start=1):
        (work / "catalogs" / "nightly.toml").write_text(
            CATALOG.format(controller=controller, criteria=criteria))
        date.write_text(f"#!/bin/sh\necho {day}\n")
        date.chmod(0o755)
        proc = subprocess.run(["sh", str(script)], cwd=work, env=env, capture_output=True,
                              text=True, timeout=900)
        assert proc.returncode == expected, f"night {k}:\n{proc.stdout}\n{proc.stderr}"
        assert (work / "runs" / day / "report.html").is_file()
        history = subprocess.run(
            [sys.executable, "-m", "suite", "history", str(db), "--json"], cwd=ROOT,
            capture_output=True, text=True, timeout=300)
        assert history.returncode == 0, history.stderr
        doc = json.loads(history.stdout)
        assert len(doc["nights"]) == k and doc["catalog"] == "nightly"
    # the page was written after nights 1 and 2; the third stopped at compare
    page = (work / "runs" / "trends" / "history.html").read_text()
    assert len(re.findall(r'<rect class="rate', page)) == 2
    compared = (work / "runs" / "2026-11-03.compare" / "compare.csv").read_text()
    assert "behaviour_regression" in compared and "sut_changed" in compared
    second = (work / "runs" / "2026-11-02.compare" / "compare.csv").read_text()
    assert "limits_changed" in second and "behaviour_regression" not in second
    # neither a criteria edit nor a controller swap is a change of the test
    assert "test_changed" not in second and "test_changed" not in compared
    (stall,) = [s for s in doc["scenarios"] if s["scenario"] == "stall"]
    assert stall["changes"] == ["", "limits", "sut"]
    assert stall["failing_now"] and stall["first_failures"]
