"""Cut lanelets at their neighbours' boundaries, so that side-by-side lanelets cover the
same stretch and rows (:mod:`~suite.importers.commonroad.lanelets`) align.

CommonRoad gives a lanelet one ``adjacentLeft``/``adjacentRight``, but a long lanelet
can lie beside two or more consecutive ones (exiD: its neighbour row is split at a ramp;
highD-like files with lanelets of different lengths), or its neighbour changes along it.

1. **Pairs.** (right, left) pairs of same-direction neighbours: every ``adjacentLeft``
   of a lanelet and every ``adjacentRight`` pointing at it, in either direction, plus
   the successors/predecessors of a left (right) neighbour that still lie beside the
   lanelet (walked along the neighbour's row while they do). A referenced pair must lie
   side by side: their centre lines overlap by more than :data:`CUT_MARGIN_M` along
   the right one, and the left one's centre is left of the right one's by a median
   lateral offset d with 0.25 w <= d <= 2.5 w, w the mean of their widths; otherwise
   the adjacency is inconsistent (an error naming the lanelet).
2. **Cuts.** Each lanelet is cut at the arc length s of its centre line where a
   partner's start or end projects (its anchor, where it has one: a lanelet opening or
   ending at a connector, :mod:`~suite.importers.commonroad.connectors`), when
   :data:`CUT_MARGIN_M` < s < length - :data:`CUT_MARGIN_M`. A cut at s interpolates
   both bounds at the same parameter of the vertex pair segment holding s (the centre
   line is the mean of the bounds, so the pieces' centre lines are the original's,
   joined end to end). Pairs of pieces are the pairs of the original lanelets' pieces
   that still overlap; cutting repeats until no cut is left (a lanelet beside a cut
   lanelet can need a cut in turn), at most :data:`MAX_ROUNDS` rounds.
3. **Relations.** The first piece keeps the lanelet's id and predecessors; the last
   piece takes its successors; piece k is the successor of piece k-1; references
   elsewhere (another lanelet's predecessor list naming a cut lanelet) go to its last
   piece. Each piece's left/right neighbour is its one overlapping partner on that side
   (two partners overlapping one piece: inconsistent adjacency, an error).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace

import numpy as np

from reports.geometry import arc_lengths_m
from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import polyline_length_m, project, resample
from suite.importers.commonroad.records import FloatArray, LaneletRecord

__all__ = ["CUT_MARGIN_M", "MAX_ROUNDS", "SplitRoad", "cut_lanelet", "lies_beside", "overlap_m",
           "split_road"]

CUT_MARGIN_M = 1.0
"""A neighbour's end projecting closer than this [m] to a lanelet's end cuts nothing
(the ends are taken as aligned); it is also the least overlap of a pair [m]."""

MAX_ROUNDS = 20

Pair = tuple[int, int]
"""(right lanelet id, left lanelet id)."""


@dataclass(frozen=True)
class SplitRoad:
    """The road after cutting: lanelets by (internal) id, each file lanelet's pieces in
    order (file id -> piece ids), the number of lanelets cut and of cuts."""

    lanelets: dict[int, LaneletRecord]
    pieces: dict[int, tuple[int, ...]]
    cut_lanelets: int
    cuts: int

    def __post_init__(self) -> None:
        if self.cuts < self.cut_lanelets or self.cut_lanelets < 0:
            raise ValueError(f"{self.cuts} cuts of {self.cut_lanelets} lanelets")


def overlap_m(right: LaneletRecord, left: LaneletRecord) -> tuple[float, float]:
    """The stretch [a, b] of ``right``'s centre line [m] that ``left`` lies beside (the
    projections of its centre line's ends)."""
    rc, lc = right.centre_xy_m, left.centre_xy_m
    a = project(rc, float(lc[0, 0]), float(lc[0, 1])).s_m
    b = project(rc, float(lc[-1, 0]), float(lc[-1, 1])).s_m
    return min(a, b), max(a, b)


def lies_beside(right: LaneletRecord, left: LaneletRecord) -> bool:
    """Whether ``left`` lies left of ``right`` along more than the margin (module
    docstring, step 1)."""
    a, b = overlap_m(right, left)
    if b - a <= CUT_MARGIN_M:
        return False
    rc = right.centre_xy_m
    length = polyline_length_m(rc)
    lateral = []
    for x, y in resample(left.centre_xy_m, np.linspace(0.0, 1.0, 11)):
        pr = project(rc, float(x), float(y))
        if 0.0 < pr.s_m < length:
            lateral.append(pr.lateral_m)
    if not lateral:
        return False
    d = float(np.median(lateral))
    w = 0.5 * (right.width_m + left.width_m)
    return 0.25 * w <= d <= 2.5 * w


def _walk(road: dict[int, LaneletRecord], base: LaneletRecord, start: int,
          on_left: bool) -> set[int]:
    """``start`` and the lanelets of its row (successors, predecessors) beside ``base``."""
    found = {start}
    todo = [start]
    while todo:
        ll = road[todo.pop()]
        for nxt in (*ll.successors, *ll.predecessors):
            if nxt in found or nxt not in road or nxt == base.lanelet_id:
                continue
            cand = road[nxt]
            if lies_beside(base, cand) if on_left else lies_beside(cand, base):
                found.add(nxt)
                todo.append(nxt)
    return found


def _pairs(path: str, road: dict[int, LaneletRecord]) -> set[Pair]:
    """Step 1 of the module docstring."""
    referenced: set[Pair] = set()
    for lid, ll in road.items():
        if ll.adj_left in road:
            referenced.add((lid, ll.adj_left))
        if ll.adj_right in road:
            referenced.add((ll.adj_right, lid))
    pairs: set[Pair] = set()
    for r, lf in sorted(referenced):
        if r == lf or not lies_beside(road[r], road[lf]):
            raise ImportFailure(path, f"lanelet {lf}", f"inconsistent adjacency: it is the "
                                f"left neighbour of lanelet {r} (or that its right "
                                "neighbour) but it does not lie beside it")
        pairs |= {(r, x) for x in _walk(road, road[r], lf, on_left=True)}
        pairs |= {(x, lf) for x in _walk(road, road[lf], r, on_left=False)}
    return pairs


def cut_lanelet(ll: LaneletRecord, cuts_m: Iterable[float]) -> list[LaneletRecord]:
    """``ll`` cut at the centre-line arc lengths ``cuts_m`` [m] (strictly inside), bounds
    interpolated at the same vertex-pair parameter (module docstring, step 2). The
    pieces keep ``ll``'s fields but their bounds (the caller renumbers and rewires)."""
    left, right = ll.left_xy_m, ll.right_xy_m
    cum = arc_lengths_m(ll.centre_xy_m)
    pieces: list[LaneletRecord] = []
    lo_l, lo_r, lo_idx = left[:0], right[:0], 0
    for s in sorted(cuts_m):
        i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(cum) - 2))
        seg = float(cum[i + 1] - cum[i])
        t = (s - float(cum[i])) / seg if seg > 0 else 0.0
        cut_l = left[i] + t * (left[i + 1] - left[i])
        cut_r = right[i] + t * (right[i + 1] - right[i])
        lx, rx = _drop_repeats(np.vstack([lo_l, left[lo_idx:i + 1], cut_l]),
                               np.vstack([lo_r, right[lo_idx:i + 1], cut_r]))
        # a start anchor belongs to the first piece only, an end anchor to the last
        pieces.append(replace(ll, left_xy_m=lx, right_xy_m=rx, end_anchor_xy_m=None,
                              start_anchor_xy_m=None if pieces else ll.start_anchor_xy_m))
        lo_l, lo_r, lo_idx = cut_l[None, :], cut_r[None, :], i + 1
    lx, rx = _drop_repeats(np.vstack([lo_l, left[lo_idx:]]), np.vstack([lo_r, right[lo_idx:]]))
    pieces.append(replace(ll, left_xy_m=lx, right_xy_m=rx,
                          start_anchor_xy_m=None if pieces else ll.start_anchor_xy_m))
    return pieces


def _drop_repeats(left: FloatArray, right: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Drop vertex pairs whose centre repeats the previous one's (within 1 mm)."""
    centre = 0.5 * (left + right)
    keep = [0]
    for k in range(1, len(centre)):
        if float(np.hypot(*(centre[k] - centre[keep[-1]]))) > 1e-3:
            keep.append(k)
    if len(keep) < 2:
        keep = [0, len(centre) - 1]
    elif keep[-1] != len(centre) - 1:
        keep[-1] = len(centre) - 1
    return left[keep].copy(), right[keep].copy()


def _cut_positions(road: dict[int, LaneletRecord], pairs: set[Pair]) -> dict[int, list[float]]:
    """Where each lanelet must be cut [m along its centre line] (step 2)."""
    cuts: dict[int, list[float]] = {}
    for a, b in pairs:
        for here, there in ((a, b), (b, a)):
            centre = road[here].centre_xy_m
            length = polyline_length_m(centre)
            other = road[there]
            for x, y in (other.start_xy_m, other.end_xy_m):  # anchors: connectors.py
                s = project(centre, x, y).s_m
                if CUT_MARGIN_M < s < length - CUT_MARGIN_M:
                    cuts.setdefault(here, []).append(s)
    out: dict[int, list[float]] = {}
    for lid, values in cuts.items():
        merged: list[float] = []
        for s in sorted(values):
            if not merged or s - merged[-1] > CUT_MARGIN_M:
                merged.append(s)
        out[lid] = merged
    return out


def _renumber(road: dict[int, LaneletRecord], cuts: dict[int, list[float]],
              next_id: int) -> tuple[dict[int, LaneletRecord], dict[int, list[int]], int]:
    """Cut every lanelet of ``cuts``: the first piece keeps the id, the others get new
    ids from ``next_id`` (labels are set at the end); successors/predecessors rewired
    (step 3)."""
    out = dict(road)
    pieces: dict[int, list[int]] = {}
    for lid in sorted(cuts):
        ll = road[lid]
        parts = cut_lanelet(ll, cuts[lid])
        ids = [lid, *range(next_id, next_id + len(parts) - 1)]
        next_id += len(parts) - 1
        for k, (pid, part) in enumerate(zip(ids, parts, strict=True)):
            out[pid] = replace(
                part, lanelet_id=pid,
                source_id=ll.source_id if k == 0 else ll.file_id,
                piece=ll.piece if k == 0 else 1,
                predecessors=ll.predecessors if k == 0 else (ids[k - 1],),
                successors=ll.successors if k == len(ids) - 1 else (ids[k + 1],))
        pieces[lid] = ids
    last = {lid: ids[-1] for lid, ids in pieces.items()}
    inner = {i for ids in pieces.values() for i in ids[1:]}
    for lid, ll in list(out.items()):
        if lid not in inner and any(p in last for p in ll.predecessors):
            out[lid] = replace(ll, predecessors=tuple(last.get(p, p) for p in ll.predecessors))
    return out, pieces, next_id


def _label_pieces(road: dict[int, LaneletRecord], order: dict[int, list[int]]
                  ) -> dict[int, LaneletRecord]:
    """Pieces numbered 1, 2, ... along each file lanelet (piece 0 keeps the file id)."""
    out = dict(road)
    for source, ids in order.items():
        for k, pid in enumerate(ids):
            out[pid] = replace(out[pid], source_id=None if k == 0 else source, piece=k)
    return out


def _adjacency(path: str, road: dict[int, LaneletRecord], pairs: set[Pair]
               ) -> dict[int, LaneletRecord]:
    """Step 3: each piece's one overlapping partner per side."""
    left: dict[int, int] = {}
    right: dict[int, int] = {}
    for r, lf in sorted(pairs):
        for side, key, val in ((left, r, lf), (right, lf, r)):
            if side.get(key, val) != val:
                ll = road[key]
                raise ImportFailure(path, f"lanelet {ll.label}", "inconsistent adjacency: "
                                    f"lanelets {road[side[key]].label} and "
                                    f"{road[val].label} are both beside it on the same "
                                    "side, along the same stretch")
            side[key] = val
    return {lid: replace(ll, adj_left=left.get(lid), adj_right=right.get(lid))
            for lid, ll in road.items()}


def split_road(path: str, road: dict[int, LaneletRecord], next_id: int) -> SplitRoad:
    """Cut the lanelets of ``road`` (one carriageway, same-direction adjacency only)
    at their neighbours' boundaries (module docstring); new ids from ``next_id``."""
    pairs = _pairs(path, road)
    order: dict[int, list[int]] = {lid: [lid] for lid in road}
    cut_ids: set[int] = set()
    n_cuts = 0
    for _ in range(MAX_ROUNDS):
        cuts = _cut_positions(road, pairs)
        if not cuts:
            break
        road, pieces, next_id = _renumber(road, cuts, next_id)
        n_cuts += sum(len(v) for v in cuts.values())
        for lid, ids in pieces.items():
            source = road[lid].file_id
            cut_ids.add(source)
            seq = order[source]
            k = seq.index(lid)
            order[source] = seq[:k] + ids + seq[k + 1:]
        new_pairs: set[Pair] = set()
        for r, lf in pairs:
            for pr in pieces.get(r, [r]):
                for pl in pieces.get(lf, [lf]):
                    a, b = overlap_m(road[pr], road[pl])
                    if b - a > CUT_MARGIN_M:
                        new_pairs.add((pr, pl))
        pairs = new_pairs
    else:
        raise ImportFailure(path, "lanelet network", f"lanelets still need cutting after "
                            f"{MAX_ROUNDS} rounds of cuts at their neighbours' ends")
    road = _label_pieces(road, order)
    road = _adjacency(path, road, pairs)
    return SplitRoad(road, {k: tuple(v) for k, v in order.items()}, len(cut_ids), n_cuts)
