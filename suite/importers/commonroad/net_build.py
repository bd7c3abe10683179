"""The SUMO net of the ego's road: one edge per lanelet row, lanelet centre lines as lane
shapes, successors as lane connections, straight extension edges where the road ends.

Plain-XML sources (nodes, edge types, edges with an explicit ``shape`` and ``width`` per
lane, connections) go through netconvert with the bundled nets' options
(:data:`sumo_nets.build.NETCONVERT_OPTIONS`: no offset normalisation, so net x/y are
CommonRoad x/y; no turnarounds; mm precision).

* Nodes: a row's end and the starts of the rows its lanelets' successors are in are one
  node (and likewise for predecessors); it lies at the mean of those lane ends.
* Extensions: a row whose start node nothing enters gets an upstream edge of
  ``upstream_extension_m``; a row whose end node nothing leaves gets a downstream edge of
  ``downstream_extension_m``, straight along d = the normalised mean of its lanes' last
  (first) segment directions, lane i from its end point p_i to p_i + L d (or from
  p_i - L d to p_i), same widths, lane i connected to lane i.
* Link edges (``highway.motorway_link``, what hwyeval's default route avoids): rows with
  a lanelet of type ``accessRamp``/``exitRamp``; at a node two or more rows enter, those
  with fewer lanes than the widest (an on-ramp); at a node two or more rows leave, those
  with fewer lanes than the widest (an exit); then every row that only leads into links
  (upstream of an on-ramp) or is only reached from links (downstream of an exit), and the
  extensions of links. Every other edge is ``highway.motorway``.
* Lane speeds: :mod:`~suite.importers.commonroad.speed` (signs, else a default);
  extensions keep the speeds of the row they continue.
* Edge ids: ``L<label>`` of the row's rightmost lanelet (``L12``, or ``L12_1`` for the
  second piece of a cut lanelet 12, :mod:`~suite.importers.commonroad.split`).
* Lanes of ``shoulder`` lanelets allow only ``emergency``/``authority`` (hwyeval's hard
  shoulder, :func:`suite.road.network.is_shoulder_permissions`); others disallow
  pedestrians and bicycles.
* The file is deterministic: netconvert's header comment (its time stamp and the
  temporary source paths) is replaced by a fixed one naming the CommonRoad file and
  netconvert's version (:func:`fixed_header`), so one file imported twice gives the
  same bytes.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from suite.importers.commonroad.errors import ImportFailure
from suite.importers.commonroad.geometry import resample
from suite.importers.commonroad.lanelets import RoadRows
from suite.importers.commonroad.records import FloatArray
from suite.importers.commonroad.speed import SpeedPlan
from sumo_nets import SHOULDER_VCLASSES, SPEED_LIMIT_MPS, sumo_home
from sumo_nets.build import NETCONVERT_OPTIONS, netconvert_path

__all__ = ["MAX_EXTENSION_M", "BuiltNet", "NetEdge", "NetParams", "build_net", "fixed_header",
           "plan_net"]

MAIN_TYPE = "highway.motorway"
LINK_TYPE = "highway.motorway_link"
RAMP_LANELET_TYPES = ("accessRamp", "exitRamp")
NON_VEHICLES = "pedestrian bicycle"

MAX_EXTENSION_M = 100_000.0
"""The longest straight extension or approach [m] (``--extension-m``,
``--approach-m``). A run resamples every lane of its route every 5 m
(:mod:`suite.road.lanes`) and its reference path finer, so the road's length sizes a
run's memory: 1e12 m would ask for 2e11 points. 100 km is more than a run drives
(24 min at 70 m/s)."""


@dataclass(frozen=True)
class NetParams:
    """Net-building parameters: extension lengths [m] and one speed limit [m/s] for
    every lane (``None``: from the file's signs, else the default of
    :mod:`~suite.importers.commonroad.speed`)."""

    downstream_extension_m: float = 1000.0
    upstream_extension_m: float = 200.0
    speed_limit_mps: float | None = None

    def __post_init__(self) -> None:
        for name in ("downstream_extension_m", "upstream_extension_m", "speed_limit_mps"):
            value = getattr(self, name)
            if value is None and name == "speed_limit_mps":
                continue
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
            if name != "speed_limit_mps" and value > MAX_EXTENSION_M:
                raise ValueError(f"{name}: expected at most {MAX_EXTENSION_M:g} m "
                                 f"(net_build.MAX_EXTENSION_M), got {value!r}")


@dataclass(frozen=True, eq=False)
class NetEdge:
    """One edge: id, lane shapes (n_i, 2) and widths [m] right to left, its row (``None``
    for an extension) and the rows' lanelet ids per lane, link or not."""

    edge_id: str
    from_node: str
    to_node: str
    lanes_xy_m: tuple[FloatArray, ...]
    widths_m: tuple[float, ...]
    shoulder: tuple[bool, ...]
    row: int | None
    lanelet_ids: tuple[int | None, ...]
    link: bool = False
    speeds_mps: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.lanes_xy_m)
        if not (len(self.widths_m) == len(self.shoulder) == len(self.lanelet_ids) == n):
            raise ValueError(f"edge {self.edge_id}: per-lane fields of different lengths")
        if self.speeds_mps and len(self.speeds_mps) != n:
            raise ValueError(f"edge {self.edge_id}: {len(self.speeds_mps)} speeds for {n} "
                             "lanes")

    def lane_speed_mps(self, lane: int) -> float:
        """Lane ``lane``'s speed limit [m/s] (SPEED_LIMIT_MPS when none was planned)."""
        return self.speeds_mps[lane] if self.speeds_mps else SPEED_LIMIT_MPS


@dataclass(frozen=True)
class BuiltNet:
    """The plan of the net and, once built, its file: edges by id, lane connections
    ((from edge, lane), (to edge, lane)), the edge of each row, extension edges, node
    positions [m], netconvert's warnings."""

    edges: dict[str, NetEdge]
    connections: tuple[tuple[tuple[str, int], tuple[str, int]], ...]
    row_edges: tuple[str, ...]
    downstream: tuple[str, ...]
    upstream: tuple[str, ...]
    nodes: dict[str, tuple[float, float]]
    path: Path | None = None
    warnings: tuple[str, ...] = field(default=())

    def successors(self, edge_id: str) -> tuple[str, ...]:
        return tuple(sorted({b[0] for a, b in self.connections if a[0] == edge_id}))

    def predecessors(self, edge_id: str) -> tuple[str, ...]:
        return tuple(sorted({a[0] for a, b in self.connections if b[0] == edge_id}))


class _Union:
    def __init__(self) -> None:
        self.parent: dict[tuple[str, int], tuple[str, int]] = {}

    def find(self, k: tuple[str, int]) -> tuple[str, int]:
        self.parent.setdefault(k, k)
        while self.parent[k] != k:
            self.parent[k] = self.parent[self.parent[k]]
            k = self.parent[k]
        return k

    def union(self, a: tuple[str, int], b: tuple[str, int]) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[max(ra, rb)] = min(ra, rb)


def _row_connections(road: RoadRows) -> set[tuple[tuple[int, int], tuple[int, int]]]:
    """Lane connections between rows ((row, lane), (row, lane)) from successors and
    predecessors (either side suffices)."""
    out = set()
    for r, row in enumerate(road.rows):
        for i, ll in enumerate(row.lanelets):
            for s in ll.successors:
                if s in road.place:
                    out.add(((r, i), road.place[s]))
            for p in ll.predecessors:
                if p in road.place:
                    out.add((road.place[p], (r, i)))
    return out


def _direction(lanes: list[FloatArray], at_end: bool) -> FloatArray:
    vecs = []
    for xy in lanes:
        seg = xy[-1] - xy[-2] if at_end else xy[1] - xy[0]
        n = float(np.hypot(*seg))
        if n > 0:
            vecs.append(seg / n)
    mean = np.mean(vecs, axis=0)
    return np.asarray(mean / float(np.hypot(*mean)), dtype=np.float64)


def _dedupe(xy: FloatArray) -> FloatArray:
    keep = [0]
    for k in range(1, len(xy)):
        if float(np.hypot(*(xy[k] - xy[keep[-1]]))) > 1e-3:
            keep.append(k)
    if keep[-1] != len(xy) - 1:
        keep[-1] = len(xy) - 1
    return np.asarray(xy[keep], dtype=np.float64)


def _links(road: RoadRows, nodes_in: dict[str, list[int]], nodes_out: dict[str, list[int]],
           succ: dict[int, set[int]], pred: dict[int, set[int]]) -> set[int]:
    """Rows that are links (module docstring)."""
    width = [len(row.lanelets) for row in road.rows]
    links = {r for r, row in enumerate(road.rows) if set(row.types) & set(RAMP_LANELET_TYPES)}
    for group in (*nodes_in.values(), *nodes_out.values()):
        if len(group) >= 2:
            widest = max(width[r] for r in group)
            links |= {r for r in group if width[r] < widest}
    changed = True
    while changed:
        changed = False
        for r in range(len(road.rows)):
            if r in links:
                continue
            if (succ[r] and succ[r] <= links) or (pred[r] and pred[r] <= links):
                links.add(r)
                changed = True
    return links


Connection = tuple[tuple[str, int], tuple[str, int]]
"""A lane connection ((from edge, lane), (to edge, lane))."""
RowEnd = tuple[str, int]
"""One end of a row: ("s", row) its start, ("e", row) its end."""


def _row_node_ids(road: RoadRows, conns: set[tuple[tuple[int, int], tuple[int, int]]],
                  path: str) -> dict[RowEnd, str]:
    """The node id of each row end: the end of a row and the starts of the rows it
    connects to are one node (module docstring). Raises ImportFailure for a row whose
    start and end are one node."""
    uf = _Union()
    for r in range(len(road.rows)):
        uf.find(("s", r))
        uf.find(("e", r))
    for (ra, _), (rb, _) in conns:
        uf.union(("e", ra), ("s", rb))
    node_id = {k: f"n{uf.find(k)[0]}{uf.find(k)[1]}" for k in list(uf.parent)}
    for r, row in enumerate(road.rows):
        if node_id[("s", r)] == node_id[("e", r)]:
            raise ImportFailure(path, f"lanelet {row.label}", "its row starts where it ends "
                                "(a loop of successors): it cannot become an edge")
    return node_id


def _node_positions(node_id: dict[RowEnd, str], lanes: list[list[FloatArray]]
                    ) -> dict[str, tuple[float, float]]:
    """Each node's position (x, y) [m]: the mean of the ends of the row lanes
    ``lanes[row]`` that meet there."""
    ends: dict[str, list[FloatArray]] = {}
    for r, row_lanes in enumerate(lanes):
        ends.setdefault(node_id[("s", r)], []).extend(xy[0] for xy in row_lanes)
        ends.setdefault(node_id[("e", r)], []).extend(xy[-1] for xy in row_lanes)
    return {n: (float(np.mean([p[0] for p in pts])), float(np.mean([p[1] for p in pts])))
            for n, pts in ends.items()}


def _rows_at_nodes(n_rows: int, node_id: dict[RowEnd, str]
                   ) -> tuple[dict[str, list[int]], dict[str, list[int]]]:
    """(rows entering each node, rows leaving each node), in row order."""
    nodes_in: dict[str, list[int]] = {}
    nodes_out: dict[str, list[int]] = {}
    for r in range(n_rows):
        nodes_in.setdefault(node_id[("e", r)], []).append(r)
        nodes_out.setdefault(node_id[("s", r)], []).append(r)
    return nodes_in, nodes_out


def _row_neighbours(n_rows: int, conns: set[tuple[tuple[int, int], tuple[int, int]]]
                    ) -> tuple[dict[int, set[int]], dict[int, set[int]]]:
    """(successor rows, predecessor rows) of each row."""
    succ: dict[int, set[int]] = {r: set() for r in range(n_rows)}
    pred: dict[int, set[int]] = {r: set() for r in range(n_rows)}
    for (ra, _), (rb, _) in conns:
        succ[ra].add(rb)
        pred[rb].add(ra)
    return succ, pred


def _downstream_extension(base: NetEdge, nodes: dict[str, tuple[float, float]],
                          length_m: float) -> tuple[NetEdge, set[Connection]]:
    """The straight edge of ``length_m`` [m] continuing ``base`` past its end (its end
    node is added to ``nodes``) and its lane connections from ``base``."""
    n = len(base.lanes_xy_m)
    d = _direction(list(base.lanes_xy_m), at_end=True) * length_m
    eid = f"{base.edge_id}-extension"
    end_node = f"{eid}-end"
    nodes[end_node] = (nodes[base.to_node][0] + d[0], nodes[base.to_node][1] + d[1])
    edge = NetEdge(eid, base.to_node, end_node,
                   tuple(np.array([xy[-1], xy[-1] + d]) for xy in base.lanes_xy_m),
                   base.widths_m, base.shoulder, None, (None,) * n, base.link, base.speeds_mps)
    return edge, {((base.edge_id, i), (eid, i)) for i in range(n)}


def _upstream_approach(base: NetEdge, nodes: dict[str, tuple[float, float]],
                       length_m: float) -> tuple[NetEdge, set[Connection]]:
    """The straight edge of ``length_m`` [m] leading into ``base`` at its start (its
    start node is added to ``nodes``) and its lane connections into ``base``."""
    n = len(base.lanes_xy_m)
    d = _direction(list(base.lanes_xy_m), at_end=False) * length_m
    eid = f"{base.edge_id}-approach"
    start_node = f"{eid}-start"
    nodes[start_node] = (nodes[base.from_node][0] - d[0], nodes[base.from_node][1] - d[1])
    edge = NetEdge(eid, start_node, base.from_node,
                   tuple(np.array([xy[0] - d, xy[0]]) for xy in base.lanes_xy_m),
                   base.widths_m, base.shoulder, None, (None,) * n, base.link, base.speeds_mps)
    return edge, {((eid, i), (base.edge_id, i)) for i in range(n)}


def plan_net(road: RoadRows, params: NetParams, path: str,
             speeds: SpeedPlan | None = None) -> BuiltNet:
    """The net's edges, nodes and connections (no file yet); lane speeds from
    ``speeds`` (one per lane of each row; ``None``: ``SPEED_LIMIT_MPS``)."""
    rows = road.rows
    conns = _row_connections(road)
    node_id = _row_node_ids(road, conns, path)
    lanes = [[_dedupe(ll.centre_xy_m) for ll in row.lanelets] for row in rows]
    nodes = _node_positions(node_id, lanes)
    nodes_in, nodes_out = _rows_at_nodes(len(rows), node_id)
    succ, pred = _row_neighbours(len(rows), conns)
    links = _links(road, nodes_in, nodes_out, succ, pred)
    edges: dict[str, NetEdge] = {}
    row_edges = []
    for r, row in enumerate(rows):
        eid = f"L{row.label}"
        row_edges.append(eid)
        edges[eid] = NetEdge(eid, node_id[("s", r)], node_id[("e", r)], tuple(lanes[r]),
                             tuple(ll.width_m for ll in row.lanelets),
                             tuple("shoulder" in ll.types for ll in row.lanelets), r,
                             tuple(ll.lanelet_id for ll in row.lanelets), r in links,
                             speeds.lanes_mps[r] if speeds is not None else ())
    connections = {((row_edges[ra], i), (row_edges[rb], j)) for (ra, i), (rb, j) in conns}
    downstream, upstream = [], []
    for r, row_edge in enumerate(row_edges):
        base = edges[row_edge]
        if not nodes_out.get(node_id[("e", r)]):
            ext, ext_conns = _downstream_extension(base, nodes, params.downstream_extension_m)
            edges[ext.edge_id] = ext
            connections |= ext_conns
            downstream.append(ext.edge_id)
        if not nodes_in.get(node_id[("s", r)]):
            ext, ext_conns = _upstream_approach(base, nodes, params.upstream_extension_m)
            edges[ext.edge_id] = ext
            connections |= ext_conns
            upstream.append(ext.edge_id)
    return BuiltNet(edges, tuple(sorted(connections)), tuple(row_edges), tuple(downstream),
                    tuple(upstream), nodes)


def _fmt_xy(xy: FloatArray) -> str:
    return " ".join(f"{x:.3f},{y:.3f}" for x, y in np.asarray(xy).reshape(-1, 2))


def _edge_shape(edge: NetEdge, nodes: dict[str, tuple[float, float]]) -> FloatArray:
    """The mean of the lane shapes (each resampled at the same arc-length fractions),
    from the from-node to the to-node."""
    k = max(len(xy) for xy in edge.lanes_xy_m)
    frac = np.linspace(0.0, 1.0, max(k, 2))
    mean = np.mean([resample(xy, frac) for xy in edge.lanes_xy_m], axis=0)
    mean[0] = nodes[edge.from_node]
    mean[-1] = nodes[edge.to_node]
    return np.asarray(mean, dtype=np.float64)


def render_sources(net: BuiltNet, params: NetParams) -> dict[str, str]:
    """Plain-XML sources ``{suffix: text}`` (``nod``, ``typ``, ``edg``, ``con``); each
    lane gets its own speed, an edge the highest of its lanes', a type the highest of
    the net's (``params.speed_limit_mps`` overrides all)."""
    def speed(e: NetEdge, lane: int) -> float:
        return params.speed_limit_mps or e.lane_speed_mps(lane)

    top = max((speed(e, i) for e in net.edges.values() for i in range(len(e.lanes_xy_m))),
              default=SPEED_LIMIT_MPS)
    head = '<?xml version="1.0" encoding="UTF-8"?>\n'
    nod = [head, "<nodes>\n"]
    for nid, (x, y) in sorted(net.nodes.items()):
        nod.append(f'    <node id={quoteattr(nid)} x="{x:.3f}" y="{y:.3f}" type="priority"/>\n')
    nod.append("</nodes>\n")
    typ = [head, "<types>\n",
           f'    <type id="{MAIN_TYPE}" priority="10" speed="{top:.2f}"/>\n',
           f'    <type id="{LINK_TYPE}" priority="5" speed="{top:.2f}"/>\n',
           "</types>\n"]
    edg = [head, "<edges>\n"]
    for eid, e in sorted(net.edges.items()):
        edg.append(f'    <edge id={quoteattr(eid)} from={quoteattr(e.from_node)} '
                   f'to={quoteattr(e.to_node)} type="{LINK_TYPE if e.link else MAIN_TYPE}" '
                   f'numLanes="{len(e.lanes_xy_m)}" '
                   f'speed="{max(speed(e, i) for i in range(len(e.lanes_xy_m))):.2f}" '
                   f'shape="{_fmt_xy(_edge_shape(e, net.nodes))}">\n')
        for i, (xy, w, sh) in enumerate(zip(e.lanes_xy_m, e.widths_m, e.shoulder, strict=True)):
            perm = (f'allow="{" ".join(SHOULDER_VCLASSES)}"' if sh
                    else f'disallow="{NON_VEHICLES}"')
            edg.append(f'        <lane index="{i}" width="{w:.3f}" speed="{speed(e, i):.2f}" '
                       f'{perm} '
                       f'shape="{_fmt_xy(xy)}"/>\n')
        edg.append("    </edge>\n")
    edg.append("</edges>\n")
    con = [head, "<connections>\n"]
    for (a, i), (b, j) in net.connections:
        con.append(f'    <connection from={quoteattr(a)} to={quoteattr(b)} fromLane="{i}" '
                   f'toLane="{j}"/>\n')
    con.append("</connections>\n")
    return {"nod": "".join(nod), "typ": "".join(typ), "edg": "".join(edg), "con": "".join(con)}


_HEADER_RE = re.compile(r"\A(<\?xml[^>]*\?>\s*)<!--(.*?)-->\s*", re.DOTALL)
_VERSION_RE = re.compile(r"netconvert\s+v?([0-9][^\s]*)")


def fixed_header(text: str, source: str) -> str:
    """``text`` (a net netconvert wrote) with its header comment, which holds a time
    stamp and the temporary source paths, replaced by a fixed one naming ``source``
    (a file name) and netconvert's version; unchanged when it has no such header."""
    m = _HEADER_RE.match(text)
    if m is None:
        return text
    version = _VERSION_RE.search(m.group(2))
    # XML comments may not hold "--": the options are written without their dashes
    opts = " ".join(f"{NETCONVERT_OPTIONS[i][2:]}={NETCONVERT_OPTIONS[i + 1]}"
                    for i in range(0, len(NETCONVERT_OPTIONS), 2))
    header = (f"<!-- built by hwyeval import commonroad from {source.replace('--', '- -')}\n"
              f"     with Eclipse SUMO netconvert {version.group(1) if version else '?'}, "
              f"options: {opts} -->\n\n")
    return m.group(1) + header + text[m.end():]


def build_net(net: BuiltNet, params: NetParams, out: Path, path: str) -> BuiltNet:
    """Run netconvert on the rendered sources and move the net to ``out`` atomically;
    :class:`ImportFailure` (element ``SUMO net``) when netconvert fails."""
    from dataclasses import replace

    sources = render_sources(net, params)
    with tempfile.TemporaryDirectory(prefix="hwyeval_cr_") as tmp:
        files = {}
        for suffix, text in sources.items():
            p = Path(tmp) / f"net.{suffix}.xml"
            p.write_text(text, encoding="utf-8")
            files[suffix] = p
        tmp_out = Path(tmp) / "out.net.xml"
        cmd = [str(netconvert_path()), "--node-files", str(files["nod"]),
               "--type-files", str(files["typ"]), "--edge-files", str(files["edg"]),
               "--connection-files", str(files["con"]), *NETCONVERT_OPTIONS,
               "--output-file", str(tmp_out)]
        res = subprocess.run(cmd, capture_output=True, text=True,
                             env={**os.environ, "SUMO_HOME": sumo_home()})
        msgs = [ln.strip() for ln in (res.stdout + res.stderr).splitlines() if ln.strip()]
        if res.returncode != 0 or not tmp_out.is_file():
            detail = "; ".join(m for m in msgs if "Error" in m) or "; ".join(msgs[-3:])
            raise ImportFailure(path, "SUMO net", f"netconvert failed (rc={res.returncode}): "
                                f"{detail}")
        out.parent.mkdir(parents=True, exist_ok=True)
        partial = out.with_name(out.name + ".partial")
        text = tmp_out.read_text(encoding="utf-8")
        partial.write_text(fixed_header(text, Path(path).name), encoding="utf-8")
        partial.replace(out)
    warnings = tuple(m for m in msgs if m.startswith("Warning"))
    return replace(net, path=out, warnings=warnings)
