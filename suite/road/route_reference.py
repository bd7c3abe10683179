"""The reference path of a run: which lane it follows, its geometry, and how route
positions map onto it.

1. :class:`~suite.road.lane_graph.RouteLaneGraph` picks the lane chain
   (``reference_chain``): the through lane the ego starts in, followed across index
   shifts, never into an exit or a lane that ends.
2. The chain's polyline: each lane's shape, joined across every junction by a straight
   bridge from the end of one lane to the start of the next (the internal lane's own
   shape carries netconvert's S-jog, which is not the road).
3. Its geometry: the minimum-curvature curve within ``lane_tube_m`` of the lane shapes
   and ``junction_tube_m`` of the bridges (:mod:`suite.road.reference`), cropped to the
   stretch the run can use.
4. Route positions (what catalogs give: edge lengths plus mean junction lengths) map
   to arc length on the curve by *projection*: every vertex of every chain lane has a
   route position (SUMO's own lane position: the edge's start plus the vertex's share
   of the lane shape's length times the edge length) and an arc length on the curve (the
   vertex projected onto it); between vertices the map is linear.

Why projection and not a length ratio: the curve is smoothed, so its arc length is not
the polyline's, and near the polyline's ends a smoothing window reaches past them. The
polyline is therefore extended straight by :data:`END_EXTENSION_M` at both ends before
smoothing and the curve cropped after, at the projections of the chain's first and last
vertex: the curve starts where the lane starts, and a route position lands on the curve
beside the point of the lane polyline SUMO puts it at (tests/test_placement*.py check
the front bumper at t = 0 against the lane polyline itself).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from reports.geometry import arc_lengths_m
from suite.road.interp import interp_scalar
from suite.road.lane_graph import ChainStep, RouteLaneGraph
from suite.road.network import RoadNetwork
from suite.road.reference import Resampled, TubeParams, resample, smooth_within_support

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

END_EXTENSION_M = 60.0
"""The straight extension [m] of the chain polyline at both ends before smoothing: more
than the base smoothing's reach (a Gaussian of ``TubeParams.base_smoothing_m``, 15 m,
counted to 3 sigma), so the cropped curve's ends are smoothed like its interior."""


@dataclass(frozen=True)
class RouteReference:
    """The reference of a run.

    points_xy_m: (n, 2) the smooth curve, about ``spacing_m`` apart;
    polyline_xy_m: (m, 2) the lane chain's polyline (lanes and junction bridges) and
    polyline_junction: (m,) its vertices inside junctions;
    chain: the lanes followed; lane_index_by_edge: route edge -> the chain's lane index
    on it; route_pos_m / path_s_m: matching breakpoints (route position, arc length on
    ``points_xy_m``) at every chain edge's start and end.
    """

    points_xy_m: FloatArray
    polyline_xy_m: FloatArray
    polyline_junction: npt.NDArray[np.bool_]
    offsets_m: FloatArray
    chain: tuple[ChainStep, ...]
    lane_index_by_edge: dict[str, int]
    route_pos_m: FloatArray
    path_s_m: FloatArray
    # route_pos runs every control step: its breakpoints as lists for interp_scalar
    _path_s_list: list[float] = field(init=False, repr=False, compare=False)
    _route_pos_list: list[float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_path_s_list", self.path_s_m.tolist())
        object.__setattr__(self, "_route_pos_list", self.route_pos_m.tolist())

    def path_s(self, route_pos_m: float) -> float:
        """Arc length on the reference at a route position [m] (linear beyond the ends)."""
        return float(np.interp(route_pos_m, self.route_pos_m, self.path_s_m,
                               left=self.path_s_m[0] + route_pos_m - self.route_pos_m[0],
                               right=self.path_s_m[-1] + route_pos_m - self.route_pos_m[-1]))

    def route_pos(self, path_s_m: float) -> float:
        """Route position at an arc length on the reference [m] (linear beyond the ends;
        numpy.interp's numbers, by :func:`~suite.road.interp.interp_scalar`)."""
        ss, rs = self._path_s_list, self._route_pos_list
        x = float(path_s_m)
        return interp_scalar(x, ss, rs, rs[0] + x - ss[0], rs[-1] + x - ss[-1])

    @property
    def max_offset_m(self) -> float:
        """Largest distance of the smooth curve from the polyline's lanes [m]."""
        return float(np.max(np.abs(self.offsets_m))) if self.offsets_m.size else 0.0


def _chain_polyline(chain: list[ChainStep]) -> tuple[FloatArray, npt.NDArray[np.bool_],
                                                     list[tuple[int, int]]]:
    """(polyline (m, 2), junction flag per vertex, (first, last) vertex of each lane)."""
    pts: list[FloatArray] = []
    flags: list[npt.NDArray[np.bool_]] = []
    spans: list[tuple[int, int]] = []
    count = 0
    for step in chain:
        shape = np.asarray(step.lane.shape_xy_m, dtype=np.float64).reshape(-1, 2)
        spans.append((count, count + len(shape) - 1))
        pts.append(shape)
        flags.append(np.zeros(len(shape), dtype=bool))
        count += len(shape)
    poly = np.vstack(pts)
    junction = np.concatenate(flags)
    del flags
    # Both ends of every bridge (the last vertex of a lane, the first of the next) are
    # junction vertices: the bridge segment between them gets the junction tube.
    for (_, last), (first, _) in zip(spans, spans[1:], strict=False):
        junction[last] = junction[first] = True
    return poly, junction, spans


def _jog_m(poly: FloatArray, last: int, first: int) -> float:
    """Lateral offset [m] of the next lane's first vertex from the line of the lane that
    ends at ``last`` (its last segment, extended)."""
    a, b = poly[last - 1], poly[last]
    t = (b - a) / max(float(np.hypot(*(b - a))), 1e-12)
    d = poly[first] - b
    return float(t[0] * d[1] - t[1] * d[0])


def _tube_half_widths(poly: FloatArray, cum: FloatArray, spans: list[tuple[int, int]],
                      res: Resampled, tube: TubeParams) -> tuple[FloatArray, BoolArray]:
    """Per resampled point: the tube's half-width [m] and whether it lies in a jog zone."""
    half = np.where(res.junction, tube.junction_tube_m, tube.lane_tube_m)
    zone = np.zeros(len(res.s_m), dtype=bool)
    for (_, last), (first, _) in zip(spans, spans[1:], strict=False):
        if last < 1:
            continue
        jog = abs(_jog_m(poly, last, first))
        if jog < tube.jog_min_m:
            continue
        reach = math.sqrt(tube.jog_radius_m * jog)
        inside = (res.s_m >= cum[last] - reach) & (res.s_m <= cum[first] + reach)
        half[inside] = np.maximum(half[inside], jog + tube.lane_tube_m)
        zone |= inside
    return half, zone


def build_reference(network: RoadNetwork, route: tuple[str, ...], ego_pos_m: float,
                    ego_lane: int, tube: TubeParams | None = None,
                    window_m: tuple[float, float] | None = None) -> RouteReference:
    """The reference for an ego in lane ``ego_lane`` at route position ``ego_pos_m``.

    ``window_m`` = (from, to) route positions: only that stretch of the chain is smoothed
    (a run never uses more; the smoothing is the costly part).
    """
    tube = tube or TubeParams()
    graph = RouteLaneGraph(network, route)
    edge, _ = network.locate(route, ego_pos_m)
    k = route.index(edge)
    chain = graph.reference_chain(k, ego_lane)
    starts = network.route_edge_starts_m(route)
    if window_m is not None:
        lo, hi = window_m
        chain = [st for st in chain
                 if starts[route[st.k]] + network.edge_length_m(route[st.k]) >= lo
                 and starts[route[st.k]] <= hi] or chain
    poly, junction, spans = _chain_polyline(chain)
    ext_poly, ext_junction, ext_spans = _extended(poly, junction, spans, END_EXTENSION_M)
    res = resample(ext_poly, tube.spacing_m, ext_junction)
    cum = arc_lengths_m(ext_poly)
    half, jog_zone = _tube_half_widths(ext_poly, cum, ext_spans, res, tube)
    room = _room(network, route, chain, ext_spans, cum, res)
    full_curve, offsets, used_half = smooth_within_support(res, tube, half, room)
    full_s = arc_lengths_m(full_curve)
    # Every chain vertex projected onto the curve, searched near its own place on it.
    vertex_s = project_along(full_curve, full_s, ext_poly[1:-1], cum[1:-1])
    s0, s1 = float(vertex_s[0]), float(vertex_s[-1])
    curve = crop_curve(full_curve, full_s, s0, s1)
    route_pos, path_s = _breakpoints(network, route, chain, spans, cum[1:-1] - cum[1],
                                     vertex_s - s0)
    keep = (res.s_m >= cum[1]) & (res.s_m <= cum[-2])  # not the extensions
    # Offsets from the lanes where the plain lane tube holds (not junctions, jog zones or
    # spots widened for a digitising kink).
    on_lanes = ~(res.junction | jog_zone) & keep & (used_half <= tube.lane_tube_m + 1e-12)
    return RouteReference(
        points_xy_m=curve, polyline_xy_m=poly, polyline_junction=junction,
        offsets_m=offsets[on_lanes] if np.any(on_lanes) else np.zeros(0),
        chain=tuple(chain), lane_index_by_edge={route[st.k]: st.lane.index for st in chain},
        route_pos_m=route_pos, path_s_m=path_s)


def _room(network: RoadNetwork, route: tuple[str, ...], chain: list[ChainStep],
          spans: list[tuple[int, int]], cum: FloatArray, res: Resampled
          ) -> tuple[BoolArray, BoolArray]:
    """(right, left) per resampled point: whether the chain's lane there has a lane
    beside it on that side (index above 0 / below the edge's lane count - 1). Junction
    bridges and the extensions have none (the tube widens for a kink only towards a
    neighbour lane)."""
    right = np.zeros(len(res.s_m), dtype=bool)
    left = np.zeros(len(res.s_m), dtype=bool)
    for step, (first, last) in zip(chain, spans, strict=True):
        on = (res.s_m >= cum[first]) & (res.s_m <= cum[last])
        index = step.lane.index
        right |= on & (index > 0)
        left |= on & (index < network.lane_count(route[step.k]) - 1)
    return right, left


def _extended(poly: FloatArray, junction: BoolArray, spans: list[tuple[int, int]],
              length_m: float) -> tuple[FloatArray, BoolArray, list[tuple[int, int]]]:
    """The polyline with one vertex added ``length_m`` beyond each end along its end
    segment (vertex indices of ``spans`` shifted by one)."""
    head = poly[0] - length_m * _unit(poly[_distinct(poly, 0, 1)] - poly[0])
    tail = poly[-1] + length_m * _unit(poly[-1] - poly[_distinct(poly, len(poly) - 1, -1)])
    return (np.vstack([head, poly, tail]), np.concatenate([[False], junction, [False]]),
            [(a + 1, b + 1) for a, b in spans])


def _distinct(poly: FloatArray, i: int, step: int) -> int:
    """The first vertex from ``i`` in direction ``step`` that is not at vertex i."""
    j = i + step
    while 0 <= j + step < len(poly) and np.hypot(*(poly[j] - poly[i])) < 1e-6:
        j += step
    return j


def _unit(v: FloatArray) -> FloatArray:
    out: FloatArray = v / max(float(np.hypot(*v)), 1e-12)
    return out


def project_along(curve: FloatArray, curve_s: FloatArray, points: FloatArray,
                  guess_s: FloatArray, window_m: float = 40.0) -> FloatArray:
    """Arc length [m] on ``curve`` (n, 2; arc length ``curve_s`` (n,)) of the orthogonal
    projection of each of ``points`` (m, 2), searched over the curve's segments within
    ``window_m`` of ``guess_s`` (m,) (the point's own arc length along the polyline: the
    curve stays within the tube of it, so the nearest segment is near that place, and a
    road that comes back near itself cannot capture the projection). Non-decreasing
    along the points (the chain's vertices are in driving order)."""
    out = np.empty(len(points))
    for i, (p, g) in enumerate(zip(points, guess_s, strict=True)):
        lo = max(int(np.searchsorted(curve_s, g - window_m)) - 1, 0)
        hi = min(int(np.searchsorted(curve_s, g + window_m)) + 1, len(curve) - 1)
        a, b = curve[lo:hi], curve[lo + 1:hi + 1]
        ab = b - a
        den = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
        t = np.clip(np.einsum("ij,ij->i", p - a, ab) / den, 0.0, 1.0)
        d = np.hypot(*(a + t[:, None] * ab - p).T)
        j = int(np.argmin(d))
        out[i] = curve_s[lo + j] + t[j] * (curve_s[lo + j + 1] - curve_s[lo + j])
    result: FloatArray = np.maximum.accumulate(out)
    return result


def crop_curve(curve: FloatArray, curve_s: FloatArray, s0: float, s1: float) -> FloatArray:
    """The part of ``curve`` (n, 2; arc length ``curve_s``) between arc lengths s0 < s1,
    its ends interpolated exactly at s0 and s1 (inner points closer than 1 cm to an end
    dropped)."""
    inner = (curve_s > s0 + 0.01) & (curve_s < s1 - 0.01)
    ends = np.column_stack([np.interp([s0, s1], curve_s, curve[:, 0]),
                            np.interp([s0, s1], curve_s, curve[:, 1])])
    out: FloatArray = np.vstack([ends[:1], curve[inner], ends[1:]])
    return out


def _breakpoints(network: RoadNetwork, route: tuple[str, ...], chain: list[ChainStep],
                 spans: list[tuple[int, int]], vertex_cum_m: FloatArray, vertex_s_m: FloatArray
                 ) -> tuple[FloatArray, FloatArray]:
    """(route positions, arc lengths on the curve) at every chain vertex, strictly
    increasing in both. A vertex's route position is SUMO's lane position of it: the
    edge's start plus its share of the lane shape's length times the edge's length."""
    starts = network.route_edge_starts_m(route)
    route_pos: list[float] = []
    path_s: list[float] = []
    for step, (first, last) in zip(chain, spans, strict=True):
        edge = route[step.k]
        shape_len = float(vertex_cum_m[last] - vertex_cum_m[first])
        scale = network.edge_length_m(edge) / shape_len if shape_len > 0 else 0.0
        for v in range(first, last + 1):
            pos = starts[edge] + float(vertex_cum_m[v] - vertex_cum_m[first]) * scale
            s = float(vertex_s_m[v])
            if route_pos and pos <= route_pos[-1] + 1e-6:
                continue  # a repeated vertex adds nothing
            if route_pos and s <= path_s[-1] + 1e-6:
                # A junction of some length whose ends meet (no bridge): its route
                # positions all lie at one point of the curve.
                s = path_s[-1] + 1e-6
            route_pos.append(pos)
            path_s.append(s)
    return np.asarray(route_pos), np.asarray(path_s)


__all__ = ["END_EXTENSION_M", "RouteReference", "build_reference", "crop_curve", "project_along"]
