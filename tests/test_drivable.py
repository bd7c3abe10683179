"""The drivable area (reports.metrics.drivable): known answers on its geometry, the lane
drop and the taper of tests/feature_nets.py (both spreads) with synthetic ego traces, and
the boundary an off-road verdict names."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import synthetic_runs as sr
from feature_nets import lane_drop_net, taper_net

from reports.geometry import polygons_excess
from reports.html.failures import failure_detail
from reports.metrics.drivable import OFFROAD_TOLERANCE_M, drivable_area, lane_pieces
from reports.record import RoadRecord, RunRecord, Trace, load_run
from reports.record.verdict import CROSSING_SIDES, BoundaryCrossing
from suite.road.network import RoadNetwork
from suite.road.record import route_lane_records
from suite.road.route_reference import build_reference

HALF_W = 0.5 * sr.EGO_WIDTH_M


# ----------------------------------------------------------------- geometry kernel


def test_polygons_excess_known_answers() -> None:
    square = np.array([[[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]])
    pts = np.array([[1.0, 0.5], [1.0, 0.2], [3.0, 0.5], [3.0, 2.0], [np.nan, 0.0]])
    excess, piece, edge = polygons_excess(pts, square)
    np.testing.assert_allclose(excess[:4], [-0.5, -0.2, 1.0, math.sqrt(2.0)], atol=1e-12)
    assert math.isnan(excess[4]) and piece[4] == -1
    assert list(piece[:4]) == [0, 0, 0, 0]
    assert edge[1] == 0 and edge[2] == 1  # nearest: the bottom edge, the right edge
    # a triangle stored as a quad (its last vertex repeated), beside the square
    tri = np.array([[[2.0, 0.0], [3.0, 0.0], [2.0, 1.0], [2.0, 1.0]]])
    both = np.concatenate([square, tri])
    excess, piece, _ = polygons_excess(np.array([[2.2, 0.3], [2.0, 0.5], [3.0, 1.0]]), both)
    assert excess[0] == pytest.approx(-0.2)  # nearest side: x = 2 (0.3 to y = 0)
    assert excess[0] < 0 and piece[0] == 1
    assert excess[1] <= 0.0  # on the shared edge
    assert excess[2] == pytest.approx(1.0 / math.sqrt(2.0))  # off the hypotenuse


def test_polygons_excess_without_polygons_and_bad_shapes() -> None:
    excess, piece, _ = polygons_excess(np.zeros((2, 2)), np.zeros((0, 4, 2)))
    assert np.all(np.isinf(excess)) and np.all(piece == -1)
    with pytest.raises(ValueError):
        polygons_excess(np.zeros((1, 2)), np.zeros((1, 2, 2)))


# ----------------------------------------------------------------- lane strips


def _point_in_polygon(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Even-odd ray casting (an independent point-in-polygon for any simple polygon)."""
    inside = np.zeros(pts.shape[0], dtype=bool)
    x, y = pts[:, 0], pts[:, 1]
    for (x1, y1), (x2, y2) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        crosses = (y1 > y) != (y2 > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
        inside ^= crosses & (x < x_at)
    return inside


def _offset_polygon(shape: np.ndarray, half_w: float) -> np.ndarray:
    """SUMO's lane outline: the centreline offset by ±half_w with miter joins, as one
    polygon (the right boundary forward, the left one back)."""
    d = np.diff(shape, axis=0)
    d /= np.hypot(d[:, 0], d[:, 1])[:, None]
    n = np.stack([-d[:, 1], d[:, 0]], axis=1)
    vn = np.concatenate([n[:1], n[:-1] + n[1:], n[-1:]])
    scale = np.ones(len(shape))
    scale[1:-1] = 1.0 / (1.0 + np.sum(n[:-1] * n[1:], axis=1))
    off = vn * (half_w * scale)[:, None]
    return np.concatenate([shape - off, (shape + off)[::-1]])


def test_straight_lane_is_flat_at_its_ends() -> None:
    shape = np.array([[0.0, 0.0], [100.0, 0.0]])
    polys, sides = lane_pieces(shape, 3.5)
    assert polys.shape == (1, 4, 2)
    excess, _, edge = polygons_excess(np.array([[101.0, 0.0], [50.0, 1.95], [-0.5, -1.0]]),
                                      polys)
    np.testing.assert_allclose(excess, [1.0, 0.2, 0.5], atol=1e-12)  # no round cap
    assert [CROSSING_SIDES[sides[0, j]] for j in edge] == ["end", "left", "start"]


def test_kinked_lane_is_its_offset_outline() -> None:
    """Points inside SUMO's outline (miter joins) of a kinked lane have excess <= 0, points
    outside > 0, and outside the excess is the distance to the outline."""
    heading = np.cumsum(np.radians([0.0, 5.0, 20.0, -30.0, 2.0]))
    steps = np.array([40.0, 30.0, 25.0, 35.0, 40.0])
    shape = np.concatenate([[[0.0, 0.0]], np.cumsum(np.stack(
        [steps * np.cos(heading), steps * np.sin(heading)], axis=1), axis=0)])
    polys, _ = lane_pieces(shape, 3.5)
    outline = _offset_polygon(shape, 1.75)
    rng = np.random.default_rng(3)
    lo, hi = outline.min(axis=0) - 3.0, outline.max(axis=0) + 3.0
    pts = lo + rng.random((20000, 2)) * (hi - lo)
    ccw = _orient(polys)
    excess, _, _ = polygons_excess(pts, ccw)
    inside = _point_in_polygon(pts, outline)
    a, b = outline, np.roll(outline, -1, axis=0)
    dist = np.min([_segment_distance(pts, p, q) for p, q in zip(a, b, strict=True)], axis=0)
    clear = dist > 1e-6
    assert np.all(excess[inside & clear] <= 0.0)
    assert np.all(excess[~inside & clear] > 0.0)
    np.testing.assert_allclose(excess[~inside], dist[~inside], atol=1e-9)


def _orient(polys: np.ndarray) -> np.ndarray:
    x, y = polys[..., 0], polys[..., 1]
    area2 = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    out = polys.copy()
    out[area2 < 0] = out[area2 < 0][:, ::-1]
    return out


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(((p - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    out: np.ndarray = np.hypot(*(p - (a + t[:, None] * ab)).T)
    return out


# ----------------------------------------------------------------- the feature nets

NETS = [("drop", "right"), ("drop", "center"), ("taper", "right"), ("taper", "center")]


@pytest.fixture(scope="module")
def nets(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], Path]:
    out = tmp_path_factory.mktemp("feature_nets")
    made = {}
    for kind, spread in NETS:
        build = lane_drop_net if kind == "drop" else taper_net
        made[(kind, spread)] = build(out, name=f"{kind}_{spread}", spread=spread)
    return made


def _road(net: Path) -> RoadRecord:
    network = RoadNetwork.load(net)
    route = network.default_route()
    return RoadRecord(lanes=route_lane_records(network, route), route=route)


def _lane(road: RoadRecord, lane_id: str) -> tuple[float, float]:
    """(centre y, width) of a straight lane of a feature net."""
    lane = next(ln for ln in road.lanes if ln.id == lane_id)
    return float(lane.shape_xy_m[0, 1]), lane.width_m


@pytest.mark.parametrize(("kind", "spread"), NETS)
def test_every_lane_and_junction_lane_is_drivable(nets: dict[tuple[str, str], Path], kind: str,
                                                  spread: str) -> None:
    """Random points inside every lane's segment rectangles (internal junction lanes too)
    are inside the drivable area."""
    road = _road(nets[(kind, spread)])
    area = drivable_area(road, road.lanes)
    assert any(ln.internal for ln in road.lanes)
    rng = np.random.default_rng(0)
    for lane in road.lanes:
        shape = lane.shape_xy_m
        for a, b in zip(shape[:-1], shape[1:], strict=True):
            d = (b - a) / np.hypot(*(b - a))
            n = np.array([-d[1], d[0]])
            u = rng.random((200, 1))
            v = (rng.random((200, 1)) - 0.5) * lane.width_m
            excess, _, _ = area.excess(a + u * (b - a) + v * n)
            assert np.all(excess <= 1e-9), lane.id


def _junction_x(road: RoadRecord, ending: str) -> tuple[float, float]:
    """(x where lane ``ending`` ends, x where the next edge starts)."""
    lane = next(ln for ln in road.lanes if ln.id == ending)
    edge = road.route[road.route.index(lane.edge_id) + 1]
    start = next(ln for ln in road.lanes if ln.edge_id == edge)
    return float(lane.shape_xy_m[-1, 0]), float(start.shape_xy_m[0, 0])


@pytest.mark.parametrize(("kind", "spread"), NETS)
def test_wedge_where_the_lane_ends_and_beyond_it(nets: dict[tuple[str, str], Path], kind: str,
                                                 spread: str) -> None:
    """Inside the wedge between the ending lane's outer end corner and the next edge's
    right edge a point is on the road (the old capsules missed it); beyond the line
    joining them it is off by its distance to that line."""
    road = _road(nets[(kind, spread)])
    ending = "a_0" if kind == "drop" else "t_0"
    x0, x1 = _junction_x(road, ending)
    y_end, w_end = _lane(road, ending)
    y_next, w_next = _lane(road, "b_0")
    p = np.array([x0, y_end - 0.5 * w_end])  # the ending lane's outer end corner
    q = np.array([x1, y_next - 0.5 * w_next])  # where the next edge's right edge starts
    mid = 0.5 * (p + q)
    normal = np.array([q[1] - p[1], -(q[0] - p[0])]) / np.hypot(*(q - p))  # to the right
    area = drivable_area(road, road.lanes)
    excess, piece, edge = area.excess(np.array([mid - 0.3 * normal, mid + 0.25 * normal]))
    assert excess[0] <= 0.0
    assert excess[1] == pytest.approx(0.25, abs=1e-9)
    owner = area.owners[area.owner[piece[1]]]
    assert (owner.kind, owner.edge_id, owner.to_edge_id) == ("junction", road.route[-2], "b")
    assert CROSSING_SIDES[area.side[piece[1], edge[1]]] == "right"


def _trace_along(xs: np.ndarray, ys: np.ndarray, speed_mps: float = 25.0) -> Trace:
    psi = np.arctan2(np.gradient(ys), np.gradient(xs))
    ds = np.hypot(np.diff(xs), np.diff(ys))
    t = np.concatenate([[0.0], np.cumsum(ds / speed_mps)])
    return sr.kinematic_trace(t, xs, ys, psi, np.full(xs.size, speed_mps))


def _smoothstep_y(xs: np.ndarray, knots_x: list[float], knots_y: list[float]) -> np.ndarray:
    u = np.clip((xs[:, None] - np.array(knots_x[:-1])) / np.diff(knots_x), 0.0, 1.0)
    return float(knots_y[0]) + np.sum(np.diff(knots_y) * u * u * (3.0 - 2.0 * u), axis=1)


def _judge(road: RoadRecord, trace: sr.Trace) -> RunRecord:
    return sr.judge(sr.make_record(trace, road=road))


@pytest.mark.parametrize(("kind", "spread"), NETS)
@pytest.mark.parametrize("lane", [1, 2])
@pytest.mark.parametrize("deviation_m", [-0.3, 0.0, 0.3])
def test_ego_keeping_a_continuing_lane_is_never_off_road(
        nets: dict[tuple[str, str], Path], kind: str, spread: str, lane: int,
        deviation_m: float) -> None:
    """On the reference of the lane (which crosses netconvert's half-lane shifts as a long
    S), or beside it by a tracking error."""
    net = nets[(kind, spread)]
    network = RoadNetwork.load(net)
    road = _road(net)
    ref = build_reference(network, road.route, 300.0, lane).points_xy_m
    step = np.hypot(*np.diff(ref, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(step)])
    grid = np.arange(0.0, s[-1] - 5.0, 0.5)
    xs, ys = np.interp(grid, s, ref[:, 0]), np.interp(grid, s, ref[:, 1])
    psi = np.arctan2(np.gradient(ys), np.gradient(xs))
    xs, ys = xs - deviation_m * np.sin(psi), ys + deviation_m * np.cos(psi)
    keep = (xs > 350.0) & (xs < 1400.0)
    run = _judge(road, _trace_along(xs[keep], ys[keep]))
    assert run.verdict is not None
    assert run.verdict.value("offroad_s") == 0.0
    assert run.verdict.value("max_offroad_m") <= OFFROAD_TOLERANCE_M


# (knots x, knots y) of a smooth lane change out of the ending lane to the left, per net;
# the late ones pass the lane's end with the rear still in it
LEAVING = {
    ("drop", "right"): [([420, 480, 596], [-8.75, -8.75, -5.25]),
                        ([420, 550, 615], [-8.75, -8.75, -5.25])],
    ("drop", "center"): [([420, 480, 596], [-3.5, -3.5, -1.75]),
                         ([420, 560, 620], [-3.5, -3.5, -1.75])],
    ("taper", "right"): [([420, 480, 598], [-8.75, -8.75, -5.25])],
    ("taper", "center"): [([420, 480, 598, 700, 760], [-3.5, -3.5, -0.875, -0.875, -1.75]),
                          ([420, 660, 730], [-3.5, -3.5, -1.75])],
}


@pytest.mark.parametrize(("kind", "spread"), NETS)
def test_ego_leaving_the_ending_lane_smoothly_is_never_off_road(
        nets: dict[tuple[str, str], Path], kind: str, spread: str) -> None:
    road = _road(nets[(kind, spread)])
    xs = np.arange(430.0, 1000.0, 0.5)
    for knots_x, knots_y in LEAVING[(kind, spread)]:
        run = _judge(road, _trace_along(xs, _smoothstep_y(xs, knots_x, knots_y)))
        assert run.verdict is not None
        assert run.verdict.value("offroad_s") == 0.0, knots_x
        assert run.verdict.metric("offroad_s").crossing is None


@pytest.mark.parametrize(("kind", "spread"), NETS)
def test_ego_beyond_the_right_edge_is_off_road_by_its_distance(
        nets: dict[tuple[str, str], Path], kind: str, spread: str) -> None:
    """Straight on in the ending lane's line (drop), or 0.5 m right of the narrowed lane
    (taper): off-road on every row past the junction by the known excess, the verdict
    naming the right edge of the lane beside."""
    road = _road(nets[(kind, spread)])
    if kind == "drop":
        y_ego, x_from, x_to, beside = _lane(road, "a_0")[0], 620.0, 1400.0, "b_0"
    else:
        y_t0, w_t0 = _lane(road, "t_0")
        y_ego, x_from, x_to, beside = y_t0 - 0.5 * w_t0 - 0.5 + HALF_W, 610.0, 705.0, "t_0"
    y_edge = _lane(road, beside)[0] - 0.5 * _lane(road, beside)[1]
    xs = np.arange(x_from, x_to, 0.5)
    run = _judge(road, _trace_along(xs, np.full(xs.size, y_ego)))
    assert run.verdict is not None and run.series is not None
    expected = y_edge - (y_ego - HALF_W)
    assert expected > OFFROAD_TOLERANCE_M
    np.testing.assert_allclose(run.series.offroad_excess_m, expected, atol=1e-9)
    assert run.verdict.value("offroad_s") > 0.0
    crossing = run.verdict.metric("offroad_s").crossing
    assert crossing is not None and crossing == run.verdict.metric("max_offroad_m").crossing
    assert (crossing.kind, crossing.lane_id, crossing.side) == ("lane", beside, "right")
    assert crossing.excess_m == pytest.approx(expected, abs=1e-9)
    assert crossing.corner in ("rear-right", "front-right")
    off = next(f for f in run.verdict.failures if f.criterion == "max_offroad_s")
    assert beside in failure_detail(off, run.verdict.metrics)


def test_the_end_of_the_route_is_a_boundary(nets: dict[tuple[str, str], Path]) -> None:
    road = _road(nets[("drop", "right")])
    area = drivable_area(road, road.lanes)
    end_x = float(next(ln for ln in road.lanes if ln.id == "b_0").shape_xy_m[-1, 0])
    excess, piece, edge = area.excess(np.array([[end_x + 1.0, -5.25]]))
    assert excess[0] == pytest.approx(1.0)
    assert area.owners[area.owner[piece[0]]].lane_id == "b_0"
    assert CROSSING_SIDES[area.side[piece[0], edge[0]]] == "end"


# ----------------------------------------------------------------- the typed record


def test_crossing_is_validated() -> None:
    good = {"kind": "lane", "lane_id": "a_0", "edge_id": "a", "side": "right",
            "excess_m": 0.4, "step": 3, "t_s": 0.15, "corner": "front-right"}
    BoundaryCrossing(**good)  # type: ignore[arg-type]
    for key, bad in (("kind", "road"), ("side", "up"), ("excess_m", 0.0),
                     ("excess_m", math.nan), ("step", -1), ("corner", "nose")):
        with pytest.raises(ValueError):
            BoundaryCrossing(**{**good, key: bad})  # type: ignore[arg-type]


def test_crossing_round_trips_through_the_run_directory(tmp_path: Path) -> None:
    trace = sr.straight_trace(5.0, 0.05, 20.0, y_m=-1.75 - 0.6 + HALF_W)  # 0.6 m off
    run_dir = sr.write_run(tmp_path / "off", trace, road=sr.straight_road(n_lanes=1))
    verdict = load_run(run_dir).verdict
    assert verdict is not None
    crossing = verdict.metric("offroad_s").crossing
    assert crossing is not None
    assert (crossing.lane_id, crossing.side) == ("E0_0", "right")
    assert crossing.excess_m == pytest.approx(0.6)
    assert crossing == verdict.metric("max_offroad_m").crossing
