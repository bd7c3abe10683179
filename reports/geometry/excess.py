"""The signed excess of points over a union of convex polygons (the drivable area):
distance outside, minus the depth inside, in one compiled call (:func:`polygons_excess`)."""

from __future__ import annotations

import math

import numba
import numpy as np

from reports.geometry.boxes import _point_segment

_NAN = math.nan


@numba.njit(cache=True, error_model="numpy", inline="always")
def _depth_and_distance(polys: np.ndarray, k: int, x: float, y: float
                        ) -> tuple[float, int, float, int]:
    """(depth, its edge, distance, its edge) of the point (x, y) in polygon k: the
    smallest signed distance to the lines of its edges (> 0 on the inner side) and the
    smallest distance to its edges (edge -1 where every edge has zero length)."""
    n_vert = polys.shape[1]
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
    return depth, depth_edge, dist, dist_edge


@numba.njit(cache=True, error_model="numpy", inline="always")
def _box_culls(bbox: np.ndarray, k: int, x: float, y: float, inside: bool,
               best_out: float) -> bool:
    """Whether polygon k's bounding box rules it out: outside it once the point is
    inside some polygon, or farther than the nearest polygon so far."""
    gx: float = max(bbox[k, 0] - x, 0.0, x - bbox[k, 2])
    gy: float = max(bbox[k, 1] - y, 0.0, y - bbox[k, 3])
    if inside:
        return gx > 0.0 or gy > 0.0  # outside its box: cannot contain the point
    return gx * gx + gy * gy >= best_out * best_out  # farther than the nearest so far


@numba.njit(cache=True, error_model="numpy")
def _polygons_excess_kernel(px: np.ndarray, py: np.ndarray, polys: np.ndarray,
                            bbox: np.ndarray, excess: np.ndarray, piece: np.ndarray,
                            edge: np.ndarray) -> None:
    """Per point: signed excess over a union of convex CCW polygons (K, V, 2) with
    bounding boxes (K, 4) = (xmin, ymin, xmax, ymax), its polygon and edge (module doc
    of :func:`polygons_excess`)."""
    n_poly = polys.shape[0]
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
            if _box_culls(bbox, k, x, y, inside, best_out):
                continue
            depth, depth_edge, dist, dist_edge = _depth_and_distance(polys, k, x, y)
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
