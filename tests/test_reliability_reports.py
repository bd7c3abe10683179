"""Reports and compare on hostile input (W8, W10, W11, W12): junit.xml stays well-formed,
``report`` reports a malformed run as an error and the others as usual, ``compare``
refuses what it cannot compare honestly (exit 2), never a traceback."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd
import pytest

import tests.synthetic_runs as sr
from reports import write_reports
from tests.reliability_support import hwyeval


def _two_runs(out: Path, controller: str = "ctrl_a") -> Path:
    sr.write_run(out / "one", sr.straight_trace(2.0), info=sr.base_info("one", controller))
    sr.write_run(out / "two", sr.straight_trace(2.0), info=sr.base_info("two", controller))
    return out


@pytest.mark.parametrize("controller", ["ctrl\x01\x1b[31m<&>\"'", "ctrl\x00\x0b\ufffe",
                                        "]]><!--"])
def test_junit_is_well_formed_whatever_the_controller_is_called(tmp_path: Path,
                                                                 controller: str) -> None:
    """W8: a controller name with control characters: the testsuite name was not escaped."""
    out = _two_runs(tmp_path / "out", controller)
    write_reports(out)
    root = ET.parse(out / "junit.xml").getroot()
    assert [s.get("name") for s in root].__len__() == 1
    assert root.get("tests") == "2"


RUN_JSON_DAMAGE = {
    "a_list": [1, 2],
    "null": None,
    "stalled_not_a_list": "outcome.stalled",
    "verdict_metrics_a_dict": "verdict.metrics",
    "info_null": "info",
    "lone_surrogate": "info.controller",
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(RUN_JSON_DAMAGE))
def test_report_marks_a_malformed_run_json_as_an_error(tmp_path: Path, case: str) -> None:
    """W10: report crashed on run.json a list or null, stalled not a list, ..., after
    rewriting results.csv and junit.xml (an older report.html then contradicted them)."""
    out = _two_runs(tmp_path / "out")
    path = out / "two" / "run.json"
    damage = RUN_JSON_DAMAGE[case]
    if isinstance(damage, str):
        doc = json.loads(path.read_text())
        section, key = damage.split(".") if "." in damage else (damage, None)
        if key is None:
            doc[section] = None
        elif case == "lone_surrogate":
            doc[section][key] = "ctrl\ud800"
        else:
            doc[section][key] = "not a list" if case == "stalled_not_a_list" else {"a": 1}
        path.write_text(json.dumps(doc))
    else:
        path.write_text(json.dumps(damage))
    proc = hwyeval("report", str(out))
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    res = pd.read_csv(out / "results.csv").set_index("run")
    assert res.loc["two", "status"] == "error"
    assert res.loc["one", "status"] == "pass"
    ET.parse(out / "junit.xml")
    assert "two" in (out / "report.html").read_text()


@pytest.mark.slow
@pytest.mark.parametrize("road", ["[]", "null", '{"lanes": "x"}', '{"lanes": [{"id": 1}]}',
                                  '{"reference_xy_m": [[1, 2, 3]]}', "{", ""])
def test_report_marks_a_malformed_road_json_as_an_error(tmp_path: Path, road: str) -> None:
    out = _two_runs(tmp_path / "out")
    (out / "two" / "road.json").write_text(road)
    proc = hwyeval("report", str(out))
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    res = pd.read_csv(out / "results.csv").set_index("run")
    assert list(res["status"]) == ["pass", "error"]


def test_compare_refuses_two_directories_of_one_run(tmp_path: Path) -> None:
    """W11: two directories for one scenario collapsed silently into one."""
    base = _two_runs(tmp_path / "base")
    new = _two_runs(tmp_path / "new")
    shutil.copytree(new / "two", new / "two_again")
    proc = hwyeval("compare", str(base), str(new))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "two_again" in proc.stderr and "ambiguous" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("sides", ["empty_empty", "empty_base", "nothing_matches"])
def test_compare_with_nothing_to_compare_exits_2(tmp_path: Path, sides: str) -> None:
    """W11: compare exited 0 when nothing matched (empty vs empty, empty baseline)."""
    base, new = tmp_path / "base", tmp_path / "new"
    base.mkdir()
    new.mkdir()
    if sides != "empty_empty":
        _two_runs(new)
    if sides == "nothing_matches":
        sr.write_run(base / "other", sr.straight_trace(2.0), info=sr.base_info("other"))
    proc = hwyeval("compare", str(base), str(new))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("text", ["nonsense = 1", "[metrics", 'metrics = "x"', "timing = [1]",
                                  "[metrics.min_gap_m]\nabs = \"far\"", "gate_kinds = 3",
                                  "timing_gate = 1", "[timing]\nstep_ms_p99 = 0.5", "\xff"])
def test_compare_with_bad_tolerances_exits_2(tmp_path: Path, text: str) -> None:
    """W12: an unknown key or bad TOML gave a traceback and rc 1 (a 'regression')."""
    base = _two_runs(tmp_path / "base")
    new = _two_runs(tmp_path / "new")
    tolerances = tmp_path / "tol.toml"
    tolerances.write_bytes(text.encode("latin-1"))
    proc = hwyeval("compare", str(base), str(new), "--tolerances", str(tolerances))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "--tolerances" in proc.stderr and "Traceback" not in proc.stderr


@pytest.mark.slow
def test_compare_with_a_missing_or_directory_tolerances_exits_2(tmp_path: Path) -> None:
    base = _two_runs(tmp_path / "base")
    new = _two_runs(tmp_path / "new")
    for tolerances in (tmp_path / "missing.toml", tmp_path):
        proc = hwyeval("compare", str(base), str(new), "--tolerances", str(tolerances))
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
