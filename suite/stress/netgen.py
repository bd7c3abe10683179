"""Generated stress nets: one carriageway with a curve and, optionally, an on-ramp, built
from plain XML with netconvert (as ``sumo_nets.build`` builds the bundled nets).

Layout (:class:`NetLayout`), metres and degrees: a straight lead-in, one constant-radius
arc, a straight lead-out; ``lanes`` regular lanes of ``LANE_WIDTH_M`` (3.5 m), optionally
a hard shoulder (lane 0, ``SHOULDER_WIDTH_M`` = 3 m, emergency and authority vehicles
only). ``radius_m`` is the radius of the centre of the regular lanes, ``angle_deg`` the
turn (positive left). Every edge has ``spreadType="right"``: its shape is the left edge
of the carriageway and lanes are laid out to its right, so the regular lanes keep their
place where a lane is added on the right.

With a merge, the straight holding ``merge_at_m`` is split there: an acceleration edge of
``ACCEL_LENGTH_M`` (250 m) with one more lane, right of the regular lanes (inside a
shoulder), fed by the single-lane on-ramp ``ramp`` (``RAMP_LENGTH_M`` = 250 m, joining at
``RAMP_ANGLE_DEG`` = 4 deg, 80 km/h); the acceleration lane ends with the edge (traffic on
it must change left). Connections are explicit (a connection file): lanes continue
straight, shoulder to shoulder; nothing leaves the acceleration lane.

Determinism: the sources are a function of the layout; netconvert's output is
deterministic but for its leading comment, which is replaced by a fixed one (as
``sumo_nets.build`` does), so a layout always gives the same bytes. Warnings of
netconvert are errors.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from sumo_nets import LANE_WIDTH_M, SHOULDER_VCLASSES, SHOULDER_WIDTH_M, SPEED_LIMIT_MPS, sumo_home
from sumo_nets.build import NETCONVERT_OPTIONS, netconvert_path

__all__ = ["ACCEL_LENGTH_M", "RAMP_EDGE", "RAMP_LENGTH_M", "NetLayout", "build_net",
           "render_sources"]

ACCEL_LENGTH_M = 250.0
RAMP_LENGTH_M = 250.0
RAMP_ANGLE_DEG = 4.0
RAMP_SPEED_MPS = 22.22
RAMP_EDGE = "ramp"
ARC_POINT_SPACING_M = 5.0
EDGE_PRIORITY = 10
RAMP_PRIORITY = 5


@dataclass(frozen=True)
class NetLayout:
    """A generated carriageway (module doc). Lengths [m], angle [deg] (+ left)."""

    name: str
    lanes: int
    shoulder: bool
    lead_in_m: float
    radius_m: float
    angle_deg: float
    lead_out_m: float
    merge_at_m: float | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.lanes <= 6:
            raise ValueError(f"NetLayout.lanes must be in 1..6, got {self.lanes}")
        for field_name in ("lead_in_m", "lead_out_m", "radius_m"):
            value = getattr(self, field_name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"NetLayout.{field_name} must be > 0, got {value!r}")
        if not (math.isfinite(self.angle_deg) and 0 < abs(self.angle_deg) < 180):
            raise ValueError(f"NetLayout.angle_deg must be in (0, 180) in magnitude, got "
                             f"{self.angle_deg!r}")
        if self.radius_m <= self.half_width_m:
            raise ValueError("NetLayout.radius_m must exceed half the regular lanes' width")
        if self.merge_at_m is not None:
            straights = ((0.0, self.lead_in_m), (self.curve_end_m, self.length_m))
            if not any(a + 30.0 <= self.merge_at_m <= b - ACCEL_LENGTH_M - 30.0
                       for a, b in straights):
                raise ValueError("NetLayout.merge_at_m must leave the acceleration edge on "
                                 f"a straight, got {self.merge_at_m!r}")

    @property
    def half_width_m(self) -> float:
        """Half the width of the regular lanes [m]."""
        return 0.5 * self.lanes * LANE_WIDTH_M

    @property
    def arc_length_m(self) -> float:
        """Length of the curve along the regular lanes' centre [m]."""
        return self.radius_m * math.radians(abs(self.angle_deg))

    @property
    def curve_end_m(self) -> float:
        return self.lead_in_m + self.arc_length_m

    @property
    def length_m(self) -> float:
        """Length of the carriageway along the regular lanes' centre [m]."""
        return self.curve_end_m + self.lead_out_m


@dataclass(frozen=True)
class _Edge:
    """One main edge: its left-edge polyline and whether it is the acceleration edge."""

    points: tuple[tuple[float, float], ...]
    accel: bool


def _fmt(v: float) -> str:
    s = f"{v:.3f}"
    return "0.000" if s == "-0.000" else s


def _straight(x: float, y: float, h: float, length: float) -> list[tuple[float, float]]:
    return [(x, y), (x + length * math.cos(h), y + length * math.sin(h))]


def _arc(x: float, y: float, h: float, radius: float, angle_rad: float
         ) -> list[tuple[float, float]]:
    sign = 1.0 if angle_rad > 0 else -1.0
    cx, cy = x - sign * radius * math.sin(h), y + sign * radius * math.cos(h)
    n = max(2, math.ceil(radius * abs(angle_rad) / ARC_POINT_SPACING_M))
    return [(cx + sign * radius * math.sin(h + angle_rad * k / n),
             cy - sign * radius * math.cos(h + angle_rad * k / n)) for k in range(n + 1)]


def _main_edges(layout: NetLayout) -> list[_Edge]:
    """The main edges' left-edge polylines, starting at (0, half width) heading +X: the
    regular lanes' centre starts at the origin. The left edge of a left turn is inside
    the curve (radius R - W/2), of a right turn outside (R + W/2)."""
    half = layout.half_width_m
    turn = math.radians(layout.angle_deg)
    r_left = layout.radius_m - half if turn > 0 else layout.radius_m + half
    # straight pieces as (start along the centre, length); the lead-out starts after the arc
    pieces: list[tuple[str, float]] = []
    m = layout.merge_at_m
    for start, length in ((0.0, layout.lead_in_m), (layout.curve_end_m, layout.lead_out_m)):
        if m is not None and start < m < start + length:
            pieces += [("s", m - start), ("a", ACCEL_LENGTH_M),
                       ("s", start + length - m - ACCEL_LENGTH_M)]
        else:
            pieces.append(("s", length))
        if start == 0.0:
            pieces.append(("c", 0.0))
    edges: list[_Edge] = []
    x, y, h = 0.0, half, 0.0
    for kind, length in pieces:
        if kind == "c":
            pts = _arc(x, y, h, r_left, turn)
            h += turn
        else:
            pts = _straight(x, y, h, length)
        x, y = pts[-1]
        edges.append(_Edge(tuple(pts), accel=kind == "a"))
    return edges


def _lanes_xml(layout: NetLayout) -> list[str]:
    """The lanes that differ from the edge's defaults: the hard shoulder."""
    out = []
    if layout.shoulder:
        out.append(f'        <lane index="0" allow="{" ".join(SHOULDER_VCLASSES)}" '
                   f'width="{SHOULDER_WIDTH_M:.2f}"/>')
    return out


def _ramp_points(node: tuple[float, float], heading: float, layout: NetLayout
                 ) -> tuple[tuple[float, float], tuple[float, float]]:
    """(start, end) of the on-ramp: it ends at the acceleration lane's centre where the
    acceleration edge starts and comes from behind, on the right, at RAMP_ANGLE_DEG."""
    offset = 2.0 * layout.half_width_m + 0.5 * LANE_WIDTH_M
    ex = node[0] + offset * math.sin(heading)
    ey = node[1] - offset * math.cos(heading)
    back = heading + math.radians(RAMP_ANGLE_DEG)  # pointing left of the road: from the right
    return (ex - RAMP_LENGTH_M * math.cos(back), ey - RAMP_LENGTH_M * math.sin(back)), (ex, ey)


def _connections(layout: NetLayout, edges: list[_Edge]) -> list[str]:
    s = int(layout.shoulder)
    n = layout.lanes
    out = []
    for k in range(len(edges) - 1):
        a, b = f"e{k}", f"e{k + 1}"
        pairs: list[tuple[int, int]] = [(0, 0)] if s else []
        if edges[k + 1].accel:  # into the acceleration edge: regular lanes move up one
            pairs += [(s + j, s + 1 + j) for j in range(n)]
            out.append(f'    <connection from="{RAMP_EDGE}" to="{b}" fromLane="0" '
                       f'toLane="{s}"/>')
        elif edges[k].accel:  # out of it: the acceleration lane ends
            pairs += [(s + 1 + j, s + j) for j in range(n)]
        else:
            pairs += [(s + j, s + j) for j in range(n)]
        out += [f'    <connection from="{a}" to="{b}" fromLane="{i}" toLane="{o}"/>'
                for i, o in pairs]
    return out


def render_sources(layout: NetLayout) -> dict[str, str]:
    """The plain-XML sources ``{file name: text}`` (``.nod.xml``, ``.edg.xml``, ``.con.xml``)."""
    edges = _main_edges(layout)
    header = (f'<?xml version="1.0" encoding="UTF-8"?>\n<!-- {layout.name}: generated by '
              "suite.stress.netgen from its NetLayout. Units: m, m/s. -->\n")
    nodes = [edges[0].points[0], *(e.points[-1] for e in edges)]
    nod = [header, "<nodes>\n"]
    for i, (nx, ny) in enumerate(nodes):
        kind = "dead_end" if i in (0, len(nodes) - 1) else "priority"
        nod.append(f'    <node id="n{i}" x="{_fmt(nx)}" y="{_fmt(ny)}" type="{kind}"/>\n')
    ramp: tuple[tuple[float, float], tuple[float, float]] | None = None
    merge_k = next((k for k, e in enumerate(edges) if e.accel), None)
    if merge_k is not None:
        p0, p1 = edges[merge_k].points[0], edges[merge_k].points[1]
        ramp = _ramp_points(p0, math.atan2(p1[1] - p0[1], p1[0] - p0[0]), layout)
        nod.append(f'    <node id="r0" x="{_fmt(ramp[0][0])}" y="{_fmt(ramp[0][1])}" '
                   'type="dead_end"/>\n')
    nod.append("</nodes>\n")
    edg = [header, "<edges>\n"]
    total = layout.lanes + int(layout.shoulder)
    for k, e in enumerate(edges):
        lanes = total + int(e.accel)
        attrs = (f'id="e{k}" from="n{k}" to="n{k + 1}" priority="{EDGE_PRIORITY}" '
                 f'numLanes="{lanes}" speed="{SPEED_LIMIT_MPS:.2f}" width="{LANE_WIDTH_M:.2f}" '
                 'spreadType="right"')
        if len(e.points) > 2:
            attrs += ' shape="' + " ".join(f"{_fmt(px)},{_fmt(py)}" for px, py in e.points) + '"'
        extra = _lanes_xml(layout)
        if extra:
            edg += [f"    <edge {attrs}>\n", *(line + "\n" for line in extra), "    </edge>\n"]
        else:
            edg.append(f"    <edge {attrs}/>\n")
    if ramp is not None and merge_k is not None:
        (sx, sy), (ex, ey) = ramp
        edg.append(f'    <edge id="{RAMP_EDGE}" from="r0" to="n{merge_k}" '
                   f'priority="{RAMP_PRIORITY}" numLanes="1" speed="{RAMP_SPEED_MPS:.2f}" '
                   f'width="{LANE_WIDTH_M:.2f}" shape="{_fmt(sx)},{_fmt(sy)} '
                   f'{_fmt(ex)},{_fmt(ey)}"/>\n')
    edg.append("</edges>\n")
    con = [header, "<connections>\n", *(c + "\n" for c in _connections(layout, edges)),
           "</connections>\n"]
    return {f"{layout.name}.nod.xml": "".join(nod), f"{layout.name}.edg.xml": "".join(edg),
            f"{layout.name}.con.xml": "".join(con)}


def route_of(layout: NetLayout) -> tuple[str, ...]:
    """The main edges in driving order."""
    return tuple(f"e{k}" for k in range(len(_main_edges(layout))))


_HEADER_RE = re.compile(r"\A(<\?xml[^>]*\?>\s*)<!--.*?-->\s*", re.DOTALL)


def build_net(layout: NetLayout, out_dir: Path, src_dir: Path | None = None) -> Path:
    """Write the sources (into ``src_dir``, default ``out_dir/src``) and build
    ``out_dir/<name>.net.xml``; raises RuntimeError if netconvert fails or warns."""
    src_dir = Path(src_dir) if src_dir is not None else Path(out_dir) / "src"
    src_dir.mkdir(parents=True, exist_ok=True)
    paths = {}
    for fname, text in render_sources(layout).items():
        (src_dir / fname).write_text(text, encoding="utf-8")
        paths[fname.rsplit(".", 2)[1]] = src_dir / fname
    out = Path(out_dir) / f"{layout.name}.net.xml"
    with tempfile.TemporaryDirectory(prefix="stress_net_") as tmp:
        tmp_out = Path(tmp) / out.name
        cmd = [str(netconvert_path()), "--node-files", str(paths["nod"]), "--edge-files",
               str(paths["edg"]), "--connection-files", str(paths["con"]),
               *NETCONVERT_OPTIONS, "--output-file", str(tmp_out)]
        res = subprocess.run(cmd, capture_output=True, text=True,
                             env={**os.environ, "SUMO_HOME": sumo_home()}, check=False)
        msgs = (res.stdout + res.stderr).strip()
        if res.returncode != 0 or "Warning" in msgs or "Error" in msgs:
            raise RuntimeError(f"netconvert failed or warned for {layout.name}:\n{msgs}")
        text = tmp_out.read_text(encoding="utf-8")
    m = _HEADER_RE.match(text)
    if m is None:
        raise RuntimeError(f"unexpected netconvert output header for {layout.name}")
    fixed = (f"<!-- {layout.name}.net.xml: built by suite.stress.netgen with netconvert from "
             "src/; do not edit. -->\n\n")
    out.write_text(m.group(1) + fixed + text[m.end():], encoding="utf-8")
    return out
