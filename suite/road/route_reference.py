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
   to arc length on the curve piecewise linearly, edge start to edge start.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from suite.road.interp import interp_scalar
from suite.road.lane_graph import ChainStep, RouteLaneGraph
from suite.road.network import RoadNetwork
from suite.road.reference import Resampled, TubeParams, resample, smooth_in_tube

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


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
    res = resample(poly, tube.spacing_m, junction)
    seg = np.hypot(*np.diff(poly, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    half, jog_zone = _tube_half_widths(poly, cum, spans, res, tube)
    curve, offsets = smooth_in_tube(res, tube, half)
    # Arc length on the smooth curve at each polyline vertex ~ along the polyline (the
    # curve stays within a few centimetres of it); scale to the curve's own length.
    curve_len = float(np.sum(np.hypot(*np.diff(curve, axis=0).T)))
    scale = curve_len / cum[-1] if cum[-1] > 0 else 1.0
    route_pos, path_s = [], []
    for step, (first, last) in zip(chain, spans, strict=True):
        start = starts[route[step.k]]
        route_pos += [start, start + network.edge_length_m(route[step.k])]
        path_s += [cum[first] * scale, cum[last] * scale]
    on_lanes = ~(res.junction | jog_zone)
    return RouteReference(
        points_xy_m=curve, polyline_xy_m=poly, polyline_junction=junction,
        offsets_m=offsets[on_lanes] if np.any(on_lanes) else np.zeros(0),
        chain=tuple(chain), lane_index_by_edge={route[st.k]: st.lane.index for st in chain},
        route_pos_m=np.asarray(route_pos), path_s_m=np.asarray(path_s))


__all__ = ["RouteReference", "build_reference", "math"]
