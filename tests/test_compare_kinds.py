"""compare's finding kinds (why a run differs) on pairs of hand-made nights: a changed
controller is a behaviour regression; a tightened criterion, a criterion switched off and
a changed test are not (a behaviour change beside a waiver still is); removed and new
scenarios; timing. Also the CLI's JSON ``kind``, ``compare A A`` refused, the page
written beside the new night."""

from __future__ import annotations

import dataclasses
import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import synthetic_runs as sr

from reports.compare import compare_runs
from reports.compare.kinds import CATEGORIES
from reports.identity import TEST_KEY
from reports.record import RunRecord, write_run

ROOT = Path(__file__).resolve().parents[1]
RUN = "lane_change_left__ctrl_a"
KEY = "lane_change_left [ctrl_a]"


@pytest.fixture()
def base(tmp_path: Path) -> Path:
    return sr.make_catalog(tmp_path / "base")


def _night(base: Path, tmp_path: Path, change: Callable[[RunRecord], RunRecord],
           criteria: dict[str, object] | None = None, name: str = "new") -> Path:
    """A copy of ``base`` with RUN run again after ``change`` (judged with ``criteria``
    overrides, as a catalog's [criteria] table would)."""
    new = Path(shutil.copytree(base, tmp_path / name))
    _rewrite(new, change(dict(sr.catalog_records())[RUN]), criteria)
    return new


def _rewrite(night: Path, record: RunRecord, criteria: dict[str, object] | None = None,
             name: str = RUN) -> None:
    """Replace the run directory ``night/name`` with ``record``, judged."""
    if (night / name).exists():
        shutil.rmtree(night / name)
    write_run(sr.judge(record, criteria), night / name)


def _worse(record: RunRecord) -> RunRecord:
    record.trace.ego.lat_dev_m[:] *= 1.5  # the controller tracks worse
    return record


def _same(record: RunRecord) -> RunRecord:
    return record


def _with_hash(value: str) -> Callable[[RunRecord], RunRecord]:
    """The run with the recorded test digest ``value`` (as the runner writes it)."""
    def change(record: RunRecord) -> RunRecord:
        spec = dict(record.info.scenario_spec, **{TEST_KEY: value})
        record.info = dataclasses.replace(record.info, scenario_spec=spec)
        return record
    return change


def _categories(result: object, key: str = KEY) -> set[str]:
    return {r.category for r in result.rows if r.key == key}  # type: ignore[attr-defined]


def test_a_worse_controller_is_a_behaviour_regression(base: Path, tmp_path: Path) -> None:
    result = compare_runs(base, _night(base, tmp_path, _worse), tmp_path / "cmp")
    assert result.exit_code == 1
    assert {r.category for r in result.regressions} == {"behaviour_regression"}
    assert all(r.category in CATEGORIES for r in result.rows)


def test_a_tightened_criterion_is_limits_changed_not_a_regression(base: Path,
                                                                  tmp_path: Path) -> None:
    # the same trajectory judged with a limit it cannot meet: a new failure, but the
    # limit moved, not the behaviour
    new = _night(base, tmp_path, _same, {"max_abs_lat_acc_mps2": 0.01})
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 0 and not result.regressions
    assert "limits_changed" in _categories(result)
    failures = [r for r in result.rows if r.key == KEY and r.kind == "new_failure"]
    assert failures and failures[0].category == "limits_changed"
    assert result.category_counts["limits_changed"] >= 2  # the failure and the change
    # the changed criterion's row carries both limits and the new value under each
    (row,) = [r for r in result.rows if r.kind == "limit_changed"]
    assert row.base_limit == pytest.approx(4.89) and row.limit == pytest.approx(0.01)
    assert row.new == pytest.approx(row.base)  # the behaviour did not move


def test_a_criterion_switched_off_is_waived(base: Path, tmp_path: Path) -> None:
    new = _night(base, tmp_path, _same, {"max_abs_lat_acc_mps2": "off"})
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 0
    waived = result.of_category("waived")
    assert [r.metric for r in waived] == ["max_abs_lat_acc_mps2"]
    # a waiver loosens the limit, the behaviour is still compared under the base's
    # limits: a controller that tracks worse beside the waiver gates
    both = _night(base, tmp_path, _worse, {"max_abs_lat_acc_mps2": "off"}, name="both")
    r2 = compare_runs(base, both, tmp_path / "cmp2")
    assert r2.exit_code == 1 and r2.of_category("waived")
    assert {r.category for r in r2.regressions} == {"behaviour_regression"}


def test_a_waiver_of_a_failing_criterion_is_not_a_fix(base: Path, tmp_path: Path) -> None:
    # the sharp curve fails lateral acceleration in base; switching that criterion off
    # makes it pass, which is a limit change, never "fixed"
    run = "sharp_curve__ctrl_a"
    new = Path(shutil.copytree(base, tmp_path / "new"))
    _rewrite(new, dict(sr.catalog_records())[run], {"max_abs_lat_acc_mps2": "off"}, name=run)
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 0 and result.fixed == []
    rows = [r for r in result.rows if r.key == "sharp_curve [ctrl_a]"]
    assert {r.category for r in rows} == {"waived"}
    (limit,) = [r for r in rows if r.kind == "criterion_off"]
    assert limit.new > limit.base_limit  # still beyond the old limit: nothing was fixed


def test_a_changed_test_is_test_changed(base: Path, tmp_path: Path) -> None:
    b = Path(shutil.copytree(base, tmp_path / "b"))
    _rewrite(b, _with_hash("a" * 64)(dict(sr.catalog_records())[RUN]))
    new = _night(base, tmp_path, lambda r: _worse(_with_hash("b" * 64)(r)))
    result = compare_runs(b, new, tmp_path / "cmp")
    assert result.exit_code == 0 and not result.regressions
    assert "test_changed" in _categories(result)
    # the same hash on both sides: the worse tracking gates again
    same = _night(base, tmp_path, lambda r: _worse(_with_hash("a" * 64)(r)), name="same")
    assert compare_runs(b, same, tmp_path / "cmp2").exit_code == 1


def test_removed_and_new_scenarios(base: Path, tmp_path: Path) -> None:
    new = Path(shutil.copytree(base, tmp_path / "new"))
    shutil.move(str(new / RUN), str(new / "renamed"))
    record = dict(sr.catalog_records())[RUN]
    record.info = dataclasses.replace(record.info, scenario="renamed")
    _rewrite(new, record, name="renamed")
    result = compare_runs(base, new, tmp_path / "cmp")
    assert [r.key for r in result.of_category("removed_scenario")] == [KEY]
    assert [r.scenario for r in result.of_category("new_scenario")] == ["renamed"]
    assert result.exit_code == 1  # a removed scenario gates by default


def test_timing_findings_are_timing(base: Path, tmp_path: Path) -> None:
    slow = sr.make_catalog(tmp_path / "slow", speedup=2.0)
    result = compare_runs(base, slow, tmp_path / "cmp")
    assert result.of_category("timing") and result.exit_code == 0
    assert all(r.category == "timing" for r in result.of_kind("timing_slower"))


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", "compare", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_the_cli_json_kinds_the_same_night_and_the_default_output(base: Path,
                                                                   tmp_path: Path) -> None:
    new = _night(base, tmp_path, _same, {"max_abs_lat_acc_mps2": 0.01})
    proc = _cli(str(base), str(new), "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    kinds = {row["kind"] for row in doc["rows"]}
    assert "limits_changed" in kinds and kinds <= set(CATEGORIES)
    assert {row["finding"] for row in doc["rows"] if row["kind"] == "limits_changed"} >= {
        "new_failure"}
    assert set(doc["gating_kinds"]) == {"behaviour_regression", "known_failure", "unreadable",
                                        "removed_scenario"}
    # the comparison's files beside the new night, not inside it
    assert (tmp_path / "new.compare" / "compare.html").is_file()
    assert not (new / "compare").exists()
    assert _cli(str(new), str(new)).returncode == 2
    worse = _night(base, tmp_path, _worse, name="worse")
    assert _cli(str(base), str(worse)).returncode == 1


def test_rows_link_to_both_runs_pages(base: Path, tmp_path: Path) -> None:
    from reports.write import write_reports

    new = _night(base, tmp_path, _worse)
    write_reports(base)
    write_reports(new)
    result = compare_runs(base, new, tmp_path / "cmp")
    html = (tmp_path / "cmp" / "compare.html").read_text()
    assert result.regressions
    page = f"report-runs/{RUN}.html"
    assert f"base/{page}" in html and f"new/{page}" in html


@pytest.mark.slow
def test_a_misspelt_metric_in_the_tolerances_exits_2(base: Path, tmp_path: Path) -> None:
    new = _night(base, tmp_path, _same)
    typo = tmp_path / "tol.toml"
    typo.write_text("[metrics.min_gap_mm]\nabs = 0.1\n")
    proc = _cli(str(base), str(new), "--tolerances", str(typo))
    assert proc.returncode == 2
    assert "min_gap_mm" in proc.stderr and "min_gap_m" in proc.stderr.replace("min_gap_mm", "")
    good = tmp_path / "good.toml"
    good.write_text("[metrics.min_gap_m]\nabs = 0.1\n[timing]\nstep_ms_p99 = 2.0\n")
    assert _cli(str(base), str(new), "--tolerances", str(good)).returncode == 0
