"""The lanelet network as rows: side-by-side same-direction lanelets, right to left.

Steps:

1. The ego's lanelet: the one whose centre line passes within half its width of the
   planning problem's initial position, heading within 90 deg of the ego's.
2. The ego's road: every lanelet connected to it by successor, predecessor or
   same-direction adjacency (the opposite carriageway and unconnected roads are dropped,
   with a note; dangling references are dropped, with a note).
3. Connectors (:mod:`~suite.importers.commonroad.connectors`): wedges and short skewed
   lanelets that join lanes without being one become junction links from their
   predecessors to their successors (a note lists them).
4. Cuts (:mod:`~suite.importers.commonroad.split`): a lanelet beside two or more
   consecutive lanelets, or whose neighbour row is split elsewhere, is cut where its
   neighbours start and end, so that side-by-side lanelets cover the same stretch; the
   pieces are ``<id>``, ``<id>_1``, ... The ego's lanelet is then the piece it is on.
5. Rows: from each lanelet with no same-direction right neighbour, walk left along
   ``adjacentLeft``; every lanelet of the road must be in exactly one row (adjacency
   that disagrees between the two neighbours, a cycle, a lanelet in two rows, a row
   whose lanelets point in opposite directions, a successor in its own row, and a
   centre line shorter than :data:`MIN_LANELET_LENGTH_M` are errors naming the lanelet).

Lane 0 of a row is its rightmost lanelet (SUMO's convention).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from suite.importers.commonroad.connectors import bridge_connectors
from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import angle_diff_rad, polyline_length_m, project
from suite.importers.commonroad.records import EgoStart, LaneletRecord, RecordedFile
from suite.importers.commonroad.split import split_road

__all__ = ["MIN_LANELET_LENGTH_M", "LaneRow", "RoadRows", "build_road"]

MIN_LANELET_LENGTH_M = 0.1
"""A lanelet whose centre line is shorter than this [m] cannot become a lane."""


@dataclass(frozen=True, eq=False)
class LaneRow:
    """One future SUMO edge: ``lanelets`` right (lane 0) to left."""

    lanelets: tuple[LaneletRecord, ...]

    @property
    def row_id(self) -> int:
        return self.lanelets[0].lanelet_id

    @property
    def label(self) -> str:
        """The rightmost lanelet's label (``<id>`` or ``<id>_<piece>``): the edge is
        ``L<label>``."""
        return self.lanelets[0].label

    @property
    def types(self) -> tuple[str, ...]:
        return tuple(sorted({t for ll in self.lanelets for t in ll.types}))


@dataclass(frozen=True)
class RoadRows:
    """The ego's road: its rows, where each lanelet is (row index, lane index), the
    ego's lanelet, the lanelets dropped (not on the ego's road), notes, and each file
    lanelet's pieces (file id -> internal ids, one when it was not cut)."""

    rows: tuple[LaneRow, ...]
    place: dict[int, tuple[int, int]]
    ego_lanelet: int
    dropped_lanelets: int
    notes: tuple[str, ...]
    pieces: dict[int, tuple[int, ...]] = field(default_factory=dict)

    def places_of(self, file_id: int) -> list[tuple[int, int]]:
        """(row, lane) of every piece of the file's lanelet ``file_id`` on the road."""
        return [self.place[p] for p in self.pieces.get(file_id, (file_id,))
                if p in self.place]

    def lanelet(self, lanelet_id: int) -> LaneletRecord:
        r, i = self.place[lanelet_id]
        return self.rows[r].lanelets[i]


def _ego_lanelet(path: str, lanelets: dict[int, LaneletRecord], ego: EgoStart) -> int:
    best: tuple[float, int] | None = None
    for lid, ll in sorted(lanelets.items()):
        pr = project(ll.centre_xy_m, ego.x_m, ego.y_m)
        if angle_diff_rad(pr.heading_rad, ego.heading_rad) > 0.5 * math.pi:
            continue
        excess = pr.distance_m - 0.5 * ll.width_m
        if best is None or excess < best[0]:
            best = (excess, lid)
    if best is None or best[0] > 0.5 * max(ll.width_m for ll in lanelets.values()):
        raise ImportFailure(path, f"planningProblem {ego.problem_id} initialState",
                            f"the ego at ({ego.x_m:.2f}, {ego.y_m:.2f}) m is on no lanelet "
                            "of its heading")
    return best[1]


def _component(lanelets: dict[int, LaneletRecord], start: int) -> set[int]:
    seen = {start}
    todo = deque([start])
    while todo:
        ll = lanelets[todo.popleft()]
        for nxt in (*ll.successors, *ll.predecessors, ll.adj_left, ll.adj_right):
            if nxt is not None and nxt in lanelets and nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


def _neighbours(path: str, road: dict[int, LaneletRecord]
                ) -> tuple[dict[int, int], dict[int, int]]:
    """Left and right same-direction neighbours, made symmetric (checked)."""
    left = {lid: ll.adj_left for lid, ll in road.items() if ll.adj_left in road}
    right = {lid: ll.adj_right for lid, ll in road.items() if ll.adj_right in road}
    for a, b, here, there in (("left", "right", left, right), ("right", "left", right, left)):
        for lid, other in sorted(here.items()):
            back = there.get(other)
            if back is None:
                there[other] = lid
            elif back != lid:
                raise ImportFailure(path, f"lanelet {road[other].label}",
                                    f"inconsistent adjacency: it is the {a} neighbour of "
                                    f"lanelet {lid} but its {b} neighbour is lanelet {back}")
    return {k: v for k, v in left.items() if v is not None}, \
        {k: v for k, v in right.items() if v is not None}


def _rows(path: str, road: dict[int, LaneletRecord]) -> list[LaneRow]:
    left, right = _neighbours(path, road)
    rows: list[LaneRow] = []
    placed: dict[int, int] = {}
    for start in sorted(lid for lid in road if lid not in right):
        chain = [start]
        while chain[-1] in left:
            nxt = left[chain[-1]]
            if nxt in chain or nxt in placed:
                raise ImportFailure(path, f"lanelet {road[nxt].label}", "inconsistent "
                                    "adjacency: it is reached twice walking left from a "
                                    "rightmost lanelet")
            chain.append(nxt)
        for lid in chain:
            placed[lid] = len(rows)
        rows.append(LaneRow(tuple(road[lid] for lid in chain)))
    missing = sorted(set(road) - set(placed))
    if missing:
        raise ImportFailure(path, f"lanelet {road[missing[0]].label}", "inconsistent "
                            "adjacency: its row has no rightmost lanelet (a cycle of "
                            "left/right neighbours)")
    return rows


def _check_row(path: str, row: LaneRow) -> None:
    ref = row.lanelets[0].centre_xy_m
    ref_heading = math.atan2(*(ref[-1] - ref[0])[::-1])
    for ll in row.lanelets:
        centre = ll.centre_xy_m
        if polyline_length_m(centre) < MIN_LANELET_LENGTH_M:
            raise ImportFailure(path, f"lanelet {ll.label}", "its centre line is shorter "
                                f"than {MIN_LANELET_LENGTH_M} m: it cannot become a lane")
        if not ll.width_m > 0.0:
            raise ImportFailure(path, f"lanelet {ll.label}", "zero width")
        heading = math.atan2(*(centre[-1] - centre[0])[::-1])
        if angle_diff_rad(heading, ref_heading) > 0.5 * math.pi:
            raise ImportFailure(path, f"lanelet {ll.label}", "it is a same-direction "
                                f"neighbour in the row of lanelet {row.label} but points the "
                                "other way")


def build_road(rec: RecordedFile) -> RoadRows:
    """The rows of the ego's road (module docstring); :class:`ImportFailure` otherwise."""
    path = rec.path
    lanelets = {ll.lanelet_id: ll for ll in rec.lanelets}
    if len(lanelets) != len(rec.lanelets):
        raise ImportFailure(path, "lanelet", "duplicate lanelet ids")
    notes: list[str] = []
    dangling = sorted({(ll.lanelet_id, ref) for ll in rec.lanelets
                       for ref in (*ll.successors, *ll.predecessors, ll.adj_left, ll.adj_right)
                       if ref is not None and ref not in lanelets})
    if dangling:
        notes.append(f"{len(dangling)} references to missing lanelets dropped (first: "
                     f"lanelet {dangling[0][0]} -> {dangling[0][1]})")
    ego = _ego_lanelet(path, lanelets, rec.ego)
    keep = _component(lanelets, ego)
    bridged = bridge_connectors({lid: lanelets[lid] for lid in sorted(keep)})
    if bridged.note:
        notes.append(bridged.note)
    split = split_road(path, bridged.lanelets, max(lanelets) + 1)
    road = split.lanelets
    if split.cuts:
        notes.append(f"{split.cut_lanelets} lanelets cut at their neighbours' ends "
                     f"({split.cuts} cuts) so that rows align: pieces <id>_1, <id>_2, ...")
    ego = _ego_lanelet(path, road, rec.ego)
    rows = _rows(path, road)
    for row in rows:
        _check_row(path, row)
    place = {ll.lanelet_id: (r, i) for r, row in enumerate(rows)
             for i, ll in enumerate(row.lanelets)}
    for ll in road.values():
        for s in ll.successors:
            if s in place and place[s][0] == place[ll.lanelet_id][0]:
                raise ImportFailure(path, f"lanelet {ll.label}", f"its successor {s} is "
                                    "beside it in the same row (lanelets of a row must be "
                                    "side by side, not one after the other)")
    dropped = len(lanelets) - len(keep)
    if dropped:
        notes.append(f"{dropped} lanelets not connected to the ego's road (opposite "
                     "carriageway, other roads) dropped")
    return RoadRows(tuple(rows), place, ego, dropped, tuple(notes), split.pieces)


def lane_direction_ok(heading_a: float, heading_b: float) -> bool:
    """Whether two headings [rad] are within 90 deg."""
    return angle_diff_rad(heading_a, heading_b) <= 0.5 * math.pi

