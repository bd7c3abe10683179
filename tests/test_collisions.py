"""At-fault collisions as nuPlan classifies them (reports.metrics.collisions), on hand-made
typed records: one collision of every class, each classified and judged at fault or not;
the lane test (within one lane, across a junction, straddling two lanes, off the road);
episodes; the swept test between rows; SUMO's collider/victim beside each, and the
disagreements between SUMO's report and the boxes (listed, never counted when only SUMO
saw one); the default criterion."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from geometry_reference import box_corners, box_distance_reference, boxes_overlap
from synthetic_runs import (
    EGO,
    LANE_WIDTH_M,
    base_info,
    judge,
    kinematic_trace,
    make_record,
    straight_road,
    times,
)

from reports.metrics.collisions import (
    MONITOR,
    OVERLAP,
    SWEPT,
    CollisionClass,
    CollisionEvent,
    CollisionJudgement,
    classify_collisions,
    judge_collisions,
    segment_hits_box,
)
from reports.metrics.context import build_context
from reports.metrics.lane_occupancy import LaneTopology, points_in_lane
from reports.record import (
    LaneRecord,
    NeighbourColumns,
    RoadRecord,
    RunOutcome,
    RunRecord,
    SumoCollision,
)
from reports.record.verdict import GEOMETRY_ONLY, SUMO_ONLY, CollisionDisagreement

DT = 0.05
# the synthetic ego (4.6 m x 1.8 m, box centre at the CG) with its rear axle 1.4 m back
AXLE_EGO = dataclasses.replace(EGO, cg_to_rear_axle_m=1.4)


@dataclass(frozen=True)
class Other:
    """A vehicle moving at constant velocity along its heading: box centre at t = 0."""

    vid: str
    x0_m: float
    y_m: float
    speed_mps: float
    heading_rad: float = 0.0
    vy_mps: float = 0.0  # drift across the road (a cut-in)
    stalled: bool = False


def scene(ego_x0_m: float, ego_y_m: float, ego_speed_mps: float, others: Sequence[Other], *,
          duration_s: float = 3.0, ego_vy_mps: float = 0.0,
          sumo: tuple[SumoCollision, ...] = (), road: RoadRecord | None = None,
          ego_box: object = AXLE_EGO, neighbours: bool = True, dt_s: float = DT) -> RunRecord:
    """A record of the ego at constant speed along +X (drifting ``ego_vy_mps`` across) and
    ``others``, sampled every ``dt_s``; the monitor's overlap flags set where the boxes
    overlap (and SUMO's flags where ``sumo`` reports)."""
    t = times(duration_s, dt_s)
    n = len(t)
    x = ego_x0_m + ego_speed_mps * t
    y = ego_y_m + ego_vy_mps * t
    psi = np.full(n, math.atan2(ego_vy_mps, ego_speed_mps) if ego_speed_mps > 0 else 0.0)
    trace = kinematic_trace(t, x, y, psi, np.full(n, ego_speed_mps), r=np.zeros(n))
    parts = []
    ego_corners = box_corners(x, y, psi, EGO.length_m, EGO.width_m)
    for o in others:
        nb = NeighbourColumns.allocate(n)
        nb.step[:], nb.t_s[:], nb.id[:] = trace.step, t, o.vid
        nb.x_m[:] = o.x0_m + o.speed_mps * math.cos(o.heading_rad) * t
        nb.y_m[:] = o.y_m + o.speed_mps * math.sin(o.heading_rad) * t + o.vy_mps * t
        nb.heading_rad[:] = o.heading_rad
        nb.speed_mps[:] = math.hypot(o.speed_mps, o.vy_mps)
        nb.length_m[:], nb.width_m[:] = 4.6, 1.8
        nb.lane_index[:], nb.stalled[:] = 0, o.stalled
        overlap = boxes_overlap(ego_corners, box_corners(nb.x_m, nb.y_m, o.heading_rad, 4.6,
                                                         1.8))
        trace.safety.geom_collision |= overlap
        trace.safety.gap_vehicle[overlap] = o.vid
        parts.append(nb)
    trace.safety.sumo_collision[:] = False
    for hit in sumo:
        trace.safety.sumo_collision[int(np.argmin(np.abs(t - hit.t_s)))] = True
    nbs = NeighbourColumns(**{name: np.concatenate([getattr(p, name) for p in parts])
                              for name, _ in NeighbourColumns.allocate(0).columns()}) \
        if parts and neighbours else NeighbourColumns.allocate(0)
    info = base_info("collision", ego=ego_box, step_s=dt_s)
    return make_record(trace, info=info, road=road or straight_road(2000.0, n_lanes=3),
                       neighbours=nbs, outcome=RunOutcome(sim_time_s=float(t[-1]), wall_s=1.0,
                                                          steps=n, sumo_collisions=sumo))


def events(record: RunRecord) -> tuple[CollisionEvent, ...]:
    return classify_collisions(build_context(record))


def judged(record: RunRecord) -> CollisionJudgement:
    return judge_collisions(build_context(record))


def only(record: RunRecord) -> CollisionEvent:
    (event,) = events(record)
    return event


def first_contact_t(record: RunRecord) -> float:
    rows = np.flatnonzero(record.trace.safety.geom_collision)
    assert rows.size, "the hand-made scene has no contact"
    return float(record.trace.t_s[rows[0]])


# ------------------------------------------------------------------ one of every class


def test_active_front_rear_ending_a_slower_car_is_at_fault() -> None:
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)],
                sumo=(SumoCollision(2.1, "ego", "lead", "collision"),))
    e = only(rec)
    assert (e.kind, e.at_fault, e.other_id) == (CollisionClass.ACTIVE_FRONT, True, "lead")
    assert e.t_s == pytest.approx(first_contact_t(rec))
    assert e.ego_within_one_lane and e.geometric
    assert (e.sumo_role, e.sumo_type) == ("collider", "collision")
    assert e.delta_v_mps == pytest.approx(0.5 * 10.0)  # equal masses, same heading


def test_stopped_track_a_stalled_car_is_at_fault_even_from_the_side() -> None:
    # the ego drifts into a stalled car beside it: its side hits, yet the car stood still
    rec = scene(0.0, 0.0, 15.0, [Other("stalled0", 30.0, 2.6, 0.0, stalled=True)],
                ego_vy_mps=1.0)
    e = only(rec)
    assert (e.kind, e.at_fault, e.other_stalled) == (CollisionClass.STOPPED_TRACK, True, True)
    assert e.other_speed_mps == 0.0


def test_stopped_ego_hit_from_behind_is_not_at_fault() -> None:
    rec = scene(100.0, 0.0, 0.0, [Other("follower", 70.0, 0.0, 12.0)],
                sumo=(SumoCollision(2.2, "follower", "ego", "collision"),))
    e = only(rec)
    assert (e.kind, e.at_fault) == (CollisionClass.STOPPED_EGO, False)
    assert e.sumo_role == "victim"


def test_stopped_ego_comes_before_stopped_track() -> None:
    """nuPlan tests the ego first: both standing still is the ego's class."""
    rec = scene(0.0, 0.0, 0.0, [Other("parked", 3.0, 0.0, 0.0, stalled=True)], duration_s=0.5)
    assert only(rec).kind == CollisionClass.STOPPED_EGO


def test_active_rear_a_faster_car_from_behind_is_not_at_fault() -> None:
    rec = scene(50.0, 0.0, 15.0, [Other("fast", 20.0, 0.0, 25.0)])
    e = only(rec)
    assert (e.kind, e.at_fault) == (CollisionClass.ACTIVE_REAR, False)


def test_active_lateral_within_one_lane_is_not_at_fault() -> None:
    # the ego keeps the centre of lane 0; a car alongside in lane 1 cuts into it
    # (half a metre behind the ego's centre: its side, not its front edge, is hit)
    rec = scene(0.0, 0.0, 20.0, [Other("cutter", -0.5, LANE_WIDTH_M, 20.0, vy_mps=-1.5)])
    e = only(rec)
    assert (e.kind, e.ego_within_one_lane, e.at_fault) == (
        CollisionClass.ACTIVE_LATERAL, True, False)


def test_active_lateral_while_changing_lanes_is_at_fault() -> None:
    # the ego straddles lanes 0 and 1 on its way left and sideswipes a car in lane 1
    rec = scene(0.0, 1.0, 20.0, [Other("neighbour", -0.5, LANE_WIDTH_M + 0.3, 20.0)],
                ego_vy_mps=1.0)
    e = only(rec)
    assert (e.kind, e.ego_within_one_lane, e.at_fault) == (
        CollisionClass.ACTIVE_LATERAL, False, True)


def test_active_lateral_with_a_corner_off_the_road_is_at_fault() -> None:
    # one lane only: the ego drifts right off it into a car passing on the right verge
    road = straight_road(2000.0, n_lanes=1)
    rec = scene(0.0, -0.7, 20.0, [Other("verge", -0.5, -3.3, 20.0, vy_mps=0.6)], road=road,
                ego_vy_mps=-0.3)
    e = only(rec)
    assert (e.kind, e.ego_within_one_lane, e.at_fault) == (
        CollisionClass.ACTIVE_LATERAL, False, True)


def test_a_sumo_report_without_the_vehicle_is_no_collision_but_listed() -> None:
    """SUMO reports a vehicle the record never saw: nothing the boxes show, so no
    collision; the report is a 'sumo_only' disagreement without a gap (not recorded)."""
    rec = scene(0.0, 0.0, 20.0, [], sumo=(SumoCollision(1.0, "ego", "ghost", "collision"),))
    result = judged(rec)
    assert result.events == ()
    (d,) = result.disagreements
    assert (d.kind, d.other_id, d.sumo_reports, d.sumo_role) == (SUMO_ONLY, "ghost", 1,
                                                                 "collider")
    assert d.t_s == pytest.approx(1.0) and math.isnan(d.min_gap_m)
    assert rec.trace.t_s[d.step] == pytest.approx(1.0)


def test_monitor_overlap_without_recorded_neighbours_is_unclassified() -> None:
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)], neighbours=False)
    e = only(rec)
    assert (e.kind, e.at_fault, e.other_id, e.evidence) == (
        CollisionClass.UNCLASSIFIED, True, "lead", MONITOR)


def test_sumo_report_of_a_recorded_vehicle_the_boxes_do_not_touch_is_not_counted() -> None:
    """SUMO saw a collision (its lane-based, 1-D check) that the boxes do not show: a lead
    0.2 m ahead at the ego's speed, a car alongside 0.2 m across. Neither is a collision;
    each is listed with the boxes' smallest distance over SUMO's reports."""
    lead = scene(0.0, 0.0, 20.0, [Other("lead", 4.8, 0.0, 20.0)],
                 sumo=(SumoCollision(1.0, "ego", "lead", "collision"),
                       SumoCollision(1.1, "ego", "lead", "collision")))
    side = scene(0.0, 0.0, 20.0, [Other("side", -2.5, 2.0, 20.0)],
                 sumo=(SumoCollision(1.0, "side", "ego", "collision"),))
    for rec, vid, role, reports in ((lead, "lead", "collider", 2), (side, "side", "victim", 1)):
        result = judged(rec)
        assert result.events == ()
        (d,) = result.disagreements
        assert (d.kind, d.other_id, d.sumo_role, d.sumo_reports) == (SUMO_ONLY, vid, role,
                                                                     reports)
        assert d.min_gap_m == pytest.approx(0.2)  # 4.8 − 4.6 along, 2.0 − 1.8 across
        assert d.t_s == pytest.approx(1.0)
        v = judge(rec, {"max_collision": 0.0}).verdict
        assert v is not None
        assert v.value("collision") == 0.0 and v.value("at_fault_collisions") == 0.0
        assert not [f for f in v.failures if "collision" in f.criterion]
        assert v.value("sumo_only_collisions") == 1.0 and v.value("collision_disagreements") == 1
        assert v.value("sumo_collisions_reported") == reports
        assert v.collision_disagreements == result.disagreements


def test_sumo_time_is_taken_on_its_own_clock() -> None:
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)],
                sumo=(SumoCollision(102.0, "ego", "lead", "collision"),))
    rec = dataclasses.replace(rec, outcome=dataclasses.replace(rec.outcome,
                                                              sumo_t_origin_s=100.0))
    assert only(rec).sumo_role == "collider"  # 102 s on SUMO's clock is 2 s in the trace


def test_an_episode_is_located_at_its_earliest_geometric_evidence() -> None:
    """SUMO reported the collision 0.3 s before the boxes touched in the record: the report
    agrees with the collision (same vehicle, within 1 s) but does not locate it; the
    monitor's overlap flag 0.3 s early does."""
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)])
    contact = first_contact_t(rec)
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)],
                sumo=(SumoCollision(contact - 0.3, "ego", "lead", "collision"),))
    result = judged(rec)
    (e,) = result.events
    assert e.t_s == pytest.approx(contact) and e.contact_row == e.row
    assert e.kind == CollisionClass.ACTIVE_FRONT and e.evidence == OVERLAP
    assert (e.sumo_role, e.sumo_reports) == ("collider", 1)
    assert result.disagreements == ()
    v = judge(rec).verdict
    assert v is not None
    (fail,) = [f for f in v.failures if f.criterion == "max_at_fault_collisions"]
    assert fail.t_s == pytest.approx(v.value("first_collision_t_s")) == pytest.approx(contact)
    flagged = int(np.argmin(np.abs(rec.trace.t_s - (contact - 0.3))))
    rec.trace.safety.geom_collision[flagged] = True  # the monitor saw it first
    rec.trace.safety.gap_vehicle[flagged] = "lead"
    early = only(rec)
    assert early.t_s == pytest.approx(contact - 0.3)
    assert rec.trace.t_s[early.contact_row] == pytest.approx(contact)


# ------------------------------------------------------------------ the rear-axle test


def test_behind_is_measured_from_the_rear_axle() -> None:
    """A centre 158 deg off the heading seen from the CG is 148 deg from the rear axle:
    nuPlan (rear axle) calls the contact lateral; a record without the axle, rear."""
    ego_box = box_corners(0.0, 0.0, 0.0, EGO.length_m, EGO.width_m)
    other = box_corners(-4.0, 1.6, 0.0, 4.6, 1.8)
    assert boxes_overlap(ego_box, other)

    def at(ego: object) -> CollisionClass:
        rec = scene(-0.5, 0.0, 10.0, [Other("side", -4.5, 1.6, 10.0)], duration_s=0.1,
                    ego_box=ego)
        return only(rec).kind

    assert at(AXLE_EGO) == CollisionClass.ACTIVE_LATERAL
    assert at(EGO) == CollisionClass.ACTIVE_REAR  # no axle recorded: from the CG


def test_front_edge_segment_against_a_box() -> None:
    quad = box_corners(10.0, 0.0, 0.0, 4.0, 2.0)  # x 8..12, y -1..1
    assert segment_hits_box(np.array([8.0, -3.0]), np.array([8.0, 3.0]), quad)  # touches
    assert segment_hits_box(np.array([9.0, -3.0]), np.array([9.0, 3.0]), quad)  # crosses
    assert segment_hits_box(np.array([9.0, -0.5]), np.array([9.0, 0.5]), quad)  # inside
    assert not segment_hits_box(np.array([7.9, -3.0]), np.array([7.9, 3.0]), quad)
    assert not segment_hits_box(np.array([9.0, 1.1]), np.array([11.0, 3.0]), quad)


# ------------------------------------------------------------------ lanes


def _lane(lane_id: str, shape: list[list[float]], internal: bool = False) -> LaneRecord:
    return LaneRecord(id=lane_id, edge_id=lane_id.rsplit("_", 1)[0], index=0, width_m=3.5,
                      shape_xy_m=np.array(shape, dtype=np.float64), internal=internal)


def test_points_in_a_lane_polygon_flat_ends_round_joins() -> None:
    shape = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0]])  # a right-angle bend
    pts = np.array([[50.0, 1.74], [50.0, 1.76], [-0.1, 0.0], [101.7, -1.7], [101.0, -1.0],
                    [100.0, 50.0], [101.76, 50.0]])
    assert points_in_lane(pts, shape, 3.5).tolist() == [True, False, False, False, True,
                                                        True, False]


def test_within_one_lane_across_a_junction_and_not_across_two_lanes() -> None:
    road = RoadRecord(lanes=(
        _lane("E0_0", [[0.0, 0.0], [100.0, 0.0]]),
        _lane(":J0_0_0", [[100.0, 0.0], [110.0, 0.0]], internal=True),
        _lane("E1_0", [[110.0, 0.0], [400.0, 0.0]]),
        _lane("E0_1", [[0.0, 3.5], [100.0, 3.5]]),
        _lane("X_0", [[100.0, 30.0], [200.0, 30.0]]),  # far away, not connected
    ))
    topo = LaneTopology.of(road)
    ids = [ln.id for ln in topo.lanes]
    assert topo.outgoing[ids.index("E0_0")] == {ids.index(":J0_0_0")}
    assert topo.outgoing[ids.index(":J0_0_0")] == {ids.index("E1_0")}
    assert topo.incoming[ids.index("E0_0")] == frozenset()

    def box(x: float, y: float) -> np.ndarray:
        return box_corners(x, y, 0.0, 4.6, 1.8)

    assert topo.within_one_lane(box(50.0, 0.0))  # in E0_0
    assert topo.within_one_lane(box(99.0, 0.0))  # E0_0 and the junction lane
    assert topo.within_one_lane(box(108.0, 0.0))  # the junction lane and E1_0
    assert not topo.within_one_lane(box(50.0, 1.75))  # across E0_0 and E0_1
    assert not topo.within_one_lane(box(50.0, -1.2))  # right corners off the road
    assert not topo.within_one_lane(box(50.0, -20.0))  # all off the road


def test_lateral_contact_across_a_junction_inside_the_lane_is_not_at_fault() -> None:
    road = RoadRecord(lanes=(
        _lane("E0_0", [[-200.0, 0.0], [30.0, 0.0]]),
        _lane(":J0_0_0", [[30.0, 0.0], [32.0, 0.0]], internal=True),
        _lane("E1_0", [[32.0, 0.0], [600.0, 0.0]]),
        _lane("E0_1", [[-200.0, 3.5], [30.0, 3.5]]),
        _lane(":J0_1_0", [[30.0, 3.5], [32.0, 3.5]], internal=True),
        _lane("E1_1", [[32.0, 3.5], [600.0, 3.5]]),
    ), reference_xy_m=np.array([[-200.0, 0.0], [600.0, 0.0]]), reference_length_m=800.0,
        route=("E0", "E1"))
    # contact at x ~ 31: the ego's box spans E0_0, the junction lane and E1_0
    rec = scene(14.0, 0.0, 20.0, [Other("cutter", 13.5, 3.0, 20.0, vy_mps=-1.5)], road=road,
                duration_s=1.5)
    e = only(rec)
    assert e.kind == CollisionClass.ACTIVE_LATERAL
    x = float(rec.trace.ego.x_m[e.row])
    assert 29.5 < x < 30.5  # the box spans x 27.2 .. 32.8: E0_0, the junction, E1_0
    corners = build_context(rec).corners_m[e.row]
    lanes = LaneTopology.of(road).lanes_of(corners)
    assert not frozenset.intersection(*lanes)  # no one lane holds all four corners
    assert e.ego_within_one_lane and not e.at_fault


# ------------------------------------------------------------------ episodes


def test_one_episode_per_contact_first_contact_counts() -> None:
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)], duration_s=4.0)
    e = only(rec)  # many overlapping rows, one collision
    assert int(np.sum(rec.trace.safety.geom_collision)) > 10
    assert e.last_row > e.row


def _touching(windows: Sequence[tuple[float, float]]) -> RunRecord:
    """A car alongside at the ego's speed, overlapping it only within ``windows`` [s]
    (5 m further left otherwise)."""
    rec = scene(0.0, 0.0, 20.0, [Other("side", -2.5, 1.5, 20.0)], duration_s=4.0)
    nb = rec.neighbours
    inside = np.zeros(len(nb), dtype=bool)
    for a, b in windows:
        inside |= (nb.t_s >= a) & (nb.t_s <= b)
    nb.y_m[~inside] += 5.0
    rec.trace.safety.geom_collision[:] = False  # the monitor agrees: flag only the windows
    for a, b in windows:
        rec.trace.safety.geom_collision |= (rec.trace.t_s >= a) & (rec.trace.t_s <= b)
    return rec


def test_separate_contacts_more_than_a_second_apart_are_two_episodes() -> None:
    two = events(_touching([(1.0, 1.3), (2.8, 3.0)]))
    assert [e.t_s for e in two] == pytest.approx([1.0, 2.8])
    assert [e.kind for e in two] == [CollisionClass.ACTIVE_LATERAL] * 2
    (one,) = events(_touching([(1.0, 1.3), (1.8, 2.0)]))  # 0.5 s apart: one episode
    assert one.t_s == pytest.approx(1.0) and one.last_row > one.row


def test_two_vehicles_two_collisions() -> None:
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0),
                                 Other("fast", -40.0, 0.0, 40.0)], duration_s=3.0)
    kinds = {e.other_id: e.kind for e in events(rec)}
    assert kinds == {"lead": CollisionClass.ACTIVE_FRONT, "fast": CollisionClass.ACTIVE_REAR}


# ------------------------------------------------------------------ metrics and criteria


def test_metrics_count_by_class_and_the_default_criterion_is_at_fault() -> None:
    front = judge(scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)],
                        sumo=(SumoCollision(2.0, "ego", "lead", "collision"),)))
    v = front.verdict
    assert v is not None
    assert v.value("collision") == 1.0 and v.value("collisions") == 1.0
    assert v.value("at_fault_collisions") == 1.0
    assert v.value("collisions_active_front") == 1.0
    assert v.value("collisions_active_rear") == 0.0
    assert v.value("sumo_collisions_as_collider") == 1.0
    assert v.value("sumo_collisions_as_victim") == 0.0
    assert v.value("max_at_fault_delta_v_mps") == pytest.approx(5.0)
    (fail,) = [f for f in v.failures if f.criterion == "max_at_fault_collisions"]
    assert fail.metric == "at_fault_collisions" and fail.step == only(front).row
    assert fail.t_s == pytest.approx(v.value("first_at_fault_collision_t_s"))
    assert v.criteria["max_collision"] is None  # off by default, still available

    rear = judge(scene(50.0, 0.0, 15.0, [Other("fast", 20.0, 0.0, 25.0)],
                       sumo=(SumoCollision(2.0, "fast", "ego", "collision"),)))
    v = rear.verdict
    assert v is not None
    assert v.value("collision") == 1.0 and v.value("collisions_active_rear") == 1.0
    assert v.value("at_fault_collisions") == 0.0
    assert v.value("sumo_collisions_as_victim") == 1.0
    assert math.isnan(v.value("first_at_fault_collision_t_s"))
    assert not [f for f in v.failures if "collision" in f.criterion]
    strict = judge(rear.__class__(**{**rear.__dict__, "verdict": None}),
                   {"max_collision": 0.0})
    assert strict.verdict is not None
    assert [f.criterion for f in strict.verdict.failures if "collision" in f.criterion] == [
        "max_collision"]


def test_no_collision_no_counts_and_nan_without_rows() -> None:
    v = judge(scene(0.0, 0.0, 20.0, [Other("far", 200.0, 0.0, 20.0)])).verdict
    assert v is not None and v.value("collisions") == 0.0
    assert v.value("at_fault_collisions") == 0.0 and v.value("max_at_fault_delta_v_mps") == 0.0
    empty = judge(make_record(None)).verdict
    assert empty is not None and math.isnan(empty.value("at_fault_collisions"))


def test_every_collision_is_in_the_counts() -> None:
    """Whatever the scene, collision == 1 exactly when some episode was found."""
    rng = np.random.default_rng(5)
    for _ in range(40):
        others = [Other(f"v{k}", float(rng.uniform(-40, 60)), float(rng.choice([0.0, 3.5])),
                        float(rng.uniform(0, 30)), vy_mps=float(rng.uniform(-1, 1)))
                  for k in range(3)]
        v = judge(scene(0.0, float(rng.uniform(-0.5, 2.0)), float(rng.uniform(0, 30)),
                        others)).verdict
        assert v is not None
        assert (v.value("collision") == 1.0) == (v.value("collisions") >= 1.0)
        assert v.value("collisions") == sum(
            v.value(f"collisions_{k.value}") for k in CollisionClass)


# ------------------------------------------------------------------ SUMO beside the boxes


def test_a_collision_sumo_also_reports_agrees_and_is_not_listed() -> None:
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)],
                sumo=(SumoCollision(2.1, "ego", "lead", "collision"),
                      SumoCollision(2.2, "ego", "lead", "collision")))
    result = judged(rec)
    (e,) = result.events
    assert (e.sumo_role, e.sumo_reports) == ("collider", 2)
    (s,) = result.sumo
    assert (s.other_id, s.reports, s.role) == ("lead", 2, "collider")
    assert result.disagreements == ()


def test_a_side_swipe_sumo_did_not_report_is_counted_and_listed() -> None:
    """The lateral contact SUMO's lane-based check misses: counted (the boxes overlap),
    listed as 'geometry_only' at the collision's row with no gap."""
    rec = scene(0.0, 1.0, 20.0, [Other("neighbour", -0.5, LANE_WIDTH_M + 0.3, 20.0)],
                ego_vy_mps=1.0)
    result = judged(rec)
    (e,) = result.events
    (d,) = result.disagreements
    assert (d.kind, d.other_id, d.step, d.sumo_reports, d.sumo_role) == (
        GEOMETRY_ONLY, "neighbour", e.row, 0, "")
    assert d.min_gap_m == 0.0 and d.t_s == pytest.approx(e.t_s)
    v = judge(rec).verdict
    assert v is not None
    assert v.value("collisions") == 1.0 and v.value("at_fault_collisions") == 1.0
    assert v.value("geometry_only_collisions") == 1.0 and v.value("sumo_only_collisions") == 0


def test_sumo_reports_a_second_apart_are_one_listing_further_apart_two() -> None:
    side = [Other("side", -2.5, 2.0, 20.0)]  # 0.2 m across, never touching
    burst = tuple(SumoCollision(1.0 + 0.1 * k, "side", "ego", "collision") for k in range(5))
    (one,) = judged(scene(0.0, 0.0, 20.0, side, sumo=burst)).disagreements
    assert one.sumo_reports == 5
    assert (one.t_s, one.last_t_s) == (pytest.approx(1.0), pytest.approx(1.4))
    later = burst + (SumoCollision(2.6, "ego", "side", "collision"),)
    two = judged(scene(0.0, 0.0, 20.0, side, sumo=later)).disagreements
    assert [(d.t_s, d.sumo_reports, d.sumo_role) for d in two] == [
        (pytest.approx(1.0), 5, "victim"), (pytest.approx(2.6), 1, "collider")]


def test_a_report_far_from_the_contact_is_both_listings() -> None:
    """The boxes touch the lead at ~2 s; SUMO reports it at 0.2 s only: they do not agree
    (more than 1 s apart), so SUMO's is 'sumo_only' and the contact 'geometry_only'."""
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)],
                sumo=(SumoCollision(0.2, "ego", "lead", "collision"),))
    result = judged(rec)
    assert len(result.events) == 1
    assert [d.kind for d in result.disagreements] == [SUMO_ONLY, GEOMETRY_ONLY]
    assert result.disagreements[0].min_gap_m == pytest.approx(25.0 - 4.6 - 10.0 * 0.2, rel=1e-9)


def test_a_sumo_flag_without_its_report_is_listed_unnamed() -> None:
    rec = scene(0.0, 0.0, 20.0, [])
    rec.trace.safety.sumo_collision[10] = True
    (d,) = judged(rec).disagreements
    assert (d.kind, d.other_id, d.step, d.sumo_reports, d.sumo_role) == (SUMO_ONLY, "", 10, 1,
                                                                         "")


def test_the_rerun_fixture_collision_agrees_and_without_its_overlap_is_sumo_only() -> None:
    """rerun_fixtures' collision: the monitor flags an overlap (rows 100-104, no vehicle
    named) and SUMO reports stalled0 at row 101: one collision, agreeing. Without the
    monitor's flags only SUMO's report is left: no collision, one listing with the
    boxes' distance at row 101."""
    import rerun_fixtures as rf

    rec = rf.make_record(collision=True)
    v = rec.verdict
    assert v is not None
    assert v.value("collision") == 1.0 and v.value("collisions_unclassified") == 1.0
    assert v.collision_disagreements == ()
    rec.trace.safety.geom_collision[:] = False
    rec = judge(dataclasses.replace(rec, verdict=None))
    v = rec.verdict
    assert v is not None
    assert v.value("collision") == 0.0 and v.value("at_fault_collisions") == 0.0
    (d,) = v.collision_disagreements
    assert (d.kind, d.other_id, d.step, d.sumo_role, d.sumo_reports) == (
        SUMO_ONLY, "stalled0", 101, "collider", 1)
    ego = build_context(rec).corners_m[101]
    stalled = box_corners(rf.STALLED_X, rf.LANE_Y[1], 0.0, 4.5, 1.8)
    assert d.min_gap_m == pytest.approx(float(box_distance_reference(ego, stalled)))
    assert d.ego_lane_index == int(rec.trace.ego.lane_index[101]) and d.other_lane_index == 1
    assert v.status == "pass"  # the fixture passes every other criterion


def test_disagreements_round_trip_through_run_json(tmp_path: Path) -> None:
    from synthetic_runs import write_judged

    from reports.record import load_run

    rec = scene(0.0, 0.0, 20.0, [Other("side", -2.5, 2.0, 20.0)],
                sumo=(SumoCollision(1.0, "side", "ego", "collision"),))
    write_judged(rec, tmp_path / "run")
    back = load_run(tmp_path / "run", trace=False, neighbours=False, arrays=False,
                    series=False)
    assert back.verdict is not None
    (d,) = back.verdict.collision_disagreements
    assert isinstance(d, CollisionDisagreement)
    assert d == judged(rec).disagreements[0]


def test_a_disagreement_is_validated() -> None:
    ok = CollisionDisagreement(SUMO_ONLY, "s0", 3, 1.0, 1.5, sumo_reports=2,
                               sumo_role="victim", min_gap_m=0.4)
    assert ok.min_gap_m == 0.4
    bad: list[dict[str, object]] = [
        {"kind": "both"}, {"sumo_role": "bystander"}, {"step": -1}, {"last_t_s": 0.5},
        {"t_s": math.nan}, {"min_gap_m": -0.1}, {"sumo_reports": 0},
        {"kind": GEOMETRY_ONLY}]  # geometry_only with SUMO's reports
    for change in bad:
        with pytest.raises(ValueError):
            dataclasses.replace(ok, **change)  # type: ignore[arg-type]


# ------------------------------------------------------------------ between two rows


def test_a_contact_between_two_rows_is_found_by_the_swept_test() -> None:
    """Sampled every 0.5 s at 20 m/s the ego moves 10 m a row: it drives through a
    stalled car (centre 5 m ahead, then 5 m behind) without an overlapping row. The
    swept test finds it, classified at the row before (stopped track: at fault); 2 m
    across (0.2 m of clearance) it finds nothing."""
    stalled = [Other("stalled0", 15.0, 0.0, 0.0, stalled=True)]
    rec = scene(0.0, 0.0, 20.0, stalled, duration_s=2.0, dt_s=0.5)
    assert not rec.trace.safety.geom_collision.any()
    e = only(rec)
    assert (e.evidence, e.kind, e.at_fault, e.other_id) == (SWEPT, CollisionClass.STOPPED_TRACK,
                                                            True, "stalled0")
    assert rec.trace.t_s[e.contact_row] == pytest.approx(1.0)  # ego at 20 m: 5 m past it
    v = judge(rec).verdict
    assert v is not None
    assert v.value("swept_only_collisions") == 1.0 and v.value("collision") == 1.0
    beside = [Other("stalled0", 15.0, 2.0, 0.0, stalled=True)]
    assert events(scene(0.0, 0.0, 20.0, beside, duration_s=2.0, dt_s=0.5)) == ()


def test_the_swept_test_adds_nothing_where_the_rows_overlap_or_stay_apart() -> None:
    """Every contact of the finely sampled scenes is an overlapping row; passing 0.2 m
    beside a car is no contact at any sampling."""
    rec = scene(0.0, 0.0, 20.0, [Other("lead", 25.0, 0.0, 10.0)], duration_s=4.0)
    assert only(rec).evidence == OVERLAP
    for dt in (0.05, 0.2, 0.5):
        close = scene(0.0, 0.0, 20.0, [Other("slow", 20.0, 2.0, 5.0)], duration_s=4.0,
                      dt_s=dt)
        assert events(close) == ()


# ------------------------------------------------------------------ the loop's stop rule


def _ego_at(x_m: float) -> object:
    from suite.run.ego import EgoState

    return EgoState(state=np.array([x_m, 0.0, 0.0, 10.0, 0.0, 0.0]), long_acc_mps2=0.0,
                    lat_acc_mps2=0.0, steer_rad=0.0, torque_nm=0.0, s_m=x_m, lat_m=0.0,
                    heading_err_rad=0.0)


def test_only_a_geometric_contact_stops_the_run() -> None:
    """The monitor: a SUMO report beside boxes 0.2 m apart is recorded, not a contact.
    The stop rule: SUMO's flag never starts the 0.5 s grace; an overlap ends the run
    0.5 s after it."""
    from controllers.behaviour.types import Traffic
    from controllers.plant.vehicle_model import VehicleParams
    from suite.run.safety import SafetyMonitor, SafetySample
    from suite.run.stop import COLLISION_GRACE_S, StandardStop
    from suite.world.protocol import Scene

    veh = VehicleParams()
    monitor = SafetyMonitor(veh)
    ego = _ego_at(100.0)
    centre = 100.0 + veh.cg_to_box_centre_m
    beside = Traffic(ids=("s0",), x_m=np.array([centre]),
                     y_m=np.array([0.5 * veh.width_m + 0.9 + 0.2]), heading_rad=np.zeros(1),
                     speed_mps=np.zeros(1), length_m=np.array([4.5]), width_m=np.array([1.8]),
                     lane_index=np.zeros(1, dtype=np.int64), road_id=("e",),
                     stalled=np.ones(1, dtype=bool))
    hit = (SumoCollision(5.0, "s0", "ego", "collision"),)
    sample = monitor.check(ego, Scene(t_s=5.0, traffic=beside, ego=None, collisions=hit))
    assert sample.sumo_collision and not sample.geom_collision and not sample.collided
    assert sample.min_gap_m == pytest.approx(0.2)

    stop = StandardStop(reference_length_m=10_000.0)
    sumo_only = SafetySample(0.2, "s0", geom_collision=False, sumo_collision=True)
    for k in range(40):  # 2 s of SUMO reports: the run goes on
        assert stop.check(5.0 + 0.05 * k, ego, sumo_only) is None
    contact = SafetySample(0.0, "s0", geom_collision=True, sumo_collision=False)
    assert stop.check(7.0, ego, contact) is None
    clear = SafetySample(1.0, "s0", geom_collision=False, sumo_collision=False)
    assert stop.check(7.0 + COLLISION_GRACE_S - 0.01, ego, clear) is None
    assert stop.check(7.0 + COLLISION_GRACE_S, ego, clear) is not None
