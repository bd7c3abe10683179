"""Metrics on synthetic typed records with known answers, and where failures are located."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import synthetic_runs as sr

from reports.geometry import box_corners
from reports.metrics import REQUIRED_METRICS, Evaluation, evaluate, signal
from reports.metrics.collisions import classify_collisions
from reports.metrics.comfort import sg_window
from reports.metrics.context import build_context
from reports.metrics.drivable import OFFROAD_TOLERANCE_M
from reports.metrics.ttc import swept_box_ttc
from reports.record import Failure, RunOutcome, RunRecord, Trace, load_run
from reports.record.codec import to_plain


def _judge(trace: Trace | None, overrides: dict[str, Any] | None = None, **kw: Any
           ) -> tuple[RunRecord, Evaluation]:
    record = sr.make_record(trace, **kw)
    return record, evaluate(record, overrides)


def _values(trace: Trace | None, **kw: Any) -> dict[str, float]:
    return _judge(trace, **kw)[1].verdict.values()


def _failed(trace: Trace | None, overrides: dict[str, Any] | None = None, **kw: Any
            ) -> list[str]:
    return [f.text for f in _judge(trace, overrides, **kw)[1].verdict.failures]


# --------------------------------------------------------------------------- comfort


def test_constant_radius_turn() -> None:
    _, ev = _judge(sr.turn_trace(radius_m=100.0, speed_mps=20.0), road=sr.circle_road(100.0))
    m = ev.verdict.values()
    assert m["max_abs_lat_acc_mps2"] == pytest.approx(4.0, abs=1e-9)
    assert m["rms_lat_acc_mps2"] == pytest.approx(4.0, abs=1e-9)
    assert m["max_abs_yaw_rate_radps"] == pytest.approx(0.2, abs=1e-9)
    assert m["max_abs_yaw_acc_radps2"] == pytest.approx(0.0, abs=1e-9)
    assert m["max_long_acc_mps2"] == pytest.approx(0.0, abs=1e-9)
    assert m["max_abs_long_jerk_mps3"] == pytest.approx(0.0, abs=1e-9)
    # the acceleration vector (4 m/s², toward the centre) turns at 0.2 rad/s: |j| = 0.8
    assert m["max_abs_jerk_mps3"] == pytest.approx(0.8, abs=1e-3)
    assert ev.verdict.status == "pass", ev.verdict.failed_text
    assert m["offroad_s"] == 0.0


def test_turn_derived_from_pose_when_columns_missing() -> None:
    trace = sr.turn_trace(radius_m=100.0, speed_mps=20.0)
    for col in (trace.ego.r_radps, trace.ego.lat_acc_mps2, trace.ego.long_acc_mps2):
        col[:] = np.nan
    m = _values(trace, road=sr.circle_road(100.0))
    assert m["max_abs_yaw_rate_radps"] == pytest.approx(0.2, abs=1e-6)
    assert m["max_abs_lat_acc_mps2"] == pytest.approx(4.0, abs=1e-4)


def test_jerk_of_acceleration_ramp() -> None:
    _, ev = _judge(sr.accel_ramp_trace(jerk_mps3=2.0, duration_s=2.0, dt_s=0.02))
    m = ev.verdict.values()
    assert m["max_abs_long_jerk_mps3"] == pytest.approx(2.0, abs=1e-9)
    assert m["max_abs_jerk_mps3"] == pytest.approx(2.0, abs=1e-9)
    assert m["max_long_acc_mps2"] == pytest.approx(4.0, abs=1e-9)
    assert m["min_long_acc_mps2"] == pytest.approx(0.04, abs=1e-9)
    assert "max_long_acc_mps2=4>2.4" in [f.text for f in ev.verdict.failures]
    assert ev.verdict.status == "fail"


def test_sg_window_scales_with_period() -> None:
    assert sg_window(1000, 0.1) == 5  # nuPlan: 5 samples at 10 Hz
    assert sg_window(1000, 0.05) == 11
    assert sg_window(1000, 0.02) == 25
    assert sg_window(4, 0.02) == 3


# --------------------------------------------------------------------------- drivable area


@pytest.mark.parametrize(("over_m", "violation"), [(0.5, True), (0.2, False), (0.0, False)])
def test_box_over_lane_edge(over_m: float, violation: bool) -> None:
    # one lane centred on y = 0, width 3.5: left edge y = 1.75; ego half width 0.9
    y = 1.75 - 0.9 + over_m
    _, ev = _judge(sr.straight_trace(5.0, 0.05, 20.0, y_m=y), road=sr.straight_road(n_lanes=1))
    m = ev.verdict.values()
    assert m["max_offroad_m"] == pytest.approx(max(over_m, 0.0), abs=1e-9)
    if violation:
        assert m["max_offroad_m"] > OFFROAD_TOLERANCE_M
        assert m["offroad_s"] == pytest.approx(5.0)
        assert m["offroad_m"] == pytest.approx(100.0)
        assert any(f.text.startswith("offroad_s=5>0") for f in ev.verdict.failures)
    else:
        assert m["offroad_s"] == 0.0


def test_union_of_lanes_is_drivable() -> None:
    # straddling the line between lanes 0 and 1 is not off-road
    m = _values(sr.straight_trace(5.0, 0.05, 20.0, y_m=1.75), road=sr.straight_road(n_lanes=2))
    assert m["offroad_s"] == 0.0


@pytest.mark.parametrize("allow", [False, True])
def test_shoulder_counts_only_when_allowed(allow: bool) -> None:
    trace = sr.straight_trace(4.0, 0.05, 20.0, y_m=-3.5)  # centred on the shoulder
    m = _values(trace, road=sr.straight_road(n_lanes=2, shoulder=True),
                info=sr.base_info("sh", allow_shoulder=allow))
    assert m["shoulder_s"] == pytest.approx(4.0)
    assert m["offroad_s"] == (0.0 if allow else pytest.approx(4.0))


def test_non_passenger_lane_is_not_drivable() -> None:
    bus = sr.with_lane(sr.straight_road(n_lanes=2), 1, allowed=("bus",), allows_passenger=False)
    m = _values(sr.straight_trace(3.0, 0.05, 20.0, y_m=3.5), road=bus)
    assert m["offroad_s"] == pytest.approx(3.0)
    # the record's allows_passenger flag decides, whatever the class list says
    flagged = sr.with_lane(bus, 1, allowed=("passenger",), allows_passenger=False)
    assert _values(sr.straight_trace(3.0, 0.05, 20.0, y_m=3.5),
                   road=flagged)["offroad_s"] == pytest.approx(3.0)


# --------------------------------------------------------------------------- TTC


def _box(x: float, y: float = 0.0, h: float = 0.0) -> np.ndarray:
    return box_corners(x, y, h, 4.6, 1.8)


def test_swept_box_ttc_known_answers() -> None:
    # bumper gap 20 m, closing at 10 m/s -> 2.0 s
    ego, lead = _box(0.0), _box(4.6 + 20.0)
    assert swept_box_ttc(ego, np.array([20.0, 0.0]), lead, np.array([10.0, 0.0])) == \
        pytest.approx(2.0)
    # opening gap, or same speed: never
    assert swept_box_ttc(ego, np.array([10.0, 0.0]), lead, np.array([20.0, 0.0])) == math.inf
    assert swept_box_ttc(ego, np.array([10.0, 0.0]), lead, np.array([10.0, 0.0])) == math.inf
    # adjacent lane: passes without touching
    assert swept_box_ttc(ego, np.array([20.0, 0.0]), _box(24.6, 3.5),
                         np.array([10.0, 0.0])) == math.inf
    # overlapping now -> 0
    assert swept_box_ttc(ego, np.array([0.0, 0.0]), _box(3.0), np.array([0.0, 0.0])) == 0.0
    # beyond the 10 s horizon -> inf
    assert swept_box_ttc(ego, np.array([11.0, 0.0]), _box(4.6 + 20.0),
                         np.array([10.0, 0.0])) == math.inf
    # crossing: a box 10 m to the left driving right at 5 m/s toward the waiting ego's
    # path touches when its near side reaches y = 0.9
    crossing = _box(0.0, 10.0, -math.pi / 2)
    ttc = swept_box_ttc(ego, np.array([0.0, 0.0]), crossing, np.array([0.0, -5.0]))
    assert ttc == pytest.approx((10.0 - 2.3 - 0.9) / 5.0)


def test_run_min_ttc_approach() -> None:
    trace, nb = sr.approach_run_parts(gap_end_m=20.0, ego_speed_mps=20.0, lead_speed_mps=10.0)
    _, ev = _judge(trace, neighbours=nb)
    m = ev.verdict.values()
    assert m["min_ttc_s"] == pytest.approx(2.0, abs=1e-9)
    assert m["min_gap_m"] == pytest.approx(20.0)
    assert ev.verdict.status == "pass"
    # the series the verdict is the minimum of: 20 m / 10 m/s at the last step
    assert ev.series.ttc_s[-1] == pytest.approx(2.0)
    assert ev.verdict.metric("min_ttc_s").worst_step == len(trace) - 1  # type: ignore[union-attr]


def test_ttc_below_limit_fails() -> None:
    trace, nb = sr.approach_run_parts(gap_end_m=5.0, ego_speed_mps=20.0, lead_speed_mps=10.0)
    assert "min_ttc_s=0.5<0.95" in _failed(trace, neighbours=nb)


def test_ttc_ignored_while_stationary_behind_stopped_car() -> None:
    trace = sr.straight_trace(3.0, 0.05, 0.0)
    nb = sr.lead_vehicle(trace, np.full(len(trace), 4.6 + 0.5), 0.0, 0.0)
    trace.safety.min_gap_m[:] = 0.5
    _, ev = _judge(trace, neighbours=nb)
    assert ev.verdict.value("min_ttc_s") == math.inf
    assert not any(f.metric == "min_ttc_s" for f in ev.verdict.failures)


def test_ttc_from_behind_is_reported_separately() -> None:
    trace = sr.straight_trace(2.0, 0.05, 5.0)
    ego_x = trace.ego.x_m
    follower_x = ego_x[0] - 4.6 - 30.0 + 15.0 * (trace.t_s - 0.05)
    nb = sr.lead_vehicle(trace, follower_x, 0.0, 15.0, vid="fast")
    m = _values(trace, neighbours=nb)
    assert m["min_ttc_s"] == math.inf
    gap_end = ego_x[-1] - follower_x[-1] - 4.6
    assert m["min_ttc_rear_s"] == pytest.approx(gap_end / 10.0, rel=1e-9)


# --------------------------------------------------------------------------- safety misc


def test_collision_flags() -> None:
    trace = sr.straight_trace(2.0, 0.05, 20.0)
    assert _values(trace)["collision"] == 0.0
    t2 = sr.straight_trace(2.0, 0.05, 20.0)
    t2.safety.sumo_collision[10] = True
    _, ev = _judge(t2)
    # SUMO's flag alone is no collision (the verdict rests on the 2-D boxes): it is
    # counted beside the verdict and listed as a disagreement, never a failure
    assert ev.verdict.value("collision") == 0.0
    assert math.isnan(ev.verdict.value("first_collision_t_s"))
    assert ev.verdict.value("sumo_collision_steps") == 1.0
    assert ev.verdict.value("sumo_only_collisions") == 1.0
    assert not ev.verdict.failures
    t3 = sr.straight_trace(2.0, 0.05, 20.0)
    t3.safety.geom_collision[5:8] = True
    m3 = _values(t3)
    assert m3["geom_collision_steps"] == 3.0
    # the monitor's overlap flag is a contact: no vehicle recorded, so unclassified
    assert m3["collision"] == 1.0 and m3["first_collision_t_s"] == pytest.approx(0.3)
    assert m3["collisions_unclassified"] == 1.0


def test_ellipse_margin() -> None:
    trace = sr.straight_trace(10.0, 0.05, 20.0)  # passes x = 100 at y = 0
    m = _values(trace, arrays=sr.ellipse_arrays(trace, (100.0, 3.0), 6.0, 2.0))
    assert m["min_ellipse_margin"] == pytest.approx((3.0 / 2.0) ** 2 - 1.0)
    m2 = _values(trace, arrays=sr.ellipse_arrays(trace, (100.0, 1.0), 6.0, 2.0))
    assert m2["min_ellipse_margin"] == pytest.approx(0.25 - 1.0)
    assert math.isnan(_values(trace)["min_ellipse_margin"])


# --------------------------------------------------------------------------- tracking


def test_progress_ratio() -> None:
    ok = _values(sr.straight_trace(10.0, 0.05, 20.0))
    assert ok["progress_ratio"] == pytest.approx(1.0)
    assert ok["progress_m"] == pytest.approx(199.0)  # 20 m/s from t = 0.05 s to 10 s
    slow = _judge(sr.straight_trace(10.0, 0.05, 8.0, target_speed_mps=20.0))[1].verdict
    assert slow.value("progress_ratio") == pytest.approx(0.4)
    assert "progress_ratio=0.4<0.5" in [f.text for f in slow.failures]
    # an aggregate: no step to point at
    assert [f.step for f in slow.failures if f.metric == "progress_ratio"] == [None]
    # a route shorter than the run caps the expectation
    short = _values(sr.straight_trace(10.0, 0.05, 20.0), road=sr.straight_road(length_m=100.0))
    assert short["expected_progress_m"] == pytest.approx(100.0)
    assert short["progress_ratio"] > 1.0


def test_twenty_metres_per_second_for_two_seconds_is_forty_metres() -> None:
    m = _values(sr.straight_trace(2.0, 0.05, 20.0))
    assert m["progress_m"] == pytest.approx(20.0 * (2.0 - 0.05))
    assert m["expected_progress_m"] == pytest.approx(20.0 * (2.0 - 0.05))
    assert m["mean_speed_mps"] == pytest.approx(20.0)


def test_lat_dev_and_speed() -> None:
    trace = sr.straight_trace(4.0, 0.05, 18.0, target_speed_mps=20.0)
    trace.ego.lat_dev_m[:] = np.where(np.arange(len(trace)) % 2 == 0, 0.3, -0.3)
    m = _values(trace)
    assert m["rms_lat_dev_m"] == pytest.approx(0.3)
    assert m["max_abs_lat_dev_m"] == pytest.approx(0.3)
    assert m["mean_speed_mps"] == pytest.approx(18.0)
    assert m["mean_speed_error_mps"] == pytest.approx(-2.0)


def test_final_lat_dev_is_taken_over_the_last_two_seconds() -> None:
    trace = sr.straight_trace(10.0, 0.05, 20.0)
    t = trace.t_s
    # 1.5 m out until 7.5 s, then 0.2 m: the last 2 s (from 7.95 s) see only 0.2 m.
    trace.ego.lat_dev_m[:] = np.where(t < 7.5, 1.5, 0.2)
    m = _values(trace, info=sr.base_info("f", criteria={"max_final_abs_lat_dev_m": 0.3}))
    assert m["final_abs_lat_dev_m"] == pytest.approx(0.2)
    trace.ego.lat_dev_m[:] = np.where(t < 8.5, 0.0, -0.45)
    failed = _failed(trace, {"max_final_abs_lat_dev_m": 0.3})
    assert "final_abs_lat_dev_m=0.45>0.3" in failed


# --------------------------------------------------------------------------- timing


def test_timing_and_deadline_misses() -> None:
    trace = sr.straight_trace(5.0, 0.05, 20.0)
    n = len(trace)
    ctrl = np.full(n, 0.002)
    late = [3, 10, 50, 51, 52, 60, 99]
    ctrl[late] = 0.06  # 7 steps over the 50 ms period
    trace.timing.controller_s[:] = ctrl
    trace.controller.outer_s[:] = 0.001
    trace.controller.fallback[:2] = True
    trace.controller.guard_fired[2] = 3
    trace.controller.residual[:] = np.linspace(1e-3, 1e-5, n)
    _, ev = _judge(trace, outcome=RunOutcome(sim_time_s=5.0, wall_s=2.5),
                   info=sr.base_info("t", criteria={"max_deadline_misses": 4}))
    m = ev.verdict.values()
    assert m["deadline_misses"] == 7.0
    assert m["step_ms_p50"] == pytest.approx(2.0)
    assert m["step_ms_max"] == pytest.approx(60.0)
    assert m["step_var_s2"] == pytest.approx(float(np.var(ctrl)))
    assert m["outer_ms_p99"] == pytest.approx(1.0)
    assert m["realtime_factor"] == pytest.approx(2.0)
    assert m["residual_max"] == pytest.approx(1e-3)
    assert m["residual_final"] == pytest.approx(1e-5)
    assert m["fallbacks"] == 2.0
    assert m["guards"] == 3.0
    assert m["deadline_miss_frac"] == pytest.approx(7 / n)
    # at most 4 misses allowed: the 5th late step is where the run failed
    (miss,) = [f for f in ev.verdict.failures if f.metric == "deadline_misses"]
    assert miss.text == "deadline_misses=7>4" and miss.step == late[4]
    assert miss.t_s == pytest.approx(trace.t_s[late[4]])


# --------------------------------------------------------------------------- the verdict


def test_required_metric_names_and_kinds() -> None:
    _, ev = _judge(sr.lane_change_trace())
    names = [m.name for m in ev.verdict.metrics]
    assert names[: len(REQUIRED_METRICS)] == list(REQUIRED_METRICS)
    assert names[len(REQUIRED_METRICS):] == sorted(names[len(REQUIRED_METRICS):])
    assert ev.verdict.status == "pass" and ev.verdict.failed_text == ""
    kinds = {m.name: m.kind for m in ev.verdict.metrics}
    assert kinds["collision"] == "safety" and kinds["max_abs_jerk_mps3"] == "comfort"
    assert kinds["rms_lat_dev_m"] == "tracking" and kinds["step_ms_p99"] == "timing"
    assert kinds["residual_max"] == "health"
    units = {m.name: m.unit for m in ev.verdict.metrics}
    assert units["min_gap_m"] == "m" and units["max_abs_lat_acc_mps2"] == "m/s^2"
    assert units["step_ms_p99"] == "ms" and units["min_ttc_s"] == "s"
    assert ev.verdict.criteria["max_abs_lat_acc_mps2"] == 4.89


def test_empty_trace_fails_steps() -> None:
    record, ev = _judge(None)
    assert ev.verdict.status == "fail"
    assert [f.text for f in ev.verdict.failures] == ["steps=0<1"]
    assert {m.name for m in ev.verdict.metrics} >= set(REQUIRED_METRICS)
    assert math.isnan(ev.verdict.value("max_abs_lat_acc_mps2"))
    assert len(ev.series) == 0 == len(record.trace)


@pytest.mark.parametrize("end", ["error", "timeout"])
def test_unfinished_run_keeps_its_end_and_what_was_recorded(end: str) -> None:
    trace = sr.straight_trace(2.0, 0.05, 20.0)
    _, ev = _judge(trace, outcome=RunOutcome(end=end, error="boom", sim_time_s=2.0,
                                             wall_s=1.0))
    assert ev.verdict.status == end
    assert ev.verdict.value("progress_m") == pytest.approx(39.0)
    assert len(ev.series) == len(trace)


def test_verdict_round_trips_through_the_run_directory(tmp_path: Path) -> None:
    trace, nb = sr.approach_run_parts(gap_end_m=5.0)
    record = sr.judge(sr.make_record(trace, neighbours=nb))
    sr.write_judged(record, tmp_path / "run")
    back = load_run(tmp_path / "run")
    assert back.verdict is not None and back.series is not None
    assert json.dumps(to_plain(back.verdict)) == json.dumps(to_plain(record.verdict))
    for name, values in record.series.columns():  # type: ignore[union-attr]
        np.testing.assert_array_equal(getattr(back.series, name), values)


# --------------------------------------------------------------------------- locating


def _drift_off_road() -> tuple[Trace, dict[str, Any]]:
    """Drives straight, then drifts left off a one-lane road: off-road from some step on."""
    trace = sr.straight_trace(6.0, 0.05, 20.0)
    t = trace.t_s
    trace.ego.y_m[:] = np.where(t > 2.0, 1.0 * (t - 2.0), 0.0)
    trace.ego.lat_dev_m[:] = trace.ego.y_m
    return trace, {"road": sr.straight_road(n_lanes=1)}


def _sharp_turn_ramp() -> tuple[Trace, dict[str, Any]]:
    """A turn whose lateral acceleration ramps up: the comfort limits fail at the end."""
    trace = sr.turn_trace(radius_m=60.0, speed_mps=20.0)
    trace.ego.lat_acc_mps2[:] *= np.linspace(0.2, 1.0, len(trace))
    return trace, {"road": sr.circle_road(60.0)}


def _rear_end() -> tuple[Trace, dict[str, Any]]:
    trace, nb = sr.approach_run_parts(gap_end_m=0.0, duration_s=4.0)
    trace.safety.geom_collision[-5:] = True
    return trace, {"neighbours": nb}


def _fallbacks() -> tuple[Trace, dict[str, Any]]:
    trace = sr.straight_trace(3.0, 0.05, 20.0)
    trace.controller.fallback[[7, 20, 21, 40]] = True
    return trace, {"info": sr.base_info("fb", criteria={"max_fallbacks": 2})}


FAILING = {"drift_off_road": _drift_off_road, "sharp_turn_ramp": _sharp_turn_ramp,
           "rear_end": _rear_end, "fallbacks": _fallbacks,
           "accel_ramp": lambda: (sr.accel_ramp_trace(jerk_mps3=3.0, duration_s=3.0), {})}
# cumulative metrics: per-step contributions of a run, in the metric's unit
CUMULATIVE = {
    "collision": lambda r, e: np.bincount(
        [c.row for c in classify_collisions(build_context(r))][:1],
        minlength=len(r.trace)).astype(float),
    "at_fault_collisions": lambda r, e: np.bincount(
        [c.row for c in classify_collisions(build_context(r)) if c.at_fault],
        minlength=len(r.trace)).astype(float),
    "offroad_s": lambda r, e: np.where(e.series.offroad_excess_m > OFFROAD_TOLERANCE_M,
                                       0.05, 0.0),
    "fallbacks": lambda r, e: r.trace.controller.fallback.astype(float),
}


def _check_located(record: RunRecord, ev: Evaluation, failure: Failure) -> None:
    assert failure.step is not None, failure
    assert failure.t_s == pytest.approx(record.trace.t_s[failure.step])
    if failure.metric in CUMULATIVE:
        total = np.cumsum(CUMULATIVE[failure.metric](record, ev))
        # the running total crosses the limit at this step, not before
        assert total[failure.step] > failure.limit, failure
        assert failure.step == 0 or total[failure.step - 1] <= failure.limit, failure
        return
    metric = ev.verdict.metric(failure.metric)
    assert metric is not None and metric.series, failure
    values = signal(metric.series, record.trace, ev.series)
    assert values is not None
    here = abs(values[failure.step]) if "_abs_" in metric.name else values[failure.step]
    assert here == pytest.approx(failure.value), failure
    assert (here > failure.limit) if failure.bound == "max" else (here < failure.limit)


@pytest.mark.parametrize("case", sorted(FAILING))
def test_each_failure_is_located_where_its_series_crosses_the_limit(case: str) -> None:
    trace, kw = FAILING[case]()
    record, ev = _judge(trace, **kw)
    located = [f for f in ev.verdict.failures if f.metric not in ("progress_ratio",)]
    assert located, ev.verdict.failed_text
    for failure in located:
        _check_located(record, ev, failure)


def test_located_failures_of_known_runs() -> None:
    trace, kw = _drift_off_road()
    record, ev = _judge(trace, **kw)
    (off,) = [f for f in ev.verdict.failures if f.metric == "offroad_s"]
    # the left corners leave the lane (edge 1.75 m) by 0.3 m when y + 0.9 > 2.05
    first = int(np.flatnonzero(record.trace.ego.y_m + 0.9 > 1.75 + OFFROAD_TOLERANCE_M)[0])
    assert off.step == first
    trace, kw = _rear_end()
    record, ev = _judge(trace, **kw)
    (hit,) = [f for f in ev.verdict.failures if f.metric == "at_fault_collisions"]
    assert hit.step == len(trace) - 5  # the monitor's first overlap flag with the lead


def _worst_case_records() -> list[tuple[RunRecord, Evaluation]]:
    trace = sr.lane_change_trace()
    nb = sr.lead_vehicle(trace, 60.0 + 18.0 * trace.t_s, 0.0, 18.0)
    trace.safety.min_gap_m[:] = np.abs(nb.x_m - trace.ego.x_m) - 4.6
    arrays = sr.ellipse_arrays(trace, (150.0, 0.3), 6.6, 2.2)
    cases = [_judge(trace, neighbours=nb, arrays=arrays)]
    for build in (_sharp_turn_ramp, _rear_end, _drift_off_road):
        tr, kw = build()
        cases.append(_judge(tr, **kw))
    return cases


def test_worst_step_points_at_the_extreme_of_its_series() -> None:
    checked = set()
    for record, ev in _worst_case_records():
        for m in ev.verdict.metrics:
            if m.worst_step is None or not m.series:
                continue
            values = signal(m.series, record.trace, ev.series)
            assert values is not None, m
            v = np.abs(values) if "_abs_" in m.name else values
            assert v[m.worst_step] == m.value, m
            if m.name != "final_abs_lat_dev_m":  # an extreme over the last 2 s only
                finite = v[np.isfinite(v)]
                extreme = finite.min() if m.name.startswith("min_") else finite.max()
                assert m.value == extreme, m
            checked.add(m.name)
    assert {"min_gap_m", "min_ttc_s", "min_ellipse_margin", "max_abs_lat_acc_mps2",
            "max_abs_jerk_mps3", "min_long_acc_mps2", "max_offroad_m", "residual_max",
            "max_abs_lat_dev_m"} <= checked


def test_series_have_one_row_per_trace_row() -> None:
    for record, ev in _worst_case_records():
        for name, values in ev.series.columns():
            assert values.shape == (len(record.trace),), name
    # the copy the runner stores carries this verdict and these series
    record, ev = _worst_case_records()[0]
    stored = ev.apply(record)
    assert stored.series is ev.series and stored.verdict is ev.verdict
    assert record.verdict is None  # the record itself is left as it was
