"""Tests of the bundled highway nets (sumo_nets): sources, build, geometry, libsumo loading.

Units: metres, m/s, degrees.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import sumo_nets
from sumo_nets import (
    BUNDLED,
    LANE_WIDTH_M,
    SHOULDER_WIDTH_M,
    SPEED_LIMIT_MPS,
    SRC_DIR,
    NetInfo,
    available,
    net_path,
)
from sumo_nets import build as nb

REPO_ROOT = Path(__file__).resolve().parents[1]
NAMES = sorted(BUNDLED)

# --------------------------------------------------------------------------- helpers


def _load(path: Path) -> Any:
    import sumolib

    return sumolib.net.readNet(str(path), withInternal=True)


def _route_polyline(net: Any, info: NetInfo, lane_index: int) -> tuple[np.ndarray, list[str]]:
    """Concatenated shape (N, 2) of lane ``lane_index`` along the main route, following the
    connections through the internal junction lanes; also the list of lane ids used."""
    pts: list[tuple[float, float]] = []
    lane_ids: list[str] = []
    for k, eid in enumerate(info.main_route):
        lane = net.getEdge(eid).getLane(lane_index)
        lane_ids.append(lane.getID())
        pts.extend((float(x), float(y)) for x, y in lane.getShape())
        if k + 1 == len(info.main_route):
            break
        nxt = info.main_route[k + 1]
        conns = [c for c in lane.getOutgoing() if c.getToLane().getEdge().getID() == nxt]
        assert len(conns) == 1, f"{lane.getID()}: expected one connection to {nxt}, got {conns}"
        conn = conns[0]
        assert conn.getToLane().getIndex() == lane_index, "connection changes lane index"
        assert conn.getDirection() == "s", f"{lane.getID()}->{nxt} is not straight-through"
        via = conn.getViaLaneID()
        assert via, f"{lane.getID()}->{nxt}: no internal junction lane"
        vlane = net.getLane(via)
        lane_ids.append(via)
        pts.extend((float(x), float(y)) for x, y in vlane.getShape())
    return np.asarray(pts, dtype=np.float64), lane_ids


def _headings_deg(poly: np.ndarray, min_seg_m: float) -> np.ndarray:
    """Headings (deg) of the polyline segments longer than ``min_seg_m`` (shorter ones,
    e.g. zero-length internal lanes at straight-through junctions, have no heading)."""
    d = np.diff(poly, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    keep = seg > min_seg_m
    return np.degrees(np.arctan2(d[keep, 1], d[keep, 0]))


def _fit_circle(pts: np.ndarray) -> tuple[float, float]:
    """Least-squares (Kasa) circle fit; returns (radius m, rms residual m)."""
    c = pts.mean(axis=0)
    p = pts - c
    a = np.column_stack([2.0 * p[:, 0], 2.0 * p[:, 1], np.ones(len(p))])
    b = (p**2).sum(axis=1)
    (cx, cy, k), *_ = np.linalg.lstsq(a, b, rcond=None)
    r = math.sqrt(k + cx * cx + cy * cy)
    resid = np.hypot(p[:, 0] - cx, p[:, 1] - cy) - r
    return r, float(np.sqrt(np.mean(resid**2)))


def _max_chord_deviation(pts: np.ndarray) -> float:
    """Largest distance (m) of the polyline points from the chord joining its ends."""
    a, b = pts[0], pts[-1]
    ab = b - a
    n = np.array([-ab[1], ab[0]]) / np.hypot(*ab)
    return float(np.max(np.abs((pts - a) @ n)))


def _net_signature(path: Path) -> dict[str, Any]:
    """Everything that matters in a .net.xml, without the header comment."""
    root = ET.parse(path).getroot()
    sig: dict[str, Any] = {"net": dict(root.attrib), "location": None}
    loc = root.find("location")
    sig["location"] = dict(loc.attrib) if loc is not None else None
    sig["edges"] = {
        e.get("id"): (
            dict(e.attrib),
            [dict(ln.attrib) for ln in e.findall("lane")],
        )
        for e in root.findall("edge")
    }
    sig["junctions"] = {j.get("id"): dict(j.attrib) for j in root.findall("junction")}
    sig["connections"] = sorted(
        tuple(sorted(c.attrib.items())) for c in root.findall("connection")
    )
    return sig


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def rebuilt(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("nets")
    paths = nb.build_all(out)
    assert sorted(p.name for p in paths) == sorted(f"{n}.net.xml" for n in NAMES)
    return {n: out / f"{n}.net.xml" for n in NAMES}


# --------------------------------------------------------------------------- registry


def test_registry_consistent() -> None:
    assert len(NAMES) >= 5
    assert available() == NAMES
    assert set(nb.LAYOUTS) == set(BUNDLED)
    for name, info in BUNDLED.items():
        assert info.name == name
        assert len(info.main_route) == len(nb.LAYOUTS[name]) >= 4
        assert info.length_m == pytest.approx(nb.layout_length_m(name), abs=1.0)
        assert info.length_m >= 2000.0
        radii = [s.radius_m for s in nb.LAYOUTS[name] if isinstance(s, nb.Arc)]
        if info.min_curve_radius_m is None:
            assert not radii
        else:
            assert min(radii) == pytest.approx(info.min_curve_radius_m)
        assert net_path(name) == sumo_nets.NET_DIR / f"{name}.net.xml"
        assert net_path(name).is_file(), f"{name}: built net not committed; run the build"


def test_net_path_unknown_lists_names() -> None:
    with pytest.raises(KeyError) as exc:
        net_path("no_such_net")
    msg = str(exc.value)
    assert "no_such_net" in msg
    for name in NAMES:
        assert name in msg


def test_netinfo_frozen() -> None:
    info = BUNDLED["straight_3lane_shoulder"]
    with pytest.raises(AttributeError):
        info.traffic_lanes = 4  # type: ignore[misc]
    assert info.total_lanes == 4
    assert info.first_traffic_lane == 1


def test_sumo_home_sets_env(monkeypatch: pytest.MonkeyPatch) -> None:
    import sumo

    monkeypatch.delenv("SUMO_HOME", raising=False)
    home = sumo_nets.sumo_home()
    assert home == str(sumo.SUMO_HOME)
    assert os.environ["SUMO_HOME"] == home
    assert (Path(home) / "bin").is_dir()


@pytest.mark.parametrize("name", NAMES)
def test_sources_match_layouts(name: str) -> None:
    """The committed plain-XML sources are exactly what LAYOUTS renders."""
    for fname, text in nb.render_sources(name).items():
        committed = (SRC_DIR / fname).read_text(encoding="utf-8")
        assert committed == text, f"{fname} differs from LAYOUTS; run build --write-sources"


def test_arc_points_dense_and_on_circle() -> None:
    for name, segs in nb.LAYOUTS.items():
        for seg, poly in zip(segs, nb.reference_polylines(name), strict=True):
            pts = np.asarray(poly)
            if isinstance(seg, nb.Arc):
                step = np.hypot(*np.diff(pts, axis=0).T)
                assert step.max() <= nb.ARC_POINT_SPACING_M + 1e-9
                r, rms = _fit_circle(pts)
                assert r == pytest.approx(seg.radius_m, rel=1e-6)
                assert rms < 1e-6


# --------------------------------------------------------------------------- built nets


@pytest.mark.sumo
def test_netconvert_path() -> None:
    p = nb.netconvert_path()
    assert p.is_file() and os.access(p, os.X_OK)


@pytest.mark.sumo
@pytest.mark.parametrize("name", NAMES)
def test_lanes(rebuilt: dict[str, Path], name: str) -> None:
    info = BUNDLED[name]
    net = _load(rebuilt[name])
    normal = sorted(e.getID() for e in net.getEdges(withInternal=False))
    assert normal == sorted(info.main_route)
    for eid in info.main_route:
        edge = net.getEdge(eid)
        lanes = edge.getLanes()
        assert len(lanes) == info.total_lanes, f"{eid}: {len(lanes)} lanes"
        for lane in lanes:
            assert lane.getSpeed() == pytest.approx(SPEED_LIMIT_MPS, abs=1e-3)
            if info.has_shoulder and lane.getIndex() == 0:
                assert lane.getWidth() == pytest.approx(SHOULDER_WIDTH_M)
                assert lane.getPermissions() == {"emergency", "authority"}
                assert not lane.allows("passenger")
                assert not lane.allows("truck")
            else:
                assert lane.getWidth() == pytest.approx(LANE_WIDTH_M)
                assert lane.allows("passenger")
                assert lane.allows("truck")
        # lateral layout: lanes side by side, adjacent centres one half-width-sum apart
        mids = [np.asarray(ln.getShape()[0]) for ln in lanes]
        for a, b, la, lb in zip(mids, mids[1:], lanes, lanes[1:], strict=False):
            assert np.hypot(*(b - a)) == pytest.approx(
                0.5 * (la.getWidth() + lb.getWidth()), abs=0.01
            )
    # the internal junction lanes keep the shoulder restriction too
    if info.has_shoulder:
        for e in net.getEdges(withInternal=True):
            if e.getFunction() == "internal":
                assert not e.getLane(0).allows("passenger")


@pytest.mark.sumo
@pytest.mark.parametrize("name", NAMES)
def test_route_length_and_continuity(rebuilt: dict[str, Path], name: str) -> None:
    info = BUNDLED[name]
    net = _load(rebuilt[name])
    for li in range(info.total_lanes):
        poly, lane_ids = _route_polyline(net, info, li)
        # lengths: sum of SUMO lane lengths along the route, and geometric length
        sumo_len = sum(net.getLane(lid).getLength() for lid in lane_ids)
        geo_len = float(np.hypot(*np.diff(poly, axis=0).T).sum())
        assert sumo_len >= 2000.0
        assert geo_len >= 2000.0
        # SUMO gives every lane of an edge the reference-line length (positions along
        # parallel lanes correspond), while the lane centre lines are offset from the
        # reference line: on an arc of angle a their length changes by offset * a,
        # at most 5.25 m * 2.1 rad here
        assert sumo_len == pytest.approx(info.length_m, abs=1.0)
        assert geo_len == pytest.approx(info.length_m, abs=12.0)
        # continuity: every consecutive point pair is close (no jumps between lanes) ...
        steps = np.hypot(*np.diff(poly, axis=0).T)
        assert steps.max() <= 500.0 + 1e-6
        # ... in particular at each lane->internal->lane joint (shape end == next start)
        joints = []
        pos = 0
        for lid in lane_ids[:-1]:
            pos += len(net.getLane(lid).getShape())
            joints.append(steps[pos - 1])
        assert max(joints) < 0.01, f"lane {li}: gap of {max(joints):.3f} m at a junction"
        # smoothness: heading changes by < 2 deg between consecutive segments > 5 cm
        hd = _headings_deg(poly, min_seg_m=0.05)
        dh = (np.diff(hd) + 180.0) % 360.0 - 180.0
        assert np.abs(dh).max() < 2.0, f"lane {li}: kink of {np.abs(dh).max():.2f} deg"
        # and the total heading change equals the layout's (left arcs positive)
        total = sum(s.angle_deg for s in nb.LAYOUTS[name] if isinstance(s, nb.Arc))
        assert float(dh.sum()) == pytest.approx(total, abs=0.5)


@pytest.mark.sumo
@pytest.mark.parametrize("name", NAMES)
def test_curvature(rebuilt: dict[str, Path], name: str) -> None:
    info = BUNDLED[name]
    net = _load(rebuilt[name])
    radii: list[float] = []
    for eid, seg in zip(info.main_route, nb.LAYOUTS[name], strict=True):
        edge = net.getEdge(eid)
        if not isinstance(seg, nb.Arc):
            for lane in edge.getLanes():
                dev = _max_chord_deviation(np.asarray(lane.getShape(), dtype=np.float64))
                assert dev < 0.01, f"{lane.getID()} should be straight, deviates {dev:.3f} m"
            continue
        lane_r = []
        for lane in edge.getLanes():
            pts = np.asarray(lane.getShape(), dtype=np.float64)
            assert len(pts) >= seg.length_m / nb.ARC_POINT_SPACING_M - 2
            r, rms = _fit_circle(pts)
            assert rms < 0.01, f"{lane.getID()}: not a circular arc (rms {rms:.3f} m)"
            lane_r.append(r)
            radii.append(r)
            assert r == pytest.approx(seg.radius_m, rel=0.10)
        # lanes are concentric: the mean lane radius is the reference-line radius
        # (exact for a symmetric lane set, i.e. without a shoulder)
        assert float(np.mean(lane_r)) == pytest.approx(seg.radius_m, rel=0.01)
        assert max(lane_r) - min(lane_r) == pytest.approx(
            sum(ln.getWidth() for ln in edge.getLanes()) - LANE_WIDTH_M, abs=0.05
        )
    if info.min_curve_radius_m is None:
        assert not radii
    else:
        assert radii, "no curved edge found"
        assert min(radii) == pytest.approx(info.min_curve_radius_m, rel=0.10)


@pytest.mark.sumo
@pytest.mark.parametrize("name", NAMES)
def test_committed_equals_rebuilt(rebuilt: dict[str, Path], name: str) -> None:
    committed = _net_signature(net_path(name))
    fresh = _net_signature(rebuilt[name])
    for key in ("net", "location", "junctions", "connections"):
        assert committed[key] == fresh[key], f"{name}: {key} differ; rerun sumo_nets.build"
    assert committed["edges"].keys() == fresh["edges"].keys()
    for eid, val in fresh["edges"].items():
        assert committed["edges"][eid] == val, f"{name}: edge {eid} differs; rerun the build"


@pytest.mark.sumo
def test_build_is_byte_deterministic(tmp_path: Path, rebuilt: dict[str, Path]) -> None:
    name = "s_curve_3lane"
    again = nb.build_net(name, tmp_path)
    assert again.read_bytes() == rebuilt[name].read_bytes()
    assert b"generated on" not in again.read_bytes()  # no date stamp
    assert str(tmp_path).encode() not in again.read_bytes()  # no absolute paths


_LIBSUMO_SCRIPT = r"""
import json, os, sys
import libsumo
from sumo_nets import BUNDLED, sumo_home

name, net = sys.argv[1], sys.argv[2]
info = BUNDLED[name]
binary = os.path.join(sumo_home(), "bin", "sumo")
libsumo.start([binary, "-n", net, "--no-step-log", "true", "--step-length", "0.5"])
try:
    lanes = list(libsumo.lane.getIDList())
    allowed0 = list(libsumo.lane.getAllowed(info.main_route[0] + "_0"))
    libsumo.route.add("main", list(info.main_route))
    libsumo.vehicle.add("ego", "main", departLane="best", departSpeed="max")
    libsumo.vehicle.setSpeedFactor("ego", 1.0)
    arrived_t = None
    edges_seen = []
    for _ in range(2000):
        libsumo.simulationStep()
        if "ego" in libsumo.vehicle.getIDList():
            e = libsumo.vehicle.getRoadID("ego")
            if not e.startswith(":") and (not edges_seen or edges_seen[-1] != e):
                edges_seen.append(e)
        if "ego" in libsumo.simulation.getArrivedIDList():
            arrived_t = libsumo.simulation.getTime()
            break
    out = dict(lanes=lanes, allowed0=allowed0, arrived_t=arrived_t, edges_seen=edges_seen,
               teleports=libsumo.simulation.getStartingTeleportNumber())
finally:
    libsumo.close()
print("RESULT " + json.dumps(out))
"""


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize("name", NAMES)
def test_loads_and_drives_in_libsumo(name: str) -> None:
    """Each committed net loads in libsumo (in a subprocess: one simulation per process)
    and a vehicle drives the main route end to end."""
    info = BUNDLED[name]
    env = {**os.environ, "SUMO_HOME": sumo_nets.sumo_home()}
    env["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(REPO_ROOT), env.get("PYTHONPATH", "")) if p
    )
    res = subprocess.run(
        [sys.executable, "-c", _LIBSUMO_SCRIPT, name, str(net_path(name))],
        capture_output=True, text=True, env=env, timeout=120,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    line = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")][-1]
    out = json.loads(line[len("RESULT "):])
    normal = sorted(ln for ln in out["lanes"] if not ln.startswith(":"))
    expected = sorted(f"{e}_{i}" for e in info.main_route for i in range(info.total_lanes))
    assert normal == expected
    if info.has_shoulder:
        assert sorted(out["allowed0"]) == ["authority", "emergency"]
    else:
        assert "passenger" in out["allowed0"] and "truck" in out["allowed0"]
    assert out["edges_seen"] == list(info.main_route)
    assert out["teleports"] == 0
    # departing at the speed limit with speed factor 1, the route takes length/33.33 s
    # (+ a few steps): no slow-down at the straight-through junctions
    assert out["arrived_t"] is not None
    t_free = info.length_m / SPEED_LIMIT_MPS
    assert t_free <= out["arrived_t"] <= t_free + 5.0
