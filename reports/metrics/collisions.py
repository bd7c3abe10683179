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

import numpy as np

from reports.geometry import box_corners, box_distance
from reports.geometry.motion import jump_excess_mps
from reports.geometry.segments import segment_box_distance_m, segment_hits_box
from reports.metrics.collision_contacts import (
    _after_jump,
    _agree,
    _Contact,
    _monitor_contacts,
    _nb_index,
    _NeighbourContacts,
    _other,
    _recorded_contacts,
    _sumo_trace_times,
    neighbour_contacts,
    sumo_episodes,
)
from reports.metrics.collision_events import (
    BEHIND_ANGLE_RAD,
    EGO_ID,
    EPISODE_GAP_S,
    EVIDENCE,
    JUMP_AFTER_S,
    JUMP_EXCESS_MPS,
    JUMP_MAX_GAP_S,
    MONITOR,
    OVERLAP,
    STOPPED_SPEED_MPS,
    SUMO_MATCH_S,
    SWEPT,
    CollisionClass,
    CollisionEvent,
    CollisionJudgement,
    SumoEpisode,
)
from reports.metrics.context import RunContext
from reports.metrics.lane_occupancy import LaneTopology
from reports.metrics.values import Measured, measured
from reports.record import AGENT_REPLAYED, NeighbourColumns
from reports.record.columns import IntColumn
from reports.record.verdict import GEOMETRY_ONLY, SUMO_ONLY, CollisionDisagreement

__all__ = ["BEHIND_ANGLE_RAD", "COUNT_NAMES", "CollisionClass", "CollisionEvent",
           "CollisionJudgement", "EGO_ID", "EPISODE_GAP_S", "EVIDENCE", "INFO_NAMES",
           "JUMP_AFTER_S", "JUMP_EXCESS_MPS", "JUMP_MAX_GAP_S", "MONITOR", "OVERLAP",
           "STOPPED_SPEED_MPS", "SUMO_MATCH_S", "SWEPT", "SumoEpisode", "classify_collisions",
           "collision_metrics", "judge_collisions", "jump_excess_mps", "neighbour_contacts",
           "segment_box_distance_m", "segment_hits_box", "sumo_episodes"]


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
