"""Criteria: defaults, overrides (catalog, then explicit), typed failures and their text."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import synthetic_runs as sr

from reports.metrics import Criteria, evaluate
from reports.metrics.criteria import CRITERIA_METRICS
from reports.metrics.values import Measured, measured
from reports.record import Failure


def _m(name: str, value: float, worst_step: int | None = None,
       increments: np.ndarray | None = None) -> Measured:
    return measured(name, value, "-", "safety", worst_step=worst_step, increments=increments)


def test_nuplan_defaults() -> None:
    c = Criteria()
    assert (c.min_long_acc_mps2, c.max_long_acc_mps2) == (-4.05, 2.40)
    assert c.max_abs_lat_acc_mps2 == 4.89
    assert c.max_abs_yaw_acc_radps2 == 1.93
    assert c.max_abs_yaw_rate_radps == 0.95
    assert c.max_abs_long_jerk_mps3 == 4.13
    assert c.max_abs_jerk_mps3 == 8.37
    assert c.min_ttc_s == 0.95
    # collisions: the default is on the at-fault ones (nuPlan); any contact is off by
    # default but available
    assert c.max_at_fault_collisions == 0.0 and c.max_collision is None
    assert c.max_offroad_s == 0.0
    assert c.min_progress_fraction == 0.5
    assert set(CRITERIA_METRICS) == set(Criteria.names())
    with pytest.raises(dataclasses.FrozenInstanceError):
        c.min_ttc_s = 2.0  # type: ignore[misc]


def test_overrides_apply_and_validate() -> None:
    c = Criteria.from_overrides({"max_abs_lat_acc_mps2": 6, "min_ttc_s": None})
    assert c.max_abs_lat_acc_mps2 == 6.0
    assert c.min_ttc_s is None
    assert Criteria.from_overrides(None) == Criteria()
    with pytest.raises(ValueError, match=r"max_lat_acc.*valid criteria: .*max_abs_lat_acc_mps2"):
        Criteria.from_overrides({"max_lat_acc": 3.0})
    with pytest.raises(ValueError, match="min_ttc_s"):
        Criteria.from_overrides({"min_ttc_s": "fast"})
    with pytest.raises(ValueError, match="min_ttc_s"):
        Criteria.from_overrides({"min_ttc_s": math.inf})
    with pytest.raises(ValueError):
        Criteria.from_overrides({"max_collision": True})


def test_check_gives_typed_failures_in_criteria_order() -> None:
    t_s = 0.1 * np.arange(1, 11)
    failed = Criteria().check([
        _m("max_abs_lat_acc_mps2", 5.0, worst_step=7), _m("min_long_acc_mps2", -5.0,
                                                          worst_step=2),
        _m("min_ttc_s", 0.5, worst_step=4), _m("offroad_s", math.nan),
        _m("collision", 1.0, worst_step=3, increments=np.eye(10)[3]),
        _m("at_fault_collisions", 1.0, worst_step=3, increments=np.eye(10)[3])], t_s)
    assert [f.text for f in failed] == ["at_fault_collisions=1>0", "min_ttc_s=0.5<0.95",
                                        "min_long_acc_mps2=-5<-4.05",
                                        "max_abs_lat_acc_mps2=5>4.89"]
    assert failed[0] == Failure(criterion="max_at_fault_collisions",
                                metric="at_fault_collisions", value=1.0, limit=0.0,
                                bound="max", unit="-", step=3, t_s=pytest.approx(0.4))
    assert [(f.criterion, f.bound, f.step) for f in failed[1:]] == [
        ("min_ttc_s", "min", 4), ("min_long_acc_mps2", "min", 2),
        ("max_abs_lat_acc_mps2", "max", 7)]
    assert Criteria().check([_m("min_ttc_s", math.inf)]) == ()


def test_cumulative_failure_is_where_the_running_total_exceeds_the_limit() -> None:
    inc = np.zeros(20)
    inc[[2, 5, 9, 14]] = 1.0  # four fallbacks
    c = Criteria.from_overrides({"max_fallbacks": 2})
    (f,) = c.check([_m("fallbacks", 4.0, increments=inc)], 0.05 * np.arange(20))
    assert f.text == "fallbacks=4>2" and f.step == 9 and f.t_s == pytest.approx(0.45)


def test_optional_criteria_off_by_default() -> None:
    assert Criteria().check([_m("deadline_misses", 100.0), _m("min_gap_m", 0.1)]) == ()
    c = Criteria.from_overrides({"max_deadline_misses": 0, "min_gap_m": 1.0})
    assert [f.text for f in c.check([_m("deadline_misses", 3.0), _m("min_gap_m", 0.1)])] == [
        "min_gap_m=0.1<1", "deadline_misses=3>0"]


def test_catalog_criteria_then_explicit_overrides() -> None:
    trace = sr.turn_trace(radius_m=60.0, speed_mps=20.0)  # lat acc 6.67 m/s²
    road = sr.circle_road(60.0)
    plain = evaluate(sr.make_record(trace, road=road)).verdict
    assert plain.failed_text == "max_abs_lat_acc_mps2=6.667>4.89"
    relaxed = sr.make_record(trace, road=road,
                             info=sr.base_info("relaxed", criteria={"max_abs_lat_acc_mps2": 7.0}))
    assert evaluate(relaxed).verdict.status == "pass"
    assert evaluate(relaxed).verdict.criteria["max_abs_lat_acc_mps2"] == 7.0
    # explicit overrides win over the catalog's
    strict = evaluate(relaxed, {"max_abs_lat_acc_mps2": 6.0}).verdict
    assert strict.failed_text == "max_abs_lat_acc_mps2=6.667>6"
    assert strict.criteria["max_abs_lat_acc_mps2"] == 6.0
    bad = sr.make_record(trace, road=road, info=sr.base_info("bad", criteria={"lat_acc": 7.0}))
    with pytest.raises(ValueError, match="lat_acc"):
        evaluate(bad)
