"""Polyline geometry: project a point onto a polyline; a lanelet's width and its bounds
paired vertex to vertex.

For a polyline p_0..p_{m-1} and a point q, the projection is the nearest point on any
segment: t_i = clamp(((q - p_i) . d_i) / |d_i|^2, 0, 1) with d_i = p_{i+1} - p_i. It
gives the arc length ``s_m`` of that point, the unsigned distance ``distance_m``, the
signed lateral offset ``lateral_m`` (left of the direction of travel > 0: the z
component of d_i x (q - p_i), over |d_i|) and the segment heading ``heading_rad``.
:func:`project_points` does the same for k points at once (the foot points, and whether
each foot is an end of the polyline: the point lies beyond it, not beside it).

**Width** (:func:`bound_width_m`): the median perpendicular distance between the two
bounds. Each bound is resampled every :data:`WIDTH_SAMPLE_M` of its arc length; each
sample's distance to the *other* bound's polyline counts where its foot falls inside that
polyline (beyond the other bound's ends a distance measures where the bounds end, not how
far apart they are). Pairing the i-th left with the i-th right vertex instead measures a
diagonal wherever the vertices are not opposite (exiD: 20.11 m for a 3.87 m lane).

**Pairing** (:func:`pair_bounds`): CommonRoad's centre line is the mean of the i-th left
and i-th right vertex, right only when they are opposite. Bounds whose interior pairs are
more than :data:`PAIR_SKEW_TOL_M` apart along the road (:func:`pair_skew_m`), or of
different vertex counts, are re-paired: the two end pairs stay (they delimit the
lanelet), and inside every vertex of each bound is paired with its foot on the other
bound (where that foot lies inside it), the pairs ordered along both bounds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["PAIR_SKEW_TOL_M", "WIDTH_SAMPLE_M", "Feet", "FloatArray", "Projection",
           "angle_diff_rad", "bound_width_m", "end_heading_rad", "pair_bounds", "pair_skew_m",
           "polyline_length_m", "project", "project_points", "resample"]

WIDTH_SAMPLE_M = 1.0
"""Bounds are sampled this densely [m of arc length] to measure a lanelet's width."""

MIN_WIDTH_SAMPLES = 11
MAX_WIDTH_SAMPLES = 400

PAIR_SKEW_TOL_M = 0.5
"""Interior vertex pairs farther apart than this along the road [m] are re-paired."""

_SAME_M = 1e-3  # points closer than this [m] are one point

FloatArray = npt.NDArray[np.float64]


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


def _samples(xy: FloatArray) -> FloatArray:
    """Points every :data:`WIDTH_SAMPLE_M` of arc length (ends included, within
    [MIN_WIDTH_SAMPLES, MAX_WIDTH_SAMPLES] points)."""
    n = int(np.clip(math.ceil(polyline_length_m(xy) / WIDTH_SAMPLE_M) + 1,
                    MIN_WIDTH_SAMPLES, MAX_WIDTH_SAMPLES))
    return resample(xy, np.linspace(0.0, 1.0, n))


def bound_width_m(left: FloatArray, right: FloatArray) -> float:
    """A lanelet's width [m]: the median perpendicular distance between its bounds
    (module docstring); any vertex counts and spacings. Bounds with no sample beside the
    other bound (they do not overlap along the road): the median of every distance."""
    lf = project_points(right, _samples(left))
    rf = project_points(left, _samples(right))
    dist = np.concatenate([lf.distance_m, rf.distance_m])
    inside = ~np.concatenate([lf.at_end, rf.at_end])
    return float(np.median(dist[inside] if np.any(inside) else dist))


def pair_skew_m(left: FloatArray, right: FloatArray) -> float:
    """How far apart along the road the interior vertex pairs are at most [m]: |(l_i -
    r_i) . u_i|, u_i the unit tangent of the vertex-mean centre line at i; ``inf`` for
    bounds of different vertex counts (they have no pairs)."""
    lf = np.asarray(left, dtype=np.float64).reshape(-1, 2)
    rt = np.asarray(right, dtype=np.float64).reshape(-1, 2)
    if lf.shape != rt.shape:
        return math.inf
    if lf.shape[0] < 3:
        return 0.0
    tangent = np.gradient(0.5 * (lf + rt), axis=0)
    norm = np.hypot(*tangent.T)
    ok = norm[1:-1] > 0.0
    along = np.einsum("ij,ij->i", (lf - rt)[1:-1], tangent[1:-1]) / np.where(ok, norm[1:-1],
                                                                             1.0)
    return float(np.max(np.abs(along[ok]), initial=0.0))


def pair_bounds(left: FloatArray, right: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Bounds (n, 2) and (n, 2) whose i-th vertices are opposite (module docstring)."""
    lf = np.asarray(left, dtype=np.float64).reshape(-1, 2)
    rt = np.asarray(right, dtype=np.float64).reshape(-1, 2)
    len_l, len_r = polyline_length_m(lf), polyline_length_m(rt)
    on_r = project_points(rt, lf[1:-1])
    on_l = project_points(lf, rt[1:-1])
    cum_l = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(lf, axis=0).T))])
    cum_r = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(rt, axis=0).T))])
    cand = [(float(sl), float(sr), pl, pr) for sl, sr, pl, pr, end in zip(
        cum_l[1:-1], on_r.s_m, lf[1:-1], on_r.xy_m, on_r.at_end, strict=True) if not end]
    cand += [(float(sl), float(sr), pl, pr) for sl, sr, pl, pr, end in zip(
        on_l.s_m, cum_r[1:-1], on_l.xy_m, rt[1:-1], on_l.at_end, strict=True) if not end]
    cand.sort(key=lambda c: c[0] / max(len_l, _SAME_M) + c[1] / max(len_r, _SAME_M))
    out_l, out_r = [lf[0]], [rt[0]]
    last = (0.0, 0.0)
    for sl, sr, pl, pr in cand:
        # a pair stepping back along either bound would fold the lanelet
        if sl < last[0] or sr < last[1] or max(sl - last[0], sr - last[1]) <= _SAME_M:
            continue
        if len_l - sl <= _SAME_M and len_r - sr <= _SAME_M:
            continue  # the end pair follows
        out_l.append(pl)
        out_r.append(pr)
        last = (sl, sr)
    out_l.append(lf[-1])
    out_r.append(rt[-1])
    return np.asarray(out_l, dtype=np.float64), np.asarray(out_r, dtype=np.float64)


def end_heading_rad(xy: FloatArray, at_end: bool, span_m: float = 5.0) -> float:
    """Direction [rad] of a polyline at its end (``at_end``) or start: of the chord over
    its last (first) ``span_m`` of arc length (the whole polyline when shorter), so that
    a millimetre-long last segment does not decide it."""
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    length = polyline_length_m(pts)
    f = min(span_m / length, 1.0) if length > 0.0 else 1.0
    a, b = resample(pts, np.array([1.0 - f, 1.0]) if at_end else np.array([0.0, f]))
    return math.atan2(float(b[1] - a[1]), float(b[0] - a[0]))
