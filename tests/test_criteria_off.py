"""A criterion switched off from TOML with "off" (TOML has no null)."""

from __future__ import annotations

import pytest
import synthetic_runs as sr

from reports.metrics.criteria import OFF, Criteria, override_limit, override_problem


def test_off_switches_a_criterion_off() -> None:
    crit = Criteria.from_overrides({"min_ttc_s": "off", "max_abs_lat_acc_mps2": 3})
    assert crit.min_ttc_s is None and crit.max_abs_lat_acc_mps2 == 3.0
    assert override_limit(OFF) is None and override_limit(None) is None
    assert override_limit(2) == 2.0
    assert override_problem("off") is None and override_problem(1.5) is None


@pytest.mark.parametrize("bad", ["Off", "none", "", True, float("nan"), float("inf"), [1]])
def test_anything_else_is_refused_with_what_fits(bad: object) -> None:
    assert override_problem(bad) == 'a finite number or "off"'
    with pytest.raises(ValueError, match='finite number or "off"'):
        Criteria.from_overrides({"min_ttc_s": bad})


def test_a_run_judged_with_a_criterion_off_does_not_fail_it() -> None:
    # a sharp turn fails lateral acceleration by default, not once it is off
    record = sr.make_record(sr.turn_trace(radius_m=60.0, speed_mps=20.0),
                            road=sr.circle_road(60.0))
    judged = sr.judge(record)
    assert judged.verdict is not None
    assert "max_abs_lat_acc_mps2" in {f.criterion for f in judged.verdict.failures}
    off = sr.judge(record, {"max_abs_lat_acc_mps2": "off", "max_abs_yaw_rate_radps": OFF})
    assert off.verdict is not None
    assert "max_abs_lat_acc_mps2" not in {f.criterion for f in off.verdict.failures}
    assert off.verdict.criteria["max_abs_lat_acc_mps2"] is None
