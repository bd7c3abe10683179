"""``--resume`` keeps a run only when what produced it is unchanged: the scenario, the
hwyeval sources, the plug-in controller's source and the run directory's files (real
runs in SUMO with the example bare-module plug-in)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from reports.record import TRACE, incomplete_files, load_run

pytestmark = [pytest.mark.sumo, pytest.mark.slow]
ROOT = Path(__file__).resolve().parents[1]
PLUGIN = ROOT / "examples" / "hwyeval_example_controller" / "pd_follow_module.py"
CATALOG = """
[defaults]
duration_s = 6.0
step_s = 0.05
[[scenario]]
name = "bare_stall"
net = "straight_3lane"
ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 220.0 } ]
controller = "pd_follow_bare"
[[scenario]]
name = "builtin_free"
net = "straight_2lane"
ego = { lane = 0, pos_m = 60.0, speed_mps = 25.0 }
controller = "lane_keep"
"""


def run(catalog: Path, out: Path, plugin: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--no-log", "--jobs", "1", "--plugin", str(plugin),
                           *extra], cwd=ROOT, capture_output=True, text=True, timeout=600)


def wall(out: Path, name: str) -> float:
    return load_run(out / name, trace=False, neighbours=False, arrays=False,
                    series=False).outcome.wall_s


@pytest.fixture()
def night(tmp_path: Path) -> tuple[Path, Path, Path]:
    catalog = tmp_path / "cat.toml"
    catalog.write_text(CATALOG)
    plugin = tmp_path / "pd_follow_module.py"
    shutil.copy(PLUGIN, plugin)
    out = tmp_path / "out"
    first = run(catalog, out, plugin)
    assert first.returncode in (0, 1), first.stdout + first.stderr
    return catalog, plugin, out


def test_nothing_edited_keeps_everything(night: tuple[Path, Path, Path]) -> None:
    catalog, plugin, out = night
    before = {n: wall(out, n) for n in ("bare_stall", "builtin_free")}
    again = run(catalog, out, plugin, "--resume")
    assert again.returncode in (0, 1), again.stdout + again.stderr
    assert {n: wall(out, n) for n in before} == before  # neither ran again
    assert "[1/" not in again.stdout


def test_an_edited_plug_in_reruns_its_scenarios_as_a_fresh_run_would(
        night: tuple[Path, Path, Path], tmp_path: Path) -> None:
    catalog, plugin, out = night
    kept = wall(out, "builtin_free")
    # a one-line edit that changes the behaviour: a longer default time gap
    text = plugin.read_text()
    edited = text.replace('time_gap_s: float = param(1.6,', 'time_gap_s: float = param(2.4,')
    assert edited != text
    plugin.write_text(edited)
    again = run(catalog, out, plugin, "--resume")
    assert again.returncode in (0, 1), again.stdout + again.stderr
    assert wall(out, "builtin_free") == kept  # the built-in controller's run is kept
    fresh = tmp_path / "fresh"
    assert run(catalog, fresh, plugin).returncode in (0, 1)
    resumed = load_run(out / "bare_stall")
    clean = load_run(fresh / "bare_stall")
    assert resumed.info.controller_params == clean.info.controller_params
    assert resumed.info.controller_params["time_gap_s"] == 2.4
    assert resumed.status == clean.status
    a = pd.read_parquet(out / "bare_stall" / TRACE)
    b = pd.read_parquet(fresh / "bare_stall" / TRACE)
    pd.testing.assert_frame_equal(a.drop(columns=[c for c in a if c.endswith("_s") and
                                                  c != "t_s"]),
                                  b.drop(columns=[c for c in b if c.endswith("_s") and
                                                  c != "t_s"]))


def test_a_truncated_file_is_run_again_and_is_an_error_in_the_reports(
        night: tuple[Path, Path, Path]) -> None:
    catalog, plugin, out = night
    trace = out / "builtin_free" / TRACE
    trace.write_bytes(trace.read_bytes()[: trace.stat().st_size // 2])
    assert incomplete_files(out / "builtin_free")
    report = subprocess.run([sys.executable, "-m", "suite", "report", str(out)], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    assert report.returncode in (0, 1)
    results = pd.read_csv(out / "results.csv").set_index("scenario")
    assert results.loc["builtin_free", "status"] == "error"
    before = wall(out, "bare_stall")
    again = run(catalog, out, plugin, "--resume")
    assert again.returncode in (0, 1), again.stdout + again.stderr
    assert incomplete_files(out / "builtin_free", contents=True) == []
    assert wall(out, "bare_stall") == before
    results = pd.read_csv(out / "results.csv").set_index("scenario")
    assert results.loc["builtin_free", "status"] == "pass"
