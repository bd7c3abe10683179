"""``hwyeval search`` end to end in SUMO: found.toml replays with the same status and
robustness; Ctrl-C then --resume ends as the uninterrupted search; the search's
directory is a normal output (report, compare); a planted weakness is found."""

from __future__ import annotations

import csv
import math
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.sumo

HWYEVAL = str(Path(sys.executable).parent / "hwyeval")
PLANTED = Path(__file__).resolve().parents[1] / "catalogs" / "search_planted.toml"

CATALOG = """
[defaults]
controller = "two_loop"
duration_s = 8.0
step_s = 0.02
[[scenario]]
name = "stall_close"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 200.0 } ]
[scenario.search]
"stalled.0.pos_m" = { min = 70.0, max = 200.0 }
"ego.speed_mps" = { min = 18.0, max = 33.0 }
"""


def hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([HWYEVAL, *args], capture_output=True, text=True, timeout=600)


def rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def catalog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("search") / "stall.toml"
    path.write_text(CATALOG)
    return path


@pytest.fixture(scope="module")
def searched(catalog: Path) -> Path:
    out = catalog.parent / "out"
    done = hwyeval("search", str(catalog), "--out", str(out), "--budget", "6", "--jobs", "2",
                   "--no-log", "--seed", "0")
    assert done.returncode == 1, done.stdout + done.stderr  # a failure was found
    return out


@pytest.mark.slow
def test_found_toml_replays_with_the_same_status_and_robustness(searched: Path) -> None:
    found = [r for r in rows(searched / "search.csv") if r["found"]]
    assert found
    replay = searched.parent / "replay"
    done = hwyeval("run", str(searched / "found.toml"), "--out", str(replay), "--no-log",
                   "--jobs", "1")
    assert done.returncode == 1, done.stdout + done.stderr
    results = {r["scenario"]: r for r in rows(replay / "results.csv")}
    assert set(results) == {r["found"] for r in found}
    for r in found:
        again = results[r["found"]]
        assert again["status"] == r["status"] == "fail"
        assert math.isclose(float(again["robustness"]), float(r["robustness"]), rel_tol=0,
                            abs_tol=1e-6)
        assert float(again["robustness"]) < 0.0


@pytest.mark.slow
def test_every_trial_is_a_run_directory_the_reports_read(searched: Path) -> None:
    trials = [r for r in rows(searched / "search.csv") if r["kind"] == "trial"]
    assert len(trials) == 6
    results = {r["run"]: r for r in rows(searched / "results.csv")}
    for t in trials:
        assert (searched / t["run"] / "run.json").is_file()
        assert results[t["run"]]["status"] == t["status"]
        assert math.isclose(float(results[t["run"]]["robustness"]), float(t["robustness"]))
    assert (searched / "search.html").is_file() and (searched / "report.html").is_file()
    assert hwyeval("report", str(searched)).returncode == 0
    base = searched.parent / "base"
    shutil.copytree(searched, base)
    assert hwyeval("compare", str(base), str(searched),
                   "--out", str(searched.parent / "cmp")).returncode == 0


@pytest.mark.slow
def test_resume_refuses_other_settings(searched: Path, catalog: Path) -> None:
    done = hwyeval("search", str(catalog), "--out", str(searched), "--budget", "6",
                   "--jobs", "2", "--seed", "1", "--resume", "--no-log")
    assert done.returncode == 2
    done = hwyeval("search", str(catalog), "--out", str(searched), "--budget", "6")
    assert done.returncode == 2  # not empty, neither --resume nor --overwrite


def _key(path: Path) -> list[tuple[str, ...]]:
    return [tuple(r.values()) for r in rows(path)]


@pytest.mark.slow
def test_ctrl_c_then_resume_equals_the_uninterrupted_search(catalog: Path) -> None:
    common = ["--budget", "6", "--jobs", "1", "--no-log", "--seed", "4", "--no-shrink"]
    whole = catalog.parent / "whole"
    assert hwyeval("search", str(catalog), "--out", str(whole), *common).returncode in (0, 1)
    cut = catalog.parent / "cut"
    proc = subprocess.Popen([HWYEVAL, "search", str(catalog), "--out", str(cut), *common],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith("[stall_close 3/"):
            proc.send_signal(signal.SIGINT)
            break
    proc.stdout.read()
    assert proc.wait(timeout=120) == 130
    assert len([r for r in rows(cut / "search.csv") if r["kind"] == "trial"]) < 6
    again = hwyeval("search", str(catalog), "--out", str(cut), *common, "--resume")
    assert again.returncode in (0, 1), again.stdout + again.stderr
    assert _key(cut / "search.csv") == _key(whole / "search.csv")


@pytest.mark.slow
def test_a_planted_weakness_is_found_where_the_nominal_catalog_passes(tmp_path: Path) -> None:
    nominal = hwyeval("run", str(PLANTED), "--out", str(tmp_path / "nominal"), "--no-log")
    assert nominal.returncode == 0, nominal.stdout + nominal.stderr
    out = tmp_path / "search"
    done = hwyeval("search", str(PLANTED), "--out", str(out), "--budget", "40", "--no-log",
                   "--no-shrink")
    assert done.returncode == 1, done.stdout + done.stderr
    failed: dict[str, int] = {}
    for r in rows(out / "search.csv"):
        failed[r["family"]] = failed.get(r["family"], 0) + (r["status"] == "fail")
    assert failed["stall_ahead"] == 0
    assert failed["stall_ahead_slow_lateral"] >= 1
