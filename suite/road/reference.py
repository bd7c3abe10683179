"""The reference path's geometry: the smoothest curve that stays within a tube around
the lane polyline.

SUMO moves its vehicles along lane polylines whose heading steps at every vertex (OSM
nets: vertices 30-250 m apart turning up to ~7°), and junction internal lanes carry
netconvert's S-jogs. The reference the controller tracks must be smooth (finite,
physically meaningful curvature) and yet stay where SUMO has the lane, or the ego ends
up beside SUMO's lane (wrong lane, false off-road). So the reference is the solution of

    min  sum_k |C_{k-1} - 2 C_k + C_{k+1}|^2 + w3 sum_k |third difference of C|^2
         + w_off sum_k o_k^2
    s.t. C_k = P_k + o_k n_k,   |o_k| <= d_k

where P_k are the polyline resampled every ``spacing_m`` (1 m), n_k its unit normals,
o_k the lateral offsets (the unknowns) and d_k the tube's half-width: ``lane_tube_m``
(0.10 m) on lanes, ``junction_tube_m`` across junction interiors (whose jogs are not
the road). The second differences are h² times the curvature, so this is the
minimum-curvature-energy curve inside the tube; the third-difference term makes the
curvature itself change gradually (clothoid-like onsets), the small ``w_off`` keeps the
problem strictly convex and the curve centred where the tube does not bind. At a kink of
angle alpha the tube forces a radius of about 8 d / alpha² (d = 0.10 m: 5° -> R 105 m,
2° -> 660 m): no curve within 0.10 m of SUMO's lane turns more gently, and the solution
turns no more sharply than that (docs/road.md has the figures on the bundled and real
nets).

The box-constrained QP (banded Hessian) is solved by a primal active-set method with
sparse LU solves (:func:`box_qp`): exact, a few milliseconds per kilometre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.ndimage import gaussian_filter1d

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class TubeParams:
    """spacing_m [m]: resampling step; lane_tube_m / junction_tube_m [m]: the tube's
    half-width on lanes / across junction interiors; w3 [m²]: weight of curvature
    change against curvature; w_off [1/m²]: weight of staying centred.

    A lane whose next lane starts laterally offset by jog d (netconvert moves lane
    centres by half a lane where an edge gains or loses one, and draws the internal lane
    as an S-jog) gets a *jog zone*: over sqrt(jog_radius_m |d|) [m] before and after the
    junction the tube widens to |d| + lane_tube_m, so the reference crosses from one lane
    centre to the other as an S of radius about ``jog_radius_m`` instead of jogging.
    Jogs below ``jog_min_m`` [m] are left to the junction tube.

    Digitising kinks (:func:`smooth_within_support`): the reference's curvature is bounded
    by what the polyline's overall geometry supports, ``support_margin`` x the largest
    Menger curvature of the polyline over arms ``support_arms_m`` [m] plus
    ``support_slack_per_m`` [1/m]; where the curve bends more, the tube is doubled
    over ``kink_reach_m`` [m] around the spot, up to ``kink_tube_max_m`` [m], at most
    ``kink_passes`` times."""

    spacing_m: float = 1.0
    lane_tube_m: float = 0.10
    junction_tube_m: float = 0.60
    w3: float = 10.0
    w_off: float = 1e-4
    jog_radius_m: float = 1000.0
    jog_min_m: float = 0.15
    base_smoothing_m: float = 15.0
    kink_tube_max_m: float = 0.8
    support_arms_m: tuple[float, ...] = (75.0, 150.0)
    support_margin: float = 1.25
    support_slack_per_m: float = 1.0 / 3000.0
    kink_reach_m: float = 40.0
    kink_passes: int = 5

    def __post_init__(self) -> None:
        if not (self.support_arms_m and all(
                isinstance(a, int | float) and math.isfinite(a) and a > 0
                for a in self.support_arms_m)):
            raise ValueError("TubeParams.support_arms_m must be numbers > 0, got "
                             f"{self.support_arms_m!r}")
        if isinstance(self.kink_passes, bool) or not (isinstance(self.kink_passes, int)
                                                      and self.kink_passes >= 0):
            raise ValueError(f"TubeParams.kink_passes must be an int >= 0, got "
                             f"{self.kink_passes!r}")
        for name in ("spacing_m", "lane_tube_m", "junction_tube_m", "w3", "w_off",
                     "jog_radius_m", "jog_min_m", "base_smoothing_m", "kink_tube_max_m",
                     "support_margin", "support_slack_per_m", "kink_reach_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, int | float) and math.isfinite(v)
                                           and v > 0):
                raise ValueError(f"TubeParams.{name} must be a finite number > 0, got {v!r}")


@dataclass(frozen=True)
class Resampled:
    """A polyline resampled at a uniform spacing: points (n, 2), unit left normals
    (n, 2), arc length (n,) and a flag per point (True: inside a junction)."""

    points: FloatArray
    normals: FloatArray
    s_m: FloatArray
    junction: BoolArray


def resample(poly: FloatArray, spacing_m: float, junction_vertex: BoolArray | None = None
             ) -> Resampled:
    """Resample ``poly`` (M, 2) every ``spacing_m`` (the last step shortened).

    ``junction_vertex`` (M,) marks the vertices of junction interiors; a point is in a
    junction when both ends of its segment are. Normals are the segment's; at a vertex
    (shared by two segments) the bisector of both.
    """
    pts = np.asarray(poly, dtype=np.float64)
    jv = np.zeros(len(pts), dtype=bool) if junction_vertex is None else np.asarray(
        junction_vertex, dtype=bool)
    seg = np.hypot(*np.diff(pts, axis=0).T)
    keep = np.concatenate([[True], seg > 1e-6])
    pts, jv = pts[keep], jv[keep]
    if len(pts) < 2:
        raise ValueError("a reference polyline needs two distinct points")
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(int(math.ceil(cum[-1] / spacing_m)), 2)
    s = np.concatenate([np.arange(n) * (cum[-1] / n), [cum[-1]]])
    idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    frac = (s - cum[idx]) / seg[idx]
    out = pts[idx] + frac[:, None] * (pts[idx + 1] - pts[idx])
    tan = (pts[idx + 1] - pts[idx]) / seg[idx, None]
    at_vertex = (frac < 1e-9) & (idx > 0)
    if np.any(at_vertex):
        prev = (pts[idx[at_vertex]] - pts[idx[at_vertex] - 1]) / seg[idx[at_vertex] - 1, None]
        both = tan[at_vertex] + prev
        tan[at_vertex] = both / np.maximum(np.hypot(*both.T), 1e-12)[:, None]
    normals = np.column_stack([-tan[:, 1], tan[:, 0]])
    junction = jv[idx] & jv[np.minimum(idx + 1, len(jv) - 1)]
    return Resampled(out, normals, s, junction)


def _banded_upper(h: sp.spmatrix, u: int) -> FloatArray:
    """Upper banded storage of a symmetric matrix with bandwidth u (solveh_banded's)."""
    n = h.shape[0]
    ab = np.zeros((u + 1, n))
    dia = sp.dia_matrix(h)
    for offset, row in zip(dia.offsets, dia.data, strict=True):
        if 0 <= offset <= u:
            ab[u - offset, offset:] = row[offset:]
    return ab


def box_qp(hessian: sp.spmatrix, grad: FloatArray, lo: FloatArray, hi: FloatArray,
           bandwidth: int = 3, tol: float = 1e-6, max_iter: int = 20_000) -> FloatArray:
    """min ½ xᵀHx + gᵀx subject to lo <= x <= hi, H banded symmetric positive definite.

    ADMM on x = z, lo <= z <= hi (Boyd et al. 2011, §5): x <- (H + rho I)⁻¹ (rho (z - u)
    - g), z <- clip(x + u), u <- u + x - z, with one banded Cholesky factor reused
    until rho is rebalanced (primal vs dual residual). Stops when both residuals are
    below ``tol`` (in the units of x); returns z, which always satisfies the bounds.
    """
    from scipy.linalg import cho_solve_banded, cholesky_banded

    h = sp.csr_matrix(hessian)
    n = grad.shape[0]
    band = _banded_upper(h, bandwidth)
    rho = max(float(np.mean(h.diagonal())), 1e-9)
    z = np.clip(np.zeros(n), lo, hi)
    u = np.zeros(n)

    def factor(rho: float) -> FloatArray:
        ab = band.copy()
        ab[bandwidth] += rho
        out: FloatArray = cholesky_banded(ab, check_finite=False)
        return out

    chol = factor(rho)
    for it in range(max_iter):
        x = np.asarray(cho_solve_banded((chol, False), rho * (z - u) - grad,
                                        check_finite=False), dtype=np.float64)
        z_prev = z
        z = np.clip(x + u, lo, hi)
        u += x - z
        primal = float(np.max(np.abs(x - z)))
        dual = rho * float(np.max(np.abs(z - z_prev)))
        if primal < tol and dual < tol * rho:
            return z
        if it % 25 == 24 and (primal > 10 * dual / rho or dual / rho > 10 * primal):
            scale = 2.0 if primal > 10 * dual / rho else 0.5
            rho *= scale
            u /= scale
            chol = factor(rho)
    raise RuntimeError(f"box_qp: ADMM did not reach {tol} in {max_iter} iterations")


def _normals(curve: FloatArray) -> FloatArray:
    """Unit left normals of a densely sampled curve (central differences)."""
    tan = np.gradient(curve, axis=0)
    tan /= np.maximum(np.hypot(*tan.T), 1e-12)[:, None]
    return np.column_stack([-tan[:, 1], tan[:, 0]])


def offsets_to_polyline(base: FloatArray, normals: FloatArray, poly: FloatArray,
                         window: int = 40) -> FloatArray:
    """Signed distance along each base normal to the resampled polyline ``poly`` (same
    length as ``base``, point k near point k): the polyline's offset from the base.

    Each base point is projected onto the polyline segments j = clip(k + w, 0, n - 2),
    w in [-window, window), of its index k; the offset along the normal of the nearest
    projection (the first of equals) is returned. Shapes: base, normals, poly (n, 2);
    result (n,) [m].
    """
    out: FloatArray = _offsets_kernel(np.ascontiguousarray(base, dtype=np.float64),
                                      np.ascontiguousarray(normals, dtype=np.float64),
                                      np.ascontiguousarray(poly, dtype=np.float64),
                                      int(window))
    return out


# Compiled: the numpy form gathered (n, 2 window, 2) arrays, 14 ms a call on a 1 km road
# and three calls per run (1 ms compiled; the same operations in the same order, so the
# same numbers bit for bit).
@numba.njit(cache=True)
def _offsets_kernel(base: FloatArray, normals: FloatArray, poly: FloatArray,
                    window: int) -> FloatArray:
    n = base.shape[0]
    out = np.empty(n)
    for k in range(n):
        best = math.inf
        qx = qy = 0.0
        for w in range(-window, window):
            j = min(max(k + w, 0), n - 2)
            ax, ay = poly[j, 0], poly[j, 1]
            abx, aby = poly[j + 1, 0] - ax, poly[j + 1, 1] - ay
            den = max(abx * abx + aby * aby, 1e-12)
            t = min(max(((base[k, 0] - ax) * abx + (base[k, 1] - ay) * aby) / den, 0.0), 1.0)
            nx, ny = ax + t * abx, ay + t * aby
            d = math.hypot(nx - base[k, 0], ny - base[k, 1])
            if d < best:
                best, qx, qy = d, nx, ny
        out[k] = (qx - base[k, 0]) * normals[k, 0] + (qy - base[k, 1]) * normals[k, 1]
    return out


def _solve(base: FloatArray, normals: FloatArray, lo: FloatArray, hi: FloatArray,
           params: TubeParams, centring: FloatArray | None = None) -> FloatArray:
    """Offsets o minimising the bending energy of base + o normals within [lo, hi];
    ``centring`` (n,) scales the stay-centred weight ``w_off`` per point (default 1)."""
    n = len(base)
    d2 = sp.diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(n - 2, n))
    d3 = sp.diags([-1.0, 3.0, -3.0, 1.0], [0, 1, 2, 3], shape=(n - 3, n))
    nx, ny = sp.diags(normals[:, 0]), sp.diags(normals[:, 1])
    w3 = math.sqrt(params.w3) / params.spacing_m  # third differences are h³, second h²
    root = math.sqrt(params.w_off) * (np.ones(n) if centring is None else np.sqrt(centring))
    a = sp.vstack([d2 @ nx, d2 @ ny, w3 * (d3 @ nx), w3 * (d3 @ ny),
                   sp.diags(root)]).tocsr()
    mid = 0.5 * (lo + hi)  # the centred curve is the "stay centred" target
    b = np.concatenate([-(d2 @ base[:, 0]), -(d2 @ base[:, 1]), -w3 * (d3 @ base[:, 0]),
                        -w3 * (d3 @ base[:, 1]), root * mid])
    return box_qp(a.T @ a, -(a.T @ b), lo, hi)


def curvature_of(curve: FloatArray) -> FloatArray:
    """Signed curvature [1/m] of a densely sampled curve (n, 2), central differences
    (np.gradient's one-sided ones at the ends)."""
    d1 = np.gradient(curve, axis=0)
    d2 = np.gradient(d1, axis=0)
    speed = np.maximum(np.hypot(*d1.T), 1e-12)
    out: FloatArray = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / speed ** 3
    return out


def support_curvature(points: FloatArray, s_m: FloatArray, arms_m: tuple[float, ...]
                      ) -> FloatArray:
    """|curvature| [1/m] the polyline's overall geometry supports at each of its points
    (n, 2) at arc lengths ``s_m`` (n,): the largest over the arms a of the Menger
    curvature 2 |(B - A) x (C - A)| / (|B - A| |C - B| |C - A|) of A = P(s - a), B = P(s),
    C = P(s + a) (clipped to the ends).

    On a circular arc this is exactly 1/R whatever the arm; a vertex displaced by d
    (a digitising kink) moves it by about 2 d / a² only, where the kink itself turns
    like R = 8 tube / alpha²."""
    out = np.zeros(len(s_m))
    for arm in arms_m:
        at = [np.column_stack([np.interp(np.clip(s_m + k * arm, s_m[0], s_m[-1]), s_m,
                                         points[:, i]) for i in range(2)])
              for k in (-1.0, 0.0, 1.0)]
        a, b, c = at
        cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
        sides = np.hypot(*(b - a).T) * np.hypot(*(c - b).T) * np.hypot(*(c - a).T)
        out = np.maximum(out, np.where(sides > 1e-9, 2.0 * cross / np.maximum(sides, 1e-12),
                                       0.0))
    return out


def smooth_within_support(res: Resampled, params: TubeParams, half_width_m: FloatArray,
                          room: tuple[BoolArray, BoolArray] | None = None
                          ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`smooth_in_tube`, with the tube widened where the curve would bend more than
    the polyline's overall geometry supports (a digitising kink: OSM polylines step
    their heading by up to ~7° every 30-120 m on roads of kilometres of radius, and a
    0.10 m tube turns such a kink into a bend of ~100 m radius).

    The allowed curvature is ``support_margin`` x :func:`support_curvature` +
    ``support_slack_per_m``. Each pass finds the points where the solution exceeds it
    (not within 3 points of an end) and doubles the half-width within ``kink_reach_m`` of
    them, up to ``kink_tube_max_m`` (a wider tube, a junction's or a jog zone's, is never
    narrowed); at most ``kink_passes`` passes. ``room`` = (right, left) (n,) each: where
    the lane has a neighbour lane on that side; the tube widens only towards a
    neighbour (never towards the road's edge, where a car 0.8 m off its lane's centre
    would leave the road; default: both sides). Returns (points (n, 2), offsets (n,) as
    :func:`smooth_in_tube`, the larger half-width (n,) finally used on either side [m])."""
    base_half = np.asarray(half_width_m, dtype=np.float64)
    right, left = base_half.copy(), base_half.copy()
    room_right, room_left = room if room is not None else (np.ones(len(base_half), bool),) * 2
    curve, offsets = smooth_in_tube(res, params, base_half)
    if len(res.s_m) < 8 or params.kink_passes == 0:
        return curve, offsets, base_half
    allowed = (params.support_margin * support_curvature(res.points, res.s_m,
                                                          params.support_arms_m)
               + params.support_slack_per_m)
    reach = max(int(round(params.kink_reach_m / params.spacing_m)), 1)
    for _ in range(params.kink_passes):
        over = np.abs(curvature_of(curve)) > allowed
        over[:3] = over[-3:] = False
        if not np.any(over):
            break
        near = np.convolve(over.astype(np.float64), np.ones(2 * reach + 1), mode="same") > 0
        wider_right = _widen(right, near & room_right, params)
        wider_left = _widen(left, near & room_left, params)
        if np.array_equal(wider_right, right) and np.array_equal(wider_left, left):
            break
        right, left = wider_right, wider_left
        curve, offsets = smooth_in_tube(res, params, right,
                                        _centring(np.maximum(right, left), base_half, params),
                                        half_left_m=left)
    return curve, offsets, np.maximum(right, left)


def _widen(half: FloatArray, where: BoolArray, params: TubeParams) -> FloatArray:
    """``half`` doubled where ``where``, up to ``kink_tube_max_m`` (never narrowed)."""
    out: FloatArray = np.where(where, np.maximum(half, np.minimum(2.0 * half,
                                                                  params.kink_tube_max_m)),
                               half)
    return out


def _centring(half: FloatArray, base_half: FloatArray, params: TubeParams) -> FloatArray:
    """The stay-centred weight's scale per point: (lane tube / half-width)² where the tube
    was widened for a digitising kink (``half`` > ``base_half``), else 1. There the curve
    must be free to leave the polyline's corner: the full pull to the centre holds it to
    the kink (with a 0.8 m tube and the full weight a 5° kink still bends the reference to
    R ~ 280 m). A jog zone's or a junction's own tube keeps the full pull: it is as wide on
    the road edge's side as on the other, and a free curve would drift towards the edge."""
    out: FloatArray = np.where(half > base_half,
                               np.minimum((params.lane_tube_m / np.maximum(half, 1e-9)) ** 2,
                                          1.0), 1.0)
    return out


def smooth_in_tube(res: Resampled, params: TubeParams, half_width_m: FloatArray | None = None,
                   centring: FloatArray | None = None, half_left_m: FloatArray | None = None
                   ) -> tuple[FloatArray, FloatArray]:
    """The minimum-curvature curve inside the tube (module docstring): (points (n, 2),
    signed distance (n,) of each point from the polyline, left +).

    The unknowns are offsets along the normals of a smooth *base* curve (a Gaussian
    smoothing of the polyline, then the first solution): offsets along the polyline's own
    normals would change the spacing of the points around every kink, and the second
    differences would count that as bending. The tube, |C_k - polyline| <= d_k, becomes
    the linear bounds o0_k - d_k <= o_k <= o0_k + d_k with o0_k the polyline's offset
    from the base along its normal.

    ``half_width_m`` (n,) overrides the tube's half-width per point (default: the lane
    or junction tube of ``params`` by ``res.junction``), on the right and, without
    ``half_left_m`` (n,), on the left too; ``centring`` (n,) scales the stay-centred
    weight per point (default 1).
    """
    n = len(res.s_m)
    half = (np.where(res.junction, params.junction_tube_m, params.lane_tube_m)
            if half_width_m is None else np.asarray(half_width_m, dtype=np.float64))
    left = half if half_left_m is None else np.asarray(half_left_m, dtype=np.float64)
    if n < 8:
        return res.points.copy(), np.zeros(n)
    sigma = max(params.base_smoothing_m / params.spacing_m, 1.0)
    base = np.column_stack([gaussian_filter1d(res.points[:, i], sigma, mode="nearest")
                            for i in range(2)])
    curve = base
    for _ in range(2):  # the second pass re-bases on the first solution
        normals = _normals(base)
        o0 = offsets_to_polyline(base, normals, res.points)
        # 1 mm inside the tube: the bound is along the base normal, the deviation is the
        # true distance to the polyline (equal to first order, not exactly).
        inner_right = np.maximum(half - 1e-3, 0.5 * half)
        inner_left = np.maximum(left - 1e-3, 0.5 * left)
        offsets = _solve(base, normals, o0 - inner_right, o0 + inner_left, params, centring)
        curve = base + normals * offsets[:, None]
        base = curve
    normals = _normals(curve)
    return curve, -offsets_to_polyline(curve, normals, res.points)
