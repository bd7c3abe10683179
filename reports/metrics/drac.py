"""Deceleration rate to avoid a crash (DRAC) with the vehicle ahead in the ego's path.

Definition (SUMO's SSM device, ``MSDevice_SSM::computeDRAC``, for a lead/follow
encounter; CommonRoad-CriMe's DRAC is the same formula): for a follower at speed v_f
behind a leader at speed v_l with a bumper-to-bumper gap g > 0,

    DRAC = (v_f − v_l)² / (2 g)   [m/s²]   when v_f > v_l,   0 otherwise,

the constant deceleration that brings the follower to the leader's speed exactly when
the gap closes, the leader holding its speed. Here the follower is the ego.

Which vehicle is ahead, and the gap and speeds, are those of the time-to-collision pairs
(:mod:`reports.metrics.ttc`, one definition of "ahead" for both): at each trace row the
pairs that count ahead (``ahead`` and ``ego_moving``: the ego at least 0.5 m/s; a
replayed car only once wholly ahead of the ego's front), predicted along the road (or
in straight lines where a box cannot be placed on it), restricted to those **in the
ego's path** (the boxes overlap across the ego's heading). The leader is the nearest of
them (smallest gap). g = ``TtcPairs.gap_m`` (its rearmost corner minus the ego's
foremost corner along the ego's heading, in metres) and v_f − v_l =
``TtcPairs.closing_mps`` (the velocity difference along the ego's heading).

Per row (``series.drac_mps2``): 0 without a leader or when not closing (v_f − v_l <=
0); NaN where the leader's gap is <= 0 (the boxes touch or overlap along the path: a
contact, SUMO's "invalid" DRAC; the collision metrics judge it) or not finite. DRAC
grows without bound as g → 0+ with the speeds held, so a near-contact gives a large
finite value, never +inf.

Metric ``max_drac_mps2`` [m/s²] (lower is better): the largest finite per-row value,
located at its first row; 0 with no worst row when it never exceeded 0 (nothing was
ever closed on); NaN without trace rows or when every row is NaN.
"""

from __future__ import annotations

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.ttc import TtcPairs
from reports.metrics.values import Measured, extreme, measured
from reports.record.columns import FloatColumn


def drac_mps2(gap_m: np.ndarray, closing_mps: np.ndarray) -> FloatColumn:
    """DRAC [m/s²] elementwise for gaps ``gap_m`` [m] and closing speeds v_f − v_l
    ``closing_mps`` [m/s] (module doc): closing²/(2 gap) while closing, 0 when not, NaN
    for a gap <= 0 or a non-finite input."""
    g = np.asarray(gap_m, dtype=np.float64)
    dv = np.asarray(closing_mps, dtype=np.float64)
    valid = np.isfinite(g) & np.isfinite(dv) & (g > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        value = np.where(dv > 0, dv * dv / (2.0 * g), 0.0)
    out: FloatColumn = np.where(valid, value, np.nan)
    return out


def leader_rows(pairs: TtcPairs) -> tuple[np.ndarray, FloatColumn, FloatColumn]:
    """The ego's leader at each trace row that has one (module doc: ahead, the ego
    moving, in its path, the nearest): (rows (L,), their gaps [m] (L,), closing speeds
    [m/s] (L,)), rows ascending. The one definition of "the vehicle ahead" for DRAC and
    the R157 time gap (:mod:`reports.metrics.r157`)."""
    keep = pairs.ahead & pairs.ego_moving & pairs.in_path
    rows, gaps, closing = pairs.row[keep], pairs.gap_m[keep], pairs.closing_mps[keep]
    if rows.size == 0:
        return rows, gaps, closing
    # the nearest leader per row: sort by row, then gap (a NaN gap sorts last)
    order = np.lexsort((np.where(np.isnan(gaps), np.inf, gaps), rows))
    rows, gaps, closing = rows[order], gaps[order], closing[order]
    first = np.ones(rows.size, dtype=bool)
    first[1:] = rows[1:] != rows[:-1]
    return rows[first], gaps[first], closing[first]


def drac_series(ctx: RunContext, pairs: TtcPairs) -> FloatColumn:
    """Per trace row: the DRAC [m/s²] of the ego against its leader (module doc)."""
    out = np.zeros(ctx.n)
    rows, gaps, closing = leader_rows(pairs)
    if rows.size:
        out[rows] = drac_mps2(gaps, closing)
    return out


def drac_metrics(ctx: RunContext, drac: FloatColumn) -> list[Measured]:
    """``max_drac_mps2`` from :func:`drac_series` (module doc)."""
    if ctx.n == 0:
        return [measured("max_drac_mps2", float("nan"))]
    value, row = extreme(drac, "max")
    return [measured("max_drac_mps2", value, worst_step=row if value > 0 else None)]
