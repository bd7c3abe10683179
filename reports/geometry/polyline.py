"""Polylines: length, cumulative arc length, resampling, and the projection of points.

For a polyline p_0..p_{m-1} and a point q, the projection is the nearest point on any
segment: t_i = clamp(((q - p_i) . d_i) / |d_i|^2, 0, 1) with d_i = p_{i+1} - p_i. It
gives the arc length ``s_m`` of that point, the unsigned distance ``distance_m``, the
signed lateral offset ``lateral_m`` (left of the direction of travel > 0: the z
component of d_i x (q - p_i), over |d_i|) and the segment heading ``heading_rad``
(:func:`project`). :func:`project_points` does the same for k points at once (the foot
points, and whether each foot is an end of the polyline: the point lies beyond it, not
beside it).

:func:`polyline_length_m` sums the segments (numpy's pairwise sum);
:func:`arc_lengths_m` is the running sum from 0 (its last entry may differ from the
length in the last bit). The Frenet frame of a long reference, compiled, is
:func:`reports.geometry.frenet.polyline_frenet`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def polyline_length_m(xy: FloatArray) -> float:
    """Length [m] of a polyline (m, 2): the sum of its segments (0 below two points)."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    return float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) if len(pts) > 1 else 0.0


def segment_lengths_m(xy: FloatArray) -> FloatArray:
    """Lengths [m] of the m - 1 segments of a polyline (m, 2), m >= 1."""
    out: FloatArray = np.hypot(*np.diff(np.asarray(xy, dtype=np.float64), axis=0).T)
    return out


def arc_lengths_m(xy: FloatArray) -> FloatArray:
    """Cumulative arc length (m,) [m] of a polyline (m, 2), starting at 0 (empty for no
    point)."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if pts.shape[0] == 0:
        return np.zeros(0)
    seg = np.hypot(*np.diff(pts, axis=0).T) if pts.shape[0] > 1 else np.zeros(0)
    return np.concatenate([[0.0], np.cumsum(seg)])


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
    cum = arc_lengths_m(pts)
    s = np.asarray(fractions, dtype=np.float64) * cum[-1]
    return np.column_stack([np.interp(s, cum, pts[:, 0]), np.interp(s, cum, pts[:, 1])])


def angle_diff_rad(a_rad: float, b_rad: float) -> float:
    """|a - b| wrapped to [0, pi]."""
    return abs(math.remainder(a_rad - b_rad, 2.0 * math.pi))


@dataclass(frozen=True, eq=False)
class Feet:
    """Projections of k points on one polyline: arc length of each foot ``s_m`` (k,),
    the feet ``xy_m`` (k, 2), the distances ``distance_m`` (k,) [m], and ``at_end``
    (k,): the foot is the polyline's first or last point (the point lies beyond an end)."""

    s_m: FloatArray
    xy_m: FloatArray
    distance_m: FloatArray
    at_end: npt.NDArray[np.bool_]


def project_points(xy: FloatArray, points: FloatArray) -> Feet:
    """Project every point of ``points`` (k, 2) onto the polyline ``xy`` (m, 2), m >= 2
    (module docstring): (k, m - 1) arrays, one numpy pass."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    q = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    d = np.diff(pts, axis=0)
    seg2 = np.einsum("ij,ij->i", d, d)
    rel = q[:, None, :] - pts[None, :-1, :]
    t = np.clip(np.einsum("kij,ij->ki", rel, d) / np.where(seg2 > 0, seg2, 1.0), 0.0, 1.0)
    foot = pts[None, :-1, :] + t[:, :, None] * d[None, :, :]
    dist = np.hypot(q[:, None, 0] - foot[:, :, 0], q[:, None, 1] - foot[:, :, 1])
    i = np.argmin(dist, axis=1)
    k = np.arange(q.shape[0])
    ti = t[k, i]
    seg = np.sqrt(seg2)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    at_end = ((i == 0) & (ti <= 0.0)) | ((i == len(d) - 1) & (ti >= 1.0))
    return Feet(np.asarray(cum[i] + ti * seg[i], dtype=np.float64),
                np.asarray(foot[k, i], dtype=np.float64),
                np.asarray(dist[k, i], dtype=np.float64), np.asarray(at_end, dtype=np.bool_))


def end_heading_rad(xy: FloatArray, at_end: bool, span_m: float = 5.0) -> float:
    """Direction [rad] of a polyline at its end (``at_end``) or start: of the chord over
    its last (first) ``span_m`` of arc length (the whole polyline when shorter), so that
    a millimetre-long last segment does not decide it."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    length = polyline_length_m(pts)
    f = min(span_m / length, 1.0) if length > 0.0 else 1.0
    a, b = resample(pts, np.array([1.0 - f, 1.0]) if at_end else np.array([0.0, f]))
    return math.atan2(float(b[1] - a[1]), float(b[0] - a[0]))
