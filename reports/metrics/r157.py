"""UN R157 (ALKS) §5.2.3.3: the minimum following time gap to the vehicle ahead.

The regulation asks an active ALKS to keep at least a minimum time gap to a vehicle in
front in its lane, growing with its speed: 1.0 s at 7.2 km/h, 1.6 s at 60 km/h (its
table, extended to 130 km/h by the 01 series), i.e.

    t_min(v) = 1.0 s + v[km/h] / 100,        for v >= 7.2 km/h (2 m/s);

below 7.2 km/h it asks nothing. It also says when the gap may be shorter: "if the
minimum time gap cannot be respected temporarily because of other road users (e.g. a
vehicle cutting in, a decelerating lead vehicle)", the ALKS readjusts "at the next
available opportunity". The regulation puts no number on that opportunity; here it is
:data:`READJUST_S` after each shortfall begins (an interpretation, documented in
docs/metrics.md).

The vehicle ahead is the ego's leader of the DRAC metric
(:func:`reports.metrics.drac.leader_rows`: ahead, in the ego's path, the nearest) with
its bumper-to-bumper gap g [m]; the time gap is t = g / v_ego. A trace row is short when
it has a leader, v_ego >= 2 m/s and t < t_min(v_ego). A shortfall episode is a maximal
run of short rows; it counts beyond its first :data:`READJUST_S` seconds.

Metric ``r157_gap_shortfall_s`` [s] (lower is better): the sum over episodes of
max(0, D − READJUST_S), D an episode's duration (row durations summed), located at the
first row past the grace of the longest episode; 0 with no worst row when there is none,
NaN without trace rows. Its criterion ``max_r157_gap_shortfall_s`` is off by default
(most catalogs are not R157 tests); the bundled R157 pack switches it on at 0 s.
"""

from __future__ import annotations

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.drac import leader_rows
from reports.metrics.ttc import TtcPairs
from reports.metrics.values import Measured, measured
from reports.record.columns import BoolColumn, FloatColumn

__all__ = ["MIN_SPEED_MPS", "READJUST_S", "gap_shortfall_metrics", "min_time_gap_s",
           "short_rows"]

MIN_SPEED_MPS = 7.2 / 3.6  # the regulation's table starts at 7.2 km/h
READJUST_S = 3.0  # the time allowed to restore the gap after a shortfall begins [s]


def min_time_gap_s(speed_mps: FloatColumn) -> FloatColumn:
    """R157's minimum time gap t_min = 1.0 + v[km/h] / 100 [s] at ``speed_mps`` [m/s]."""
    out: FloatColumn = 1.0 + 3.6 * np.asarray(speed_mps, dtype=np.float64) / 100.0
    return out


def short_rows(ctx: RunContext, pairs: TtcPairs) -> BoolColumn:
    """Per trace row: whether the ego follows its leader closer than R157's minimum
    time gap at a speed the regulation covers (module doc), (n,)."""
    speed = np.asarray(ctx.record.trace.ego.speed_mps, dtype=np.float64)
    out = np.zeros(ctx.n, dtype=bool)
    rows, gaps, _ = leader_rows(pairs)
    if rows.size == 0:
        return out
    v = speed[rows]
    covered = np.isfinite(gaps) & np.isfinite(v) & (v >= MIN_SPEED_MPS)
    with np.errstate(divide="ignore", invalid="ignore"):
        short = covered & (gaps / np.where(v > 0, v, np.nan) < min_time_gap_s(v))
    out[rows[short]] = True
    return out


def gap_shortfall_metrics(ctx: RunContext, pairs: TtcPairs) -> list[Measured]:
    """``r157_gap_shortfall_s`` (module doc)."""
    if ctx.n == 0:
        return [measured("r157_gap_shortfall_s", float("nan"))]
    short = short_rows(ctx, pairs)
    total, worst_row, worst_excess = 0.0, None, 0.0
    edges = np.flatnonzero(np.diff(np.concatenate(([0], short.astype(np.int8), [0]))))
    for start, end in zip(edges[0::2], edges[1::2], strict=True):
        elapsed = np.cumsum(ctx.durations_s[start:end])
        excess = float(elapsed[-1]) - READJUST_S
        if excess <= 1e-12:
            continue
        total += excess
        if excess > worst_excess:
            worst_excess = excess
            worst_row = int(start + np.searchsorted(elapsed, READJUST_S, side="right"))
    return [measured("r157_gap_shortfall_s", total, worst_step=worst_row)]
