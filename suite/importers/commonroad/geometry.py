"""Lanelet bounds: a lanelet's width and its bounds paired vertex to vertex.

The polyline projection these use (:func:`project`, :func:`project_points`,
:func:`resample`, :func:`polyline_length_m`, ...) lives in the one home of geometry,
:mod:`reports.geometry.polyline`, and is re-exported here for the importer's modules.

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

import numpy as np

from reports.geometry.polyline import (
    Feet,
    FloatArray,
    Projection,
    angle_diff_rad,
    arc_lengths_m,
    end_heading_rad,
    polyline_length_m,
    project,
    project_points,
    resample,
)

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
    cum_l, cum_r = arc_lengths_m(lf), arc_lengths_m(rt)
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
