"""Frenet reference path: a C² arc-length parametrisation of a lane centreline polyline.

Construction (``FrenetPath.from_polyline``), built once per route
-----------------------------------------------------------------
SUMO lane shapes are polylines with kinks (small heading jumps at vertices and at
junction internal lanes), so the tangent angle of the raw polyline is a step
function. We smooth it, then interpolate exactly:

1. The polyline is extended by straight segments at both ends (``_PAD_BACK_M``
   before the start, ``_PAD_FWD_M`` after the end) and resampled at a uniform
   arc-length spacing ``h = spacing_m``.
2. The heading of every resampled chord, phi_{k+1/2} (unwrapped), is convolved with
   a Gaussian of standard deviation ``smoothing_m`` (default 4 m). Convolving a
   heading that is linear in s (a circular arc) returns it unchanged, so arcs keep
   their curvature; a kink of angle alpha becomes a smooth turn with peak
   curvature alpha / (sqrt(2 pi) smoothing_m) (0.052 rad -> 0.0052 1/m at 4 m)
   that cuts the corner by about 0.4 alpha smoothing_m (0.08 m for 3 degrees).
3. gamma, kappa = gamma', kappa' at the knots s_k = s_0 + k h come from the
   smoothed heading and second-order finite differences of it, and a *quintic
   Hermite* polynomial in s interpolates (gamma, kappa, kappa') on every knot
   interval. Hence gamma is C², and kappa(s), kappa'(s) returned are the exact
   first and second derivatives of gamma(s) everywhere (which the hand-derived
   OCP derivatives rely on).
4. Positions are the exact integral of the tangent: x(s) = x_k + int cos(gamma),
   y(s) = y_k + int sin(gamma), by 4-point Gauss-Legendre quadrature per interval
   (error ~1e-12 m for 1 m intervals). The knot positions are accumulated from the
   start point, so the path is continuous and consistent with gamma.

Tolerance to the input polyline: on smooth polylines (arcs sampled every <= 5 m,
radius >= 100 m) the distance of the input vertices to the path is a few cm; at a
kink of angle alpha it is about 0.4 alpha smoothing_m (tested: <= 0.15 m for a
3 degree kink, curvature bounded by 0.006 1/m). ``max_deviation_m`` on the built
path records the measured maximum over the input vertices.

s = 0 is the first input vertex; ``length_m`` is the resampled polyline length.
Beyond the padded tables the path is extrapolated straight (gamma constant,
kappa = kappa' = 0); since the padding is straight, this is C² as well. Within
[-_PAD_BACK_M, length_m + _PAD_FWD_M] the smoothed straight padding is used.

Compiled evaluation: :meth:`FrenetPath.tables` returns ``(meta, coef, knot_xy)``
(see :func:`path_gamma`), which numba kernels use directly.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict

import numba
import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import cKDTree

_PAD_BACK_M = 60.0
_PAD_FWD_M = 300.0

# Gauss-Legendre nodes/weights on [0, 1] (4 points, exact to degree 7).
_GL_X = np.array([0.0694318442029737, 0.3300094782075719, 0.6699905217924281,
                  0.9305681557970263])
_GL_W = np.array([0.1739274225687269, 0.3260725774312731, 0.3260725774312731,
                  0.1739274225687269])


@numba.njit(cache=True, inline="always")
def path_gamma(meta: np.ndarray, coef: np.ndarray, s: float) -> tuple[float, float, float]:
    """(gamma(s) [rad], kappa(s) [1/m], kappa'(s) [1/m²]) from the packed tables.

    meta = [s0_m, h_m, n_seg, length_m]; coef (n_seg, 6): gamma on knot interval k
    is sum_i coef[k, i] u^i with u = s - (s0 + k h) in [0, h]. Outside the tables
    the path is straight: gamma held, kappa = kappa' = 0.
    """
    s0 = meta[0]
    h = meta[1]
    n = int(meta[2])
    r = (s - s0) / h
    if r < 0.0:
        return coef[0, 0], 0.0, 0.0
    k = int(r)
    if k >= n:
        c = coef[n - 1]
        return c[0] + h * (c[1] + h * (c[2] + h * (c[3] + h * (c[4] + h * c[5])))), 0.0, 0.0
    c = coef[k]
    u = s - (s0 + k * h)
    g = c[0] + u * (c[1] + u * (c[2] + u * (c[3] + u * (c[4] + u * c[5]))))
    dg = c[1] + u * (2.0 * c[2] + u * (3.0 * c[3] + u * (4.0 * c[4] + u * 5.0 * c[5])))
    ddg = 2.0 * c[2] + u * (6.0 * c[3] + u * (12.0 * c[4] + u * 20.0 * c[5]))
    return g, dg, ddg


@numba.njit(cache=True)
def path_point(meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray,
               s: float) -> tuple[float, float]:
    """World point (x, y) [m] of the path at arc length s (Gauss-Legendre integral)."""
    s0 = meta[0]
    h = meta[1]
    n = int(meta[2])
    r = (s - s0) / h
    if r < 0.0:
        k = 0
    elif r >= n:
        k = n
    else:
        k = int(r)
    sk = s0 + k * h
    x = knot_xy[k, 0]
    y = knot_xy[k, 1]
    u = s - sk
    if (k == 0 and r < 0.0) or k == n:
        g, _, _ = path_gamma(meta, coef, s)
        return x + u * math.cos(g), y + u * math.sin(g)
    # 4-point Gauss-Legendre on [sk, s].
    w0, w1 = 0.1739274225687269, 0.3260725774312731
    x0, x1 = 0.0694318442029737, 0.3300094782075719
    g1, _, _ = path_gamma(meta, coef, sk + x0 * u)
    g2, _, _ = path_gamma(meta, coef, sk + x1 * u)
    g3, _, _ = path_gamma(meta, coef, sk + (1.0 - x1) * u)
    g4, _, _ = path_gamma(meta, coef, sk + (1.0 - x0) * u)
    x += u * (w0 * math.cos(g1) + w1 * math.cos(g2) + w1 * math.cos(g3) + w0 * math.cos(g4))
    y += u * (w0 * math.sin(g1) + w1 * math.sin(g2) + w1 * math.sin(g3) + w0 * math.sin(g4))
    return x, y


@numba.njit(cache=True)
def path_to_global(meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray,
                   s: float, y: float) -> tuple[float, float]:
    """Frenet (s, y) -> world (X, Y): point(s) + y n(s), n = (-sin gamma, cos gamma)."""
    px, py = path_point(meta, coef, knot_xy, s)
    g, _, _ = path_gamma(meta, coef, s)
    return px - y * math.sin(g), py + y * math.cos(g)


@numba.njit(cache=True)
def path_project_local(meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray,
                       x: float, y: float, s_hint: float) -> tuple[float, float, bool]:
    """Newton projection of (x, y) onto the path starting at s_hint.

    Solves g(s) = (p - r(s)).t(s) = 0 with g'(s) = -(1 - kappa(s) d), d the signed
    normal distance. Returns (s, d, ok); ok is False if Newton did not converge.
    """
    s = s_hint
    for _ in range(12):
        px, py = path_point(meta, coef, knot_xy, s)
        g, k, _ = path_gamma(meta, coef, s)
        tx, ty = math.cos(g), math.sin(g)
        dx, dy = x - px, y - py
        along = dx * tx + dy * ty
        d = -dx * ty + dy * tx
        den = 1.0 - k * d
        if den < 0.2:
            den = 0.2
        step = along / den
        # Limit steps to a few metres so a bad hint cannot jump to a far branch.
        if step > 20.0:
            step = 20.0
        elif step < -20.0:
            step = -20.0
        s += step
        if abs(step) < 1e-9:
            px, py = path_point(meta, coef, knot_xy, s)
            g, k, _ = path_gamma(meta, coef, s)
            d = -(x - px) * math.sin(g) + (y - py) * math.cos(g)
            return s, d, True
    px, py = path_point(meta, coef, knot_xy, s)
    g, k, _ = path_gamma(meta, coef, s)
    along = (x - px) * math.cos(g) + (y - py) * math.sin(g)
    d = -(x - px) * math.sin(g) + (y - py) * math.cos(g)
    return s, d, abs(along) < 1e-6


def _hermite5_coef(h: float, g0: np.ndarray, d0: np.ndarray, dd0: np.ndarray,
                   g1: np.ndarray, d1: np.ndarray, dd1: np.ndarray) -> np.ndarray:
    """Quintic Hermite coefficients (n, 6) matching value/1st/2nd derivative at both ends."""
    delta = g1 - g0 - d0 * h - 0.5 * dd0 * h * h
    dp = d1 - d0 - dd0 * h
    dpp = dd1 - dd0
    c3 = (20.0 * delta - 8.0 * h * dp + h * h * dpp) / (2.0 * h**3)
    c4 = (-30.0 * delta + 14.0 * h * dp - 2.0 * h * h * dpp) / (2.0 * h**4)
    c5 = (12.0 * delta - 6.0 * h * dp + h * h * dpp) / (2.0 * h**5)
    return np.stack([g0, d0, 0.5 * dd0, c3, c4, c5], axis=1)


def _resample(xy: np.ndarray, spacing: float) -> tuple[np.ndarray, float]:
    seg = np.diff(xy, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    keep = np.concatenate([[True], seg_len > 1e-9])
    xy = xy[keep]
    seg = np.diff(xy, axis=0)
    seg_len = np.hypot(seg[:, 0], seg[:, 1])
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    total = float(cum[-1])
    n = max(int(round(total / spacing)), 1)
    sq = np.linspace(0.0, total, n + 1)
    out = np.column_stack([np.interp(sq, cum, xy[:, 0]), np.interp(sq, cum, xy[:, 1])])
    return out, total


class FrenetPath:
    """C² reference path with exact gamma, kappa, kappa' (see module docstring)."""

    _cache: OrderedDict[str, FrenetPath] = OrderedDict()

    def __init__(self, meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray,
                 length_m: float, smoothing_m: float, source_xy: np.ndarray) -> None:
        self._meta = meta
        self._coef = coef
        self._knot_xy = knot_xy
        self.length_m = float(length_m)
        self.smoothing_m = float(smoothing_m)
        self._tree = cKDTree(knot_xy)
        self._knot_s = meta[0] + meta[1] * np.arange(knot_xy.shape[0])
        self.source_xy = source_xy
        s_src, d_src = self.project(source_xy[:, 0], source_xy[:, 1])
        inside = (s_src > 1e-6) & (s_src < self.length_m - 1e-6)
        self.max_deviation_m = float(np.max(np.abs(d_src[inside]))) if np.any(inside) else 0.0

    # ------------------------------------------------------------------ build
    @classmethod
    def from_polyline(cls, xy_m: np.ndarray, spacing_m: float = 1.0,
                      smoothing_m: float = 4.0) -> FrenetPath:
        """Build from an (M, 2) polyline in driving order [m]; see module docstring."""
        xy = np.asarray(xy_m, dtype=np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2 or xy.shape[0] < 2 or not np.all(np.isfinite(xy)):
            raise ValueError(f"polyline must be finite with shape (M>=2, 2), got {xy.shape}")
        if not (spacing_m > 0 and math.isfinite(spacing_m)):
            raise ValueError(f"spacing_m must be > 0, got {spacing_m}")
        if not (smoothing_m > 0 and math.isfinite(smoothing_m)):
            raise ValueError(f"smoothing_m must be > 0, got {smoothing_m}")
        h = float(spacing_m)
        pts, total = _resample(xy, h)
        if total < 1e-6:
            raise ValueError("polyline has zero length")
        h = total / (pts.shape[0] - 1)  # exact spacing over the polyline
        # Straight padding along the first / last chord directions.
        d_start = pts[1] - pts[0]
        d_start /= np.hypot(*d_start)
        d_end = pts[-1] - pts[-2]
        d_end /= np.hypot(*d_end)
        n_back = int(math.ceil(_PAD_BACK_M / h))
        n_fwd = int(math.ceil(_PAD_FWD_M / h))
        back = pts[0] - d_start * h * np.arange(n_back, 0, -1)[:, None]
        fwd = pts[-1] + d_end * h * np.arange(1, n_fwd + 1)[:, None]
        allp = np.vstack([back, pts, fwd])
        chords = np.diff(allp, axis=0)
        phi = np.unwrap(np.arctan2(chords[:, 1], chords[:, 0]))  # at chord midpoints
        sigma = smoothing_m / h
        phi_s = gaussian_filter1d(phi, sigma, mode="nearest", truncate=5.0)
        # Knot headings at vertices: mean of the adjacent chord headings.
        gam = np.empty(allp.shape[0])
        gam[1:-1] = 0.5 * (phi_s[:-1] + phi_s[1:])
        gam[0] = phi_s[0]
        gam[-1] = phi_s[-1]
        kap = np.gradient(gam, h, edge_order=2)
        dkap = np.gradient(kap, h, edge_order=2)
        # The straight ends must be exactly straight for the C² extrapolation.
        edge = max(int(5 * sigma) + 2, 2)
        kap[:edge // 4 + 1] = 0.0
        dkap[:edge // 4 + 1] = 0.0
        kap[-(edge // 4 + 1):] = 0.0
        dkap[-(edge // 4 + 1):] = 0.0
        coef = _hermite5_coef(h, gam[:-1], kap[:-1], dkap[:-1], gam[1:], kap[1:], dkap[1:])
        s0 = -n_back * h
        n_seg = coef.shape[0]
        meta = np.array([s0, h, float(n_seg), total])
        # Integrate positions knot to knot; anchor s = 0 at the first input vertex.
        knot_xy = np.empty((n_seg + 1, 2))
        knot_xy[0] = 0.0
        u = _GL_X * h
        powers = np.stack([u**i for i in range(6)])  # (6, 4)
        gq = coef @ powers  # (n_seg, 4)
        knot_xy[1:, 0] = np.cumsum(h * (np.cos(gq) @ _GL_W))
        knot_xy[1:, 1] = np.cumsum(h * (np.sin(gq) @ _GL_W))
        knot_xy += pts[0] - knot_xy[n_back]
        return cls(meta, coef, knot_xy, total, smoothing_m, xy.copy())

    @classmethod
    def cached(cls, xy_m: np.ndarray, spacing_m: float = 1.0,
               smoothing_m: float = 4.0) -> FrenetPath:
        """Like :meth:`from_polyline`, memoised by the polyline's bytes (16 most recent)."""
        xy = np.ascontiguousarray(np.asarray(xy_m, dtype=np.float64))
        key = hashlib.sha1(xy.tobytes() + repr((xy.shape, spacing_m, smoothing_m)).encode())
        digest = key.hexdigest()
        hit = cls._cache.get(digest)
        if hit is not None:
            cls._cache.move_to_end(digest)
            return hit
        path = cls.from_polyline(xy, spacing_m, smoothing_m)
        cls._cache[digest] = path
        while len(cls._cache) > 16:
            cls._cache.popitem(last=False)
        return path

    # ------------------------------------------------------------ evaluation
    def tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(meta (4,), coef (n_seg, 6), knot_xy (n_seg+1, 2)) for the compiled kernels."""
        return self._meta, self._coef, self._knot_xy

    def _gk(self, s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s_arr = np.asarray(s, dtype=np.float64)
        s0, h, n = self._meta[0], self._meta[1], int(self._meta[2])
        r = (s_arr - s0) / h
        k = np.clip(np.floor(r).astype(np.int64), 0, n - 1)
        u = s_arr - (s0 + k * h)
        c = self._coef[k]
        g = c[..., 0] + u * (c[..., 1] + u * (c[..., 2] + u * (c[..., 3] + u * (c[..., 4]
                                                                           + u * c[..., 5]))))
        dg = c[..., 1] + u * (2 * c[..., 2] + u * (3 * c[..., 3] + u * (4 * c[..., 4]
                                                                       + u * 5 * c[..., 5])))
        ddg = 2 * c[..., 2] + u * (6 * c[..., 3] + u * (12 * c[..., 4] + u * 20 * c[..., 5]))
        lo = r < 0
        hi = r >= n
        g = np.where(lo, self._coef[0, 0], g)
        g_end = float(np.polyval(self._coef[-1, ::-1], h))
        g = np.where(hi, g_end, g)
        dg = np.where(lo | hi, 0.0, dg)
        ddg = np.where(lo | hi, 0.0, ddg)
        return g, dg, ddg

    def gamma(self, s: np.ndarray | float) -> np.ndarray:
        """Tangent angle [rad], CCW from +X, continuous (unwrapped) in s."""
        s_arr = np.asarray(s, dtype=np.float64)
        out = np.empty(s_arr.size)
        _gamma_many(self._meta, self._coef, s_arr.reshape(-1).copy(), out)
        return out.reshape(s_arr.shape)

    def kappa(self, s: np.ndarray | float) -> np.ndarray:
        """Signed curvature d gamma / ds [1/m] (positive turning left); one compiled pass
        of :func:`path_gamma` (the numbers of the array form ``_gk`` bit for bit,
        tests/test_frenet.py), since the behaviour asks for it inside control steps."""
        s_arr = np.asarray(s, dtype=np.float64)
        out = np.empty(s_arr.size)
        _kappa_many(self._meta, self._coef, s_arr.reshape(-1).copy(), out)
        return out.reshape(s_arr.shape)

    def dkappa(self, s: np.ndarray | float) -> np.ndarray:
        """d kappa / ds [1/m²]."""
        return self._gk(s)[2]

    def point(self, s: np.ndarray | float) -> np.ndarray:
        """World point(s) on the path, shape s.shape + (2,) [m]."""
        s_arr = np.asarray(s, dtype=np.float64)
        flat = s_arr.reshape(-1)
        out = np.empty((flat.shape[0], 2))
        _points_many(self._meta, self._coef, self._knot_xy, flat, np.zeros_like(flat), out)
        return out.reshape(s_arr.shape + (2,))

    def to_global(self, s: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray,
                                                                              np.ndarray]:
        """Frenet (s, y) -> world (X, Y) [m]; y positive to the left of the path."""
        s_arr, y_arr = np.broadcast_arrays(np.asarray(s, dtype=np.float64),
                                           np.asarray(y, dtype=np.float64))
        out = np.empty((s_arr.size, 2))
        _points_many(self._meta, self._coef, self._knot_xy, s_arr.reshape(-1).copy(),
                     y_arr.reshape(-1).copy(), out)
        return out[:, 0].reshape(s_arr.shape), out[:, 1].reshape(s_arr.shape)

    def project(self, x: np.ndarray | float, y: np.ndarray | float,
                s_hint: np.ndarray | float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) -> Frenet (s, y_lat).

        With ``s_hint``: Newton from the hint (local, ~2 µs); if it fails to converge
        or lands more than 50 m from the hint, fall back to the global search
        (nearest knot by k-d tree, then Newton).
        """
        x_arr, y_arr = np.broadcast_arrays(np.asarray(x, dtype=np.float64),
                                           np.asarray(y, dtype=np.float64))
        xf = x_arr.reshape(-1).copy()
        yf = y_arr.reshape(-1).copy()
        s_out = np.empty(xf.shape[0])
        d_out = np.empty(xf.shape[0])
        if s_hint is None:
            need = np.ones(xf.shape[0], dtype=np.bool_)
        else:
            hints = np.broadcast_to(np.asarray(s_hint, dtype=np.float64), x_arr.shape)
            hints = hints.reshape(-1).copy()
            need = _project_many(self._meta, self._coef, self._knot_xy, xf, yf, hints,
                                 s_out, d_out)
        if np.any(need):
            _, idx = self._tree.query(np.column_stack([xf[need], yf[need]]))
            hints2 = self._knot_s[idx]
            s2 = np.empty(hints2.shape[0])
            d2 = np.empty(hints2.shape[0])
            _project_many(self._meta, self._coef, self._knot_xy, xf[need].copy(),
                          yf[need].copy(), hints2, s2, d2)
            s_out[need] = s2
            d_out[need] = d2
        return s_out.reshape(x_arr.shape), d_out.reshape(x_arr.shape)

    def project_along(self, x: np.ndarray, y: np.ndarray, x_ref: float, y_ref: float,
                      s_ref: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Project many points near a known one: (s, y_lat, gamma(s)), arrays (n,).

        Each point's Newton projection starts from s_ref plus its displacement from
        (x_ref, y_ref) along the tangent at s_ref (a good hint hundreds of metres
        out on highway curves, so the k-d tree fallback is rarely needed), and the
        tangent angle of the result comes from the same compiled pass (one kernel call
        for the hints, the projections and the angles: the behaviour calls this every
        control step; the points it does not converge for go the general way).
        """
        xf = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
        yf = np.ascontiguousarray(y, dtype=np.float64).reshape(-1)
        g0 = path_gamma(self._meta, self._coef, float(s_ref))[0]  # what gamma() evaluates
        # numpy's cos/sin, as the hints have always used (libm's may differ in the last bit)
        cos_g0, sin_g0 = float(np.cos(g0)), float(np.sin(g0))
        s_out, d_out, g_out = np.empty(xf.size), np.empty(xf.size), np.empty(xf.size)
        need = _project_along_many(self._meta, self._coef, self._knot_xy, xf, yf,
                                   float(x_ref), float(y_ref), float(s_ref), cos_g0, sin_g0,
                                   s_out, d_out, g_out)
        if np.count_nonzero(need):  # C call: ndarray.any() goes through Python wrappers
            s2, d2 = self.project(xf[need], yf[need])
            s_out[need], d_out[need] = s2, d2
            g_out[need] = self.gamma(s2)
        return s_out, d_out, g_out

    def project_pose(self, x: np.ndarray | float, y: np.ndarray | float,
                     heading: np.ndarray | float,
                     s_hint: np.ndarray | float | None = None,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(s, y_lat, heading_error); heading_error = heading - gamma(s) wrapped to (-pi, pi].

        One pose with a hint (the run loop's ego, every control step) takes the same
        compiled kernels without the array wrapping (bit-identical results); anything
        else, or a hint Newton does not converge from, goes the general way."""
        if s_hint is not None and all(isinstance(v, (float, np.floating))
                                      for v in (x, y, heading, s_hint)):
            sf, df, ok = path_project_local(self._meta, self._coef, self._knot_xy,
                                            float(x), float(y), float(s_hint))
            if ok and abs(sf - float(s_hint)) <= 50.0:
                g = path_gamma(self._meta, self._coef, sf)[0]
                e = (float(heading) - g + np.pi) % (2 * np.pi) - np.pi
                return np.asarray(sf), np.asarray(df), np.asarray(e)
        s, d = self.project(x, y, s_hint)
        err = np.asarray(heading, dtype=np.float64) - self.gamma(s)
        err = (err + np.pi) % (2 * np.pi) - np.pi
        return s, d, err


@numba.njit(cache=True)
def _project_along_many(meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray,
                        x: np.ndarray, y: np.ndarray, x_ref: float, y_ref: float,
                        s_ref: float, cos_g0: float, sin_g0: float, s_out: np.ndarray,
                        d_out: np.ndarray, g_out: np.ndarray) -> np.ndarray:
    """Newton projections of (x_i, y_i) from the hints s_ref + (x_i - x_ref) cos g0 +
    (y_i - y_ref) sin g0, with gamma at the results; returns the (n,) mask of the points
    that need the global search (no convergence, or > 50 m from the hint)."""
    need = np.zeros(x.shape[0], dtype=np.bool_)
    for i in range(x.shape[0]):
        hint = s_ref + (x[i] - x_ref) * cos_g0 + (y[i] - y_ref) * sin_g0
        s, d, ok = path_project_local(meta, coef, knot_xy, x[i], y[i], hint)
        s_out[i] = s
        d_out[i] = d
        g_out[i] = path_gamma(meta, coef, s)[0]
        if not ok or abs(s - hint) > 50.0:
            need[i] = True
    return need


@numba.njit(cache=True)
def _gamma_many(meta: np.ndarray, coef: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    for i in range(s.shape[0]):
        out[i] = path_gamma(meta, coef, s[i])[0]


@numba.njit(cache=True)
def _kappa_many(meta: np.ndarray, coef: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """kappa at every s: NaN for NaN, 0 beyond the tables (inf included) as ``_gk``."""
    for i in range(s.shape[0]):
        x = s[i]
        if x != x:
            out[i] = np.nan
        elif not (x - meta[0]) / meta[1] < meta[2]:  # beyond the end (before int())
            out[i] = 0.0
        else:
            out[i] = path_gamma(meta, coef, x)[1]


@numba.njit(cache=True)
def _points_many(meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray, s: np.ndarray,
                 y: np.ndarray, out: np.ndarray) -> None:
    for i in range(s.shape[0]):
        gx, gy = path_to_global(meta, coef, knot_xy, s[i], y[i])
        out[i, 0] = gx
        out[i, 1] = gy


@numba.njit(cache=True)
def _project_many(meta: np.ndarray, coef: np.ndarray, knot_xy: np.ndarray, x: np.ndarray,
                  y: np.ndarray, hints: np.ndarray, s_out: np.ndarray,
                  d_out: np.ndarray) -> np.ndarray:
    need = np.zeros(x.shape[0], dtype=np.bool_)
    for i in range(x.shape[0]):
        s, d, ok = path_project_local(meta, coef, knot_xy, x[i], y[i], hints[i])
        s_out[i] = s
        d_out[i] = d
        if not ok or abs(s - hints[i]) > 50.0:
            need[i] = True
    return need
