"""Generic pieces of C/GMRES (Ohtsuka 2004, docs/method.md §5).

Continuation: choose U' so that dF/dt = -zeta_s F along the trajectory,

    F_U U' = -zeta_s F - F_x x' - F_t                                   (27)(28)

solved matrix-free by *forward-difference* GMRES with a fixed number of
iterations k_max, warm-started from the previous U', then U <- U + U' dt (Euler):

    D_h F(U, x, t : W, w, 1) = [F(U + h W, x + h w, t + h) - F(U, x + h w, t + h)] / h
    b   = -zeta_s F(U, x, t) - [F(U, x + h x', t + h) - F(U, x, t)] / h
    r_0 = b - D_h F(U, x + h x', t + h : U'_prev)

The Krylov kernels below (Arnoldi with modified Gram-Schmidt, Givens rotations,
back substitution) are compiled with numba and used by the problem-specific
compiled update (``controllers.two_loop.outer.cgmres``), which calls the residual directly
so that one update is a single compiled call with fixed-size preallocated arrays.
``cgmres_step`` is the same algorithm for any Python residual function (tests,
prototyping); its operation count is equally fixed (k_max + 3 residual calls).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np

# Fast-math flags of the hot kernels: no 'nnan'/'ninf' (non-finite checks stay valid), and
# no 'reassoc'/'contract': with them LLVM may reorder sums and fuse multiply-adds
# differently when a kernel is compiled in the run's process than when it comes from
# numba's cache, so the first run after an install or a change gave other numbers than
# every later one (a two_loop run of the paper catalog differed from step 1). Without
# them a kernel computes the same bits however it was compiled.
_FM = {"nsz", "arcp", "afn"}


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def arnoldi_mgs(vb: np.ndarray, hm: np.ndarray, j: int) -> float:
    """Orthogonalise vb[j+1] against vb[0..j] (modified Gram-Schmidt) and normalise it.

    Fills hm[0..j+1, j]; returns hm[j+1, j] (the norm before normalisation).
    """
    n = vb.shape[1]
    for ll in range(j + 1):
        acc = 0.0
        for i in range(n):
            acc += vb[j + 1, i] * vb[ll, i]
        hm[ll, j] = acc
        for i in range(n):
            vb[j + 1, i] -= acc * vb[ll, i]
    nrm = 0.0
    for i in range(n):
        nrm += vb[j + 1, i] * vb[j + 1, i]
    nrm = math.sqrt(nrm)
    hm[j + 1, j] = nrm
    if nrm > 1e-300:
        inv = 1.0 / nrm
        for i in range(n):
            vb[j + 1, i] *= inv
    return nrm


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def givens_column(hm: np.ndarray, cs: np.ndarray, sn: np.ndarray, g: np.ndarray,
                  j: int) -> float:
    """Apply the previous rotations to column j of hm, make the new one, rotate g.

    Returns |g[j+1]|, the GMRES residual norm after j+1 iterations.
    """
    for ll in range(j):
        tmp = cs[ll] * hm[ll, j] + sn[ll] * hm[ll + 1, j]
        hm[ll + 1, j] = -sn[ll] * hm[ll, j] + cs[ll] * hm[ll + 1, j]
        hm[ll, j] = tmp
    a = hm[j, j]
    b = hm[j + 1, j]
    nu = math.sqrt(a * a + b * b)
    if nu < 1e-300:
        cs[j] = 1.0
        sn[j] = 0.0
    else:
        cs[j] = a / nu
        sn[j] = b / nu
    hm[j, j] = cs[j] * a + sn[j] * b
    hm[j + 1, j] = 0.0
    g[j + 1] = -sn[j] * g[j]
    g[j] = cs[j] * g[j]
    res: float = abs(g[j + 1])
    return res


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def back_substitute(hm: np.ndarray, g: np.ndarray, k: int, y: np.ndarray) -> None:
    """Solve the k x k upper-triangular system hm[:k, :k] y = g[:k] (zero on a null pivot)."""
    for i in range(k - 1, -1, -1):
        acc = g[i]
        for ll in range(i + 1, k):
            acc -= hm[i, ll] * y[ll]
        piv = hm[i, i]
        y[i] = acc / piv if abs(piv) > 1e-300 else 0.0


@numba.njit(cache=True, error_model="numpy", fastmath=_FM)
def combine(udot: np.ndarray, vb: np.ndarray, y: np.ndarray, k: int) -> None:
    """udot += sum_l y[l] vb[l] (l < k)."""
    n = udot.shape[0]
    for ll in range(k):
        c = y[ll]
        for i in range(n):
            udot[i] += c * vb[ll, i]


def cgmres_step(residual: Callable[[np.ndarray, np.ndarray, float], np.ndarray],  # noqa: PLR0913 - U, U', x, x' and settings, flat like the compiled update
                u: np.ndarray, udot: np.ndarray, x: np.ndarray, xdot: np.ndarray, t: float,
                dt: float, zeta_s: float, h: float, k_max: int,
                ) -> tuple[np.ndarray, np.ndarray, float]:
    """One C/GMRES update for a Python residual F(U, x, t) -> (n,).

    Returns (U_new, U'_new, ||F(U, x, t)||_inf before the update). Same algorithm
    (and Krylov kernels) as the compiled SPMM update.
    """
    n = u.shape[0]
    f0 = residual(u, x, t)
    xh = x + h * xdot
    fxh = residual(u, xh, t + h)
    b = -zeta_s * f0 - (fxh - f0) / h
    fw = residual(u + h * udot, xh, t + h)
    r0 = b - (fw - fxh) / h
    beta = float(np.linalg.norm(r0))
    udot_new = udot.copy()
    if beta > 1e-300:
        vb = np.zeros((k_max + 1, n))
        hm = np.zeros((k_max + 1, k_max))
        cs = np.zeros(k_max)
        sn = np.zeros(k_max)
        g = np.zeros(k_max + 1)
        g[0] = beta
        vb[0] = r0 / beta
        k = 0
        for j in range(k_max):
            vb[j + 1] = (residual(u + h * vb[j], xh, t + h) - fxh) / h
            nrm = arnoldi_mgs(vb, hm, j)
            givens_column(hm, cs, sn, g, j)
            k = j + 1
            if nrm < 1e-14 * beta:
                break
        y = np.zeros(k_max)
        back_substitute(hm, g, k, y)
        combine(udot_new, vb, y, k)
    return u + dt * udot_new, udot_new, float(np.max(np.abs(f0)))
