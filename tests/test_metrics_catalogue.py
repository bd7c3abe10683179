"""The metric catalogue: every metric stored is an entry, every table is a view of it,
entries are validated, and a metric added to the catalogue reaches the outputs without
breaking a comparison with runs made before it (reports.metrics.catalogue)."""

from __future__ import annotations

import dataclasses
import math
import pickle
from pathlib import Path

import pytest
import synthetic_runs as sr

from reports.compare import compare_runs
from reports.compare.overlay import METRIC_SERIES
from reports.compare.tolerances import default_metric_tolerances, default_timing_ratios
from reports.junit import KEY_METRICS
from reports.metrics import CATALOGUE, REQUIRED_METRICS, Criteria, evaluate, spec
from reports.metrics.catalogue import CRITERIA, CRITERIA_METRICS, SUMMARY_METRICS
from reports.metrics.robustness import SCALES
from reports.metrics.spec import Criterion, Drawing, MetricSpec, Summary, Tolerance
from reports.record import write_run
from reports.tables import collect_runs, results_frame

NEW = "max_drac_mps2"


def _records() -> list[object]:
    trace, nb = sr.approach_run_parts()
    return [sr.make_record(trace, neighbours=nb), sr.make_record(None),
            *(r for _, r in sr.catalog_records())]


def test_every_stored_metric_is_its_entry() -> None:
    """A metric's unit, kind, direction and series are its entry's, for every metric of
    runs with and without rows, neighbours, errors."""
    for record in _records():
        for m in evaluate(record).verdict.metrics:  # type: ignore[arg-type]
            entry = spec(m.name)
            assert (m.unit, m.kind, m.better, m.series) == (
                entry.unit, entry.kind, entry.better, entry.series), m.name


def test_tables_are_views_of_the_catalogue() -> None:
    assert REQUIRED_METRICS[:3] == ("collision", "at_fault_collisions", "min_gap_m")
    assert len(REQUIRED_METRICS) == 24 and NEW not in REQUIRED_METRICS
    assert Criteria.names() == list(CRITERIA) == list(CRITERIA_METRICS)
    assert list(CRITERIA)[:3] == ["max_at_fault_collisions", "max_collision", "max_offroad_s"]
    assert set(SCALES) == set(CRITERIA)
    assert Criteria().min_ttc_s == 0.95 and Criteria().max_collision is None
    assert list(SUMMARY_METRICS)[:4] == ["collision", "min_gap_m", "min_ttc_s", "progress_m"]
    assert KEY_METRICS[:2] == ("collision", "collision_disagreements")
    tolerances = default_metric_tolerances()
    assert tolerances[NEW].abs == 0.3 and tolerances[NEW].rel == 0.1
    assert default_timing_ratios()["realtime_factor"] == 1.5
    assert METRIC_SERIES[NEW].ref == "series.drac_mps2"
    assert METRIC_SERIES["rms_lat_dev_m"].ref == "ego.lat_dev_m"
    names = [s.name for s in CATALOGUE]
    assert len(names) == len(set(names))


def test_criteria_are_values() -> None:
    c = Criteria(max_collision=1.0)
    assert c.max_collision == 1.0 and c.limit("max_collision") == 1.0
    assert c == Criteria.from_overrides({"max_collision": 1})
    assert pickle.loads(pickle.dumps(c)) == c and hash(c) == hash(Criteria(max_collision=1.0))
    with pytest.raises(TypeError, match="unknown"):
        Criteria(no_such_limit=1.0)
    with pytest.raises(ValueError, match="max_collision"):
        Criteria(max_collision=math.nan)
    with pytest.raises(AttributeError):
        _ = c.no_such_limit


@pytest.mark.parametrize("build", [
    lambda: MetricSpec("Bad Name", "-", "safety", "lower"),
    lambda: MetricSpec("x", "", "safety", "lower"),
    lambda: MetricSpec("x", "-", "speed", "lower"),
    lambda: MetricSpec("x", "-", "safety", "smaller"),
    lambda: MetricSpec("x", "-", "safety", "lower", "nowhere.col"),
    lambda: MetricSpec("x", "-", "safety", "lower", timing_ratio=1.5),
    lambda: MetricSpec("x", "-", "safety", "lower", drawing=Drawing("x", "-")),
    lambda: MetricSpec("x", "-", "safety", "lower", mark="red"),
    lambda: Criterion("max_x", "above", 1.0, 1.0, 0),
    lambda: Criterion("max_x", "max", math.inf, 1.0, 0),
    lambda: Criterion("max_x", "max", 1.0, 0.0, 0),
    lambda: Tolerance(-1.0, 0.0),
    lambda: Summary(("median",), 0),
    lambda: Drawing("x", "-", cap=math.nan),
])
def test_entries_are_validated(build: object) -> None:
    with pytest.raises(ValueError):
        build()  # type: ignore[operator]


def _write_without(out: Path, name: str) -> Path:
    """The synthetic catalog judged as a version without metric ``name`` would have."""
    for run, record in sr.catalog_records():
        judged = sr.judge(record)
        if judged.verdict is not None:
            kept = tuple(m for m in judged.verdict.metrics if m.name != name)
            judged = dataclasses.replace(
                judged, verdict=dataclasses.replace(judged.verdict, metrics=kept))
        write_run(judged, out / run)
    return out


def test_a_new_metric_is_a_column_and_not_in_base_never_a_regression(tmp_path: Path) -> None:
    base = _write_without(tmp_path / "base", NEW)
    new = sr.make_catalog(tmp_path / "new")
    old_cols = list(results_frame(collect_runs(base)).columns)
    new_cols = list(results_frame(collect_runs(new)).columns)
    assert [c for c in new_cols if c != NEW] == old_cols and NEW in new_cols
    result = compare_runs(base, new)
    assert result.exit_code == 0 and result.regressions == []
    rows = result.of_kind("metric_not_in_base")
    assert rows and {r.metric for r in rows} == {NEW}
    assert all(r.category == "info" and not r.gate for r in rows)
    assert f"{NEW} not in base" in result.summary_text()
    # and the other way round: a metric only base has is "not in new"
    back = compare_runs(new, base)
    assert back.exit_code == 0 and back.of_kind("metric_not_in_new")
