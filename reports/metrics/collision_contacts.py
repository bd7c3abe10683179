"""The contacts of the collision judgement (:mod:`reports.metrics.collisions`): where the
ego's box and a neighbour's overlap or touch between two rows, the monitor's flags,
a replayed vehicle's jumps, and SUMO's own reports grouped into episodes."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from reports.geometry import box_corners, boxes_overlap, swept_box_ttc
from reports.geometry.motion import jump_excess_mps
from reports.metrics.collision_events import (
    EGO_ID,
    EPISODE_GAP_S,
    JUMP_AFTER_S,
    JUMP_EXCESS_MPS,
    JUMP_MAX_GAP_S,
    MONITOR,
    OVERLAP,
    SUMO_MATCH_S,
    SWEPT,
    SumoEpisode,
)
from reports.metrics.context import RunContext, neighbour_trace_rows
from reports.record import AGENT_REPLAYED, SumoCollision
from reports.record.columns import BoolColumn, IntColumn


@dataclass(frozen=True)
class _Contact:
    """An episode before classification: rows of first and last contact, the other
    vehicle, its neighbour row index at the first contact (-1: not recorded), how the
    first contact was found, and the row of the earliest evidence (``start``)."""

    row: int
    last_row: int
    other_id: str
    nb_index: int
    evidence: str
    start: int


@dataclass(frozen=True)
class _NeighbourContacts:
    """Per neighbour row (N,): its trace row (-1: its step is no trace step), whether its
    box overlaps the ego's there (``sampled``) and whether they touch between the
    previous trace row and this one without overlapping at either (``swept``); the
    neighbour boxes (N, 4, 2) [m]."""

    rows: IntColumn
    sampled: BoolColumn
    swept: BoolColumn
    boxes: np.ndarray


# ------------------------------------------------------------------ a replayed vehicle's jumps


def _after_jump(ctx: RunContext, rows: IntColumn, vid: str, t: float) -> bool:
    """Whether replayed vehicle ``vid`` jumped (module doc) in its neighbour rows at or
    within ``JUMP_AFTER_S`` before run time ``t`` [s]."""
    nb = ctx.record.neighbours
    idx = np.flatnonzero((np.asarray(nb.id, dtype=object) == vid) & (rows >= 0)
                         & (nb.agent == AGENT_REPLAYED))
    if idx.size < 2:
        return False
    idx = idx[np.argsort(rows[idx], kind="stable")]
    ts = ctx.t_s[rows[idx]]
    excess = jump_excess_mps(ts, nb.x_m[idx], nb.y_m[idx], nb.heading_rad[idx],
                             nb.speed_mps[idx])
    dt = np.diff(ts)
    jumped = (excess > JUMP_EXCESS_MPS) & (dt <= JUMP_MAX_GAP_S)
    # the pair's interval [t_a, t_b] widened by JUMP_AFTER_S after it contains t
    return bool(np.any(jumped & (ts[:-1] <= t) & (t <= ts[1:] + JUMP_AFTER_S)))


# ------------------------------------------------------------------ contacts


def _swept(ctx: RunContext, rows: IntColumn, boxes: np.ndarray, usable: BoolColumn,
           sampled: BoolColumn) -> BoolColumn:
    """Per neighbour row k (N,) at trace row r: the boxes touch between rows r-1 and r
    while they overlap at neither (module doc).

    With the box corners A_{r-1}, B_{r-1} (4, 2) [m] and the centre displacements d_e,
    d_o (2,) [m] from r-1 to r, forwards A(τ) = A_{r-1} + τ d_e, B(τ) = B_{r-1} + τ d_o,
    backwards A_r - τ d_e, B_r - τ d_o, τ in [0, 1]: a contact when the swept
    separating-axis test finds a touch with τ <= 1 both ways. Pairs whose bounding
    circles cannot meet (centre distance at r-1 beyond both circumradii plus |d_o - d_e|)
    are skipped."""
    nb = ctx.record.neighbours
    out = np.zeros(len(nb), dtype=bool)
    idx = np.flatnonzero(usable)
    if idx.size < 2:
        return out
    _, codes = np.unique(np.asarray(nb.id, dtype=object)[idx].astype(str), return_inverse=True)
    perm = np.lexsort((rows[idx], codes))
    ks, cs = idx[perm], codes[perm]
    k0, k1 = ks[:-1], ks[1:]
    r0, r1 = rows[k0], rows[k1]
    pair = (cs[:-1] == cs[1:]) & (r1 == r0 + 1) & ~sampled[k0] & ~sampled[k1]
    k0, k1, r0, r1 = k0[pair], k1[pair], r0[pair], r1[pair]
    # only pairs whose bounding circles can meet within the interval
    ego_box = ctx.record.info.ego
    reach = 0.5 * (np.hypot(nb.length_m[k0], nb.width_m[k0])
                   + math.hypot(ego_box.length_m, ego_box.width_m))
    gap0 = np.hypot(nb.x_m[k0] - ctx.box_x_m[r0], nb.y_m[k0] - ctx.box_y_m[r0])
    rel = np.hypot(nb.x_m[k1] - nb.x_m[k0] - ctx.box_x_m[r1] + ctx.box_x_m[r0],
                   nb.y_m[k1] - nb.y_m[k0] - ctx.box_y_m[r1] + ctx.box_y_m[r0])
    near = gap0 <= reach + rel
    k0, k1, r0, r1 = k0[near], k1[near], r0[near], r1[near]
    if k0.size == 0:
        return out
    ego_move = np.stack([ctx.box_x_m[r1] - ctx.box_x_m[r0],
                         ctx.box_y_m[r1] - ctx.box_y_m[r0]], axis=-1)
    nb_move = np.stack([nb.x_m[k1] - nb.x_m[k0], nb.y_m[k1] - nb.y_m[k0]], axis=-1)
    forward = swept_box_ttc(ctx.corners_m[r0], ego_move, boxes[k0], nb_move, 1.0)
    backward = swept_box_ttc(ctx.corners_m[r1], -ego_move, boxes[k1], -nb_move, 1.0)
    out[k1[np.isfinite(forward) & np.isfinite(backward)]] = True
    return out


def neighbour_contacts(ctx: RunContext) -> _NeighbourContacts:
    """Sampled and swept contacts of the ego box with every recorded neighbour row."""
    nb = ctx.record.neighbours
    rows = neighbour_trace_rows(ctx)
    boxes = box_corners(nb.x_m, nb.y_m, nb.heading_rad, nb.length_m, nb.width_m)
    none = np.zeros(len(nb), dtype=bool)
    if ctx.n == 0 or len(nb) == 0:
        return _NeighbourContacts(rows, none, none.copy(), boxes)
    ok = rows >= 0
    ego = ctx.corners_m[np.where(ok, rows, 0)]
    usable = ok & np.all(np.isfinite(boxes.reshape(len(nb), 8)), axis=1) & \
        np.all(np.isfinite(ego.reshape(len(nb), 8)), axis=1)
    sampled = usable & boxes_overlap(ego, boxes)
    return _NeighbourContacts(rows, sampled, _swept(ctx, rows, boxes, usable, sampled), boxes)


def _split_episodes(rows: list[int], t_s: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) row of each run of rows separated by > EPISODE_GAP_S."""
    out: list[tuple[int, int]] = []
    for row in sorted(set(rows)):
        if out and t_s[row] - t_s[out[-1][1]] <= EPISODE_GAP_S:
            out[-1] = (out[-1][0], row)
        else:
            out.append((row, row))
    return out


def _flag_rows(ctx: RunContext, vid: str) -> list[int]:
    """Rows where the monitor flagged an overlap with ``vid`` as the nearest vehicle."""
    safety = ctx.record.trace.safety
    flagged = safety.geom_collision & (np.asarray(safety.gap_vehicle, dtype=object) == vid)
    return [int(r) for r in np.flatnonzero(flagged)]


def _recorded_contacts(ctx: RunContext, nc: _NeighbourContacts) -> list[_Contact]:
    """Episodes of sampled and swept contacts, per vehicle."""
    nb = ctx.record.neighbours
    by_vehicle: dict[str, dict[int, int]] = {}
    for k in np.flatnonzero(nc.sampled | nc.swept):
        by_vehicle.setdefault(str(nb.id[k]), {})[int(nc.rows[k])] = int(k)
    out = []
    t_s = ctx.t_s
    for vid, row_to_nb in by_vehicle.items():
        flags = _flag_rows(ctx, vid)
        for first, last in _split_episodes(list(row_to_nb), t_s):
            earlier = [r for r in flags if t_s[first] - EPISODE_GAP_S <= t_s[r] <= t_s[first]]
            at = row_to_nb[first]
            out.append(_Contact(first, last, vid, at, OVERLAP if nc.sampled[at] else SWEPT,
                                min([first, *earlier])))
    return out


def _within(contacts: list[_Contact], t_s: np.ndarray, t: float) -> bool:
    return any(t_s[c.row] - SUMO_MATCH_S <= t <= t_s[c.last_row] + SUMO_MATCH_S
               for c in contacts)


def _nb_index(rows: np.ndarray, ids: np.ndarray, row: int, vid: str) -> int:
    hit = np.flatnonzero((rows == row) & (ids == vid))
    return int(hit[0]) if hit.size else -1


def _monitor_contacts(ctx: RunContext, rows: IntColumn, contacts: list[_Contact]
                      ) -> list[_Contact]:
    """Episodes known only from the monitor's overlap flag (no recorded contact within
    ``SUMO_MATCH_S`` of the flag)."""
    ids = np.asarray(ctx.record.neighbours.id, dtype=object)
    t_s = ctx.t_s
    safety = ctx.record.trace.safety
    found: dict[str, list[int]] = {}
    for row in np.flatnonzero(safety.geom_collision):
        if not _within(contacts, t_s, float(t_s[row])):
            # the nearest vehicle: the one the ego overlaps
            found.setdefault(str(safety.gap_vehicle[row]), []).append(int(row))
    return [_Contact(first, last, vid, _nb_index(rows, ids, first, vid), MONITOR, first)
            for vid, vrows in found.items() for first, last in _split_episodes(vrows, t_s)]


# ------------------------------------------------------------------ SUMO's report


def _other(hit: SumoCollision) -> str:
    return hit.victim if hit.collider == EGO_ID else hit.collider


def _sumo_trace_times(ctx: RunContext) -> list[tuple[float, SumoCollision]]:
    origin = ctx.record.outcome.sumo_t_origin_s
    return [(float(h.t_s) - origin, h) for h in ctx.record.outcome.sumo_collisions
            if EGO_ID in (h.collider, h.victim)]


def sumo_episodes(ctx: RunContext) -> tuple[SumoEpisode, ...]:
    """SUMO's reports of the ego grouped per other vehicle (module doc), in time order;
    a ``sumo_collision`` flag farther than ``SUMO_MATCH_S`` from every report is a report
    with an unnamed vehicle."""
    if ctx.n == 0:
        return ()
    t_s = ctx.t_s
    reports = _sumo_trace_times(ctx)
    times = np.sort(np.array([t for t, _ in reports], dtype=np.float64))
    by_vehicle: dict[str, list[tuple[float, SumoCollision | None]]] = {}
    for t, hit in reports:
        by_vehicle.setdefault(_other(hit), []).append((t, hit))
    flagged = t_s[ctx.record.trace.safety.sumo_collision]
    if times.size:  # the distance of each flag to the nearest report
        pos = np.searchsorted(times, flagged)
        near = np.minimum(np.abs(flagged - times[np.clip(pos - 1, 0, times.size - 1)]),
                          np.abs(flagged - times[np.clip(pos, 0, times.size - 1)]))
        flagged = flagged[near > SUMO_MATCH_S]
    by_vehicle.setdefault("", []).extend((float(t), None) for t in flagged)
    by_vehicle = {vid: items for vid, items in by_vehicle.items() if items}
    out = []
    for vid, items in by_vehicle.items():
        items.sort(key=lambda item: item[0])
        groups: list[list[tuple[float, SumoCollision | None]]] = []
        for item in items:
            if groups and item[0] - groups[-1][-1][0] <= EPISODE_GAP_S:
                groups[-1].append(item)
            else:
                groups.append([item])
        for group in groups:
            first, last = group[0], group[-1]
            report = first[1]
            role = "" if report is None else (
                "collider" if report.collider == EGO_ID else "victim")
            out.append(SumoEpisode(
                other_id=vid, row=int(np.argmin(np.abs(t_s - first[0]))),
                last_row=int(np.argmin(np.abs(t_s - last[0]))), t_s=float(first[0]),
                last_t_s=float(last[0]), reports=len(group), role=role,
                type=report.type if report is not None else ""))
    return tuple(sorted(out, key=lambda s: (s.t_s, s.other_id)))


def _agree(c: _Contact, s: SumoEpisode, t_s: np.ndarray) -> bool:
    """A collision episode and a SUMO episode describe one collision (module doc)."""
    same = c.other_id == s.other_id or not c.other_id or not s.other_id
    return same and s.t_s <= float(t_s[c.last_row]) + SUMO_MATCH_S \
        and s.last_t_s >= float(t_s[c.start]) - SUMO_MATCH_S
