"""Metrics on synthetic traces with known answers."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import synthetic_runs as sr

from reports.metrics import REQUIRED_METRICS, evaluate_run
from reports.metrics.comfort import comfort_metrics, sg_window
from reports.metrics.geometry import box_corners
from reports.metrics.safety import (
    OFFROAD_TOLERANCE_M,
    min_ttc_rear_s,
    min_ttc_s,
    offroad_metrics,
    swept_box_ttc,
)
from reports.metrics.timing import timing_metrics
from reports.metrics.tracking import progress_ratio
from reports.run_record import load_run


def _load(tmp_path: Path, trace, name: str = "run", **kw):
    meta = kw.pop("meta", None) or sr.base_meta(name, **kw.pop("meta_kw", {}))
    return load_run(sr.write_run(tmp_path / name, trace, meta=meta, **kw))


# --------------------------------------------------------------------------- comfort


def test_constant_radius_turn(tmp_path: Path) -> None:
    rec = _load(tmp_path, sr.turn_trace(radius_m=100.0, speed_mps=20.0),
                road=sr.circle_road(100.0))
    m = comfort_metrics(rec)
    assert m["max_abs_lat_acc_mps2"] == pytest.approx(4.0, abs=1e-9)
    assert m["rms_lat_acc_mps2"] == pytest.approx(4.0, abs=1e-9)
    assert m["max_abs_yaw_rate_radps"] == pytest.approx(0.2, abs=1e-9)
    assert m["max_abs_yaw_acc_radps2"] == pytest.approx(0.0, abs=1e-9)
    assert m["max_long_acc_mps2"] == pytest.approx(0.0, abs=1e-9)
    assert m["max_abs_long_jerk_mps3"] == pytest.approx(0.0, abs=1e-9)
    # the acceleration vector (4 m/s², toward the centre) turns at 0.2 rad/s: |j| = 0.8
    assert m["max_abs_jerk_mps3"] == pytest.approx(0.8, abs=1e-3)
    result = evaluate_run(rec)
    assert result.status == "pass", result.failed
    assert result.metrics["offroad_s"] == 0.0


def test_turn_derived_from_pose_when_columns_missing(tmp_path: Path) -> None:
    trace = sr.turn_trace(radius_m=100.0, speed_mps=20.0)
    for col in ("r_radps", "lat_acc_mps2", "long_acc_mps2"):
        trace[col] = np.nan
    m = comfort_metrics(_load(tmp_path, trace, road=sr.circle_road(100.0)))
    assert m["max_abs_yaw_rate_radps"] == pytest.approx(0.2, abs=1e-6)
    assert m["max_abs_lat_acc_mps2"] == pytest.approx(4.0, abs=1e-4)


def test_jerk_of_acceleration_ramp(tmp_path: Path) -> None:
    rec = _load(tmp_path, sr.accel_ramp_trace(jerk_mps3=2.0, duration_s=2.0, dt_s=0.02))
    m = comfort_metrics(rec)
    assert m["max_abs_long_jerk_mps3"] == pytest.approx(2.0, abs=1e-9)
    assert m["max_abs_jerk_mps3"] == pytest.approx(2.0, abs=1e-9)
    assert m["max_long_acc_mps2"] == pytest.approx(4.0, abs=1e-9)
    assert m["min_long_acc_mps2"] == pytest.approx(0.04, abs=1e-9)
    result = evaluate_run(rec)
    assert "max_long_acc_mps2=4>2.4" in result.failed
    assert result.status == "fail"


def test_sg_window_scales_with_period() -> None:
    assert sg_window(1000, 0.1) == 5  # nuPlan: 5 samples at 10 Hz
    assert sg_window(1000, 0.05) == 11
    assert sg_window(1000, 0.02) == 25
    assert sg_window(4, 0.02) == 3


# --------------------------------------------------------------------------- drivable area


@pytest.mark.parametrize(("over_m", "violation"), [(0.5, True), (0.2, False), (0.0, False)])
def test_box_over_lane_edge(tmp_path: Path, over_m: float, violation: bool) -> None:
    # one lane centred on y = 0, width 3.5: left edge y = 1.75; ego half width 0.9
    y = 1.75 - 0.9 + over_m
    rec = _load(tmp_path, sr.straight_trace(5.0, 0.05, 20.0, y_m=y),
                road=sr.straight_road(n_lanes=1))
    m = offroad_metrics(rec)
    assert m["max_offroad_m"] == pytest.approx(max(over_m, 0.0), abs=1e-9)
    if violation:
        assert m["max_offroad_m"] > OFFROAD_TOLERANCE_M
        assert m["offroad_s"] == pytest.approx(5.0)
        assert m["offroad_m"] == pytest.approx(100.0)
        assert any(f.startswith("offroad_s=5>0") for f in evaluate_run(rec).failed)
    else:
        assert m["offroad_s"] == 0.0


def test_union_of_lanes_is_drivable(tmp_path: Path) -> None:
    # straddling the line between lanes 0 and 1 is not off-road
    rec = _load(tmp_path, sr.straight_trace(5.0, 0.05, 20.0, y_m=1.75),
                road=sr.straight_road(n_lanes=2))
    assert offroad_metrics(rec)["offroad_s"] == 0.0


@pytest.mark.parametrize("allow", [False, True])
def test_shoulder_counts_only_when_allowed(tmp_path: Path, allow: bool) -> None:
    trace = sr.straight_trace(4.0, 0.05, 20.0, y_m=-3.5)  # centred on the shoulder
    rec = _load(tmp_path, trace, road=sr.straight_road(n_lanes=2, shoulder=True),
                meta=sr.base_meta("sh", allow_shoulder=allow))
    m = offroad_metrics(rec)
    assert m["shoulder_s"] == pytest.approx(4.0)
    assert m["offroad_s"] == (0.0 if allow else pytest.approx(4.0))


def test_non_passenger_lane_is_not_drivable(tmp_path: Path) -> None:
    road = sr.straight_road(n_lanes=2)
    road["lanes"][1]["allowed"] = ["bus"]
    rec = _load(tmp_path, sr.straight_trace(3.0, 0.05, 20.0, y_m=3.5), road=road)
    assert offroad_metrics(rec)["offroad_s"] == pytest.approx(3.0)
    # road.json's allows_passenger flag, when present, decides
    road["lanes"][1]["allowed"] = ["passenger"]
    road["lanes"][1]["allows_passenger"] = False
    rec2 = _load(tmp_path, sr.straight_trace(3.0, 0.05, 20.0, y_m=3.5), "flag", road=road)
    assert offroad_metrics(rec2)["offroad_s"] == pytest.approx(3.0)


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
    # crossing: a box 12 m ahead, 10 m to the left, driving right at 5 m/s toward the
    # ego's path while the ego waits: touches when its near side reaches y = 0.9
    crossing = _box(0.0 + 0.0, 10.0, -math.pi / 2)  # heading -Y, length along Y
    ttc = swept_box_ttc(ego, np.array([0.0, 0.0]), crossing, np.array([0.0, -5.0]))
    assert ttc == pytest.approx((10.0 - 2.3 - 0.9) / 5.0)


def test_run_min_ttc_approach(tmp_path: Path) -> None:
    trace, nb = sr.approach_run_parts(gap_end_m=20.0, ego_speed_mps=20.0, lead_speed_mps=10.0)
    rec = _load(tmp_path, trace, neighbours=nb)
    assert min_ttc_s(rec) == pytest.approx(2.0, abs=1e-9)
    result = evaluate_run(rec)
    assert result.metrics["min_ttc_s"] == pytest.approx(2.0, abs=1e-9)
    assert result.metrics["min_gap_m"] == pytest.approx(20.0)
    assert result.status == "pass"


def test_ttc_below_limit_fails(tmp_path: Path) -> None:
    trace, nb = sr.approach_run_parts(gap_end_m=5.0, ego_speed_mps=20.0, lead_speed_mps=10.0)
    result = evaluate_run(_load(tmp_path, trace, neighbours=nb))
    assert "min_ttc_s=0.5<0.95" in result.failed


def test_ttc_ignored_while_stationary_behind_stopped_car(tmp_path: Path) -> None:
    trace = sr.straight_trace(3.0, 0.05, 0.0)
    nb = sr.lead_vehicle(trace, np.full(len(trace), 4.6 + 0.5), 0.0, 0.0)
    trace["min_gap_m"] = 0.5
    result = evaluate_run(_load(tmp_path, trace, neighbours=nb))
    assert result.metrics["min_ttc_s"] == math.inf
    assert not any(f.startswith("min_ttc_s") for f in result.failed)


def test_ttc_from_behind_is_reported_separately(tmp_path: Path) -> None:
    trace = sr.straight_trace(2.0, 0.05, 5.0)
    ego_x = trace["x_m"].to_numpy()
    gap = 30.0
    follower_x = ego_x[0] - 4.6 - gap + (15.0 - 5.0) * 0.0 + 15.0 * (trace["t_s"] - 0.05)
    nb = sr.lead_vehicle(trace, np.asarray(follower_x), 0.0, 15.0, vid="fast")
    rec = _load(tmp_path, trace, neighbours=nb)
    assert min_ttc_s(rec) == math.inf
    gap_end = ego_x[-1] - follower_x.iloc[-1] - 4.6
    assert min_ttc_rear_s(rec) == pytest.approx(gap_end / 10.0, rel=1e-9)


# --------------------------------------------------------------------------- safety misc


def test_collision_flags(tmp_path: Path) -> None:
    trace = sr.straight_trace(2.0, 0.05, 20.0)
    assert evaluate_run(_load(tmp_path, trace, "a")).metrics["collision"] == 0.0
    t2 = trace.copy()
    t2.loc[10, "sumo_collision"] = True
    r2 = evaluate_run(_load(tmp_path, t2, "b"))
    assert r2.metrics["collision"] == 1.0
    assert r2.metrics["first_collision_t_s"] == pytest.approx(0.55)
    assert "collision=1>0" in r2.failed
    t3 = trace.copy()
    t3.loc[5:7, "geom_collision"] = True
    assert evaluate_run(_load(tmp_path, t3, "c")).metrics["geom_collision_steps"] == 3.0


def test_ellipse_margin(tmp_path: Path) -> None:
    trace = sr.straight_trace(10.0, 0.05, 20.0)  # passes x = 100 at y = 0
    arrays = sr.ellipse_arrays(trace, (100.0, 3.0), 6.0, 2.0)
    m = evaluate_run(_load(tmp_path, trace, "in", arrays=arrays)).metrics
    assert m["min_ellipse_margin"] == pytest.approx((3.0 / 2.0) ** 2 - 1.0)
    inside = sr.ellipse_arrays(trace, (100.0, 1.0), 6.0, 2.0)
    m2 = evaluate_run(_load(tmp_path, trace, "in2", arrays=inside)).metrics
    assert m2["min_ellipse_margin"] == pytest.approx(0.25 - 1.0)
    m3 = evaluate_run(_load(tmp_path, trace, "none")).metrics
    assert math.isnan(m3["min_ellipse_margin"])


# --------------------------------------------------------------------------- tracking


def test_progress_ratio(tmp_path: Path) -> None:
    ok = _load(tmp_path, sr.straight_trace(10.0, 0.05, 20.0), "ok")
    assert progress_ratio(ok) == pytest.approx(1.0)
    assert evaluate_run(ok).metrics["progress_m"] == pytest.approx(199.0)
    slow = _load(tmp_path, sr.straight_trace(10.0, 0.05, 8.0, target_speed_mps=20.0), "slow")
    result = evaluate_run(slow)
    assert result.metrics["progress_ratio"] == pytest.approx(0.4)
    assert "progress_ratio=0.4<0.5" in result.failed
    # a route shorter than the run caps the expectation
    road = sr.straight_road(length_m=100.0)
    short = _load(tmp_path, sr.straight_trace(10.0, 0.05, 20.0), "short", road=road)
    m = evaluate_run(short).metrics
    assert m["expected_progress_m"] == pytest.approx(100.0)
    assert m["progress_ratio"] > 1.0


def test_lat_dev_and_speed(tmp_path: Path) -> None:
    trace = sr.straight_trace(4.0, 0.05, 18.0, target_speed_mps=20.0)
    trace["lat_dev_m"] = np.where(np.arange(len(trace)) % 2 == 0, 0.3, -0.3)
    m = evaluate_run(_load(tmp_path, trace)).metrics
    assert m["rms_lat_dev_m"] == pytest.approx(0.3)
    assert m["max_abs_lat_dev_m"] == pytest.approx(0.3)
    assert m["mean_speed_mps"] == pytest.approx(18.0)
    assert m["mean_speed_error_mps"] == pytest.approx(-2.0)


def test_final_lat_dev_is_taken_over_the_last_two_seconds(tmp_path: Path) -> None:
    trace = sr.straight_trace(10.0, 0.05, 20.0)
    t = trace["t_s"].to_numpy()
    # 1.5 m out until 7.5 s, then 0.2 m: the last 2 s (from 7.95 s) see only 0.2 m.
    trace["lat_dev_m"] = np.where(t < 7.5, 1.5, 0.2)
    m = evaluate_run(_load(tmp_path, trace), {"max_final_abs_lat_dev_m": 0.3}).metrics
    assert m["final_abs_lat_dev_m"] == pytest.approx(0.2)
    trace["lat_dev_m"] = np.where(t < 8.5, 0.0, -0.45)
    result = evaluate_run(_load(tmp_path / "b", trace), {"max_final_abs_lat_dev_m": 0.3})
    assert result.metrics["final_abs_lat_dev_m"] == pytest.approx(0.45)
    assert "final_abs_lat_dev_m=0.45>0.3" in result.failed


# --------------------------------------------------------------------------- timing


def test_timing_and_deadline_misses(tmp_path: Path) -> None:
    trace = sr.straight_trace(5.0, 0.05, 20.0)
    n = len(trace)
    ctrl = np.full(n, 0.002)
    ctrl[[3, 10, 50, 51, 52, 60, 99]] = 0.06  # 7 steps over the 50 ms period
    trace["controller_s"] = ctrl
    trace["outer_s"] = 0.001
    trace.loc[0, "fallback"] = True
    trace.loc[1, "fallback"] = True
    trace["guard_fired"] = 0
    trace.loc[2, "guard_fired"] = 3
    trace["residual"] = np.linspace(1e-3, 1e-5, n)
    rec = _load(tmp_path, trace, meta=sr.base_meta("t", sim_time_s=5.0, wall_s=2.5))
    m = evaluate_run(rec).metrics
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
    assert timing_metrics(rec)["deadline_miss_frac"] == pytest.approx(7 / n)


# --------------------------------------------------------------------------- evaluate


def test_required_metric_names(tmp_path: Path) -> None:
    result = evaluate_run(_load(tmp_path, sr.lane_change_trace()))
    for name in REQUIRED_METRICS:
        assert name in result.metrics, name
    assert list(result.metrics)[: len(REQUIRED_METRICS)] == list(REQUIRED_METRICS)
    assert result.status == "pass"
    assert result.as_row()["failed_criteria"] == ""


def test_empty_trace_is_tolerated(tmp_path: Path) -> None:
    rec = _load(tmp_path, None)
    result = evaluate_run(rec)
    assert result.status == "fail"
    assert result.failed == ["steps=0<1"]
    assert set(REQUIRED_METRICS) <= set(result.metrics)
    assert math.isnan(result.metrics["max_abs_lat_acc_mps2"])
