"""results.csv, summary.csv, junit.xml and report.html from synthetic run directories."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import synthetic_runs as sr

from reports import write_reports
from reports.html import MAX_POINTS, decimate
from reports.metrics import REQUIRED_METRICS
from reports.tables import LEAD_COLUMNS, scenario_family


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
    assert "collision=1>0" in rear.failed_criteria.split(";")
    assert by[("crash_case", "ctrl_b")].status == "error"
    assert by[("crash_case", "ctrl_b")].run == "crash_case__ctrl_b"
    assert by[("slow_case", "ctrl_b")].status == "timeout"
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


def test_criteria_override_rejudges(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "c", controllers=("ctrl_a",))
    write_reports(out, criteria_overrides={"max_abs_lat_acc_mps2": 8.0})
    df = pd.read_csv(out / "results.csv")
    assert df.set_index("scenario").loc["sharp_curve", "status"] == "pass"


def test_broken_run_is_an_error_row(tmp_path: Path) -> None:
    out = sr.make_catalog(tmp_path / "c", controllers=("ctrl_a",))
    meta_path = out / "cruise_straight__ctrl_a" / "run.json"
    meta = json.loads(meta_path.read_text())
    meta["criteria"] = {"no_such_limit": 1.0}
    meta_path.write_text(json.dumps(meta))
    (tmp_path / "c" / "garbage__x").mkdir()
    (tmp_path / "c" / "garbage__x" / "run.json").write_text("{not json")
    paths = write_reports(out)
    df = pd.read_csv(paths.results_csv)
    assert len(df) == 6
    assert df[df.run == "cruise_straight__ctrl_a"].iloc[0].status == "error"
    assert df[df.run == "garbage__x"].iloc[0].status == "error"
    assert "no_such_limit" in paths.report_html.read_text()
    assert "no_such_limit" in paths.junit_xml.read_text()


def test_html_is_self_contained(catalog: Path) -> None:
    text = (catalog / "report.html").read_text()
    assert not re.search(r"https?://", text)
    assert not re.search(r"""(src|href)\s*=\s*["'](?!#|data:)""", text)
    assert "<script src" not in text and "@import" not in text and "url(" not in text
    assert text.count("<details") == 12
    assert 'id="scenario-matrix"' in text
    assert text.count("<svg") > 12 * 5
    # failed ones come first and open
    first = re.search(r'<details class="run" id="[^"]+" data-status="(\w+)"[^>]*?( open)?>', text)
    assert first is not None and first.group(1) == "error" and first.group(2) == " open"


def test_decimation_keeps_extremes() -> None:
    x = np.arange(100_000, dtype=float)
    y = np.sin(x / 5000.0)
    y[31_337] = 50.0
    xd, yd = decimate(x, y)
    assert len(xd) <= MAX_POINTS
    assert yd.max() == 50.0 and np.all(np.diff(xd) > 0)


def test_html_size_for_a_large_catalog(tmp_path: Path) -> None:
    out = tmp_path / "big"
    for i in range(100):
        trace = sr.lane_change_trace(duration_s=30.0, dt_s=0.02, seed=i)
        nb = sr.lead_vehicle(trace, 40.0 + 25.0 * trace["t_s"].to_numpy(), 7.0, 25.0)
        sr.write_run(out / f"case_{i:03d}", trace, neighbours=nb,
                     meta=sr.base_meta(f"case_{i:03d}", "ctrl_a" if i % 2 else "ctrl_b",
                                       family=f"fam{i % 5}", step_s=0.02))
    paths = write_reports(out)
    size = paths.report_html.stat().st_size
    assert size < 12_000_000, size
    for m in re.finditer(r'<path d="([^"]+)"', paths.report_html.read_text()):
        assert m.group(1).count("L") < MAX_POINTS + 1


def test_family_fallback() -> None:
    assert scenario_family({"family": "x"}, "anything") == "x"
    assert scenario_family({}, "stall_mid_s3") == "stall_mid"
    assert scenario_family({}, "stall__pos300") == "stall"
