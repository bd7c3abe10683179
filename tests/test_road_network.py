"""RoadNetwork on small nets built with netconvert from plain XML (nets not seen before)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from suite.road.network import (
    RoadNetwork,
    RoadNetworkError,
    centreline_arclength,
    dedupe_polyline,
    is_shoulder_permissions,
)
from suite.road.record import route_lane_records
from tests.plain_nets import PlainNet

# A 3-lane road with a hard shoulder on e0, a curve on e1, a lane drop to 2 lanes on e2
# (the right lane of e1 ends), 3 lanes again on e3, and a short side branch from b.
MIXED_NODES = """<nodes>
  <node id="a" x="0" y="0"/>
  <node id="b" x="500" y="0"/>
  <node id="c" x="900" y="200"/>
  <node id="d" x="1400" y="200"/>
  <node id="e" x="1800" y="200"/>
  <node id="x" x="700" y="-150"/>
</nodes>"""
MIXED_EDGES = """<edges>
  <edge id="e0" from="a" to="b" numLanes="3" speed="30">
    <lane index="0" allow="emergency authority"/>
  </edge>
  <edge id="e1" from="b" to="c" numLanes="3" speed="30" shape="500,0 700,20 800,120 900,200"/>
  <edge id="e2" from="c" to="d" numLanes="2" speed="25"/>
  <edge id="e3" from="d" to="e" numLanes="3" speed="30"/>
  <edge id="ramp" from="b" to="x" numLanes="1" speed="20"/>
</edges>"""

# A ring (cycle) with a lead-in and an exit: default_route must terminate.
RING_NODES = """<nodes>
  <node id="s" x="-300" y="0"/>
  <node id="p" x="0" y="0"/>
  <node id="q" x="400" y="0"/>
  <node id="r" x="200" y="300"/>
  <node id="t" x="800" y="0"/>
</nodes>"""
RING_EDGES = """<edges>
  <edge id="in" from="s" to="p" numLanes="2" speed="30"/>
  <edge id="pq" from="p" to="q" numLanes="2" speed="30"/>
  <edge id="qr" from="q" to="r" numLanes="2" speed="30"/>
  <edge id="rp" from="r" to="p" numLanes="2" speed="30"/>
  <edge id="out" from="q" to="t" numLanes="2" speed="30"/>
</edges>"""


NO_TURNAROUNDS = ("--no-turnarounds", "true")


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory, plain_net: PlainNet) -> RoadNetwork:
    return RoadNetwork.load(plain_net(tmp_path_factory.mktemp("nets"), "mixed", MIXED_NODES,
                                      MIXED_EDGES, options=NO_TURNAROUNDS))


ROUTE = ("e0", "e1", "e2", "e3")


# ------------------------------------------------------------------ pure helpers
def test_shoulder_rule() -> None:
    assert is_shoulder_permissions(["emergency", "authority"])
    assert is_shoulder_permissions({"authority"})
    assert not is_shoulder_permissions({"passenger", "emergency"})
    assert not is_shoulder_permissions({"bus"})


def test_dedupe_and_arclength() -> None:
    poly = np.array([[0.0, 0.0], [0.0, 0.0], [3.0, 4.0], [3.0, 4.0], [6.0, 8.0]])
    d = dedupe_polyline(poly)
    assert d.shape == (3, 2)
    np.testing.assert_allclose(centreline_arclength(d), [0.0, 5.0, 10.0])


# ------------------------------------------------------------------ loading
@pytest.mark.sumo
def test_load_is_cached_and_errors_name_file(mixed: RoadNetwork, tmp_path: Path) -> None:
    assert RoadNetwork.load(mixed.path) is mixed
    missing = tmp_path / "nope.net.xml"
    with pytest.raises(RoadNetworkError, match="nope.net.xml"):
        RoadNetwork.load(missing)
    bad = tmp_path / "bad.net.xml"
    bad.write_text("<net><edge id='x'")
    with pytest.raises(RoadNetworkError, match="bad.net.xml"):
        RoadNetwork.load(bad)


@pytest.mark.sumo
def test_edges_lanes_lengths(mixed: RoadNetwork) -> None:
    assert mixed.edge_ids() == sorted(["e0", "e1", "e2", "e3", "ramp"])
    assert [mixed.lane_count(e) for e in ROUTE] == [3, 3, 2, 3]
    assert mixed.edge_length_m("e0") == pytest.approx(500.0, abs=10.0)  # junction cut
    assert mixed.lane_width_m("e0", 1) == pytest.approx(3.2)
    with pytest.raises(KeyError):
        mixed.lane_count("nope")


# ------------------------------------------------------------------ routes
@pytest.mark.sumo
def test_default_route_is_longest_path(mixed: RoadNetwork) -> None:
    assert mixed.default_route() == ROUTE


@pytest.mark.sumo
def test_default_route_with_cycle_terminates(tmp_path: Path, plain_net: PlainNet) -> None:
    net = RoadNetwork.load(plain_net(tmp_path, "ring", RING_NODES, RING_EDGES,
                                     options=NO_TURNAROUNDS))
    route = net.default_route()
    assert len(set(route)) == len(route)  # a simple path
    net.validate_route(route)
    assert route[0] == "in"


@pytest.mark.sumo
def test_validate_route(mixed: RoadNetwork) -> None:
    mixed.validate_route(ROUTE)
    mixed.validate_route(("e0", "ramp"))
    with pytest.raises(ValueError, match="unknown edge"):
        mixed.validate_route(("e0", "zz"))
    with pytest.raises(ValueError, match="not connected"):
        mixed.validate_route(("e0", "e2"))
    with pytest.raises(ValueError):
        mixed.validate_route(())


@pytest.mark.sumo
def test_route_length_locate_lanes_at(mixed: RoadNetwork) -> None:
    lengths = [mixed.edge_length_m(e) for e in ROUTE]
    total = mixed.route_length_m(ROUTE)
    assert sum(lengths) < total < sum(lengths) + 30.0  # junction lanes included
    assert mixed.locate(ROUTE, 0.0) == ("e0", 0.0)
    edge, pos = mixed.locate(ROUTE, 499.0)
    assert edge == "e0" and pos == pytest.approx(499.0)
    starts = mixed.route_edge_starts_m(ROUTE)
    edge, pos = mixed.locate(ROUTE, starts["e2"] + 10.0)
    assert edge == "e2" and pos == pytest.approx(10.0)
    # inside the junction between e1 and e2 -> start of e2
    assert mixed.locate(ROUTE, starts["e2"] - 1e-3) == ("e2", 0.0)
    assert mixed.lanes_at(ROUTE, starts["e2"] + 10.0) == 2
    assert mixed.lanes_at(ROUTE, total - 1.0) == 3
    for bad in (-1.0, total, total + 5.0, float("nan")):
        with pytest.raises(ValueError):
            mixed.locate(ROUTE, bad)


# ------------------------------------------------------------------ lanes
@pytest.mark.sumo
def test_lane_info_shoulder_and_json(mixed: RoadNetwork) -> None:
    info = mixed.lane_info(ROUTE)
    assert len(info) == 3 + 3 + 2 + 3
    e0 = [i for i in info if i.edge_id == "e0"]
    assert [i.index for i in e0] == [0, 1, 2]
    assert e0[0].is_shoulder and not e0[0].allows_passenger
    assert set(e0[0].allowed) == {"emergency", "authority"}
    assert not e0[1].is_shoulder and e0[1].allows_passenger
    e2 = [i for i in info if i.edge_id == "e2"]
    assert e2[0].speed_mps == pytest.approx(25.0)
    assert e2[0].shape_xy_m.ndim == 2 and e2[0].shape_xy_m.shape[1] == 2
    text = json.dumps([i.as_dict() for i in info])
    assert "e0_0" in text


def _check_continuous(poly: np.ndarray, max_jump_m: float = 10.0, max_turn_deg: float = 50.0
                      ) -> None:
    assert poly.ndim == 2 and poly.shape[1] == 2 and poly.shape[0] >= 2
    seg = np.diff(poly, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    assert lengths.min() > 0.0  # duplicates removed
    heading = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
    assert np.degrees(np.abs(np.diff(heading))).max() < max_turn_deg  # no zig-zag jumps
    # Segments across junctions (via lanes, lane-end joins) are a few metres at most; long
    # segments only occur along straight lane shapes (heading checked above).
    short = lengths[lengths < 50.0]
    assert short.size == 0 or short.max() < max_jump_m


@pytest.mark.sumo
@pytest.mark.parametrize("lane", [0, 1, 2])
def test_lane_centreline_continuous_and_length(mixed: RoadNetwork, lane: int) -> None:
    poly = mixed.lane_centreline(ROUTE, lane)
    _check_continuous(poly)
    total = mixed.route_length_m(ROUTE)
    assert centreline_arclength(poly)[-1] == pytest.approx(total, rel=0.02)
    first = mixed.lane_info(("e0",))[lane].shape_xy_m
    np.testing.assert_allclose(poly[0], first[0])


@pytest.mark.sumo
def test_lane_centreline_goes_through_junction_lanes(mixed: RoadNetwork) -> None:
    poly = mixed.lane_centreline(ROUTE, 1)
    e0_end = mixed.lane_info(("e0",))[1].shape_xy_m[-1]
    e1_start = mixed.lane_info(("e1",))[1].shape_xy_m[0]
    assert np.hypot(*(e0_end - e1_start)) > 0.1  # there is a junction in between ...
    i = int(np.argmin(np.hypot(*(poly - e0_end).T)))
    # ... and the polyline bridges it with short steps (the via lane), not one long jump
    assert np.hypot(*(poly[i + 1] - poly[i])) < 2.5


def test_route_lane_records_keep_the_route_and_its_junction_lanes(mixed: RoadNetwork) -> None:
    """road.json's lanes: every lane of every route edge, each internal lane of the
    connections between consecutive route edges once (permissions of the lane it leaves,
    starting at that lane's end), nothing of the side branch."""
    lanes = route_lane_records(mixed, ROUTE)
    ids = [ln.id for ln in lanes]
    assert len(ids) == len(set(ids))
    regular = [ln for ln in lanes if not ln.internal]
    assert [ln.id for ln in regular] == [li.id for li in mixed.lane_info(ROUTE)]
    assert not any(ln.edge_id == "ramp" for ln in lanes)
    internal = [ln for ln in lanes if ln.internal]
    vias = {v for k, edge in enumerate(ROUTE[:-1]) for link in mixed.lane_links(edge)
            if link.to_edge_id == ROUTE[k + 1] for v in link.via_ids}
    assert internal and {ln.id for ln in internal} == vias
    checked = 0
    for ln in internal:
        assert ln.id.startswith(":")
        source = next((r for r in regular
                       if np.hypot(*(r.shape_xy_m[-1] - ln.shape_xy_m[0])) < 1e-6), None)
        if source is not None:  # the first internal lane of its connection
            assert (ln.allowed, ln.is_shoulder, ln.allows_passenger) == (
                source.allowed, source.is_shoulder, source.allows_passenger)
            checked += 1
    assert checked > 0


@pytest.mark.sumo
def test_lane_drop_continues_on_nearest_lane(mixed: RoadNetwork) -> None:
    # lane 2 (left) of e1 connects to lane 1 of e2 (2 lanes): the reference stays in the
    # leftmost lane through the drop and returns to lane 2 on e3.
    poly = mixed.lane_centreline(ROUTE, 2)
    e2_lanes = {i.index: i.shape_xy_m for i in mixed.lane_info(("e2",))}
    mid_e2 = e2_lanes[1].mean(axis=0)
    d_to_line = np.min(np.abs(poly[:, 1] - mid_e2[1])[np.abs(poly[:, 0] - mid_e2[0]) < 300])
    assert d_to_line < 0.01
    e3_l2_end = mixed.lane_info(("e3",))[2].shape_xy_m[-1]
    np.testing.assert_allclose(poly[-1], e3_l2_end)
    # lane 0 of e1 ends without a connection: the path still has no gap
    _check_continuous(mixed.lane_centreline(ROUTE, 0))
    # an index beyond the first edge's lanes is clamped to the nearest existing lane
    np.testing.assert_allclose(mixed.lane_centreline(ROUTE, 7), poly)
    with pytest.raises(ValueError):
        mixed.lane_centreline(ROUTE, -1)


@pytest.mark.sumo
def test_bundled_nets_if_available() -> None:
    sumo_nets = pytest.importorskip("sumo_nets")
    names = sumo_nets.available()
    if not names:
        pytest.skip("no bundled nets yet")
    for name in names:
        net = RoadNetwork.load(sumo_nets.net_path(name))
        route = net.default_route()
        assert net.route_length_m(route) >= 2000.0
        for lane in range(net.lane_count(route[0])):
            poly = net.lane_centreline(route, lane)
            _check_continuous(poly, max_turn_deg=60.0)
            assert centreline_arclength(poly)[-1] == pytest.approx(
                net.route_length_m(route), rel=0.02)
