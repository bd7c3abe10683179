"""Polyline geometry: project a point onto a polyline.

For a polyline p_0..p_{m-1} and a point q, the projection is the nearest point on any
segment: t_i = clamp(((q - p_i) . d_i) / |d_i|^2, 0, 1) with d_i = p_{i+1} - p_i. It
gives the arc length ``s_m`` of that point, the unsigned distance ``distance_m``, the
signed lateral offset ``lateral_m`` (left of the direction of travel > 0: the z
component of d_i x (q - p_i), over |d_i|) and the segment heading ``heading_rad``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from suite.importers.commonroad.records import FloatArray

__all__ = ["Projection", "angle_diff_rad", "polyline_length_m", "project", "resample"]


@dataclass(frozen=True)
class Projection:
    """A point's projection on a polyline: arc length ``s_m``, polyline length
    ``length_m``, distance ``distance_m`` and signed lateral offset ``lateral_m`` [m],
    heading of the segment ``heading_rad``."""

    s_m: float
    length_m: float
    distance_m: float
    lateral_m: float
    heading_rad: float


def polyline_length_m(xy: FloatArray) -> float:
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    return float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) if len(pts) > 1 else 0.0


def project(xy: FloatArray, x_m: float, y_m: float) -> Projection:
    """Project (x_m, y_m) onto the polyline ``xy`` (m, 2), m >= 2 (module docstring)."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    d = np.diff(pts, axis=0)
    seg2 = np.einsum("ij,ij->i", d, d)
    q = np.array([x_m, y_m]) - pts[:-1]
    t = np.clip(np.einsum("ij,ij->i", q, d) / np.where(seg2 > 0, seg2, 1.0), 0.0, 1.0)
    foot = pts[:-1] + d * t[:, None]
    dist = np.hypot(x_m - foot[:, 0], y_m - foot[:, 1])
    i = int(np.argmin(dist))
    seg = np.sqrt(seg2)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    cross = d[i, 0] * q[i, 1] - d[i, 1] * q[i, 0]
    lateral = float(cross / seg[i]) if seg[i] > 0 else 0.0
    if t[i] in (0.0, 1.0):  # beyond a segment's end: the offset is the distance
        lateral = math.copysign(float(dist[i]), lateral if lateral != 0.0 else 1.0)
    return Projection(float(cum[i] + t[i] * seg[i]), float(cum[-1]), float(dist[i]), lateral,
                      float(math.atan2(d[i, 1], d[i, 0])))


def resample(xy: FloatArray, fractions: FloatArray) -> FloatArray:
    """Points at the given fractions (k,) in [0, 1] of the polyline's arc length."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    s = np.asarray(fractions, dtype=np.float64) * cum[-1]
    return np.column_stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])


def angle_diff_rad(a_rad: float, b_rad: float) -> float:
    """|a - b| wrapped to [0, pi]."""
    return abs(math.remainder(a_rad - b_rad, 2.0 * math.pi))
