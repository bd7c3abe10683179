"""Forty nights of a small catalog from real SUMO runs, in a real DuckDB history, with
known answers: a controller parameter change at night 20 makes ``stall_evade`` fail
from then on, and ``curve_lane_keep`` is seeded flaky (it fails on nights 8 and 31
with the same scenario hash and revision as its neighbours).

To keep it fast each distinct configuration is run once for real (``hwyeval run
--no-log --jobs 1``): the catalog before the change, after it (``lateral`` rate
options of ``two_loop``: the evasive move jerks beyond ``max_abs_jerk_mps3``), and
the flaky scenario's failing variant (a tight ``max_abs_lat_acc_mps2``). The forty
nights are copies of those output directories with a rewritten manifest (night id,
start time a day apart, git revision: a new one every 4 nights and one at night 20);
the flaky variant's copies carry the passing variant's scenario hash, as a
non-deterministic run would. The trend page is checked in headless Chromium.
"""

from __future__ import annotations

import datetime as dt
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from browser import chromium, console_errors, needs_chromium, screenshot

from reports.history import load_trends
from reports.manifest import catalog_identity

pytestmark = [pytest.mark.sumo, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
T0 = dt.datetime(2026, 10, 1, 2, 0, tzinfo=dt.UTC)
N_NIGHTS, CHANGE_NIGHT, FLAKY_NIGHTS = 40, 20, (8, 31)

COMMON = """
[defaults]
controller = "two_loop"
duration_s = 10.0
step_s = 0.02
seed = 0

[[scenario]]
name = "free_lane_keep"
net = "straight_2lane"
ego = { lane = 0, pos_m = 60.0, speed_mps = 25.0, target_speed_mps = 25.0 }
controller = { name = "lane_keep" }
duration_s = 8.0

[[scenario]]
name = "curve_lane_keep"
net = "curve_2lane"
ego = { lane = 0, pos_m = 300.0, speed_mps = 22.0, target_speed_mps = 22.0 }
controller = { name = "lane_keep" }
duration_s = 8.0
"""
STALL = """
[[scenario]]
name = "stall_evade"
net = "straight_3lane"
ego = { lane = 1, pos_m = 60.0, speed_mps = 25.0, target_speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 280.0 } ]
"""
CHANGED = ('controller = { name = "two_loop", lateral = { rate_mps = 4.0, heading_rad = 0.4, '
           'evasive_rate_mps = 5.0, evasive_heading_rad = 0.5, max_lat_acc_mps2 = 9.0 } }\n')
FLAKY_BAD = """
[defaults]
duration_s = 8.0
step_s = 0.02
seed = 0

[[scenario]]
name = "curve_lane_keep"
net = "curve_2lane"
ego = { lane = 0, pos_m = 300.0, speed_mps = 22.0, target_speed_mps = 22.0 }
controller = { name = "lane_keep" }
criteria = { max_abs_lat_acc_mps2 = 0.01 }
"""


def hwyeval(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)


def revision(k: int) -> str:
    """Night k's git revision: a new one every 4 nights, and a new one at the change."""
    group = (k - 1) // 4 if k < CHANGE_NIGHT else 100 + (k - CHANGE_NIGHT) // 4
    return f"{group:02x}" * 20


def started(k: int) -> str:
    return (T0 + dt.timedelta(days=k - 1)).isoformat()


def night_id(k: int) -> str:
    """The first and last night are added with --night-id, the others get the default
    id, ``<catalog name>@<started>``."""
    return f"nightly-{k:02d}" if k in (1, N_NIGHTS) else f"nightly@{started(k)}"


def _set_hash(run_dir: Path, content_sha256: str) -> None:
    path = run_dir / "run.json"
    data = json.loads(path.read_text())
    data["info"]["scenario_spec"]["content_sha256"] = content_sha256
    path.write_text(json.dumps(data))


def _hash_of(run_dir: Path) -> str:
    return str(json.loads((run_dir / "run.json").read_text())["info"]["scenario_spec"]
               ["content_sha256"])


def make_night(k: int, source: Path, flaky_bad: Path | None, dest: Path, catalog: str) -> Path:
    shutil.copytree(source, dest)
    if flaky_bad is not None:
        good_hash = _hash_of(dest / "curve_lane_keep")
        shutil.rmtree(dest / "curve_lane_keep")
        shutil.copytree(flaky_bad / "curve_lane_keep", dest / "curve_lane_keep")
        _set_hash(dest / "curve_lane_keep", good_hash)
    manifest = json.loads((dest / "manifest.json").read_text())
    identity = catalog_identity(Path(catalog))  # as run from that catalog file
    manifest.update(catalog=catalog, catalog_name="nightly", started=started(k),
                    finished=started(k), catalog_id=identity.name,
                    catalog_origin=identity.origin)
    manifest["provenance"].update(git_sha=revision(k), git_dirty=False)
    (dest / "manifest.json").write_text(json.dumps(manifest))
    return dest


@pytest.fixture(scope="module")
def nights(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp("history40")
    (tmp / "before.toml").write_text(COMMON + STALL)
    (tmp / "after.toml").write_text(COMMON + STALL + CHANGED)
    (tmp / "flaky_bad.toml").write_text(FLAKY_BAD)
    runs = tmp / "runs"
    before = hwyeval("run", str(tmp / "before.toml"), "--out", str(runs / "before"),
                     "--no-log", "--jobs", "1")
    assert before.returncode == 0, before.stdout + before.stderr
    # the changed catalog fails a scenario: --no-fail exits 0 and --history adds the night
    after = hwyeval("run", str(tmp / "after.toml"), "--out", str(runs / "after"), "--no-log",
                    "--jobs", "1", "--no-fail", "--history", str(tmp / "single.duckdb"))
    assert after.returncode == 0, after.stdout + after.stderr
    bad = hwyeval("run", str(tmp / "flaky_bad.toml"), "--out", str(runs / "flaky_bad"),
                  "--no-log", "--jobs", "1")
    assert bad.returncode == 1, bad.stdout + bad.stderr
    catalog = str(ROOT / "catalogs" / "nightly.toml")
    dirs = [make_night(k, runs / ("before" if k < CHANGE_NIGHT else "after"),
                       runs / "flaky_bad" if k in FLAKY_NIGHTS else None,
                       tmp / "nights" / f"night{k:02d}", catalog) for k in range(1, N_NIGHTS + 1)]
    db = tmp / "history.duckdb"
    for k, d in enumerate(dirs, start=1):
        proc = hwyeval("history", "add", str(db), str(d), "--night-id", night_id(k)) \
            if k in (1, N_NIGHTS) else None
        if proc is not None:
            assert proc.returncode == 0, proc.stderr
    added = hwyeval("history", "add", str(db), *map(str, dirs[1:-1]))
    assert added.returncode == 0, added.stderr
    return {"db": db, "dirs": dirs, "tmp": tmp, "single": tmp / "single.duckdb"}


def test_the_real_runs_give_the_injected_outcomes(nights: dict[str, Any]) -> None:
    single = hwyeval("history", str(nights["single"]), "--sql",
                     "SELECT scenario, status FROM runs ORDER BY scenario")
    assert single.returncode == 0, single.stderr
    assert single.stdout.split("\n")[1:4] == ["curve_lane_keep\tpass", "free_lane_keep\tpass",
                                              "stall_evade\tfail"]


def test_a_night_that_cannot_be_added_exits_2_and_keeps_the_run(nights: dict[str, Any]
                                                                ) -> None:
    tmp = nights["tmp"]
    not_a_db = tmp / "a_directory"
    not_a_db.mkdir()
    out = tmp / "runs" / "kept"
    proc = hwyeval("run", str(tmp / "flaky_bad.toml"), "--out", str(out), "--no-log",
                   "--jobs", "1", "--no-fail", "--history", str(not_a_db))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr
    assert (out / "results.csv").is_file() and (out / "curve_lane_keep" / "run.json").is_file()
    db = tmp / "retry.duckdb"
    assert hwyeval("history", "add", str(db), str(out)).returncode == 0


def test_first_failing_night_revision_and_flaky_known_answers(nights: dict[str, Any]) -> None:
    proc = hwyeval("history", str(nights["db"]), "--json", "--metric", "max_abs_jerk_mps3")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert [n["night_id"] for n in data["nights"]] == [night_id(k)
                                                       for k in range(1, N_NIGHTS + 1)]
    by = {s["scenario"]: s for s in data["scenarios"]}
    assert [s["scenario"] for s in data["scenarios"]] == ["stall_evade", "curve_lane_keep",
                                                          "free_lane_keep"]
    stall = by["stall_evade"]
    assert stall["status_now"] == "fail" and not stall["flaky"]
    assert stall["first_failing_night"] == night_id(CHANGE_NIGHT)
    assert stall["first_failing_revision"] == revision(CHANGE_NIGHT)
    assert stall["last_good_night"] == night_id(CHANGE_NIGHT - 1)
    assert stall["last_good_revision"] == revision(CHANGE_NIGHT - 1)
    assert stall["alternations"] == 1
    assert all(v > stall["metric_limit"] for v in stall["metric_values"][CHANGE_NIGHT - 1:])
    assert all(v < stall["metric_limit"] for v in stall["metric_values"][:CHANGE_NIGHT - 1])
    curve = by["curve_lane_keep"]
    assert curve["flaky"] and curve["status_now"] == "pass" and curve["alternations"] == 4
    assert [k + 1 for k, s in enumerate(curve["statuses"]) if s != "pass"] == list(FLAKY_NIGHTS)
    free = by["free_lane_keep"]
    assert free["status_now"] == "pass" and not free["flaky"]
    assert set(free["statuses"]) == {"pass"}
    rates = [n["pass_rate"] for n in data["nights"]]
    for k, rate in enumerate(rates, start=1):
        passed = 3 - (k >= CHANGE_NIGHT) - (k in FLAKY_NIGHTS)
        assert rate == pytest.approx(passed / 3), k
    # a window that starts after the flaky nights: nothing flaky, still failing since 20
    late = load_trends(nights["db"], window=8)
    assert not any(s.flaky for s in late.scenarios)
    assert late.scenarios[0].scenario == "stall_evade"
    assert late.scenarios[0].first_failing_night == night_id(N_NIGHTS - 7)


def test_compare_against_the_last_night_and_the_last_pass(nights: dict[str, Any]) -> None:
    new = str(nights["dirs"][-1])
    last = hwyeval("compare", "--history", str(nights["db"]), new, "--json")
    assert last.returncode == 0, last.stderr  # night 39 behaved the same
    assert Path(json.loads(last.stdout)["base_dir"]) == nights["dirs"][-2]
    good = hwyeval("compare", "--history", str(nights["db"]), new, "--baseline", "last-pass",
                   "--json")
    # against night 19, the last all-pass night: stall_evade now fails and its
    # controller's options changed: the system under test, which is what the gate is
    # for (its test is the same), so it gates and says what changed
    assert good.returncode == 1, good.stderr
    result = json.loads(good.stdout)
    assert Path(result["base_dir"]) == nights["dirs"][CHANGE_NIGHT - 2]
    kinds = {(r["kind"], r["scenario"]) for r in result["rows"]}
    assert {("sut_changed", "stall_evade"), ("behaviour_regression", "stall_evade")} <= kinds
    assert not any(r["kind"] == "test_changed" for r in result["rows"])
    assert {r["scenario"] for r in result["rows"] if r["gate"]} == {"stall_evade"}


@pytest.fixture()
def driver() -> Any:
    yield from chromium(1400, 1100)


@needs_chromium[0]
@needs_chromium[1]
def test_the_trend_page_in_chromium(nights: dict[str, Any], driver: Any) -> None:
    from selenium.webdriver.common.by import By

    out = nights["tmp"] / "page"
    proc = hwyeval("history", str(nights["db"]), "--out", str(out), "--metric",
                   "max_abs_jerk_mps3")
    assert proc.returncode == 0, proc.stderr
    page = out / "history.html"
    text = page.read_text()
    assert "http://" not in text and "https://" not in text and "<script" not in text
    driver.get(page.resolve().as_uri())
    assert console_errors(driver) == []
    resources = driver.execute_script(
        "return performance.getEntriesByType('resource').map(function(e){return e.name;})")
    assert resources == []
    strip = driver.find_element(By.ID, "status-strip")
    assert strip.is_displayed()
    rows = strip.find_elements(By.CSS_SELECTOR, "tbody tr")
    assert [r.get_attribute("data-scenario") for r in rows] == [
        "stall_evade", "curve_lane_keep", "free_lane_keep"]
    assert rows[0].location["y"] + rows[0].size["height"] < driver.execute_script(
        "return window.innerHeight")
    # the failing row's strip: pass until night 19, fail from 20, a cell per night, each
    # linked to that night's run page; an S over night 20: its controller changed
    cells = rows[0].find_elements(By.CSS_SELECTOR, "svg.strip rect")
    assert [c.get_attribute("class") for c in cells] == (
        ["pass"] * (CHANGE_NIGHT - 1) + ["fail"] * (N_NIGHTS - CHANGE_NIGHT + 1))
    assert len(rows[0].find_elements(By.CSS_SELECTOR, "svg.strip a")) == N_NIGHTS
    marks = rows[0].find_elements(By.CSS_SELECTOR, "svg.strip text.chg")
    assert [m.text for m in marks] == ["S"]
    assert rows[0].find_elements(By.CSS_SELECTOR, "svg.sparkline line.limit")
    assert rows[1].find_elements(By.CSS_SELECTOR, ".badge.flaky")
    failing = driver.find_element(By.ID, "failing-table").text
    assert night_id(CHANGE_NIGHT) in failing and revision(CHANGE_NIGHT)[:10] in failing
    assert len(driver.find_elements(By.CSS_SELECTOR, "#pass-rate-chart rect")) == N_NIGHTS
    screenshot(driver, "history_trend_page")
