"""Oriented-box geometry for collision, gap and TTC checks, and the point-to-polygon excess
of the drivable area: compiled kernels.

The lowest layer of ``reports`` (below ``reports.record``): the simulation loop's per-step
safety check (``suite.run.safety``), the metrics, the bird's-eye view and the Rerun world
all take their boxes from here.

A box is (cx, cy, heading_rad, length_m, width_m): centre [m], heading CCW from +X [rad],
length and width [m]. Its corners (4, 2) are, in this order, front-left, rear-left,
rear-right, front-right (:func:`box_corners`).

Three questions, each over many boxes in one compiled call (numba, ``cache=True``):

* overlap: the separating-axis test on the 4 edge normals (2 of each rectangle); the
  boxes overlap when no axis separates their projections (touching counts as overlap);
* distance: 0 where they overlap, else the smallest of the 32 point-to-segment
  distances (each corner of either box to each edge of the other), the exact Euclidean
  distance between two disjoint convex quads;
* swept TTC: both boxes translate at constant velocities with fixed headings; on each
  of the 4 unit normals n the relative motion w = v_a - v_b moves A's projection by
  (w . n) t, so the projections overlap for t in [t_lo, t_hi] on that axis; the boxes
  first touch at tau = max over axes of t_lo if that is <= the min of t_hi and the
  interval ends at t >= 0 (0 if they overlap now, +inf if they never touch within the
  horizon).

A fourth, for the drivable area (:func:`polygons_excess`): the signed excess of points
over a union of convex polygons (distance outside, minus the depth inside). A fifth, for
predicting traffic along the road (the TTC of ``reports.metrics.ttc``):
:func:`polyline_frenet`, points in the Frenet frame of a polyline (arc length and signed
offset of the nearest foot, the tangent angle and curvature there).

The kernels follow numpy's NaN propagation exactly (the tests hold them to numpy
references, ``tests/geometry_reference.py``, on every input): a box with a NaN
coordinate is separated on no axis, hence *overlapping* at distance 0 (callers mask
non-finite boxes themselves, as the metrics do; SUMO never reports one).

:func:`box_gaps` is the per-step safety check of the simulation loop: one box (the
ego's) against every neighbour at once, from the boxes' parameters (no corner arrays).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numba
import numpy as np

_NAN = math.nan


def box_corners(cx: np.ndarray | float, cy: np.ndarray | float, heading_rad: np.ndarray | float,
                length_m: np.ndarray | float, width_m: np.ndarray | float) -> np.ndarray:
    """Corners of boxes [m], shape (..., 4, 2) for broadcast inputs of shape (...):
    front-left, rear-left, rear-right, front-right."""
    cx, cy, h, ln, wd = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64)
                                              for v in (cx, cy, heading_rad, length_m, width_m)))
    c, s = np.cos(h), np.sin(h)
    hl, hw = 0.5 * ln, 0.5 * wd
    local = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    lx = local[:, 0] * hl[..., None]
    ly = local[:, 1] * hw[..., None]
    x = cx[..., None] + c[..., None] * lx - s[..., None] * ly
    y = cy[..., None] + s[..., None] * lx + c[..., None] * ly
    return np.stack([x, y], axis=-1)


# ------------------------------------------------------------------ compiled kernels
# numpy's maximum/minimum propagate NaN; Python's max/min and comparisons do not.


@numba.njit(cache=True, error_model="numpy", inline="always")
def _pmax(a: float, b: float) -> float:
    if a != a or b != b:
        return _NAN
    return a if a > b else b


@numba.njit(cache=True, error_model="numpy", inline="always")
def _pmin(a: float, b: float) -> float:
    if a != a or b != b:
        return _NAN
    return a if a < b else b


@numba.njit(cache=True, error_model="numpy", inline="always")
def _proj_range(q: np.ndarray, nx: float, ny: float) -> tuple[float, float]:
    """(min, max) of the projections of the 4 corners q (4, 2) on (nx, ny), NaN-propagating."""
    p = q[0, 0] * nx + q[0, 1] * ny
    lo = p
    hi = p
    for k in range(1, 4):
        p = q[k, 0] * nx + q[k, 1] * ny
        lo = _pmin(lo, p)
        hi = _pmax(hi, p)
    return lo, hi


@numba.njit(cache=True, error_model="numpy", inline="always")
def _overlap_quads(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two rectangles (4, 2): no edge normal separates them."""
    for poly in range(2):
        q = a if poly == 0 else b
        for i in range(2):
            nx = -(q[i + 1, 1] - q[i, 1])
            ny = q[i + 1, 0] - q[i, 0]
            amin, amax = _proj_range(a, nx, ny)
            bmin, bmax = _proj_range(b, nx, ny)
            if amax < bmin or bmax < amin:
                return False
    return True


@numba.njit(cache=True, error_model="numpy", inline="always")
def _point_segment(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance [m] from point p to segment a-b (the numpy reference's formula)."""
    abx = bx - ax
    aby = by - ay
    denom = max(abx * abx + aby * aby, 1e-12)
    t = ((px - ax) * abx + (py - ay) * aby) / denom
    if t < 0.0:
        t = 0.0
    elif t > 1.0:
        t = 1.0
    elif t != t:
        t = _NAN
    dx = px - (ax + t * abx)
    dy = py - (ay + t * aby)
    return math.sqrt(dx * dx + dy * dy)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _distance_quads(a: np.ndarray, b: np.ndarray) -> float:
    """Distance [m] between two rectangles (4, 2), 0 where they overlap."""
    if _overlap_quads(a, b):
        return 0.0
    best = math.inf
    for poly in range(2):
        p = a if poly == 0 else b
        s = b if poly == 0 else a
        for k in range(4):
            for e in range(4):
                f = (e + 1) % 4
                best = _pmin(best, _point_segment(p[k, 0], p[k, 1], s[e, 0], s[e, 1],
                                                  s[f, 0], s[f, 1]))
    return best


@numba.njit(cache=True, error_model="numpy", inline="always")
def _fill_corners(cx: float, cy: float, h: float, length: float, width: float,
                  out: np.ndarray) -> None:
    """The corners (4, 2) of one box into ``out`` (the order of :func:`box_corners`)."""
    c = math.cos(h)
    s = math.sin(h)
    hl = 0.5 * length
    hw = 0.5 * width
    for k in range(4):
        lx = hl if (k == 0 or k == 3) else -hl
        ly = hw if k < 2 else -hw
        out[k, 0] = cx + c * lx - s * ly
        out[k, 1] = cy + s * lx + c * ly


@numba.njit(cache=True, error_model="numpy")
def _pairs_kernel(a: np.ndarray, b: np.ndarray, want_distance: bool, dist: np.ndarray,
                  overlap: np.ndarray) -> None:
    """Row by row over a, b (M, 4, 2): overlap (M,) and, if asked, distance (M,)."""
    for i in range(a.shape[0]):
        ov = _overlap_quads(a[i], b[i])
        overlap[i] = ov
        if want_distance:
            dist[i] = 0.0 if ov else _distance_quads(a[i], b[i])


@numba.njit(cache=True, error_model="numpy")
def _gaps_kernel(cx: float, cy: float, h: float, length: float, width: float, xs: np.ndarray,
                 ys: np.ndarray, hs: np.ndarray, ls: np.ndarray, ws: np.ndarray,
                 gap: np.ndarray, overlap: np.ndarray) -> None:
    ego = np.empty((4, 2))
    other = np.empty((4, 2))
    _fill_corners(cx, cy, h, length, width, ego)
    for i in range(xs.shape[0]):
        _fill_corners(xs[i], ys[i], hs[i], ls[i], ws[i], other)
        ov = _overlap_quads(ego, other)
        overlap[i] = ov
        gap[i] = 0.0 if ov else _distance_quads(ego, other)


@numba.njit(cache=True, error_model="numpy")
def _nearest_kernel(cx: float, cy: float, h: float, length: float, width: float,
                    xs: np.ndarray, ys: np.ndarray, hs: np.ndarray, ls: np.ndarray,
                    ws: np.ndarray) -> tuple[int, float, bool]:
    """(index of the nearest box, its distance, whether any box overlaps); boxes whose
    bounding circles cannot beat the best distance so far are skipped (exact: the
    distance of two sets is >= centre distance - both circumradii)."""
    ego = np.empty((4, 2))
    other = np.empty((4, 2))
    _fill_corners(cx, cy, h, length, width, ego)
    r_ego = 0.5 * math.sqrt(length * length + width * width)
    best = math.inf
    best_i = -1
    any_overlap = False
    for i in range(xs.shape[0]):
        dx = xs[i] - cx
        dy = ys[i] - cy
        lower = (math.sqrt(dx * dx + dy * dy) - r_ego
                 - 0.5 * math.sqrt(ls[i] * ls[i] + ws[i] * ws[i]))
        if lower == lower and lower > 1e-9 and lower - 1e-9 >= best:
            continue  # cannot overlap, cannot be nearer
        _fill_corners(xs[i], ys[i], hs[i], ls[i], ws[i], other)
        ov = _overlap_quads(ego, other)
        d = 0.0 if ov else _distance_quads(ego, other)
        any_overlap = any_overlap or ov
        if d < best or best_i < 0:
            best = d
            best_i = i
    return best_i, best, any_overlap


@numba.njit(cache=True, error_model="numpy")
def _ttc_kernel(a: np.ndarray, va: np.ndarray, b: np.ndarray, vb: np.ndarray, horizon: float,
                out: np.ndarray) -> None:
    """Swept TTC [s] row by row over a, b (M, 4, 2) and va, vb (M, 2) [m/s]."""
    for i in range(a.shape[0]):
        wx = va[i, 0] - vb[i, 0]
        wy = va[i, 1] - vb[i, 1]
        t_enter = -math.inf
        t_exit = math.inf
        never = False
        for poly in range(2):
            q = a[i] if poly == 0 else b[i]
            for j in range(2):
                nx = -(q[j + 1, 1] - q[j, 1])
                ny = q[j + 1, 0] - q[j, 0]
                norm = max(math.sqrt(nx * nx + ny * ny), 1e-12)
                nx /= norm
                ny /= norm
                amin, amax = _proj_range(a[i], nx, ny)
                bmin, bmax = _proj_range(b[i], nx, ny)
                c = wx * nx + wy * ny
                if abs(c) < 1e-9:
                    lo = -math.inf
                    hi = math.inf
                    if amin > bmax or amax < bmin:
                        never = True
                else:
                    t1 = (bmin - amax) / c
                    t2 = (bmax - amin) / c
                    lo = _pmin(t1, t2)
                    hi = _pmax(t1, t2)
                t_enter = _pmax(t_enter, lo)
                t_exit = _pmin(t_exit, hi)
        ttc = math.inf
        if not never and t_enter <= t_exit and t_exit >= 0.0:
            ttc = max(t_enter, 0.0)
        out[i] = ttc if ttc <= horizon else math.inf


@numba.njit(cache=True, error_model="numpy")
def _polygons_excess_kernel(px: np.ndarray, py: np.ndarray, polys: np.ndarray,
                            bbox: np.ndarray, excess: np.ndarray, piece: np.ndarray,
                            edge: np.ndarray) -> None:
    """Per point: signed excess over a union of convex CCW polygons (K, V, 2) with
    bounding boxes (K, 4) = (xmin, ymin, xmax, ymax), its polygon and edge (module doc
    of :func:`polygons_excess`)."""
    n_poly = polys.shape[0]
    n_vert = polys.shape[1]
    for i in range(px.shape[0]):
        x = px[i]
        y = py[i]
        excess[i] = _NAN
        piece[i] = -1
        edge[i] = -1
        if x != x or y != y:
            continue
        best_out = math.inf
        best_in = 0.0  # the largest depth found so far (> 0 once inside a polygon)
        inside = False
        for k in range(n_poly):
            gx = max(bbox[k, 0] - x, 0.0, x - bbox[k, 2])
            gy = max(bbox[k, 1] - y, 0.0, y - bbox[k, 3])
            if inside:
                if gx > 0.0 or gy > 0.0:
                    continue  # outside its box: cannot contain the point
            elif gx * gx + gy * gy >= best_out * best_out:
                continue  # its box is farther than the nearest polygon so far
            depth = math.inf
            depth_edge = -1
            dist = math.inf
            dist_edge = -1
            for j in range(n_vert):
                ax = polys[k, j, 0]
                ay = polys[k, j, 1]
                bx = polys[k, (j + 1) % n_vert, 0]
                by = polys[k, (j + 1) % n_vert, 1]
                ex = bx - ax
                ey = by - ay
                length = math.sqrt(ex * ex + ey * ey)
                if length < 1e-12:
                    continue  # a repeated vertex (a triangle stored as a quad)
                signed = (ex * (y - ay) - ey * (x - ax)) / length  # > 0 on the inner side
                if signed < depth:
                    depth = signed
                    depth_edge = j
                d = _point_segment(x, y, ax, ay, bx, by)
                if d < dist:
                    dist = d
                    dist_edge = j
            if depth_edge < 0:
                continue  # a degenerate polygon (every edge of zero length)
            if depth >= 0.0:
                if not inside or depth > best_in:
                    best_in = depth
                    piece[i] = k
                    edge[i] = depth_edge
                inside = True
            elif not inside and dist < best_out:
                best_out = dist
                piece[i] = k
                edge[i] = dist_edge
        excess[i] = -best_in if inside else best_out


# The projection on a polyline (:func:`polyline_frenet`) tests the segments of one block
# only when the point may be nearer to them than the best foot so far (a bounding circle
# per block of this many segments), so that a long reference costs tens of tests a point.
_PROJ_BLOCK = 16


@numba.njit(cache=True, error_model="numpy", inline="always")
def _segment_foot(ref: np.ndarray, k: int, n_seg: int, x: float, y: float
                  ) -> tuple[float, float, float]:
    """(squared distance [m²], foot fraction t, cross product) of the point (x, y) and
    segment k of ``ref``; the first segment extends backwards and the last forwards (t
    not clamped there: the path continues straight beyond its ends)."""
    ax = ref[k, 0]
    ay = ref[k, 1]
    ex = ref[k + 1, 0] - ax
    ey = ref[k + 1, 1] - ay
    px = x - ax
    py = y - ay
    t = (px * ex + py * ey) / (ex * ex + ey * ey)
    if t < 0.0 and k > 0:
        t = 0.0
    elif t > 1.0 and k < n_seg - 1:
        t = 1.0
    dx = px - t * ex
    dy = py - t * ey
    return dx * dx + dy * dy, t, ex * py - ey * px


@numba.njit(cache=True, error_model="numpy", inline="always")
def _scan_segments(ref: np.ndarray, n_seg: int, k0: int, k1: int, x: float, y: float,
                   best: tuple[float, int, float, float]) -> tuple[float, int, float, float]:
    """The nearest foot (d², k, t, cross) on segments k0..k1-1, or ``best`` if none is nearer."""
    d2b, kb, tb, cb = best
    for k in range(k0, k1):
        d2, t, cr = _segment_foot(ref, k, n_seg, x, y)
        if d2 < d2b:
            d2b = d2
            kb = k
            tb = t
            cb = cr
    return d2b, kb, tb, cb


@numba.njit(cache=True, error_model="numpy", inline="always")
def _segment_window(cum: np.ndarray, centre: float, half: float) -> tuple[int, int]:
    """First and last segment meeting [centre - half, centre + half] along the path; every
    segment for a NaN centre or half."""
    n_seg = cum.shape[0] - 1
    if centre != centre or half != half:
        return 0, n_seg - 1
    k_lo = np.searchsorted(cum, centre - half) - 1
    k_hi = np.searchsorted(cum, centre + half, side="right") - 1
    return min(max(k_lo, 0), n_seg - 1), min(max(k_hi, 0), n_seg - 1)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _nearest_foot(ref: np.ndarray, circles: np.ndarray, x: float, y: float, k_lo: int,
                  k_hi: int) -> tuple[float, int, float, float]:
    """The nearest foot (d², k, t, cross) of (x, y) on segments k_lo..k_hi: first the
    block whose circle centre is nearest, then every other block whose bounding circle
    may hold a nearer foot (exact: a block is skipped only when its circle lies no
    nearer than the best foot; the end blocks, whose end segments extend without bound,
    never are)."""
    n_seg = ref.shape[0] - 1
    last = circles.shape[0] - 1
    b_lo = k_lo // _PROJ_BLOCK
    b_hi = k_hi // _PROJ_BLOCK
    first = b_lo
    low = math.inf
    for b in range(b_lo, b_hi + 1):
        dx = x - circles[b, 0]
        dy = y - circles[b, 1]
        if dx * dx + dy * dy < low:
            low = dx * dx + dy * dy
            first = b
    best = _scan_segments(ref, n_seg, max(first * _PROJ_BLOCK, k_lo),
                          min(first * _PROJ_BLOCK + _PROJ_BLOCK, k_hi + 1), x, y,
                          (math.inf, -1, 0.0, 0.0))
    reach = math.sqrt(best[0])
    for b in range(b_lo, b_hi + 1):
        dx = x - circles[b, 0]
        dy = y - circles[b, 1]
        far = circles[b, 2] + reach  # the circle is no nearer than the best foot beyond this
        # (a NaN circle, from overflowing coordinates, is scanned: "not >=")
        if b != first and (b == 0 or b == last or not dx * dx + dy * dy >= far * far):
            best = _scan_segments(ref, n_seg, max(b * _PROJ_BLOCK, k_lo),
                                  min(b * _PROJ_BLOCK + _PROJ_BLOCK, k_hi + 1), x, y, best)
            reach = math.sqrt(best[0])
    return best


@numba.njit(cache=True, error_model="numpy")
def _frenet_kernel(ref: np.ndarray, cum: np.ndarray, circles: np.ndarray, x: np.ndarray,
                   y: np.ndarray, hint: np.ndarray, half: np.ndarray, track: bool,
                   s_out: np.ndarray, d_out: np.ndarray) -> None:
    """Per point: arc length s and signed offset d (left +) of its nearest foot on the
    polyline ``ref`` (M, 2) with cumulative lengths ``cum`` (M,), searched within
    hint ± half (all of it for a NaN hint); ``track``: around the previous point's s
    instead, widened by twice the distance moved (:func:`polyline_frenet`)."""
    for i in range(x.shape[0]):
        s_out[i] = _NAN
        d_out[i] = _NAN
        if not (math.isfinite(x[i]) and math.isfinite(y[i])):
            continue
        centre = hint[i]
        width = half[i]
        if track and i > 0 and s_out[i - 1] == s_out[i - 1]:
            centre = s_out[i - 1]
            width = half[i] + 2.0 * math.hypot(x[i] - x[i - 1], y[i] - y[i - 1])
        k_lo, k_hi = _segment_window(cum, centre, width)
        d2, k, t, cross = _nearest_foot(ref, circles, x[i], y[i], k_lo, k_hi)
        if k < 0:
            continue
        s_out[i] = cum[k] + t * (cum[k + 1] - cum[k])
        dist = math.sqrt(d2)
        d_out[i] = dist if cross >= 0.0 else -dist


# ------------------------------------------------------------------ public API


def _pairs(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """a, b broadcast to a common (..., 4, 2) and flattened to (M, 4, 2) C-contiguous."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    if a.shape[-2:] != (4, 2):
        raise ValueError(f"boxes must have shape (..., 4, 2), got {a.shape}")
    shape = a.shape[:-2]
    return (np.ascontiguousarray(a.reshape(-1, 4, 2)),
            np.ascontiguousarray(b.reshape(-1, 4, 2)), shape)


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether rectangles a and b (..., 4, 2), broadcast together, overlap -> bool (...)."""
    fa, fb, shape = _pairs(a, b)
    overlap = np.empty(fa.shape[0], dtype=np.bool_)
    _pairs_kernel(fa, fb, False, np.empty(0), overlap)
    return overlap.reshape(shape)


def box_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distance [m] between rectangles a and b (..., 4, 2), broadcast
    together -> (...); 0 where they overlap."""
    fa, fb, shape = _pairs(a, b)
    dist = np.empty(fa.shape[0])
    overlap = np.empty(fa.shape[0], dtype=np.bool_)
    _pairs_kernel(fa, fb, True, dist, overlap)
    return dist.reshape(shape)


def box_gaps(cx: float, cy: float, heading_rad: float, length_m: float, width_m: float,
             x_m: np.ndarray, y_m: np.ndarray, other_heading_rad: np.ndarray,
             other_length_m: np.ndarray, other_width_m: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    """One box against n others given by their parameters, each (n,) [m, rad]:
    (distance (n,) [m], 0 on overlap; overlap (n,) bool). One compiled call."""
    xs = np.ascontiguousarray(x_m, dtype=np.float64)
    n = xs.shape[0]
    gap = np.empty(n)
    overlap = np.empty(n, dtype=np.bool_)
    _gaps_kernel(float(cx), float(cy), float(heading_rad), float(length_m), float(width_m), xs,
                 np.ascontiguousarray(y_m, dtype=np.float64),
                 np.ascontiguousarray(other_heading_rad, dtype=np.float64),
                 np.ascontiguousarray(other_length_m, dtype=np.float64),
                 np.ascontiguousarray(other_width_m, dtype=np.float64), gap, overlap)
    return gap, overlap


def nearest_box(cx: float, cy: float, heading_rad: float, length_m: float, width_m: float,
                x_m: np.ndarray, y_m: np.ndarray, other_heading_rad: np.ndarray,
                other_length_m: np.ndarray, other_width_m: np.ndarray
                ) -> tuple[int, float, bool]:
    """One box against n others given by their parameters, each (n,) [m, rad]:
    (index of the nearest, its distance [m] (0 on overlap), whether any overlaps);
    (-1, inf, False) when n = 0. Equals ``argmin``/``min``/``any`` of :func:`box_gaps`
    (first index on ties) at a fraction of its cost: far boxes are culled by their
    bounding circles."""
    i, d, ov = _nearest_kernel(float(cx), float(cy), float(heading_rad), float(length_m),
                               float(width_m), np.ascontiguousarray(x_m, dtype=np.float64),
                               np.ascontiguousarray(y_m, dtype=np.float64),
                               np.ascontiguousarray(other_heading_rad, dtype=np.float64),
                               np.ascontiguousarray(other_length_m, dtype=np.float64),
                               np.ascontiguousarray(other_width_m, dtype=np.float64))
    return int(i), float(d), bool(ov)


def swept_box_ttc(corners_a: np.ndarray, vel_a: np.ndarray, corners_b: np.ndarray,
                  vel_b: np.ndarray, horizon_s: float) -> np.ndarray:
    """Time [s] until rectangles A and B (..., 4, 2) first touch when translating at
    constant velocities vel_a, vel_b (..., 2) [m/s] (all broadcast together): 0 if they
    overlap now, +inf if they do not touch within ``horizon_s`` (module docstring)."""
    a = np.asarray(corners_a, dtype=np.float64)
    b = np.asarray(corners_b, dtype=np.float64)
    va = np.asarray(vel_a, dtype=np.float64)
    vb = np.asarray(vel_b, dtype=np.float64)
    shape = np.broadcast_shapes(a.shape[:-2], b.shape[:-2], va.shape[:-1], vb.shape[:-1])
    fa = np.ascontiguousarray(np.broadcast_to(a, shape + (4, 2)).reshape(-1, 4, 2))
    fb = np.ascontiguousarray(np.broadcast_to(b, shape + (4, 2)).reshape(-1, 4, 2))
    fva = np.ascontiguousarray(np.broadcast_to(va, shape + (2,)).reshape(-1, 2))
    fvb = np.ascontiguousarray(np.broadcast_to(vb, shape + (2,)).reshape(-1, 2))
    out = np.empty(fa.shape[0])
    _ttc_kernel(fa, fva, fb, fvb, float(horizon_s), out)
    return out.reshape(shape)


def polygons_excess(points_xy_m: np.ndarray, polygons_xy_m: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed excess [m] of points (P, 2) over the union of convex polygons (K, V, 2),
    each counter-clockwise (a triangle may repeat a vertex): one compiled call.

    Outside every polygon the excess is the Euclidean distance to the nearest one (the
    smallest point-to-edge distance, exact for convex polygons); inside it is minus the
    largest depth over the polygons holding the point (depth in a convex polygon = the
    smallest distance to the lines of its edges), a lower bound of the depth in the
    union. Returns (excess (P,) [m], polygon (P,), edge (P,)): the polygon and edge
    (j from vertex j to j + 1) that give the value (the nearest edge of the nearest
    polygon outside, the nearest edge of the deepest one inside); NaN, -1, -1 for a
    point with a NaN coordinate or without polygons."""
    pts = np.ascontiguousarray(np.asarray(points_xy_m, dtype=np.float64).reshape(-1, 2))
    polys = np.ascontiguousarray(np.asarray(polygons_xy_m, dtype=np.float64))
    if polys.ndim != 3 or polys.shape[-1] != 2 or polys.shape[1] < 3:
        raise ValueError(f"polygons must have shape (K, V >= 3, 2), got {polys.shape}")
    n = pts.shape[0]
    excess = np.empty(n)
    piece = np.empty(n, dtype=np.int64)
    edge = np.empty(n, dtype=np.int64)
    bbox = (np.concatenate([polys.min(axis=1), polys.max(axis=1)], axis=1) if polys.shape[0]
            else np.zeros((0, 4)))
    _polygons_excess_kernel(np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]),
                            polys, np.ascontiguousarray(bbox), excess, piece, edge)
    return excess, piece, edge


@dataclass(frozen=True)
class PathFrame:
    """Points in the Frenet frame of a polyline, each (P,): arc length ``s_m`` [m] of the
    nearest foot (negative before the start, beyond the length after the end, where the
    path continues straight), signed offset ``d_m`` [m] (left of the direction of travel
    +), the path's tangent angle ``tangent_rad`` [rad, CCW from +X] and curvature
    ``curvature_1pm`` [1/m, left turn +] at s. NaN where a point is not finite or the
    polyline has fewer than two distinct finite points."""

    s_m: np.ndarray
    d_m: np.ndarray
    tangent_rad: np.ndarray
    curvature_1pm: np.ndarray


def polyline_frenet(ref_xy_m: np.ndarray, x_m: np.ndarray, y_m: np.ndarray,
                    hint_s_m: np.ndarray | None = None, window_m: np.ndarray | None = None,
                    track: bool = False) -> PathFrame:
    """Project points (P,) [m] on the polyline ``ref_xy_m`` (M, 2) [m]: one compiled call.

    Each point's foot is the nearest point of the polyline (exact, by segments), found
    within ``hint_s_m ± window_m`` along the path (the whole path where either is NaN or
    not given): the window keeps a point near a road that passes by itself (a loop, a
    cloverleaf) on the right part of it. ``track``: the points are a trajectory; after
    the first, each is searched around the previous one's s within ``window_m`` plus
    twice the distance moved (the hint only where the previous point has no foot).

    The tangent angle is the segments' headings (unwrapped) interpolated linearly
    between the segments' midpoints, held beyond the first and last midpoint, and the
    curvature its derivative along s (piecewise constant, 0 beyond the end midpoints):
    for a polyline sampling a smooth curve every h metres, the curve's own tangent and
    curvature to O(h²), without the steps of the chords' headings. Non-finite vertices
    and repeated ones are dropped first."""
    x = np.ascontiguousarray(x_m, dtype=np.float64).reshape(-1)
    y = np.ascontiguousarray(y_m, dtype=np.float64).reshape(-1)
    n = x.shape[0]
    ref = _clean_polyline(ref_xy_m)
    if ref.shape[0] < 2:
        nan = np.full(n, np.nan)
        return PathFrame(nan, nan.copy(), nan.copy(), nan.copy())
    with np.errstate(all="ignore"):
        seg = np.diff(ref, axis=0)
        length = np.hypot(seg[:, 0], seg[:, 1])
        cum = np.concatenate([[0.0], np.cumsum(length)])
    # writable C arrays always: a read-only one (a broadcast scalar) is another numba
    # signature, compiled or loaded from the cache in every scenario process
    hint = np.require(np.full(n, np.nan) if hint_s_m is None else _per_point(hint_s_m, n),
                      np.float64, ("C", "W"))
    half = np.require(np.full(n, np.nan) if window_m is None else _per_point(window_m, n),
                      np.float64, ("C", "W"))
    s = np.empty(n)
    d = np.empty(n)
    _frenet_kernel(ref, cum, _block_circles(ref), x, y, hint, half, bool(track), s, d)
    heading = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
    mid = cum[:-1] + 0.5 * length
    tangent = np.interp(s, mid, heading)
    curvature = np.zeros(n)
    if mid.size >= 2:
        j = np.searchsorted(mid, s, side="right") - 1
        inside = (j >= 0) & (j < mid.size - 1)
        with np.errstate(all="ignore"):  # overflowing coordinates give NaN, not a warning
            rate = np.diff(heading) / np.diff(mid)
        curvature = np.where(inside, rate[np.clip(j, 0, mid.size - 2)], 0.0)
    finite = np.isfinite(s)
    return PathFrame(np.where(finite, s, np.nan), np.where(finite, d, np.nan),
                     np.where(finite, tangent, np.nan), np.where(finite, curvature, np.nan))


def _per_point(values: np.ndarray, n: int) -> np.ndarray:
    return np.ascontiguousarray(np.broadcast_to(np.asarray(values, dtype=np.float64), (n,)))


def _clean_polyline(ref_xy_m: np.ndarray) -> np.ndarray:
    """The polyline (K, 2) without non-finite vertices and vertices repeating the previous."""
    ref = np.asarray(ref_xy_m, dtype=np.float64).reshape(-1, 2)
    ref = ref[np.all(np.isfinite(ref), axis=1)]
    if ref.shape[0] >= 2:
        with np.errstate(all="ignore"):  # overflowing coordinates: NaN feet, no warning
            step = np.hypot(*np.diff(ref, axis=0).T)
        ref = ref[np.concatenate([[True], step > 1e-9])]
    return np.ascontiguousarray(ref)


def _block_circles(ref: np.ndarray) -> np.ndarray:
    """(B, 3) bounding circles (cx, cy, r) [m] of blocks of ``_PROJ_BLOCK`` segments."""
    n_seg = ref.shape[0] - 1
    n_blk = -(-n_seg // _PROJ_BLOCK)
    idx = np.minimum(np.arange(n_blk)[:, None] * _PROJ_BLOCK
                     + np.arange(_PROJ_BLOCK + 1)[None, :], n_seg)
    pts = ref[idx]  # (B, block + 1, 2): a block's segments' vertices (the last repeated)
    with np.errstate(all="ignore"):  # overflowing coordinates: an infinite circle, culls nothing
        centre = 0.5 * (pts.min(axis=1) + pts.max(axis=1))
        radius = np.max(np.hypot(pts[..., 0] - centre[:, None, 0],
                                 pts[..., 1] - centre[:, None, 1]), axis=1)
    return np.ascontiguousarray(np.concatenate([centre, radius[:, None]], axis=1))


def load_kernels() -> None:
    """Load (or compile once) every kernel of this module by calling it on tiny inputs: a
    process that forks scenario processes calls it once, so that they inherit the
    compiled code instead of each loading it from numba's cache."""
    one = box_corners(0.0, 0.0, 0.0, 4.0, 2.0)[None]
    boxes_overlap(one, one)
    box_distance(one, one)
    swept_box_ttc(one, np.zeros((1, 2)), one, np.zeros((1, 2)), 1.0)
    z = np.zeros(1)
    box_gaps(0.0, 0.0, 0.0, 4.0, 2.0, z, z, z, z + 4.0, z + 2.0)
    nearest_box(0.0, 0.0, 0.0, 4.0, 2.0, z, z, z, z + 4.0, z + 2.0)
    polygons_excess(np.zeros((1, 2)), one)
    polyline_frenet(np.array([[0.0, 0.0], [1.0, 0.0]]), z, z, z, z, track=True)


# ------------------------------------------------------------------ the ego's box


class BoxShape(Protocol):
    """A body box relative to its CG [m] (``reports.record.meta.EgoBox`` is one)."""

    @property
    def length_m(self) -> float: ...

    @property
    def width_m(self) -> float: ...

    @property
    def cg_to_box_centre_m(self) -> float: ...


def ego_box_centre(x_cg: float, y_cg: float, psi_rad: float,
                   cg_to_box_centre_m: float) -> tuple[float, float]:
    """The ego's box centre [m] from its CG (the box centre lies ahead of the CG by the
    offset [m] along the yaw psi_rad)."""
    return (float(x_cg + cg_to_box_centre_m * np.cos(psi_rad)),
            float(y_cg + cg_to_box_centre_m * np.sin(psi_rad)))


def ego_box_centres(x_m: np.ndarray, y_m: np.ndarray, psi_rad: np.ndarray,
                    ego: BoxShape) -> tuple[np.ndarray, np.ndarray]:
    """Box centres (T,) [m] along a CG path (T,): ``cg_to_box_centre_m`` ahead of the CG
    along the yaw."""
    psi = np.asarray(psi_rad, dtype=np.float64)
    return (np.asarray(x_m, dtype=np.float64) + ego.cg_to_box_centre_m * np.cos(psi),
            np.asarray(y_m, dtype=np.float64) + ego.cg_to_box_centre_m * np.sin(psi))


def ego_box_corners(x_m: np.ndarray, y_m: np.ndarray, psi_rad: np.ndarray,
                    ego: BoxShape) -> np.ndarray:
    """Corners (T, 4, 2) [m] of the ego box along a CG path (T,)."""
    cx, cy = ego_box_centres(x_m, y_m, psi_rad, ego)
    return box_corners(cx, cy, psi_rad, ego.length_m, ego.width_m).reshape(cx.shape[0], 4, 2)
