"""R157's minimum following time gap (reports.metrics.r157) on synthetic records with
hand-computed answers: t_min = 1.0 s + v[km/h] / 100, shortfalls beyond the 3 s
readjustment counted."""

from __future__ import annotations

import numpy as np
import pytest
import synthetic_runs as sr

from reports.metrics import evaluate
from reports.metrics.criteria import Criteria
from reports.metrics.r157 import READJUST_S, min_time_gap_s
from reports.record import Trace

DT = 0.05


def _shortfall(trace: Trace, gap_m: np.ndarray, speed_mps: float) -> tuple[float, int | None]:
    """The metric for a lead in the ego's lane at bumper gap ``gap_m`` (per row)."""
    lead_x = trace.ego.x_m + sr.EGO_LENGTH_M + gap_m
    record = sr.make_record(trace, neighbours=sr.lead_vehicle(trace, lead_x, 0.0, speed_mps))
    m = evaluate(record).verdict.metric("r157_gap_shortfall_s")
    assert m is not None
    return m.value, m.worst_step


def test_the_regulations_table() -> None:
    # 7.2 km/h -> 1.07 (the table rounds to 1.0), 10 km/h -> 1.1, 60 km/h -> 1.6,
    # 130 km/h -> 2.3 (the 01 series' extension)
    got = min_time_gap_s(np.array([7.2, 10.0, 60.0, 130.0]) / 3.6)
    np.testing.assert_allclose(got, [1.072, 1.1, 1.6, 2.3], rtol=1e-12)


def test_a_steady_short_gap_counts_beyond_the_readjustment() -> None:
    """20 m/s (72 km/h: t_min 1.72 s, 34.4 m) at 30 m (1.5 s) for the whole run."""
    trace = sr.straight_trace(10.0, DT, 20.0)
    n = len(trace)
    value, row = _shortfall(trace, np.full(n, 30.0), 20.0)
    assert value == pytest.approx(n * DT - READJUST_S, abs=1e-9)
    assert row == int(round(READJUST_S / DT))  # the first row past the grace


def test_a_gap_at_or_above_the_minimum_is_not_short() -> None:
    trace = sr.straight_trace(10.0, DT, 20.0)
    assert _shortfall(trace, np.full(len(trace), 35.0), 20.0) == (0.0, None)


def test_short_episodes_within_the_readjustment_do_not_count() -> None:
    """A cut-in at 30 m for 2.5 s, then the gap restored: nothing counts."""
    trace = sr.straight_trace(10.0, DT, 20.0)
    t = trace.t_s
    gap = np.where((t >= 2.0) & (t < 4.5), 30.0, 40.0)
    assert _shortfall(trace, gap, 20.0) == (0.0, None)


def test_each_episode_gets_its_own_readjustment() -> None:
    """Two 4 s episodes: 1 s beyond the grace each, 2 s in all."""
    trace = sr.straight_trace(12.0, DT, 20.0)
    t = trace.t_s
    short = ((t >= 1.0) & (t < 5.0)) | ((t >= 6.0) & (t < 10.0))
    gap = np.where(short, 30.0, 40.0)
    value, _ = _shortfall(trace, gap, 20.0)
    assert value == pytest.approx(2.0, abs=DT + 1e-9)


def test_below_7_2_kmh_the_regulation_asks_nothing() -> None:
    trace = sr.straight_trace(10.0, DT, 1.5)
    assert _shortfall(trace, np.full(len(trace), 0.5), 1.5) == (0.0, None)


def test_the_criterion_is_off_unless_a_catalog_sets_it() -> None:
    assert Criteria().as_dict()["max_r157_gap_shortfall_s"] is None
    trace = sr.straight_trace(10.0, DT, 20.0)
    lead_x = trace.ego.x_m + sr.EGO_LENGTH_M + 30.0
    record = sr.make_record(trace, neighbours=sr.lead_vehicle(trace, lead_x, 0.0, 20.0))
    off = evaluate(record).verdict
    assert "max_r157_gap_shortfall_s" not in [f.criterion for f in off.failures]
    on = evaluate(record, {"max_r157_gap_shortfall_s": 0.0}).verdict
    assert "max_r157_gap_shortfall_s" in [f.criterion for f in on.failures]
    assert on.criteria["max_r157_gap_shortfall_s"] == 0.0
