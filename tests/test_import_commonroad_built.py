"""Issue #31, item 2, "recorded roads as built": CommonRoad files written here with
commonroad-io's own classes and XML writer, each with a known answer.

* **Widths.** Two lanes of 3.5 m along a 1000 m-radius arc whose bounds' vertices are
  not opposite (the left bound's i-th vertex ~19.7 m ahead of the right bound's, as in
  exiD; the outer bound spaced unevenly): every lane of the net is 3.5 m wide (0.05 m)
  and lies on the true centre arc. Pairing the i-th vertices measures ~19.8 m.
* **A wedge at a lane gain** (exiD's exits): lanelet 9 splits into its through lane 13
  and a 3.3 m wedge 50 skewed ~34 deg across the road, which leads into lane 22 opening
  between 13 and 49. The wedge becomes a junction link (9 -> 22), not a lane: 2 lanes
  in, 3 lanes out, lane 9 connected to both 13 and 22. Imported as a lane (connectors
  switched off), the same file is refused with *inconsistent adjacency*. The same road
  driven the other way is a lane drop at an entry: 22 ends through the wedge into 9.
* **The ego's start pose.** An ego recorded mid lane change (1.6 m left of its lane's
  centre, 0.06 rad towards the next lane, on the arc): the run's initial state, built by
  :func:`suite.run.runner.ego_start_state` (the lines ``_build`` runs), puts its front
  bumper and box centre within 0.05 m of the recorded pose, centre + L/2 along the
  heading, read from the file with commonroad-io (not the importer's reader), heading
  within 0.01 rad. The catalog's ``lateral_offset_m`` / ``heading_rad`` are checked
  against the arc's own geometry. The same check on the shared development files.

Along-road dependency: none of these assertions depends on the route-position ->
reference arc-length mapping (suite/road/route_reference.py): an ego with a start pose is
placed from the lane frame of the net file (:mod:`suite.road.lane_pose`), not through the
reference. Only an ego *without* the keys (today's placement, unchanged) goes through it.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("commonroad.common.writer.file_writer_xml")

from controllers.plant.vehicle_model import VehicleParams  # noqa: E402
from suite.catalog import load_catalog  # noqa: E402
from suite.catalog.errors import CatalogError  # noqa: E402
from suite.catalog.specs import EgoSpec, Scenario  # noqa: E402
from suite.importers.commonroad import (  # noqa: E402
    FileResult,
    ImportFailure,
    ImportParams,
    import_file,
    import_files,
)
from suite.importers.commonroad import connectors as connectors_mod  # noqa: E402
from suite.importers.commonroad.geometry import (  # noqa: E402
    bound_width_m,
    pair_bounds,
    pair_skew_m,
    project,
)
from suite.road.network import RoadNetwork  # noqa: E402
from suite.run.runner import ego_start_state  # noqa: E402

W = 3.5  # lane width [m]
R = 1000.0  # arc radius [m]
ARC_M = 300.0  # arc length [m]
SHIFT_M = 19.7  # how far the left bound's vertices run ahead of the right bound's [m]
TOL_M = 0.05
TOL_RAD = 0.01
SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "commonroad"

Samples = Sequence[tuple[int, float, float, float, float]]  # (step, x, y, heading, speed)


@dataclass(frozen=True)
class LL:
    """A lanelet by its bounds (n, 2) [m], relations and same-direction neighbours."""

    lid: int
    left: np.ndarray
    right: np.ndarray
    succ: tuple[int, ...] = ()
    pred: tuple[int, ...] = ()
    left_nb: int | None = None
    right_nb: int | None = None


def write_xml(path: Path, lanelets: Sequence[LL], ego: tuple[float, float, float, float],
              cars: Sequence[tuple[int, Samples]] = (), dt_s: float = 0.1) -> Path:
    """A CommonRoad 2020a file: ``lanelets``, recorded ``cars`` and the ego's initial state
    (centre x, y [m], heading [rad], speed [m/s]) at time step 0."""
    from commonroad.common.util import Interval
    from commonroad.common.writer.file_writer_interface import OverwriteExistingFile
    from commonroad.common.writer.file_writer_xml import XMLFileWriter
    from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork, LaneletType
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.scenario import Scenario as CrScenario
    from commonroad.scenario.scenario import ScenarioID, Tag
    from commonroad.scenario.state import CustomState, InitialState, KSState
    from commonroad.scenario.trajectory import Trajectory

    scenario = CrScenario(dt_s, ScenarioID(country_id="DEU", map_name="Built"))
    net = LaneletNetwork()
    for ll in lanelets:
        net.add_lanelet(Lanelet(
            ll.left, 0.5 * (ll.left + ll.right), ll.right, ll.lid, predecessor=list(ll.pred),
            successor=list(ll.succ), adjacent_left=ll.left_nb,
            adjacent_left_same_direction=True if ll.left_nb is not None else None,
            adjacent_right=ll.right_nb,
            adjacent_right_same_direction=True if ll.right_nb is not None else None,
            lanelet_type={LaneletType.HIGHWAY}))
    scenario.add_objects(net)
    shape = RectObstacleShape(width=1.8, length=4.5)
    for oid, samples in cars:
        k0, x0, y0, h0, v0 = samples[0]
        init = InitialState(time_step=k0, position=np.array([x0, y0]), orientation=h0,
                            velocity=v0, acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
        traj = Trajectory(k0 + 1, [KSState(time_step=k, position=np.array([x, y]),
                                           orientation=h, velocity=v, steering_angle=0.0)
                                   for k, x, y, h, v in samples[1:]])
        scenario.add_objects(DynamicObstacle(oid, ObstacleType.CAR, shape, init,
                                             TrajectoryPrediction(traj, shape)))
    x, y, h, v = ego
    init = InitialState(time_step=0, position=np.array([x, y]), orientation=h, velocity=v,
                        acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
    goal = GoalRegion([CustomState(time_step=Interval(0, 50))])
    XMLFileWriter(scenario, PlanningProblemSet([PlanningProblem(9000, init, goal)]),
                  author="hwyeval tests", affiliation="hwyeval", source="built",
                  tags={Tag.HIGHWAY}).write_to_file(str(path), OverwriteExistingFile.ALWAYS)
    return path


def _import(tmp_path: Path, src: Path) -> FileResult:
    outcome = import_files([src], tmp_path / "out", ImportParams())
    assert not outcome.failures, outcome.failures
    return outcome.results[0]


def _scenario(r: FileResult) -> Scenario:
    return load_catalog(r.net_path.parent / "catalog.toml").get(r.name)


def _lane_widths(network: RoadNetwork, recorded_only: bool = True) -> list[float]:
    return [ln.width_m for eid in network.edge_ids()
            if not (recorded_only and "-" in eid) for ln in network.lane_info((eid,))]


# --- (1) bounds with non-opposite vertices on an arc ---------------------------------------


def arc_at(s_m: float, d_m: float) -> np.ndarray:
    """The point ``d_m`` left of the arc (centre (0, R), turning left from (0, 0) heading
    +x) at arc length ``s_m``: radius R - d_m."""
    th = s_m / R
    return np.array([(R - d_m) * math.sin(th), R - (R - d_m) * math.cos(th)])


def arc_bound(d_m: float, s_m: np.ndarray) -> np.ndarray:
    return np.array([arc_at(float(s), d_m) for s in s_m])


def arc_layout(n: int = 61) -> list[LL]:
    """Lanelets 100 (right, centre d = 0) and 101 (left, d = W) over ARC_M of the arc.
    100's right bound: interior vertices every ~4.6 m; its left bound (= 101's right):
    each interior vertex SHIFT_M further along; 101's left bound: spaced as
    (i / n)^1.3."""
    i = np.arange(n, dtype=np.float64)
    step = (ARC_M - SHIFT_M - 1.0) / (n - 2)
    even = np.concatenate([[0.0], i[1:-1] * step, [ARC_M]])
    ahead = np.concatenate([[0.0], SHIFT_M + i[1:-1] * step, [ARC_M]])
    uneven = ARC_M * (i / (n - 1)) ** 1.3
    mid = arc_bound(0.5 * W, ahead)
    return [LL(100, mid, arc_bound(-0.5 * W, even), left_nb=101),
            LL(101, arc_bound(1.5 * W, uneven), mid, right_nb=100)]


def arc_pose(s_m: float, d_m: float, rel_heading_rad: float) -> tuple[float, float, float]:
    x, y = arc_at(s_m, d_m)
    return float(x), float(y), s_m / R + rel_heading_rad


def arc_car(oid: int, s0_m: float, d_m: float, speed_mps: float) -> tuple[int, Samples]:
    out = []
    for k in range(40):
        x, y, h = arc_pose(s0_m + speed_mps * 0.1 * k, d_m, 0.0)
        out.append((k, x, y, h, speed_mps))
    return oid, out


MID_CHANGE = (150.0, 1.6, 0.06)  # the ego: arc length, offset from lane 0, heading [m, m, rad]


@pytest.fixture(scope="module")
def arc_import(tmp_path_factory: pytest.TempPathFactory) -> tuple[FileResult, Path]:
    tmp = tmp_path_factory.mktemp("arc")
    x, y, h = arc_pose(*MID_CHANGE)
    src = write_xml(tmp / "DEU_BuiltArc-1_1_T-1.xml", arc_layout(), (x, y, h, 27.0),
                    [arc_car(1, 60.0, 0.0, 27.0), arc_car(2, 200.0, W, 30.0)])
    return _import(tmp, src), src


def test_the_arc_fixture_has_non_opposite_vertices() -> None:
    """The case exiD is: pairing the i-th left and right vertex measures a diagonal."""
    ll = arc_layout()[0]
    paired = float(np.median(np.hypot(*(ll.left - ll.right).T)))
    assert paired > 19.0
    assert pair_skew_m(ll.left, ll.right) > 15.0


def test_imported_lane_widths_are_perpendicular(arc_import: tuple[FileResult, Path]) -> None:
    r, _ = arc_import
    network = RoadNetwork.load(r.net_path)
    widths = _lane_widths(network)
    assert widths and max(abs(w - W) for w in widths) <= TOL_M, widths


def test_imported_lane_shapes_lie_on_the_true_centre_arcs(arc_import: tuple[FileResult, Path]
                                                          ) -> None:
    """Every vertex of a recorded lane's shape is at radius R - d of its lane (0.05 m):
    the centre line is the mean of opposite points, not of the i-th vertices."""
    r, _ = arc_import
    network = RoadNetwork.load(r.net_path)
    worst = 0.0
    for eid in network.edge_ids():
        if "-" in eid:
            continue
        for ln in network.lane_info((eid,)):
            radius = np.hypot(ln.shape_xy_m[:, 0], ln.shape_xy_m[:, 1] - R)
            worst = max(worst, float(np.max(np.abs(radius - (R - ln.index * W)))))
    assert worst <= TOL_M


@pytest.mark.parametrize("n_right", [2, 5, 37])
def test_width_and_pairing_with_different_vertex_counts(n_right: int) -> None:
    """Bounds of different vertex counts and spacings (which commonroad-io's XML reader
    itself refuses, but a bound may come so from elsewhere): the width is 3.5 m, and the
    re-paired vertices are opposite (their centre on the centre line)."""
    straight = n_right == 2
    s_left = np.linspace(0.0, 100.0, 23) ** 1.0
    s_right = np.linspace(0.0, 100.0, n_right) ** 1.2 / 100.0 ** 0.2
    if straight:
        left = np.column_stack([s_left, np.full_like(s_left, 0.5 * W)])
        right = np.column_stack([s_right, np.full_like(s_right, -0.5 * W)])
    else:
        left, right = arc_bound(0.5 * W, s_left), arc_bound(-0.5 * W, s_right)
    # the chords of a 37-vertex bound on R = 1000 m sag < 1 mm; of 5 vertices 0.13 m
    tol = 0.15 if n_right == 5 else TOL_M
    assert bound_width_m(left, right) == pytest.approx(W, abs=tol)
    pl, pr = pair_bounds(left, right)
    assert pl.shape == pr.shape and pl.shape[0] >= 3
    centre = 0.5 * (pl + pr)
    if straight:
        assert np.max(np.abs(centre[:, 1])) <= 1e-9
    else:
        radius = np.hypot(centre[:, 0], centre[:, 1] - R)
        assert np.max(np.abs(radius - R)) <= tol
    assert np.all(np.diff(centre[:, 0]) > 0.0)  # in order along the road


def test_a_lanelet_record_refuses_unpaired_or_broken_bounds() -> None:
    """Bounds reach a record paired (the reader re-pairs them); else it names itself."""
    from suite.importers.commonroad.records import LaneletRecord

    left = np.array([[0.0, 1.75], [50.0, 1.75], [100.0, 1.75]])
    right = np.array([[0.0, -1.75], [100.0, -1.75]])
    for lf, rt in ((left, right), (left[:1], right[:1]), (left * np.nan, left)):
        with pytest.raises(ValueError):
            LaneletRecord(7, lf, rt, None, None, False, (), (), ())
    paired = LaneletRecord(7, *pair_bounds(left, right), None, None, False, (), (), ())
    assert paired.width_m == pytest.approx(W)


# --- (2) a wedge at a lane gain, and the same road driven the other way ----------------------


def line(x0: float, x1: float, y0: float, y1: float, n: int = 2) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    return np.column_stack([x0 + (x1 - x0) * t, y0 + (y1 - y0) * t])


X_GAIN = 102.7  # where the wedge ends and lane 22 starts [m]


def _shift(x: np.ndarray | float) -> np.ndarray:
    """How far lane 49 has moved left at x [m]: 0 at 100 m to one lane at 160 m."""
    return np.asarray(np.clip((np.asarray(x) - 100.0) / 60.0, 0.0, 1.0) * W, dtype=np.float64)


def wedge_layout() -> list[LL]:
    """9 (right, y = 0) and 8 (left, y = W) over x 0..100 m; 9 -> 13 (through, y = 0) and
    9 -> 50 -> 22; 8 -> 49, which moves left by a lane over 100..160 m while 22 opens
    between 13 and 49 from X_GAIN (0.16 m wide there). Wedge 50: its left bound along
    49's right edge, its right bound from 9's right edge across to 22's: centre chord
    ~34 deg from the road, 3.3 m long. As in the exiD files, the wedge names 49 as its
    left neighbour."""
    xs = np.linspace(100.0, 300.0, 41)
    xs22 = np.concatenate([[X_GAIN], xs[xs > X_GAIN]])
    edge49 = 0.5 * W + _shift(xs)
    return [
        LL(9, line(0, 100, 0.5 * W, 0.5 * W, 11), line(0, 100, -0.5 * W, -0.5 * W, 11),
           succ=(13, 50), left_nb=8),
        LL(8, line(0, 100, 1.5 * W, 1.5 * W, 11), line(0, 100, 0.5 * W, 0.5 * W, 11),
           succ=(49,), right_nb=9),
        LL(13, line(100, 300, 0.5 * W, 0.5 * W, 41), line(100, 300, -0.5 * W, -0.5 * W, 41),
           pred=(9,), left_nb=22),
        LL(50, np.array([[100.0, 0.5 * W], [X_GAIN, 0.5 * W + float(_shift(X_GAIN))]]),
           np.array([[100.0, -0.5 * W], [X_GAIN, 0.5 * W]]), pred=(9,), succ=(22,),
           left_nb=49),
        LL(22, np.column_stack([xs22, 0.5 * W + _shift(xs22)]),
           np.column_stack([xs22, np.full_like(xs22, 0.5 * W)]), pred=(50,), left_nb=49,
           right_nb=13),
        LL(49, np.column_stack([xs, edge49 + W]), np.column_stack([xs, edge49]), pred=(8,),
           right_nb=22),
    ]


def reversed_layout(lanelets: Sequence[LL]) -> list[LL]:
    """The same road driven the other way: bounds reversed and swapped, successors and
    predecessors, left and right neighbours exchanged."""
    return [LL(ll.lid, ll.right[::-1].copy(), ll.left[::-1].copy(), ll.pred, ll.succ,
               ll.right_nb, ll.left_nb) for ll in lanelets]


def wedge_car(oid: int, forward: bool) -> tuple[int, Samples]:
    """A car on lane 9 at 80 m crossing the wedge into 22 (forward), or on 22 at 130 m
    crossing it into 9 (reversed), 20 m/s, 3 s."""
    out = []
    for k in range(31):
        x = 80.0 + 2.0 * k if forward else 130.0 - 2.0 * k
        y = float(np.interp(x, [0.0, 100.0, X_GAIN, 160.0, 300.0],
                            [0.0, 0.0, 1.8, W, W]))
        out.append((k, x, y, 0.0 if forward else math.pi, 20.0))
    return oid, out


def _links(network: RoadNetwork, edge: str) -> set[tuple[int, str, int]]:
    return {(ln.from_index, ln.to_edge_id, ln.to_index) for ln in network.lane_links(edge)}


def _recorded_edges(network: RoadNetwork) -> dict[str, int]:
    return {e: network.lane_count(e) for e in network.edge_ids() if "-" not in e}


@pytest.fixture(scope="module")
def gain_import(tmp_path_factory: pytest.TempPathFactory) -> FileResult:
    tmp = tmp_path_factory.mktemp("gain")
    src = write_xml(tmp / "DEU_BuiltGain-1_1_T-1.xml", wedge_layout(),
                    (40.0, 0.0, 0.0, 25.0), [wedge_car(1, True)])
    return _import(tmp, src)


def test_a_wedge_at_a_lane_gain_is_a_junction_link(gain_import: FileResult) -> None:
    r = gain_import
    network = RoadNetwork.load(r.net_path)
    # 2 lanes in (9, 8), 3 out (13, 22, 49): no edge, no lane of the wedge
    assert _recorded_edges(network) == {"L9": 2, "L13": 3}
    assert {(0, "L13", 0), (0, "L13", 1), (1, "L13", 2)} == _links(network, "L9")
    assert any("connector" in n and "50 (9 -> 22)" in n for n in r.notes)
    assert r.kept == 1  # the car crossing the wedge is on the road
    assert r.route == ("L9-approach", "L9", "L13", "L13-extension")
    lane22 = network.lane_info(("L13",))[1].shape_xy_m
    assert float(np.min(lane22[:, 0])) >= X_GAIN - TOL_M  # 22 itself starts where it did


@pytest.mark.parametrize("x_m", [90.0, 97.0, 99.0, 100.5, 103.0, 110.0])
def test_a_pose_round_trips_through_the_lane_frame(gain_import: FileResult, x_m: float
                                                   ) -> None:
    """Before, inside and after the junction at 100 m (netconvert cut the lane shapes
    back ~4 m on either side): the pose the importer finds places the point back where
    it was (suite.road.lane_pose's forward and inverse)."""
    from suite.road.lane_pose import lane_frame, pose_in_lane

    network = RoadNetwork.load(gain_import.net_path)
    route = gain_import.route
    x, y, h = x_m, 0.3, 0.02
    pose = pose_in_lane(network, route, 300.0, lambda _: 0, x, y, h)  # lane 0: y = 0
    assert abs(pose.residual_m) <= 1e-4
    assert pose.lateral_m == pytest.approx(0.3, abs=1e-6)
    px, py, ph = lane_frame(network, route, pose.pos_m, pose.lane).place(pose.lateral_m,
                                                                         pose.heading_rad)
    assert math.hypot(px - x, py - y) <= 1e-4 and ph == pytest.approx(h, abs=1e-12)


def test_the_wedge_imported_as_a_lane_is_refused(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The failure the exiD files had: with connectors switched off the wedge is a lane
    beside its neighbours and the import stops at *inconsistent adjacency*."""
    monkeypatch.setattr(connectors_mod, "CONNECTOR_MIN_SKEW_RAD", math.pi)
    src = write_xml(tmp_path / "DEU_BuiltGain-1_2_T-1.xml", wedge_layout(),
                    (40.0, 0.0, 0.0, 25.0), [wedge_car(1, True)])
    with pytest.raises(ImportFailure) as info:
        import_file(src, tmp_path / "out", ImportParams())
    assert re.fullmatch(r"lanelet \d+(_\d+)?", info.value.element)


def test_a_wedge_at_a_lane_drop_is_a_junction_link(tmp_path: Path) -> None:
    """Driven the other way: 49 -> 8, 13 -> 9 and 22 -> (wedge) -> 9: three lanes in, two
    out, lane 22 ending into 9."""
    src = write_xml(tmp_path / "DEU_BuiltDrop-1_1_T-1.xml", reversed_layout(wedge_layout()),
                    (200.0, W, math.pi, 25.0), [wedge_car(1, False)])
    r = _import(tmp_path, src)
    network = RoadNetwork.load(r.net_path)
    assert _recorded_edges(network) == {"L49": 3, "L8": 2}
    assert {(0, "L8", 0), (1, "L8", 1), (2, "L8", 1)} == _links(network, "L49")
    assert any("connector" in n and "50 (22 -> 9)" in n for n in r.notes)
    assert r.kept == 1


def test_a_short_piece_of_a_lane_is_no_connector() -> None:
    """A 3 m lanelet that continues its neighbours' direction stays a lane."""
    from suite.importers.commonroad.records import LaneletRecord

    def rec(lid: int, x0: float, x1: float, pred: tuple[int, ...] = (),
            succ: tuple[int, ...] = ()) -> LaneletRecord:
        return LaneletRecord(lid, line(x0, x1, 0.5 * W, 0.5 * W), line(x0, x1, -0.5 * W, -0.5 * W),
                             None, None, False, succ, pred, ())

    road = {1: rec(1, 0.0, 100.0, succ=(2,)), 2: rec(2, 100.0, 103.0, (1,), (3,)),
            3: rec(3, 103.0, 200.0, pred=(2,))}
    assert not any(connectors_mod.is_connector(ll, road) for ll in road.values())
    assert connectors_mod.bridge_connectors(road).connectors == ()


# --- (3) the ego's start pose ------------------------------------------------------------------


def recorded_pose(src: Path) -> tuple[np.ndarray, float]:
    """The planning problem's initial centre [m] and heading [rad], read with
    commonroad-io (a position shape: its centre; an interval: its middle)."""
    from commonroad.common.reader.file_reader_xml import XMLFileReader

    _, problems = XMLFileReader(str(src)).open()
    init = next(iter(problems.planning_problem_dict.values())).initial_state
    pos = init.position
    centre = np.asarray(pos.center if hasattr(pos, "center") else pos, dtype=np.float64)
    h = init.orientation
    heading = 0.5 * (float(h.start) + float(h.end)) if hasattr(h, "start") else float(h)
    return centre.reshape(-1)[:2], heading


def start_errors(scenario: Scenario, src: Path) -> tuple[float, float, float]:
    """(front bumper [m], box centre [m], heading [rad]) errors of the run's initial state
    (suite.run.runner.ego_start_state) against the recorded pose."""
    vehicle = VehicleParams(friction_coeff=scenario.friction)
    state = ego_start_state(RoadNetwork.load(scenario.net_path), scenario, vehicle)
    centre, heading = recorded_pose(src)
    u = np.array([math.cos(heading), math.sin(heading)])
    front = centre + 0.5 * vehicle.length_m * u
    v = np.array([math.cos(state[2]), math.sin(state[2])])
    run_front = state[:2] + vehicle.cg_to_front_bumper_m * v
    run_centre = state[:2] + vehicle.cg_to_box_centre_m * v
    return (float(np.hypot(*(run_front - front))), float(np.hypot(*(run_centre - centre))),
            abs(math.remainder(float(state[2]) - heading, 2.0 * math.pi)))


def test_an_ego_recorded_mid_lane_change_starts_mid_lane_change(
        arc_import: tuple[FileResult, Path]) -> None:
    r, src = arc_import
    sc = _scenario(r)
    front_err, centre_err, heading_err = start_errors(sc, src)
    assert front_err <= TOL_M and centre_err <= TOL_M  # along and across the road
    assert heading_err <= TOL_RAD
    # the catalog's keys against the arc: the front bumper's offset from lane 0's centre
    # (radius R) and the heading against the arc's tangent there
    centre, heading = recorded_pose(src)
    front = centre + 0.5 * VehicleParams().length_m * np.array([math.cos(heading),
                                                               math.sin(heading)])
    assert sc.ego.lane == 0 and sc.ego.start_pose is not None
    lateral, rel_heading = sc.ego.start_pose
    assert lateral == pytest.approx(R - math.hypot(front[0], front[1] - R), abs=TOL_M)
    tangent = math.atan2(front[0], R - front[1])
    assert rel_heading == pytest.approx(heading - tangent, abs=TOL_RAD)
    assert lateral > 1.6 and rel_heading > 0.05  # mid lane change
    assert r.ego_lateral_m == pytest.approx(MID_CHANGE[1], abs=TOL_M)


@pytest.mark.slow
@pytest.mark.skipif(not SHARED.is_dir(), reason=f"{SHARED} is absent")
def test_the_shared_recordings_start_where_they_were_recorded(tmp_path: Path) -> None:
    """US-101 (2018b, 2020a) and the A 9 (2018b: a position rectangle, orientation and
    velocity intervals): the run's first pose is the recorded one."""
    files = sorted(SHARED.glob("*.xml"))
    outcome = import_files(files, tmp_path / "out", ImportParams())
    assert not outcome.failures
    catalog = load_catalog(tmp_path / "out" / "catalog.toml")
    for r in outcome.results:
        sc = catalog.get(r.name)
        assert sc.ego.start_pose is not None
        front_err, centre_err, heading_err = start_errors(sc, r.source)
        assert front_err <= TOL_M and centre_err <= TOL_M, r.name
        assert heading_err <= TOL_RAD, r.name


# --- (4) the catalog keys ----------------------------------------------------------------------


def _catalog(tmp_path: Path, ego: str) -> Path:
    path = tmp_path / "c.toml"
    path.write_text('[[scenario]]\nname = "s"\nnet = "straight_3lane"\ncontroller = '
                    f'"lane_keep"\nduration_s = 5.0\nstep_s = 0.02\nego = {{ {ego} }}\n')
    return path


def test_without_the_keys_nothing_changes(tmp_path: Path) -> None:
    """No key: no start pose, the scenario's dict (its identity) has no new key, and the
    run's initial state is the reference-path one."""
    from suite.road.lane_pose import ego_front_pose

    sc = load_catalog(_catalog(tmp_path, "lane = 1, pos_m = 50.0, speed_mps = 20.0")).get("s")
    assert sc.ego.start_pose is None
    assert set(sc.as_dict()["ego"]) == {"lane", "pos_m", "speed_mps", "target_speed_mps"}
    network = RoadNetwork.load(sc.net_path)
    assert ego_front_pose(network, sc.route, sc.ego) is None


@pytest.mark.parametrize(("lateral", "heading"), [(0.6, 0.0), (-0.9, -0.04), (0.0, 0.03)])
def test_the_keys_place_the_front_bumper_in_the_lane_frame(tmp_path: Path, lateral: float,
                                                           heading: float) -> None:
    """On a bundled straight net: the front bumper ``lateral_offset_m`` from lane 1's
    centre line at ``pos_m``, the heading ``heading_rad`` off the lane's direction."""
    sc = load_catalog(_catalog(tmp_path, f"lane = 1, pos_m = 80.0, speed_mps = 20.0, "
                               f"lateral_offset_m = {lateral}, heading_rad = {heading}")
                      ).get("s")
    network = RoadNetwork.load(sc.net_path)
    vehicle = VehicleParams()
    state = ego_start_state(network, sc, vehicle)
    d = vehicle.cg_to_front_bumper_m
    front = state[:2] + d * np.array([math.cos(state[2]), math.sin(state[2])])
    edge, u = network.locate(sc.route, 80.0)
    shape = network.lane_info((edge,))[1].shape_xy_m
    pr = project(shape, float(front[0]), float(front[1]))
    assert pr.lateral_m == pytest.approx(lateral, abs=1e-6)
    assert pr.s_m * network.edge_length_m(edge) / pr.length_m == pytest.approx(u, abs=1e-6)
    assert math.remainder(state[2] - pr.heading_rad, 2 * math.pi) == pytest.approx(heading,
                                                                                 abs=1e-9)
    assert sc.as_dict()["ego"]["lateral_offset_m"] == lateral


@pytest.mark.parametrize(("key", "value"), [("lateral_offset_m", 7.5),
                                            ("lateral_offset_m", '"left"'),
                                            ("heading_rad", 1.6), ("heading_rad", "nan"),
                                            ("heading_rad", "true")])
def test_a_bad_key_names_file_scenario_and_key(tmp_path: Path, key: str, value: object) -> None:
    path = _catalog(tmp_path, f"lane = 1, pos_m = 50.0, speed_mps = 20.0, {key} = {value}")
    with pytest.raises(CatalogError) as info:
        load_catalog(path)
    (issue,) = info.value.issues
    assert issue.key.endswith(f"ego.{key}") and issue.scenario == "s"
    assert info.value.path == path


def test_the_spec_refuses_what_the_loader_refuses() -> None:
    from suite.catalog.errors import SpecError

    with pytest.raises(SpecError):
        EgoSpec(lane=0, pos_m=1.0, speed_mps=1.0, lateral_offset_m=math.inf)
    with pytest.raises(SpecError):
        EgoSpec(lane=0, pos_m=1.0, speed_mps=1.0, heading_rad=-math.pi / 2)
    ego = EgoSpec(lane=0, pos_m=1.0, speed_mps=1.0, heading_rad=0)
    assert ego.start_pose == (0.0, 0.0) and isinstance(ego.heading_rad, float)


def test_every_ego_key_is_documented() -> None:
    doc = (Path(__file__).resolve().parents[1] / "docs" / "catalog.md").read_text()
    for key in EgoSpec._RULES:
        assert f"| `{key}` |" in doc, key
