"""Drivable area: how far the ego box is outside the road it may use, and shoulder use.

The drivable area is a union of convex pieces built from the road record's lanes (the
route's lanes and their internal junction lanes, netconvert's shapes and widths):

* **lane strips**: for each segment a-b of a lane's centreline, the rectangle
  a-b ± n·w/2 (n the segment's left unit normal, w the lane width [m]); at each inner
  vertex, on the outer side of the turn, the kite between the two rectangles' corners
  and the miter point v ± n̄·(w/2)/(1 + n_1·n_2) (n̄ = n_1 + n_2; a bevel triangle for
  turns of 90° or more), so that a lane is the polygon SUMO draws: its centreline
  offset by ±w/2, flat at its ends (no cap beyond a lane's end);
* **junction wedges**: between consecutive route edges k and k+1, the quadrilateral
  from edge k's end cross-section (the right end corner of its rightmost drivable lane
  to the left end corner of its leftmost) to edge k+1's start cross-section, split
  into two triangles on its diagonal. It holds the wedge where a lane ends beside
  another (a lane drop or the end of a taper: from the ending lane's outer end corner
  to the continuing lanes' outer boundary where the next edge starts), where a lane
  begins beside another (an acceleration lane), and the straight bridge the
  reference takes where netconvert shifts the continuing lanes through S-shaped
  internal lanes. On a junction of length L on a curve of radius R it reaches
  L²/(8R) inside the curve beyond the internal lanes (2 cm for 8 m on R 400 m).

Lanes count when passenger cars may use them (:meth:`reports.record.LaneRecord.drivable`);
shoulder lanes only when the scenario allows the shoulder (``info.allow_shoulder``).

A point's *excess* is its distance to the union outside it and minus its depth inside
(:func:`reports.geometry.polygons_excess`). A box corner is *off the drivable
area* when its excess is more than ``OFFROAD_TOLERANCE_M`` (0.3 m).

Metrics: ``offroad_s`` [s] time with any corner off, ``offroad_m`` [m] distance driven
meanwhile, ``max_offroad_m`` [m] the largest corner excess (0 when always inside),
``shoulder_s`` [s] time with the box centre inside a shoulder lane and not inside a
regular drivable lane. All NaN without trace rows or without lanes. ``offroad_s`` (when
some corner was off) and ``max_offroad_m`` (when some corner was outside at all) carry
the boundary crossed farthest (:class:`reports.record.verdict.BoundaryCrossing`): the
nearest edge of the nearest piece to the farthest corner at the row of the largest
excess.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from reports.geometry import polygons_excess
from reports.metrics.context import RunContext
from reports.metrics.values import Measured, extreme, measured
from reports.record import LaneRecord, MetricValue, RoadRecord
from reports.record.columns import BoolColumn, FloatColumn
from reports.record.verdict import CORNERS, CROSSING_KINDS, CROSSING_SIDES, BoundaryCrossing

OFFROAD_TOLERANCE_M = 0.3
RIGHT, LEFT, END, START = (CROSSING_SIDES.index(s) for s in ("right", "left", "end", "start"))
_MIN_SEGMENT_M = 1e-6  # shorter centreline segments are repeated points


@dataclass(frozen=True)
class AreaOwner:
    """What a piece of the drivable area belongs to: a lane (``kind`` 'lane', its id and
    edge) or the junction between route edges ``edge_id`` and ``to_edge_id`` ('junction')."""

    kind: str
    lane_id: str
    edge_id: str
    to_edge_id: str = ""

    def __post_init__(self) -> None:
        if self.kind not in CROSSING_KINDS:
            raise ValueError(f"AreaOwner.kind must be one of {CROSSING_KINDS}, got {self.kind!r}")


@dataclass(frozen=True)
class DrivableArea:
    """The drivable area as K convex pieces (module doc).

    polygons_xy_m: (K, 4, 2) [m] counter-clockwise (a triangle repeats its last vertex);
    owner: (K,) index into ``owners``; side: (K, 4) the side code (index into
    :data:`reports.record.verdict.CROSSING_SIDES`) of edge j (vertex j to j + 1).
    """

    polygons_xy_m: np.ndarray
    owner: np.ndarray
    side: np.ndarray
    owners: tuple[AreaOwner, ...]

    def __post_init__(self) -> None:
        k = self.polygons_xy_m.shape[0]
        if self.polygons_xy_m.shape != (k, 4, 2):
            raise ValueError(f"polygons_xy_m must be (K, 4, 2), got {self.polygons_xy_m.shape}")
        if self.owner.shape != (k,) or self.side.shape != (k, 4):
            raise ValueError(f"owner must be ({k},) and side ({k}, 4), got "
                             f"{self.owner.shape} and {self.side.shape}")

    @property
    def empty(self) -> bool:
        return int(self.polygons_xy_m.shape[0]) == 0

    def excess(self, points_xy_m: np.ndarray) -> tuple[FloatColumn, np.ndarray, np.ndarray]:
        """(excess (P,) [m], piece (P,), edge (P,)) of points (P, 2): see
        :func:`reports.geometry.polygons_excess` (+inf, -1, -1 without pieces)."""
        pts = np.asarray(points_xy_m, dtype=np.float64).reshape(-1, 2)
        if self.empty:
            n = pts.shape[0]
            return np.full(n, np.inf), np.full(n, -1), np.full(n, -1)
        return polygons_excess(pts, self.polygons_xy_m)


class _Pieces:
    """Accumulates pieces and their owners while the area is built."""

    def __init__(self) -> None:
        self.polygons: list[np.ndarray] = []
        self.owner: list[np.ndarray] = []
        self.side: list[np.ndarray] = []
        self.owners: list[AreaOwner] = []

    def add(self, owner: AreaOwner, polygons: np.ndarray, sides: np.ndarray) -> None:
        """Pieces (N, 4, 2) with their edge sides (N, 4), made counter-clockwise."""
        if polygons.shape[0] == 0:
            return
        polygons, sides = _counter_clockwise(polygons, sides)
        self.polygons.append(polygons)
        self.side.append(sides)
        self.owner.append(np.full(polygons.shape[0], len(self.owners)))
        self.owners.append(owner)

    def area(self) -> DrivableArea:
        if not self.polygons:
            return DrivableArea(np.zeros((0, 4, 2)), np.zeros(0, dtype=np.int64),
                                np.zeros((0, 4), dtype=np.int64), ())
        return DrivableArea(np.concatenate(self.polygons), np.concatenate(self.owner),
                            np.concatenate(self.side), tuple(self.owners))


def _counter_clockwise(polygons: np.ndarray, sides: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Reverse the clockwise pieces (vertex order and edge sides: edge j of the reversed
    polygon is edge 2 - j mod 4 of the original) and drop those of no area."""
    x, y = polygons[..., 0], polygons[..., 1]
    area2 = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    cw = area2 < 0
    polygons = polygons.copy()
    sides = sides.copy()
    polygons[cw] = polygons[cw][:, ::-1]
    sides[cw] = sides[cw][:, [2, 1, 0, 3]]
    keep = np.abs(area2) > 1e-12
    return polygons[keep], sides[keep]


def _centreline(lane: LaneRecord) -> np.ndarray:
    """The lane's centreline (M, 2) without repeated points."""
    shape = np.asarray(lane.shape_xy_m, dtype=np.float64).reshape(-1, 2)
    if shape.shape[0] < 2:
        return shape
    seg = np.hypot(*np.diff(shape, axis=0).T)
    return np.concatenate([shape[:1], shape[1:][seg > _MIN_SEGMENT_M]])


def _normals(shape: np.ndarray) -> np.ndarray:
    """Left unit normals (M - 1, 2) of the segments of a polyline (M, 2)."""
    d = np.diff(shape, axis=0)
    d = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    return np.stack([-d[:, 1], d[:, 0]], axis=1)


def lane_pieces(shape_xy_m: np.ndarray, width_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The strip of a centreline (M, 2) and width [m] (module doc): pieces (N, 4, 2) and
    their edge sides (N, 4), not yet oriented."""
    shape = np.asarray(shape_xy_m, dtype=np.float64).reshape(-1, 2)
    if shape.shape[0] < 2:
        return np.zeros((0, 4, 2)), np.zeros((0, 4), dtype=np.int64)
    h = 0.5 * float(width_m)
    n = _normals(shape)
    a, b = shape[:-1], shape[1:]
    rects = np.stack([a - h * n, b - h * n, b + h * n, a + h * n], axis=1)
    s = len(a)
    rect_sides = np.tile(np.array([RIGHT, END, LEFT, START]), (s, 1))
    if s < 2:
        return rects, rect_sides
    n1, n2 = n[:-1], n[1:]
    v = shape[1:-1]
    turn = n1[:, 0] * n2[:, 1] - n1[:, 1] * n2[:, 0]  # > 0: turning left
    cos = np.sum(n1 * n2, axis=1)
    bend = np.abs(turn) > 1e-9
    outer = np.where(turn > 0, -1.0, 1.0)[:, None]  # the right side is outside a left turn
    p1 = v + outer * h * n1
    p2 = v + outer * h * n2
    miter = v + outer * h * (n1 + n2) / np.maximum(1.0 + cos, 1e-9)[:, None]
    tip = np.where((cos > 0)[:, None], miter, p2)  # a bevel (triangle) at 90 degrees or more
    joins = np.stack([v, p1, tip, p2], axis=1)[bend]
    join_side = np.where(turn[bend] > 0, RIGHT, LEFT)
    joins_sides = np.repeat(join_side[:, None], 4, axis=1)
    return np.concatenate([rects, joins]), np.concatenate([rect_sides, joins_sides])


def _cross_section(lane: LaneRecord, at_end: bool) -> tuple[np.ndarray, np.ndarray]:
    """(right corner, left corner) [m] of a lane's end (or start) cross-section."""
    shape = _centreline(lane)
    n = _normals(shape[-2:] if at_end else shape[:2])[0]
    p = shape[-1] if at_end else shape[0]
    h = 0.5 * lane.width_m
    return p - h * n, p + h * n


def junction_pieces(ending: Sequence[LaneRecord], starting: Sequence[LaneRecord]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The junction wedge (module doc) between the lanes of one edge and those of the
    next: two triangles (2, 4, 2) (each repeats its last vertex) and their sides."""
    if not ending or not starting:
        return np.zeros((0, 4, 2)), np.zeros((0, 4), dtype=np.int64)
    in_right, _ = _cross_section(min(ending, key=lambda ln: ln.index), at_end=True)
    _, in_left = _cross_section(max(ending, key=lambda ln: ln.index), at_end=True)
    out_right, _ = _cross_section(min(starting, key=lambda ln: ln.index), at_end=False)
    _, out_left = _cross_section(max(starting, key=lambda ln: ln.index), at_end=False)
    # the right half (right edge, the next edge's start, the diagonal on its left) and the
    # left half (the diagonal on its right, the left edge, the first edge's end)
    polys = np.array([[in_right, out_right, out_left, out_left],
                      [in_right, out_left, in_left, in_left]])
    sides = np.array([[RIGHT, START, LEFT, LEFT], [RIGHT, LEFT, END, END]])
    return polys, sides


def _usable(lane: LaneRecord) -> bool:
    return _centreline(lane).shape[0] >= 2 and lane.width_m > 0


def drivable_area(road: RoadRecord, lanes: Sequence[LaneRecord]) -> DrivableArea:
    """The drivable area (module doc) of ``lanes`` (lanes of ``road``), with the junction
    wedges between consecutive ``road.route`` edges built from the non-internal ones."""
    pieces = _Pieces()
    usable = [ln for ln in lanes if _usable(ln)]
    for lane in usable:
        polys, sides = lane_pieces(_centreline(lane), lane.width_m)
        pieces.add(AreaOwner("lane", lane.id, lane.edge_id), polys, sides)
    by_edge: dict[str, list[LaneRecord]] = {}
    for lane in usable:
        if not lane.internal:
            by_edge.setdefault(lane.edge_id, []).append(lane)
    for here, there in zip(road.route, road.route[1:], strict=False):
        polys, sides = junction_pieces(by_edge.get(here, []), by_edge.get(there, []))
        pieces.add(AreaOwner("junction", "", here, there), polys, sides)
    return pieces.area()


def road_lanes(ctx: RunContext) -> list[LaneRecord]:
    """Lanes with a centreline and a width."""
    return [ln for ln in ctx.record.road.lanes if ln.shape_xy_m.shape[0] > 0 and ln.width_m > 0]


# the last area built, with the road record and the shoulder flag it was built for: the
# series and the metrics of one run ask for the same area twice
_LAST_AREA: list[tuple[RoadRecord, bool, DrivableArea]] = []


def ego_drivable_area(ctx: RunContext) -> DrivableArea:
    """The area the ego may use in this run (shoulders only where allowed)."""
    allow = ctx.record.info.allow_shoulder
    road = ctx.record.road
    if _LAST_AREA and _LAST_AREA[0][0] is road and _LAST_AREA[0][1] == allow:
        return _LAST_AREA[0][2]
    area = drivable_area(road, [ln for ln in road_lanes(ctx) if ln.drivable(allow)])
    _LAST_AREA[:] = [(road, allow, area)]
    return area


def offroad_excess_series(ctx: RunContext) -> FloatColumn:
    """Per trace row: the largest ego-corner excess beyond the drivable area [m] (NaN
    without lanes or pose)."""
    n = ctx.n
    area = ego_drivable_area(ctx)
    if n == 0 or area.empty:
        return np.full(n, np.nan)
    excess, _, _ = area.excess(ctx.corners_m.reshape(-1, 2))
    out: FloatColumn = excess.reshape(n, 4).max(axis=1)
    out[~np.all(np.isfinite(ctx.corners_m.reshape(n, 8)), axis=1)] = np.nan
    return out


def boundary_crossing(ctx: RunContext, area: DrivableArea, row: int) -> BoundaryCrossing | None:
    """The boundary nearest to the farthest corner of row ``row`` (None when every corner
    is inside or the row has no pose)."""
    corners = ctx.corners_m[row].reshape(4, 2)
    excess, piece, edge = area.excess(corners)
    if not np.any(np.isfinite(excess)):
        return None
    worst = int(np.argmax(np.where(np.isfinite(excess), excess, -np.inf)))
    if not excess[worst] > 0.0 or piece[worst] < 0:
        return None
    owner = area.owners[int(area.owner[piece[worst]])]
    t = float(ctx.t_s[row])
    return BoundaryCrossing(kind=owner.kind, lane_id=owner.lane_id, edge_id=owner.edge_id,
                            to_edge_id=owner.to_edge_id,
                            side=CROSSING_SIDES[int(area.side[piece[worst], edge[worst]])],
                            excess_m=float(excess[worst]), step=row,
                            t_s=t if math.isfinite(t) else float("nan"), corner=CORNERS[worst])


def offroad_steps(excess_m: np.ndarray) -> BoolColumn:
    """Per trace row: some corner is more than the tolerance outside the drivable area."""
    flags: BoolColumn = np.nan_to_num(excess_m, nan=-np.inf) > OFFROAD_TOLERANCE_M
    return flags


def shoulder_steps(ctx: RunContext) -> BoolColumn:
    """Per trace row: box centre inside a shoulder lane and not inside a regular lane
    (lane strips with the junction wedges of the regular lanes)."""
    n = ctx.n
    lanes = road_lanes(ctx)
    shoulders = [ln for ln in lanes if ln.is_shoulder]
    if n == 0 or not shoulders:
        return np.zeros(n, dtype=bool)
    regular = [ln for ln in lanes if not ln.is_shoulder and ln.drivable(False)]
    pts = np.stack([ctx.box_x_m, ctx.box_y_m], axis=-1)
    on_sh = drivable_area(RoadRecord(), shoulders).excess(pts)[0] <= 0.0
    on_reg = drivable_area(ctx.record.road, regular).excess(pts)[0] <= 0.0
    out: BoolColumn = on_sh & ~on_reg
    return out


def _with_crossing(m: Measured, crossing: BoundaryCrossing | None) -> Measured:
    metric = m.metric
    return Measured(MetricValue(name=metric.name, value=metric.value, unit=metric.unit,
                                kind=metric.kind, better=metric.better,
                                worst_step=metric.worst_step, series=metric.series,
                                crossing=crossing), m.increments)


def drivable_metrics(ctx: RunContext, excess_m: FloatColumn) -> list[Measured]:
    """offroad_s, offroad_m, max_offroad_m, shoulder_s (see the module doc);
    ``excess_m`` is :func:`offroad_excess_series`."""
    if ctx.n == 0 or not road_lanes(ctx):
        nan = float("nan")
        return [measured(name, nan) for name in ("offroad_s", "offroad_m", "max_offroad_m",
                                                 "shoulder_s")]
    bad = offroad_steps(excess_m)
    dt = ctx.durations_s
    speed = np.nan_to_num(ctx.record.trace.ego.speed_mps)
    peak, row = extreme(excess_m, "max")
    crossing = (boundary_crossing(ctx, ego_drivable_area(ctx), row)
                if row is not None and peak > 0 else None)
    shoulder = shoulder_steps(ctx)
    offroad_s = measured("offroad_s", float(np.sum(dt[bad])), increments=np.where(bad, dt, 0.0))
    # clamped at 0: inside the lanes the whole run has no worst corner to point at
    max_offroad = measured("max_offroad_m", max(0.0, peak) if row is not None else float("inf"),
                           worst_step=row if peak > 0 else None)
    return [
        _with_crossing(offroad_s, crossing if bool(np.any(bad)) else None),
        measured("offroad_m", float(np.sum((speed * dt)[bad]))),
        _with_crossing(max_offroad, crossing),
        measured("shoulder_s", float(np.sum(dt[shoulder])),
                 increments=np.where(shoulder, dt, 0.0)),
    ]
