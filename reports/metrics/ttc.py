"""Time to collision between oriented boxes predicted along the road.

The prediction
--------------
At each step, for each recorded neighbour, the ego box and the neighbour's box are
predicted *along the road*: both are expressed in the Frenet frame of the run's
reference path (``road.reference_xy_m``, :func:`reports.geometry.polyline_frenet`) and
held at constant Frenet velocity with fixed headings relative to the path. For a box
with centre (x, y), heading ψ and world velocity (v_x, v_y), whose centre's foot on the
path has arc length s, signed offset d (left +), tangent angle γ and curvature κ:

* centre (s, d); heading relative to the path θ = ψ − γ;
* velocity (ds/dt, dd/dt) = (v_t / (1 − κ d), v_n), (v_t, v_n) the world velocity in
  the tangent frame (ego: from u, v, ψ; neighbour: ``speed_mps`` along its heading, so
  v_t = v cos θ, v_n = v sin θ);
* corners: the box's corners at heading θ about (s, d), their along-path offsets
  stretched by 1 / (1 − κ d) (a length ℓ along the tangent at offset d spans
  ℓ / (1 − κ d) of s), a parallelogram.

In (s, d) the relative motion is a translation, and the boxes first touch at the first
time τ at which their projections overlap on all four separating axes (two edge
normals of each parallelogram): the same exact swept separating-axis test as before
(:func:`reports.geometry.swept_box_ttc`), no sampling. TTC = τ (0 if they overlap
now), +inf if they do not touch within ``TtcParams.horizon_s`` (10 s). So two cars
following one lane round a bend at equal speeds keep their distance (no TTC), and a
faster car behind a slower one reaches it after gap / closing speed, the gap measured
along the lane. On a straight reference the frame is a rigid motion of the plane, so
the answer is the straight-line one (to rounding).

Why along the road: highway traffic follows its lanes. Extrapolating both boxes in
straight lines at constant velocity (the model before) lets each car leave its lane
tangentially on a bend: on R = 300 m, passing a car 14 m ahead in the next lane at
30 against 22 m/s gave a TTC of 1.37 s, and a stalled car ahead in the ego's lane
round a bend none. Constant yaw rate with sampled overlap was the alternative; it
needs every neighbour's yaw rate (differences of SUMO's lane-segment headings, which
step at every vertex) and gives up the exact swept test. The Frenet frame needs
nothing but what is recorded, keeps the exact test, and reduces to the old answer
where the road is straight. It does not model a car that leaves the reference's
direction along its own lane (an on-ramp bending into the carriageway): that car is
held at its heading relative to the reference, as the straight lines held it in the
world.

The ego's foot is tracked along the trace (each row searched near the previous row's
s), and each neighbour's is searched near the ego's along the path (within π/2 times
their distance plus twice ``max_offset_m``, plus ``track_margin_m``: that holds every
foot within that offset for arcs up to a half circle), so a road passing near itself
cannot swap a box onto another part of it. The ego's recorded ``s_m`` is not used: it
is the CG's on the controller's own smoothing of the reference, the boxes need their
centres' feet on one polyline.

Fallback: a pair is predicted in straight lines at constant velocity in the world
frame, as before, where either box cannot be placed on the road: no reference (fewer
than two distinct points), its centre farther than ``max_offset_m`` (20 m, about five
lanes: beyond the carriageway the reference is not that car's road, e.g. a parallel
ramp or the opposite carriageway) from the path, or 1 − κ d < ``min_metric`` (0.5: the
frame folds at d = 1/κ). Beyond the ends of the reference the path continues straight
along its end tangent (s < 0 or s > length), the same assumption as the straight-line
model, without a jump where a car crosses an end.

Which pairs count
-----------------
A pair counts only while the ego moves (speed ≥ ``min_ego_speed_mps`` = 0.5 m/s:
waiting behind a stopped car is no conflict). It counts *ahead* when the neighbour's
box centre is not behind the ego's (projection on the ego heading ≥ 0, in the frame
the pair is predicted in: along the road, or the world: conflicts the ego drives
into), else *behind* (being caught up by faster traffic).

A car replayed from a recording (``agent`` = replayed, not handed over) is blind to the
ego: it counts ahead only while its whole box lies ahead of the ego's front (the
rearmost corner's projection on the ego heading beyond the ego's foremost corner's,
in the pair's frame). Otherwise it counts behind: a recorded car that drives into the
ego from behind or from the side, or on through it, is nothing the ego's braking could
prevent, and the collision judgement classes such contacts ``replayed_into_ego`` (not
at fault).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports import geometry
from reports.geometry import PathFrame, box_corners, polyline_frenet
from reports.metrics.context import RunContext, neighbour_trace_rows
from reports.record.columns import AGENT_REPLAYED, BoolColumn, FloatColumn, IntColumn


@dataclass(frozen=True)
class TtcParams:
    """horizon_s [s]: TTCs beyond it are +inf; min_ego_speed_mps [m/s]: pairs count while
    the ego is at least this fast; max_offset_m [m] and min_metric [-]: a box is placed
    on the road while its centre is within max_offset_m of the reference and
    1 − κ d ≥ min_metric there (else its pairs are predicted in straight lines);
    track_margin_m [m]: the ego's foot is searched within this, plus twice the distance
    moved, of the previous row's."""

    horizon_s: float = 10.0
    min_ego_speed_mps: float = 0.5
    max_offset_m: float = 20.0
    min_metric: float = 0.5
    track_margin_m: float = 10.0


DEFAULT_TTC = TtcParams()
TTC_HORIZON_S = DEFAULT_TTC.horizon_s
TTC_MIN_EGO_SPEED_MPS = DEFAULT_TTC.min_ego_speed_mps


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
    ``ego_moving``, ``on_road`` (predicted along the road; False: in straight lines).

    The same pair seen along the ego's heading h in the frame it is predicted in
    (:func:`pair_geometry`): ``gap_m`` [m], the neighbour's rearmost corner minus the
    ego's foremost corner along h (bumper to bumper; <= 0 once they overlap along h),
    ``closing_mps`` [m/s], (v_ego − v_neighbour)·h (> 0: the ego closes in), and
    ``in_path``, whether the boxes overlap across h (the neighbour is in the ego's
    path). On the road both are converted from arc length to metres at the ego's
    offset (times 1 − κ d of the ego's centre)."""

    row: IntColumn
    ttc_s: FloatColumn
    ahead: BoolColumn
    ego_moving: BoolColumn
    on_road: BoolColumn
    gap_m: FloatColumn
    closing_mps: FloatColumn
    in_path: BoolColumn

    @classmethod
    def empty(cls) -> TtcPairs:
        none = np.zeros(0, dtype=bool)
        return cls(np.zeros(0, dtype=np.int64), np.zeros(0), none, none, none, np.zeros(0),
                   np.zeros(0), none)


@dataclass(frozen=True)
class Boxes:
    """P boxes moving at constant velocity in one plane frame, each field (P,): centre
    ``cx``, ``cy`` [m], heading [rad] in that frame, length and width [m], velocity
    ``vx``, ``vy`` [m/s], and ``stretch`` [-], the factor on the corners' offsets from the
    centre along the frame's first axis (1 in the world frame, 1 / (1 − κ d) on the
    road)."""

    cx: FloatColumn
    cy: FloatColumn
    heading: FloatColumn
    length: FloatColumn
    width: FloatColumn
    vx: FloatColumn
    vy: FloatColumn
    stretch: FloatColumn

    def corners(self) -> np.ndarray:
        """(P, 4, 2) [m] in the order of :func:`reports.geometry.box_corners`."""
        c = box_corners(self.cx, self.cy, self.heading, self.length, self.width)
        stretched = self.cx[:, None] + (c[..., 0] - self.cx[:, None]) * self.stretch[:, None]
        # unstretched corners stay bit for bit those of box_corners (the world frame)
        c[..., 0] = np.where(self.stretch[:, None] == 1.0, c[..., 0], stretched)
        return c

    def velocity(self) -> np.ndarray:
        """(P, 2) [m/s]."""
        return np.stack([self.vx, self.vy], axis=-1)

    def where(self, mask: BoolColumn, other: Boxes) -> Boxes:
        """This box where ``mask``, else ``other``'s, field by field."""
        return Boxes(*(np.where(mask, getattr(self, f), getattr(other, f))
                       for f in Boxes.__dataclass_fields__))


def on_road(boxes: Boxes, frame: PathFrame, params: TtcParams = DEFAULT_TTC
            ) -> tuple[Boxes, BoolColumn]:
    """The world-frame ``boxes`` in the Frenet frame of the reference, given their centres'
    feet ``frame``, (s, d) for (x, y) (the module doc), and where that is valid (finite,
    within ``max_offset_m``, 1 − κ d ≥ ``min_metric``)."""
    metric = 1.0 - frame.curvature_1pm * frame.d_m
    valid = (np.isfinite(frame.s_m) & np.isfinite(metric)
             & (np.abs(frame.d_m) <= params.max_offset_m) & (metric >= params.min_metric))
    metric = np.where(valid, metric, 1.0)
    c, s = np.cos(frame.tangent_rad), np.sin(frame.tangent_rad)
    along = boxes.vx * c + boxes.vy * s
    across = -boxes.vx * s + boxes.vy * c
    road = Boxes(cx=frame.s_m, cy=frame.d_m, heading=boxes.heading - frame.tangent_rad,
                 length=boxes.length, width=boxes.width, vx=along / metric, vy=across,
                 stretch=1.0 / metric)
    return road, valid


def _matched_rows(ctx: RunContext) -> tuple[IntColumn, BoolColumn] | None:
    """(trace row of each neighbour row whose step is a trace step, which neighbour rows
    those are); None if there is none."""
    rows = neighbour_trace_rows(ctx)
    valid = rows >= 0
    if not np.any(valid):
        return None
    return rows[valid], valid


def _world_boxes(ctx: RunContext, rows: IntColumn, valid: BoolColumn) -> tuple[Boxes, Boxes]:
    """(ego boxes at ``rows``, the matched neighbours' boxes) in the world frame."""
    nbv = ctx.record.neighbours.take(valid)
    ego = ctx.record.info.ego
    p = rows.size
    ones = np.ones(p)
    ego_boxes = Boxes(ctx.box_x_m[rows], ctx.box_y_m[rows], ctx.psi_rad[rows],
                      np.full(p, ego.length_m), np.full(p, ego.width_m), ctx.vel_x_mps[rows],
                      ctx.vel_y_mps[rows], ones)
    speed = np.nan_to_num(nbv.speed_mps)  # a neighbour without a speed stands still
    heading = np.asarray(nbv.heading_rad, dtype=np.float64)
    nb_boxes = Boxes(np.asarray(nbv.x_m, dtype=np.float64), np.asarray(nbv.y_m, np.float64),
                     heading, np.asarray(nbv.length_m, np.float64),
                     np.asarray(nbv.width_m, np.float64),
                     np.nan_to_num(speed * np.cos(heading)),
                     np.nan_to_num(speed * np.sin(heading)), ones)
    return ego_boxes, nb_boxes


def _road_frames(ctx: RunContext, rows: IntColumn, nb: Boxes, params: TtcParams
                 ) -> tuple[PathFrame, PathFrame]:
    """Feet on the reference of the ego's box centre at ``rows`` (tracked along the whole
    trace) and of the neighbours' centres (near the ego's foot: the module doc)."""
    ref = ctx.record.road.reference_xy_m
    ego = polyline_frenet(ref, ctx.box_x_m, ctx.box_y_m, window_m=np.full(
        ctx.n, params.track_margin_m), track=True)
    ego_rows = PathFrame(ego.s_m[rows], ego.d_m[rows], ego.tangent_rad[rows],
                         ego.curvature_1pm[rows])
    reach = np.hypot(nb.cx - ctx.box_x_m[rows], nb.cy - ctx.box_y_m[rows])
    window = 0.5 * math.pi * (reach + 2.0 * params.max_offset_m) + params.track_margin_m
    # where the ego has no foot, its pairs are predicted in straight lines: skip the search
    skip = ~np.isfinite(ego_rows.s_m)
    nb_frame = polyline_frenet(ref, np.where(skip, np.nan, nb.cx), nb.cy, ego_rows.s_m, window)
    return ego_rows, nb_frame


def ttc_pairs(ctx: RunContext, params: TtcParams = DEFAULT_TTC) -> TtcPairs:
    """TTC for every neighbour row whose ``step`` is a trace step (see the module doc)."""
    matched = _matched_rows(ctx)
    if matched is None:
        return TtcPairs.empty()
    rows, valid = matched
    ego_w, nb_w = _world_boxes(ctx, rows, valid)
    ego_frame, nb_frame = _road_frames(ctx, rows, nb_w, params)
    ego_r, ego_ok = on_road(ego_w, ego_frame, params)
    nb_r, nb_ok = on_road(nb_w, nb_frame, params)
    road = ego_ok & nb_ok
    ego_b, nb_b = ego_r.where(road, ego_w), nb_r.where(road, nb_w)
    ego_c, nb_c = ego_b.corners(), nb_b.corners()
    ttc = swept_box_ttc(ego_c, ego_b.velocity(), nb_c, nb_b.velocity(), params.horizon_s)
    finite_pose = (np.isfinite(nb_w.cx) & np.isfinite(nb_w.cy) & np.isfinite(ego_w.cx)
                   & np.isfinite(ego_w.cy))
    ttc = np.where(finite_pose, ttc, np.inf)
    hx, hy = np.cos(ego_b.heading), np.sin(ego_b.heading)
    ahead = (nb_b.cx - ego_b.cx) * hx + (nb_b.cy - ego_b.cy) * hy >= 0.0
    replayed = ctx.record.neighbours.agent[valid] == AGENT_REPLAYED
    if np.any(replayed):
        ahead = np.where(replayed, ahead & _wholly_ahead(ego_c, nb_c, hx, hy), ahead)
    speed = np.hypot(ctx.vel_x_mps[rows], ctx.vel_y_mps[rows])
    gap, closing, in_path = pair_geometry(ego_b, nb_b, ego_c, nb_c)
    return TtcPairs(row=rows, ttc_s=ttc, ahead=ahead,
                    ego_moving=speed >= params.min_ego_speed_mps, on_road=road,
                    gap_m=np.where(finite_pose, gap, np.nan), closing_mps=closing,
                    in_path=in_path & finite_pose)


def pair_geometry(ego: Boxes, nb: Boxes, ego_corners: np.ndarray, nb_corners: np.ndarray
                  ) -> tuple[FloatColumn, FloatColumn, BoolColumn]:
    """(gap_m, closing_mps, in_path) of P pairs in one frame (see :class:`TtcPairs`):
    with h = (cos ψ_ego, sin ψ_ego) and n = (−sin ψ_ego, cos ψ_ego) in that frame,
    gap = min(nb corners · h) − max(ego corners · h), closing = (v_ego − v_nb) · h,
    in_path = the intervals of the corners · n overlap; gap and closing divided by the
    ego's stretch (1 in the world frame, 1 / (1 − κ d) on the road)."""
    hx, hy = np.cos(ego.heading), np.sin(ego.heading)

    def along(c: np.ndarray, ux: FloatColumn, uy: FloatColumn) -> np.ndarray:
        out: np.ndarray = c[..., 0] * ux[:, None] + c[..., 1] * uy[:, None]
        return out

    gap = np.min(along(nb_corners, hx, hy), axis=1) - np.max(along(ego_corners, hx, hy), axis=1)
    closing = (ego.vx - nb.vx) * hx + (ego.vy - nb.vy) * hy
    ego_n, nb_n = along(ego_corners, -hy, hx), along(nb_corners, -hy, hx)
    in_path: BoolColumn = (np.min(nb_n, axis=1) < np.max(ego_n, axis=1)) \
        & (np.min(ego_n, axis=1) < np.max(nb_n, axis=1))
    return gap / ego.stretch, closing / ego.stretch, in_path


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
