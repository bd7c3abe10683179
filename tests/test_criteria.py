"""Criteria defaults, overrides and failure strings."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
import synthetic_runs as sr

from reports.metrics import Criteria, evaluate_run
from reports.metrics.criteria import parse_failure
from reports.run_record import load_run


def test_nuplan_defaults() -> None:
    c = Criteria()
    assert (c.min_long_acc_mps2, c.max_long_acc_mps2) == (-4.05, 2.40)
    assert c.max_abs_lat_acc_mps2 == 4.89
    assert c.max_abs_yaw_acc_radps2 == 1.93
    assert c.max_abs_yaw_rate_radps == 0.95
    assert c.max_abs_long_jerk_mps3 == 4.13
    assert c.max_abs_jerk_mps3 == 8.37
    assert c.min_ttc_s == 0.95
    assert c.max_collision == 0.0 and c.max_offroad_s == 0.0
    assert c.min_progress_fraction == 0.5
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


def test_check_formats_failures() -> None:
    c = Criteria()
    failed = c.check({"max_abs_lat_acc_mps2": 5.0, "min_long_acc_mps2": -5.0,
                      "min_ttc_s": 0.5, "collision": 1.0, "offroad_s": math.nan})
    assert failed == ["collision=1>0", "min_ttc_s=0.5<0.95", "min_long_acc_mps2=-5<-4.05",
                      "max_abs_lat_acc_mps2=5>4.89"]
    assert parse_failure("min_ttc_s=0.5<0.95") == ("min_ttc_s", 0.5, "<", 0.95)
    assert c.check({"min_ttc_s": math.inf}) == []


def test_optional_criteria_off_by_default() -> None:
    assert Criteria().check({"deadline_misses": 100.0, "min_gap_m": 0.1}) == []
    c = Criteria.from_overrides({"max_deadline_misses": 0, "min_gap_m": 1.0})
    assert c.check({"deadline_misses": 3.0, "min_gap_m": 0.1}) == [
        "min_gap_m=0.1<1", "deadline_misses=3>0"]


def test_run_json_criteria_and_explicit_overrides(tmp_path: Path) -> None:
    trace = sr.turn_trace(radius_m=60.0, speed_mps=20.0)  # lat acc 6.67 m/s²
    road = sr.circle_road(60.0)
    plain = load_run(sr.write_run(tmp_path / "plain", trace, road=road))
    assert evaluate_run(plain).failed == ["max_abs_lat_acc_mps2=6.667>4.89"]
    relaxed_meta = sr.base_meta("relaxed", criteria={"max_abs_lat_acc_mps2": 7.0})
    relaxed = load_run(sr.write_run(tmp_path / "relaxed", trace, road=road, meta=relaxed_meta))
    assert evaluate_run(relaxed).status == "pass"
    # explicit overrides win over run.json
    strict = evaluate_run(relaxed, {"max_abs_lat_acc_mps2": 6.0})
    assert strict.failed == ["max_abs_lat_acc_mps2=6.667>6"]
    assert strict.failed_criteria == "max_abs_lat_acc_mps2=6.667>6"
    bad_meta = sr.base_meta("bad", criteria={"lat_acc": 7.0})
    bad = load_run(sr.write_run(tmp_path / "bad", trace, road=road, meta=bad_meta))
    with pytest.raises(ValueError, match="lat_acc"):
        evaluate_run(bad)
