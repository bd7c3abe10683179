"""Robustness (reports.metrics.robustness): its sign is the verdict's, on every criterion;
known answers; results.csv carries it for every run."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from reports.metrics.criteria import CRITERIA_METRICS, Criteria, steps_failure
from reports.metrics.robustness import SCALES, margin_of, robustness
from reports.metrics.values import measured
from reports.record import Verdict
from reports.tables import RunEntry, results_frame

EXTRA = ("max_at_fault_delta_v_mps", "max_offroad_m")
METRICS = sorted({m for m, _ in CRITERIA_METRICS.values()} | set(EXTRA))

values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.floats(min_value=-10.0, max_value=10.0),
    st.sampled_from([0.0, -0.0, 1.0, 0.95, 5e-324, -5e-324, 1e308]),
    st.integers(min_value=0, max_value=3).map(float))
limits = st.one_of(st.none(), st.floats(min_value=-1e6, max_value=1e6),
                   st.sampled_from([0.0, 0.95, 1.0, -4.05]))


def judged(metric_values: dict[str, float], limit_values: dict[str, float | None]) -> Verdict:
    """A verdict as reports.metrics.evaluate makes it: the criteria's check decides."""
    crit = Criteria(**limit_values)  # type: ignore[arg-type]
    found = [measured(name, v, "-", "safety") for name, v in metric_values.items()]
    failures = crit.check(found)
    return Verdict(status="fail" if failures else "pass",
                   metrics=tuple(m.metric for m in found), failures=failures,
                   criteria=crit.as_dict())


@pytest.mark.slow
@settings(max_examples=400, deadline=None)
@given(st.fixed_dictionaries({m: values for m in METRICS}),
       st.fixed_dictionaries({c: limits for c in CRITERIA_METRICS}))
def test_robustness_is_negative_exactly_when_the_verdict_fails(
        metric_values: dict[str, float], limit_values: dict[str, float | None]) -> None:
    verdict = judged(metric_values, limit_values)
    rob = robustness(verdict)
    assert not math.isnan(rob.value)
    assert (rob.value < 0.0) == (verdict.status == "fail")
    # every criterion's own margin has the sign of its own check
    failed = {f.criterion for f in verdict.failures}
    for m in rob.margins:
        assert (m.margin < 0.0) == (m.criterion in failed), m
    if verdict.failures:
        assert rob.criterion in failed


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(CRITERIA_METRICS)), values, st.floats(-1e3, 1e3))
def test_each_criterion_alone(criterion: str, value: float, limit: float) -> None:
    metric, _ = CRITERIA_METRICS[criterion]
    lims: dict[str, float | None] = {c: None for c in CRITERIA_METRICS}
    lims[criterion] = limit
    verdict = judged({metric: value}, lims)
    rob = robustness(verdict)
    if math.isnan(value):
        assert rob.value == math.inf and rob.criterion == ""
    else:
        assert (rob.value < 0.0) == (verdict.status == "fail")
        assert rob.criterion == criterion


def test_known_answers() -> None:
    lims: dict[str, float | None] = {c: None for c in CRITERIA_METRICS}
    lims.update(min_ttc_s=0.95, max_abs_lat_acc_mps2=4.89)
    rob = robustness(judged({"min_ttc_s": 2.27, "max_abs_lat_acc_mps2": 2.6}, lims))
    assert math.isclose(rob.value, 1.32) and rob.criterion == "min_ttc_s"
    # a comfort failure: (4.89 - 5.89) / 0.5 m/s^2
    rob = robustness(judged({"min_ttc_s": 2.27, "max_abs_lat_acc_mps2": 5.89}, lims))
    assert math.isclose(rob.value, -2.0) and rob.criterion == "max_abs_lat_acc_mps2"
    assert math.isclose(margin_of("max_abs_yaw_rate_radps", 1.15, 0.95, "max"),
                        -0.2 / SCALES["max_abs_yaw_rate_radps"])


def _collision(delta_v: float, gap: float) -> float:
    lims: dict[str, float | None] = {c: None for c in CRITERIA_METRICS}
    lims["max_at_fault_collisions"] = 0.0
    count = 1.0 if delta_v > 0 else 0.0
    return robustness(judged({"at_fault_collisions": count, "min_gap_m": gap,
                              "max_at_fault_delta_v_mps": delta_v}, lims)).value


def test_a_crash_is_worse_than_a_graze_and_a_near_miss_is_near_zero() -> None:
    crash, graze = _collision(12.0, 0.0), _collision(0.5, 0.0)
    assert crash == -13.0 and graze == -1.5 and crash < graze < 0.0
    near, far = _collision(0.0, 0.05), _collision(0.0, 2.0)
    assert 0.0 < near < far


def test_offroad_headroom_shrinks_toward_the_tolerance() -> None:
    lims: dict[str, float | None] = {c: None for c in CRITERIA_METRICS}
    lims["max_offroad_s"] = 0.0
    inside = robustness(judged({"offroad_s": 0.0, "max_offroad_m": 0.0}, lims)).value
    close = robustness(judged({"offroad_s": 0.0, "max_offroad_m": 0.25}, lims)).value
    off = robustness(judged({"offroad_s": 0.4, "max_offroad_m": 0.6}, lims)).value
    assert math.isclose(inside, 3.0) and 0.0 < close < inside and off < 0.0


def test_no_trace_rows_and_unfinished_runs() -> None:
    v = Verdict(status="fail", failures=(steps_failure(),), criteria={})
    rob = robustness(v)
    assert rob.value == -1.0 and rob.criterion == "min_steps"
    for status in ("error", "timeout"):
        rob = robustness(Verdict(status=status))
        assert math.isnan(rob.value) and rob.criterion == status


def _entry(name: str, verdict: Verdict | None, status: str) -> Any:
    record = SimpleNamespace(verdict=verdict, outcome=SimpleNamespace(wall_s=1.0,
                                                                       sim_time_s=2.0))
    return RunEntry(Path("/nowhere") / name, name, "two_loop", "fam", status,
                    record=record)  # type: ignore[arg-type]


def test_results_csv_has_the_two_columns_for_every_run() -> None:
    lims: dict[str, float | None] = {c: None for c in CRITERIA_METRICS}
    lims["min_ttc_s"] = 0.95
    runs = [_entry("a", judged({"min_ttc_s": 0.5}, lims), "fail"),
            _entry("b", judged({"min_ttc_s": 3.0}, lims), "pass"),
            _entry("c", Verdict(status="error"), "error"),
            _entry("d", None, "error")]
    frame = results_frame(runs)
    assert list(frame["robustness_criterion"]) == ["min_ttc_s", "min_ttc_s", "error", "error"]
    rob = list(frame["robustness"])
    assert math.isclose(rob[0], -0.45) and math.isclose(rob[1], 2.05)
    assert math.isnan(rob[2]) and math.isnan(rob[3])
