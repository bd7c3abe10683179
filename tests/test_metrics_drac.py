"""DRAC (deceleration rate to avoid a crash, SUMO's SSM definition) on synthetic records
with hand-computed answers, and its invariants (reports.metrics.drac)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import synthetic_runs as sr

from reports.metrics import evaluate
from reports.metrics.context import build_context
from reports.metrics.drac import drac_metrics, drac_mps2, drac_series
from reports.metrics.ttc import ttc_pairs
from reports.record import Trace


def _drac(trace: Trace, nb: object = None) -> tuple[float, int | None, np.ndarray]:
    record = sr.make_record(trace, neighbours=nb)  # type: ignore[arg-type]
    ev = evaluate(record)
    m = ev.verdict.metric("max_drac_mps2")
    assert m is not None
    return m.value, m.worst_step, ev.series.drac_mps2


def test_hand_computed_approach() -> None:
    """Ego 20 m/s behind a 10 m/s car in its lane, the bumper gap closing to 20 m:
    DRAC = (20 - 10)^2 / (2 * 20) = 2.5 m/s^2 at the last row, and per row
    (v_f - v_l)^2 / (2 g(t)) with g(t) = 20 + 10 (t_end - t)."""
    trace, nb = sr.approach_run_parts(gap_end_m=20.0, ego_speed_mps=20.0, lead_speed_mps=10.0)
    value, row, series = _drac(trace, nb)
    assert value == pytest.approx(2.5, rel=1e-9)
    assert row == len(trace) - 1
    t = trace.t_s
    gap = 20.0 + 10.0 * (t[-1] - t)
    np.testing.assert_allclose(series, 100.0 / (2.0 * gap), rtol=1e-9)


def test_agrees_with_ttc_on_the_same_pair() -> None:
    """One definition of the pair: DRAC = closing / (2 TTC) for a constant-speed
    approach (TTC = gap / closing)."""
    trace, nb = sr.approach_run_parts(gap_end_m=12.0, ego_speed_mps=25.0, lead_speed_mps=19.0)
    record = sr.make_record(trace, neighbours=nb)
    ev = evaluate(record)
    np.testing.assert_allclose(ev.series.drac_mps2, 6.0 / (2.0 * ev.series.ttc_s), rtol=1e-9)


def test_zero_when_not_closing() -> None:
    """A faster car ahead (opening gap) or one at the same speed: 0, no worst row."""
    for lead_speed in (20.0, 26.0):
        trace = sr.straight_trace(3.0, 0.05, 20.0)
        lead_x = trace.ego.x_m + sr.EGO_LENGTH_M + 15.0 + (lead_speed - 20.0) * trace.t_s
        value, row, series = _drac(trace, sr.lead_vehicle(trace, lead_x, 0.0, lead_speed))
        assert value == 0.0 and row is None
        assert np.all(series == 0.0)


def test_zero_without_a_car_in_the_path() -> None:
    """No neighbour, or a slower car in the next lane (no overlap across the heading)."""
    trace = sr.straight_trace(3.0, 0.05, 20.0)
    assert _drac(trace)[:2] == (0.0, None)
    lead_x = trace.ego.x_m + sr.EGO_LENGTH_M + 15.0 - 10.0 * trace.t_s
    beside = sr.lead_vehicle(trace, lead_x, sr.LANE_WIDTH_M, 10.0)
    assert _drac(trace, beside)[:2] == (0.0, None)


def test_the_nearest_car_in_the_path_is_the_leader() -> None:
    """A car at the ego's speed 10 m ahead hides a stopped car 60 m ahead: DRAC 0."""
    trace = sr.straight_trace(2.0, 0.05, 20.0)
    near = sr.lead_vehicle(trace, trace.ego.x_m + sr.EGO_LENGTH_M + 10.0, 0.0, 20.0, vid="a")
    far_x = trace.ego.x_m[0] + sr.EGO_LENGTH_M + 60.0 + 0.0 * trace.t_s
    far = sr.lead_vehicle(trace, far_x, 0.0, 0.0, vid="b")
    both = type(near)(**{k: np.concatenate([getattr(near, k), getattr(far, k)])
                         for k in near.names()})
    assert _drac(trace, both)[:2] == (0.0, None)
    # the far car alone: (20 - 0)^2 / (2 g), largest at the smallest gap (the last row)
    value, row, _ = _drac(trace, far)
    gap_end = far_x[-1] - trace.ego.x_m[-1] - sr.EGO_LENGTH_M
    assert value == pytest.approx(400.0 / (2.0 * gap_end), rel=1e-9)
    assert row == len(trace) - 1


def test_formula_edge_cases() -> None:
    """closing^2 / (2 gap) while closing; 0 when not; NaN at a gap <= 0 (a contact, SUMO's
    invalid DRAC) or a non-finite input; a tiny gap gives a large finite value."""
    gap = np.array([20.0, 20.0, 20.0, 0.0, -1.0, 1e-9, np.nan, 5.0, np.inf])
    closing = np.array([10.0, 0.0, -3.0, 5.0, 5.0, 1.0, 1.0, np.nan, 2.0])
    out = drac_mps2(gap, closing)
    assert out[0] == pytest.approx(2.5)
    assert out[1] == 0.0 and out[2] == 0.0
    assert np.isnan(out[3]) and np.isnan(out[4])
    assert out[5] == pytest.approx(5e8) and np.isfinite(out[5])
    assert np.isnan(out[6]) and np.isnan(out[7]) and np.isnan(out[8])


def test_contact_rows_are_nan_and_skipped_by_the_maximum() -> None:
    """The lead box reaches the ego's front (gap <= 0) for the last rows, overlapping by
    up to 1 m (its centre still ahead): those rows are NaN, the maximum is over the
    finite rows before."""
    trace = sr.straight_trace(2.0, 0.05, 20.0)
    t = trace.t_s
    gap = np.maximum(10.25 - 10.0 * t, -1.0)  # 0.25 m at t = 1 s, then overlapping
    nb = sr.lead_vehicle(trace, trace.ego.x_m + sr.EGO_LENGTH_M + gap, 0.0, 10.0)
    value, row, series = _drac(trace, nb)
    assert np.all(np.isnan(series[gap < 0]))
    finite = gap > 0
    assert value == pytest.approx(float(np.max(100.0 / (2.0 * gap[finite]))), rel=1e-9)
    assert row == int(np.flatnonzero(finite)[-1])


def test_nan_without_rows_and_a_stopped_ego_does_not_count() -> None:
    record = sr.make_record(None)
    ctx = build_context(record)
    assert math.isnan(drac_metrics(ctx, drac_series(ctx, ttc_pairs(ctx)))[0].metric.value)
    trace = sr.straight_trace(2.0, 0.05, 0.0)  # waiting behind a stopped car
    nb = sr.lead_vehicle(trace, trace.ego.x_m + sr.EGO_LENGTH_M + 2.0, 0.0, 0.0)
    assert _drac(trace, nb)[:2] == (0.0, None)
