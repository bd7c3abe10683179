"""The off-road verdict on real motorways, checked by an independent method.

Runs ~116 scenarios on the OpenStreetMap motorways of ../shared/nets_real (its own
catalog, and the stress generator's real-road scenarios), 20 s each, then for every
fifth trace row of every run, as driven and with the ego moved sideways by ±1.5, ±2.5
and ±4 m, classifies the ego's box corners against the lanes read from the .net.xml by
xml.etree (each lane segment's rectangle and a disc of half the width at each inner
vertex, the route's lanes and the internal lanes of
the connections between consecutive route edges) and netconvert's junction outlines,
with an exact point-in-rectangle test and ray casting. Nothing of the metric's code is
used. It checks that

* a row whose four corners all lie inside lanes (a rectangle or a round join at an
  inner vertex) has an excess <= 0 (never off-road), and
* a row with a corner outside every lane, junction outline and the quadrilateral
  between one route edge's lane ends and the next one's lane starts (where a lane ends
  or begins beside another) by more than the tolerance (+ 15 cm: netconvert's miter
  joins reach beyond round ones) is off-road.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from reports.metrics.context import build_context
from reports.metrics.drivable import OFFROAD_TOLERANCE_M, offroad_excess_series
from reports.record import RunRecord, Trace, load_run

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "nets_real"
OFFSETS_M = (0.0, -1.5, 1.5, -2.5, 2.5, -4.0, 4.0)
ROW_STRIDE = 5
JOIN_MARGIN_M = 0.15  # a miter join reaches h (1/cos(a/2) - 1) beyond a round one

pytestmark = [pytest.mark.sumo, pytest.mark.slow,
              pytest.mark.skipif(not (REAL / "catalog.toml").is_file(),
                                 reason="../shared/nets_real is not there")]


@dataclass(frozen=True)
class IndependentRoad:
    """Lane segment rectangles (R, 4, 2), round joins at inner vertices (centres (J, 2),
    radii (J,)), junction outlines and the end-to-start quadrilaterals of a route."""

    rects: np.ndarray
    join_xy: np.ndarray
    join_r: np.ndarray
    junctions: tuple[np.ndarray, ...]


def _shape(text: str) -> np.ndarray:
    return np.array([[float(v) for v in p.split(",")[:2]] for p in text.split()])


def _rectangles(shape: np.ndarray, width: float) -> list[np.ndarray]:
    out = []
    for a, b in zip(shape[:-1], shape[1:], strict=True):
        length = math.hypot(*(b - a))
        if length < 1e-6:
            continue
        n = np.array([-(b - a)[1], (b - a)[0]]) / length * 0.5 * width
        out.append(np.array([a - n, b - n, b + n, a + n]))
    return out


def _passenger(lane: ET.Element) -> bool:
    allow, disallow = lane.get("allow"), lane.get("disallow")
    return ((allow is None or "passenger" in allow.split())
            and (disallow is None or "passenger" not in disallow.split()))


def _corner(lane: ET.Element, at_end: bool, side: float) -> np.ndarray:
    """A corner of a lane's end (or start) cross-section, side +1 left, -1 right."""
    shape = _shape(lane.get("shape", ""))
    a, b = (shape[-2], shape[-1]) if at_end else (shape[0], shape[1])
    d = (b - a) / math.hypot(*(b - a))
    p = b if at_end else a
    return p + side * 0.5 * float(lane.get("width", "3.2")) * np.array([-d[1], d[0]])


def _bridge(ending: list[ET.Element], starting: list[ET.Element]) -> np.ndarray:
    """The quadrilateral from one edge's lane ends to the next edge's lane starts (right
    end corner of the rightmost lane, ..., left end corner of the leftmost)."""
    def index(lane: ET.Element) -> int:
        return int(lane.get("index", "0"))

    return np.array([_corner(min(ending, key=index), True, -1.0),
                     _corner(min(starting, key=index), False, -1.0),
                     _corner(max(starting, key=index), False, 1.0),
                     _corner(max(ending, key=index), True, 1.0)])


def read_road(net: Path, route: tuple[str, ...]) -> IndependentRoad:
    root = ET.parse(net).getroot()
    lanes = {ln.get("id"): ln for e in root.iter("edge") for ln in e.iter("lane")}
    edges = {e.get("id"): e for e in root.iter("edge")}
    keep: list[ET.Element] = [ln for eid in route for ln in edges[eid].iter("lane")
                              if _passenger(ln)]
    for a, b in zip(route, route[1:], strict=False):
        for conn in root.iter("connection"):
            if conn.get("from") != a or conn.get("to") != b:
                continue
            via = conn.get("via")
            while via:  # the chain of internal lanes of this connection
                keep.append(lanes[via])
                via = next((c.get("via") for c in root.iter("connection")
                            if c.get("from") == via.rsplit("_", 1)[0]
                            and c.get("fromLane") == via.rsplit("_", 1)[1]
                            and c.get("to") == b), None)
    shapes = [(_shape(ln.get("shape", "")), float(ln.get("width", "3.2"))) for ln in keep]
    rects = [r for shape, width in shapes for r in _rectangles(shape, width)]
    joins = [(v, 0.5 * width) for shape, width in shapes for v in shape[1:-1]]
    nodes = {edges[eid].get("to") for eid in route[:-1]}
    junctions = tuple(_shape(j.get("shape", "")) for j in root.iter("junction")
                      if j.get("id") in nodes and j.get("shape"))
    junctions += tuple(_bridge([ln for ln in edges[a].iter("lane") if _passenger(ln)],
                               [ln for ln in edges[b].iter("lane") if _passenger(ln)])
                       for a, b in zip(route, route[1:], strict=False))
    return IndependentRoad(np.array(rects), np.array([v for v, _ in joins]).reshape(-1, 2),
                           np.array([r for _, r in joins]), junctions)


def _in_lanes(pts: np.ndarray, road: IndependentRoad) -> tuple[np.ndarray, np.ndarray]:
    """(inside some lane (P,), distance to the nearest lane (P,)): rectangles and joins."""
    inside, dist = _in_rects(pts, road.rects)
    if road.join_r.size:
        d = np.hypot(pts[:, None, 0] - road.join_xy[None, :, 0],
                     pts[:, None, 1] - road.join_xy[None, :, 1]) - road.join_r[None]
        inside |= np.any(d <= 0.0, axis=1)
        dist = np.minimum(dist, np.maximum(np.min(d, axis=1), 0.0))
    return inside, dist


def _in_rects(pts: np.ndarray, rects: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(inside some rectangle (P,), distance to the nearest rectangle (P,))."""
    a = rects[:, 0]
    u = rects[:, 1] - rects[:, 0]
    v = rects[:, 3] - rects[:, 0]
    lu, lv = np.hypot(u[:, 0], u[:, 1]), np.hypot(v[:, 0], v[:, 1])
    rel = pts[:, None, :] - a[None]
    su = np.sum(rel * u[None], axis=-1) / lu
    sv = np.sum(rel * v[None], axis=-1) / lv
    inside = (su >= -1e-9) & (su <= lu + 1e-9) & (sv >= -1e-9) & (sv <= lv + 1e-9)
    du = np.maximum(np.maximum(-su, su - lu), 0.0)
    dv = np.maximum(np.maximum(-sv, sv - lv), 0.0)
    return np.any(inside, axis=1), np.min(np.hypot(du, dv), axis=1)


def _polygon_distance(pts: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance to a polygon (0 inside; even-odd ray casting, then the nearest edge)."""
    inside = np.zeros(len(pts), dtype=bool)
    best = np.full(len(pts), np.inf)
    for p, q in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        crosses = (p[1] > pts[:, 1]) != (q[1] > pts[:, 1])
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = p[0] + (pts[:, 1] - p[1]) * (q[0] - p[0]) / (q[1] - p[1])
        inside ^= crosses & (pts[:, 0] < x_at)
        d = q - p
        t = np.clip(((pts - p) @ d) / max(float(d @ d), 1e-12), 0.0, 1.0)
        best = np.minimum(best, np.hypot(*(pts - (p + t[:, None] * d)).T))
    out: np.ndarray = np.where(inside, 0.0, best)
    return out


def _corners(record: RunRecord, x: np.ndarray, y: np.ndarray, psi: np.ndarray) -> np.ndarray:
    box = record.info.ego
    c, s = np.cos(psi), np.sin(psi)
    cx, cy = x + box.cg_to_box_centre_m * c, y + box.cg_to_box_centre_m * s
    out = []
    for lx, ly in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
        ax, ay = 0.5 * lx * box.length_m, 0.5 * ly * box.width_m
        out.append(np.stack([cx + c * ax - s * ay, cy + s * ax + c * ay], axis=-1))
    return np.stack(out, axis=1)  # (T, 4, 2)


@dataclass
class Tally:
    runs: int = 0
    inside_rows: int = 0
    outside_rows: int = 0
    recorded_offroad_runs: int = 0


def check_run(run_dir: Path, tally: Tally) -> None:
    record = load_run(run_dir, neighbours=False, arrays=False, series=False)
    road = read_road(Path(record.info.net), record.road.route)
    ego = record.trace.ego
    rows = np.arange(0, len(record.trace), ROW_STRIDE)
    tally.runs += 1
    assert record.verdict is not None
    tally.recorded_offroad_runs += record.verdict.value("offroad_s") > 0
    for offset in OFFSETS_M:
        x = ego.x_m - offset * np.sin(ego.psi_rad)
        y = ego.y_m + offset * np.cos(ego.psi_rad)
        excess = offroad_excess_series(build_context(_moved(record, rows, x, y)))
        corners = _corners(record, x[rows], y[rows], ego.psi_rad[rows]).reshape(-1, 2)
        ok = np.all(np.isfinite(corners.reshape(-1, 8)), axis=1)
        inside, dist = _in_lanes(corners, road)
        inside, dist = inside.reshape(-1, 4), dist.reshape(-1, 4)
        junction = (np.min([_polygon_distance(corners, j) for j in road.junctions], axis=0)
                    .reshape(-1, 4) if road.junctions else np.full_like(dist, np.inf))
        all_in = ok & np.all(inside, axis=1)
        far_out = ok & np.any(np.minimum(dist, junction)
                              > OFFROAD_TOLERANCE_M + JOIN_MARGIN_M, axis=1)
        assert np.all(excess[all_in] <= 1e-6), (run_dir.name, offset)
        assert np.all(excess[far_out] > OFFROAD_TOLERANCE_M), (run_dir.name, offset)
        tally.inside_rows += int(np.sum(all_in))
        tally.outside_rows += int(np.sum(far_out))


def _moved(record: RunRecord, rows: np.ndarray, x: np.ndarray, y: np.ndarray) -> RunRecord:
    """The record with the trace rows ``rows`` only and the ego's CG at (x, y)[rows]."""
    tr = record.trace
    ego = replace(tr.ego.take(rows), x_m=np.asarray(x, dtype=np.float64)[rows],
                  y_m=np.asarray(y, dtype=np.float64)[rows])
    trace = Trace(step=tr.step[rows], t_s=tr.t_s[rows], ego=ego,
                  decision=tr.decision.take(rows), safety=tr.safety.take(rows),
                  controller=tr.controller.take(rows), timing=tr.timing.take(rows))
    return replace(record, trace=trace)


def _catalogs(out: Path) -> list[Path]:
    """The shared real catalog at 20 s (absolute net paths) and a real-share stress one."""
    text = (REAL / "catalog.toml").read_text()
    text = re.sub(r'net = "([^"]+)"', lambda m: f'net = "{REAL / m.group(1)}"', text)
    text = re.sub(r"duration_s = [0-9.]+", "duration_s = 20.0", text)
    shared = out / "shared.toml"
    shared.write_text(text)
    stress = out / "stress"
    subprocess.run([sys.executable, "-m", "suite.stress", "--n", "110", "--seed", "3",
                    "--out", str(stress), "--real-share", "1.0", "--duration-s", "20"],
                   check=True, cwd=REPO, capture_output=True)
    return [shared, stress / "catalog.toml"]


def test_offroad_verdicts_on_real_motorways_agree_with_an_independent_check(
        tmp_path: Path) -> None:
    jobs = "2" if (os.cpu_count() or 1) > 1 else "1"
    tally = Tally()
    for k, catalog in enumerate(_catalogs(tmp_path)):
        runs = tmp_path / f"runs{k}"
        res = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                              str(runs), "--jobs", jobs, "--no-log"], cwd=REPO,
                             capture_output=True, text=True, check=False)
        assert res.returncode in (0, 1), res.stdout[-2000:] + res.stderr[-2000:]
        for run_dir in sorted(p for p in runs.iterdir() if (p / "run.json").is_file()):
            check_run(run_dir, tally)
    print(tally)  # with -s: how many rows each check covered
    assert tally.runs >= 100
    assert tally.inside_rows > 10_000 and tally.outside_rows > 10_000
