"""Rebuild the bundled highway nets from their plain-XML sources with netconvert.

Usage::

    python -m sumo_nets.build                  # rebuild every net into sumo_nets/
    python -m sumo_nets.build --only curve_2lane
    python -m sumo_nets.build --write-sources  # regenerate src/*.xml from LAYOUTS, then build

The plain-XML sources in ``sumo_nets/src`` are the inputs of the build. They are
themselves generated from the geometric layouts in :data:`LAYOUTS` (straights and
constant-radius arcs, one edge each) by :func:`render_sources`, so that curve shapes
are exact circles sampled every <= :data:`ARC_POINT_SPACING_M` metres; the committed
sources must equal the rendered ones (checked by the tests).

netconvert options and why:

* ``--offset.disable-normalization``: keep the authored coordinates (route starts at
  (0, 0) heading +X; the S-curve and the curve reach negative/positive y). Without
  it netconvert shifts the net so that its bounding box starts at (0, 0), which would
  make positions in the net differ from those in the sources for no benefit.
* ``--no-turnarounds``: a carriageway has no opposite direction, so no U-turn can be
  built anyway; the option makes that explicit and guards against a future reverse
  edge silently getting turnaround connections.
* ``--precision 3`` (netconvert's default is 2): coordinates in mm. With cm precision,
  the lane ends on either side of a straight-through junction on a diagonal edge are
  rounded independently, which can leave a 1 cm internal lane pointing backwards (a
  spurious 150 deg heading kink for anyone concatenating lane shapes); with mm
  precision those internal lanes collapse to identical points, as on axis-aligned
  edges.
* ``--no-warnings`` is NOT used: warnings are captured and raised as errors, so a
  source change that makes netconvert unhappy fails the build.
* Edges use ``spreadType="center"``: the edge ``shape`` is the carriageway centre line
  (including the shoulder, if any) and the lanes are laid out symmetrically around it,
  so the arc radius in :data:`LAYOUTS` is the radius of the carriageway centre.

Determinism: netconvert's output is deterministic except for its leading XML comment
(generation date and the absolute input/output paths). :func:`build_net` replaces
that comment with a fixed one, so a rebuild of unchanged sources is byte-identical.

Units: metres, m/s, degrees (angles in :class:`Arc` are degrees, positive = left turn).
"""

from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from sumo_nets import (
    BUNDLED,
    LANE_WIDTH_M,
    NET_DIR,
    SHOULDER_VCLASSES,
    SHOULDER_WIDTH_M,
    SPEED_LIMIT_MPS,
    SRC_DIR,
    net_info,
    sumo_home,
)

ARC_POINT_SPACING_M = 5.0
"""Maximum spacing of the polyline points sampling an arc edge shape (m)."""

EDGE_PRIORITY = 10
"""Priority of every carriageway edge (all equal: every junction is a straight-through)."""

NETCONVERT_OPTIONS: tuple[str, ...] = (
    "--offset.disable-normalization",
    "true",
    "--no-turnarounds",
    "true",
    "--precision",
    "3",
)
"""Extra netconvert options used for every net (see the module docstring for why)."""


@dataclass(frozen=True)
class Straight:
    """A straight edge of ``length_m`` metres."""

    length_m: float


@dataclass(frozen=True)
class Arc:
    """A constant-radius arc edge: radius ``radius_m`` (m), turning ``angle_deg`` degrees
    (positive = left / counter-clockwise, negative = right)."""

    radius_m: float
    angle_deg: float

    @property
    def length_m(self) -> float:
        """Arc length along the reference line (m)."""
        return self.radius_m * math.radians(abs(self.angle_deg))


Segment = Straight | Arc

LAYOUTS: dict[str, tuple[Segment, ...]] = {
    "straight_2lane": (Straight(500.0),) * 5,
    "straight_3lane": (Straight(500.0),) * 5,
    "straight_3lane_shoulder": (Straight(500.0),) * 5,
    "curve_2lane": (
        Straight(500.0),
        Arc(400.0, 60.0),
        Arc(400.0, 60.0),
        Straight(500.0),
        Straight(300.0),
    ),
    "s_curve_3lane": (
        Straight(500.0),
        Arc(500.0, 50.0),
        Arc(500.0, -50.0),
        Straight(400.0),
        Straight(400.0),
    ),
}
"""Geometric layout of each net's reference line: one segment per edge, in route order
(edge ``e<i>`` from node ``n<i>`` to ``n<i+1>``), starting at (0, 0) heading +X."""


def layout_length_m(name: str) -> float:
    """Length of the reference line of net ``name`` (m), from :data:`LAYOUTS`."""
    return sum(seg.length_m for seg in LAYOUTS[name])


def _segment_points(
    seg: Segment, x: float, y: float, heading_rad: float
) -> tuple[list[tuple[float, float]], float]:
    """Polyline of one segment from (x, y) with heading ``heading_rad``.

    Returns (points including both ends, end heading in rad).
    """
    if isinstance(seg, Straight):
        end = (x + seg.length_m * math.cos(heading_rad), y + seg.length_m * math.sin(heading_rad))
        return [(x, y), end], heading_rad
    sign = 1.0 if seg.angle_deg > 0 else -1.0
    # centre of the circle lies to the left (left turn) or right (right turn)
    cx = x - sign * seg.radius_m * math.sin(heading_rad)
    cy = y + sign * seg.radius_m * math.cos(heading_rad)
    n = max(2, math.ceil(seg.length_m / ARC_POINT_SPACING_M))
    total = math.radians(seg.angle_deg)
    pts = []
    for k in range(n + 1):
        h = heading_rad + total * k / n
        pts.append((cx + sign * seg.radius_m * math.sin(h), cy - sign * seg.radius_m * math.cos(h)))
    return pts, heading_rad + total


def _fmt(v: float) -> str:
    s = f"{v:.3f}"
    return "0.000" if s == "-0.000" else s


def reference_polylines(name: str) -> list[list[tuple[float, float]]]:
    """Reference-line polyline (edge shape) of each edge of net ``name``, in route order (m)."""
    x = y = h = 0.0
    out = []
    for seg in LAYOUTS[name]:
        pts, h = _segment_points(seg, x, y, h)
        x, y = pts[-1]
        out.append(pts)
    return out


def render_sources(name: str) -> dict[str, str]:
    """Plain-XML sources of net ``name`` as ``{file name: text}`` (``.nod.xml``, ``.edg.xml``)."""
    info = net_info(name)
    polys = reference_polylines(name)
    if len(polys) != len(info.main_route):
        raise ValueError(f"{name}: layout has {len(polys)} edges, registry {len(info.main_route)}")
    header = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f"<!-- {name}: generated by sumo_nets.build.write_sources() from\n"
        "     sumo_nets.build.LAYOUTS; edit LAYOUTS rather than this file. Units: m, m/s. -->\n"
    )
    nodes = [polys[0][0]] + [p[-1] for p in polys]
    nod = [header, "<nodes>\n"]
    for i, (nx, ny) in enumerate(nodes):
        end = i in (0, len(nodes) - 1)
        ntype = "dead_end" if end else "priority"
        nod.append(f'    <node id="n{i}" x="{_fmt(nx)}" y="{_fmt(ny)}" type="{ntype}"/>\n')
    nod.append("</nodes>\n")

    edg = [header, "<edges>\n"]
    for i, (eid, pts) in enumerate(zip(info.main_route, polys, strict=True)):
        attrs = (
            f'id="{eid}" from="n{i}" to="n{i + 1}" priority="{EDGE_PRIORITY}" '
            f'numLanes="{info.total_lanes}" speed="{SPEED_LIMIT_MPS:.2f}" '
            f'width="{LANE_WIDTH_M:.2f}" spreadType="center"'
        )
        if len(pts) > 2:
            attrs += ' shape="' + " ".join(f"{_fmt(px)},{_fmt(py)}" for px, py in pts) + '"'
        if info.has_shoulder:
            edg.append(f"    <edge {attrs}>\n")
            edg.append(
                f'        <lane index="0" allow="{" ".join(SHOULDER_VCLASSES)}" '
                f'width="{SHOULDER_WIDTH_M:.2f}"/>\n'
            )
            edg.append("    </edge>\n")
        else:
            edg.append(f"    <edge {attrs}/>\n")
    edg.append("</edges>\n")
    return {f"{name}.nod.xml": "".join(nod), f"{name}.edg.xml": "".join(edg)}


def write_sources(name: str, src_dir: Path | None = None) -> list[Path]:
    """Write the rendered plain-XML sources of net ``name`` into ``src_dir`` (default SRC_DIR)."""
    src_dir = SRC_DIR if src_dir is None else Path(src_dir)
    src_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for fname, text in render_sources(name).items():
        p = src_dir / fname
        p.write_text(text, encoding="utf-8")
        written.append(p)
    return written


def netconvert_path() -> Path:
    """Path of the netconvert binary of the installed eclipse-sumo wheel."""
    exe = "netconvert.exe" if os.name == "nt" else "netconvert"
    p = Path(sumo_home()) / "bin" / exe
    if not p.is_file():
        raise FileNotFoundError(f"netconvert not found at {p} (is eclipse-sumo installed?)")
    return p


def _netconvert_version() -> str:
    out = subprocess.run(
        [str(netconvert_path()), "--version"], capture_output=True, text=True, check=True
    ).stdout
    m = re.search(r"netconvert\s+(?:Version\s+)?v?([0-9][^\s]*)", out)
    return m.group(1) if m else "unknown"


def source_files(name: str, src_dir: Path | None = None) -> dict[str, Path]:
    """Existing source files of net ``name``: ``{netconvert option: path}``."""
    src_dir = SRC_DIR if src_dir is None else Path(src_dir)
    files: dict[str, Path] = {}
    for opt, suffix in (
        ("--node-files", "nod"),
        ("--edge-files", "edg"),
        ("--type-files", "typ"),
        ("--connection-files", "con"),
    ):
        p = src_dir / f"{name}.{suffix}.xml"
        if p.is_file():
            files[opt] = p
    for required in ("--node-files", "--edge-files"):
        if required not in files:
            raise FileNotFoundError(f"{name}: missing source for {required} in {src_dir}")
    return files


_HEADER_RE = re.compile(r"\A(<\?xml[^>]*\?>\s*)<!--.*?-->\s*", re.DOTALL)


def _fixed_header(name: str, files: dict[str, Path], version: str) -> str:
    # XML comments may not contain "--", so options are written without their dashes.
    opts = [*(f"{opt[2:]}=src/{p.name}" for opt, p in files.items())]
    opts += [
        f"{NETCONVERT_OPTIONS[i][2:]}={NETCONVERT_OPTIONS[i + 1]}"
        for i in range(0, len(NETCONVERT_OPTIONS), 2)
    ]
    return (
        f"<!-- {name}.net.xml: built by sumo_nets.build.build_net({name!r})\n"
        f"     with Eclipse SUMO netconvert {version}, options:\n"
        f"     {' '.join(opts)}\n"
        "     Do not edit; edit the sources (sumo_nets.build.LAYOUTS) and rebuild. -->\n\n"
    )


def build_net(name: str, out_dir: Path | None = None) -> Path:
    """Build net ``name`` from its sources in SRC_DIR into ``out_dir/<name>.net.xml``.

    ``out_dir`` defaults to NET_DIR (the committed location). Raises
    ``subprocess.CalledProcessError``/``RuntimeError`` if netconvert fails or warns.
    Returns the path of the written net.
    """
    net_info(name)  # KeyError with the list of names for an unknown net
    out_dir = NET_DIR if out_dir is None else Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = source_files(name)
    out = out_dir / f"{name}.net.xml"
    with tempfile.TemporaryDirectory(prefix=f"sumo_nets_{name}_") as tmp:
        tmp_out = Path(tmp) / f"{name}.net.xml"
        cmd = [str(netconvert_path())]
        for opt, p in files.items():
            cmd += [opt, str(p)]
        cmd += [*NETCONVERT_OPTIONS, "--output-file", str(tmp_out)]
        res = subprocess.run(
            cmd, capture_output=True, text=True, env={**os.environ, "SUMO_HOME": sumo_home()}
        )
        msgs = (res.stdout + res.stderr).strip()
        if res.returncode != 0:
            raise RuntimeError(f"netconvert failed for {name} (rc={res.returncode}):\n{msgs}")
        if "Warning" in msgs or "Error" in msgs:
            raise RuntimeError(f"netconvert warned for {name}:\n{msgs}")
        text = tmp_out.read_text(encoding="utf-8")
    m = _HEADER_RE.match(text)
    if m is None:
        raise RuntimeError(f"unexpected netconvert output header for {name}")
    text = m.group(1) + _fixed_header(name, files, _netconvert_version()) + text[m.end():]
    out.write_text(text, encoding="utf-8")
    return out


def build_all(out_dir: Path | None = None) -> list[Path]:
    """Build every bundled net into ``out_dir`` (default NET_DIR); returns the written paths."""
    return [build_net(name, out_dir) for name in sorted(BUNDLED)]


def main(argv: Sequence[str] | None = None) -> int:
    """Command-line entry point; returns the process exit status."""
    ap = argparse.ArgumentParser(
        prog="python -m sumo_nets.build", description=(__doc__ or "").split("\n")[0]
    )
    ap.add_argument("--only", metavar="NAME", action="append", choices=sorted(BUNDLED),
                    help="build only this net (repeatable)")
    ap.add_argument("--out-dir", type=Path, default=None,
                    help="write the .net.xml files here instead of sumo_nets/")
    ap.add_argument("--write-sources", action="store_true",
                    help="regenerate src/*.nod.xml and *.edg.xml from LAYOUTS before building")
    args = ap.parse_args(argv)
    names = args.only or sorted(BUNDLED)
    for name in names:
        if args.write_sources:
            for p in write_sources(name):
                print(f"wrote {p}")
        out = build_net(name, args.out_dir)
        print(f"built {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
