"""Synthetic run directories (the run-record contract of ``reports.run_record``) for tests.

Each ``*_trace`` builds a full trace DataFrame from a kinematic path with analytic
velocities/accelerations; ``write_run`` writes run.json, road.json, trace.parquet,
neighbours.parquet and optionally controller_arrays.npz / traceback.txt.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from reports.run_record import NEIGHBOUR_COLUMNS, TRACE_COLUMNS

EGO_LENGTH_M = 4.6
EGO_WIDTH_M = 1.8
LANE_WIDTH_M = 3.5


# --------------------------------------------------------------------------- road


def straight_road(length_m: float = 2000.0, n_lanes: int = 3, width_m: float = LANE_WIDTH_M,
                  shoulder: bool = False, x0_m: float = -100.0) -> dict[str, Any]:
    """Straight edge along +X; lane i's centre at y = i·width (0 is the rightmost regular
    lane); a shoulder (is_shoulder, emergency only) at y = −width if asked."""
    lanes: list[dict[str, Any]] = []
    for i in range(n_lanes):
        lanes.append({"id": f"E0_{i + int(shoulder)}", "edge_id": "E0", "index": i + int(shoulder),
                      "width_m": width_m,
                      "shape_xy_m": [[x0_m, i * width_m], [x0_m + length_m, i * width_m]],
                      "allowed": ["passenger", "truck"], "is_shoulder": False, "on_route": True})
    if shoulder:
        lanes.append({"id": "E0_0", "edge_id": "E0", "index": 0, "width_m": width_m,
                      "shape_xy_m": [[x0_m, -width_m], [x0_m + length_m, -width_m]],
                      "allowed": ["emergency"], "is_shoulder": True, "on_route": True})
    return {"lanes": lanes, "reference_xy_m": [[x0_m, 0.0], [x0_m + length_m, 0.0]],
            "reference_length_m": length_m, "route": ["E0"]}


def circle_road(radius_m: float = 100.0, width_m: float = LANE_WIDTH_M) -> dict[str, Any]:
    """One lane on a circle of ``radius_m`` centred at (0, radius) (starts at origin heading +X)."""
    a = np.linspace(-0.2, 2 * np.pi + 0.2, 400)
    shape = np.stack([radius_m * np.sin(a), radius_m * (1 - np.cos(a))], axis=-1)
    lane = {"id": "C_0", "edge_id": "C", "index": 0, "width_m": width_m,
            "shape_xy_m": shape.tolist(), "allowed": [], "is_shoulder": False, "on_route": True}
    return {"lanes": [lane], "reference_xy_m": shape.tolist(),
            "reference_length_m": float(radius_m * (2 * np.pi + 0.4)), "route": ["C"]}


# --------------------------------------------------------------------------- traces


def timing_columns(n: int, seed: int = 0, outer_ms: float = 3.0, inner_ms: float = 1.0,
                   period_s: float = 0.05) -> dict[str, np.ndarray]:
    """Plausible per-step times [s] (lognormal around the given medians)."""
    rng = np.random.default_rng(seed)
    outer = outer_ms * 1e-3 * rng.lognormal(0.0, 0.25, n)
    inner = inner_ms * 1e-3 * rng.lognormal(0.0, 0.25, n)
    obstacles = 0.2e-3 * rng.lognormal(0.0, 0.2, n)
    return {"outer_s": outer, "inner_s": inner, "obstacles_s": obstacles,
            "controller_s": outer + inner + obstacles,
            "sumo_s": 0.5e-3 * rng.lognormal(0.0, 0.2, n)}


def kinematic_trace(t: np.ndarray, x: np.ndarray, y: np.ndarray, psi: np.ndarray,
                    u: np.ndarray, *, v: np.ndarray | None = None, r: np.ndarray | None = None,
                    long_acc: np.ndarray | None = None, lat_acc: np.ndarray | None = None,
                    target_speed_mps: float | np.ndarray = 20.0, s_m: np.ndarray | None = None,
                    lat_dev_m: np.ndarray | None = None, seed: int = 0,
                    **extra: Any) -> pd.DataFrame:
    """A trace with every TRACE_COLUMNS column; missing kinematics are set to 0 / derived."""
    n = len(t)
    zeros = np.zeros(n)
    v = zeros if v is None else v
    r = np.gradient(np.unwrap(psi), t) if r is None and n > 1 else (zeros if r is None else r)
    cols: dict[str, Any] = {
        "step": np.arange(n), "t_s": t, "x_m": x, "y_m": y, "psi_rad": psi, "u_mps": u,
        "v_mps": v, "r_radps": r, "speed_mps": np.hypot(u, v),
        "target_speed_mps": np.broadcast_to(np.asarray(target_speed_mps, float), (n,)).copy(),
        "long_acc_mps2": zeros if long_acc is None else long_acc,
        "lat_acc_mps2": r * u if lat_acc is None else lat_acc,
        "steer_rad": np.arctan(2.8 * r / np.maximum(u, 0.1)), "torque_nm": 300.0 + zeros,
        "steer_outer_rad": zeros, "steer_corr_rad": zeros, "torque_outer_nm": 300.0 + zeros,
        "torque_corr_nm": zeros,
        "s_m": (np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
                if s_m is None else s_m),
        "lat_dev_m": zeros if lat_dev_m is None else lat_dev_m,
        "heading_err_rad": zeros, "lane_index": np.zeros(n, dtype=np.int64),
        "min_gap_m": np.full(n, np.inf), "gap_vehicle": [""] * n,
        "geom_collision": np.zeros(n, dtype=bool), "sumo_collision": np.zeros(n, dtype=bool),
        "ssm_ttc_s": np.full(n, np.nan), "side": np.zeros(n, dtype=np.int64),
        "side_reason": ["none"] * n, "n_obstacles": np.zeros(n, dtype=np.int64),
        "residual": 1e-4 * (1 + np.abs(np.sin(t))), "fallback": np.zeros(n, dtype=bool),
        "guard_fired": np.zeros(n, dtype=np.int64),
    }
    cols.update(timing_columns(n, seed))
    cols.update(extra)
    df = pd.DataFrame(cols)
    for name in TRACE_COLUMNS:  # columns added to the contract later: NaN
        if name not in df.columns:
            df[name] = np.nan
    return df[list(TRACE_COLUMNS)]


def times(duration_s: float, dt_s: float) -> np.ndarray:
    """t = dt, 2 dt, …, duration (t_s is the time at the end of a step)."""
    n = int(round(duration_s / dt_s))
    return dt_s * np.arange(1, n + 1)


def straight_trace(duration_s: float = 10.0, dt_s: float = 0.05, speed_mps: float = 20.0,
                   y_m: float = 0.0, x0_m: float = 0.0, **kw: Any) -> pd.DataFrame:
    """Constant speed along +X at lateral position y_m."""
    t = times(duration_s, dt_s)
    x = x0_m + speed_mps * t
    n = len(t)
    return kinematic_trace(t, x, np.full(n, y_m), np.zeros(n), np.full(n, speed_mps),
                           lat_dev_m=np.full(n, y_m), **kw)


def turn_trace(radius_m: float = 100.0, speed_mps: float = 20.0, duration_s: float = 10.0,
               dt_s: float = 0.05, **kw: Any) -> pd.DataFrame:
    """Constant-radius left turn: yaw rate v/R, lateral acceleration v²/R."""
    t = times(duration_s, dt_s)
    w = speed_mps / radius_m
    n = len(t)
    return kinematic_trace(t, radius_m * np.sin(w * t), radius_m * (1 - np.cos(w * t)), w * t,
                           np.full(n, speed_mps), r=np.full(n, w),
                           lat_acc=np.full(n, speed_mps * w), **kw)


def accel_ramp_trace(jerk_mps3: float = 2.0, duration_s: float = 2.0, dt_s: float = 0.02,
                     speed0_mps: float = 10.0, **kw: Any) -> pd.DataFrame:
    """Straight line with a(t) = jerk·t (constant longitudinal jerk)."""
    t = times(duration_s, dt_s)
    a = jerk_mps3 * t
    u = speed0_mps + 0.5 * jerk_mps3 * t ** 2
    x = speed0_mps * t + jerk_mps3 * t ** 3 / 6
    n = len(t)
    return kinematic_trace(t, x, np.zeros(n), np.zeros(n), u, long_acc=a, **kw)


def lane_change_trace(width_m: float = LANE_WIDTH_M, speed_mps: float = 20.0,
                      duration_s: float = 12.0, change_s: float = 4.0, start_s: float = 3.0,
                      dt_s: float = 0.05, **kw: Any) -> pd.DataFrame:
    """Lane change to the left (y 0 → width) with a cosine lateral profile."""
    t = times(duration_s, dt_s)
    tau = np.clip((t - start_s) / change_s, 0.0, 1.0)
    y = width_m * 0.5 * (1 - np.cos(np.pi * tau))
    vy = np.where((tau > 0) & (tau < 1), width_m * 0.5 * np.pi / change_s * np.sin(np.pi * tau), 0)
    psi = np.arctan2(vy, speed_mps)
    x = speed_mps * t
    return kinematic_trace(t, x, y, psi, np.hypot(speed_mps, vy), lat_dev_m=y, **kw)


def lead_vehicle(trace: pd.DataFrame, x_m: np.ndarray, y_m: float, speed_mps: float,
                 vid: str = "lead", length_m: float = 4.6, width_m: float = 1.8,
                 stalled: bool = False, heading_rad: float = 0.0) -> pd.DataFrame:
    """Neighbour rows for one vehicle at every trace step."""
    n = len(trace)
    return pd.DataFrame({
        "step": trace["step"].to_numpy(), "t_s": trace["t_s"].to_numpy(), "id": [vid] * n,
        "x_m": x_m, "y_m": np.full(n, y_m), "heading_rad": np.full(n, heading_rad),
        "speed_mps": np.full(n, speed_mps), "length_m": np.full(n, length_m),
        "width_m": np.full(n, width_m), "lane_index": np.zeros(n, dtype=np.int64),
        "stalled": np.full(n, stalled)})[list(NEIGHBOUR_COLUMNS)]


def approach_run_parts(gap_end_m: float = 20.0, ego_speed_mps: float = 20.0,
                       lead_speed_mps: float = 10.0, duration_s: float = 3.0,
                       dt_s: float = 0.05, seed: int = 0) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Ego at ego_speed behind a slower lead in the same lane; the bumper gap shrinks to
    ``gap_end_m`` at the last step, so min TTC = gap_end / (ego − lead speed)."""
    trace = straight_trace(duration_s, dt_s, ego_speed_mps, seed=seed)
    t = trace["t_s"].to_numpy()
    t_end = t[-1]
    ego_x = trace["x_m"].to_numpy()
    closing = ego_speed_mps - lead_speed_mps
    gap = gap_end_m + closing * (t_end - t)
    lead_x = ego_x + EGO_LENGTH_M + gap  # centre distance = gap + half lengths (equal cars)
    trace["min_gap_m"] = gap
    trace["gap_vehicle"] = "lead"
    return trace, lead_vehicle(trace, lead_x, 0.0, lead_speed_mps)


# --------------------------------------------------------------------------- run dirs


def base_meta(scenario: str, controller: str = "ctrl_a", **overrides: Any) -> dict[str, Any]:
    """A run.json dict with every contract field."""
    meta: dict[str, Any] = {
        "scenario": scenario, "controller": controller, "controller_options": {},
        "controller_params": {}, "catalog": "synthetic", "seed": 0, "net": "synthetic.net.xml",
        "duration_s": 10.0, "step_s": 0.05, "target_speed_mps": 20.0, "criteria": {},
        "status": "pass", "error": None, "wall_s": 5.0, "sim_time_s": 10.0,
        "ego": {"length_m": EGO_LENGTH_M, "width_m": EGO_WIDTH_M, "cg_to_front_bumper_m": 2.3,
                "cg_to_box_centre_m": 0.0},
        "stalled": [], "sumo_collisions": [], "ssm": {}, "metrics": {}, "failed_criteria": [],
    }
    meta.update(overrides)
    return meta


def write_run(run_dir: str | Path, trace: pd.DataFrame | None, *,
              meta: Mapping[str, Any] | None = None, road: Mapping[str, Any] | None = None,
              neighbours: pd.DataFrame | None = None,
              arrays: Mapping[str, np.ndarray] | None = None,
              traceback: str | None = None) -> Path:
    """Write one run directory; returns its path. ``trace=None`` writes no trace file."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    meta = dict(meta) if meta is not None else base_meta(run_dir.name)
    if trace is not None and len(trace):
        meta.setdefault("sim_time_s", float(trace["t_s"].iloc[-1]))
    (run_dir / "run.json").write_text(json.dumps(meta, indent=1))
    (run_dir / "road.json").write_text(json.dumps(road if road is not None else straight_road()))
    if trace is not None:
        trace.to_parquet(run_dir / "trace.parquet")
    nb = neighbours if neighbours is not None else pd.DataFrame(
        {c: pd.Series(dtype="float64") for c in NEIGHBOUR_COLUMNS})
    nb.to_parquet(run_dir / "neighbours.parquet")
    if arrays:
        np.savez(run_dir / "controller_arrays.npz", **dict(arrays))
    if traceback is not None:
        (run_dir / "traceback.txt").write_text(traceback)
    return run_dir


def ellipse_arrays(trace: pd.DataFrame, centre_xy: Sequence[float], semi_a_m: float,
                   semi_b_m: float, heading_rad: float = 0.0) -> dict[str, np.ndarray]:
    """controller_arrays with one static active ellipse at every step."""
    n = len(trace)
    ell = np.full((n, 2, 6), np.nan)
    ell[:, 0] = [centre_xy[0], centre_xy[1], heading_rad, semi_a_m, semi_b_m, 1.0]
    return {"ellipses": ell, "plan_xy_m": np.full((n, 3, 2), np.nan),
            "preview_xy_m": np.full((n, 3, 2), np.nan), "detection_radius_m": np.array(80.0)}


def make_catalog(out_dir: str | Path, controllers: Sequence[str] = ("ctrl_a", "ctrl_b"),
                 speedup: float = 1.0) -> Path:
    """A small mixed catalog output: per controller a passing cruise, a lane change, a
    stalled-car pass, an uncomfortable sharp turn (fail), a collision (fail) and, for the
    second controller, an error run and a timeout run. Run dirs are ``<scenario>__<ctrl>``.

    ``speedup`` scales every controller time (to fake a timing regression)."""
    out_dir = Path(out_dir)
    for ci, ctrl in enumerate(controllers):
        seed = ci

        def meta(scn: str, family: str, _ctrl: str = ctrl, **kw: Any) -> dict[str, Any]:
            return base_meta(scn, _ctrl, family=family, **kw)

        def slow(tr: pd.DataFrame) -> pd.DataFrame:
            for c in ("outer_s", "inner_s", "obstacles_s", "controller_s"):
                tr[c] = tr[c] * speedup
            return tr

        tr = slow(straight_trace(20.0, 0.05, 20.0, seed=seed))
        write_run(out_dir / f"cruise_straight__{ctrl}", tr,
                  meta=meta("cruise_straight", "cruise", sim_time_s=20.0, wall_s=4.0))

        tr = slow(lane_change_trace(seed=seed))
        other_x = 30.0 + 25.0 * tr["t_s"].to_numpy()
        nb = lead_vehicle(tr, other_x, LANE_WIDTH_M * 2, 25.0, vid="car1")
        write_run(out_dir / f"lane_change_left__{ctrl}", tr, neighbours=nb,
                  meta=meta("lane_change_left", "lane_change", sim_time_s=12.0, wall_s=3.0))

        tr = slow(lane_change_trace(start_s=2.0, duration_s=10.0, seed=seed))
        stalled = {"id": "stalled0", "x_m": 150.0, "y_m": 0.0, "heading_rad": 0.0,
                   "length_m": 4.6, "width_m": 1.8, "lane_index": 0}
        nb = lead_vehicle(tr, np.full(len(tr), 150.0), 0.0, 0.0, vid="stalled0", stalled=True)
        gaps = np.abs(150.0 - tr["x_m"].to_numpy()) - EGO_LENGTH_M
        tr["min_gap_m"] = np.maximum(gaps, 0.5)
        arrays = ellipse_arrays(tr, (150.0, 0.3), 6.6, 2.2)
        write_run(out_dir / f"stalled_pass_left__{ctrl}", tr, neighbours=nb, arrays=arrays,
                  meta=meta("stalled_pass_left", "stalled", stalled=[stalled], sim_time_s=10.0,
                            wall_s=2.5))

        tr = slow(turn_trace(radius_m=60.0 if ci == 0 else 200.0, speed_mps=20.0, seed=seed))
        write_run(out_dir / f"sharp_curve__{ctrl}", tr, road=circle_road(60.0 if ci == 0 else
                                                                         200.0),
                  meta=meta("sharp_curve", "curve", sim_time_s=10.0, wall_s=2.0))

        tr, nb = approach_run_parts(gap_end_m=0.0, duration_s=4.0, seed=seed)
        tr = slow(tr)
        k = len(tr) - 5
        tr.loc[k:, "geom_collision"] = True
        tr.loc[k:, "sumo_collision"] = True
        write_run(out_dir / f"rear_end__{ctrl}", tr, neighbours=nb,
                  meta=meta("rear_end", "cut_in", sim_time_s=4.0, wall_s=1.0,
                            sumo_collisions=[{"t_s": 3.8, "collider": "ego", "victim": "lead",
                                              "type": "collision"}]))
        if ci == 1:
            tb = ('Traceback (most recent call last):\n  File "runner.py", line 1\n'
                  'RuntimeError: solver diverged <&> "quoted"\n')
            tr = slow(straight_trace(1.0, 0.05, 20.0, seed=seed))
            write_run(out_dir / f"crash_case__{ctrl}", tr, traceback=tb,
                      meta=meta("crash_case", "cruise", status="error", error=tb,
                                sim_time_s=1.0, wall_s=0.5))
            write_run(out_dir / f"slow_case__{ctrl}", None,
                      meta=meta("slow_case", "cruise", status="timeout",
                                error="timed out after 600 s", sim_time_s=0.0, wall_s=600.0))
    return out_dir
