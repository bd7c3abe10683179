"""The behaviour layer on scripted scenes (pure numpy, no SUMO): lane plan, gap acceptance,
car following, obstacles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.behaviour.decision import BehaviourParams, EgoShape, LaneBehaviour
from controllers.behaviour.ellipses import ellipse_semi_axes
from controllers.behaviour.following import FollowParams, follow_speed_mps
from controllers.behaviour.lane_change import LaneChangeParams
from controllers.behaviour.perception import relative_lanes
from controllers.behaviour.types import (
    SIDE_FOLLOW,
    SIDE_LEFT,
    SIDE_NONE,
    SIDE_RIGHT,
    Decision,
    EgoFrenet,
    LaneCheck,
    LaneContext,
    LaneSlot,
    ObstaclePolicy,
    Reason,
    Side,
    Traffic,
)
from controllers.path.frenet import FrenetPath
from reports.geometry import box_corners, box_distance

W = 3.5
THREE_LANES = {i: LaneSlot(i, W, True, False) for i in range(3)}


def traffic(rows: list[tuple[str, float, float, float]], road: str = "e0",
            lanes: list[int] | None = None) -> Traffic:
    """rows: (id, x, y, speed) on a straight road along +X; 'stalled*' ids are stalled."""
    n = len(rows)
    return Traffic(
        ids=tuple(r[0] for r in rows), x_m=np.array([r[1] for r in rows], float),
        y_m=np.array([r[2] for r in rows], float), heading_rad=np.zeros(n),
        speed_mps=np.array([r[3] for r in rows], float), length_m=np.full(n, 4.8),
        width_m=np.full(n, 1.9),
        lane_index=np.array(lanes if lanes is not None else [-1] * n, dtype=np.int64),
        road_id=(road,) * n,
        stalled=np.array([r[0].startswith("stalled") for r in rows], dtype=bool))


@pytest.fixture(scope="module")
def path() -> FrenetPath:
    return FrenetPath.from_polyline(np.array([[0.0, 0.0], [3000.0, 0.0]]))


def behaviour(path: FrenetPath, shoulder: bool = False, **lane_change: float) -> LaneBehaviour:
    params = BehaviourParams(lane_change=LaneChangeParams(**lane_change))
    return LaneBehaviour(path, ObstaclePolicy(), EgoShape(4.8, 1.9, shoulder), W, params)


def at(b: LaneBehaviour, s: float, y: float, nb: Traffic, lanes: dict[int, LaneSlot],
       ref: int = 1, v: float = 25.0, t: float = 100.0, set_speed: float = 25.0) -> Decision:
    """The decision with the ego's CG at (s, y) at time t; lane i's centre at (i - ref) W."""
    slots = {i: LaneSlot(sl.index, sl.width_m, sl.allows_passenger, sl.is_shoulder,
                         offset_m=(i - ref) * W, continues_m=sl.continues_m)
             for i, sl in lanes.items()}
    return b.decide(EgoFrenet(s, y, s, y, v, t), nb, LaneContext(slots, ref), set_speed)


def test_ellipse_contains_the_box_sum_rectangle_with_margins() -> None:
    pol = ObstaclePolicy()
    a, b = ellipse_semi_axes(4.8, 1.9, 4.8, 1.9, pol)
    for dy in (1.9 + pol.offset_m, -(1.9 - pol.offset_m)):
        assert (4.8 / a) ** 2 + (dy / b) ** 2 <= 1.0 + 1e-12
    obstacle = box_corners(0.0, 0.0, 0.0, 4.8, 1.9)
    for ang in np.linspace(0, 2 * math.pi, 73):
        cx, cy = a * math.cos(ang), b * math.sin(ang) - pol.offset_m
        ego = box_corners(cx, cy, 0.0, 4.8, 1.9)
        assert float(box_distance(ego[None], obstacle[None])[0]) > 0.0


def test_an_empty_road_keeps_the_lane_at_the_set_speed(path: FrenetPath) -> None:
    d = at(behaviour(path), 100.0, 0.0, traffic([]), THREE_LANES)
    assert d.side == SIDE_NONE and d.obstacles.count == 0 and d.target_speed_mps == 25.0
    assert d.lateral_reference_m == 0.0


def test_a_stalled_car_ahead_is_passed_on_the_left(path: FrenetPath) -> None:
    d = at(behaviour(path), 100.0, 0.0, traffic([("stalled0", 200.0, 0.0, 0.0)]), THREE_LANES)
    assert d.side == SIDE_LEFT and d.reason_code is Reason.PASS
    assert d.reason.startswith("pass stalled0 on the left")
    assert d.lane_check(1) is LaneCheck.FREE
    assert d.lateral_reference_m == pytest.approx(W)
    assert d.obstacles.count == 1
    assert d.obstacles.y_m[0] == pytest.approx(-ObstaclePolicy().offset_m)  # shifted right
    # the ellipse names its vehicle, and the side is the enum with the trace's code
    assert d.obstacles.vehicle_ids == ("stalled0",) == d.obstacle_ids
    assert d.side is Side.LEFT and int(d.side) == 1 and d.pass_side == 1


def test_side_codes_and_validation() -> None:
    # the integers the trace has always recorded
    assert [int(s) for s in (Side.KEEP, Side.LEFT, Side.RIGHT, Side.FOLLOW)] == [0, 1, -1, 2]
    assert Side.FOLLOW.pass_side == 0 and Side.RIGHT.pass_side == -1
    assert Decision(side=2).side is Side.FOLLOW  # an int is taken as its Side
    with pytest.raises(ValueError):
        Decision(side=3)
    with pytest.raises(ValueError):
        Decision(reason_code="bored")


def test_a_car_alongside_on_the_left_sends_the_pass_right(path: FrenetPath) -> None:
    nb = traffic([("stalled0", 200.0, 0.0, 0.0), ("car", 102.0, W, 25.0)])
    d = at(behaviour(path), 100.0, 0.0, nb, THREE_LANES)
    assert d.side == SIDE_RIGHT and d.reason_code is Reason.PASS
    assert d.lateral_reference_m == pytest.approx(-W)


def test_no_free_side_follows_the_stalled_car(path: FrenetPath) -> None:
    nb = traffic([("stalled0", 200.0, 0.0, 0.0), ("carL", 101.0, W, 25.0),
                  ("carR", 98.0, -W, 25.0)])
    d = at(behaviour(path), 100.0, 0.0, nb, THREE_LANES)
    assert d.side == SIDE_FOLLOW and d.reason_code is Reason.FOLLOW
    left, right = d.lane_check(1), d.lane_check(-1)
    assert left is not None and left.gap_too_short and right is not None and right.gap_too_short
    assert d.target_speed_mps < 25.0
    blocker = list(d.obstacle_ids).index("stalled0")
    # A wall across the carriageway: no way round and no sideways push.
    assert d.obstacles.semi_b_m[blocker] == pytest.approx(10.0 * W)


def test_a_fast_car_closing_from_behind_in_the_target_lane_blocks_the_change(
        path: FrenetPath) -> None:
    # A car at 35 m/s against the ego's 25 in the left lane: 40 m bumper gap behind, it
    # sheds the 10 m/s within the 36 m beyond the 4 m standstill at 1.4 m/s² (fine); at
    # 25 m it needs 100 / (2 * 21.2) = 2.4 m/s², more than the 2 m/s² bound (MOBIL).
    # (The stalled car is far enough to stop for comfortably: not an evasive change.)
    ok = at(behaviour(path), 100.0, 0.0,
            traffic([("stalled0", 270.0, 0.0, 0.0), ("fast", 55.2, W, 35.0)]), THREE_LANES)
    assert ok.side == SIDE_LEFT and not ok.evasive
    no = at(behaviour(path), 100.0, 0.0,
            traffic([("stalled0", 270.0, 0.0, 0.0), ("fast", 70.0, W, 35.0)]), THREE_LANES)
    assert no.side == SIDE_RIGHT and no.lane_check(1) is LaneCheck.CLOSING_FROM_BEHIND
    assert no.lane_check(-1) is LaneCheck.FREE


def test_an_evasive_change_accepts_a_follower_braking_harder(path: FrenetPath) -> None:
    # 40 m behind a stalled car at 25 m/s: stopping would need 625 / (2 * 35.2) = 8.9
    # m/s², so passing is evasive; the fast car's 2.4 m/s² (above the 2 m/s² bound of an
    # ordinary change) is within the evasive bound of 4.5 m/s²: the ego goes left.
    d = at(behaviour(path), 100.0, 0.0,
           traffic([("stalled0", 145.0, 0.0, 0.0), ("fast", 70.0, W, 35.0)]), THREE_LANES)
    assert d.side == SIDE_LEFT and d.evasive
    # The speed target no longer brakes for the car being evaded.
    assert d.target_speed_mps == 25.0


def test_an_evasive_change_carries_on_when_aborting_is_worse(path: FrenetPath) -> None:
    b = behaviour(path)
    nb = traffic([("stalled0", 145.0, 0.0, 0.0)])
    assert at(b, 100.0, 0.0, nb, THREE_LANES).evasive
    # 0.8 m into the move a car closes fast from behind in the left lane (16 m, 12 m/s
    # faster: 144 / (2 * 15) = 4.7 m/s² for it, beyond every bound); stopping for the
    # stalled car 24 m ahead would need 625 / (2 * 23) = 13.5 m/s²: carry on.
    closing = traffic([("stalled0", 145.0, 0.0, 0.0), ("fast", 95.0, W, 37.0)])
    d = at(b, 116.0, 0.8, closing, THREE_LANES, t=100.7)
    assert d.side == SIDE_LEFT and d.reason_code is not Reason.ABORT, d.reason
    # An ordinary change in the same gap is aborted.
    b2 = behaviour(path)
    far = traffic([("stalled0", 270.0, 0.0, 0.0)])
    assert at(b2, 100.0, 0.0, far, THREE_LANES).side == SIDE_LEFT
    d2 = at(b2, 116.0, 0.8, traffic([("stalled0", 270.0, 0.0, 0.0), ("fast", 95.0, W, 37.0)]),
            THREE_LANES, t=100.7)
    assert d2.reason_code is Reason.ABORT and d2.side == SIDE_NONE, d2.reason


def test_minimal_risk_braking_known_answers() -> None:
    from controllers.behaviour.types import Obstacles
    from controllers.two_loop.fallback import most_urgent_obstacle
    x0 = np.array([100.0, 0.0, 0.0])
    obs = Obstacles(s_m=np.array([150.0, 130.0]), y_m=np.array([0.0, 3.5]),
                    speed_s_mps=np.array([0.0, 0.0]), speed_y_mps=np.zeros(2),
                    semi_a_m=np.array([10.0, 10.0]), semi_b_m=np.array([2.5, 2.5]))
    # Only the first covers the ego's offset: 20² / (2 (50 - 10)) = 5 m/s².
    assert most_urgent_obstacle(x0, 20.0, obs)[0] == pytest.approx(5.0)
    # Closing on a moving ellipse: (20 - 10)² / (2 * 40).
    moving = Obstacles(s_m=obs.s_m, y_m=obs.y_m, speed_s_mps=np.array([10.0, 0.0]),
                       speed_y_mps=np.zeros(2), semi_a_m=obs.semi_a_m, semi_b_m=obs.semi_b_m)
    assert most_urgent_obstacle(x0, 20.0, moving)[0] == pytest.approx(1.25)
    assert most_urgent_obstacle(np.array([145.0, 0.0, 0.0]), 5.0, obs)[0] == math.inf
    assert most_urgent_obstacle(x0, 20.0, Obstacles.empty())[0] == 0.0


def test_inside_an_ellipse_the_braking_need_uses_the_bumper_gap() -> None:
    """A car merging in with its rear 4 m ahead of the ego's front, 1 m/s slower: the
    ego's CG is inside its ellipse (inf without the policy); with it, the need is
    1² / (2 (4 - 1)) m/s² (standstill 1 m), and a closing stopped car 0.5 m ahead is inf.
    Far ahead the ellipse's distance is kept; just outside the ellipse the distance is
    its margin over the box sum, A - a - 1, continuous with the bumper gap inside."""
    from controllers.behaviour.ellipses import box_half_length_m, ellipse_semi_axes
    from controllers.behaviour.types import ObstaclePolicy, Obstacles
    from controllers.two_loop.fallback import most_urgent_obstacle
    policy = ObstaclePolicy(margin_long_m=2.0, margin_lat_m=0.4, offset_m=0.3)
    sa, sb = ellipse_semi_axes(4.6, 1.8, 4.6, 1.8, policy)
    assert box_half_length_m(np.array([sa]), np.array([sb]), policy) == pytest.approx([4.6])
    x0 = np.array([100.0, 0.0, 0.0])
    merge = Obstacles(s_m=np.array([100.0 + 4.6 + 4.0]), y_m=np.zeros(1),
                      speed_s_mps=np.array([21.0]), speed_y_mps=np.zeros(1),
                      semi_a_m=np.array([sa]), semi_b_m=np.array([sb]))
    assert most_urgent_obstacle(x0, 22.0, merge)[0] == math.inf
    assert most_urgent_obstacle(x0, 22.0, merge, policy, 1.0)[0] == pytest.approx(1.0 / 6.0)
    stopped = Obstacles(s_m=np.array([100.0 + 4.6 + 0.5]), y_m=np.zeros(1),
                        speed_s_mps=np.zeros(1), speed_y_mps=np.zeros(1),
                        semi_a_m=np.array([sa]), semi_b_m=np.array([sb]))
    assert most_urgent_obstacle(x0, 5.0, stopped, policy, 1.0)[0] == math.inf
    far = Obstacles(s_m=np.array([160.0]), y_m=np.zeros(1), speed_s_mps=np.zeros(1),
                    speed_y_mps=np.zeros(1), semi_a_m=np.array([sa]), semi_b_m=np.array([sb]))
    assert most_urgent_obstacle(x0, 20.0, far, policy, 1.0)[0] == pytest.approx(
        400.0 / (2.0 * (60.0 - sa)))
    for ds_m, d_m in ((sa + 0.5, sa - 4.6 - 1.0), (sa - 1e-9, sa - 4.6 - 1.0),
                      (4.6 + 2.0, 1.0)):
        near = Obstacles(s_m=np.array([100.0 + ds_m]), y_m=np.zeros(1),
                         speed_s_mps=np.zeros(1), speed_y_mps=np.zeros(1),
                         semi_a_m=np.array([sa]), semi_b_m=np.array([sb]))
        assert most_urgent_obstacle(x0, 2.0, near, policy, 1.0)[0] == pytest.approx(
            4.0 / (2.0 * d_m)), ds_m


def test_a_slower_car_in_the_passing_lane_is_followed_not_passed(path: FrenetPath) -> None:
    # The ego's lane has a car at 20 m/s; so has the left lane (and the right lane is a
    # shoulder): nothing is gained by changing: follow, no lane change.
    lanes = {0: LaneSlot(0, 3.0, False, True), 1: LaneSlot(1, W, True, False),
             2: LaneSlot(2, W, True, False)}
    nb = traffic([("slow", 140.0, 0.0, 20.0), ("slowL", 160.0, W, 20.0)])
    d = at(behaviour(path), 100.0, 0.0, nb, lanes)
    assert d.side == SIDE_FOLLOW and d.lateral_reference_m == 0.0
    assert d.target_speed_mps < 25.0
    assert d.reason_code is Reason.FOLLOW


def test_shoulder_only_when_allowed(path: FrenetPath) -> None:
    lanes = {0: LaneSlot(0, 3.0, False, True), 1: LaneSlot(1, W, True, False),
             2: LaneSlot(2, W, True, False)}
    nb = traffic([("stalled0", 200.0, 0.0, 0.0), ("carL", 101.0, W, 25.0)])
    refused = at(behaviour(path, shoulder=False), 100.0, 0.0, nb, lanes)
    assert refused.side == SIDE_FOLLOW
    assert refused.lane_check(-1) is LaneCheck.SHOULDER_NOT_ALLOWED
    allowed = at(behaviour(path, shoulder=True), 100.0, 0.0, nb, lanes)
    assert allowed.side == SIDE_RIGHT and allowed.lane_check(-1) is LaneCheck.FREE
    # The lateral reference is the shoulder's centre: half of 3.5 + 3.0 to the right.
    assert allowed.lateral_reference_m == pytest.approx(-W)


def test_missing_barred_and_ending_lanes_are_not_used(path: FrenetPath) -> None:
    lanes = {0: LaneSlot(0, W, False, False), 1: LaneSlot(1, W, True, False)}
    d = at(behaviour(path), 100.0, 0.0, traffic([("stalled0", 200.0, 0.0, 0.0)]), lanes)
    assert d.side == SIDE_FOLLOW
    assert d.lane_check(1) is LaneCheck.NO_LANE
    assert d.lane_check(-1) is LaneCheck.BARS_PASSENGER
    ending = {1: LaneSlot(1, W, True, False), 2: LaneSlot(2, W, True, False, continues_m=80.0)}
    e = at(behaviour(path), 100.0, 0.0, traffic([("stalled0", 200.0, 0.0, 0.0)]), ending)
    assert e.side == SIDE_FOLLOW and e.lane_check(1) is LaneCheck.ENDS


def test_a_change_aborts_before_the_commit_point_and_not_after(path: FrenetPath) -> None:
    b = behaviour(path)
    first = at(b, 100.0, 0.0, traffic([("stalled0", 200.0, 0.0, 0.0)]), THREE_LANES)
    assert first.side == SIDE_LEFT
    danger = traffic([("stalled0", 200.0, 0.0, 0.0), ("fast", 95.0, W, 40.0)])
    early = at(b, 101.0, 1.0, danger, THREE_LANES, t=100.1)  # 1.0 of 3.5 m: before commit
    assert early.reason_code is Reason.ABORT and early.lateral_reference_m == 0.0
    b2 = behaviour(path)
    at(b2, 100.0, 0.0, traffic([("stalled0", 200.0, 0.0, 0.0)]), THREE_LANES)
    late = at(b2, 101.0, 2.5, danger, THREE_LANES, t=100.1)  # past half the lateral move
    assert late.side == SIDE_LEFT and late.lateral_reference_m == pytest.approx(W)


def test_cars_two_lanes_away_are_not_obstacles(path: FrenetPath) -> None:
    d = at(behaviour(path), 100.0, 0.0, traffic([("far", 130.0, 2 * W, 20.0)]), THREE_LANES,
           ref=0)
    assert d.obstacles.count == 0


def test_follow_law_known_answers() -> None:
    p = FollowParams(time_gap_s=1.8, standstill_m=6.0, gap_close_s=3.0, comfort_decel_mps2=2.0)
    # At the desired gap (6 + 1.8 * 20 = 42 m) behind a car at 20 m/s: its speed.
    assert follow_speed_mps(42.0, 20.0, 20.0, 30.0, p) == pytest.approx(20.0)
    # 30 m farther: v_gap = 20 + 30/3 = 30, v_safe = sqrt(20² + 2·2·66) = 25.77.
    assert follow_speed_mps(72.0, 20.0, 20.0, 30.0, p) == pytest.approx(math.sqrt(664.0))
    # Behind a stopped car at standstill distance: stop.
    assert follow_speed_mps(6.0, 0.0, 0.0, 30.0, p) == 0.0
    # 106 m behind a stopped car at 0 m/s: v_gap = (106 - 6)/3 = 33.3, v_safe = 20.
    assert follow_speed_mps(106.0, 0.0, 0.0, 30.0, p) == pytest.approx(20.0)
    with pytest.raises(ValueError, match="time_gap_s"):
        FollowParams(time_gap_s=1.0)


def test_follow_law_sees_a_braking_lead_before_the_gap_shrinks() -> None:
    p = FollowParams(time_gap_s=1.8, standstill_m=6.0, gap_close_s=3.0,
                     comfort_decel_mps2=2.0, anticipation_s=1.0)
    # A lead at 40 m/s 100 m ahead of an ego at 33 m/s (desired gap 6 + 1.8·33 = 65.4 m):
    # steady, v_gap = 40 + 34.6/3 and v_safe = sqrt(40² + 2·2·94) both exceed the cruise
    # speed 40. Braking at 4 m/s² its stopping distance is 200 m: v_safe = sqrt(40² · 2/4
    # + 2·2·94) = sqrt(1176) = 34.3 (Gipps' bound) binds, v_gap = 36 + 34.6/3 does not.
    assert follow_speed_mps(100.0, 40.0, 33.0, 40.0, p) == 40.0
    braking = follow_speed_mps(100.0, 40.0, 33.0, 40.0, p, lead_accel_mps2=-4.0)
    assert braking == pytest.approx(math.sqrt(1176.0))
    # 42 m behind it the anticipated speed binds: 40 - 4·1 + (42 - 65.4)/3 = 28.2.
    assert follow_speed_mps(42.0, 40.0, 33.0, 40.0, p) == pytest.approx(40.0 - 23.4 / 3.0)
    assert follow_speed_mps(42.0, 40.0, 33.0, 40.0, p, lead_accel_mps2=-4.0) == pytest.approx(
        36.0 - 23.4 / 3.0)
    # Braking no harder than b leaves the constant-speed bound unchanged.
    assert follow_speed_mps(72.0, 20.0, 20.0, 30.0, p, lead_accel_mps2=-1.0) == pytest.approx(
        min(20.0 - 1.0 + 30.0 / 3.0, math.sqrt(664.0)))
    # An accelerating lead is not extrapolated upwards.
    assert follow_speed_mps(42.0, 20.0, 20.0, 30.0, p, lead_accel_mps2=2.0) == pytest.approx(20.0)


def test_tracker_estimates_the_lead_deceleration_from_held_speeds() -> None:
    from controllers.behaviour.tracking import AccelerationTracker, TrackingParams
    tr = AccelerationTracker(TrackingParams(tau_s=0.4))
    # SUMO updates the speed every 0.1 s while the controller looks every 0.02 s: the same
    # speed five times, then a step of -0.4 m/s (a = -4 m/s²).
    est = 0.0
    for k in range(200):
        t = 0.02 * k
        v = 40.0 - 4.0 * 0.1 * math.floor(t / 0.1 + 1e-9)
        est = float(tr.update(t, traffic([("lead", 0.0, 0.0, v)]))[0])
    assert est == pytest.approx(-4.0, abs=0.6)
    # A vehicle unseen for longer than forget_s starts again at 0.
    assert float(tr.update(10.0, traffic([("lead", 0.0, 0.0, 5.0)]))[0]) == 0.0
    with pytest.raises(ValueError, match="tau_s"):
        TrackingParams(tau_s=0.0)


def test_a_car_behind_in_the_kept_lane_is_no_obstacle(path: FrenetPath) -> None:
    # Queued behind a stalled car with no free side: the follower 7 m behind must not get
    # an ellipse (squeezed between two ellipses, the ego's only way out is sideways).
    nb = traffic([("stalled0", 110.0, 0.0, 0.0), ("behind", 93.0, 0.0, 0.0),
                  ("carL", 101.0, W, 5.0), ("carR", 99.0, -W, 5.0)])
    d = at(behaviour(path), 100.0, 0.0, nb, THREE_LANES, v=0.0)
    assert d.side == SIDE_FOLLOW
    assert "behind" not in d.obstacle_ids and "stalled0" in d.obstacle_ids


def test_back_in_the_home_lane_once_the_passed_car_is_behind(path: FrenetPath) -> None:
    b = behaviour(path, hold_s=0.0)
    nb = traffic([("stalled0", 200.0, 0.0, 0.0)])
    assert at(b, 100.0, 0.0, nb, THREE_LANES).side == SIDE_LEFT
    done = at(b, 150.0, W, nb, THREE_LANES, t=102.0)
    assert done.reason_code is Reason.IN_LANE and done.side == SIDE_LEFT
    alongside = at(b, 219.0, W, nb, THREE_LANES, t=104.0)
    assert alongside.lateral_reference_m == pytest.approx(W)  # not yet 15 m beyond
    # Box centres 4.8 m apart when the bumpers meet: 15 m beyond at s = 200 + 4.8 + 15.
    back = at(b, 220.5, W, nb, THREE_LANES, t=105.0)
    assert back.reason_code is Reason.RETURN and back.side == SIDE_RIGHT
    assert back.lateral_reference_m == 0.0
    # ... but not while a car is alongside in the home lane.
    b2 = behaviour(path, hold_s=0.0)
    at(b2, 100.0, 0.0, nb, THREE_LANES)
    at(b2, 150.0, W, nb, THREE_LANES, t=102.0)
    busy = traffic([("stalled0", 200.0, 0.0, 0.0), ("car", 219.0, 0.0, 25.0)])
    held = at(b2, 220.5, W, busy, THREE_LANES, t=105.0)
    assert held.lateral_reference_m == pytest.approx(W)


def test_a_lane_change_holds_for_hold_s(path: FrenetPath) -> None:
    b = behaviour(path, hold_s=3.0)
    nb = traffic([("stalled0", 200.0, 0.0, 0.0)])
    at(b, 100.0, 0.0, nb, THREE_LANES, t=10.0)
    at(b, 150.0, W, nb, THREE_LANES, t=12.0)  # completes at t = 12
    early = at(b, 222.0, W, nb, THREE_LANES, t=13.0)
    assert early.lateral_reference_m == pytest.approx(W) and early.reason_code is Reason.KEEP
    assert LaneCheck.HOLDING in {check for _, check in early.lane_checks}
    later = at(b, 240.0, W, nb, THREE_LANES, t=15.5)
    assert later.lateral_reference_m == 0.0


def test_relative_lanes_follow_the_worlds_lane_index_across_a_shift() -> None:
    # On road "b" an on-ramp lane was added on the right: the reference lane is index 1
    # there, 0 on road "a". A car on "b" in lane 1 is in the ego's lane.
    nb = traffic([("x", 150.0, 0.0, 20.0), ("y", 150.0, 3.5, 20.0)], road="b", lanes=[1, 2])
    ctx = LaneContext({0: LaneSlot(0, W, True, False), 1: LaneSlot(1, W, True, False)}, 0,
                      reference_index_by_road={"a": 0, "b": 1})
    from controllers.behaviour.perception import FrenetTraffic

    fn = FrenetTraffic(np.array([150.0, 150.0]), np.array([0.0, 3.5]), np.zeros(2),
                       np.zeros(2), np.full(2, 4.8), np.full(2, 1.9))
    assert relative_lanes(nb, fn, ctx, W).tolist() == [0, 1]


def test_a_car_on_an_ending_lane_leads_the_lane_it_must_merge_into(path: FrenetPath) -> None:
    # Road "e1": lane 0 an acceleration lane ending at route position 330 m, merging left
    # into lane 1, the ego's lane (reference index 1 on e1). The ego is at route position
    # 200 m (path s 100): a car on the acceleration lane 30 m ahead at 20 m/s has 100 m
    # left, less than 6 s of its driving: it leads the ego's lane (speed target lowered).
    slots = {0: LaneSlot(0, W, True, False, offset_m=-W, continues_m=200.0),
             1: LaneSlot(1, W, True, False, offset_m=0.0)}
    ctx = LaneContext(slots, 1, {"e1": 1}, {"e1": {0: (330.0, 1)}}, 200.0)
    merger = traffic([("ramp0", 130.0, -W, 20.0)], road="e1", lanes=[0])
    d = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 28.0, 100.0), merger, ctx,
                               28.0)
    assert d.target_speed_mps < 28.0 and "ramp0" in d.obstacle_ids
    # With 230 m of its lane left (more than 6 s at 20 m/s) it is not a lead yet.
    far = LaneContext(slots, 1, {"e1": 1}, {"e1": {0: (460.0, 1)}}, 200.0)
    d2 = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 28.0, 100.0), merger, far,
                                28.0)
    assert d2.target_speed_mps == 28.0
