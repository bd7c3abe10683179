"""Points in the Frenet frame of a polyline (:func:`polyline_frenet`): arc length and
signed offset of the nearest foot, the tangent angle and curvature there, for predicting
traffic along the road (the TTC of ``reports.metrics.ttc``). One compiled call."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

_NAN = math.nan

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
