"""Synthetic run directories for the Rerun log tests, and a tiny bird's-eye renderer.

The road runs along +X: a shoulder (lane 0) and three driving lanes (1..3), 3.5 m
wide. The ego starts in lane 1 at 25 m/s, changes to lane 2 to pass a car stalled in
lane 1 at x = 200 m and returns; ``n_traffic`` faster vehicles drive ahead in lanes 2
and 3. The records are assembled, judged and written by :mod:`synthetic_runs`'s builders (the
one set the tests share), as the runner does; this module only draws the scene.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import synthetic_runs
from synthetic_runs import base_info, judge, write_judged, write_record

from reports.record import (
    ControllerArrays,
    EgoBox,
    LaneRecord,
    NeighbourColumns,
    RoadRecord,
    RunInfo,
    RunOutcome,
    RunRecord,
    StalledVehicle,
    SumoCollision,
    Trace,
)

LANE_W = 3.5
SHOULDER_W = 2.5
LANE_Y = {0: -(LANE_W + SHOULDER_W) / 2.0, 1: 0.0, 2: LANE_W, 3: 2 * LANE_W}
STALLED_X = 200.0
EGO_SPEED = 25.0
EGO = EgoBox(length_m=4.6, width_m=1.9, cg_to_front_bumper_m=3.5, cg_to_box_centre_m=1.2)
# the controller's own diagnostics in every synthetic trace (Trace.extra)
EXTRA = ("steer_outer_rad", "steer_corr_rad", "torque_outer_nm", "torque_corr_nm",
         "preview_err_t_m", "preview_err_n_m", "lateral_ref_m")
N_PLAN, N_PREVIEW = 20, 10


def _smooth(u: np.ndarray) -> np.ndarray:
    """0 → 1 with continuous acceleration (a lane change within the comfort limits)."""
    u = np.clip(u, 0.0, 1.0)
    return u ** 3 * (10 - 15 * u + 6 * u * u)


def ego_xy(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ego CG path: lane 1, over to lane 2 around the stalled car, back to lane 1
    (each change over 100 m, 4 s)."""
    x = EGO_SPEED * np.asarray(t, dtype=np.float64)
    y = LANE_W * (_smooth((x - 100.0) / 100.0) - _smooth((x - 240.0) / 100.0))
    return x, y


def _trace(steps: int, dt: float, seed: int, collision: bool) -> Trace:
    rng = np.random.default_rng(seed)
    tr = Trace.allocate(steps, EXTRA)
    t = (tr.step + 1) * dt
    x, y = ego_xy(t)
    xs, ys = ego_xy(t + 1e-3)
    psi = np.arctan2(ys - y, xs - x)
    lane_index = np.where(y > LANE_W / 2, 2, 1)
    tr.t_s[:] = t
    _fill_ego(tr, rng, t, psi, lane_index)
    _fill_scene(tr, x, lane_index, collision)
    _fill_controller(tr, rng, t)
    return tr


def _fill_ego(tr: Trace, rng: np.random.Generator, t: np.ndarray, psi: np.ndarray,
              lane_index: np.ndarray) -> None:
    """The ego's columns: the lane change of :func:`ego_xy` at constant speed."""
    steps = tr.step.shape[0]
    x, y = ego_xy(t)
    ego = tr.ego
    ego.x_m[:], ego.y_m[:], ego.psi_rad[:] = x, y, psi
    ego.u_mps[:], ego.v_mps[:], ego.r_radps[:] = EGO_SPEED, 0.0, np.gradient(psi, t)
    ego.speed_mps[:] = EGO_SPEED
    ego.long_acc_mps2[:] = 0.05 * rng.standard_normal(steps)
    ego.lat_acc_mps2[:] = np.gradient(np.gradient(y, t), t)
    ego.steer_rad[:], ego.torque_nm[:] = 0.02 * np.sin(t), 150 + 10 * np.sin(t)
    ego.s_m[:], ego.lat_dev_m[:], ego.heading_err_rad[:] = x, y, psi
    ego.lane_index[:] = lane_index
    ego.sumo_front_x_m[:] = x + EGO.cg_to_front_bumper_m * np.cos(psi)
    ego.sumo_front_y_m[:] = y + EGO.cg_to_front_bumper_m * np.sin(psi)
    ego.sumo_heading_rad[:] = psi


def _fill_scene(tr: Trace, x: np.ndarray, lane_index: np.ndarray, collision: bool) -> None:
    """The safety and decision columns: the stalled car's gap and SUMO's TTC, the pass."""
    front = x + EGO.cg_to_front_bumper_m
    behind = (lane_index == 1) & (front < STALLED_X - 4.5 / 2)
    gap = np.where(behind, STALLED_X - 4.5 / 2 - front, 30.0)
    ahead = (STALLED_X - x > 0) & (STALLED_X - x < 80.0)
    safety = tr.safety
    safety.ssm_ttc_s[:] = np.where((lane_index == 1) & (front < STALLED_X), gap / EGO_SPEED,
                                   np.nan)
    safety.gap_vehicle[:] = np.where(ahead, "stalled0", "")
    if collision:
        safety.geom_collision[100:105] = True
        safety.sumo_collision[101] = True
        gap[100:105] = 0.0
    safety.min_gap_m[:] = gap
    decision = tr.decision
    decision.target_speed_mps[:] = EGO_SPEED
    decision.side[:] = np.where(ahead, 1, 0)
    decision.side_reason[:] = np.where(ahead, "left lane free", "")
    decision.n_obstacles[:] = ahead.astype(int)
    decision.lat_ref_m[:] = np.where(ahead, LANE_W, 0.0)


def _fill_controller(tr: Trace, rng: np.random.Generator, t: np.ndarray) -> None:
    """The controller's columns, timing and diagnostics (a short fallback at 60-62)."""
    steps = tr.step.shape[0]
    ctrl = tr.controller
    ctrl.residual[:] = 1e-6 * (1 + rng.random(steps))
    ctrl.fallback[60:63] = True
    ctrl.guard_fired[:] = 0
    ctrl.outer_s[:] = 0.004 + 0.001 * rng.random(steps)
    ctrl.inner_s[:] = 0.001 + 0.0005 * rng.random(steps)
    tr.timing.obstacles_s[:] = 2e-4
    tr.timing.controller_s[:] = 0.0065
    tr.timing.sumo_s[:] = 0.002 + 0.001 * rng.random(steps)

    extra = tr.extra
    extra["steer_outer_rad"][:] = 0.018 * np.sin(t)
    extra["steer_corr_rad"][:] = 0.002 * np.sin(t)
    extra["torque_outer_nm"][:] = 140 + 10 * np.sin(t)
    extra["torque_corr_nm"][:] = 10.0
    extra["preview_err_t_m"][:] = 0.3 * np.cos(0.5 * t)
    extra["preview_err_n_m"][:] = 0.05 * N_PREVIEW  # the preview's drift below (0.05 m/knot)
    extra["lateral_ref_m"][:] = tr.decision.lat_ref_m


def _neighbours(t: np.ndarray, x: np.ndarray, y: np.ndarray, n_traffic: int,
                radius_m: float | None) -> NeighbourColumns:
    """The stalled car and traffic in lanes 2/3, driving faster than the ego."""
    lanes = np.array([2 + (i % 2) for i in range(n_traffic)])
    x0 = np.array([40.0 + 45.0 * i for i in range(n_traffic)])
    speed = np.array([27.0 + (i % 3) for i in range(n_traffic)])
    ids = ["stalled0"] + [f"veh{i}" for i in range(n_traffic)]
    vy = np.array([LANE_Y[1]] + [LANE_Y[int(la)] for la in lanes])
    rows: list[tuple[int, int]] = []  # (step, vehicle)
    for k in range(len(t)):
        vx = np.concatenate([[STALLED_X], x0 + speed * t[k]])
        near = np.ones(len(ids), bool) if radius_m is None \
            else np.hypot(vx - x[k], vy - y[k]) <= radius_m
        rows += [(k, j) for j in np.flatnonzero(near)]
    step = np.array([r[0] for r in rows], dtype=np.int64)
    veh = np.array([r[1] for r in rows], dtype=np.int64)
    nb = NeighbourColumns.allocate(len(rows))
    nb.step[:], nb.t_s[:] = step, t[step]
    nb.id[:] = [ids[j] for j in veh]
    moving = veh > 0
    nb.x_m[:] = np.where(moving, x0[np.maximum(veh - 1, 0)] + speed[np.maximum(veh - 1, 0)]
                         * t[step], STALLED_X)
    nb.y_m[:] = vy[veh]
    nb.heading_rad[:] = 0.0
    nb.speed_mps[:] = np.where(moving, speed[np.maximum(veh - 1, 0)], 0.0)
    nb.length_m[:] = np.where(moving, 4.8, 4.5)
    nb.width_m[:] = np.where(moving, 1.9, 1.8)
    nb.lane_index[:] = np.where(moving, lanes[np.maximum(veh - 1, 0)], 1)
    nb.stalled[:] = ~moving
    return nb


def _arrays(t: np.ndarray, ahead: np.ndarray) -> ControllerArrays:
    """Plan (0.2 s knots), preview (0.1 s, drifting 0.05 m per knot to the left), one
    ellipse for the stalled car while it is ahead."""
    tp = t[:, None] + 0.2 * np.arange(N_PLAN + 1)[None, :]
    px, py = ego_xy(tp)
    plan = np.stack([px, py], axis=-1)
    plan[:5] = np.nan  # no plan yet for the first steps (NaN padding)
    tq = t[:, None] + 0.1 * np.arange(N_PREVIEW + 1)[None, :]
    qx, qy = ego_xy(tq)
    preview = np.stack([qx, qy + 0.05 * np.arange(N_PREVIEW + 1)[None, :]], axis=-1)
    ell = np.full((len(t), 3, 6), np.nan)
    ell[:, :, 5] = 0.0
    ell[ahead, 0] = [STALLED_X, -0.3, 0.0, 4.5 / 2 + EGO.length_m / 2 + 2.0,
                     1.8 / 2 + EGO.width_m / 2 + 0.4, 1.0]
    return ControllerArrays(plan_xy_m=plan, preview_xy_m=preview, ellipses=ell,
                            detection_radius_m=80.0)


def _road(x_end: float) -> RoadRecord:
    road_len = max(1000.0, x_end + 300.0)
    xs = np.linspace(-50.0, road_len, 12)
    lanes = tuple(LaneRecord(
        id=f"E0_{i}", edge_id="E0", index=i, width_m=SHOULDER_W if i == 0 else LANE_W,
        shape_xy_m=np.stack([xs, np.full(xs.size, LANE_Y[i])], axis=1), allowed=("passenger",),
        is_shoulder=i == 0) for i in range(4))
    return RoadRecord(lanes=lanes, reference_xy_m=np.stack([xs, np.zeros(xs.size)], axis=1),
                      reference_length_m=road_len + 50.0, route=("E0",))


def info(scenario: str, seed: int, catalog: str, steps: int, dt: float,
         criteria: Mapping[str, Any] | None = None) -> RunInfo:
    """:func:`synthetic_runs.base_info` with this scene's catalog, net, ego and options."""
    return base_info(scenario, controller="mpc_spmm", family="stalled",
                     catalog=f"catalogs/{catalog}.toml", catalog_name=catalog, seed=seed,
                     net="sumo_nets/straight3.net.xml", net_name="straight3",
                     duration_s=steps * dt, step_s=dt, target_speed_mps=EGO_SPEED, ego=EGO,
                     controller_options={"horizon": N_PLAN},
                     controller_params={"horizon": N_PLAN, "dt_plan_s": 0.2, "q_y": 1.0},
                     criteria=dict(criteria or {}))


def make_record(*, scenario: str = "stalled_pass", seed: int = 1, catalog: str = "smoke",
                steps: int = 300, n_traffic: int = 2, dt: float = 0.1, collision: bool = False,
                criteria: Mapping[str, Any] | None = None,
                neighbour_radius_m: float | None = 150.0) -> RunRecord:
    """A judged synthetic record (see the module doc)."""
    tr = _trace(steps, dt, seed, collision)
    x, y = tr.ego.x_m, tr.ego.y_m
    ahead = (STALLED_X - x > 0) & (STALLED_X - x < 80.0)
    stalled = StalledVehicle(id="stalled0", x_m=STALLED_X, y_m=0.0, heading_rad=0.0,
                             length_m=4.5, width_m=1.8, lane_index=1)
    hits = (SumoCollision(t_s=float(tr.t_s[101]), collider="ego", victim="stalled0",
                          type="collision"),) if collision else ()
    outcome = RunOutcome(wall_s=3.2, sim_time_s=float(tr.t_s[-1]), steps=steps,
                         stalled=(stalled,), sumo_collisions=hits)
    record = synthetic_runs.make_record(
        tr, info=info(scenario, seed, catalog, steps, dt, criteria), outcome=outcome,
        road=_road(float(x[-1])),
        neighbours=_neighbours(tr.t_s, x, y, n_traffic, neighbour_radius_m),
        arrays=_arrays(tr.t_s, ahead))
    return judge(record)


def make_run_dir(root: Path, *, scenario: str = "stalled_pass", **kw: Any) -> Path:
    """Write a judged synthetic run directory ``root/<scenario>`` and return it."""
    run_dir = Path(root) / scenario
    write_record(make_record(scenario=scenario, **kw), run_dir)
    return run_dir


def make_error_dir(root: Path, scenario: str = "boom", error: str = "Traceback...\n"
                   "RuntimeError: SUMO died") -> Path:
    """A run that crashed before its first step, judged and written as the runner does."""
    record = synthetic_runs.make_record(
        None, info=info(scenario, 3, "smoke", 0, 0.1),
        outcome=RunOutcome(end="error", error=error), road=RoadRecord())
    return write_judged(record, Path(root) / scenario)


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
