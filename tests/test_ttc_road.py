"""TTC predicted along the road (reports.metrics.ttc, issue #31 item 4): known answers on
a bend, the straight-line answer on a straight road, the fall-backs, the replayed-car
rules on a bend, and the projection on the reference (reports.geometry.polyline_frenet)
against a brute-force one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import tests.synthetic_runs as sr
from reports.geometry import box_corners, polyline_frenet, swept_box_ttc
from reports.metrics import evaluate
from reports.metrics.context import RunContext, build_context
from reports.metrics.ttc import TTC_HORIZON_S, TtcPairs, ttc_pairs, ttc_series
from reports.record import AGENT_REPLAYED, NeighbourColumns, RoadRecord, RunRecord, Trace

R_M = 300.0  # the bend of the known answers
L_M = sr.EGO_LENGTH_M  # ego and neighbours are 4.6 m x 1.8 m


# --------------------------------------------------------------------------- helpers


def _on_circle(angle: np.ndarray, radius_m: float = R_M) -> tuple[np.ndarray, np.ndarray]:
    """Points at ``angle`` [rad] on a circle of ``radius_m`` about (0, R_M) (sr.circle_road's
    centre; the reference lane is the one of radius R_M): a left bend from the origin."""
    return radius_m * np.sin(angle), R_M - radius_m * np.cos(angle)


def _neighbour(trace: Trace, x: np.ndarray, y: np.ndarray, heading: np.ndarray,
               speed_mps: float, vid: str = "car", agent: int = 0) -> NeighbourColumns:
    nb = NeighbourColumns.allocate(len(trace))
    nb.step[:], nb.t_s[:], nb.id[:] = trace.step, trace.t_s, vid
    nb.x_m[:], nb.y_m[:], nb.heading_rad[:], nb.speed_mps[:] = x, y, heading, speed_mps
    nb.length_m[:], nb.width_m[:], nb.lane_index[:] = L_M, sr.EGO_WIDTH_M, 0
    nb.agent[:] = agent
    return nb


def _bend_run(ego_speed_mps: float, nb_speed_mps: float, arc_ahead_m: float,
              nb_radius_m: float = R_M, duration_s: float = 10.0, dt_s: float = 0.02,
              agent: int = 0) -> RunRecord:
    """The ego in the reference lane of the R = 300 m bend at constant speed; a neighbour
    in the lane of radius ``nb_radius_m`` whose centre starts ``arc_ahead_m`` ahead of the
    ego's along the reference (behind if negative), at constant speed along its lane."""
    trace = sr.turn_trace(radius_m=R_M, speed_mps=ego_speed_mps, duration_s=duration_s,
                          dt_s=dt_s)
    t = trace.t_s
    a_nb = (arc_ahead_m + ego_speed_mps * t[0]) / R_M + nb_speed_mps / nb_radius_m * (t - t[0])
    x, y = _on_circle(a_nb, nb_radius_m)
    nb = _neighbour(trace, x, y, a_nb, nb_speed_mps, agent=agent)
    return sr.make_record(trace, road=sr.circle_road(R_M), neighbours=nb,
                          info=sr.base_info("bend", step_s=dt_s))


def _straight_line_ttc(ctx: RunContext) -> np.ndarray:
    """The model before: both boxes in straight lines at constant world velocity."""
    nb = ctx.record.neighbours
    corners = box_corners(nb.x_m, nb.y_m, nb.heading_rad, nb.length_m, nb.width_m)
    vel = np.stack([nb.speed_mps * np.cos(nb.heading_rad),
                    nb.speed_mps * np.sin(nb.heading_rad)], axis=-1)
    ego_vel = np.stack([ctx.vel_x_mps, ctx.vel_y_mps], axis=-1)
    out: np.ndarray = swept_box_ttc(ctx.corners_m, ego_vel, corners, vel, TTC_HORIZON_S)
    return out


def _pairs(record: RunRecord) -> tuple[RunContext, TtcPairs]:
    ctx = build_context(record)
    return ctx, ttc_pairs(ctx)


# --------------------------------------------------------------------------- known answers


def test_one_lane_round_a_bend_at_equal_speeds_is_never_a_conflict() -> None:
    # (a) a car 20 m ahead and one 20 m behind, all at 25 m/s for 10 s (250 m of the
    # bend, 48 degrees): never a finite TTC, at any step, ahead or behind
    for arc_m in (20.0, -20.0):
        record = _bend_run(25.0, 25.0, arc_m)
        ctx, pairs = _pairs(record)
        assert pairs.row.size == ctx.n and np.all(pairs.on_road)
        assert np.all(np.isinf(pairs.ttc_s))
        verdict = evaluate(record).verdict
        assert verdict.value("min_ttc_s") == math.inf
        assert verdict.value("min_ttc_rear_s") == math.inf


@pytest.mark.parametrize(("ego_speed", "nb_speed", "arc_m", "ahead"),
                         [(25.0, 20.0, 45.0, True), (20.0, 25.0, -45.0, False)])
def test_a_faster_car_behind_a_slower_one_on_a_bend_meets_it_after_gap_over_closing_speed(
        ego_speed: float, nb_speed: float, arc_m: float, ahead: bool) -> None:
    # (b) one lane of the R = 300 m bend; the bumper gap along the lane shrinks from
    # 40.4 m to 15.4 m over 5 s at 5 m/s: TTC = gap / 5 at every step (< 10 s)
    record = _bend_run(ego_speed, nb_speed, arc_m, duration_s=5.0)
    ctx, pairs = _pairs(record)
    t = record.trace.t_s
    gap = abs(arc_m) - L_M - 5.0 * (t - t[0])
    want = np.where(gap / 5.0 <= TTC_HORIZON_S, gap / 5.0, np.inf)
    assert np.all(pairs.ahead == ahead)
    np.testing.assert_allclose(pairs.ttc_s[np.isfinite(want)], want[np.isfinite(want)],
                               rtol=5e-4)
    assert np.all(np.isinf(pairs.ttc_s[~np.isfinite(want)]))
    series = ttc_series(ctx, pairs, ahead=ahead)
    assert float(np.min(series)) == pytest.approx(gap[-1] / 5.0, rel=5e-4)
    assert np.all(np.isinf(ttc_series(ctx, pairs, ahead=not ahead)))


def test_passing_a_car_in_the_next_lane_of_a_bend_is_no_conflict() -> None:
    # the ego at 30 m/s passes, on the inside of the bend, a car at 22 m/s in the outer
    # lane (3.5 m right) 14 m ahead; both keep their lanes. In straight lines the car
    # ahead, turned 0.047 rad further left by the bend, crosses into the ego's path: a
    # TTC of 1.37 s. Along the road each keeps its lane: none.
    record = _bend_run(30.0, 22.0, 14.0, nb_radius_m=R_M + sr.LANE_WIDTH_M, duration_s=1.0)
    ctx, pairs = _pairs(record)
    old = _straight_line_ttc(ctx)
    assert float(old[0]) == pytest.approx(1.372, abs=1e-3)  # what the straight lines said
    assert np.all(pairs.on_road) and np.all(pairs.ahead) and np.all(np.isinf(pairs.ttc_s))


# --------------------------------------------------------------------------- straight road


def _random_straight_record(angle_rad: float, seed: int) -> RunRecord:
    """An ego weaving along a straight road at ``angle_rad`` and 40 cars at random poses
    around it (some beyond the reference's ends, some more than 20 m off it), random
    speeds and headings."""
    rng = np.random.default_rng(seed)
    n = 60
    t = 0.1 * np.arange(1, n + 1)
    along = 22.0 * t
    across = 1.5 * np.sin(0.8 * t)
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    origin = np.array([30.0, -40.0])
    psi = angle_rad + np.arctan2(1.2 * np.cos(0.8 * t), 22.0)
    trace = sr.kinematic_trace(t, origin[0] + along * c - across * s,
                               origin[1] + along * s + across * c, psi, np.full(n, 22.0),
                               v=rng.normal(0.0, 0.3, n))
    k = 40
    rows = np.repeat(np.arange(n), k)
    nb = NeighbourColumns.allocate(rows.size)
    nb.step[:], nb.t_s[:] = trace.step[rows], trace.t_s[rows]
    nb.id[:] = np.array([f"v{j}" for j in range(k)] * n, dtype=object)
    a = along[rows] + rng.uniform(-90.0, 90.0, rows.size)
    b = rng.choice([-26.0, -7.0, -3.5, 0.0, 3.5, 7.0, 25.0], rows.size) \
        + rng.normal(0.0, 0.4, rows.size)
    nb.x_m[:] = origin[0] + a * c - b * s
    nb.y_m[:] = origin[1] + a * s + b * c
    nb.heading_rad[:] = angle_rad + rng.normal(0.0, 0.15, rows.size)
    nb.speed_mps[:] = rng.uniform(0.0, 40.0, rows.size)
    nb.length_m[:], nb.width_m[:] = rng.uniform(4.0, 12.0, rows.size), 1.8
    # the reference covers only part of the run: boxes beyond both ends
    ref = origin + np.outer([20.0, 150.0, 400.0], [c, s])
    road = RoadRecord(lanes=sr.straight_road().lanes, reference_xy_m=ref,
                      reference_length_m=380.0, route=("E0",))
    return sr.make_record(trace, road=road, neighbours=nb, info=sr.base_info("straight"))


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, -127.0])
def test_on_a_straight_road_the_answer_is_the_straight_line_one(angle_deg: float) -> None:
    # (c) the frame of a straight reference is a rigid motion of the plane
    record = _random_straight_record(math.radians(angle_deg), seed=int(angle_deg) + 200)
    ctx, pairs = _pairs(record)
    old = _old_per_pair(ctx)
    assert np.any(pairs.on_road) and np.any(~pairs.on_road)  # far cars fall back
    assert np.sum(np.isfinite(old)) > 50  # the comparison has finite answers in it
    assert np.array_equal(np.isinf(pairs.ttc_s), np.isinf(old))
    finite = np.isfinite(old)
    np.testing.assert_allclose(pairs.ttc_s[finite], old[finite], rtol=1e-9, atol=1e-9)


def _old_per_pair(ctx: RunContext) -> np.ndarray:
    """The straight-line TTC per neighbour row (rows of ``_random_straight_record`` are
    step-major: row r of the trace for each of its neighbours)."""
    nb = ctx.record.neighbours
    rows = nb.step.astype(np.int64) - int(ctx.record.trace.step[0])
    corners = box_corners(nb.x_m, nb.y_m, nb.heading_rad, nb.length_m, nb.width_m)
    vel = np.stack([nb.speed_mps * np.cos(nb.heading_rad),
                    nb.speed_mps * np.sin(nb.heading_rad)], axis=-1)
    ego_vel = np.stack([ctx.vel_x_mps[rows], ctx.vel_y_mps[rows]], axis=-1)
    out: np.ndarray = swept_box_ttc(ctx.corners_m[rows], ego_vel, corners, vel, TTC_HORIZON_S)
    return out


# --------------------------------------------------------------------------- fall-backs


def test_a_car_far_off_the_reference_is_predicted_in_straight_lines() -> None:
    # a car 30 m inside the bend (a parallel road): beyond max_offset_m, so the pair is
    # the straight-line one
    record = _bend_run(25.0, 25.0 * (R_M - 30.0) / R_M, 10.0, nb_radius_m=R_M - 30.0,
                       duration_s=2.0)
    ctx, pairs = _pairs(record)
    assert not np.any(pairs.on_road)
    np.testing.assert_array_equal(pairs.ttc_s, _straight_line_ttc(ctx))


def test_without_a_reference_every_pair_is_predicted_in_straight_lines() -> None:
    record = _bend_run(25.0, 20.0, 45.0, duration_s=2.0)
    record = dataclasses.replace(record, road=RoadRecord(lanes=record.road.lanes))
    ctx, pairs = _pairs(record)
    assert not np.any(pairs.on_road)
    np.testing.assert_array_equal(pairs.ttc_s, _straight_line_ttc(ctx))


# --------------------------------------------------------------------------- replayed cars


def test_a_replayed_car_counts_ahead_only_while_wholly_ahead_on_a_bend() -> None:
    # a replayed car (blind to the ego) overlapping the ego's length in the same lane is
    # behind (it drives into the ego); once its rear is past the ego's front it is ahead
    alongside = _bend_run(20.0, 20.0, 2.0, duration_s=1.0, agent=AGENT_REPLAYED)
    _, pairs = _pairs(alongside)
    assert not np.any(pairs.ahead)
    clear = _bend_run(20.0, 20.0, L_M + 0.5, duration_s=1.0, agent=AGENT_REPLAYED)
    _, pairs = _pairs(clear)
    assert np.all(pairs.ahead)
    same = _bend_run(20.0, 20.0, 2.0, duration_s=1.0)  # a SUMO car there is ahead
    _, pairs = _pairs(same)
    assert np.all(pairs.ahead)


# --------------------------------------------------------------------------- the projection


def _brute_force(ref: np.ndarray, x: np.ndarray, y: np.ndarray, k_lo: int = 0,
                 k_hi: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(s, d) of the nearest foot on segments k_lo..k_hi (numpy, every segment)."""
    seg = np.diff(ref, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(length)])
    k_hi = len(seg) - 1 if k_hi is None else k_hi
    ks = np.arange(k_lo, k_hi + 1)
    px = x[:, None] - ref[ks, 0]
    py = y[:, None] - ref[ks, 1]
    t = (px * seg[ks, 0] + py * seg[ks, 1]) / length[ks] ** 2
    t = np.where(ks > 0, np.maximum(t, 0.0), t)
    t = np.where(ks < len(seg) - 1, np.minimum(t, 1.0), t)
    dx, dy = px - t * seg[ks, 0], py - t * seg[ks, 1]
    j = np.argmin(dx * dx + dy * dy, axis=1)
    i = np.arange(x.size)
    cross = seg[ks[j], 0] * py[i, j] - seg[ks[j], 1] * px[i, j]
    s = cum[ks[j]] + t[i, j] * length[ks[j]]
    return s, np.sign(cross) * np.hypot(dx[i, j], dy[i, j])


def test_the_projection_is_the_nearest_foot_exactly() -> None:
    rng = np.random.default_rng(7)
    u = np.linspace(0.0, 900.0, 700)
    ref = np.stack([u, 40.0 * np.sin(u / 90.0) + 0.2 * rng.normal(size=u.size)], axis=-1)
    x = rng.uniform(-60.0, 960.0, 3000)  # beyond both ends too
    y = 40.0 * np.sin(x / 90.0) + rng.uniform(-25.0, 25.0, x.size)
    got = polyline_frenet(ref, x, y)
    s, d = _brute_force(ref, x, y)
    np.testing.assert_allclose(got.s_m, s, atol=1e-9)
    np.testing.assert_allclose(got.d_m, d, atol=1e-9)
    assert np.min(got.s_m) < 0.0 and np.max(got.s_m) > 900.0


def test_tangent_and_curvature_of_a_sampled_circle() -> None:
    a = np.linspace(-0.2, 2.0, 300)
    x, y = _on_circle(a)
    ref = np.stack([x, y], axis=-1)
    q = np.linspace(0.0, 1.8, 50)
    px, py = _on_circle(q, R_M - 3.5)
    got = polyline_frenet(ref, px, py)
    np.testing.assert_allclose(got.tangent_rad, q, atol=1e-4)
    np.testing.assert_allclose(got.curvature_1pm, 1.0 / R_M, rtol=1e-4)
    np.testing.assert_allclose(got.d_m, 3.5, atol=0.01)  # chords inside the arc by 7 mm


def test_a_hint_keeps_a_point_on_its_own_part_of_a_hairpin() -> None:
    # a hairpin whose two legs are 12 m apart: a point 7 m off the outbound leg is
    # nearer the return leg; searched near where it belongs, it stays on its leg
    out = np.stack([np.linspace(0.0, 200.0, 201), np.zeros(201)], axis=-1)
    turn = np.stack([200.0 + 6.0 * np.sin(np.linspace(0, math.pi, 20)),
                     6.0 - 6.0 * np.cos(np.linspace(0, math.pi, 20))], axis=-1)
    back = np.stack([np.linspace(200.0, 0.0, 201), np.full(201, 12.0)], axis=-1)
    ref = np.concatenate([out, turn[1:-1], back])
    x, y = np.array([100.0]), np.array([7.0])
    assert polyline_frenet(ref, x, y).s_m[0] > 300.0  # the return leg
    hinted = polyline_frenet(ref, x, y, np.array([98.0]), np.array([30.0]))
    assert hinted.s_m[0] == pytest.approx(100.0) and hinted.d_m[0] == pytest.approx(7.0)
    # a trajectory along the outbound leg, placed on it at its start, is tracked on it
    # (the hint of the first point only: later points are searched near the previous)
    start = np.full(76, np.nan)
    start[0] = 0.0
    track = polyline_frenet(ref, np.linspace(0.0, 150.0, 76), np.full(76, 7.0), start,
                            np.full(76, 10.0), track=True)
    np.testing.assert_allclose(track.s_m, np.linspace(0.0, 150.0, 76), atol=1e-9)


def test_degenerate_references_give_no_frame() -> None:
    x = np.array([1.0, 2.0])
    for ref in (np.zeros((0, 2)), np.array([[0.0, 0.0]]), np.array([[1.0, 1.0], [1.0, 1.0]]),
                np.array([[0.0, 0.0], [np.nan, 1.0]])):
        frame = polyline_frenet(ref, x, x)
        assert np.all(np.isnan(frame.s_m)) and np.all(np.isnan(frame.curvature_1pm))
    # a repeated or non-finite vertex is dropped, the rest is used
    frame = polyline_frenet(np.array([[0.0, 0.0], [0.0, 0.0], [np.nan, 5.0], [10.0, 0.0]]),
                            np.array([4.0, np.nan]), np.array([-2.0, 0.0]))
    assert frame.s_m[0] == pytest.approx(4.0) and frame.d_m[0] == pytest.approx(-2.0)
    assert np.isnan(frame.s_m[1])
