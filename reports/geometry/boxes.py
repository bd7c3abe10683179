"""Oriented boxes: corners, overlap, distance, gaps and swept TTC (compiled kernels).

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

The kernels follow numpy's NaN propagation exactly (the tests hold them to numpy
references, ``tests/geometry_reference.py``, on every input): a box with a NaN
coordinate is separated on no axis, hence *overlapping* at distance 0 (callers mask
non-finite boxes themselves, as the metrics do; SUMO never reports one).

:func:`box_gaps` is the per-step safety check of the simulation loop: one box (the
ego's) against every neighbour at once, from the boxes' parameters (no corner arrays).
"""
from __future__ import annotations

import math

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
