"""Collisions classified as nuPlan's ``no_ego_at_fault_collisions`` metric does, with SUMO's
collider/victim report beside each.

Contacts and episodes
    At every trace row, the ego box (from the CG, yaw and ``info.ego``) is tested for
    overlap with the box of every recorded neighbour of that step (``neighbours.parquet``;
    separating axes, :func:`reports.metrics.geometry.boxes_overlap`). The contacts with
    one vehicle form one *episode* until the boxes have been apart for more than
    ``EPISODE_GAP_S`` (1 s); each episode is one collision, classified at its first
    contact row. (nuPlan counts one collision per track and run; the run stops 0.5 s
    after the first collision anyway.) An episode is *located* at its earliest evidence:
    its first contact, or an earlier overlap flag of the safety monitor with that
    vehicle (``safety.geom_collision`` where ``safety.gap_vehicle`` is it) or SUMO report
    with it, up to 1 s before; the collision metric and its criterion point there.

Classes, in nuPlan's order of tests, at the first contact row
    ``stopped_ego``      the ego's speed <= ``STOPPED_SPEED_MPS`` (0.05 m/s);
    ``stopped_track``    else the other vehicle's speed <= 0.05 m/s;
    ``active_rear``      else the other's box centre is behind the ego: the angle between
                         the ego's heading and the vector from its rear axle to that
                         centre exceeds 150 deg (the CG where the record has no axle);
    ``active_front``     else the ego's front edge (the segment front-left to front-right
                         corner) intersects the other box (for an episode known only
                         from SUMO's report, whose boxes do not touch in the record: the
                         front edge is the part of the ego nearest the other box);
    ``active_lateral``   otherwise;
    ``unclassified``     a collision the record cannot classify: SUMO reported one, or
                         the safety monitor flagged an overlap (``geom_collision``) or a
                         SUMO collision (``sumo_collision``), with a vehicle that is not
                         among the row's recorded neighbours (or none is named).

At fault (nuPlan: could have been prevented by the planner)
    ``active_front`` and ``stopped_track`` always; ``active_lateral`` when the ego is not
    within one lane at that row (:mod:`reports.metrics.lane_occupancy`: its four
    corners in one lane or in a lane and its continuation, on ``road.lanes`` with the
    internal junction lanes; a corner off every lane counts as not within one lane);
    ``unclassified`` too (conservative: what cannot be judged is not excused);
    ``stopped_ego`` and ``active_rear`` never.

SUMO's report (``outcome.sumo_collisions``, times on SUMO's clock: the trace time is
``t_s - outcome.sumo_t_origin_s``)
    A report with the episode's vehicle (collider or victim is the ego, the other one is
    that vehicle) from 1 s before its first contact to 1 s after its last gives the
    episode its ``sumo_role`` (``collider``: SUMO blames the ego; ``victim``) and
    ``sumo_type``; no such report: ''. Reports no episode explains become episodes of
    their own, at the trace row nearest in time, classified from that row's neighbours
    (``geometric`` = False).

Severity: nuPlan's ego delta-v with equal masses, 0.5 sqrt(v_e^2 + v_o^2 - 2 v_e v_o
cos(psi_e - psi_o)) [m/s] (the speed change of the ego in a perfectly plastic impact).

Metrics (counts [-] unless stated; NaN without trace rows)
    ``collisions`` every episode; ``at_fault_collisions`` the at-fault ones (cumulative:
    a criterion locates its first); ``collisions_<class>`` per class;
    ``sumo_collisions_as_collider`` / ``sumo_collisions_as_victim``: episodes SUMO
    reported with the ego in that role; ``first_at_fault_collision_t_s`` [s] (NaN if
    none); ``max_at_fault_delta_v_mps`` [m/s] (0 if none).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from reports.metrics.context import RunContext
from reports.metrics.geometry import box_corners, box_distance, boxes_overlap
from reports.metrics.lane_occupancy import LaneTopology
from reports.metrics.values import Measured, measured
from reports.record import NeighbourColumns, SumoCollision

STOPPED_SPEED_MPS = 0.05
BEHIND_ANGLE_RAD = math.radians(150.0)
EPISODE_GAP_S = 1.0
SUMO_MATCH_S = 1.0
EGO_ID = "ego"


class CollisionClass(StrEnum):
    """nuPlan's CollisionType, plus what a record cannot classify."""

    STOPPED_EGO = "stopped_ego"
    STOPPED_TRACK = "stopped_track"
    ACTIVE_REAR = "active_rear"
    ACTIVE_FRONT = "active_front"
    ACTIVE_LATERAL = "active_lateral"
    UNCLASSIFIED = "unclassified"


@dataclass(frozen=True)
class CollisionEvent:
    """One collision episode, judged at its first contact (see the module doc).

    ``row``/``t_s``: trace row and time [s] where the episode is located (its earliest
    evidence); ``contact_row``: the first contact, where it was classified (speeds [m/s]
    and ``ego_within_one_lane`` are taken there); ``last_row``: its last contact;
    ``geometric``: the boxes overlapped in the record (False: known from SUMO's report or
    the monitor's flag only); ``sumo_role``: 'collider', 'victim' or '' (SUMO did not
    report it)."""

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
    geometric: bool
    sumo_role: str = ""
    sumo_type: str = ""


@dataclass(frozen=True)
class _Contact:
    """An episode before classification: rows of first and last contact, the other
    vehicle, its neighbour row index at the first contact (-1: not recorded), and the
    row of the earliest evidence (``start``)."""

    row: int
    last_row: int
    other_id: str
    nb_index: int
    geometric: bool
    start: int


# ------------------------------------------------------------------ geometry


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


# ------------------------------------------------------------------ episodes


def _neighbour_rows(ctx: RunContext) -> tuple[np.ndarray, np.ndarray]:
    """(trace row per neighbour row, -1 where its step is no trace step; contact flag)."""
    nb = ctx.record.neighbours
    rows = np.full(len(nb), -1, dtype=np.int64)
    contact = np.zeros(len(nb), dtype=bool)
    if ctx.n == 0 or len(nb) == 0:
        return rows, contact
    steps = ctx.record.trace.step
    order = np.argsort(steps, kind="stable")
    pos = np.clip(np.searchsorted(steps[order], nb.step), 0, len(order) - 1)
    matched = order[pos]
    ok = steps[matched] == nb.step
    rows[ok] = matched[ok]
    boxes = box_corners(nb.x_m, nb.y_m, nb.heading_rad, nb.length_m, nb.width_m)
    ego = ctx.corners_m[np.where(ok, rows, 0)]
    finite = np.all(np.isfinite(boxes.reshape(len(nb), 8)), axis=1) & \
        np.all(np.isfinite(ego.reshape(len(nb), 8)), axis=1)
    contact = ok & finite & boxes_overlap(ego, boxes)
    return rows, contact


def _split_episodes(rows: list[int], t_s: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) row of each run of contact rows separated by > EPISODE_GAP_S."""
    out: list[tuple[int, int]] = []
    for row in sorted(set(rows)):
        if out and t_s[row] - t_s[out[-1][1]] <= EPISODE_GAP_S:
            out[-1] = (out[-1][0], row)
        else:
            out.append((row, row))
    return out


def _evidence_rows(ctx: RunContext, vid: str) -> list[int]:
    """Rows where the monitor flagged an overlap with ``vid`` or SUMO reported it."""
    safety = ctx.record.trace.safety
    flagged = safety.geom_collision & (np.asarray(safety.gap_vehicle, dtype=object) == vid)
    out = [int(r) for r in np.flatnonzero(flagged)]
    out += [int(np.argmin(np.abs(ctx.t_s - t))) for t, hit in _sumo_trace_times(ctx)
            if _other(hit) == vid]
    return out


def _geometric_contacts(ctx: RunContext, rows: np.ndarray, contact: np.ndarray
                        ) -> list[_Contact]:
    nb = ctx.record.neighbours
    by_vehicle: dict[str, dict[int, int]] = {}
    for k in np.flatnonzero(contact):
        by_vehicle.setdefault(str(nb.id[k]), {})[int(rows[k])] = int(k)
    out = []
    t_s = ctx.t_s
    for vid, row_to_nb in by_vehicle.items():
        evidence = _evidence_rows(ctx, vid)
        for first, last in _split_episodes(list(row_to_nb), t_s):
            earlier = [r for r in evidence
                       if t_s[first] - EPISODE_GAP_S <= t_s[r] <= t_s[first]]
            out.append(_Contact(first, last, vid, row_to_nb[first], True,
                                min([first, *earlier])))
    return out


def _nb_index(rows: np.ndarray, ids: np.ndarray, row: int, vid: str) -> int:
    hit = np.flatnonzero((rows == row) & (ids == vid))
    return int(hit[0]) if hit.size else -1


def _other(hit: SumoCollision) -> str:
    return hit.victim if hit.collider == EGO_ID else hit.collider


def _sumo_trace_times(ctx: RunContext) -> list[tuple[float, SumoCollision]]:
    origin = ctx.record.outcome.sumo_t_origin_s
    return [(float(h.t_s) - origin, h) for h in ctx.record.outcome.sumo_collisions
            if EGO_ID in (h.collider, h.victim)]


def _explained(contacts: list[_Contact], t_s: np.ndarray, vid: str | None, t: float) -> bool:
    return any((vid is None or c.other_id == vid)
               and t_s[c.row] - SUMO_MATCH_S <= t <= t_s[c.last_row] + SUMO_MATCH_S
               for c in contacts)


def _reported_contacts(ctx: RunContext, rows: np.ndarray, contacts: list[_Contact]
                       ) -> list[_Contact]:
    """Episodes known only from SUMO's report or the monitor's overlap flag."""
    nb = ctx.record.neighbours
    ids = np.asarray(nb.id, dtype=object)
    t_s = ctx.t_s
    found: dict[str, list[int]] = {}
    for t, hit in _sumo_trace_times(ctx):
        vid = _other(hit)
        if not _explained(contacts, t_s, vid, t):
            found.setdefault(vid, []).append(int(np.argmin(np.abs(t_s - t))))
    safety = ctx.record.trace.safety
    for row in np.flatnonzero(safety.geom_collision):
        vid = str(safety.gap_vehicle[row])  # the nearest vehicle: one the ego overlaps
        if not _explained(contacts, t_s, None, float(t_s[row])):
            found.setdefault(vid, []).append(int(row))
    reported = [t for t, _ in _sumo_trace_times(ctx)]
    for row in np.flatnonzero(safety.sumo_collision):  # a flag without its report
        t = float(t_s[row])
        if not reported or min(abs(t - r) for r in reported) > SUMO_MATCH_S:
            if not _explained(contacts, t_s, None, t):
                found.setdefault("", []).append(int(row))
    out = []
    for vid, vrows in found.items():
        for first, last in _split_episodes(vrows, t_s):
            out.append(_Contact(first, last, vid, _nb_index(rows, ids, first, vid), False,
                                first))
    return out


# ------------------------------------------------------------------ classification


def _rear_axle(ctx: RunContext, row: int) -> np.ndarray:
    ego = ctx.record.trace.ego
    back = ctx.record.info.ego.cg_to_rear_axle_m
    back = back if math.isfinite(back) else 0.0
    psi = float(ego.psi_rad[row])
    return np.array([ego.x_m[row] - back * math.cos(psi), ego.y_m[row] - back * math.sin(psi)])


def _kind(ctx: RunContext, row: int, nb: NeighbourColumns, k: int, geometric: bool
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
    if geometric:
        front = segment_hits_box(corners[0], corners[3], other)
    else:  # no contact in the record: is the front edge where the ego is nearest?
        front = segment_box_distance_m(corners[0], corners[3], other) <= float(
            box_distance(corners, other)) + 1e-6
    return CollisionClass.ACTIVE_FRONT if front else CollisionClass.ACTIVE_LATERAL


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


def _sumo_match(ctx: RunContext, c: _Contact) -> tuple[str, str]:
    t_first, t_last = float(ctx.t_s[c.row]), float(ctx.t_s[c.last_row])
    for t, hit in _sumo_trace_times(ctx):
        if _other(hit) == c.other_id and t_first - SUMO_MATCH_S <= t <= t_last + SUMO_MATCH_S:
            return ("collider" if hit.collider == EGO_ID else "victim"), hit.type
    return "", ""


def classify_collisions(ctx: RunContext) -> tuple[CollisionEvent, ...]:
    """Every collision episode of a run, classified (module doc), in time order."""
    if ctx.n == 0:
        return ()
    rows, contact = _neighbour_rows(ctx)
    contacts = _geometric_contacts(ctx, rows, contact)
    contacts += _reported_contacts(ctx, rows, contacts)
    if not contacts:
        return ()
    nb = ctx.record.neighbours
    topology = LaneTopology.of(ctx.record.road)  # only for runs that collided
    events = []
    for c in sorted(contacts, key=lambda c: (c.start, c.other_id)):
        kind = _kind(ctx, c.row, nb, c.nb_index, c.geometric)
        within = topology.within_one_lane(ctx.corners_m[c.row])
        role, sumo_type = _sumo_match(ctx, c)
        k = c.nb_index
        events.append(CollisionEvent(
            row=c.start, contact_row=c.row, last_row=c.last_row, t_s=float(ctx.t_s[c.start]),
            other_id=c.other_id,
            kind=kind, at_fault=_at_fault(kind, within),
            ego_speed_mps=float(ctx.record.trace.ego.speed_mps[c.row]),
            other_speed_mps=float(nb.speed_mps[k]) if k >= 0 else math.nan,
            other_stalled=bool(nb.stalled[k]) if k >= 0 else False,
            ego_within_one_lane=within, delta_v_mps=_delta_v(ctx, c.row, nb, k),
            geometric=c.geometric, sumo_role=role, sumo_type=sumo_type))
    return tuple(events)


# ------------------------------------------------------------------ metrics


def _count(name: str, events: list[CollisionEvent], n: int, first_step: bool = False
           ) -> Measured:
    inc = np.zeros(n)
    for e in events:
        inc[e.row] += 1.0
    return measured(name, float(len(events)), "-", "safety", "lower",
                    worst_step=events[0].row if (first_step and events) else None,
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


def collision_metrics(ctx: RunContext, events: tuple[CollisionEvent, ...]) -> list[Measured]:
    """The collision-class metrics of the module doc from :func:`classify_collisions`."""
    n = ctx.n
    names = ["collisions", "at_fault_collisions",
             *(f"collisions_{k.value}" for k in CollisionClass),
             "sumo_collisions_as_collider", "sumo_collisions_as_victim"]
    if n == 0:
        nan = float("nan")
        out = [measured(name, nan, "-", "safety", "lower") for name in names]
        return out + [measured("first_at_fault_collision_t_s", nan, "s", "safety", "none"),
                      measured("max_at_fault_delta_v_mps", nan, "m/s", "safety", "lower")]
    every = list(events)
    fault = [e for e in every if e.at_fault]
    out = [_count("collisions", every, n, first_step=True),
           _count("at_fault_collisions", fault, n, first_step=True)]
    out += [_count(f"collisions_{k.value}", [e for e in every if e.kind == k], n,
                   first_step=True) for k in CollisionClass]
    out += [measured(f"sumo_collisions_as_{role}", _sumo_role_episodes(ctx, role), "-",
                     "safety", "lower") for role in ("collider", "victim")]
    worst = max(fault, key=lambda e: e.delta_v_mps) if fault else None
    out += [
        measured("first_at_fault_collision_t_s", fault[0].t_s if fault else float("nan"), "s",
                 "safety", "none", worst_step=fault[0].row if fault else None),
        measured("max_at_fault_delta_v_mps", worst.delta_v_mps if worst else 0.0, "m/s",
                 "safety", "lower", worst_step=worst.row if worst else None),
    ]
    return out
