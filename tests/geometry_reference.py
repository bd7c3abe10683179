"""numpy references of the compiled box geometry of :mod:`reports.geometry` (tests only).

Broadcast over leading axes; corners (..., 4, 2) as from :func:`reports.geometry.box_corners`.
The kernels' names are re-exported so that a test takes both from one place.
"""

from __future__ import annotations

import numpy as np

from reports.geometry import box_corners, box_distance, boxes_overlap, swept_box_ttc

__all__ = ["box_corners", "box_distance", "box_distance_reference", "boxes_overlap",
           "boxes_overlap_reference", "swept_box_ttc", "swept_box_ttc_reference"]


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p (..., 2) to segments a-b (..., 2)."""
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-12)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / denom, 0.0, 1.0)
    closest = a + t[..., None] * ab
    out: np.ndarray = np.linalg.norm(p - closest, axis=-1)
    return out


def boxes_overlap_reference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """numpy reference of :func:`reports.geometry.boxes_overlap` (separating axes, broadcast)."""
    a, b = np.broadcast_arrays(a, b)
    overlap = np.ones(a.shape[:-2], dtype=bool)
    for poly in (a, b):
        for i in range(2):  # a rectangle has two distinct edge normals
            edge = poly[..., i + 1, :] - poly[..., i, :]
            normal = np.stack([-edge[..., 1], edge[..., 0]], axis=-1)
            pa = np.einsum("...kd,...d->...k", a, normal)
            pb = np.einsum("...kd,...d->...k", b, normal)
            separated = (pa.max(-1) < pb.min(-1)) | (pb.max(-1) < pa.min(-1))
            overlap &= ~separated
    return overlap


def box_distance_reference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """numpy reference of :func:`reports.geometry.box_distance` (32 point-segment distances,
    broadcast)."""
    a, b = np.broadcast_arrays(a, b)
    best = np.full(a.shape[:-2], np.inf)
    for poly_p, poly_s in ((a, b), (b, a)):
        for k in range(4):
            p = poly_p[..., k, :]
            for e in range(4):
                d = _point_segment_distance(p, poly_s[..., e, :], poly_s[..., (e + 1) % 4, :])
                best = np.minimum(best, d)
    out: np.ndarray = np.where(boxes_overlap_reference(a, b), 0.0, best)
    return out


def swept_box_ttc_reference(corners_a: np.ndarray, vel_a: np.ndarray, corners_b: np.ndarray,
                            vel_b: np.ndarray, horizon_s: float) -> np.ndarray:
    """numpy reference of :func:`reports.geometry.swept_box_ttc`."""
    a = np.asarray(corners_a, dtype=np.float64)
    b = np.asarray(corners_b, dtype=np.float64)
    a, b = np.broadcast_arrays(a, b)
    w = np.broadcast_to(np.asarray(vel_a, dtype=np.float64) - np.asarray(vel_b, dtype=np.float64),
                        a.shape[:-2] + (2,))
    t_enter = np.full(a.shape[:-2], -np.inf)
    t_exit = np.full(a.shape[:-2], np.inf)
    never = np.zeros(a.shape[:-2], dtype=bool)
    for poly in (a, b):
        for i in range(2):
            edge = poly[..., i + 1, :] - poly[..., i, :]
            normal = np.stack([-edge[..., 1], edge[..., 0]], axis=-1)
            norm = np.linalg.norm(normal, axis=-1, keepdims=True)
            normal = normal / np.maximum(norm, 1e-12)
            pa = np.einsum("...kd,...d->...k", a, normal)
            pb = np.einsum("...kd,...d->...k", b, normal)
            a_min, a_max = pa.min(-1), pa.max(-1)
            b_min, b_max = pb.min(-1), pb.max(-1)
            c = np.einsum("...d,...d->...", w, normal)
            still = np.abs(c) < 1e-9
            with np.errstate(divide="ignore", invalid="ignore"):
                t1 = (b_min - a_max) / c
                t2 = (b_max - a_min) / c
            lo = np.where(still, -np.inf, np.minimum(t1, t2))
            hi = np.where(still, np.inf, np.maximum(t1, t2))
            never |= still & ((a_min > b_max) | (a_max < b_min))
            t_enter = np.maximum(t_enter, lo)
            t_exit = np.minimum(t_exit, hi)
    hit = ~never & (t_enter <= t_exit) & (t_exit >= 0.0)
    ttc = np.where(hit, np.maximum(t_enter, 0.0), np.inf)
    out: np.ndarray = np.where(ttc <= horizon_s, ttc, np.inf)
    return out
