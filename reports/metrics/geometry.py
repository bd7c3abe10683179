"""Oriented-box geometry for collision, gap and TTC checks (pure numpy).

A box is (cx, cy, heading_rad, length_m, width_m): centre, heading CCW from +X.
"""

from __future__ import annotations

import numpy as np

from reports.record.meta import EgoBox


def box_corners(cx: np.ndarray | float, cy: np.ndarray | float, heading_rad: np.ndarray | float,
                length_m: np.ndarray | float, width_m: np.ndarray | float) -> np.ndarray:
    """Corners of boxes, shape (..., 4, 2), counter-clockwise from front-left... order:
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


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p (..., 2) to segments a-b (..., 2)."""
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=-1), 1e-12)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / denom, 0.0, 1.0)
    closest = a + t[..., None] * ab
    out: np.ndarray = np.linalg.norm(p - closest, axis=-1)
    return out


def boxes_overlap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Separating-axis test between convex quads a (..., 4, 2) and b (..., 4, 2) -> bool (...)."""
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


def box_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distance between convex quads a and b (..., 4, 2); 0 where they overlap."""
    a, b = np.broadcast_arrays(a, b)
    best = np.full(a.shape[:-2], np.inf)
    for poly_p, poly_s in ((a, b), (b, a)):
        for k in range(4):
            p = poly_p[..., k, :]
            for e in range(4):
                d = _point_segment_distance(p, poly_s[..., e, :], poly_s[..., (e + 1) % 4, :])
                best = np.minimum(best, d)
    return np.where(boxes_overlap(a, b), 0.0, best)


def ego_box_centre(x_cg: float, y_cg: float, psi_rad: float,
                   cg_to_box_centre_m: float) -> tuple[float, float]:
    """The ego's box centre from its CG (the box centre lies ahead of the CG by the offset)."""
    return (float(x_cg + cg_to_box_centre_m * np.cos(psi_rad)),
            float(y_cg + cg_to_box_centre_m * np.sin(psi_rad)))



def ego_box_centres(x_m: np.ndarray, y_m: np.ndarray, psi_rad: np.ndarray,
                    ego: EgoBox) -> tuple[np.ndarray, np.ndarray]:
    """Box centres (T,) [m] along a CG path (T,): ``cg_to_box_centre_m`` ahead of the CG
    along the yaw."""
    psi = np.asarray(psi_rad, dtype=np.float64)
    return (np.asarray(x_m, dtype=np.float64) + ego.cg_to_box_centre_m * np.cos(psi),
            np.asarray(y_m, dtype=np.float64) + ego.cg_to_box_centre_m * np.sin(psi))


def ego_box_corners(x_m: np.ndarray, y_m: np.ndarray, psi_rad: np.ndarray,
                    ego: EgoBox) -> np.ndarray:
    """Corners (T, 4, 2) [m] of the ego box along a CG path (T,)."""
    cx, cy = ego_box_centres(x_m, y_m, psi_rad, ego)
    return box_corners(cx, cy, psi_rad, ego.length_m, ego.width_m).reshape(cx.shape[0], 4, 2)
