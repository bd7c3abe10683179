"""`hwyeval import commonroad` on SYNTHETIC CommonRoad files built here with
commonroad-io's own classes (Scenario, LaneletNetwork, Lanelet, DynamicObstacle with a
TrajectoryPrediction, PlanningProblemSet, TrafficSign) and written with its XML writer:
the layouts of files the development set lacks (highD's two carriageways at 0.04 s, a
lanelet beside two consecutive lanelets, a lane drop, ramps, a curve, speed signs).

Every case: the import succeeds, the net loads with RoadNetwork, lane counts per edge
are known, every kept vehicle's first sample is on a lane within half its width, the
ego's front bumper minus half its length is the CommonRoad centre (0.5 m), and the
catalog loads."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("commonroad.common.writer.file_writer_xml")

from controllers.plant.vehicle_model import VehicleParams  # noqa: E402
from suite.catalog.tracks import read_tracks  # noqa: E402
from suite.importers.commonroad import (  # noqa: E402
    FileResult,
    ImportParams,
    import_file,
    import_files,
)
from suite.importers.commonroad.geometry import project  # noqa: E402
from suite.importers.commonroad.records import ObstacleRecord  # noqa: E402
from suite.importers.commonroad.speed import COUNTRY_DEFAULT_MPS  # noqa: E402
from suite.importers.commonroad.tracks import first_kept, to_track  # noqa: E402
from suite.road.network import RoadNetwork  # noqa: E402

W = 3.75  # lane width [m]
Ref = Callable[[float], tuple[float, float, float]]  # s -> (x, y, heading)


def straight(x0: float = 0.0, y0: float = 0.0, heading: float = 0.0) -> Ref:
    c, s = math.cos(heading), math.sin(heading)
    return lambda t: (x0 + c * t, y0 + s * t, heading)


def arc(radius_m: float) -> Ref:
    """A left-turning arc from (0, 0) heading +x, centre (0, R)."""
    return lambda t: (radius_m * math.sin(t / radius_m),
                      radius_m * (1.0 - math.cos(t / radius_m)), t / radius_m)


def at(ref: Ref, s_m: float, d_m: float) -> tuple[float, float, float]:
    """The point ``d_m`` left of the reference at ``s_m``, and the heading."""
    x, y, h = ref(s_m)
    return x - d_m * math.sin(h), y + d_m * math.cos(h), h


@dataclass
class Lane:
    """A lanelet on a reference: s0..s1 [m], centre offset d0 -> d1 (left > 0) and width
    w0 -> w1 [m] (linear along s), neighbours and types."""

    lid: int
    ref: Ref
    s0: float
    s1: float
    d0: float
    d1: float | None = None
    w0: float = W
    w1: float | None = None
    succ: list[int] = field(default_factory=list)
    pred: list[int] = field(default_factory=list)
    left: int | None = None
    left_same: bool = True
    right: int | None = None
    types: tuple[str, ...] = ("highway",)
    signs: tuple[int, ...] = ()
    step_m: float = 25.0
    centre_fn: Callable[[float], tuple[float, float, float]] | None = None

    def bounds(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = max(2, int(math.ceil((self.s1 - self.s0) / self.step_m)) + 1)
        left, centre, right = [], [], []
        for u in np.linspace(0.0, 1.0, n):
            s = self.s0 + u * (self.s1 - self.s0)
            d = self.d0 + u * ((self.d1 if self.d1 is not None else self.d0) - self.d0)
            w = self.w0 + u * ((self.w1 if self.w1 is not None else self.w0) - self.w0)
            if self.centre_fn is not None:
                x, y, h = self.centre_fn(u)
                cx, cy = x, y
                lx, ly = x - 0.5 * w * math.sin(h), y + 0.5 * w * math.cos(h)
                rx, ry = x + 0.5 * w * math.sin(h), y - 0.5 * w * math.cos(h)
            else:
                cx, cy, _ = at(self.ref, s, d)
                lx, ly, _ = at(self.ref, s, d + 0.5 * w)
                rx, ry, _ = at(self.ref, s, d - 0.5 * w)
            left.append((lx, ly))
            centre.append((cx, cy))
            right.append((rx, ry))
        return np.array(left), np.array(centre), np.array(right)


@dataclass
class Car:
    """A recorded vehicle driving along ``ref`` at offset ``d_m`` from ``s0_m`` at
    ``speed_mps`` for steps k0..k1 (heading along the reference)."""

    oid: int
    ref: Ref
    s0_m: float
    d_m: float
    speed_mps: float
    k0: int = 0
    k1: int = 100
    length_m: float = 4.5
    width_m: float = 1.8


def write_file(path: Path, lanes: Sequence[Lane], cars: Sequence[Car], ego: Car, dt_s: float,
               country: str = "DEU", signs: dict[int, tuple[str, float, int]] | None = None,
               ego_step: int = 0, goal_lanelets: Sequence[int] = ()) -> Path:
    """Write a CommonRoad 2020a XML file with commonroad-io's classes and XML writer.
    ``signs``: sign id -> (commonroad-io element name, value [m/s], lanelet)."""
    from commonroad.common.util import Interval
    from commonroad.common.writer.file_writer_xml import XMLFileWriter
    from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork, LaneletType
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.scenario import Scenario, ScenarioID, Tag
    from commonroad.scenario.state import CustomState, InitialState, KSState
    from commonroad.scenario.traffic_sign import (
        TrafficSign,
        TrafficSignElement,
        TrafficSignIDCountries,
    )
    from commonroad.scenario.trajectory import Trajectory

    scenario = Scenario(dt_s, ScenarioID(country_id=country, map_name="Synthetic"))
    net = LaneletNetwork()
    by_type = {t.value: t for t in LaneletType}
    for ln in lanes:
        lv, cv, rv = ln.bounds()
        net.add_lanelet(Lanelet(
            lv, cv, rv, ln.lid, predecessor=list(ln.pred), successor=list(ln.succ),
            adjacent_left=ln.left, adjacent_left_same_direction=ln.left_same
            if ln.left is not None else None,
            adjacent_right=ln.right, adjacent_right_same_direction=True
            if ln.right is not None else None,
            lanelet_type={by_type[t] for t in ln.types},
            traffic_signs=set(ln.signs)))
    ids_enum = TrafficSignIDCountries[country]
    for sid, (name, value, lanelet) in (signs or {}).items():
        element = TrafficSignElement(ids_enum[name], [f"{value:g}"])
        lv, _, _ = next(ln for ln in lanes if ln.lid == lanelet).bounds()
        net.add_traffic_sign(TrafficSign(sid, [element], {lanelet}, lv[0]), set())
    scenario.add_objects(net)
    for car in cars:
        states = []
        for k in range(car.k0, car.k1 + 1):
            x, y, h = at(car.ref, car.s0_m + car.speed_mps * (k - car.k0) * dt_s, car.d_m)
            states.append((k, np.array([x, y]), h))
        k, p, h = states[0]
        init = InitialState(time_step=k, position=p, orientation=h, velocity=car.speed_mps,
                            acceleration=0.0, yaw_rate=0.0, slip_angle=0.0)
        traj = Trajectory(car.k0 + 1, [KSState(time_step=k, position=p, orientation=h,
                                               velocity=car.speed_mps, steering_angle=0.0)
                                       for k, p, h in states[1:]])
        shape = RectObstacleShape(width=car.width_m, length=car.length_m)
        scenario.add_objects(DynamicObstacle(car.oid, ObstacleType.CAR, shape, init,
                                             TrajectoryPrediction(traj, shape)))
    x, y, h = at(ego.ref, ego.s0_m, ego.d_m)
    init = InitialState(time_step=ego_step, position=np.array([x, y]), orientation=h,
                        velocity=ego.speed_mps, acceleration=0.0, yaw_rate=0.0,
                        slip_angle=0.0)
    goal = GoalRegion([CustomState(time_step=Interval(ego_step, ego_step + ego.k1))],
                      {0: list(goal_lanelets)} if goal_lanelets else None)
    problems = PlanningProblemSet([PlanningProblem(ego.oid, init, goal)])
    XMLFileWriter(scenario, problems, author="hwyeval tests", affiliation="hwyeval",
                  source="synthetic", tags={Tag.HIGHWAY}).write_to_file(str(path))
    return path


# --- the checks every case makes ------------------------------------------------------


def _lanes(network: RoadNetwork) -> list[tuple[np.ndarray, float]]:
    out = [(ln.shape_xy_m, ln.width_m) for eid in network.edge_ids()
           for ln in network.lane_info((eid,))]
    out += [(shape, w) for eid in network.edge_ids() for link in network.lane_links(eid)
            for shape, w in zip(link.via_shapes, link.via_widths_m, strict=True)
            if len(shape) >= 2]
    return out


def check_import(r: FileResult, out: Path, ego: Car, lane_counts: dict[str, int]
                 ) -> RoadNetwork:
    """The checks of the module docstring; returns the net."""
    import json

    from suite.catalog import load_catalog

    network = RoadNetwork.load(r.net_path)
    counts = {eid: network.lane_count(eid) for eid in network.edge_ids()}
    for eid, n in lane_counts.items():
        assert counts.get(eid) == n, (eid, counts)
    ts = read_tracks(r.tracks_path)
    lanes = _lanes(network)
    for t in ts.tracks:
        margin = min(project(xy, t.x_m[0], t.y_m[0]).distance_m - 0.5 * w for xy, w in lanes)
        assert margin <= 1e-6, t.track_id
    sc = json.loads((out / f"{r.source.stem}.scenario.json").read_text())["scenario"]
    route = tuple(sc["route"])
    length = VehicleParams().length_m
    cx, cy, _ = at(ego.ref, ego.s0_m, ego.d_m)
    edge, p = network.locate(route, float(sc["ego"]["pos_m"]) - 0.5 * length)
    frac = p / network.edge_length_m(edge)
    cands = []
    for ln in network.lane_info((edge,)):
        pr = project(ln.shape_xy_m, cx, cy)
        cands.append((pr.distance_m, abs(pr.s_m - frac * pr.length_m), ln.width_m))
    lateral, gap, width = min(cands)
    assert gap <= 0.5 and lateral <= 0.5 * width
    assert sc["ego"]["speed_mps"] == pytest.approx(ego.speed_mps)
    assert sc["ego"]["target_speed_mps"] == sc["ego"]["speed_mps"]
    assert not network.link_edges(route)
    cat = load_catalog(out / "catalog.toml")
    assert [s.name for s in cat.scenarios] == [sc["name"]]
    return network


def _import(tmp_path: Path, name: str, lanes: Sequence[Lane], cars: Sequence[Car], ego: Car,
            dt_s: float = 0.1, **kw: Any) -> tuple[FileResult, Path]:
    src = write_file(tmp_path / f"{name}.xml", lanes, cars, ego, dt_s, **kw)
    out = tmp_path / "out"
    outcome = import_files([src], out, ImportParams())
    assert not outcome.failures, outcome.failures
    return outcome.results[0], out


def _lane_speeds(net_path: Path) -> dict[str, list[float]]:
    root = ET.parse(net_path).getroot()
    return {e.get("id", ""): [float(ln.get("speed", "nan")) for ln in e.findall("lane")]
            for e in root.findall("edge") if e.get("function") != "internal"}


# --- (a) highD: two carriageways, 3 lanes each, 400 m lanelets, dt 0.04 s ----------------


def highd_layout(west_split: bool) -> list[Lane]:
    """East carriageway (+x) lanes 0..2 at y = 0, 3.75, 7.5; a 2 m median; west
    carriageway (-x) lanes 0..2 at y = 20.75, 17, 13.25 (its lane 2 is next to the
    median). 1200 m, lanelets of 400 m; the innermost lanes are each other's
    ``adjacentLeft`` with ``adjacentLeftSameDirection`` false. ``west_split``: the west
    middle lane is split at 500/900 m instead of 400/800 (its neighbours then need
    cutting)."""
    east = straight(0.0, 0.0, 0.0)
    west = straight(1200.0, 20.75, math.pi)
    lanes: list[Lane] = []
    for seg in range(3):
        s0, s1 = 400.0 * seg, 400.0 * (seg + 1)
        for i in range(3):
            lid = 100 + 10 * seg + i
            lanes.append(Lane(lid, east, s0, s1, i * W,
                              succ=[lid + 10] if seg < 2 else [],
                              pred=[lid - 10] if seg > 0 else [],
                              left=lid + 1 if i < 2 else 200 + 10 * (2 - seg) + 2,
                              left_same=i < 2, right=lid - 1 if i > 0 else None,
                              types=("highway", "mainCarriageWay")))
    cuts = {0: [0.0, 400.0, 800.0, 1200.0], 2: [0.0, 400.0, 800.0, 1200.0],
            1: [0.0, 500.0, 900.0, 1200.0] if west_split else [0.0, 400.0, 800.0, 1200.0]}
    for i in range(3):
        for seg in range(3):
            s0, s1 = cuts[i][seg], cuts[i][seg + 1]
            lid = 200 + 10 * seg + i

            def nb(j: int, s0: float = s0) -> int:
                return 200 + 10 * next(k for k in range(3) if cuts[j][k] <= s0 + 1e-9
                                       < cuts[j][k + 1]) + j
            lanes.append(Lane(lid, west, s0, s1, i * W,
                              succ=[lid + 10] if seg < 2 else [],
                              pred=[lid - 10] if seg > 0 else [],
                              left=nb(i + 1) if i < 2 else 100 + 10 * (2 - seg) + 2,
                              left_same=i < 2, right=nb(i - 1) if i > 0 else None,
                              types=("highway", "mainCarriageWay")))
    return lanes


@pytest.mark.parametrize("side", ["east", "west"])
def test_highd_two_carriageways(tmp_path: Path, side: str) -> None:
    """Both directions: the other carriageway and its vehicles are dropped (counted), a
    vehicle that ended before the initial step is dropped, samples before it are cut."""
    lanes = highd_layout(west_split=True)
    east, west = straight(0.0, 0.0, 0.0), straight(1200.0, 20.75, math.pi)
    mine, other = (east, west) if side == "east" else (west, east)
    cars = [Car(1001, mine, 150.0, 0.0, 30.0, 0, 150), Car(1002, mine, 60.0, W, 33.0, 0, 150),
            Car(1003, mine, 200.0, 2 * W, 36.0, 20, 150),
            Car(1004, other, 300.0, 0.0, 31.0, 0, 150), Car(1005, other, 500.0, W, 35.0, 0, 150),
            Car(1006, mine, 10.0, 0.0, 30.0, 0, 5)]  # gone before the ego's step 10
    ego = Car(9000, mine, 100.0 + 10 * 0.04 * 32.0, W, 32.0, k1=140)
    r, out = _import(tmp_path, f"DEU_HighD-{side}_T-1", lanes, cars, ego, dt_s=0.04,
                     ego_step=10)
    assert r.step.dt_s == pytest.approx(0.04) and not r.step.corrected
    assert r.dropped["opposite"] == (1004, 1005) and r.dropped["before_start"] == (1006,)
    assert r.kept == 3
    counts = {"L100": 3, "L110": 3, "L120": 3} if side == "east" else \
        {"L200": 3, "L210": 3, "L210_1": 3, "L220": 3, "L220_1": 3}
    network = check_import(r, out, ego, counts)
    recorded = [e for e in network.edge_ids() if "-" not in e]
    assert sorted(recorded) == sorted(counts)
    ts = read_tracks(r.tracks_path)
    starts = {t.track_id: t.time_s[0] for t in ts.tracks}
    # 1001/1002 start 10 steps before the ego: those samples are cut (t = 0 is a sample)
    assert starts == pytest.approx({"rec_1001": 0.0, "rec_1002": 0.0, "rec_1003": 0.4})
    assert all(np.all(t.time_s >= 0.0) for t in ts.tracks)
    speeds = _lane_speeds(r.net_path)
    assert all(v == pytest.approx(COUNTRY_DEFAULT_MPS["DEU"], abs=0.01)
               for lane in speeds.values() for v in lane)
    # west: lanelets 210, 220 (400-800, 800-1200 m) are cut at 500 and 900 m, the ends
    # of the middle lane's 201 (0-500) and 211 (500-900); lane 1 of L210 (400-500 m) is
    # the end of lanelet 201
    if side == "west":
        _, cv, _ = next(ln for ln in lanes if ln.lid == 201).bounds()
        assert network.edge_length_m("L210") == pytest.approx(100.0, abs=1.0)
        shape = network.lane_info(("L210",))[1].shape_xy_m
        assert max(project(cv, float(x), float(y)).distance_m for x, y in shape) <= 0.05


# --- (b) a long lanelet beside two consecutive neighbours ---------------------------------


def beside_two_layout(ref: Ref) -> list[Lane]:
    """Lane 0: lanelet 100 (0-400 m); lane 1: 110 (0-150), 111 (150-400); lane 2: 120
    (0-250), 121 (250-400). 100 names 110 only as its left neighbour, 111 and 110 name
    100 as their right; 111 names 121 on its left, 120 names 110 on its right."""
    return [
        Lane(100, ref, 0.0, 400.0, 0.0, left=110),
        Lane(110, ref, 0.0, 150.0, W, succ=[111], left=120, right=100),
        Lane(111, ref, 150.0, 400.0, W, pred=[110], left=121, right=100),
        Lane(120, ref, 0.0, 250.0, 2 * W, succ=[121], right=110),
        Lane(121, ref, 250.0, 400.0, 2 * W, pred=[120], right=111),
    ]


@pytest.mark.parametrize("heading", [0.0, math.pi])
def test_lanelet_beside_two_consecutive_lanelets_is_cut(tmp_path: Path, heading: float) -> None:
    """100 is cut at 150 and 250 m (the ends of 110 and 120), 110... at their
    neighbours' ends: three edges of three lanes, the pieces' shapes on the original
    centre lines; a vehicle crossing a cut keeps its track."""
    ref = straight(0.0 if heading == 0.0 else 400.0, 0.0, heading)
    lanes = beside_two_layout(ref)
    cars = [Car(1001, ref, 100.0, 0.0, 28.0, 0, 100), Car(1002, ref, 220.0, W, 30.0, 0, 100),
            Car(1003, ref, 30.0, 2 * W, 29.0, 0, 100)]
    ego = Car(9000, ref, 60.0, W, 27.0, k1=100)
    r, out = _import(tmp_path, "ZAM_Beside-1_1_T-1", lanes, cars, ego, country="ZAM")
    network = check_import(r, out, ego, {"L100": 3, "L100_1": 3, "L100_2": 3})
    assert sorted(e for e in network.edge_ids() if "-" not in e) == ["L100", "L100_1",
                                                                      "L100_2"]
    assert network.edge_length_m("L100_1") == pytest.approx(100.0, abs=1.0)
    assert r.route[:4] == ("L100-approach", "L100", "L100_1", "L100_2")
    # every piece's lanes lie on the centre lines of the lanelets they came from
    centre = {ln.lid: ln.bounds()[1] for ln in lanes}
    for eid, lids in (("L100", (100, 110, 120)), ("L100_1", (100, 111, 120)),
                      ("L100_2", (100, 111, 121))):
        for info, lid in zip(network.lane_info((eid,)), lids, strict=True):
            d = [project(centre[lid], float(x), float(y)).distance_m
                 for x, y in info.shape_xy_m]
            assert max(d) <= 0.05, (eid, lid)
    # ZAM: no country default, the recording's top speed (30 m/s) rounded up to 110 km/h
    speeds = _lane_speeds(r.net_path)
    assert speeds["L100_1"] == pytest.approx([110 / 3.6] * 3, abs=0.01)
    assert len(read_tracks(r.tracks_path).tracks) == 3


def test_adjacency_that_does_not_lie_beside_is_an_error(tmp_path: Path) -> None:
    """A left neighbour 50 m off to the side is inconsistent: an ImportFailure naming a
    lanelet."""
    from suite.importers.commonroad import ImportFailure

    ref = straight()
    lanes = [Lane(100, ref, 0.0, 400.0, 0.0, left=110),
             Lane(110, ref, 0.0, 400.0, 50.0, right=100)]
    ego = Car(9000, ref, 60.0, 0.0, 27.0, k1=50)
    src = write_file(tmp_path / "bad.xml", lanes, [Car(1001, ref, 100.0, 0.0, 28.0, 0, 50)],
                     ego, 0.1)
    with pytest.raises(ImportFailure) as info:
        import_file(src, tmp_path / "out", ImportParams())
    assert info.value.element.startswith("lanelet ")


# --- (c) a lane drop: 3 -> 2 lanes, the right lane merges ----------------------------------


def test_lane_drop_right_lane_merges(tmp_path: Path) -> None:
    """0-300 m three lanes, 300-400 m the right lane tapers to zero width into lane 1,
    then two lanes: edges of 3, 3, 2 lanes; the merging lane connects into lane 0 of
    the two-lane edge."""
    ref = straight()
    lanes = [
        Lane(100, ref, 0.0, 300.0, 0.0, succ=[110], left=101),
        Lane(101, ref, 0.0, 300.0, W, succ=[111], left=102, right=100),
        Lane(102, ref, 0.0, 300.0, 2 * W, succ=[112], right=101),
        Lane(110, ref, 300.0, 400.0, 0.0, 0.5 * W, w1=0.0, pred=[100], succ=[121], left=111),
        Lane(111, ref, 300.0, 400.0, W, pred=[101], succ=[121], left=112, right=110),
        Lane(112, ref, 300.0, 400.0, 2 * W, pred=[102], succ=[122], right=111),
        Lane(121, ref, 400.0, 700.0, W, pred=[110, 111], left=122),
        Lane(122, ref, 400.0, 700.0, 2 * W, pred=[112], right=121),
    ]
    cars = [Car(1001, ref, 200.0, 0.0, 25.0, 0, 80), Car(1002, ref, 150.0, 2 * W, 30.0, 0, 80)]
    ego = Car(9000, ref, 120.0, W, 27.0, k1=80)
    r, out = _import(tmp_path, "DEU_Drop-1_1_T-1", lanes, cars, ego)
    network = check_import(r, out, ego, {"L100": 3, "L110": 3, "L121": 2})
    links = {(ln.from_index, ln.to_edge_id, ln.to_index) for ln in network.lane_links("L110")}
    assert {(0, "L121", 0), (1, "L121", 0), (2, "L121", 1)} <= links
    assert r.route[1:4] == ("L100", "L110", "L121")


# --- (d) an on-ramp and an off-ramp ---------------------------------------------------------


def ramps_layout() -> list[Lane]:
    """Main road 2 lanes (y = 0, 3.75), an acceleration lane (y = -3.75) at 300-500 m fed
    by an on-ramp, a deceleration lane at 700-850 m leaving by an off-ramp."""
    ref = straight()

    def on_ramp(u: float) -> tuple[float, float, float]:
        x, y = 100.0 + 200.0 * u, -W - 26.25 * (1.0 - u) ** 2
        return x, y, math.atan2(2 * 26.25 * (1.0 - u), 200.0)

    def off_ramp(u: float) -> tuple[float, float, float]:
        x, y = 850.0 + 200.0 * u, -W - 26.25 * u ** 2
        return x, y, math.atan2(-2 * 26.25 * u, 200.0)

    return [
        Lane(100, ref, 0.0, 300.0, 0.0, succ=[110], left=101),
        Lane(101, ref, 0.0, 300.0, W, succ=[111], right=100),
        Lane(150, ref, 0.0, 1.0, 0.0, succ=[109], types=("accessRamp",), centre_fn=on_ramp,
             step_m=0.05),
        Lane(109, ref, 300.0, 500.0, -W, pred=[150], succ=[120], left=110),
        Lane(110, ref, 300.0, 500.0, 0.0, pred=[100], succ=[120], left=111, right=109),
        Lane(111, ref, 300.0, 500.0, W, pred=[101], succ=[121], right=110),
        Lane(120, ref, 500.0, 700.0, 0.0, pred=[109, 110], succ=[129, 130], left=121),
        Lane(121, ref, 500.0, 700.0, W, pred=[111], succ=[131], right=120),
        Lane(129, ref, 700.0, 850.0, -W, pred=[120], succ=[160], left=130),
        Lane(130, ref, 700.0, 850.0, 0.0, pred=[120], succ=[140], left=131, right=129),
        Lane(131, ref, 700.0, 850.0, W, pred=[121], succ=[141], right=130),
        Lane(160, ref, 0.0, 1.0, 0.0, pred=[129], types=("exitRamp",), centre_fn=off_ramp,
             step_m=0.05),
        Lane(140, ref, 850.0, 1200.0, 0.0, pred=[130], left=141),
        Lane(141, ref, 850.0, 1200.0, W, pred=[131], right=140),
    ]


def test_on_and_off_ramps_are_links_the_route_avoids(tmp_path: Path) -> None:
    ref = straight()
    cars = [Car(1001, ref, 150.0, 0.0, 27.0, 0, 80), Car(1002, ref, 320.0, -W, 22.0, 0, 80),
            Car(1003, ref, 720.0, -W, 20.0, 0, 40)]
    ego = Car(9000, ref, 80.0, W, 28.0, k1=80)
    r, out = _import(tmp_path, "DEU_Ramps-1_1_T-1", ramps_layout(), cars, ego)
    network = check_import(r, out, ego, {"L100": 2, "L150": 1, "L109": 3, "L120": 2,
                                         "L129": 3, "L160": 1, "L140": 2})
    assert network.is_link("L150") and network.is_link("L160")
    assert not network.is_link("L109") and not network.is_link("L129")
    assert r.route == ("L100-approach", "L100", "L109", "L120", "L129", "L140",
                       "L140-extension")
    assert network.default_route() == r.route
    assert r.kept == 3


# --- (e) a curved road -------------------------------------------------------------------------


def test_curved_road_lane_shapes_on_centre_lines(tmp_path: Path) -> None:
    """Two lanes along an arc of radius 800 m in three 200 m lanelets (5 m vertices):
    every lane shape vertex within 0.05 m of its lanelet's centre line."""
    ref = arc(800.0)
    lanes = []
    for seg in range(3):
        for i in range(2):
            lid = 100 + 10 * seg + i
            lanes.append(Lane(lid, ref, 200.0 * seg, 200.0 * (seg + 1), i * W,
                              succ=[lid + 10] if seg < 2 else [],
                              pred=[lid - 10] if seg else [],
                              left=lid + 1 if i == 0 else None,
                              right=lid - 1 if i == 1 else None, step_m=5.0))
    cars = [Car(1001, ref, 150.0, 0.0, 27.0, 0, 80), Car(1002, ref, 50.0, W, 30.0, 0, 80)]
    ego = Car(9000, ref, 100.0, 0.0, 28.0, k1=80)
    r, out = _import(tmp_path, "DEU_Curve-1_1_T-1", lanes, cars, ego)
    network = check_import(r, out, ego, {"L100": 2, "L110": 2, "L120": 2})
    worst = 0.0
    for seg in range(3):
        for i in range(2):
            cv = next(ln for ln in lanes if ln.lid == 100 + 10 * seg + i).bounds()[1]
            shape = network.lane_info((f"L{100 + 10 * seg}",))[i].shape_xy_m
            worst = max(worst, max(project(cv, float(x), float(y)).distance_m
                                   for x, y in shape))
    assert worst <= 0.05


# --- (f) speed-limit signs ----------------------------------------------------------------------


@pytest.mark.parametrize(("country", "element"), [("DEU", "MAX_SPEED"), ("USA", "MAX_SPEED")])
def test_speed_limit_signs(tmp_path: Path, country: str, element: str) -> None:
    """A MAX_SPEED sign (274 / R2-1) of 27.78 m/s on the right lane of the first segment
    holds for its row and downstream; a 33.33 m/s sign on the third segment replaces it;
    the extension keeps the last limit; the ego's target speed stays its speed."""
    ref = straight()
    lanes = []
    for seg in range(3):
        for i in range(2):
            lid = 100 + 10 * seg + i
            lanes.append(Lane(lid, ref, 300.0 * seg, 300.0 * (seg + 1), i * W,
                              succ=[lid + 10] if seg < 2 else [],
                              pred=[lid - 10] if seg else [],
                              left=lid + 1 if i == 0 else None,
                              right=lid - 1 if i == 1 else None,
                              signs=(5001,) if lid == 100 else (5002,) if seg == 2 else ()))
    signs = {5001: (element, 27.78, 100), 5002: (element, 33.33, 120)}
    cars = [Car(1001, ref, 150.0, 0.0, 27.0, 0, 80)]
    ego = Car(9000, ref, 100.0, W, 24.0, k1=80)
    r, out = _import(tmp_path, f"{country}_Signs-1_1_T-1", lanes, cars, ego,
                     country=country, signs=signs)
    check_import(r, out, ego, {"L100": 2, "L110": 2, "L120": 2})
    speeds = _lane_speeds(r.net_path)
    assert speeds["L100"] == pytest.approx([27.78, 27.78])
    assert speeds["L110"] == pytest.approx([27.78, 27.78])
    assert speeds["L120"] == pytest.approx([33.33, 33.33])
    assert speeds["L120-extension"] == pytest.approx([33.33, 33.33])
    text = r.net_path.read_text()
    assert 'speed="24' not in text  # the ego's speed is not a limit


# --- samples before the initial time step ------------------------------------------------------


def _record(steps: Sequence[int]) -> ObstacleRecord:
    k = np.asarray(steps, dtype=np.int64)
    x = 10.0 * k.astype(np.float64)
    return ObstacleRecord(1, "car", False, 4.5, 1.8, k, x, np.zeros_like(x),
                          np.zeros_like(x), np.full_like(x, 100.0))


def test_samples_before_the_initial_step() -> None:
    """Dropped, except the last one before t = 0 when t = 0 falls between samples."""
    assert first_kept(_record([0, 1, 2, 3, 4]), 2) == 2  # t = 0 is a sample
    assert first_kept(_record([0, 2, 4, 6]), 3) == 1  # step 2 kept, t = -dt
    assert first_kept(_record([5, 6]), 2) == 0  # starts later
    assert first_kept(_record([0, 1]), 2) is None  # gone before the start
    t = to_track(_record([0, 2, 4, 6]), 3, 0.1)
    assert t.time_s == pytest.approx([-0.1, 0.1, 0.3])
    assert t.x_m[0] + (t.x_m[1] - t.x_m[0]) * 0.5 == pytest.approx(30.0)  # at t = 0


# --- the ego's lateral offset ------------------------------------------------------------------


def test_ego_lateral_offset_is_reported(tmp_path: Path) -> None:
    """An ego 0.9 m left of its lane's centre: FileResult and a WARNING note carry the
    offset; the catalog's ego stays on lane 0."""
    import json

    ref = straight()
    lanes = [Lane(100, ref, 0.0, 500.0, 0.0, left=101), Lane(101, ref, 0.0, 500.0, W,
                                                              right=100)]
    ego = Car(9000, ref, 100.0, 0.9, 25.0, k1=50)
    r, out = _import(tmp_path, "DEU_Offset-1_1_T-1", lanes,
                     [Car(1001, ref, 150.0, 0.0, 27.0, 0, 50)], ego)
    assert r.ego_lateral_m == pytest.approx(0.9, abs=0.01)
    assert any(n.startswith("WARNING") and "0.90" in n for n in r.notes)
    frag = json.loads((out / "DEU_Offset-1_1_T-1.scenario.json").read_text())
    assert frag["scenario"]["ego"]["lane"] == 0
    assert "0.90" in (out / "catalog.toml").read_text()
    small = Car(9000, ref, 100.0, -0.2, 25.0, k1=50)
    (tmp_path / "b").mkdir()
    r2, _ = _import(tmp_path / "b", "DEU_Offset-1_2_T-1", lanes,
                    [Car(1001, ref, 150.0, 0.0, 27.0, 0, 50)], small)
    assert r2.ego_lateral_m == pytest.approx(-0.2, abs=0.01)
    assert not any(n.startswith("WARNING") and "lateral" in n for n in r2.notes)


# --- closed loop ------------------------------------------------------------------------------


@pytest.mark.slow
def test_imported_lanelet_cut_scenario_runs_closed_loop(tmp_path: Path) -> None:
    """The cut-lanelet case (b) under `hwyeval run`: finishes with pass or fail."""
    import csv
    import subprocess
    import sys

    ref = straight()
    cars = [Car(1001, ref, 100.0, 0.0, 28.0, 0, 100), Car(1002, ref, 220.0, W, 30.0, 0, 100)]
    ego = Car(9000, ref, 60.0, W, 27.0, k1=100)
    r, out = _import(tmp_path, "ZAM_Beside-1_1_T-1", beside_two_layout(ref), cars, ego,
                     country="ZAM")
    runs = tmp_path / "runs"
    res = subprocess.run([sys.executable, "-m", "suite", "run", str(out / "catalog.toml"),
                          "--out", str(runs), "--no-log", "--jobs", "1", "--no-fail"],
                         capture_output=True, text=True, timeout=600,
                         cwd=Path(__file__).resolve().parents[1])
    assert res.returncode == 0, res.stderr[-3000:]
    (results,) = list(runs.rglob("results.csv"))
    rows = list(csv.DictReader(results.open()))
    assert [row["status"] for row in rows] in (["pass"], ["fail"]), rows
