"""Safety metrics: collisions, gaps, time to collision, obstacle-ellipse margin.

Definitions (units in brackets; the drivable-area metrics are in
:mod:`reports.metrics.drivable`, the TTC model in :mod:`reports.metrics.ttc`)
-------------------------------------------------------------------------------
geom_collision_steps / sumo_collision_steps / sumo_collisions_reported [-]
    the steps the in-loop monitor flagged an overlap of the ego box with another box
    (``geom_collision``), the steps SUMO reported a collision of the ego
    (``sumo_collision``) and the collisions in SUMO's report (``outcome.sumo_collisions``).
    SUMO's two are informational (better 'none'): without its sublane model SUMO judges
    collisions along the lane only, so its report stands beside the verdict, never in
    it. ``collision``, ``first_collision_t_s`` and the collision classes rest on the 2-D
    boxes: :mod:`reports.metrics.collisions`.
min_gap_m [m]
    min of the trace's ``min_gap_m`` (box-to-box distance to the nearest vehicle);
    +inf if no vehicle was ever near, NaN without trace rows.
min_ttc_s / min_ttc_rear_s [s]
    min of the TTC series ahead / behind (+inf if no conflict), NaN without rows.
ssm_ttc_min_s [s]
    min of SUMO's SSM device TTC (``ssm_ttc_s``), recorded beside ours; NaN if none.
    ``sumo_ssm_conflicts`` / ``sumo_ssm_min_ttc_s`` / ``sumo_ssm_max_drac_mps2`` copy
    ``outcome.ssm`` (NaN when SUMO reported nothing or the SSM log was unreadable).
min_ellipse_margin [-]
    min over steps and active obstacle ellipses (``controller_arrays.npz``
    ``ellipses``, world frame) of (d_long/A)² + (d_lat/B)² − 1 for the ego CG, d the CG
    offset from the ellipse centre in the ellipse's axes; < 0 means the CG was inside
    an ellipse. NaN if no ellipse was ever active.
"""

from __future__ import annotations

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.values import Measured, extreme, measured
from reports.record.columns import FloatColumn


def ellipse_margin_series(ctx: RunContext) -> FloatColumn:
    """Per trace row: min over active ellipses of (d_long/A)² + (d_lat/B)² − 1 (NaN if none).

    ``ellipses`` rows are matched to trace rows by ``step`` when every step indexes the
    array, else by row order.
    """
    n = ctx.n
    out = np.full(n, np.nan)
    ell = np.asarray(ctx.record.arrays.ellipses, dtype=np.float64)
    if n == 0 or ell.ndim != 3 or ell.shape[-1] < 6 or ell.shape[0] == 0:
        return out
    steps = ctx.record.trace.step
    if np.all((steps >= 0) & (steps < ell.shape[0])):
        idx = steps.astype(np.int64)
        rows = np.arange(n)
    else:
        m = min(n, ell.shape[0])
        idx = np.arange(m)
        rows = np.arange(m)
    e = ell[idx]  # (R, K, 6)
    ego = ctx.record.trace.ego
    x = ego.x_m[rows][:, None]
    y = ego.y_m[rows][:, None]
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


def _collision_flags(ctx: RunContext) -> list[Measured]:
    safety = ctx.record.trace.safety
    return [
        measured("geom_collision_steps", float(np.sum(safety.geom_collision))),
        measured("sumo_collision_steps", float(np.sum(safety.sumo_collision))),
        measured("sumo_collisions_reported", float(len(ctx.record.outcome.sumo_collisions))),
    ]


def _min_of(name: str, values: FloatColumn, n: int) -> Measured:
    """The minimum of a per-row series where +inf means 'no conflict' (NaN without rows)."""
    if n == 0:
        return measured(name, float("nan"))
    value, row = extreme(values, "min")
    if row is None:  # nothing finite: never close to anything
        return measured(name, float("inf"))
    return measured(name, value, worst_step=row)


def _ssm_metrics(ctx: RunContext) -> list[Measured]:
    ttc = np.asarray(ctx.record.trace.safety.ssm_ttc_s, dtype=np.float64)
    counted = np.where(ttc >= 0, ttc, np.nan)
    value, row = extreme(counted, "min")
    ssm = ctx.record.outcome.ssm
    nan = float("nan")
    unreadable = ssm.error is not None
    return [
        measured("ssm_ttc_min_s", value, worst_step=row),
        measured("sumo_ssm_conflicts", nan if unreadable else float(ssm.conflicts)),
        measured("sumo_ssm_min_ttc_s", nan if unreadable or ssm.min_ttc_s is None
                 else ssm.min_ttc_s),
        measured("sumo_ssm_max_drac_mps2", nan if unreadable or ssm.max_drac_mps2 is None
                 else ssm.max_drac_mps2),
    ]


def safety_metrics(ctx: RunContext, ttc_ahead_s: FloatColumn, ttc_behind_s: FloatColumn,
                   ellipse_margin: FloatColumn) -> list[Measured]:
    """Collision flag counts, gap, TTC, SSM and ellipse metrics (see the module doc; the
    collision verdict is :mod:`reports.metrics.collisions`); the series are
    those of :mod:`reports.metrics.ttc` and :func:`ellipse_margin_series`."""
    n = ctx.n
    margin, margin_row = extreme(ellipse_margin, "min")
    out = _collision_flags(ctx)
    out += [
        _min_of("min_gap_m", ctx.record.trace.safety.min_gap_m, n),
        _min_of("min_ttc_s", ttc_ahead_s, n),
        _min_of("min_ttc_rear_s", ttc_behind_s, n),
        measured("min_ellipse_margin", margin, worst_step=margin_row),
    ]
    return out + _ssm_metrics(ctx)
