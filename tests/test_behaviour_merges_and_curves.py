"""The behaviour's rules for lane ends, merges, on-ramps and curves, on scripted scenes
(pure numpy, no SUMO): known answers and invariants."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_behaviour import W, at, behaviour, traffic

from controllers.behaviour.lane_change import (
    MIN_JERK_PEAK,
    LaneChangeParams,
    change_duration_s,
)
from controllers.behaviour.types import (
    SIDE_LEFT,
    SIDE_RIGHT,
    EgoFrenet,
    LaneCheck,
    LaneContext,
    LaneSlot,
    Reason,
)
from controllers.path.frenet import FrenetPath
from controllers.two_loop.lateral import LateralReferenceShaper, LateralRefParams


@pytest.fixture(scope="module")
def path() -> FrenetPath:
    return FrenetPath.from_polyline(np.array([[0.0, 0.0], [3000.0, 0.0]]))


def arc_path(radius_m: float, length_m: float = 1500.0) -> FrenetPath:
    th = np.linspace(0.0, length_m / radius_m, int(length_m / 2.0))
    return FrenetPath.from_polyline(np.column_stack([radius_m * np.sin(th),
                                                     radius_m * (1.0 - np.cos(th))]))


# ------------------------------------------------------------------ durations on curves


def test_change_duration_known_answers() -> None:
    p = LaneChangeParams()  # max 4.0 m/s², nominal 4 s
    assert change_duration_s(3.5, 0.0, p) == p.change_s  # 5.77·3.5/16 = 1.26 fits
    # the curve leaves 1.0 m/s²: a 3.5 m move needs sqrt(5.77·3.5/1.0) = 4.49 s
    assert change_duration_s(3.5, 3.0, p) == pytest.approx(math.sqrt(MIN_JERK_PEAK * 3.5))
    # the curve takes it all: stretched to a tenth of the limit, never endless
    assert change_duration_s(3.5, 9.0, p) == pytest.approx(math.sqrt(MIN_JERK_PEAK * 3.5 / 0.4))


@pytest.mark.parametrize("curve", [0.0, 1.0, 2.5, 3.5, 3.6])  # up to 0.9 of the limit
def test_a_stretched_change_fits_the_limit(curve: float) -> None:
    p = LaneChangeParams()
    t = change_duration_s(3.5, curve, p)
    assert MIN_JERK_PEAK * 3.5 / t**2 + curve <= p.max_lat_acc_mps2 + 1e-9


def test_a_return_waits_on_a_curve_that_leaves_no_room() -> None:
    # R 300 m at 33 m/s: v²/R = 3.63 m/s², leaving 0.37 < 1.5 m/s² for the move
    b = behaviour(arc_path(300.0))
    lanes = {i: LaneSlot(i, W, True, False) for i in range(3)}
    d = at(b, 400.0, W, traffic([]), lanes, ref=1, v=33.0, set_speed=33.0)
    assert d.lateral_reference_m == pytest.approx(W)  # stays in the left lane
    assert d.reason_code is Reason.KEEP and d.lane_check(-1) is LaneCheck.CURVE
    # the same on a straight road returns
    straight = behaviour(FrenetPath.from_polyline(np.array([[0.0, 0.0], [3000.0, 0.0]])))
    d2 = at(straight, 400.0, W, traffic([]), lanes, ref=1, v=33.0, set_speed=33.0)
    assert d2.side == SIDE_RIGHT and d2.lateral_reference_m == pytest.approx(0.0)


def test_the_shaper_bounds_the_move_by_what_the_curve_leaves() -> None:
    p = LateralRefParams()
    shaper = LateralReferenceShaper(p)
    shaper.update(0.0, None, 0.0, 30.0, 1.0)
    straight = shaper.move_rate_bound_mps(30.0)
    assert straight == pytest.approx(p.max_lat_acc_mps2 * p.filter_s * math.e)
    assert straight > p.rate_mps  # no change on a straight road
    shaper.update(0.0, 0.02, 0.0, 30.0, 1.0, curvature_1pm=1.0 / 400.0)  # 2.25 m/s²
    assert shaper.move_rate_bound_mps(30.0) == pytest.approx(
        (p.max_lat_acc_mps2 - 2.25) * p.filter_s * math.e)


@pytest.mark.parametrize("radius_m", [400.0, 600.0, 800.0])
def test_the_shaped_reference_stays_within_the_lateral_budget(radius_m: float) -> None:
    """yr'' of a 3.5 m move at 30 m/s plus v²/R stays within max_lat_acc_mps2."""
    p = LateralRefParams()
    shaper = LateralReferenceShaper(p)
    v, dt, kappa = 30.0, 0.02, 1.0 / radius_m
    shaper.update(3.5, None, 0.0, v, 1.0, curvature_1pm=kappa)
    rates = []
    for _ in range(600):
        shaper.update(3.5, dt, shaper.reference_m, v, 1.0, curvature_1pm=kappa)
        rates.append(shaper.rate_mps)
    acc = np.abs(np.diff(rates)) / dt
    assert shaper.reference_m == pytest.approx(3.5, abs=0.01)
    assert acc.max() + v * v * kappa <= p.max_lat_acc_mps2 + 0.05


# ------------------------------------------------------------------ lane ends


def ending_lanes(ends_in_m: float) -> dict[int, LaneSlot]:
    """Lane 0 ends ``ends_in_m`` ahead; lanes 1 (the reference) and 2 continue."""
    return {0: LaneSlot(0, W, True, False, continues_m=ends_in_m),
            1: LaneSlot(1, W, True, False), 2: LaneSlot(2, W, True, False)}


def test_a_lane_that_ends_is_left_towards_the_through_lanes(path: FrenetPath) -> None:
    b = behaviour(path)
    d = at(b, 200.0, -W, traffic([]), ending_lanes(400.0), ref=1)
    assert d.side == SIDE_LEFT and d.lateral_reference_m == pytest.approx(0.0)
    assert d.reason_code is Reason.LANE_ENDS


def test_a_lane_end_change_never_turns_away_from_the_through_lanes(path: FrenetPath) -> None:
    """The gap on the left closes for a while: the ego waits (and slows for the end),
    it never heads right, and it goes left once the gap is there again."""
    b = behaviour(path)
    blocker = traffic([("c1", 200.0, 0.0, 25.0)])  # alongside in the lane to its left
    sides = []
    for k in range(60):
        s = 150.0 + 0.5 * k
        nb = blocker if k < 30 else traffic([])
        d = at(b, s, -W, nb, ending_lanes(200.0 - 0.5 * k), ref=1, t=100.0 + 0.02 * k)
        sides.append(d.side)
        assert d.lateral_reference_m >= -W - 1e-9  # never further right
    assert SIDE_RIGHT not in sides
    assert sides[-1] == SIDE_LEFT


# ------------------------------------------------------------------ merges and ramps


def merge_context(route_pos_m: float = 200.0, end_m: float = 330.0) -> LaneContext:
    """Road "e1": lane 0 an acceleration lane ending at route position ``end_m`` merging
    into lane 1 (the reference, the ego's); lane 2 to the left."""
    slots = {0: LaneSlot(0, W, True, False, offset_m=-W, continues_m=end_m - route_pos_m),
             1: LaneSlot(1, W, True, False, offset_m=0.0),
             2: LaneSlot(2, W, True, False, offset_m=W)}
    return LaneContext(slots, 1, {"e1": 1}, {"e1": {0: (end_m, 1)}}, route_pos_m)


def test_a_free_left_lane_makes_room_for_merging_traffic(path: FrenetPath) -> None:
    merger = traffic([("ramp0", 110.0, -W, 24.0)], road="e1", lanes=[0])
    d = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 25.0, 100.0), merger,
                               merge_context(), 25.0)
    assert d.side == SIDE_LEFT and d.lateral_reference_m == pytest.approx(W)
    assert d.reason_code is Reason.MAKE_ROOM and "ramp0" in d.reason


def test_no_return_into_a_lane_traffic_is_merging_into(path: FrenetPath) -> None:
    merger = traffic([("ramp0", 110.0, -W, 24.0)], road="e1", lanes=[0])
    d = behaviour(path).decide(EgoFrenet(100.0, W, 100.0, W, 25.0, 100.0), merger,
                               merge_context(), 25.0)
    assert d.lateral_reference_m == pytest.approx(W)  # stays left
    free = behaviour(path).decide(EgoFrenet(100.0, W, 100.0, W, 25.0, 100.0), traffic([]),
                                  merge_context(), 25.0)
    assert free.side == SIDE_RIGHT


def test_a_faster_merger_behind_is_let_in(path: FrenetPath) -> None:
    """At 27 m/s, 10 m behind the ego's CG (25 m/s) with 130 m of its lane left: in
    4.8 s it is 0.6 m ahead, so the ego eases off now; a slower one merges behind."""
    left_blocked = traffic([("ramp0", 90.0, -W, 27.0), ("c2", 100.0, W, 25.0)], road="e1",
                           lanes=[0, 2])
    d = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 25.0, 100.0), left_blocked,
                               merge_context(), 25.0)
    assert d.target_speed_mps < 25.0
    slower = traffic([("ramp0", 90.0, -W, 22.0), ("c2", 100.0, W, 25.0)], road="e1",
                     lanes=[0, 2])
    d2 = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 25.0, 100.0), slower,
                                merge_context(), 25.0)
    assert d2.target_speed_mps == 25.0


def test_a_car_on_an_on_ramp_blocks_a_change_into_the_lane_it_enters(path: FrenetPath
                                                                      ) -> None:
    """The ego in the left lane of two passes a stalled car: the right lane is free, but
    a car on the on-ramp (a road off the route, beyond the right edge, heading along)
    is about to enter it alongside: the ego does not move right now."""
    slots = {0: LaneSlot(0, W, True, False, offset_m=-W), 1: LaneSlot(1, W, True, False,
                                                                     offset_m=0.0)}
    ctx = LaneContext(slots, 1, {"e0": 1}, {}, 200.0)
    rows = [("stalled0", 160.0, 0.0, 0.0), ("ramp0", 102.0, -2.5 * W, 25.0)]
    nb = traffic(rows, road="e0", lanes=[1, 0])
    nb = type(nb)(ids=nb.ids, x_m=nb.x_m, y_m=nb.y_m, heading_rad=nb.heading_rad,
                  speed_mps=nb.speed_mps, length_m=nb.length_m, width_m=nb.width_m,
                  lane_index=nb.lane_index, road_id=("e0", "ramp"), stalled=nb.stalled)
    d = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 25.0, 100.0), nb, ctx, 25.0)
    assert d.side != SIDE_RIGHT and d.lane_check(-1) is LaneCheck.MERGE_CONFLICT
    # without the ramp car the stalled car is passed on the right
    alone = traffic(rows[:1], road="e0", lanes=[1])
    d2 = behaviour(path).decide(EgoFrenet(100.0, 0.0, 100.0, 0.0, 25.0, 100.0), alone, ctx,
                                25.0)
    assert d2.side == SIDE_RIGHT
