"""compare_runs: regressions, fixed runs, missing/new runs, timing ratios, tolerances."""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest
import synthetic_runs as sr

from reports.compare import MetricTolerance, Tolerances, compare_runs
from reports.record import RUN_JSON, Trace


@pytest.fixture()
def base(tmp_path: Path) -> Path:
    return sr.make_catalog(tmp_path / "base")


def _copy(base: Path, tmp_path: Path, name: str = "new") -> Path:
    return Path(shutil.copytree(base, tmp_path / name))


def _scale_lat_dev(factor: float) -> Callable[[Trace], None]:
    def change(trace: Trace) -> None:
        trace.ego.lat_dev_m[:] *= factor
    return change


def _collide(trace: Trace) -> None:
    trace.safety.geom_collision[:] = True


def _shift_left_3m(trace: Trace) -> None:
    trace.ego.y_m[:] += 3.0


def _rerun(out: Path, run: str, change: Callable[[Trace], None]) -> None:
    """Run ``run`` of the synthetic catalog again with its trace changed, judged and
    written as the runner would (the comparison reads only the stored verdicts)."""
    record = dict(sr.catalog_records())[run]
    change(record.trace)
    sr.write_judged(record, out / run)


def test_identical_runs_exit_0(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 0
    assert result.regressions == [] and result.new_failures == [] and result.fixed == []
    assert result.matched == 12
    assert (tmp_path / "cmp" / "compare.csv").is_file()
    html = (tmp_path / "cmp" / "compare.html").read_text()
    assert "no regression" in html and not re.search(r"https?://", html)


def test_metric_worse_beyond_tolerance(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    _rerun(new, "lane_change_left__ctrl_a", _scale_lat_dev(1.5))
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.exit_code == 1
    regs = [(r.key, r.kind, r.metric) for r in result.regressions]
    assert ("lane_change_left [ctrl_a]", "metric_regression", "rms_lat_dev_m") in regs
    assert result.new_failures == []  # still passes its criteria
    csv = pd.read_csv(tmp_path / "cmp" / "compare.csv")
    row = csv[(csv.metric == "rms_lat_dev_m") & (csv.kind == "metric_regression")].iloc[0]
    assert row.regression == 1 and row.new == pytest.approx(row.base * 1.5)
    assert "rms_lat_dev_m" in (tmp_path / "cmp" / "compare.html").read_text()
    assert "REGRESSION" in result.summary_text()


def test_metric_change_within_tolerance(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    _rerun(new, "lane_change_left__ctrl_a", _scale_lat_dev(1.05))
    assert compare_runs(base, new, tmp_path / "cmp").exit_code == 0
    # a TOML file can tighten it
    toml = tmp_path / "tol.toml"
    toml.write_text('[metrics.rms_lat_dev_m]\nabs = 0.01\nrel = 0.01\n')
    tol = Tolerances.from_toml(toml)
    assert tol.metrics["rms_lat_dev_m"] == MetricTolerance(0.01, 0.01, "higher_is_worse")
    assert compare_runs(base, new, tmp_path / "cmp2", tol).exit_code == 1


def test_new_failure_and_fixed(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    _rerun(new, "cruise_straight__ctrl_a", _collide)
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.new_failures == ["cruise_straight [ctrl_a]"]
    assert result.exit_code == 1
    row = result.of_kind("new_failure")[0]
    assert "pass → fail" in row.note and "collision=1>0" in row.note
    # the other direction: fixed, no regression
    back = compare_runs(new, base, tmp_path / "cmp_back")
    assert back.fixed == ["cruise_straight [ctrl_a]"]
    assert back.exit_code == 0


def test_timing_ratio_regression(base: Path, tmp_path: Path) -> None:
    slow = sr.make_catalog(tmp_path / "slow", speedup=2.0)
    result = compare_runs(base, slow, tmp_path / "cmp")
    timing = result.of_kind("timing_regression")
    assert timing and result.exit_code == 1
    assert {r.metric for r in timing} >= {"step_ms_p99", "step_ms_p50"}
    assert all(r.ratio == pytest.approx(2.0, rel=0.05) for r in timing
               if r.metric.startswith("step_"))
    assert not result.of_kind("metric_regression", "new_failure")
    toml = tmp_path / "loose.toml"
    toml.write_text("[timing]\nstep_ms_p50 = 3.0\nstep_ms_p99 = 3.0\nouter_ms_p99 = 3.0\n"
                    "inner_ms_p99 = 3.0\n")
    assert compare_runs(base, slow, tmp_path / "cmp2", Tolerances.from_toml(toml)).exit_code == 0
    # and a speed-up is an improvement, not a regression
    assert compare_runs(slow, base, tmp_path / "cmp3").exit_code == 0


def test_missing_and_new_runs(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    shutil.rmtree(new / "rear_end__ctrl_b")
    sr.write_run(new / "extra__ctrl_a", sr.straight_trace(3.0),
                 info=sr.base_info("extra", "ctrl_a", family="cruise"))
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.missing == ["rear_end [ctrl_b]"]
    assert result.added == ["extra [ctrl_a]"]
    assert result.exit_code == 1
    lenient = Tolerances(missing_is_regression=False)
    assert compare_runs(base, new, tmp_path / "cmp2", lenient).exit_code == 0


def test_single_controller_dirs_match_by_scenario(tmp_path: Path) -> None:
    a = sr.make_catalog(tmp_path / "a", controllers=("ctrl_a",))
    b = sr.make_catalog(tmp_path / "b", controllers=("ctrl_x",))
    result = compare_runs(a, b, tmp_path / "cmp")
    assert result.matched == 5 and not result.missing and not result.added
    assert result.exit_code == 0


def test_compare_reads_only_the_stored_verdicts(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    # per-step files gone: nothing to re-evaluate from, the verdicts still compare
    for run_dir in new.iterdir():
        for part in run_dir.iterdir() if run_dir.is_dir() else ():
            if part.name != RUN_JSON:
                part.unlink()
    assert compare_runs(base, new, tmp_path / "cmp").exit_code == 0
    # a run directory whose run.json is unreadable counts as an error run
    (new / "cruise_straight__ctrl_a" / RUN_JSON).write_text("{")
    result = compare_runs(base, new, tmp_path / "cmp2")
    assert result.new_failures == ["cruise_straight [ctrl_a]"]
    (row,) = result.of_kind("new_failure")
    assert "pass → error" in row.note and "cannot read" in row.note


def test_new_criterion_is_told_by_the_typed_failure(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    # the sharp curve fails lateral acceleration in both; now it also leaves its lane
    _rerun(new, "sharp_curve__ctrl_a", _shift_left_3m)
    result = compare_runs(base, new, tmp_path / "cmp")
    rows = result.of_kind("new_criterion")
    assert [r.metric for r in rows] == ["offroad_s"]
    assert rows[0].note.startswith("offroad_s=")
    assert result.exit_code == 1


def test_tolerances_validation(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("timing_ratio = 2\n")
    with pytest.raises(ValueError, match="timing_ratio"):
        Tolerances.from_toml(bad)
    bad.write_text('[metrics.min_gap_m]\ndirection = "sideways"\n')
    with pytest.raises(ValueError, match="min_gap_m"):
        Tolerances.from_toml(bad)
    bad.write_text("[timing]\nstep_ms_p99 = 0.5\n")
    with pytest.raises(ValueError, match="step_ms_p99"):
        Tolerances.from_toml(bad)
