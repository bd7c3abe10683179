"""Test nets for the road features the bundled nets lack, built from plain XML with
netconvert (the bundled nets' options, ``sumo_nets.build.NETCONVERT_OPTIONS``).

* :func:`lane_drop_net` -- a straight carriageway ``a`` of ``lanes`` lanes that loses
  its rightmost lane at ``drop_at_m``: edge ``b`` has one lane fewer; the ending lane
  has no connection (SUMO's vehicles on it must change left, as at a real lane drop).
* :func:`taper_net` -- the same with the ending lane narrowing over ``taper_m`` into
  its neighbour: edge ``t`` (``taper_m`` long) keeps every lane but its rightmost lane
  is ``taper_width_m`` wide, so the carriageway's right boundary steps in, as where a
  lane tapers off.

Both head +X from (0, 0); lanes 3.5 m. By default the left edge of the carriageway
stays straight (``spreadType="right"``: an edge's shape is its left edge), so the lanes
that continue keep their place; ``spread="center"`` lays each edge's lanes about its
axis instead, as OpenStreetMap imports do. Lengths in metres. Each builder returns the
path of the written ``<name>.net.xml`` in ``out_dir``; netconvert warnings are errors
(tests/plain_nets.py builds them, once per session for the same arguments).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sumo_nets import LANE_WIDTH_M
from sumo_nets.build import NETCONVERT_OPTIONS
from tests.plain_nets import build_plain_net

SPEED_MPS = 33.33


def _netconvert(name: str, out_dir: Path, nod: str, edg: str, con: str,
                extra: tuple[str, ...] = ()) -> Path:
    return build_plain_net(out_dir, name, f"<nodes>\n{nod}</nodes>\n",
                           f"<edges>\n{edg}</edges>\n", f"<connections>\n{con}</connections>\n",
                           (*NETCONVERT_OPTIONS, *extra), warnings_are_errors=True)


def _edge(eid: str, frm: str, to: str, lanes: int, widths: dict[int, float] | None = None,
          spread: str = "right") -> str:
    widths = widths or {}
    lane_xml = "".join(f'        <lane index="{i}" width="{w:.2f}"/>\n'
                       for i, w in sorted(widths.items()))
    return (f'    <edge id="{eid}" from="{frm}" to="{to}" numLanes="{lanes}" '
            f'speed="{SPEED_MPS}" priority="10" spreadType="{spread}" width="{LANE_WIDTH_M}">\n'
            f"{lane_xml}    </edge>\n")


def lane_drop_net(out_dir: Path, *, lanes: int = 3, drop_at_m: float = 600.0,
                  length_m: float = 1500.0, name: str = "lane_drop", spread: str = "right"
                  ) -> Path:
    """``a`` (0 → drop_at_m, ``lanes`` lanes) then ``b`` (``lanes - 1`` lanes).
    ``spread="center"`` centres each edge's lanes on the axis (as OpenStreetMap imports
    do): the continuing lanes then shift half a lane at the drop, through curved
    junction lanes."""
    if lanes < 2:
        raise ValueError(f"lane_drop_net: lanes must be >= 2, got {lanes}")
    nod = (f'    <node id="n0" x="0" y="0"/>\n    <node id="n1" x="{drop_at_m}" y="0"/>\n'
           f'    <node id="n2" x="{length_m}" y="0"/>\n')
    edg = _edge("a", "n0", "n1", lanes, spread=spread) + _edge("b", "n1", "n2", lanes - 1,
                                                             spread=spread)
    # lane i+1 of a continues as lane i of b; lane 0 of a ends
    con = "".join(f'    <connection from="a" to="b" fromLane="{i + 1}" toLane="{i}"/>\n'
                  for i in range(lanes - 1))
    return _netconvert(name, out_dir, nod, edg, con)


def taper_net(out_dir: Path, *, lanes: int = 3, taper_at_m: float = 600.0,
              taper_m: float = 120.0, taper_width_m: float = 1.75, length_m: float = 1500.0,
              name: str = "taper", spread: str = "right") -> Path:
    """``a`` (``lanes`` lanes), ``t`` (``taper_m``, its rightmost lane
    ``taper_width_m`` wide, ending), ``b`` (``lanes - 1`` lanes)."""
    if lanes < 2:
        raise ValueError(f"taper_net: lanes must be >= 2, got {lanes}")
    end = taper_at_m + taper_m
    nod = (f'    <node id="n0" x="0" y="0"/>\n    <node id="n1" x="{taper_at_m}" y="0"/>\n'
           f'    <node id="n2" x="{end}" y="0"/>\n    <node id="n3" x="{length_m}" y="0"/>\n')
    edg = (_edge("a", "n0", "n1", lanes, spread=spread)
           + _edge("t", "n1", "n2", lanes, {0: taper_width_m}, spread=spread)
           + _edge("b", "n2", "n3", lanes - 1, spread=spread))
    con = "".join(f'    <connection from="a" to="t" fromLane="{i}" toLane="{i}"/>\n'
                  for i in range(lanes))
    con += "".join(f'    <connection from="t" to="b" fromLane="{i + 1}" toLane="{i}"/>\n'
                   for i in range(lanes - 1))
    return _netconvert(name, out_dir, nod, edg, con)


def _shape(points: list[tuple[float, float]]) -> str:
    return " ".join(f"{x:.3f},{y:.3f}" for x, y in points)


def kinked_net(out_dir: Path, *, radius_m: float = 4400.0, vertex_spacing_m: float = 60.0,
               kink_at_m: float = 700.0, kink_offset_m: float = 1.5, length_m: float = 1500.0,
               lanes: int = 2, name: str = "kinked") -> Path:
    """One edge ``a`` of ``lanes`` lanes along a left arc of ``radius_m`` from (0, 0)
    heading +X, its shape a polyline with vertices every ``vertex_spacing_m``, as an
    OpenStreetMap way digitises such a road, except that the vertex at ``kink_at_m`` is
    moved ``kink_offset_m`` to the left with a second vertex 30 m before it (a
    digitising error: two kinks of opposite sign 30 m apart, +2.9° and -7.1° by
    default, on a road whose true radius is ``radius_m``). The true road is the arc."""
    def arc(s: float, lateral: float = 0.0) -> tuple[float, float]:
        phi = s / radius_m
        return ((radius_m - lateral) * math.sin(phi),
                radius_m - (radius_m - lateral) * math.cos(phi))
    stations = sorted({*np.arange(0.0, length_m, vertex_spacing_m).tolist(), length_m,
                       kink_at_m - 30.0, kink_at_m})
    pts = [arc(s, kink_offset_m if s == kink_at_m else 0.0) for s in stations]
    nod = (f'    <node id="n0" x="{pts[0][0]:.3f}" y="{pts[0][1]:.3f}"/>\n'
           f'    <node id="n1" x="{pts[-1][0]:.3f}" y="{pts[-1][1]:.3f}"/>\n')
    edg = (f'    <edge id="a" from="n0" to="n1" numLanes="{lanes}" speed="{SPEED_MPS}" '
           f'priority="10" spreadType="center" width="{LANE_WIDTH_M}" '
           f'shape="{_shape(pts)}"/>\n')
    return _netconvert(name, out_dir, nod, edg, "")


def curve_exit_net(out_dir: Path, *, radius_m: float = 600.0, name: str = "curve_exit"
                   ) -> Path:
    """A two-lane carriageway that gains a lane on the right in a left curve and loses
    it to an exit: ``a`` (2 lanes, 500 m straight +X), ``b`` (3 lanes, a left arc of
    ``radius_m`` over 300 m; lane 0 is the added exit lane), ``c`` (2 lanes, straight on
    from b's end) and the exit ramp ``x`` (1 lane, from b's lane 0, bearing right).
    Route ``a b c``: lane 0 of b is a lane that leaves the route."""
    phi = 300.0 / radius_m
    arc = [(500.0 + radius_m * math.sin(phi * k / 30), radius_m * (1 - math.cos(phi * k / 30)))
           for k in range(31)]
    end = arc[-1]
    heading = phi
    c_end = (end[0] + 700.0 * math.cos(heading), end[1] + 700.0 * math.sin(heading))
    x_end = (end[0] + 400.0 * math.cos(heading - 0.6), end[1] + 400.0 * math.sin(heading - 0.6))
    nod = ('    <node id="n0" x="0" y="0"/>\n    <node id="n1" x="500" y="0"/>\n'
           f'    <node id="n2" x="{end[0]:.3f}" y="{end[1]:.3f}"/>\n'
           f'    <node id="n3" x="{c_end[0]:.3f}" y="{c_end[1]:.3f}"/>\n'
           f'    <node id="n4" x="{x_end[0]:.3f}" y="{x_end[1]:.3f}"/>\n')
    edg = (_edge("a", "n0", "n1", 2)
           + _edge("b", "n1", "n2", 3).replace(">", f' shape="{_shape(arc)}">', 1)
           + _edge("c", "n2", "n3", 2) + _edge("x", "n2", "n4", 1))
    con = ('    <connection from="a" to="b" fromLane="0" toLane="1"/>\n'
           '    <connection from="a" to="b" fromLane="1" toLane="2"/>\n'
           '    <connection from="b" to="x" fromLane="0" toLane="0"/>\n'
           '    <connection from="b" to="c" fromLane="1" toLane="0"/>\n'
           '    <connection from="b" to="c" fromLane="2" toLane="1"/>\n')
    # the ramp's sharp fork would warn that its speed is cut: no speed limit by turns
    return _netconvert(name, out_dir, nod, edg, con, ("--junctions.limit-turn-speed", "-1"))
