"""Read-only view of a SUMO road network (``.net.xml``) for the suite (sumolib only).

Works for any valid SUMO network; nothing here assumes the bundled nets. Coordinates
are SUMO network coordinates in metres (no ``netOffset`` is applied or removed).

Conventions
-----------
* A *route* is a sequence of non-internal edge ids, each consecutive pair joined by
  at least one lane connection.
* Lane indices run from 0 = rightmost, as in SUMO.
* **Route length / positions.** A route position ``pos_m`` is measured from the start
  of the first edge. Every edge contributes its length (SUMO lanes of one edge share
  one length); every junction between two consecutive route edges contributes the
  *mean* length of the internal ("via") lanes over all lane connections between the
  two edges (a chain of via lanes counts as its sum; connections without a via lane,
  e.g. in nets built with ``--no-internal-links``, count as 0 m). :meth:`locate`
  maps a position that falls inside a junction to the start (0 m) of the next edge.
* **Hard shoulder.** A lane is a shoulder when it does not allow the vClass
  ``passenger`` but allows ``emergency`` or ``authority``.
* **Default route.** The longest path (by route length, junctions included) through
  the graph of non-internal edges that allow ``passenger`` on at least one lane and are
  not *link* edges (an OpenStreetMap type ending in ``_link``: ramps, exits, slip
  roads), following lane connections and ignoring turnarounds (``dir="t"``): the through
  carriageway. Link edges are used only where no edge is left without them. The graph
  is assumed to be a DAG; cycles are broken by dropping DFS back edges (edges visited
  in sorted id order, so the result is deterministic). Ties go to the lexicographically
  smallest id sequence. :meth:`link_edges` names the link edges of a route (the catalog
  warns about a route that uses them).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import sumolib

from reports.geometry import arc_lengths_m

__all__ = [
    "LaneInfo",
    "LaneLink",
    "RoadNetwork",
    "RoadNetworkError",
    "centreline_arclength",
    "dedupe_polyline",
    "is_shoulder_permissions",
]

_DUP_TOL_M = 1e-6


class RoadNetworkError(ValueError):
    """A network file cannot be read or is not usable (the message names the file)."""


def is_shoulder_permissions(allowed: Iterable[str]) -> bool:
    """The shoulder rule: no ``passenger``, but ``emergency`` or ``authority``."""
    allowed = set(allowed)
    return "passenger" not in allowed and bool({"emergency", "authority"} & allowed)


def dedupe_polyline(points: np.ndarray, tol_m: float = _DUP_TOL_M) -> np.ndarray:
    """Drop consecutive points closer than ``tol_m`` to their predecessor."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if pts.shape[0] < 2:
        return pts.copy()
    keep = [0]
    for i in range(1, pts.shape[0]):
        if float(np.hypot(*(pts[i] - pts[keep[-1]]))) > tol_m:
            keep.append(i)
    return pts[keep]


# Cumulative arc length (M,) of a polyline (M, 2), starting at 0 (reports.geometry's).
centreline_arclength = arc_lengths_m


def _acyclic_post_order(succ: dict[str, list[str]]
                        ) -> tuple[list[str], dict[str, list[str]]]:
    """(post-order of the nodes, successor graph without back edges) of the graph
    ``succ``: an iterative DFS from each node in sorted order that drops every edge
    closing a cycle."""
    state: dict[str, int] = {}  # 1: on the stack, 2: finished
    order: list[str] = []
    dag: dict[str, list[str]] = {eid: [] for eid in succ}
    for root in sorted(succ):
        if root in state:
            continue
        stack: list[tuple[str, int]] = [(root, 0)]
        state[root] = 1
        while stack:
            node, i = stack[-1]
            if i < len(succ[node]):
                stack[-1] = (node, i + 1)
                nxt = succ[node][i]
                if state.get(nxt) == 1:
                    continue  # back edge: would close a cycle
                dag[node].append(nxt)
                if nxt not in state:
                    state[nxt] = 1
                    stack.append((nxt, 0))
            else:
                state[node] = 2
                order.append(node)
                stack.pop()
    return order, dag


@dataclass(frozen=True)
class LaneInfo:
    """One lane of a route edge. ``shape_xy_m`` is the SUMO lane shape (M, 2)."""

    id: str
    edge_id: str
    index: int
    width_m: float
    shape_xy_m: np.ndarray = field(compare=False)
    allowed: tuple[str, ...]
    is_shoulder: bool
    allows_passenger: bool
    speed_mps: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "edge_id": self.edge_id,
            "index": self.index,
            "width_m": self.width_m,
            "shape_xy_m": np.asarray(self.shape_xy_m, dtype=float).tolist(),
            "allowed": list(self.allowed),
            "is_shoulder": self.is_shoulder,
            "allows_passenger": self.allows_passenger,
            "speed_mps": self.speed_mps,
        }


@dataclass(frozen=True)
class LaneLink:
    """A lane connection: lane ``from_index`` of an edge to lane ``to_index`` of
    ``to_edge_id`` through the internal lanes ``via_ids`` (their shapes (M, 2) and widths
    [m]); ``direction`` is SUMO's ('s' straight, 't' turnaround, ...)."""

    from_index: int
    to_edge_id: str
    to_index: int
    via_ids: tuple[str, ...]
    via_shapes: tuple[np.ndarray, ...] = field(compare=False)
    via_widths_m: tuple[float, ...] = ()
    direction: str = ""


class RoadNetwork:
    """A loaded network. Use :meth:`load` (cached per resolved path and file mtime)."""

    _cache: dict[tuple[str, int, int], RoadNetwork] = {}
    _cache_lock = threading.Lock()

    def __init__(self, path: Path, net: Any) -> None:
        self.path = path
        self._net = net
        self._edges: dict[str, Any] = {
            e.getID(): e for e in net.getEdges(withInternal=True) if e.getFunction() == ""
        }
        if not self._edges:
            raise RoadNetworkError(f"{path}: the network has no (non-internal) edges")
        self._default_route: tuple[str, ...] | None = None
        self._offsets_cache: dict[tuple[str, ...], list[tuple[str, float, float, float]]] = {}

    # ------------------------------------------------------------------ loading
    @classmethod
    def load(cls, path: str | Path) -> RoadNetwork:
        """Read ``path`` (``.net.xml`` or ``.net.xml.gz``); cached by resolved path."""
        resolved = Path(path).expanduser().resolve()
        try:
            st = resolved.stat()
        except OSError as exc:
            raise RoadNetworkError(f"{resolved}: cannot read SUMO network: {exc}") from exc
        if not resolved.is_file():
            raise RoadNetworkError(f"{resolved}: cannot read SUMO network: not a file")
        key = (str(resolved), st.st_mtime_ns, st.st_size)
        with cls._cache_lock:
            cached = cls._cache.get(key)
        if cached is not None:
            return cached
        try:
            net = sumolib.net.readNet(str(resolved), withInternal=True)
        except Exception as exc:  # sumolib raises whatever its XML parser raises
            raise RoadNetworkError(
                f"{resolved}: cannot read SUMO network: {type(exc).__name__}: {exc}") from exc
        network = cls(resolved, net)
        with cls._cache_lock:
            for old in [k for k in cls._cache if k[0] == key[0]]:
                del cls._cache[old]
            cls._cache[key] = network
        return network

    @classmethod
    def clear_cache(cls) -> None:
        with cls._cache_lock:
            cls._cache.clear()

    # ------------------------------------------------------------------ edges
    def edge_ids(self) -> list[str]:
        """Ids of all non-internal edges, sorted."""
        return sorted(self._edges)

    def has_edge(self, edge_id: str) -> bool:
        return edge_id in self._edges

    def _edge(self, edge_id: str) -> Any:
        try:
            return self._edges[edge_id]
        except KeyError:
            raise KeyError(f"{self.path.name}: unknown edge {edge_id!r}") from None

    def lane_count(self, edge_id: str) -> int:
        return int(self._edge(edge_id).getLaneNumber())

    def edge_length_m(self, edge_id: str) -> float:
        return float(self._edge(edge_id).getLength())

    def lane_width_m(self, edge_id: str, index: int) -> float:
        edge = self._edge(edge_id)
        if not 0 <= index < edge.getLaneNumber():
            raise IndexError(f"edge {edge_id!r} has no lane {index}")
        return float(edge.getLane(index).getWidth())

    def _lane(self, lane_id: str) -> Any:
        return self._net.getLane(lane_id)

    # ------------------------------------------------------------------ connections
    def _connections(self, from_id: str, to_id: str) -> list[Any]:
        edge = self._edge(from_id)
        to_edge = self._edges.get(to_id)
        if to_edge is None:
            return []
        return list(edge.getOutgoing().get(to_edge, []))

    def _via_chain(self, conn: Any) -> list[Any]:
        """Internal lanes of a connection, in driving order (may be empty)."""
        lanes: list[Any] = []
        via = conn.getViaLaneID()
        target = conn.getTo()
        seen: set[str] = set()
        while via and via not in seen and len(lanes) < 16:
            seen.add(via)
            try:
                lane = self._lane(via)
            except (KeyError, ValueError, IndexError):
                break
            lanes.append(lane)
            via = ""
            for nxt in lane.getOutgoing():
                if nxt.getTo() is target and nxt.getToLane() is conn.getToLane():
                    via = nxt.getViaLaneID() or ""
                    break
        return lanes

    def _junction_length_m(self, from_id: str, to_id: str) -> float:
        conns = self._connections(from_id, to_id)
        if not conns:
            return 0.0
        lengths = [sum(float(v.getLength()) for v in self._via_chain(c)) for c in conns]
        return float(np.mean(lengths))

    def _successors(self, edge_id: str) -> list[str]:
        out = []
        for to_edge, conns in self._edge(edge_id).getOutgoing().items():
            if to_edge.getFunction() != "" or to_edge.getID() not in self._edges:
                continue
            if all(c.getDirection() == "t" for c in conns):
                continue
            out.append(to_edge.getID())
        return sorted(set(out))

    def lane_links(self, edge_id: str) -> list[LaneLink]:
        """Every lane connection leaving ``edge_id``: from which lane, to which edge and
        lane, through which internal junction lanes (shapes in driving order)."""
        out = []
        for lane in self._edge(edge_id).getLanes():
            for conn in lane.getOutgoing():
                to_lane = conn.getToLane()
                via = self._via_chain(conn)
                out.append(LaneLink(
                    from_index=int(lane.getIndex()), to_edge_id=str(conn.getTo().getID()),
                    to_index=int(to_lane.getIndex()),
                    via_ids=tuple(str(v.getID()) for v in via),
                    via_shapes=tuple(np.asarray(v.getShape(), dtype=np.float64).reshape(-1, 2)
                                     for v in via),
                    via_widths_m=tuple(float(v.getWidth()) for v in via),
                    direction=str(conn.getDirection())))
        return out

    # ------------------------------------------------------------------ routes
    def default_route(self) -> tuple[str, ...]:
        """Longest path of non-internal edges (see module docstring)."""
        if self._default_route is None:
            self._default_route = self._longest_path()
        return self._default_route

    def is_link(self, edge_id: str) -> bool:
        """Whether the edge is a link (ramp, exit, slip road): its type ends in ``_link``
        (``highway.motorway_link``, ``highway.trunk_link``, ...)."""
        edge_type = str(self._edge(edge_id).getType() or "")
        return edge_type.endswith("_link")

    def link_edges(self, route: Sequence[str]) -> list[str]:
        """The link edges of ``route``, in route order (:meth:`is_link`)."""
        return [eid for eid in route if eid in self._edges and self.is_link(eid)]

    def _longest_path(self) -> tuple[str, ...]:
        """The default route: the longest acyclic path over :meth:`_route_edges`."""
        usable = self._route_edges()
        succ = {eid: [s for s in self._successors(eid) if s in usable] for eid in sorted(usable)}
        order, dag = _acyclic_post_order(succ)
        return self._longest_over(order, dag)

    def _route_edges(self) -> set[str]:
        """The edges a default route may use: passenger edges (every edge when none
        allows passengers), and of those the through carriageway (no links) unless
        only links are left."""
        usable = {eid for eid, e in self._edges.items()
                  if any(lane.allows("passenger") for lane in e.getLanes())}
        if not usable:
            usable = set(self._edges)
        through = {eid for eid in usable if not self.is_link(eid)}
        if through:  # the through carriageway: ramps only where nothing else is left
            usable = through
        return usable

    def _longest_over(self, order: list[str], dag: dict[str, list[str]]) -> tuple[str, ...]:
        """The longest path (m, junctions included) through ``dag``, ``order`` being its
        post-order; ties (within 1e-6 m) go to the lexicographically smallest path."""
        best: dict[str, tuple[float, tuple[str, ...]]] = {}
        for node in order:  # post-order: successors first
            length = self.edge_length_m(node)
            cand: tuple[float, tuple[str, ...]] = (length, (node,))
            for nxt in dag[node]:
                sub_len, sub_path = best[nxt]
                total = length + self._junction_length_m(node, nxt) + sub_len
                path = (node, *sub_path)
                if total > cand[0] + 1e-9 or (abs(total - cand[0]) <= 1e-9 and path < cand[1]):
                    cand = (total, path)
            best[node] = cand
        top = max(lp[0] for lp in best.values())
        return min(lp[1] for lp in best.values() if lp[0] >= top - 1e-6)

    def validate_route(self, route: Sequence[str]) -> None:
        """Raise ValueError unless every edge exists and consecutive edges connect."""
        if isinstance(route, str) or len(route) == 0:
            raise ValueError("a route must be a non-empty sequence of edge ids")
        for i, eid in enumerate(route):
            if eid not in self._edges:
                raise ValueError(f"route[{i}]: unknown edge {eid!r} in {self.path.name}")
        for i, (a, b) in enumerate(zip(route, route[1:], strict=False)):
            if not self._connections(a, b):
                raise ValueError(
                    f"route[{i + 1}]: edge {b!r} is not connected from {a!r} in {self.path.name}"
                    f" (successors of {a!r}: {self._successors(a)})")

    def _offsets(self, route: Sequence[str]) -> list[tuple[str, float, float, float]]:
        """(edge, start, edge length, junction length after it) per route edge (cached)."""
        key = tuple(route) if not isinstance(route, str) else (route,)
        cached = self._offsets_cache.get(key)
        if cached is not None:
            return cached
        self.validate_route(route)
        out = []
        s = 0.0
        for i, eid in enumerate(route):
            length = self.edge_length_m(eid)
            junction = self._junction_length_m(eid, route[i + 1]) if i + 1 < len(route) else 0.0
            out.append((eid, s, length, junction))
            s += length + junction
        if len(self._offsets_cache) < 256:
            self._offsets_cache[key] = out
        return out

    def route_length_m(self, route: Sequence[str]) -> float:
        """Length of the route including junctions (see module docstring)."""
        eid, start, length, junction = self._offsets(route)[-1]
        return start + length + junction

    def route_edge_starts_m(self, route: Sequence[str]) -> dict[str, float]:
        """Route position of the start of each route edge."""
        return {eid: start for eid, start, _, _ in self._offsets(route)}

    def locate(self, route: Sequence[str], pos_m: float) -> tuple[str, float]:
        """(edge id, position on that edge) of route position ``pos_m`` in [0, length).

        A position inside a junction maps to the start of the next edge.
        """
        offsets = self._offsets(route)
        total = offsets[-1][1] + offsets[-1][2]
        if not (math.isfinite(pos_m) and 0.0 <= pos_m < total):
            raise ValueError(f"position {pos_m!r} m is outside the route [0, {total:.2f}) m")
        for k, (eid, start, length, _) in enumerate(offsets):
            if pos_m < start + length:
                return eid, float(pos_m - start)
            if k + 1 < len(offsets) and pos_m < offsets[k + 1][1]:
                return offsets[k + 1][0], 0.0
        eid, start, length, _ = offsets[-1]  # pragma: no cover - guarded above
        return eid, float(min(pos_m - start, length))

    def lanes_at(self, route: Sequence[str], pos_m: float) -> int:
        """Number of lanes of the edge at route position ``pos_m``."""
        return self.lane_count(self.locate(route, pos_m)[0])

    # ------------------------------------------------------------------ lanes
    def lane_info(self, route: Sequence[str]) -> list[LaneInfo]:
        """Every lane of every route edge, in route order then lane index."""
        self.validate_route(route)
        out: list[LaneInfo] = []
        for eid in route:
            for lane in self._edge(eid).getLanes():
                allowed = tuple(sorted(lane.getPermissions()))
                out.append(LaneInfo(
                    id=lane.getID(),
                    edge_id=eid,
                    index=int(lane.getIndex()),
                    width_m=float(lane.getWidth()),
                    shape_xy_m=np.asarray(lane.getShape(), dtype=np.float64).reshape(-1, 2),
                    allowed=allowed,
                    is_shoulder=is_shoulder_permissions(allowed),
                    allows_passenger="passenger" in allowed,
                    speed_mps=float(lane.getSpeed()),
                ))
        return out

    def lane_centreline(self, route: Sequence[str], lane_index: int) -> np.ndarray:
        """Centreline (M, 2) of lane ``lane_index`` followed along the whole route.

        Starts on lane ``min(lane_index, n - 1)`` of the first edge and follows SUMO's
        lane connections, including the internal (via) lanes through junctions, so the
        polyline has no gap. At each junction, among the connections from the current
        lane to the next route edge, the one whose target lane index is closest to
        ``lane_index`` is taken (lane drop: the nearest lane that exists). If the
        current lane has no connection to the next edge (the lane ends), the polyline
        continues straight onto the lane of the next edge whose start is nearest to
        the current lane's end. Consecutive duplicate points are removed.
        """
        if isinstance(lane_index, bool) or int(lane_index) != lane_index or lane_index < 0:
            raise ValueError(f"lane_index must be an integer >= 0, got {lane_index!r}")
        self.validate_route(route)
        first = self._edge(route[0])
        lane = first.getLane(min(int(lane_index), first.getLaneNumber() - 1))
        points: list[tuple[float, float]] = list(map(tuple, lane.getShape()))
        for nxt_id in route[1:]:
            nxt_edge = self._edge(nxt_id)
            want = min(int(lane_index), nxt_edge.getLaneNumber() - 1)
            conns = [c for c in lane.getOutgoing() if c.getTo() is nxt_edge]
            if conns:
                conn = min(conns, key=lambda c: (abs(c.getToLane().getIndex() - want),
                                                 c.getToLane().getIndex()))
                for via in self._via_chain(conn):
                    points.extend(map(tuple, via.getShape()))
                lane = conn.getToLane()
            else:
                end = np.asarray(lane.getShape()[-1])
                lane = min(nxt_edge.getLanes(), key=lambda ln: (
                    float(np.hypot(*(np.asarray(ln.getShape()[0]) - end))), ln.getIndex()))
            points.extend(map(tuple, lane.getShape()))
        return dedupe_polyline(np.asarray(points, dtype=np.float64))

    def __repr__(self) -> str:
        return f"RoadNetwork({str(self.path)!r}, edges={len(self._edges)})"
