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
path of the written ``<name>.net.xml`` in ``out_dir``; netconvert warnings are errors.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from sumo_nets import LANE_WIDTH_M, sumo_home
from sumo_nets.build import NETCONVERT_OPTIONS, netconvert_path

SPEED_MPS = 33.33


def _netconvert(name: str, out_dir: Path, nod: str, edg: str, con: str) -> Path:
    out_dir.mkdir(parents=True, exist_ok=True)
    src = {"nod": out_dir / f"{name}.nod.xml", "edg": out_dir / f"{name}.edg.xml",
           "con": out_dir / f"{name}.con.xml"}
    src["nod"].write_text(f"<nodes>\n{nod}</nodes>\n")
    src["edg"].write_text(f"<edges>\n{edg}</edges>\n")
    src["con"].write_text(f"<connections>\n{con}</connections>\n")
    out = out_dir / f"{name}.net.xml"
    cmd = [str(netconvert_path()), "--node-files", str(src["nod"]), "--edge-files",
           str(src["edg"]), "--connection-files", str(src["con"]), *NETCONVERT_OPTIONS,
           "--output-file", str(out)]
    res = subprocess.run(cmd, capture_output=True, text=True, check=False,
                         env={**os.environ, "SUMO_HOME": sumo_home()})
    msgs = (res.stdout + res.stderr).strip()
    if res.returncode != 0 or "Warning" in msgs or "Error" in msgs:
        raise RuntimeError(f"netconvert failed or warned for {name}:\n{msgs}")
    return out


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
