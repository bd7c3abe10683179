"""Synthetic run directories for the Rerun log tests, and a tiny bird's-eye renderer.

The road runs along +X: a shoulder (lane 0) and three driving lanes (1..3), 3.5 m
wide. The ego starts in lane 1 at 25 m/s, changes to lane 2 to pass a car stalled
in lane 1 at x = 200 m and returns; ``n_traffic`` vehicles drive in lanes 2 and 3.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from reports.run_record import (
    CONTROLLER_ARRAYS,
    NEIGHBOUR_COLUMNS,
    NEIGHBOURS,
    ROAD_JSON,
    RUN_JSON,
    TRACE,
    TRACE_COLUMNS,
)

LANE_W = 3.5
SHOULDER_W = 2.5
LANE_Y = {0: -(LANE_W + SHOULDER_W) / 2.0, 1: 0.0, 2: LANE_W, 3: 2 * LANE_W}
STALLED_X = 200.0
EGO_SPEED = 25.0
EGO = {"length_m": 4.6, "width_m": 1.9, "cg_to_front_bumper_m": 3.5, "cg_to_box_centre_m": 1.2}


def _smooth(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3 - 2 * u)


def ego_xy(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ego CG path: lane 1, over to lane 2 around the stalled car, back to lane 1."""
    x = EGO_SPEED * np.asarray(t, dtype=np.float64)
    y = LANE_W * (_smooth((x - 110.0) / 60.0) - _smooth((x - 240.0) / 60.0))
    return x, y


def make_run_dir(root: Path, *, scenario: str = "stalled_pass", seed: int = 1,
                 catalog: str = "smoke", steps: int = 300, n_traffic: int = 2,
                 dt: float = 0.1, collision: bool = False, status: str | None = None,
                 failed_criteria: list[str] | None = None,
                 neighbour_radius_m: float | None = 150.0) -> Path:
    """Write a synthetic run directory ``root/<scenario>`` and return it."""
    run_dir = Path(root) / scenario
    run_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    step = np.arange(steps)
    t = (step + 1) * dt
    x, y = ego_xy(t)
    xs, ys = ego_xy(t + 1e-3)
    psi = np.arctan2(ys - y, xs - x)
    speed = np.full(steps, EGO_SPEED)
    lat_acc = np.gradient(np.gradient(y, t), t)
    lane_index = np.where(y > LANE_W / 2, 2, 1)

    # stalled car and its gap / TTC
    st_len, st_wid = 4.5, 1.8
    front = x + EGO["cg_to_front_bumper_m"]
    gap = np.where(lane_index == 1, STALLED_X - st_len / 2 - front, 30.0)
    gap = np.where((gap < 0) & (lane_index == 1), 0.0, np.abs(gap))
    ttc = np.where((lane_index == 1) & (front < STALLED_X), gap / EGO_SPEED, np.nan)
    ahead = (STALLED_X - x > 0) & (STALLED_X - x < 80.0)
    side = np.where(ahead, 1, 0)
    reason = np.where(ahead, "left lane free", "")

    geom = np.zeros(steps, bool)
    sumo = np.zeros(steps, bool)
    gap_vehicle = np.where(ahead, "stalled0", "")
    if collision:
        geom[100:105] = True
        sumo[101] = True
        gap[100:105] = 0.0
    fallback = np.zeros(steps, bool)
    fallback[60:63] = True

    trace: dict[str, Any] = {
        "step": step, "t_s": t, "x_m": x, "y_m": y, "psi_rad": psi,
        "u_mps": speed, "v_mps": np.zeros(steps), "r_radps": np.gradient(psi, t),
        "speed_mps": speed, "target_speed_mps": np.full(steps, EGO_SPEED),
        "long_acc_mps2": 0.05 * rng.standard_normal(steps), "lat_acc_mps2": lat_acc,
        "steer_rad": 0.02 * np.sin(t), "torque_nm": 150 + 10 * np.sin(t),
        "steer_outer_rad": 0.018 * np.sin(t), "steer_corr_rad": 0.002 * np.sin(t),
        "torque_outer_nm": 140 + 10 * np.sin(t), "torque_corr_nm": np.full(steps, 10.0),
        "s_m": x, "lat_dev_m": y, "heading_err_rad": psi, "lane_index": lane_index,
        "min_gap_m": gap, "gap_vehicle": gap_vehicle, "geom_collision": geom,
        "sumo_collision": sumo, "ssm_ttc_s": ttc, "side": side, "side_reason": reason,
        "n_obstacles": ahead.astype(int), "residual": 1e-6 * (1 + rng.random(steps)),
        "fallback": fallback, "guard_fired": np.zeros(steps, int),
        "outer_s": 0.004 + 0.001 * rng.random(steps), "inner_s": 0.001 + 0.0005 * rng.random(steps),
        "obstacles_s": np.full(steps, 2e-4), "controller_s": np.full(steps, 0.0065),
        "sumo_s": 0.002 + 0.001 * rng.random(steps),
    }
    front = np.stack([x + EGO["cg_to_front_bumper_m"] * np.cos(psi),
                      y + EGO["cg_to_front_bumper_m"] * np.sin(psi)])
    trace.update({"sumo_front_x_m": front[0], "sumo_front_y_m": front[1], "sumo_heading_rad": psi})
    for name in TRACE_COLUMNS:  # the contract may grow; unknown columns are NaN here
        trace.setdefault(name, np.full(steps, np.nan))
    pd.DataFrame(trace)[list(TRACE_COLUMNS)].to_parquet(run_dir / TRACE)

    # neighbours: stalled car + traffic in lanes 2/3
    rows: dict[str, list[Any]] = {k: [] for k in NEIGHBOUR_COLUMNS}
    tr_lane = np.array([2 + (i % 2) for i in range(n_traffic)])
    tr_x0 = np.array([40.0 + 45.0 * i for i in range(n_traffic)])
    tr_v = np.array([21.0 + (i % 3) for i in range(n_traffic)])
    for k in range(steps):
        xs_k = np.concatenate([[STALLED_X], tr_x0 + tr_v * t[k]])
        ys_k = np.concatenate([[LANE_Y[1]], [LANE_Y[int(la)] for la in tr_lane]])
        ids = ["stalled0"] + [f"veh{i}" for i in range(n_traffic)]
        for j in range(len(ids)):
            if neighbour_radius_m is not None and np.hypot(xs_k[j] - x[k], ys_k[j] - y[k]) > \
                    neighbour_radius_m:
                continue
            rows["step"].append(k)
            rows["t_s"].append(t[k])
            rows["id"].append(ids[j])
            rows["x_m"].append(xs_k[j])
            rows["y_m"].append(ys_k[j])
            rows["heading_rad"].append(0.0)
            rows["speed_mps"].append(0.0 if j == 0 else tr_v[j - 1])
            rows["length_m"].append(st_len if j == 0 else 4.8)
            rows["width_m"].append(st_wid if j == 0 else 1.9)
            rows["lane_index"].append(1 if j == 0 else int(tr_lane[j - 1]))
            rows["stalled"].append(j == 0)
    pd.DataFrame(rows).to_parquet(run_dir / NEIGHBOURS)

    # controller arrays: plan (0.2 s knots), preview (0.1 s), one ellipse for the stalled car
    n_plan, n_prev = 20, 10
    tp = t[:, None] + 0.2 * np.arange(n_plan + 1)[None, :]
    px, py = ego_xy(tp)
    plan = np.stack([px, py], axis=-1)
    tq = t[:, None] + 0.1 * np.arange(n_prev + 1)[None, :]
    qx, qy = ego_xy(tq)
    preview = np.stack([qx, qy + 0.05 * np.arange(n_prev + 1)[None, :]], axis=-1)
    plan[:5] = np.nan  # no plan yet for the first steps (NaN padding)
    ell = np.full((steps, 3, 6), np.nan)
    ell[:, :, 5] = 0.0
    a_semi = st_len / 2 + EGO["length_m"] / 2 + 2.0
    b_semi = st_wid / 2 + EGO["width_m"] / 2 + 0.4
    ell[ahead, 0] = [STALLED_X, -0.3, 0.0, a_semi, b_semi, 1.0]
    np.savez(run_dir / CONTROLLER_ARRAYS, plan_xy_m=plan, preview_xy_m=preview, ellipses=ell,
             detection_radius_m=np.array(80.0))

    road_len = max(1000.0, float(x[-1]) + 300.0)
    xs_road = np.linspace(-50.0, road_len, 12)
    lanes = []
    for idx in range(4):
        lanes.append({
            "id": f"E0_{idx}", "edge_id": "E0", "index": idx,
            "width_m": SHOULDER_W if idx == 0 else LANE_W,
            "shape_xy_m": [[float(a), LANE_Y[idx]] for a in xs_road],
            "allowed": ["passenger"], "is_shoulder": idx == 0, "on_route": True})
    road = {"lanes": lanes, "reference_xy_m": [[float(a), 0.0] for a in xs_road],
            "reference_length_m": road_len + 50.0, "route": ["E0"]}
    (run_dir / ROAD_JSON).write_text(json.dumps(road))

    if status is None:
        status = "fail" if collision else "pass"
    if failed_criteria is None:
        failed_criteria = (["collision=1>0", "max_abs_lat_acc_mps2=4.1>3.0"] if collision else [])
    meta = {
        "scenario": scenario, "controller": "mpc_spmm",
        "controller_options": {"horizon": n_plan},
        "controller_params": {"horizon": n_plan, "dt_plan_s": 0.2, "q_y": 1.0},
        "catalog": catalog, "seed": seed, "net": "sumo_nets/straight3.net.xml",
        "duration_s": steps * dt, "step_s": dt, "target_speed_mps": EGO_SPEED,
        "criteria": {"collision": 0, "max_abs_lat_acc_mps2": 3.0, "min_ttc_s": 1.0},
        "status": status, "error": None, "wall_s": 3.2, "sim_time_s": steps * dt,
        "ego": EGO,
        "stalled": [{"id": "stalled0", "x_m": STALLED_X, "y_m": 0.0, "heading_rad": 0.0,
                     "length_m": st_len, "width_m": st_wid, "lane_index": 1}],
        "sumo_collisions": ([{"t_s": float(t[101]), "collider": "ego", "victim": "stalled0",
                              "type": "collision"}] if collision else []),
        "ssm": {}, "metrics": {"max_abs_lat_acc_mps2": float(np.max(np.abs(lat_acc)))},
        "failed_criteria": failed_criteria,
    }
    (run_dir / RUN_JSON).write_text(json.dumps(meta, indent=1))
    return run_dir


# --------------------------------------------------------------------------- reading back


def read_chunks(rrd: Path) -> list[Any]:
    """All chunks of the (first) recording in an .rrd, with Rerun's own reader."""
    from rerun.chunk import RrdReader

    return list(RrdReader(rrd).stream())


def rows_at_step(chunks: list[Any], entity: str, step: int, component: str) -> list[Any]:
    """Values of a component of an entity at a step (or its static value)."""
    static_val: list[Any] = []
    for c in chunks:
        if c.entity_path != entity:
            continue
        rb = c.to_record_batch()
        if component not in rb.schema.names:
            continue
        col = rb.column(component).to_pylist()
        if c.is_static:
            static_val = col[-1] or []
            continue
        steps = rb.column("step").to_pylist()
        for s, v in zip(steps, col, strict=True):
            if s == step and v is not None:
                return list(v)
    return list(static_val)


def render_birdseye(rrd: Path, step: int, out_png: Path, *, ahead: float = 120.0,
                    behind: float = 40.0, half_width: float = 18.0, px_per_m: float = 6.0) -> Path:
    """Draw the bird's-eye content of one step, read back from the .rrd, with PIL."""
    from PIL import Image, ImageDraw

    chunks = read_chunks(rrd)
    ego = rows_at_step(chunks, "/world/ego/box", step, "LineStrips2D:strips")
    cx, cy = np.mean(np.asarray(ego[0])[:4], axis=0) if ego else (0.0, 0.0)
    w, h = int((ahead + behind) * px_per_m), int(2 * half_width * px_per_m)
    img = Image.new("RGB", (w, h), (14, 16, 22))
    draw = ImageDraw.Draw(img)

    def to_px(p: Any) -> tuple[float, float]:
        return ((p[0] - cx + behind) * px_per_m, (half_width - (p[1] - cy)) * px_per_m)

    layers = [
        ("/world/road/centrelines", (110, 110, 120), 1),
        ("/world/road/lanes", (200, 200, 200), 2),
        ("/world/road/shoulders", (230, 160, 40), 2),
        ("/world/reference_path", (80, 170, 255), 1),
        ("/world/detection", None, 1),
        ("/world/ellipses", (230, 80, 230), 2),
        ("/world/vehicles", (150, 180, 230), 2),
        ("/world/stalled", (255, 60, 60), 3),
        ("/world/plan", (60, 255, 200), 2),
        ("/world/preview", (255, 170, 40), 2),
        ("/world/ego/box", (60, 230, 120), 3),
    ]
    for entity, color, width in layers:
        if entity == "/world/detection":
            centres = rows_at_step(chunks, entity, step, "Ellipses2D:centers")
            half = rows_at_step(chunks, entity, step, "Ellipses2D:half_sizes")
            if centres and half:
                (ex, ey), r = to_px(centres[0]), half[0][0] * px_per_m
                draw.ellipse([ex - r, ey - r, ex + r, ey + r], outline=(90, 120, 200))
            continue
        for strip in rows_at_step(chunks, entity, step, "LineStrips2D:strips"):
            pts = [to_px(p) for p in strip]
            if len(pts) >= 2:
                draw.line(pts, fill=color, width=width)
    arrows_o = rows_at_step(chunks, "/world/preview_error", step, "Arrows2D:origins")
    arrows_v = rows_at_step(chunks, "/world/preview_error", step, "Arrows2D:vectors")
    for o, v in zip(arrows_o, arrows_v, strict=False):
        draw.line([to_px(o), to_px((o[0] + v[0], o[1] + v[1]))], fill=(255, 80, 80), width=2)
    labels = rows_at_step(chunks, "/world/vehicles", step, "LineStrips2D:labels")
    strips = rows_at_step(chunks, "/world/vehicles", step, "LineStrips2D:strips")
    for label, strip in zip(labels, strips, strict=False):
        draw.text(to_px(strip[0]), str(label), fill=(150, 180, 230))
    draw.text((6, 4), f"step {step} (read back from {Path(rrd).name})", fill=(230, 230, 230))
    img.save(out_png)
    return Path(out_png)
