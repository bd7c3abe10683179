"""Segments against convex quads: intersection and distance (a vehicle's path between two
recorded rows against a box, for the swept contacts of ``reports.metrics.collisions``)."""

from __future__ import annotations

import numpy as np


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _segments_intersect(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray
                        ) -> bool:
    """Closed segments p1-p2 and q1-q2 share a point (touching counts)."""
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True

    def on(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: float) -> bool:
        return abs(d) < 1e-12 and min(a[0], b[0]) - 1e-12 <= c[0] <= max(a[0], b[0]) + 1e-12 \
            and min(a[1], b[1]) - 1e-12 <= c[1] <= max(a[1], b[1]) + 1e-12

    return on(q1, q2, p1, d1) or on(q1, q2, p2, d2) or on(p1, p2, q1, d3) or on(p1, p2, q2, d4)


def _point_in_convex(p: np.ndarray, quad: np.ndarray) -> bool:
    signs = [_cross(quad[k], quad[(k + 1) % 4], p) for k in range(4)]
    return all(s >= -1e-12 for s in signs) or all(s <= 1e-12 for s in signs)


def segment_hits_box(a: np.ndarray, b: np.ndarray, quad: np.ndarray) -> bool:
    """Whether segment a-b (2,) (2,) intersects the convex quad (4, 2), boundary
    included (shapely's ``LineString.intersects(Polygon)``)."""
    if _point_in_convex(a, quad) or _point_in_convex(b, quad):
        return True
    return any(_segments_intersect(a, b, quad[k], quad[(k + 1) % 4]) for k in range(4))


def _point_segment_m(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(float(np.dot(ab, ab)), 1e-12), 0.0, 1.0))
    return float(np.hypot(*(p - a - t * ab)))


def segment_box_distance_m(a: np.ndarray, b: np.ndarray, quad: np.ndarray) -> float:
    """Distance [m] from segment a-b to the convex quad (4, 2); 0 where they intersect."""
    if segment_hits_box(a, b, quad):
        return 0.0
    best = min(_point_segment_m(p, quad[k], quad[(k + 1) % 4]) for p in (a, b)
               for k in range(4))
    return min(best, *(_point_segment_m(quad[k], a, b) for k in range(4)))
