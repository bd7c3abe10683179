"""Collisions judged on 2-D geometry, classified as nuPlan's ``no_ego_at_fault_collisions``
metric does, with SUMO's collider/victim report beside each and every disagreement listed.

Contacts (what the verdict rests on: the boxes, never SUMO's report)
    At every trace row, the ego box (from the CG, yaw and ``info.ego``) is tested for
    overlap with the box of every recorded neighbour of that step (``neighbours.parquet``;
    separating axes, :func:`reports.metrics.geometry.boxes_overlap`): a *sampled* contact.
    Between two consecutive trace rows r-1, r at which the same neighbour is recorded,
    both boxes are moved from their poses at r-1 to their centres at r along straight
    lines, at constant speed (a translation: the headings are held), and the swept
    separating-axis test (:func:`reports.metrics.geometry.swept_box_ttc` with the
    displacements as velocities over a unit interval) finds whether they touch in
    between; the same backwards from r with the headings of r. When both sweeps touch
    and neither row overlaps, row r has a *swept* contact: a graze shorter than a
    control period that the samples step over. (Requiring both sweeps keeps a heading
    change within the interval from inventing a contact.) The in-loop safety monitor's
    overlap flag (``safety.geom_collision``, its own box test on the scene) is geometric
    evidence too: a flag no recorded contact explains (its vehicle ``gap_vehicle`` not
    among the row's neighbours) is a *monitor* contact.

Episodes
    The contacts with one vehicle form one *episode* until the boxes have been apart for
    more than ``EPISODE_GAP_S`` (1 s); each episode is one collision, classified at its
    first contact row. (nuPlan counts one collision per track and run; the run stops 0.5
    s after the first geometric contact anyway.) An episode is *located* at its earliest
    evidence: its first contact, or an earlier overlap flag of the safety monitor with
    that vehicle (``geom_collision`` where ``gap_vehicle`` is it) up to 1 s before; the
    collision metric and its criterion point there.

Classes, in nuPlan's order of tests, at the first contact row (for a swept contact: at
the row before it, the last sample before the boxes touched)
    ``stopped_ego``      the ego's speed <= ``STOPPED_SPEED_MPS`` (0.05 m/s);
    ``stopped_track``    else the other vehicle's speed <= 0.05 m/s;
    ``active_rear``      else the other's box centre is behind the ego: the angle between
                         the ego's heading and the vector from its rear axle to that
                         centre exceeds 150 deg (the CG where the record has no axle);
    ``active_front``     else the ego's front edge (the segment front-left to front-right
                         corner) intersects the other box (for a swept or monitor
                         contact, whose boxes do not overlap at that row: the front edge
                         is the part of the ego nearest the other box);
    ``active_lateral``   otherwise;
    ``unclassified``     a monitor contact with a vehicle that is not among the row's
                         recorded neighbours (or none is named).
    ``replayed_into_ego`` (hwyeval's, not nuPlan's; tested after the above) the other
                         vehicle is replayed from a recording at that row (neighbours'
                         ``agent`` = 1: not handed over to a driver, blind to the ego)
                         and drives into the ego: the class above is ``stopped_ego``, or
                         the other's front edge intersects the ego box (for a swept
                         contact: is the part of it nearest the ego box). A recording
                         cannot yield to an ego that drives differently from its
                         recorded driver (docs/replay.md). So is a contact
                         with a replayed vehicle during or within ``JUMP_AFTER_S``
                         (0.5 s) after a *jump* in its track: two consecutive neighbour
                         rows of it, both replayed, at most ``JUMP_MAX_GAP_S`` apart,
                         whose displacement differs from what its speeds and headings
                         allow (:func:`jump_excess_mps`) by more than
                         ``JUMP_EXCESS_MPS`` (10 m/s) times their interval: a recording
                         that teleports onto the ego's path (a glitch the importer warns
                         of, docs/recorded.md) is the recording's collision, whatever
                         the geometry says.

At fault (nuPlan: could have been prevented by the planner)
    ``active_front`` and ``stopped_track`` always; ``active_lateral`` when the ego is not
    within one lane at that row (:mod:`reports.metrics.lane_occupancy`: its four
    corners in one lane or in a lane and its continuation, on ``road.lanes`` with the
    internal junction lanes; a corner off every lane counts as not within one lane);
    ``unclassified`` too (conservative: what cannot be judged is not excused);
    ``stopped_ego``, ``active_rear`` and ``replayed_into_ego`` never.

SUMO's report (``outcome.sumo_collisions``, times on SUMO's clock: the trace time is
``t_s - outcome.sumo_t_origin_s``) stands beside the geometry, never in its place
    SUMO without its sublane model judges collisions along the lane only (1-D: two
    vehicles on one lane whose lane positions overlap), so it reports a car passing a
    stalled one with half a metre to spare once their lane indices agree, and misses a
    side-swipe across a lane line. Its reports with one other vehicle (collider or victim
    is the ego), no more than ``EPISODE_GAP_S`` apart, form a :class:`SumoEpisode` (a
    ``safety.sumo_collision`` flag more than ``SUMO_MATCH_S`` from every report counts
    as a report with an unnamed vehicle). A SUMO episode and a collision episode *agree*
    when they name the same vehicle (or one of them names none) and their time spans,
    widened by ``SUMO_MATCH_S`` (1 s) on each side of the collision episode, overlap;
    the collision then carries SUMO's ``sumo_role`` ('collider': SUMO blames the ego;
    'victim') and ``sumo_type`` of the first agreeing report. What does not agree is a
    :class:`reports.record.verdict.CollisionDisagreement`: 'sumo_only' (a SUMO episode no
    collision explains: not counted) or 'geometry_only' (a collision SUMO did not
    report: counted), stored in ``Verdict.collision_disagreements``.

Severity: nuPlan's ego delta-v with equal masses, 0.5 sqrt(v_e^2 + v_o^2 - 2 v_e v_o
cos(psi_e - psi_o)) [m/s] (the speed change of the ego in a perfectly plastic impact).

Metrics (counts [-] unless stated; NaN without trace rows unless stated)
    ``collision`` [0/1] 1 when there is a collision episode (0 without rows), located at
    the first; ``first_collision_t_s`` [s] its time (NaN if none); ``collisions`` every
    episode; ``at_fault_collisions`` the at-fault ones (cumulative: a criterion locates
    its first); ``collisions_<class>`` per class; ``swept_only_collisions`` episodes
    whose first contact only the swept test found; ``first_at_fault_collision_t_s`` [s]
    (NaN if none); ``max_at_fault_delta_v_mps`` [m/s] (0 if none). Beside them,
    informational (better 'none': they judge SUMO's model, not the driving):
    ``sumo_collisions_as_collider`` / ``sumo_collisions_as_victim`` (episodes of SUMO's
    reports with the ego in that role), ``collision_disagreements``,
    ``sumo_only_collisions``, ``geometry_only_collisions``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from reports.geometry import box_corners, box_distance, boxes_overlap, swept_box_ttc
from reports.metrics.context import RunContext
from reports.metrics.lane_occupancy import LaneTopology
from reports.metrics.values import Measured, measured
from reports.record import AGENT_REPLAYED, NeighbourColumns, SumoCollision
from reports.record.columns import BoolColumn, IntColumn
from reports.record.verdict import GEOMETRY_ONLY, SUMO_ONLY, CollisionDisagreement

STOPPED_SPEED_MPS = 0.05
BEHIND_ANGLE_RAD = math.radians(150.0)
EPISODE_GAP_S = 1.0
SUMO_MATCH_S = 1.0
EGO_ID = "ego"

JUMP_EXCESS_MPS = 10.0
"""A recorded vehicle *jumps* between two samples when its displacement differs from the
one its speeds and headings allow by more than this speed [m/s] times the interval
(1 m over 0.1 s). The three development recordings stay below 1.8 m/s."""
JUMP_AFTER_S = 0.5  # [s] a contact this long after a jump is still the jump's
JUMP_MAX_GAP_S = 0.5  # [s] rows further apart than this are not judged (absent between)

# How a collision episode's first contact was found (CollisionEvent.evidence)
OVERLAP = "overlap"  # the recorded boxes overlap at the row
SWEPT = "swept"  # they touch between the previous row and this one
MONITOR = "monitor"  # only the in-loop monitor's overlap flag
EVIDENCE = (OVERLAP, SWEPT, MONITOR)


class CollisionClass(StrEnum):
    """nuPlan's CollisionType, plus what a record cannot classify and a replayed
    (recorded, blind) vehicle driving into the ego."""

    STOPPED_EGO = "stopped_ego"
    STOPPED_TRACK = "stopped_track"
    ACTIVE_REAR = "active_rear"
    ACTIVE_FRONT = "active_front"
    ACTIVE_LATERAL = "active_lateral"
    UNCLASSIFIED = "unclassified"
    REPLAYED_INTO_EGO = "replayed_into_ego"


@dataclass(frozen=True)
class CollisionEvent:
    """One collision episode (2-D contact), judged at its first contact (module doc).

    ``row``/``t_s``: trace row and time [s] where the episode is located (its earliest
    evidence); ``contact_row``: the first contact, where it was classified (speeds [m/s]
    and ``ego_within_one_lane`` are taken there; for a swept contact at the row before,
    the last sample before the boxes touched); ``last_row``: its last contact;
    ``evidence``: how that first contact was found (:data:`OVERLAP`, :data:`SWEPT`,
    :data:`MONITOR`); ``sumo_reports``: SUMO's reports agreeing with it (0: SUMO did not
    report it); ``sumo_role``: the ego's role in the first ('collider', 'victim' or '')."""

    row: int
    contact_row: int
    last_row: int
    t_s: float
    other_id: str
    kind: CollisionClass
    at_fault: bool
    ego_speed_mps: float
    other_speed_mps: float
    other_stalled: bool
    ego_within_one_lane: bool
    delta_v_mps: float
    evidence: str
    sumo_role: str = ""
    sumo_type: str = ""
    sumo_reports: int = 0

    def __post_init__(self) -> None:
        if self.evidence not in EVIDENCE:
            raise ValueError(f"CollisionEvent.evidence must be one of {EVIDENCE}, "
                             f"got {self.evidence!r}")
        if not 0 <= self.row <= self.contact_row <= self.last_row:
            raise ValueError("CollisionEvent: rows must satisfy 0 <= row <= contact_row <= "
                             f"last_row, got {self.row}, {self.contact_row}, {self.last_row}")

    @property
    def geometric(self) -> bool:
        """The recorded boxes touched (sampled or swept), not only the monitor's flag."""
        return self.evidence != MONITOR


@dataclass(frozen=True)
class SumoEpisode:
    """SUMO's reports of the ego with one other vehicle, each within ``EPISODE_GAP_S`` of
    the previous: first/last trace row and time [s], the number of reports, the ego's
    role ('collider', 'victim'; '' for a flag without its report) and SUMO's type in the
    first. ``other_id`` '' when no vehicle is named."""

    other_id: str
    row: int
    last_row: int
    t_s: float
    last_t_s: float
    reports: int
    role: str
    type: str


@dataclass(frozen=True)
class CollisionJudgement:
    """Everything :func:`judge_collisions` finds: the collision episodes (what the
    verdict counts), SUMO's episodes (beside them) and where the two disagree, each in
    time order."""

    events: tuple[CollisionEvent, ...] = ()
    sumo: tuple[SumoEpisode, ...] = ()
    disagreements: tuple[CollisionDisagreement, ...] = ()


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


# ------------------------------------------------------------------ geometry


def jump_excess_mps(t_s: np.ndarray, x_m: np.ndarray, y_m: np.ndarray,
                    heading_rad: np.ndarray, speed_mps: np.ndarray) -> np.ndarray:
    """Per pair of consecutive samples (n - 1,): |d - dt (v_a u_a + v_b u_b) / 2| / dt
    [m/s], with d the displacement [m] and u the heading's unit vector: how much faster
    than its recorded speeds and headings allow the vehicle moved (about 0 for a smooth
    track; NaN where dt <= 0 or a value is not finite)."""
    dt = np.diff(t_s)
    ok = dt > 0.0
    safe = np.where(ok, dt, 1.0)
    vx, vy = speed_mps * np.cos(heading_rad), speed_mps * np.sin(heading_rad)
    ex = np.diff(x_m) - 0.5 * dt * (vx[1:] + vx[:-1])
    ey = np.diff(y_m) - 0.5 * dt * (vy[1:] + vy[:-1])
    out = np.hypot(ex, ey) / safe
    return np.where(ok & np.isfinite(out), out, np.nan)


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


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _segments_intersect(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray
                        ) -> bool:
    """Closed segments p1-p2 and q1-q2 share a point (touching counts)."""
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True

    def on(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: float) -> bool:
        return abs(d) < 1e-12 and min(a[0], b[0]) - 1e-12 <= c[0] <= max(a[0], b[0]) + 1e-12 \
            and min(a[1], b[1]) - 1e-12 <= c[1] <= max(a[1], b[1]) + 1e-12

    return on(q1, q2, p1, d1) or on(q1, q2, p2, d2) or on(p1, p2, q1, d3) or on(p1, p2, q2, d4)


def _point_in_convex(p: np.ndarray, quad: np.ndarray) -> bool:
    signs = [_cross(quad[k], quad[(k + 1) % 4], p) for k in range(4)]
    return all(s >= -1e-12 for s in signs) or all(s <= 1e-12 for s in signs)


def segment_hits_box(a: np.ndarray, b: np.ndarray, quad: np.ndarray) -> bool:
    """Whether segment a-b (2,) (2,) intersects the convex quad (4, 2), boundary
    included (shapely's ``LineString.intersects(Polygon)``)."""
    if _point_in_convex(a, quad) or _point_in_convex(b, quad):
        return True
    return any(_segments_intersect(a, b, quad[k], quad[(k + 1) % 4]) for k in range(4))


def _point_segment_m(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
    return float(np.hypot(*(p - a - t * ab)))


def segment_box_distance_m(a: np.ndarray, b: np.ndarray, quad: np.ndarray) -> float:
    """Distance [m] from segment a-b to the convex quad (4, 2); 0 where they intersect."""
    if segment_hits_box(a, b, quad):
        return 0.0
    best = min(_point_segment_m(p, quad[k], quad[(k + 1) % 4]) for p in (a, b)
               for k in range(4))
    return min(best, *(_point_segment_m(quad[k], a, b) for k in range(4)))


# ------------------------------------------------------------------ contacts


def _trace_rows(ctx: RunContext) -> IntColumn:
    """Trace row of every neighbour row (-1 where its step is no trace step)."""
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
    rows = _trace_rows(ctx)
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


# ------------------------------------------------------------------ classification


def _rear_axle(ctx: RunContext, row: int) -> np.ndarray:
    ego = ctx.record.trace.ego
    back = ctx.record.info.ego.cg_to_rear_axle_m
    back = back if math.isfinite(back) else 0.0
    psi = float(ego.psi_rad[row])
    return np.array([ego.x_m[row] - back * math.cos(psi), ego.y_m[row] - back * math.sin(psi)])


def _kind(ctx: RunContext, row: int, nb: NeighbourColumns, k: int, evidence: str
          ) -> CollisionClass:
    """nuPlan's ``_get_collision_type`` at trace row ``row`` against neighbour row ``k``."""
    if k < 0:
        return CollisionClass.UNCLASSIFIED
    if float(ctx.record.trace.ego.speed_mps[row]) <= STOPPED_SPEED_MPS:
        return CollisionClass.STOPPED_EGO
    if float(nb.speed_mps[k]) <= STOPPED_SPEED_MPS:
        return CollisionClass.STOPPED_TRACK
    to_other = np.array([nb.x_m[k], nb.y_m[k]]) - _rear_axle(ctx, row)
    norm = float(np.hypot(*to_other))
    psi = float(ctx.psi_rad[row])
    if norm > 1e-9:
        cos_angle = (to_other[0] * math.cos(psi) + to_other[1] * math.sin(psi)) / norm
        if math.acos(max(-1.0, min(1.0, cos_angle))) > BEHIND_ANGLE_RAD:
            return CollisionClass.ACTIVE_REAR
    corners = ctx.corners_m[row]
    other = box_corners(nb.x_m[k], nb.y_m[k], nb.heading_rad[k], nb.length_m[k], nb.width_m[k])
    if evidence == OVERLAP:
        front = segment_hits_box(corners[0], corners[3], other)
    else:  # no overlap at this row: is the front edge where the ego is nearest?
        front = segment_box_distance_m(corners[0], corners[3], other) <= float(
            box_distance(corners, other)) + 1e-6
    return CollisionClass.ACTIVE_FRONT if front else CollisionClass.ACTIVE_LATERAL


def _replayed_into_ego(ctx: RunContext, row: int, nb: NeighbourColumns, k: int,
                       evidence: str, kind: CollisionClass) -> bool:
    """Whether neighbour row ``k`` is a replayed vehicle driving into the ego at trace
    row ``row`` (module doc: ``replayed_into_ego``)."""
    if k < 0 or int(nb.agent[k]) != AGENT_REPLAYED or kind == CollisionClass.UNCLASSIFIED:
        return False
    if kind == CollisionClass.STOPPED_EGO:
        return True
    corners = ctx.corners_m[row]
    other = box_corners(nb.x_m[k], nb.y_m[k], nb.heading_rad[k], nb.length_m[k], nb.width_m[k])
    if evidence == OVERLAP:
        return segment_hits_box(other[0], other[3], corners)
    return segment_box_distance_m(other[0], other[3], corners) <= float(
        box_distance(corners, other)) + 1e-6


def _at_fault(kind: CollisionClass, within_one_lane: bool) -> bool:
    if kind in (CollisionClass.ACTIVE_FRONT, CollisionClass.STOPPED_TRACK,
                CollisionClass.UNCLASSIFIED):
        return True
    return kind == CollisionClass.ACTIVE_LATERAL and not within_one_lane


def _delta_v(ctx: RunContext, row: int, nb: NeighbourColumns, k: int) -> float:
    ve = float(ctx.record.trace.ego.speed_mps[row])
    if k < 0:
        return 0.5 * ve
    vo = float(nb.speed_mps[k])
    dpsi = float(ctx.psi_rad[row]) - float(nb.heading_rad[k])
    return 0.5 * math.sqrt(max(ve * ve + vo * vo - 2.0 * ve * vo * math.cos(dpsi), 0.0))


def _event(ctx: RunContext, c: _Contact, nc: _NeighbourContacts, topology: LaneTopology,
           sumo: tuple[SumoEpisode, ...]) -> CollisionEvent:
    nb = ctx.record.neighbours
    row, k = c.row, c.nb_index
    if c.evidence == SWEPT:  # the last sample before the boxes touched
        row -= 1
        k = _nb_index(nc.rows, np.asarray(nb.id, dtype=object), row, c.other_id)
    kind = _kind(ctx, row, nb, k, c.evidence)
    if _replayed_into_ego(ctx, row, nb, k, c.evidence, kind) or (
            k >= 0 and _after_jump(ctx, nc.rows, c.other_id, float(ctx.t_s[c.row]))):
        kind = CollisionClass.REPLAYED_INTO_EGO
    within = topology.within_one_lane(ctx.corners_m[row])
    agreeing = [s for s in sumo if _agree(c, s, ctx.t_s)]
    first = agreeing[0] if agreeing else None
    return CollisionEvent(
        row=c.start, contact_row=c.row, last_row=c.last_row, t_s=float(ctx.t_s[c.start]),
        other_id=c.other_id, kind=kind, at_fault=_at_fault(kind, within),
        ego_speed_mps=float(ctx.record.trace.ego.speed_mps[row]),
        other_speed_mps=float(nb.speed_mps[k]) if k >= 0 else math.nan,
        other_stalled=bool(nb.stalled[k]) if k >= 0 else False,
        ego_within_one_lane=within, delta_v_mps=_delta_v(ctx, row, nb, k),
        evidence=c.evidence, sumo_role=first.role if first is not None else "",
        sumo_type=first.type if first is not None else "",
        sumo_reports=sum(s.reports for s in agreeing))


# ------------------------------------------------------------------ disagreements


def _lane_of(nb: NeighbourColumns, rows: IntColumn, row: int, vid: str) -> int:
    hit = np.flatnonzero((rows == row) & (np.asarray(nb.id, dtype=object) == vid))
    return int(nb.lane_index[hit[0]]) if hit.size else -1


def _sumo_only(ctx: RunContext, nc: _NeighbourContacts, s: SumoEpisode
               ) -> CollisionDisagreement:
    """A SUMO episode no collision explains, with the boxes' smallest distance over it."""
    nb = ctx.record.neighbours
    mine = (nc.rows >= s.row) & (nc.rows <= s.last_row) & \
        (np.asarray(nb.id, dtype=object) == s.other_id)
    gaps = box_distance(ctx.corners_m[nc.rows[mine]], nc.boxes[mine]) if np.any(mine) \
        else np.zeros(0)
    gaps = gaps[np.isfinite(gaps)]
    return CollisionDisagreement(
        kind=SUMO_ONLY, other_id=s.other_id, step=s.row, t_s=s.t_s, last_t_s=s.last_t_s,
        sumo_reports=s.reports, sumo_role=s.role, sumo_type=s.type,
        min_gap_m=float(gaps.min()) if gaps.size else math.nan,
        ego_lane_index=int(ctx.record.trace.ego.lane_index[s.row]),
        other_lane_index=_lane_of(nb, nc.rows, s.row, s.other_id))


def _geometry_only(ctx: RunContext, nc: _NeighbourContacts, e: CollisionEvent
                   ) -> CollisionDisagreement:
    return CollisionDisagreement(
        kind=GEOMETRY_ONLY, other_id=e.other_id, step=e.row, t_s=e.t_s,
        last_t_s=max(float(ctx.t_s[e.last_row]), e.t_s), min_gap_m=0.0,
        ego_lane_index=int(ctx.record.trace.ego.lane_index[e.contact_row]),
        other_lane_index=_lane_of(ctx.record.neighbours, nc.rows, e.contact_row, e.other_id))


def judge_collisions(ctx: RunContext) -> CollisionJudgement:
    """The collision episodes of a run (classified, module doc), SUMO's episodes beside
    them and every disagreement between the two, each in time order."""
    if ctx.n == 0:
        return CollisionJudgement()
    nc = neighbour_contacts(ctx)
    contacts = _recorded_contacts(ctx, nc)
    contacts += _monitor_contacts(ctx, nc.rows, contacts)
    contacts.sort(key=lambda c: (c.start, c.other_id))
    sumo = sumo_episodes(ctx)
    events: tuple[CollisionEvent, ...] = ()
    if contacts:
        topology = LaneTopology.of(ctx.record.road)  # only for runs that collided
        events = tuple(_event(ctx, c, nc, topology, sumo) for c in contacts)
    unexplained = [s for s in sumo if not any(_agree(c, s, ctx.t_s) for c in contacts)]
    disagreements = [_sumo_only(ctx, nc, s) for s in unexplained]
    disagreements += [_geometry_only(ctx, nc, e) for e in events if e.sumo_reports == 0]
    disagreements.sort(key=lambda d: (d.t_s, d.kind, d.other_id))
    return CollisionJudgement(events=events, sumo=sumo, disagreements=tuple(disagreements))


def classify_collisions(ctx: RunContext) -> tuple[CollisionEvent, ...]:
    """Every collision episode of a run, classified (module doc), in time order."""
    return judge_collisions(ctx).events


# ------------------------------------------------------------------ metrics


def _count(name: str, located: list[int], n: int) -> Measured:
    """A count located at its first item's row; increments 1 per item at its row."""
    inc = np.zeros(n)
    for row in located:
        inc[row] += 1.0
    return measured(name, float(len(located)), worst_step=min(located) if located else None,
                    increments=inc)


def _sumo_role_episodes(ctx: RunContext, role: str) -> float:
    """Episodes (per other vehicle, reports > EPISODE_GAP_S apart) of SUMO's report with
    the ego as ``role``."""
    times: dict[str, list[float]] = {}
    for t, hit in _sumo_trace_times(ctx):
        if (hit.collider == EGO_ID) == (role == "collider"):
            times.setdefault(_other(hit), []).append(t)
    count = 0
    for ts in times.values():
        ts.sort()
        count += 1 + sum(1 for a, b in zip(ts, ts[1:], strict=False) if b - a > EPISODE_GAP_S)
    return float(count)


COUNT_NAMES = ("collisions", "at_fault_collisions",
               *(f"collisions_{k.value}" for k in CollisionClass), "swept_only_collisions")
INFO_NAMES = ("sumo_collisions_as_collider", "sumo_collisions_as_victim",
              "collision_disagreements", "sumo_only_collisions", "geometry_only_collisions")


def _empty_metrics() -> list[Measured]:
    nan = float("nan")
    return [measured("collision", 0.0), measured("first_collision_t_s", nan),
            *(measured(name, nan) for name in (*COUNT_NAMES, *INFO_NAMES)),
            measured("first_at_fault_collision_t_s", nan),
            measured("max_at_fault_delta_v_mps", nan)]


def collision_metrics(ctx: RunContext, judgement: CollisionJudgement) -> list[Measured]:
    """The collision metrics of the module doc from :func:`judge_collisions`."""
    n = ctx.n
    if n == 0:
        return _empty_metrics()
    every = list(judgement.events)
    fault = [e for e in every if e.at_fault]
    first = every[0] if every else None
    once = [first.row] if first is not None else []
    out = [_count("collision", once, n),
           measured("first_collision_t_s", first.t_s if first is not None else math.nan,
                    worst_step=first.row if first is not None else None),
           _count("collisions", [e.row for e in every], n),
           _count("at_fault_collisions", [e.row for e in fault], n)]
    out += [_count(f"collisions_{k.value}", [e.row for e in every if e.kind == k], n)
            for k in CollisionClass]
    out.append(_count("swept_only_collisions", [e.row for e in every if e.evidence == SWEPT],
                      n))
    out += [measured(f"sumo_collisions_as_{role}", _sumo_role_episodes(ctx, role))
            for role in ("collider", "victim")]
    found = judgement.disagreements
    out.append(_count("collision_disagreements", [d.step for d in found], n))
    out += [_count(f"{kind}_collisions", [d.step for d in found if d.kind == kind], n)
            for kind in (SUMO_ONLY, GEOMETRY_ONLY)]
    worst = max(fault, key=lambda e: e.delta_v_mps) if fault else None
    out += [
        measured("first_at_fault_collision_t_s", fault[0].t_s if fault else math.nan,
                 worst_step=fault[0].row if fault else None),
        measured("max_at_fault_delta_v_mps", worst.delta_v_mps if worst else 0.0,
                 worst_step=worst.row if worst else None),
    ]
    return out
