"""The behaviour layer: obstacles and pass-side choice from lane context (pure numpy, no SUMO)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controllers.behaviour.decision import EgoShape, LaneBehaviour
from controllers.behaviour.ellipses import ellipse_semi_axes
from controllers.behaviour.gap import GapPolicy, follow_speed_mps, gap_is_free
from controllers.behaviour.types import (
    SIDE_FOLLOW,
    SIDE_LEFT,
    SIDE_NONE,
    SIDE_RIGHT,
    Decision,
    EgoFrenet,
    LaneContext,
    LaneSlot,
    ObstaclePolicy,
    Traffic,
)
from controllers.path.frenet import FrenetPath
from reports.metrics.geometry import box_corners, box_distance

W = 3.5
THREE_LANES = {i: LaneSlot(i, W, True, False) for i in range(3)}


def neighbours(rows: list[tuple[str, float, float, float]]) -> Traffic:
    """rows: (id, x, y, speed) on a straight road along +X; 'stalled*' ids are stalled."""
    n = len(rows)
    return Traffic(
        ids=tuple(r[0] for r in rows), x_m=np.array([r[1] for r in rows], float),
        y_m=np.array([r[2] for r in rows], float), heading_rad=np.zeros(n),
        speed_mps=np.array([r[3] for r in rows], float), length_m=np.full(n, 4.8),
        width_m=np.full(n, 1.9), lane_index=np.zeros(n, dtype=np.int64), road_id=("e0",) * n,
        stalled=np.array([r[0].startswith("stalled") for r in rows], dtype=bool))


def behaviour(path: FrenetPath, shoulder: bool = False, gap: GapPolicy | None = None
              ) -> LaneBehaviour:
    return LaneBehaviour(path, ObstaclePolicy(), EgoShape(4.8, 1.9, shoulder), W,
                         gap or GapPolicy())


def build(b: LaneBehaviour, s: float, y: float, nb: Traffic, lanes: dict[int, LaneSlot],
          ref_lane: int = 1, v: float = 25.0) -> Decision:
    """The decision of ``b`` with the ego's CG at (s, y) on the straight road along +X."""
    return b.decide(EgoFrenet(s, y, s, y, v), nb, LaneContext(lanes, ref_lane), 25.0)


@pytest.fixture(scope="module")
def path() -> FrenetPath:
    return FrenetPath.from_polyline(np.array([[0.0, 0.0], [2000.0, 0.0]]))


def decide(path: FrenetPath, rows, lanes=THREE_LANES, ref_lane=1, shoulder=False,
           ego_s=100.0, ego_y=0.0, ego_v=25.0):
    return build(behaviour(path, shoulder), ego_s, ego_y, neighbours(rows), lanes, ref_lane, ego_v)


def test_ellipse_contains_the_box_sum_rectangle_with_margins() -> None:
    pol = ObstaclePolicy()
    a, b = ellipse_semi_axes(4.8, 1.9, 4.8, 1.9, pol)
    # Corners of the Minkowski rectangle (half sizes 4.8 x 1.9) plus lateral margin, with the
    # centre shifted by the offset away from the pass side, are inside the ellipse.
    for dy in (1.9 + pol.offset_m, -(1.9 - pol.offset_m)):
        assert (4.8 / a) ** 2 + (dy / b) ** 2 <= 1.0 + 1e-12
    # Every point of the ego box around a CG on the ellipse boundary misses the obstacle box.
    obstacle = box_corners(0.0, 0.0, 0.0, 4.8, 1.9)
    for ang in np.linspace(0, 2 * math.pi, 73):
        cx, cy = a * math.cos(ang), b * math.sin(ang) - pol.offset_m
        ego = box_corners(cx, cy, 0.0, 4.8, 1.9)
        assert float(box_distance(ego[None], obstacle[None])[0]) > 0.0


def test_no_neighbours_means_no_obstacle(path: FrenetPath) -> None:
    d = decide(path, [])
    assert d.side == SIDE_NONE and d.obstacles.count == 0 and d.target_speed_mps == 25.0


def test_stalled_car_in_lane_with_free_neighbours_is_passed_on_the_left(path: FrenetPath) -> None:
    d = decide(path, [("stalled0", 170.0, 0.0, 0.0)])
    assert d.side == SIDE_LEFT and "left lane free" in d.reason
    assert d.obstacles.count == 1
    assert d.obstacles.y_m[0] == pytest.approx(-ObstaclePolicy().offset_m)  # shifted right


def test_left_gap_occupied_picks_right(path: FrenetPath) -> None:
    d = decide(path, [("stalled0", 170.0, 0.0, 0.0), ("car", 110.0, W, 25.0)])
    assert d.side == SIDE_RIGHT and "left gap occupied" in d.reason
    assert d.obstacles.y_m[list(d.obstacle_ids).index("stalled0")] == pytest.approx(0.3)


def test_no_free_side_follows_and_slows(path: FrenetPath) -> None:
    rows = [("stalled0", 170.0, 0.0, 0.0), ("carL", 110.0, W, 25.0), ("carR", 95.0, -W, 25.0)]
    d = decide(path, rows)
    assert d.side == SIDE_FOLLOW and d.reason.startswith("follow:")
    assert d.target_speed_mps < 25.0


def test_shoulder_only_when_allowed(path: FrenetPath) -> None:
    # Ego in the rightmost traffic lane (1) above a shoulder (0); the left lane is busy.
    lanes = {0: LaneSlot(0, 3.0, False, True), 1: LaneSlot(1, W, True, False),
             2: LaneSlot(2, W, True, False)}
    rows = [("stalled0", 170.0, 0.0, 0.0), ("carL", 110.0, W, 25.0)]
    refused = decide(path, rows, lanes=lanes, shoulder=False)
    assert refused.side == SIDE_FOLLOW and "shoulder (not allowed)" in refused.reason
    allowed = decide(path, rows, lanes=lanes, shoulder=True)
    assert allowed.side == SIDE_RIGHT and "shoulder free" in allowed.reason


def test_missing_and_barred_lanes_are_not_used(path: FrenetPath) -> None:
    lanes = {0: LaneSlot(0, W, False, False), 1: LaneSlot(1, W, True, False)}
    d = decide(path, [("stalled0", 170.0, 0.0, 0.0)], lanes=lanes)
    assert d.side == SIDE_FOLLOW
    assert "no left lane" in d.reason and "bars passenger" in d.reason


def test_committed_side_is_kept_mid_manoeuvre(path: FrenetPath) -> None:
    b = behaviour(path)
    first = build(b, 140.0, 1.5, neighbours([("stalled0", 170.0, 0.0, 0.0)]), THREE_LANES)
    assert first.side == SIDE_LEFT
    # A fast car now appears in the left lane; the ego is already 1.5 m across: stay left.
    nb2 = neighbours([("stalled0", 170.0, 0.0, 0.0), ("fast", 120.0, W, 35.0)])
    again = build(b, 142.0, 1.6, nb2, THREE_LANES)
    assert again.side == SIDE_LEFT and again.reason.startswith("committed")


def test_cars_two_lanes_away_are_not_obstacles(path: FrenetPath) -> None:
    d = decide(path, [("far", 130.0, 2 * W, 20.0)], ref_lane=0,
               lanes={i: LaneSlot(i, W, True, False) for i in range(3)})
    assert d.obstacles.count == 0


def test_gap_is_free_known_answers() -> None:
    g = GapPolicy(clearance_m=4.0, time_gap_s=0.0, pass_after_m=15.0)
    empty = np.zeros(0)
    assert gap_is_free(0.0, 25.0, 4.8, 60.0, 4.8, empty, empty, empty, g)
    # A car alongside at the same speed blocks; one 100 m ahead at the same speed does not.
    assert not gap_is_free(0.0, 25.0, 4.8, 60.0, 4.8, np.array([2.0]), np.array([25.0]),
                           np.array([4.8]), g)
    assert gap_is_free(0.0, 25.0, 4.8, 60.0, 4.8, np.array([100.0]), np.array([25.0]),
                       np.array([4.8]), g)
    # A car 30 m behind closing at 10 m/s reaches the ego within the ~3.1 s window: blocked.
    assert not gap_is_free(0.0, 25.0, 4.8, 60.0, 4.8, np.array([-30.0]), np.array([35.0]),
                           np.array([4.8]), g)
    # The same car at 25 m/s stays 40 m behind: free.
    assert gap_is_free(0.0, 25.0, 4.8, 60.0, 4.8, np.array([-40.0]), np.array([25.0]),
                       np.array([4.8]), g)


def test_a_stalled_car_in_the_target_lane_blocks_even_a_crawling_ego() -> None:
    g = GapPolicy()
    # Ego nearly stopped 13 m behind the blocker; a second stalled car sits in the target
    # lane 5 m beyond it. The time-based test alone would call this free at 0.3 m/s.
    assert not gap_is_free(404.6, 0.3, 4.8, 417.6, 4.8, np.array([422.6]), np.array([0.0]),
                           np.array([4.8]), g)
    # Far beyond the manoeuvre it does not matter.
    assert gap_is_free(404.6, 0.3, 4.8, 417.6, 4.8, np.array([520.0]), np.array([0.0]),
                       np.array([4.8]), g)


def test_follow_speed_known_answers() -> None:
    g = GapPolicy(follow_standstill_m=6.0, follow_time_gap_s=1.8, follow_decel_mps2=2.0)
    assert follow_speed_mps(6.0, 0.0, 25.0, g) == 0.0
    assert follow_speed_mps(6.0 + 100.0, 0.0, 25.0, g) == pytest.approx(20.0)  # sqrt(2*2*100)
    assert follow_speed_mps(500.0, 0.0, 25.0, g) == 25.0
    assert follow_speed_mps(6.0 + 1.8 * 10.0, 10.0, 25.0, g) == pytest.approx(10.0)
    assert follow_speed_mps(12.0, 10.0, 25.0, g) == pytest.approx(5.0)


def test_lateral_reference_is_the_pass_lane_until_the_car_is_passed(path: FrenetPath) -> None:
    lanes = {0: LaneSlot(0, 3.0, False, True), 1: LaneSlot(1, W, True, False),
             2: LaneSlot(2, W, True, False)}
    b = behaviour(path, True, GapPolicy(pass_after_m=15.0))
    nb = neighbours([("stalled0", 300.0, 0.0, 0.0)])

    def at(s: float, y: float) -> Decision:
        return build(b, s, y, nb, lanes)

    assert at(200.0, 0.0).lateral_reference_m == pytest.approx(W)  # left: 3.5 m over
    alongside = at(301.0, 3.4)
    assert alongside.side == SIDE_LEFT and alongside.lateral_reference_m == pytest.approx(W)
    assert alongside.reason == "passing stalled0"
    # Stalled box centre at 300, half lengths 2.4 + 2.4: 15 m beyond that is s = 319.8.
    assert at(319.0, 3.5).lateral_reference_m == pytest.approx(W)
    done = at(320.5, 3.5)
    assert done.lateral_reference_m == 0.0 and done.side == SIDE_NONE
    # Passing on a 3.0 m shoulder: the reference is between the two centres, 3.25 m right.
    busy = neighbours([("stalled0", 300.0, 0.0, 0.0), ("carL", 200.0, W, 25.0)])
    d = build(behaviour(path, True), 200.0, 0.0, busy, lanes)
    assert d.side == SIDE_RIGHT and d.lateral_reference_m == pytest.approx(-3.25)
