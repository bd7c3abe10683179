"""Safety metrics: collisions, gaps, time to collision, obstacle-ellipse margin, drivable area.

Definitions (units in brackets)
-------------------------------
collision [0/1]
    1 if any step has ``geom_collision`` (ego box overlaps another box) or
    ``sumo_collision`` (SUMO reported a collision involving the ego), else 0.
min_gap_m [m]
    min of the trace's ``min_gap_m`` (box-to-box distance to the nearest vehicle);
    +inf if no vehicle was ever near, NaN for an empty trace.
min_ttc_s [s]
    Our own time to collision. At each step, for each recorded neighbour, both boxes
    are extrapolated at constant velocity (ego: world velocity from u, v, psi;
    neighbour: ``speed_mps`` along ``heading_rad``) with fixed headings. The relative
    motion is then a pure translation, and the boxes touch at the first time τ at which
    their projections overlap on all four separating axes (two edge normals of each
    box) — an exact swept separating-axis test, no sampling. TTC = that τ (0 if they
    already overlap), +inf if they never touch within ``TTC_HORIZON_S`` (10 s).
    ``min_ttc_s`` is the minimum over steps where the ego moves (speed ≥
    ``TTC_MIN_EGO_SPEED_MPS`` = 0.5 m/s; waiting behind a stopped car is not a
    conflict) and over neighbours whose box centre is not behind the ego box centre
    (projection on the ego heading ≥ 0): conflicts the ego drives into. Conflicts with
    vehicles behind (being caught up by faster traffic) are in ``min_ttc_rear_s``.
ssm_ttc_min_s [s]
    min of SUMO's SSM device TTC (``ssm_ttc_s``), recorded beside ours; NaN if none.
    ``sumo_ssm_conflicts`` / ``sumo_ssm_min_ttc_s`` / ``sumo_ssm_max_drac_mps2`` copy
    run.json's ``ssm`` summary (NaN when absent).
min_ellipse_margin [-]
    min over steps and active obstacle ellipses (``controller_arrays.npz`` ``ellipses``,
    world frame) of (d_long/A)² + (d_lat/B)² − 1 for the ego CG, where d is the CG
    offset from the ellipse centre in the ellipse's axes; < 0 means the CG was inside
    an ellipse. NaN if no ellipse was ever active.
offroad_s, offroad_m, max_offroad_m
    A box corner is *off the drivable area* if it is more than
    ``OFFROAD_TOLERANCE_M`` (0.3 m) outside every drivable lane; a point's excess for
    a lane is (distance to the lane centreline polyline) − width/2. Drivable lanes are
    those admitting passenger cars (road.json ``allows_passenger`` when present, else
    ``allowed`` contains ``passenger`` or is empty — SUMO's "no restriction"); shoulder
    lanes (``is_shoulder``) count only when ``run.json`` has ``allow_shoulder: true``
    (or ``shoulder_allowed``). offroad_s is the time [s] with any corner off, offroad_m
    the distance driven then [m],
    max_offroad_m the largest corner excess [m] (0 if always within a lane).
shoulder_s [s]
    Time with the ego box centre inside a shoulder lane and not inside a
    non-shoulder drivable lane.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from reports.metrics.geometry import box_corners
from reports.metrics.tracking import bool_column, column, step_durations_s
from reports.run_record import RunRecord

TTC_HORIZON_S = 10.0
TTC_MIN_EGO_SPEED_MPS = 0.5
OFFROAD_TOLERANCE_M = 0.3
# run.json "ssm" summary figures copied as sumo_ssm_<key> (NaN when absent)
SSM_SUMMARY_KEYS = ("conflicts", "min_ttc_s", "max_drac_mps2")

DEFAULT_EGO_LENGTH_M = 4.5
DEFAULT_EGO_WIDTH_M = 1.8


# --------------------------------------------------------------------------- ego geometry


def ego_dimensions(meta: Mapping[str, Any]) -> tuple[float, float, float]:
    """(length_m, width_m, cg_to_box_centre_m) of the ego from ``run.json``."""
    ego = meta.get("ego") or {}
    length = float(ego.get("length_m", DEFAULT_EGO_LENGTH_M))
    width = float(ego.get("width_m", DEFAULT_EGO_WIDTH_M))
    offset = float(ego.get("cg_to_box_centre_m", 0.0))
    return length, width, offset


def ego_boxes(record: RunRecord) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per step: ego box centre x, y [m], heading [rad] and corners (T, 4, 2) [m]."""
    length, width, offset = ego_dimensions(record.meta)
    x, y, psi = column(record, "x_m"), column(record, "y_m"), column(record, "psi_rad")
    cx = x + offset * np.cos(psi)
    cy = y + offset * np.sin(psi)
    corners = box_corners(cx, cy, psi, length, width)
    return cx, cy, psi, corners.reshape(len(x), 4, 2)


def ego_world_velocity(record: RunRecord) -> tuple[np.ndarray, np.ndarray]:
    """Ego velocity in the world frame [m/s] from body u, v and yaw (speed along yaw
    where u/v are missing)."""
    psi = column(record, "psi_rad")
    u, v = column(record, "u_mps"), column(record, "v_mps")
    speed = column(record, "speed_mps")
    u = np.where(np.isfinite(u), u, speed)
    v = np.where(np.isfinite(v), v, 0.0)
    c, s = np.cos(psi), np.sin(psi)
    return u * c - v * s, u * s + v * c


# --------------------------------------------------------------------------- collisions


def collision_steps(record: RunRecord) -> np.ndarray:
    """Per step: the ego collided (geometric overlap or SUMO report)."""
    return bool_column(record, "geom_collision") | bool_column(record, "sumo_collision")


def collision(record: RunRecord) -> float:
    """1.0 if the ego collided at any step (geometric or SUMO), else 0.0."""
    return 1.0 if bool(np.any(collision_steps(record))) else 0.0


def first_collision_t_s(record: RunRecord) -> float:
    """Simulation time of the first collision step [s] (NaN if none)."""
    steps = np.flatnonzero(collision_steps(record))
    return float(column(record, "t_s")[steps[0]]) if steps.size else float("nan")


def min_gap_m(record: RunRecord) -> float:
    """Smallest box-to-box gap to any other vehicle [m] (+inf if none, NaN if no trace)."""
    if len(record.trace) == 0:
        return float("nan")
    gap = column(record, "min_gap_m")
    gap = gap[np.isfinite(gap)]
    return float(gap.min()) if gap.size else float("inf")


def ssm_ttc_min_s(record: RunRecord) -> float:
    """Smallest SUMO SSM TTC for the ego [s] (NaN if SUMO reported none)."""
    ttc = column(record, "ssm_ttc_s")
    ttc = ttc[np.isfinite(ttc) & (ttc >= 0)]
    return float(ttc.min()) if ttc.size else float("nan")


# --------------------------------------------------------------------------- TTC


def swept_box_ttc(corners_a: np.ndarray, vel_a: np.ndarray, corners_b: np.ndarray,
                  vel_b: np.ndarray, horizon_s: float = TTC_HORIZON_S) -> np.ndarray:
    """Time until boxes A and B first touch when translating at constant velocity [s].

    corners_*: (..., 4, 2) as from :func:`reports.metrics.geometry.box_corners`; vel_*: (..., 2).
    Exact swept separating-axis test over the four edge normals. 0 if they overlap
    now, +inf if they never touch within ``horizon_s``.
    """
    a = np.asarray(corners_a, dtype=np.float64)
    b = np.asarray(corners_b, dtype=np.float64)
    a, b = np.broadcast_arrays(a, b)
    w = np.broadcast_to(np.asarray(vel_a, dtype=np.float64) - np.asarray(vel_b, dtype=np.float64),
                        a.shape[:-2] + (2,))
    t_enter = np.full(a.shape[:-2], -np.inf)
    t_exit = np.full(a.shape[:-2], np.inf)
    never = np.zeros(a.shape[:-2], dtype=bool)
    for poly in (a, b):
        for i in range(2):
            edge = poly[..., i + 1, :] - poly[..., i, :]
            normal = np.stack([-edge[..., 1], edge[..., 0]], axis=-1)
            norm = np.linalg.norm(normal, axis=-1, keepdims=True)
            normal = normal / np.maximum(norm, 1e-12)
            pa = np.einsum("...kd,...d->...k", a, normal)
            pb = np.einsum("...kd,...d->...k", b, normal)
            a_min, a_max = pa.min(-1), pa.max(-1)
            b_min, b_max = pb.min(-1), pb.max(-1)
            c = np.einsum("...d,...d->...", w, normal)
            still = np.abs(c) < 1e-9
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (b_min - a_max) / c
                t2 = (b_max - a_min) / c
            lo = np.where(still, -np.inf, np.minimum(t1, t2))
            hi = np.where(still, np.inf, np.maximum(t1, t2))
            never |= still & ((a_min > b_max) | (a_max < b_min))
            t_enter = np.maximum(t_enter, lo)
            t_exit = np.minimum(t_exit, hi)
    hit = ~never & (t_enter <= t_exit) & (t_exit >= 0.0)
    ttc = np.where(hit, np.maximum(t_enter, 0.0), np.inf)
    return np.where(ttc <= horizon_s, ttc, np.inf)


def ttc_pairs(record: RunRecord, horizon_s: float = TTC_HORIZON_S) -> dict[str, np.ndarray]:
    """TTC for every (step, neighbour) row of ``neighbours.parquet``.

    Returns arrays aligned with the neighbour rows: ``row`` (trace row index), ``ttc_s``,
    ``front`` (neighbour centre not behind the ego box centre), ``ego_moving``.
    """
    nb = record.neighbours
    empty = {"row": np.zeros(0, dtype=int), "ttc_s": np.zeros(0),
             "front": np.zeros(0, dtype=bool), "ego_moving": np.zeros(0, dtype=bool)}
    if len(record.trace) == 0 or len(nb) == 0 or "step" not in record.trace.columns:
        return empty
    steps = record.trace["step"].to_numpy()
    order = np.argsort(steps, kind="stable")
    nb_steps = nb["step"].to_numpy()
    pos = np.searchsorted(steps[order], nb_steps)
    pos = np.clip(pos, 0, len(order) - 1)
    rows = order[pos]
    valid = steps[rows] == nb_steps
    if not np.any(valid):
        return empty
    rows = rows[valid]
    nbv = nb.loc[valid]
    cx, cy, psi, corners = ego_boxes(record)
    vx, vy = ego_world_velocity(record)
    speed = np.hypot(vx, vy)

    def nb_col(name: str, default: float) -> np.ndarray:
        if name not in nbv.columns:
            return np.full(len(nbv), default)
        return nbv[name].to_numpy(dtype=np.float64)

    nx, ny = nb_col("x_m", np.nan), nb_col("y_m", np.nan)
    nh, ns = nb_col("heading_rad", 0.0), nb_col("speed_mps", 0.0)
    nl, nw = nb_col("length_m", 4.5), nb_col("width_m", 1.8)
    nb_corners = box_corners(nx, ny, nh, nl, nw)
    nb_vel = np.stack([ns * np.cos(nh), ns * np.sin(nh)], axis=-1)
    ego_vel = np.stack([vx[rows], vy[rows]], axis=-1)
    ttc = swept_box_ttc(corners[rows], ego_vel, nb_corners, np.nan_to_num(nb_vel), horizon_s)
    finite_pose = np.isfinite(nx) & np.isfinite(ny) & np.isfinite(cx[rows]) & np.isfinite(cy[rows])
    ttc = np.where(finite_pose, ttc, np.inf)
    ahead = (nx - cx[rows]) * np.cos(psi[rows]) + (ny - cy[rows]) * np.sin(psi[rows])
    return {"row": rows, "ttc_s": ttc, "front": ahead >= 0.0,
            "ego_moving": speed[rows] >= TTC_MIN_EGO_SPEED_MPS}


def ttc_series(record: RunRecord, front_only: bool = True) -> np.ndarray:
    """Per trace row: min TTC over counted neighbours [s] (+inf if none)."""
    out = np.full(len(record.trace), np.inf)
    pairs = ttc_pairs(record)
    if pairs["row"].size:
        keep = pairs["ego_moving"] & (pairs["front"] if front_only else ~pairs["front"])
        np.minimum.at(out, pairs["row"][keep], pairs["ttc_s"][keep])
    return out


def min_ttc_s(record: RunRecord) -> float:
    """Min TTC to vehicles ahead while the ego moves [s] (see module doc); inf if never."""
    if len(record.trace) == 0:
        return float("nan")
    return float(np.min(ttc_series(record, front_only=True), initial=np.inf))


def min_ttc_rear_s(record: RunRecord) -> float:
    """Min TTC to vehicles behind the ego while it moves [s]; inf if never."""
    if len(record.trace) == 0:
        return float("nan")
    return float(np.min(ttc_series(record, front_only=False), initial=np.inf))


# --------------------------------------------------------------------------- ellipses


def ellipse_margin_series(record: RunRecord) -> np.ndarray:
    """Per trace row: min over active ellipses of (d_long/A)² + (d_lat/B)² − 1 (NaN if none).

    ``ellipses`` rows are matched to trace rows by the ``step`` column when every step
    indexes the array, else by row order.
    """
    n = len(record.trace)
    out = np.full(n, np.nan)
    ell = record.arrays.get("ellipses")
    if ell is None or n == 0:
        return out
    ell = np.asarray(ell, dtype=np.float64)
    if ell.ndim != 3 or ell.shape[-1] < 6 or ell.shape[0] == 0:
        return out
    steps = column(record, "step")
    if np.all(np.isfinite(steps)) and np.all((steps >= 0) & (steps < ell.shape[0])):
        idx = steps.astype(int)
        rows = np.arange(n)
    else:
        m = min(n, ell.shape[0])
        idx = np.arange(m)
        rows = np.arange(m)
    e = ell[idx]  # (R, K, 6)
    x = column(record, "x_m")[rows][:, None]
    y = column(record, "y_m")[rows][:, None]
    cx, cy, h, sa, sb, act = (e[..., i] for i in range(6))
    dx, dy = x - cx, y - cy
    d_long = dx * np.cos(h) + dy * np.sin(h)
    d_lat = -dx * np.sin(h) + dy * np.cos(h)
    with np.errstate(divide="ignore", invalid="ignore"):
        margin = (d_long / sa) ** 2 + (d_lat / sb) ** 2 - 1.0
    ok = (np.nan_to_num(act) > 0.5) & np.isfinite(margin) & (sa > 0) & (sb > 0)
    margin = np.where(ok, margin, np.inf)
    best = margin.min(axis=1) if margin.shape[1] else np.full(len(rows), np.inf)
    out[rows] = np.where(np.isfinite(best), best, np.nan)
    return out


def min_ellipse_margin(record: RunRecord) -> float:
    """Min ellipse margin over the run [-] (< 0: CG inside an obstacle ellipse; NaN if none)."""
    m = ellipse_margin_series(record)
    m = m[np.isfinite(m)]
    return float(m.min()) if m.size else float("nan")


# --------------------------------------------------------------------------- drivable area


def shoulder_allowed(meta: Mapping[str, Any]) -> bool:
    """Whether the scenario lets the ego use shoulder lanes (``run.json`` ``allow_shoulder``)."""
    for key in ("allow_shoulder", "shoulder_allowed"):
        if key in meta:
            return bool(meta[key])
    return False


def lane_is_drivable(lane: Mapping[str, Any], allow_shoulder: bool) -> bool:
    """A lane admits the ego: passenger cars allowed (empty list = all); shoulder if allowed."""
    if lane.get("is_shoulder"):
        return allow_shoulder
    if isinstance(lane.get("allows_passenger"), bool):
        return bool(lane["allows_passenger"])
    allowed = lane.get("allowed") or []
    return (not allowed) or ("passenger" in allowed)


def point_lane_excess(points: np.ndarray, shape_xy: Sequence[Sequence[float]],
                      width_m: float) -> np.ndarray:
    """(distance of each point to the lane centreline polyline) − width/2 [m]; < 0 inside."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    shape = np.asarray(shape_xy, dtype=np.float64).reshape(-1, 2)
    if shape.shape[0] == 0:
        return np.full(pts.shape[0], np.inf)
    if shape.shape[0] == 1:
        shape = np.vstack([shape, shape])
    a, b = shape[:-1], shape[1:]
    best = np.full(pts.shape[0], np.inf)
    chunk = max(1, 200_000 // max(1, a.shape[0]))
    for start in range(0, pts.shape[0], chunk):
        p = pts[start:start + chunk, None, :]
        ab = b - a
        denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-12)
        t = np.clip(np.sum((p - a) * ab, axis=-1) / denom, 0.0, 1.0)
        closest = a + t[..., None] * ab
        d = np.linalg.norm(p - closest, axis=-1).min(axis=1)
        best[start:start + chunk] = d
    return best - 0.5 * float(width_m)


def _lanes(record: RunRecord) -> list[Mapping[str, Any]]:
    lanes = record.road.get("lanes") or []
    return [ln for ln in lanes if ln.get("shape_xy_m") and ln.get("width_m")]


def offroad_excess_series(record: RunRecord) -> np.ndarray:
    """Per trace row: the largest corner excess beyond the drivable lanes [m] (NaN if no
    road or pose). > ``OFFROAD_TOLERANCE_M`` counts as off the drivable area."""
    n = len(record.trace)
    lanes = [ln for ln in _lanes(record)
             if lane_is_drivable(ln, shoulder_allowed(record.meta))]
    if n == 0 or not lanes:
        return np.full(n, np.nan)
    _, _, _, corners = ego_boxes(record)
    pts = corners.reshape(-1, 2)
    excess = np.full(pts.shape[0], np.inf)
    for lane in lanes:
        excess = np.minimum(excess, point_lane_excess(pts, lane["shape_xy_m"], lane["width_m"]))
    per_step = excess.reshape(n, 4)
    bad_pose = ~np.all(np.isfinite(corners.reshape(n, 8)), axis=1)
    out = per_step.max(axis=1)
    out[bad_pose] = np.nan
    return out


def offroad_steps(record: RunRecord) -> np.ndarray:
    """Per trace row: some ego box corner is more than 0.3 m outside every drivable lane."""
    ex = offroad_excess_series(record)
    return np.nan_to_num(ex, nan=-np.inf) > OFFROAD_TOLERANCE_M


def offroad_metrics(record: RunRecord) -> dict[str, float]:
    """offroad_s [s], offroad_m [m], max_offroad_m [m], shoulder_s [s] (see module doc)."""
    n = len(record.trace)
    if n == 0 or not _lanes(record):
        nan = float("nan")
        return {"offroad_s": nan, "offroad_m": nan, "max_offroad_m": nan, "shoulder_s": nan}
    ex = offroad_excess_series(record)
    bad = np.nan_to_num(ex, nan=-np.inf) > OFFROAD_TOLERANCE_M
    dt = step_durations_s(record)
    speed = np.nan_to_num(column(record, "speed_mps"))
    finite = ex[np.isfinite(ex)]
    return {
        "offroad_s": float(np.sum(dt[bad])),
        "offroad_m": float(np.sum((speed * dt)[bad])),
        "max_offroad_m": float(max(0.0, finite.max())) if finite.size else float("inf"),
        "shoulder_s": float(np.sum(dt[shoulder_steps(record)])),
    }


def shoulder_steps(record: RunRecord) -> np.ndarray:
    """Per trace row: box centre inside a shoulder lane and not inside a regular drivable lane."""
    n = len(record.trace)
    lanes = _lanes(record)
    shoulders = [ln for ln in lanes if ln.get("is_shoulder")]
    if n == 0 or not shoulders:
        return np.zeros(n, dtype=bool)
    regular = [ln for ln in lanes if not ln.get("is_shoulder") and lane_is_drivable(ln, False)]
    cx, cy, _, _ = ego_boxes(record)
    pts = np.stack([cx, cy], axis=-1)
    on_sh = np.zeros(n, dtype=bool)
    for lane in shoulders:
        on_sh |= point_lane_excess(pts, lane["shape_xy_m"], lane["width_m"]) <= 0.0
    on_reg = np.zeros(n, dtype=bool)
    for lane in regular:
        on_reg |= point_lane_excess(pts, lane["shape_xy_m"], lane["width_m"]) <= 0.0
    return on_sh & ~on_reg


def safety_metrics(record: RunRecord) -> dict[str, float]:
    """All safety metrics by name (see module doc)."""
    geom = bool_column(record, "geom_collision")
    sumo = bool_column(record, "sumo_collision")
    out = {
        "collision": collision(record),
        "geom_collision_steps": float(np.sum(geom)),
        "sumo_collision_steps": float(np.sum(sumo)),
        "sumo_collisions_reported": float(len(record.meta.get("sumo_collisions") or [])),
        "first_collision_t_s": first_collision_t_s(record),
        "min_gap_m": min_gap_m(record),
        "min_ttc_s": min_ttc_s(record),
        "min_ttc_rear_s": min_ttc_rear_s(record),
        "ssm_ttc_min_s": ssm_ttc_min_s(record),
        "min_ellipse_margin": min_ellipse_margin(record),
    }
    out.update(offroad_metrics(record))
    ssm = record.meta.get("ssm") or {}
    ssm = ssm if isinstance(ssm, Mapping) else {}
    for key in SSM_SUMMARY_KEYS:  # a fixed set, so every run has the same metric names
        value = ssm.get(key)
        if isinstance(value, int | float) and not isinstance(value, bool):
            out[f"sumo_ssm_{key}"] = float(value)
        else:
            out[f"sumo_ssm_{key}"] = float("nan")
    return out
