"""The road: an OpenDRIVE file -> a SUMO net with SUMO's netconvert
(``--opendrive-files``), and the map from OpenDRIVE (road, lane) to SUMO (edge, lane
index).

netconvert splits a road into one edge per lane section and driving direction (lanes
with negative ids drive along the road's reference line, positive ids against it) and
writes each lane's OpenDRIVE origin as its ``origId`` parameter (``<road>_<lane>``,
``--output.original-names``). The output is deterministic: netconvert's header comment
(its time stamp and paths) is removed.

A *direct junction* (a junction ``connection`` without ``connectingRoad``, OpenDRIVE
1.7) is refused: netconvert cannot read it.
"""

from __future__ import annotations

import os
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from suite.importers.openscenario.errors import OscImportError, fail_at
from suite.importers.openscenario.xml_safe import read_xml
from sumo_nets import sumo_home
from sumo_nets.build import NETCONVERT_OPTIONS, netconvert_path

__all__ = ["LaneMap", "OdrRoad", "build_road"]


@dataclass(frozen=True)
class OdrRoad:
    """An OpenDRIVE road: id, length [m] and lane section starts s [m]."""

    road_id: str
    length_m: float
    sections_m: tuple[float, ...]


@dataclass(frozen=True)
class LaneMap:
    """OpenDRIVE -> SUMO: ``lanes[(road, lane id)]`` the SUMO (edge, lane index) pairs,
    one per lane section in driving order; ``roads`` by id; ``edges`` the edges of a
    (road, side) in driving order (side -1: negative lane ids, +1 positive)."""

    lanes: dict[tuple[str, int], tuple[tuple[str, int], ...]]
    roads: dict[str, OdrRoad]
    edges: dict[tuple[str, int], tuple[str, ...]]

    def as_json(self) -> dict[str, Any]:
        return {"roads": {r.road_id: {"length_m": r.length_m, "sections_m": list(r.sections_m)}
                          for r in self.roads.values()},
                "lanes": [{"road": r, "lane": ln, "sumo": [[e, i] for e, i in v]}
                          for (r, ln), v in sorted(self.lanes.items())]}


def _roads(tree: Any) -> dict[str, OdrRoad]:
    roads: dict[str, OdrRoad] = {}
    root = tree.getroot()
    for j in root.iter("junction"):
        for c in j.iter("connection"):
            if not c.get("connectingRoad"):
                raise fail_at(c, "a direct junction (a connection without connectingRoad, "
                              "OpenDRIVE 1.7) is not supported: netconvert cannot read it")
    for r in root.iter("road"):
        if r.get("rule", "RHT") == "LHT":
            raise fail_at(r, "left-hand traffic roads (rule LHT) are not supported")
        try:
            length = float(r.get("length", "nan"))
            sections = tuple(sorted(float(s.get("s", "0")) for s in r.iter("laneSection")))
        except ValueError:
            raise fail_at(r, "a road needs numeric length and laneSection s") from None
        roads[str(r.get("id"))] = OdrRoad(str(r.get("id")), length, sections)
    if not roads:
        raise OscImportError(str(tree.docinfo.URL), "OpenDRIVE", "no road in the file")
    return roads


def _netconvert(xodr: Path, out: Path) -> None:
    with tempfile.TemporaryDirectory(prefix="hwyeval_osc_") as tmp:
        tmp_out = Path(tmp) / "out.net.xml"
        cmd = [str(netconvert_path()), "--opendrive-files", str(xodr), *NETCONVERT_OPTIONS,
               "--output.original-names", "true", "--output-file", str(tmp_out)]
        res = subprocess.run(cmd, capture_output=True, text=True,
                             env={**os.environ, "SUMO_HOME": sumo_home()})
        msgs = [ln.strip() for ln in (res.stdout + res.stderr).splitlines() if ln.strip()]
        if res.returncode != 0 or not tmp_out.is_file():
            detail = "; ".join(m for m in msgs if "Error" in m) or "; ".join(msgs[-3:])
            raise OscImportError(str(xodr), "OpenDRIVE", f"netconvert failed "
                                 f"(rc={res.returncode}): {detail}")
        text = tmp_out.read_text(encoding="utf-8")
    text = re.sub(r"<!-- generated on .*?-->\s*", "", text, count=1, flags=re.S)
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(out.name + ".partial")
    partial.write_text(text, encoding="utf-8")
    partial.replace(out)


def _order(edges: list[tuple[str, str, str]]) -> tuple[str, ...]:
    """Edge ids (id, from, to) chained from the one nothing of the list enters."""
    to_nodes = {t for _, _, t in edges}
    by_from = {f: (e, t) for e, f, t in edges}
    start = [e for e in edges if e[1] not in to_nodes]
    if not start:
        return tuple(sorted(e for e, _, _ in edges))
    out, node = [start[0][0]], start[0][2]
    while node in by_from and len(out) < len(edges):
        out.append(by_from[node][0])
        node = by_from[node][1]
    return tuple(out)


def _lane_map(net: Path, roads: dict[str, OdrRoad]) -> LaneMap:
    root = read_xml(net).getroot()
    per_side: dict[tuple[str, int], list[tuple[str, str, str]]] = {}
    lanes: dict[tuple[str, int], list[tuple[str, int]]] = {}
    for e in root.iter("edge"):
        if e.get("function") == "internal":
            continue
        for ln in e.iter("lane"):
            orig = next((p.get("value") for p in ln.iter("param") if p.get("key") == "origId"),
                        None)
            if orig is None or "_" not in orig:
                continue
            road, lane_id = orig.rsplit("_", 1)
            if road not in roads:
                continue
            key = (road, int(lane_id))
            lanes.setdefault(key, []).append((str(e.get("id")), int(ln.get("index", "0"))))
            side = (road, -1 if int(lane_id) < 0 else 1)
            item = (str(e.get("id")), str(e.get("from")), str(e.get("to")))
            if item not in per_side.setdefault(side, []):
                per_side[side].append(item)
    edges = {k: _order(v) for k, v in per_side.items()}
    ordered: dict[tuple[str, int], tuple[tuple[str, int], ...]] = {}
    for (road, lane_id), pairs in lanes.items():
        chain = edges[(road, -1 if lane_id < 0 else 1)]
        ordered[(road, lane_id)] = tuple(sorted(pairs, key=lambda p: chain.index(p[0])))
    return LaneMap(ordered, roads, edges)


def build_road(xodr: Path, out: Path) -> LaneMap:
    """netconvert ``xodr`` into ``out`` and map its lanes (module docstring)."""
    roads = _roads(read_xml(xodr))
    _netconvert(xodr, out)
    return _lane_map(out, roads)
