"""What every metric module needs from a run, derived once: time base and ego geometry.

:class:`RunContext` holds, for a record of T trace rows:

* ``t_s`` (T,) [s] simulation time; ``period_s`` the control period (``info.step_s``,
  else the median spacing of ``t_s``); ``sample_period_s`` the median spacing of
  ``t_s`` (else the control period), the sampling the comfort filters assume;
  ``durations_s`` (T,) [s] the time each row stands for (``t_s`` differences, the first
  row gets the control period), used to turn per-step flags into times.
* the ego box per row: centre ``box_x_m``/``box_y_m`` [m] (the CG moved
  ``cg_to_box_centre_m`` along the yaw), ``psi_rad``, ``corners_m`` (T, 4, 2) [m];
* the ego velocity in the world frame ``vel_x_mps``/``vel_y_mps`` [m/s] from body u, v
  and yaw (``speed_mps`` along the yaw where u is missing, v = 0 where missing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports.geometry import ego_box_centres, ego_box_corners
from reports.record import RunRecord
from reports.record.columns import FloatColumn, IntColumn


def median_time_step_s(t_s: np.ndarray) -> float:
    """Median positive spacing of ``t_s`` [s]; NaN if it cannot be measured."""
    if t_s.size >= 2:
        d = np.diff(t_s)
        d = d[np.isfinite(d) & (d > 0)]
        if d.size:
            return float(np.median(d))
    return float("nan")


@dataclass(frozen=True)
class RunContext:
    """A record with its derived time base and ego geometry (see the module doc)."""

    record: RunRecord
    t_s: FloatColumn
    period_s: float
    sample_period_s: float
    durations_s: FloatColumn
    box_x_m: FloatColumn
    box_y_m: FloatColumn
    psi_rad: FloatColumn
    corners_m: np.ndarray
    vel_x_mps: FloatColumn
    vel_y_mps: FloatColumn

    @property
    def n(self) -> int:
        """Trace rows."""
        return int(self.t_s.shape[0])


def _durations_s(t_s: np.ndarray, period_s: float) -> FloatColumn:
    n = t_s.size
    if n == 0:
        return np.zeros(0)
    dt = np.full(n, period_s)
    if n >= 2 and np.all(np.isfinite(t_s)):
        dt[1:] = np.diff(t_s)
    fill = period_s if math.isfinite(period_s) else 0.0
    return np.where(np.isfinite(dt) & (dt > 0), dt, fill)


def build_context(record: RunRecord) -> RunContext:
    """The :class:`RunContext` of a record (any number of rows, including none)."""
    trace = record.trace
    ego = trace.ego
    t_s = np.asarray(trace.t_s, dtype=np.float64)
    median_dt = median_time_step_s(t_s)
    step = record.info.step_s
    period = float(step) if math.isfinite(step) and step > 0 else median_dt
    sample = median_dt if math.isfinite(median_dt) else period
    psi = ego.psi_rad
    cx, cy = ego_box_centres(ego.x_m, ego.y_m, psi, record.info.ego)
    corners = ego_box_corners(ego.x_m, ego.y_m, psi, record.info.ego)
    u = np.where(np.isfinite(ego.u_mps), ego.u_mps, ego.speed_mps)
    v = np.where(np.isfinite(ego.v_mps), ego.v_mps, 0.0)
    c, s = np.cos(psi), np.sin(psi)
    return RunContext(record=record, t_s=t_s, period_s=period, sample_period_s=sample,
                      durations_s=_durations_s(t_s, period), box_x_m=cx, box_y_m=cy,
                      psi_rad=psi, corners_m=corners, vel_x_mps=u * c - v * s,
                      vel_y_mps=u * s + v * c)


def neighbour_trace_rows(ctx: RunContext) -> IntColumn:
    """The trace row of every neighbour row, (len(neighbours),): the row whose step is
    the neighbour row's step, -1 where its step is no trace step. The one matching of
    the neighbours to the trace (collisions, time to collision)."""
    nb = ctx.record.neighbours
    rows = np.full(len(nb), -1, dtype=np.int64)
    if ctx.n == 0 or len(nb) == 0:
        return rows
    steps = ctx.record.trace.step
    order = np.argsort(steps, kind="stable")
    pos = np.clip(np.searchsorted(steps[order], nb.step), 0, len(order) - 1)
    matched = order[pos]
    ok = steps[matched] == nb.step
    rows[ok] = matched[ok]
    return rows
