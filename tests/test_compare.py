"""compare_runs: regressions, fixed runs, missing/new runs, timing ratios, tolerances."""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest
import synthetic_runs as sr

from reports.compare import MetricTolerance, NothingToCompare, Tolerances, compare_runs
from reports.manifest import Manifest, write_manifest
from reports.provenance import Provenance
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
    assert tol.metrics["rms_lat_dev_m"] == MetricTolerance(0.01, 0.01)
    assert compare_runs(base, new, tmp_path / "cmp2", tol).exit_code == 1


def test_new_failure_and_fixed(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    _rerun(new, "cruise_straight__ctrl_a", _collide)
    result = compare_runs(base, new, tmp_path / "cmp")
    assert result.new_failures == ["cruise_straight [ctrl_a]"]
    assert result.exit_code == 1
    row = result.of_kind("new_failure")[0]
    assert "pass → fail" in row.note and "at_fault_collisions=1>0" in row.note
    # the other direction: fixed, no regression
    back = compare_runs(new, base, tmp_path / "cmp_back")
    assert back.fixed == ["cruise_straight [ctrl_a]"]
    assert back.exit_code == 0


def test_timing_warns_and_gates_only_with_the_timing_gate(base: Path, tmp_path: Path) -> None:
    slow = sr.make_catalog(tmp_path / "slow", speedup=2.0)
    result = compare_runs(base, slow, tmp_path / "cmp")
    timing = result.of_kind("timing_slower")
    # every controller time doubled: warnings, ratio 2, no behaviour finding, exit 0
    assert timing and result.exit_code == 0 and not result.regressions
    assert all(r.warning and not r.regression for r in timing)
    assert {r.metric for r in timing} >= {"step_ms_p99", "step_ms_p50"}
    assert all(r.ratio == pytest.approx(2.0, rel=0.05) for r in timing
               if r.metric.startswith("step_"))
    assert not result.of_kind("metric_regression", "new_failure")
    lines = {t.metric: t for t in result.timing}
    assert lines["step_ms_p99"].median_ratio == pytest.approx(2.0, rel=0.05)
    assert lines["step_ms_p99"].slower and not lines["sumo_ms_p50"].slower
    assert "OK: no behaviour regression" in result.summary_text()
    # the timing gate: the catalog-wide median beyond its ratio fails
    gated = compare_runs(base, slow, tmp_path / "cmp_gate", Tolerances(timing_gate=True))
    assert gated.exit_code == 1 and not gated.regressions
    assert {t.metric for t in gated.timing_failures} >= {"step_ms_p50", "step_ms_p99"}
    toml = tmp_path / "loose.toml"
    toml.write_text("timing_gate = true\n[timing]\nstep_ms_p50 = 3.0\nstep_ms_p99 = 3.0\n"
                    "outer_ms_p99 = 3.0\ninner_ms_p99 = 3.0\n")
    assert compare_runs(base, slow, tmp_path / "cmp2", Tolerances.from_toml(toml)).exit_code == 0
    # and a speed-up is an improvement, never a finding that fails
    faster = compare_runs(slow, base, tmp_path / "cmp3", Tolerances(timing_gate=True))
    assert faster.exit_code == 0 and faster.of_kind("timing_faster")


def test_one_noisy_run_does_not_fail_the_timing_gate(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    record = dict(sr.catalog_records())["cruise_straight__ctrl_a"]
    sr.fill_timing(record.trace, 0, scale=5.0)
    sr.write_judged(record, new / "cruise_straight__ctrl_a")
    result = compare_runs(base, new, tmp_path / "cmp", Tolerances(timing_gate=True))
    assert [r.key for r in result.of_kind("timing_slower")][:1] == ["cruise_straight [ctrl_a]"]
    assert result.exit_code == 0  # the median run did not slow down


def test_deadline_misses_are_timing_not_behaviour(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    record = dict(sr.catalog_records())["cruise_straight__ctrl_a"]
    record.trace.timing.controller_s[:40] = 0.2  # 40 steps over the 50 ms period
    sr.write_judged(record, new / "cruise_straight__ctrl_a")
    verdict = sr.judge(record).verdict
    assert verdict is not None
    metric = verdict.metric("deadline_misses")
    assert metric is not None and metric.kind == "timing"
    result = compare_runs(base, new, tmp_path / "cmp")
    (row,) = [r for r in result.rows if r.metric == "deadline_misses"]
    assert row.kind == "timing_slower" and row.warning and not row.regression
    assert (row.base, row.new) == (0.0, 40.0)
    assert result.exit_code == 0
    assert compare_runs(base, new, tmp_path / "cmp2", Tolerances(timing_gate=True)).exit_code == 1


def test_an_empty_baseline_or_nothing_matched_is_nothing_to_compare(base: Path,
                                                                   tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(NothingToCompare, match="holds no run"):
        compare_runs(empty, base, tmp_path / "cmp")
    with pytest.raises(NothingToCompare, match="holds no run"):
        compare_runs(base, empty, tmp_path / "cmp")
    other = tmp_path / "other"
    sr.write_run(other / "elsewhere__ctrl_a", sr.straight_trace(3.0),
                 info=sr.base_info("elsewhere", "ctrl_a"))
    sr.write_run(other / "elsewhere__ctrl_b", sr.straight_trace(3.0),
                 info=sr.base_info("elsewhere", "ctrl_b"))
    with pytest.raises(NothingToCompare, match="matches"):
        compare_runs(base, other, tmp_path / "cmp")


def _manifest(out: Path, **changes: object) -> None:
    prov = Provenance(git_sha="a" * 40, git_dirty=False, hwyeval_version="0.1.0",
                      sumo_version="1.28.0", numba_version="0.60", rerun_version="0.41.0",
                      numpy_version="2.0", python_version="3.11.2", host="nightly-1",
                      cpu_model="Xeon", cpu_count=2, load_start=0.1, load_end=0.2)
    import dataclasses
    prov = dataclasses.replace(prov, **changes)  # type: ignore[arg-type]
    write_manifest(out, Manifest(catalog="cat.toml", catalog_name="cat", scenarios=(),
                                 started="2025-01-01T00:00:00+00:00", jobs=2, executor="local",
                                 provenance=prov))


def test_provenance_differences_and_load_are_reported(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    _manifest(base)
    _manifest(new, git_sha="b" * 40, git_dirty=True, host="laptop", load_end=1.9)
    result = compare_runs(base, new, tmp_path / "cmp")
    assert {d.field for d in result.provenance_differences} == {"git_sha", "git_dirty", "host"}
    assert result.exit_code == 0  # provenance alone never fails a comparison
    text = result.summary_text()
    assert "provenance differs" in text and "host: nightly-1 → laptop" in text
    assert "busy machine" in result.load and "1.90" in result.load
    html = (tmp_path / "cmp" / "compare.html").read_text()
    assert "Provenance" in html and "laptop" in html


def test_terminal_shows_base_and_new_with_units(base: Path, tmp_path: Path) -> None:
    new = _copy(base, tmp_path)
    _rerun(new, "lane_change_left__ctrl_a", _scale_lat_dev(1.5))
    result = compare_runs(base, new, tmp_path / "cmp")
    (row,) = [r for r in result.regressions if r.metric == "rms_lat_dev_m"]
    line = next(li for li in result.summary_text().splitlines() if "rms_lat_dev_m" in li)
    assert f"{row.base:.4g} m → {row.new:.4g} m" in line
    assert row.unit == "m" and row.metric_kind == "tracking"
    import json

    from reports.compare.render import as_json
    doc = json.loads(as_json(result))
    assert doc["exit_code"] == 1
    regs = {r["metric"]: r for r in doc["regressions"]}
    assert "rms_lat_dev_m" in regs and regs["rms_lat_dev_m"]["unit"] == "m"
    assert all(r["metric_kind"] == "tracking" for r in regs.values())


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


def test_compare_reads_the_stored_verdicts_of_complete_runs(base: Path, tmp_path: Path
                                                             ) -> None:
    new = _copy(base, tmp_path)
    # per-step files gone: the runs are incomplete (run.json lists them), so none of
    # them counts as passed any more, whatever its stored verdict says
    for run_dir in new.iterdir():
        for part in run_dir.iterdir() if run_dir.is_dir() else ():
            if part.name != RUN_JSON:
                part.unlink()
    gone = compare_runs(base, new, tmp_path / "cmp")
    assert gone.exit_code == 1
    rows = gone.of_kind("unreadable")
    assert len(rows) == len([d for d in new.iterdir() if (d / RUN_JSON).is_file()])
    assert all(r.gate and r.category == "unreadable" and "new: " in r.note
               and "trace.parquet: missing" in r.note for r in rows)
    assert not gone.of_kind("new_failure")  # an unreadable run is no behaviour finding
    # the verdicts alone decide: the same per-step files, nothing is re-evaluated
    new = _copy(base, tmp_path, "again")
    assert compare_runs(base, new, tmp_path / "cmp1").exit_code == 0
    # a run directory whose run.json is unreadable counts as an error run
    (new / "cruise_straight__ctrl_a" / RUN_JSON).write_text("{")
    result = compare_runs(base, new, tmp_path / "cmp2")
    (row,) = result.regressions
    assert (row.key, row.kind, row.category) == ("cruise_straight [ctrl_a]", "unreadable",
                                                 "unreadable")
    assert "new: RecordError" in row.note and "run.json" in row.note
    assert result.exit_code == 1


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


def test_the_page_overlays_base_and_new_of_a_regressed_metric(base: Path, tmp_path: Path
                                                               ) -> None:
    import numpy as np

    new = _copy(base, tmp_path)
    _rerun(new, "lane_change_left__ctrl_a", _scale_lat_dev(1.5))
    compare_runs(base, new, tmp_path / "cmp")
    page = (tmp_path / "cmp" / "compare.html").read_text()
    found = re.search(r'<div class="overlay" data-key="lane_change_left \[ctrl_a\]">(.*?)</div>',
                      page, re.S)
    assert found is not None
    svg = found.group(1)
    assert svg.count("<path") >= 2 and "base (" in svg and "new (" in svg
    # the new run's curve reaches 1.5 times the base's extreme on the chart's y axis
    y1 = float(re.search(r'data-y1="([-0-9.e]+)"', svg).group(1))  # type: ignore[union-attr]
    dev = dict(sr.catalog_records())["lane_change_left__ctrl_a"].trace.ego.lat_dev_m
    assert y1 >= 1.5 * float(np.nanmax(dev)) - 1e-9
    # identical runs draw nothing
    same = _copy(base, tmp_path, "same")
    compare_runs(base, same, tmp_path / "cmp2")
    assert 'class="overlay"' not in (tmp_path / "cmp2" / "compare.html").read_text()
