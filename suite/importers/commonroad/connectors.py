"""Connectors: lanelets that join lanes without being one (wedges, short skewed links),
bridged into junction links.

Where a lane opens or ends at an exit or an entry, some recordings (exiD) draw the gap
between the lanes' ends as a lanelet of its own: lanelet 9 splits into its through lane
13 and a 3.4 m wedge 50 skewed 38 deg across the road, which leads into the lane 22
opening beside 13. Imported as a lane, the wedge lies beside its neighbours along a metre
or so, gets cut and leaves a lanelet with two neighbours on one side (*inconsistent
adjacency*); it is not a lane anyone drives along, it is where they cross into one.

**Which.** A lanelet of the ego's road is a connector when

* it has a predecessor and a successor on the road (it connects something),
* its centre line is at most :data:`CONNECTOR_MAX_LENGTH_M` long, and
* its chord (start to end of the centre line) is skewed by more than
  :data:`CONNECTOR_MIN_SKEW_RAD` against *every* lanelet it connects: the direction of
  each predecessor's last and each successor's first 5 m
  (:func:`~suite.importers.commonroad.geometry.end_heading_rad`).

A lane's short piece continues its neighbours' direction (a 10 m piece of a 25 m-radius
loop ramp turns 23 deg, its chord 11.5 deg off either end); a wedge crosses them.

**Bridged.** Each connector becomes lane connections: every predecessor gets the
connector's successors as its own (through chains of connectors), every successor its
predecessors, and the connector leaves the road (no lane, no edge: netconvert's junction
joins the lanes, so the vehicles that drove across it still can). A neighbour reference
(``adjacentLeft``/``adjacentRight``) to a connector goes to the one of its successors or
predecessors that lies beside the referring lanelet on that side, else is dropped. A
lanelet reached only through connectors is taken to start where the (first) connector
starts, one leaving only through connectors to end where it ends
(``LaneletRecord.start_anchor_xy_m`` / ``end_anchor_xy_m``): the lanes opening or ending
there stay in the row of the lanes beside them instead of cutting those a wedge's length
apart, and the rows meet at one junction.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace

from suite.importers.commonroad.geometry import angle_diff_rad, end_heading_rad, polyline_length_m
from suite.importers.commonroad.records import LaneletRecord
from suite.importers.commonroad.split import lies_beside, overlap_m

__all__ = ["CONNECTOR_MAX_LENGTH_M", "CONNECTOR_MIN_SKEW_RAD", "Bridged", "bridge_connectors",
           "is_connector"]

CONNECTOR_MAX_LENGTH_M = 15.0
"""A lanelet longer than this [m] is a lane whatever its direction."""

CONNECTOR_MIN_SKEW_RAD = math.radians(20.0)
"""A short lanelet whose chord is skewed more than this [rad] against every lanelet it
connects is a connector."""


@dataclass(frozen=True)
class Bridged:
    """The road without its connectors (relations rewired, anchors set) and the
    connectors, each as (id, predecessor ids, successor ids) of the file."""

    lanelets: dict[int, LaneletRecord]
    connectors: tuple[tuple[int, tuple[int, ...], tuple[int, ...]], ...]

    @property
    def note(self) -> str | None:
        """What became of the connectors (``None``: there were none)."""
        if not self.connectors:
            return None
        shown = ", ".join(f"{c} ({'/'.join(map(str, p))} -> {'/'.join(map(str, s))})"
                          for c, p, s in self.connectors[:10])
        more = " ..." if len(self.connectors) > 10 else ""
        return (f"{len(self.connectors)} lanelets are connectors, not lanes (at most "
                f"{CONNECTOR_MAX_LENGTH_M:g} m long, skewed more than "
                f"{math.degrees(CONNECTOR_MIN_SKEW_RAD):g} deg against every lanelet they "
                f"connect): junction links from their predecessors to their successors: "
                f"{shown}{more}")


def is_connector(ll: LaneletRecord, road: dict[int, LaneletRecord]) -> bool:
    """Whether ``ll`` is a connector of ``road`` (module docstring)."""
    preds = [road[p] for p in ll.predecessors if p in road and p != ll.lanelet_id]
    succs = [road[s] for s in ll.successors if s in road and s != ll.lanelet_id]
    if not preds or not succs:
        return False
    centre = ll.centre_xy_m
    if polyline_length_m(centre) > CONNECTOR_MAX_LENGTH_M:
        return False
    chord = math.atan2(float(centre[-1, 1] - centre[0, 1]), float(centre[-1, 0] - centre[0, 0]))
    directions = [end_heading_rad(p.centre_xy_m, at_end=True) for p in preds]
    directions += [end_heading_rad(s.centre_xy_m, at_end=False) for s in succs]
    return min(angle_diff_rad(chord, d) for d in directions) > CONNECTOR_MIN_SKEW_RAD


def _through(start: Iterable[int], road: dict[int, LaneletRecord], connectors: set[int],
             forward: bool) -> tuple[int, ...]:
    """The non-connector lanelets reached from ``start`` through connectors (successors
    if ``forward``, else predecessors), in order, each once."""
    out: list[int] = []
    seen: set[int] = set()
    todo = list(start)
    while todo:
        lid = todo.pop(0)
        if lid in seen or lid not in road:
            continue
        seen.add(lid)
        if lid in connectors:
            ll = road[lid]
            todo.extend(ll.successors if forward else ll.predecessors)
        else:
            out.append(lid)
    return tuple(out)


def _neighbour(ll: LaneletRecord, ref: int | None, on_left: bool,
               road: dict[int, LaneletRecord], connectors: set[int]) -> int | None:
    """``ref``, or for a connector the lanelet it leads to or comes from that lies beside
    ``ll`` on that side (the longest overlap), else ``None``."""
    if ref is None or ref not in connectors:
        return ref
    c = road[ref]
    cands = [road[x] for x in (*_through(c.successors, road, connectors, True),
                               *_through(c.predecessors, road, connectors, False))
             if x != ll.lanelet_id]
    beside = [x for x in cands if (lies_beside(ll, x) if on_left else lies_beside(x, ll))]
    if not beside:
        return None

    def overlap(x: LaneletRecord) -> float:
        a, b = overlap_m(ll, x) if on_left else overlap_m(x, ll)
        return b - a

    return max(beside, key=overlap).lanelet_id


def _anchor(ids: tuple[int, ...], road: dict[int, LaneletRecord], connectors: set[int],
            at_start: bool) -> tuple[float, float] | None:
    """The point a lanelet whose predecessors (``at_start``) or successors ``ids`` are
    all connectors is anchored at: the start (end) of the first chain of connectors
    there; ``None`` otherwise."""
    on_road = [i for i in ids if i in road]
    if not on_road or any(i not in connectors for i in on_road):
        return None
    lid, seen = on_road[0], {on_road[0]}
    while True:  # to the far end of a chain of connectors
        nxt = [i for i in (road[lid].predecessors if at_start else road[lid].successors)
               if i in connectors and i not in seen]
        if not nxt:
            break
        lid = nxt[0]
        seen.add(lid)
    c = road[lid].centre_xy_m
    p = c[0] if at_start else c[-1]
    return float(p[0]), float(p[1])


def bridge_connectors(road: dict[int, LaneletRecord]) -> Bridged:
    """Find the connectors of ``road`` and bridge them (module docstring)."""
    connectors = {lid for lid, ll in road.items() if is_connector(ll, road)}
    if not connectors:
        return Bridged(dict(road), ())
    out: dict[int, LaneletRecord] = {}
    for lid, ll in road.items():
        if lid in connectors:
            continue
        out[lid] = replace(
            ll,
            successors=_through(ll.successors, road, connectors, True),
            predecessors=_through(ll.predecessors, road, connectors, False),
            adj_left=_neighbour(ll, ll.adj_left, True, road, connectors),
            adj_right=_neighbour(ll, ll.adj_right, False, road, connectors),
            start_anchor_xy_m=_anchor(ll.predecessors, road, connectors, at_start=True)
            or ll.start_anchor_xy_m,
            end_anchor_xy_m=_anchor(ll.successors, road, connectors, at_start=False)
            or ll.end_anchor_xy_m)
    listed = tuple((c, _through(road[c].predecessors, road, connectors, False),
                    _through(road[c].successors, road, connectors, True))
                   for c in sorted(connectors))
    return Bridged(out, listed)
