"""Drivable area: how far the ego box is outside the lanes it may use, and shoulder use.

A point's *excess* for a lane is (distance to the lane centreline polyline) − width/2
[m]: < 0 inside the lane. A box corner is *off the drivable area* when its smallest
excess over the drivable lanes is more than ``OFFROAD_TOLERANCE_M`` (0.3 m). Drivable
lanes admit passenger cars (:meth:`reports.record.LaneRecord.drivable`); shoulder
lanes count only when the scenario allows the shoulder (``info.allow_shoulder``).

Metrics: ``offroad_s`` [s] time with any corner off, ``offroad_m`` [m] distance driven
meanwhile, ``max_offroad_m`` [m] the largest corner excess (0 when always inside),
``shoulder_s`` [s] time with the box centre inside a shoulder lane and not inside a
regular drivable lane. All NaN without trace rows or without lanes.
"""

from __future__ import annotations

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.values import Measured, extreme, measured
from reports.record import LaneRecord
from reports.record.columns import BoolColumn, FloatColumn

OFFROAD_TOLERANCE_M = 0.3


def point_lane_excess(points: np.ndarray, shape_xy: np.ndarray, width_m: float) -> FloatColumn:
    """(distance of each point (P, 2) to the centreline polyline (M, 2)) − width/2 [m]."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    shape = np.asarray(shape_xy, dtype=np.float64).reshape(-1, 2)
    if shape.shape[0] == 0:
        return np.full(pts.shape[0], np.inf)
    if shape.shape[0] == 1:
        shape = np.vstack([shape, shape])
    a, b = shape[:-1], shape[1:]
    best = np.full(pts.shape[0], np.inf)
    chunk = max(1, 200_000 // max(1, a.shape[0]))  # bounds the (chunk, segments) temporaries
    for start in range(0, pts.shape[0], chunk):
        p = pts[start:start + chunk, None, :]
        ab = b - a
        denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-12)
        t = np.clip(np.sum((p - a) * ab, axis=-1) / denom, 0.0, 1.0)
        closest = a + t[..., None] * ab
        best[start:start + chunk] = np.linalg.norm(p - closest, axis=-1).min(axis=1)
    out: FloatColumn = best - 0.5 * float(width_m)
    return out


def road_lanes(ctx: RunContext) -> list[LaneRecord]:
    """Lanes with a centreline and a width."""
    return [ln for ln in ctx.record.road.lanes if ln.shape_xy_m.shape[0] > 0 and ln.width_m > 0]


def offroad_excess_series(ctx: RunContext) -> FloatColumn:
    """Per trace row: the largest ego-corner excess beyond the drivable lanes [m] (NaN
    without lanes or pose)."""
    n = ctx.n
    allow = ctx.record.info.allow_shoulder
    lanes = [ln for ln in road_lanes(ctx) if ln.drivable(allow)]
    if n == 0 or not lanes:
        return np.full(n, np.nan)
    pts = ctx.corners_m.reshape(-1, 2)
    excess = np.full(pts.shape[0], np.inf)
    for lane in lanes:
        excess = np.minimum(excess, point_lane_excess(pts, lane.shape_xy_m, lane.width_m))
    out: FloatColumn = excess.reshape(n, 4).max(axis=1)
    out[~np.all(np.isfinite(ctx.corners_m.reshape(n, 8)), axis=1)] = np.nan
    return out


def offroad_steps(excess_m: np.ndarray) -> BoolColumn:
    """Per trace row: some corner is more than the tolerance outside every drivable lane."""
    flags: BoolColumn = np.nan_to_num(excess_m, nan=-np.inf) > OFFROAD_TOLERANCE_M
    return flags


def shoulder_steps(ctx: RunContext) -> BoolColumn:
    """Per trace row: box centre inside a shoulder lane and not inside a regular lane."""
    n = ctx.n
    lanes = road_lanes(ctx)
    shoulders = [ln for ln in lanes if ln.is_shoulder]
    if n == 0 or not shoulders:
        return np.zeros(n, dtype=bool)
    regular = [ln for ln in lanes if not ln.is_shoulder and ln.drivable(False)]
    pts = np.stack([ctx.box_x_m, ctx.box_y_m], axis=-1)
    on_sh = np.zeros(n, dtype=bool)
    for lane in shoulders:
        on_sh |= point_lane_excess(pts, lane.shape_xy_m, lane.width_m) <= 0.0
    on_reg = np.zeros(n, dtype=bool)
    for lane in regular:
        on_reg |= point_lane_excess(pts, lane.shape_xy_m, lane.width_m) <= 0.0
    out: BoolColumn = on_sh & ~on_reg
    return out


def drivable_metrics(ctx: RunContext, excess_m: FloatColumn) -> list[Measured]:
    """offroad_s, offroad_m, max_offroad_m, shoulder_s (see the module doc);
    ``excess_m`` is :func:`offroad_excess_series`."""
    series = "series.offroad_excess_m"
    if ctx.n == 0 or not road_lanes(ctx):
        nan = float("nan")
        return [measured("offroad_s", nan, "s", "safety", "lower"),
                measured("offroad_m", nan, "m", "safety", "lower"),
                measured("max_offroad_m", nan, "m", "safety", "lower", series=series),
                measured("shoulder_s", nan, "s", "safety", "lower")]
    bad = offroad_steps(excess_m)
    dt = ctx.durations_s
    speed = np.nan_to_num(ctx.record.trace.ego.speed_mps)
    peak, row = extreme(excess_m, "max")
    shoulder = shoulder_steps(ctx)
    return [
        measured("offroad_s", float(np.sum(dt[bad])), "s", "safety", "lower",
                 increments=np.where(bad, dt, 0.0)),
        measured("offroad_m", float(np.sum((speed * dt)[bad])), "m", "safety", "lower"),
        # clamped at 0: inside the lanes the whole run has no worst corner to point at
        measured("max_offroad_m", max(0.0, peak) if row is not None else float("inf"), "m",
                 "safety", "lower", worst_step=row if peak > 0 else None, series=series),
        measured("shoulder_s", float(np.sum(dt[shoulder])), "s", "safety", "lower",
                 increments=np.where(shoulder, dt, 0.0)),
    ]
