"""Time to collision between oriented boxes moving at constant velocity.

At each step, for each recorded neighbour, both boxes are extrapolated at constant
velocity (ego: world velocity from u, v, ψ; neighbour: ``speed_mps`` along
``heading_rad``) with fixed headings. The relative motion is then a pure translation,
and the boxes touch at the first time τ at which their projections overlap on all
four separating axes (two edge normals of each box): an exact swept separating-axis
test, no sampling. TTC = τ (0 if they overlap now), +inf if they do not touch within
``TTC_HORIZON_S`` (10 s).

A pair counts only while the ego moves (speed ≥ ``TTC_MIN_EGO_SPEED_MPS`` = 0.5 m/s:
waiting behind a stopped car is no conflict). It counts *ahead* when the neighbour's
box centre is not behind the ego's (projection on the ego heading ≥ 0: conflicts the
ego drives into), else *behind* (being caught up by faster traffic).

A car replayed from a recording (``agent`` = replayed, not handed over) is blind to the
ego: it counts ahead only while its whole box lies ahead of the ego's front (the
rearmost corner's projection on the ego heading beyond the ego's foremost corner's).
Otherwise it counts behind: a recorded car that drives into the ego from behind or from
the side, or on through it, is nothing the ego's braking could prevent, and the
collision judgement classes such contacts ``replayed_into_ego`` (not at fault).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reports import geometry
from reports.geometry import box_corners
from reports.metrics.context import RunContext
from reports.record.columns import AGENT_REPLAYED, BoolColumn, FloatColumn, IntColumn

TTC_HORIZON_S = 10.0
TTC_MIN_EGO_SPEED_MPS = 0.5


def swept_box_ttc(corners_a: np.ndarray, vel_a: np.ndarray, corners_b: np.ndarray,
                  vel_b: np.ndarray, horizon_s: float = TTC_HORIZON_S) -> FloatColumn:
    """Time until boxes A and B first touch when translating at constant velocity [s].

    corners_*: (..., 4, 2) as from :func:`reports.geometry.box_corners`;
    vel_*: (..., 2) [m/s]. 0 if they overlap now, +inf if they never touch within
    ``horizon_s``. The compiled swept separating-axis test of
    :func:`reports.geometry.swept_box_ttc`, with this module's horizon.
    """
    out: FloatColumn = geometry.swept_box_ttc(corners_a, vel_a, corners_b, vel_b, horizon_s)
    return out


@dataclass(frozen=True)
class TtcPairs:
    """TTC of every (step, neighbour) row matched to a trace row, (P,) each: ``row``
    (trace row), ``ttc_s`` [s], ``ahead`` (neighbour centre not behind the ego's),
    ``ego_moving``."""

    row: IntColumn
    ttc_s: FloatColumn
    ahead: BoolColumn
    ego_moving: BoolColumn

    @classmethod
    def empty(cls) -> TtcPairs:
        return cls(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=bool),
                   np.zeros(0, dtype=bool))


def ttc_pairs(ctx: RunContext, horizon_s: float = TTC_HORIZON_S) -> TtcPairs:
    """TTC for every neighbour row whose ``step`` is a trace step (see the module doc)."""
    nb = ctx.record.neighbours
    if ctx.n == 0 or len(nb) == 0:
        return TtcPairs.empty()
    steps = ctx.record.trace.step
    order = np.argsort(steps, kind="stable")
    pos = np.clip(np.searchsorted(steps[order], nb.step), 0, len(order) - 1)
    rows = order[pos]
    valid = steps[rows] == nb.step
    if not np.any(valid):
        return TtcPairs.empty()
    rows = rows[valid]
    nbv = nb.take(valid)
    cx, cy, psi = ctx.box_x_m, ctx.box_y_m, ctx.psi_rad
    speed = np.hypot(ctx.vel_x_mps, ctx.vel_y_mps)
    nb_corners = box_corners(nbv.x_m, nbv.y_m, nbv.heading_rad, nbv.length_m, nbv.width_m)
    nb_vel = np.stack([nbv.speed_mps * np.cos(nbv.heading_rad),
                       nbv.speed_mps * np.sin(nbv.heading_rad)], axis=-1)
    ego_vel = np.stack([ctx.vel_x_mps[rows], ctx.vel_y_mps[rows]], axis=-1)
    ttc = swept_box_ttc(ctx.corners_m[rows], ego_vel, nb_corners, np.nan_to_num(nb_vel),
                        horizon_s)
    finite_pose = (np.isfinite(nbv.x_m) & np.isfinite(nbv.y_m) & np.isfinite(cx[rows])
                   & np.isfinite(cy[rows]))
    ttc = np.where(finite_pose, ttc, np.inf)
    hx, hy = np.cos(psi[rows]), np.sin(psi[rows])
    ahead = (nbv.x_m - cx[rows]) * hx + (nbv.y_m - cy[rows]) * hy >= 0.0
    replayed = nbv.agent == AGENT_REPLAYED
    if np.any(replayed):
        ahead = np.where(replayed, ahead & _wholly_ahead(ctx.corners_m[rows], nb_corners,
                                                         hx, hy), ahead)
    return TtcPairs(row=rows.astype(np.int64), ttc_s=ttc, ahead=ahead,
                    ego_moving=speed[rows] >= TTC_MIN_EGO_SPEED_MPS)


def _wholly_ahead(ego_corners: np.ndarray, nb_corners: np.ndarray, hx: FloatColumn,
                  hy: FloatColumn) -> BoolColumn:
    """(P,) whether the neighbour's box (P, 4, 2) lies wholly ahead of the ego's box
    (P, 4, 2) along the ego heading (hx, hy) (P,): its rearmost corner beyond the ego's
    foremost one."""
    ego_front = np.max(ego_corners[..., 0] * hx[:, None] + ego_corners[..., 1] * hy[:, None],
                       axis=1)
    nb_rear = np.min(nb_corners[..., 0] * hx[:, None] + nb_corners[..., 1] * hy[:, None],
                     axis=1)
    out: BoolColumn = nb_rear >= ego_front
    return out


def ttc_series(ctx: RunContext, pairs: TtcPairs, ahead: bool) -> FloatColumn:
    """Per trace row: min TTC [s] over the counted pairs ahead (or behind); +inf if none."""
    out = np.full(ctx.n, np.inf)
    if pairs.row.size:
        keep = pairs.ego_moving & (pairs.ahead if ahead else ~pairs.ahead)
        np.minimum.at(out, pairs.row[keep], pairs.ttc_s[keep])
    return out
