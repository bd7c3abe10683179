"""results.csv, summary.csv, junit.xml and report.html from synthetic run directories,
rendered from the stored verdicts and series."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import synthetic_runs as sr

from reports import write_reports
from reports.html import MAX_POINTS, decimate
from reports.metrics import REQUIRED_METRICS
from reports.record import SERIES, TRACE, Failure, MetricValue, load_run, write_run_json
from reports.tables import LEAD_COLUMNS, scenario_family

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def catalog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = sr.make_catalog(tmp_path_factory.mktemp("catalog"))
    write_reports(out)
    return out


def test_results_csv(catalog: Path) -> None:
    df = pd.read_csv(catalog / "results.csv")
    assert list(df.columns[: len(LEAD_COLUMNS)]) == list(LEAD_COLUMNS)
    for name in REQUIRED_METRICS:
        assert name in df.columns, name
    cols = list(df.columns)
    assert cols.index("failed_criteria") > cols.index("realtime_factor")
    assert "family" in cols
    assert len(df) == 12
    by = {(r.scenario, r.controller): r for r in df.itertuples()}
    assert by[("sharp_curve", "ctrl_a")].status == "fail"
    assert by[("sharp_curve", "ctrl_a")].failed_criteria == "max_abs_lat_acc_mps2=6.667>4.89"
    assert by[("sharp_curve", "ctrl_b")].status == "pass"
    rear = by[("rear_end", "ctrl_a")]
    assert rear.status == "fail" and rear.collision == 1.0
    assert "at_fault_collisions=1>0" in rear.failed_criteria.split(";")
    assert by[("crash_case", "ctrl_b")].status == "error"
    assert by[("crash_case", "ctrl_b")].run == "crash_case__ctrl_b"
    assert by[("slow_case", "ctrl_b")].status == "timeout"
    assert by[("slow_case", "ctrl_b")].failed_criteria == "steps=0<1"
    assert by[("cruise_straight", "ctrl_a")].family == "cruise"
    assert by[("cruise_straight", "ctrl_a")].wall_s == 4.0
    assert by[("cruise_straight", "ctrl_a")].progress_m == pytest.approx(399.0)


def test_summary_csv(catalog: Path) -> None:
    df = pd.read_csv(catalog / "summary.csv")
    row = df[(df.controller == "ctrl_b") & (df.family == "ALL")].iloc[0]
    assert (row.runs, row["pass"], row.fail, row.error, row.timeout) == (7, 4, 1, 1, 1)
    assert row.pass_rate == pytest.approx(4 / 7)
    row_a = df[(df.controller == "ctrl_a") & (df.family == "ALL")].iloc[0]
    assert (row_a.runs, row_a["pass"], row_a.fail) == (5, 3, 2)
    assert row_a.sum_collision == 1.0
    assert row_a.max_max_abs_lat_acc_mps2 == pytest.approx(20.0 ** 2 / 60.0)
    assert 1.0 < row_a.step_ms_p50 < row_a.step_ms_p99 < 20.0
    curve = df[(df.controller == "ctrl_a") & (df.family == "curve")].iloc[0]
    assert (curve.runs, curve.fail, curve.pass_rate) == (1, 1, 0.0)


def test_junit_xml(catalog: Path) -> None:
    root = ET.parse(catalog / "junit.xml").getroot()
    assert root.tag == "testsuites"
    assert (root.get("tests"), root.get("failures"), root.get("errors")) == ("12", "3", "2")
    cases = {(c.get("classname"), c.get("name")): c for c in root.iter("testcase")}
    assert len(cases) == 12
    curve = cases[("ctrl_a.curve", "sharp_curve")]
    failure = curve.find("failure")
    assert failure is not None and "max_abs_lat_acc_mps2=6.667>4.89" in failure.get("message", "")
    assert curve.get("time") == "2.000"
    assert cases[("ctrl_b.curve", "sharp_curve")].find("failure") is None
    rear = cases[("ctrl_a.cut_in", "rear_end")].find("failure")
    assert rear is not None
    # where it happened: the first of the 5 colliding steps of 80 (t = 3.8 s)
    assert "at_fault_collisions=1>0 (t=3.80 s, step 75)" in (rear.text or "").splitlines()
    crash = cases[("ctrl_b.cruise", "crash_case")].find("error")
    assert crash is not None and crash.get("type") == "error"
    assert "Traceback" in (crash.text or "") and '<&> "quoted"' in (crash.text or "")
    timeout = cases[("ctrl_b.cruise", "slow_case")].find("error")
    assert timeout is not None and timeout.get("type") == "timeout"
    for suite in root.iter("testsuite"):
        cases_in = suite.findall("testcase")
        assert int(suite.get("tests", "-1")) == len(cases_in)
        assert int(suite.get("failures", "-1")) == sum(c.find("failure") is not None
                                                       for c in cases_in)


def test_reports_render_the_stored_verdict_not_the_trace(tmp_path: Path) -> None:
    """A run whose trace passes but whose stored verdict says it failed is reported as
    failed, with the stored failure, value and location: nothing re-evaluates."""
    out = sr.make_catalog(tmp_path / "c", controllers=("ctrl_a",))
    run_dir = out / "cruise_straight__ctrl_a"
    record = load_run(run_dir)
    assert record.verdict is not None and record.verdict.status == "pass"
    stored = Failure(criterion="max_abs_lat_acc_mps2", metric="max_abs_lat_acc_mps2",
                     value=9.876, limit=4.89, bound="max", unit="m/s^2", step=123,
                     t_s=float(record.trace.t_s[123]))
    metrics = tuple(dataclasses.replace(m, value=9.876) if m.name == "max_abs_lat_acc_mps2"
                    else m for m in record.verdict.metrics)
    metrics += (MetricValue(name="stored_only_metric", value=42.0, unit="-", kind="health"),)
    record.verdict = dataclasses.replace(record.verdict, status="fail", metrics=metrics,
                                         failures=(stored,))
    write_run_json(record, run_dir)
    paths = write_reports(out)
    row = pd.read_csv(paths.results_csv).set_index("run").loc["cruise_straight__ctrl_a"]
    assert row.status == "fail"
    assert row.failed_criteria == "max_abs_lat_acc_mps2=9.876>4.89"
    assert row.max_abs_lat_acc_mps2 == 9.876 and row.stored_only_metric == 42.0
    junit = paths.junit_xml.read_text()
    assert "max_abs_lat_acc_mps2=9.876&gt;4.89 (t=6.20 s, step 123)" in junit
    html = paths.report_html.read_text()
    assert "9.876 m/s² &gt; 4.89 m/s²" in html and "t = 6.20 s" in html  # failures list
    page = (paths.run_pages / "cruise_straight__ctrl_a.html").read_text()
    assert "max_abs_lat_acc_mps2 at t=6.2 s" in page  # the stored location, marked


def test_unreadable_run_directories_are_error_rows(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "c", controllers=("ctrl_a",))
    (out / "garbage__x").mkdir()
    (out / "garbage__x" / "run.json").write_text("{not json")
    wrong = out / "cruise_straight__ctrl_a" / "run.json"
    wrong.write_text(wrong.read_text().replace('"seed": 0', '"seed": "zero"'))
    (out / "lane_change_left__ctrl_a" / SERIES).unlink()
    (out / "sharp_curve__ctrl_a" / TRACE).write_bytes(b"not parquet")
    paths = write_reports(out)
    df = pd.read_csv(paths.results_csv).set_index("run")
    assert len(df) == 6
    for run in ("garbage__x", "cruise_straight__ctrl_a", "lane_change_left__ctrl_a",
                "sharp_curve__ctrl_a"):
        assert df.loc[run, "status"] == "error", run
        assert np.isnan(df.loc[run, "collision"]), run
    assert df.loc["rear_end__ctrl_a", "status"] == "fail"  # the others are intact
    assert df.loc["cruise_straight__ctrl_a", "scenario"] == "cruise_straight__ctrl_a"
    junit, html = paths.junit_xml.read_text(), paths.report_html.read_text()
    # each names the file: run.json lists the others with their size and checksum
    for reason in ("info.seed: expected an integer", "series.parquet: missing",
                   "trace.parquet: 11 bytes, run.json says", "a readable JSON file"):
        assert reason in junit and reason in html, reason


def test_html_is_self_contained(catalog: Path) -> None:
    text = (catalog / "report.html").read_text()
    assert not re.search(r"https?://", text)
    # links are relative: run pages and the runs' .rrd files, nothing outside
    for href in re.findall(r"""(?:src|href)\s*=\s*["']([^"']+)""", text):
        assert href.startswith(("#", "data:", "report-runs/")) or href.endswith("/run.rrd"), href
        assert not href.startswith(("/", "file:")), href
    assert "<script src" not in text and "@import" not in text and "url(" not in text
    assert 'id="scenario-matrix"' in text
    pages = sorted((catalog / "report-runs").glob("*.html"))
    assert len(pages) == 12
    for page in pages:
        html = page.read_text()
        assert not re.search(r"https?://", html)
        assert 'href="report.css"' in html and 'href="../report.html"' in html
    # failed ones come first in the failures list, an error first of all
    rows = re.findall(r'<tr class="(\w+)"><td><span class="badge', text)
    assert rows[:2] == ["error", "timeout"] and set(rows[2:]) == {"fail"}
    # the rear-end collision is marked at its stored step's time on its page
    assert "collision" in (catalog / "report-runs" / "rear_end__ctrl_a.html").read_text()
    assert "at t=3.8 s" in (catalog / "report-runs" / "rear_end__ctrl_a.html").read_text()


def test_controller_variants_are_columns_of_their_own(tmp_path: Path) -> None:
    out = tmp_path / "variants"
    for cost in ("J1", "J2"):
        for preview in (True, False):
            name = f"cmp__cost{cost.lower()}__preview{str(preview).lower()}"
            spec = {"sweep_values": {"controller.outer.cost": cost,
                                     "controller.inner.preview": preview}}
            sr.write_run(out / name, sr.straight_trace(5.0),
                         info=sr.base_info(name, "two_loop", family="cmp", scenario_spec=spec,
                                           controller_options={"outer": {"cost": cost,
                                                                         "horizon": 20},
                                                               "inner": {"preview": preview}}))
    paths = write_reports(out)
    html = paths.report_html.read_text()
    head = re.search(r'id="scenario-matrix"><thead><tr>(.*?)</tr>', html)
    assert head is not None
    columns = re.findall(r"<th>([^<]*)</th>", head.group(1))[1:]
    assert columns == sorted(f"two_loop inner.preview={p} outer.cost={c}"
                             for c in ("J1", "J2") for p in ("true", "false"))
    # one row holds the case for every variant (the sweep's controller parts dropped)
    matrix = html[html.index('id="scenario-matrix"'):]
    matrix = matrix[:matrix.index("</table>")]
    assert matrix.count("<tr><th>cmp</th>") == 1 and matrix.count('class="cell pass"') == 4
    results = pd.read_csv(paths.results_csv)
    assert set(results["variant"]) == set(columns)
    summary = pd.read_csv(paths.summary_csv)
    assert set(summary["variant"]) == set(columns)


def test_decimation_keeps_extremes() -> None:
    x = np.arange(100_000, dtype=float)
    y = np.sin(x / 5000.0)
    y[31_337] = 50.0
    xd, yd = decimate(x, y)
    assert len(xd) <= MAX_POINTS
    assert yd.max() == 50.0 and np.all(np.diff(xd) > 0)


@pytest.mark.slow
def test_html_size_for_a_large_catalog(tmp_path: Path) -> None:
    out = tmp_path / "big"
    for i in range(100):
        trace = sr.lane_change_trace(duration_s=30.0, dt_s=0.02, seed=i)
        nb = sr.lead_vehicle(trace, 40.0 + 25.0 * trace.t_s, 7.0, 25.0)
        sr.write_run(out / f"case_{i:03d}", trace, neighbours=nb,
                     info=sr.base_info(f"case_{i:03d}", "ctrl_a" if i % 2 else "ctrl_b",
                                       family=f"fam{i % 5}", step_s=0.02))
    paths = write_reports(out)
    assert paths.report_html.stat().st_size < 400_000
    pages = list(paths.run_pages.glob("*.html"))
    assert len(pages) == 100
    assert sum(p.stat().st_size for p in pages) < 100 * 30_000
    for page in pages[:10]:
        for m in re.finditer(r'<path d="([^"]+)"', page.read_text()):
            assert m.group(1).count("l") < MAX_POINTS + 1


def test_family_fallback() -> None:
    assert scenario_family("x", "anything") == "x"
    assert scenario_family("", "stall_mid_s3") == "stall_mid"
    assert scenario_family("", "stall__pos300") == "stall"


def test_importing_the_record_schema_loads_no_renderer() -> None:
    code = ("import sys, reports.record, reports.metrics; "
            "loaded = [m for m in ('reports.html', 'reports.junit', 'reports.compare', "
            "'reports.tables', 'reports.write') if m in sys.modules]; print(loaded)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def test_the_birdseye_names_the_vehicle_behind_each_ellipse(catalog: Path) -> None:
    pages = sorted((catalog / "report-runs").glob("stalled_pass_left__*.html"))
    assert pages
    page = pages[0].read_text()
    found = re.findall(r'<polygon [^>]*data-vehicle="([^"]*)"><title>obstacle ellipse( of '
                       r'[^ ]+)? at', page)
    assert found and all(vid == "stalled0" and of == " of stalled0" for vid, of in found)
