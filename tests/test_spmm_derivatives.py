"""Hand-derived SPMM derivatives (docs/method.md §3) against central finite differences.

All three costs, obstacles active (one of them moving), on a path whose curvature
varies (kappa and kappa' both nonzero), at random states/inputs/costates.
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.path.frenet import FrenetPath
from controllers.two_loop.outer.ocp import constraint_eval, stage_eval, terminal_eval
from controllers.two_loop.outer.ocp_layout import (
    obstacle_table,
    pack_params,
    stage_fractions,
    stage_width,
)
from controllers.two_loop.outer.params import OcpParams
from controllers.two_loop.outer.spmm_problem import SpmmProblem

K_OBS = 2


@pytest.fixture(scope="module")
def spiral() -> FrenetPath:
    # Clothoid-like: heading s² / (2 R L), curvature growing linearly to 1/150 m.
    s = np.linspace(0.0, 400.0, 401)
    phi = s**2 / (2.0 * 150.0 * 400.0)
    xy = np.column_stack([np.cumsum(np.cos(phi)), np.cumsum(np.sin(phi))])
    return FrenetPath.from_polyline(xy)


def _obstacles() -> np.ndarray:
    obs = obstacle_table(K_OBS)
    obs[0] = [212.0, 0.4, 0.0, 0.0, 7.0, 2.2, 1.0, 1.0, 0.0]
    obs[1] = [190.0, -2.5, 4.0, 0.3, 6.0, 2.0, 1.0, 0.6, 0.0]  # moving, fading in
    return obs


def _stage_fn(path: FrenetPath, cost: str, y_ref: float = 0.0):  # noqa: ANN202
    params = OcpParams(cost=cost, c_y_terminal=0.7, c_e_terminal=3.0)
    prm = pack_params(params, 24.0, y_ref, lateral_weight=None if y_ref == 0.0 else 7.0)
    meta, coef, _ = path.tables()
    obs = _obstacles()
    m = stage_width(K_OBS)

    def h(x: np.ndarray, u: np.ndarray, p: np.ndarray, tau: float) -> tuple:
        f = np.empty(3)
        hx = np.empty(3)
        hu = np.empty(m)
        val = stage_eval(x, u, p, tau, True, prm, obs, meta, coef, f, hx, hu)
        return val, f, hx, hu

    return h, m, prm, meta, coef


@pytest.mark.parametrize("y_ref", [0.0, 2.9])
@pytest.mark.parametrize("cost", ["J1", "J2", "J3"])
def test_hamiltonian_gradients(spiral: FrenetPath, cost: str, y_ref: float) -> None:
    h, m, _, _, _ = _stage_fn(spiral, cost, y_ref)
    rng = np.random.default_rng(7)
    nx = 3 if cost == "J3" else 2
    for _ in range(25):
        s = rng.uniform(150.0, 260.0)
        x = np.array([s, rng.uniform(-3.0, 3.0), float(spiral.gamma(s)) + rng.uniform(-.2, .2)])
        u = np.empty(m)
        if cost == "J3":
            u[0], u[1] = rng.uniform(5.0, 30.0), rng.uniform(-0.3, 0.3)
        else:
            u[0], u[1] = float(spiral.gamma(s)) + rng.uniform(-0.2, 0.2), rng.uniform(5.0, 30.0)
        u[2:2 + K_OBS] = rng.uniform(0.2, 3.0, K_OBS)
        u[2 + K_OBS:] = rng.uniform(-2.0, 2.0, K_OBS)
        p = rng.uniform(-3.0, 3.0, 3)
        tau = rng.uniform(0.0, 2.0)
        assert abs(float(spiral.kappa(s))) > 1e-3 and abs(float(spiral.dkappa(s))) > 1e-6
        _, f, hx, hu = h(x, u, p, tau)
        for i in range(nx):
            d = 1e-6 * max(1.0, abs(x[i]))
            xp, xm = x.copy(), x.copy()
            xp[i] += d
            xm[i] -= d
            fd = (h(xp, u, p, tau)[0] - h(xm, u, p, tau)[0]) / (2 * d)
            assert hx[i] == pytest.approx(fd, rel=1e-6, abs=1e-6), (cost, "H_x", i)
        for i in range(m):
            d = 1e-6 * max(1.0, abs(u[i]))
            up, um = u.copy(), u.copy()
            up[i] += d
            um[i] -= d
            fd = (h(x, up, p, tau)[0] - h(x, um, p, tau)[0]) / (2 * d)
            assert hu[i] == pytest.approx(fd, rel=1e-6, abs=1e-6), (cost, "H_u", i)
        # dH/dp = f (the model) closes the loop on f's definition (H is linear in p, so
        # a large step is exact and keeps the round-off of a large H small).
        for i in range(nx):
            pp, pm = p.copy(), p.copy()
            pp[i] += 1e-3
            pm[i] -= 1e-3
            fd = (h(x, u, pp, tau)[0] - h(x, u, pm, tau)[0]) / 2e-3
            assert f[i] == pytest.approx(fd, rel=1e-7, abs=1e-7)


def test_constraint_gradient() -> None:
    ob = _obstacles()[1]
    rng = np.random.default_rng(3)
    for _ in range(20):
        s, y, tau = rng.uniform(150, 260), rng.uniform(-4, 4), rng.uniform(0, 2.4)
        c, cs, cy = constraint_eval(s, y, tau, ob)
        d = 1e-6
        assert cs == pytest.approx((constraint_eval(s + d, y, tau, ob)[0]
                                    - constraint_eval(s - d, y, tau, ob)[0]) / (2 * d), rel=1e-6)
        assert cy == pytest.approx((constraint_eval(s, y + d, tau, ob)[0]
                                    - constraint_eval(s, y - d, tau, ob)[0]) / (2 * d), rel=1e-6)
        # Moving centre: s_j(tau) = s_j + v tau.
        expected = ((s - ob[0] - ob[2] * tau) / ob[4]) ** 2 + ((y - ob[1] - ob[3] * tau)
                                                                / ob[5]) ** 2 - 1
        assert c == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("y_ref", [0.0, -3.5])
@pytest.mark.parametrize("cost", ["J1", "J3"])
def test_terminal_gradient(spiral: FrenetPath, cost: str, y_ref: float) -> None:
    _, _, prm, meta, coef = _stage_fn(spiral, cost, y_ref)
    x = np.array([205.0, 0.8, float(spiral.gamma(205.0)) + 0.07])
    g = np.empty(3)
    terminal_eval(x, prm, meta, coef, g)
    for i in range(3 if cost == "J3" else 2):
        xp, xm = x.copy(), x.copy()
        xp[i] += 1e-6
        xm[i] -= 1e-6
        fd = (terminal_eval(xp, prm, meta, coef, np.empty(3))
              - terminal_eval(xm, prm, meta, coef, np.empty(3))) / 2e-6
        assert g[i] == pytest.approx(fd, rel=1e-6, abs=1e-8)


@pytest.mark.parametrize(("cost", "chebyshev", "y_ref"), [
    ("J1", False, 0.0), ("J2", False, 0.0), ("J3", False, 0.0),
    ("J1", True, 0.0), ("J2", True, 0.0), ("J3", True, 0.0),
    ("J1", False, 3.5), ("J2", True, -3.5), ("J3", False, 3.5)])
def test_residual_is_reduced_lagrangian_gradient(spiral: FrenetPath, cost: str,
                                                 chebyshev: bool, y_ref: float) -> None:
    """dtau_i F_i = d/du_i [sum dtau L + sum dtau mu (c - Z²) + m] through the dynamics.

    This checks the costate recursion (24) and the whole residual (26), not just H.
    """
    params = OcpParams(cost=cost, n_stages=12, chebyshev=chebyshev,
                       c_y_terminal=0.5, c_e_terminal=2.0)
    prob = SpmmProblem(spiral, params)
    obs = _obstacles()
    x0 = np.array([170.0, 0.5, float(spiral.gamma(170.0)) + 0.03])
    rng = np.random.default_rng(11)
    u = prob.initial_guess(x0, obs, 22.0, lateral_reference_m=y_ref)
    u = u + rng.normal(0.0, 0.05, u.shape)
    f, _, _ = prob.residual(u, x0, obs, 22.0, horizon=2.0, tshift=0.3,
                            lateral_reference_m=y_ref)
    dtau = np.diff(stage_fractions(params)) * 2.0
    m = stage_width(K_OBS)
    for k in range(u.shape[0]):
        i, comp = divmod(k, m)
        if i == 0 and comp >= 2:
            continue  # trivial stage-0 rows
        d = 1e-6 * max(1.0, abs(u[k]))
        up, um = u.copy(), u.copy()
        up[k] += d
        um[k] -= d
        fd = (prob.objective(up, x0, obs, 22.0, 2.0, 0.3, True, y_ref)
              - prob.objective(um, x0, obs, 22.0, 2.0, 0.3, True, y_ref)) / (2 * d)
        assert dtau[i] * f[k] == pytest.approx(fd, rel=1e-5, abs=1e-7), (cost, i, comp)
    # Trivial rows: stage 0 constraints (Z - 1, mu).
    assert np.allclose(f[2:2 + K_OBS], u[2:2 + K_OBS] - 1.0)
    assert np.allclose(f[2 + K_OBS:m], u[2 + K_OBS:m])


def test_inactive_slot_is_inert(spiral: FrenetPath) -> None:
    params = OcpParams(n_stages=10)
    prob = SpmmProblem(spiral, params)
    obs = _obstacles()
    obs[1, 6] = 0.0
    x0 = np.array([170.0, 0.2, float(spiral.gamma(170.0))])
    u = prob.initial_guess(x0, obs, 22.0)
    f1, xs1, _ = prob.residual(u, x0, obs, 22.0)
    obs2 = obs.copy()
    obs2[1, :6] = [171.0, 0.0, 3.0, 0.0, 5.0, 2.0]  # anything: must not matter
    f2, xs2, _ = prob.residual(u, x0, obs2, 22.0)
    assert np.array_equal(f1, f2) and np.array_equal(xs1, xs2)


def test_lateral_reference_shifts_the_cost_and_is_not_compiled_in(spiral: FrenetPath) -> None:
    """Cy (y - yr)²: the stage cost at y = yr equals the one at y = 0 with yr = 0, H_y
    changes by -2 Cy yr, and new yr / Cy values reuse the compiled kernels."""
    params = OcpParams(cost="J3", c_y_terminal=0.7)
    meta, coef, _ = spiral.tables()
    obs = obstacle_table(K_OBS)  # inert slots
    m = stage_width(K_OBS)
    s = 200.0
    u = np.zeros(m)
    u[0], u[1] = 24.0, 0.01
    u[2:2 + K_OBS] = 1.0
    p = np.array([0.3, -0.2, 0.1])

    def stage(y: float, y_ref: float, c_y: float | None = None) -> tuple[float, np.ndarray]:
        x = np.array([s, y, float(spiral.gamma(s)) + 0.02])
        hx = np.empty(3)
        val = stage_eval(x, u, p, 0.0, True, pack_params(params, 24.0, y_ref, lateral_weight=c_y),
                         obs, meta, coef, np.empty(3), hx, np.empty(m))
        return val, hx

    n_sig = len(stage_eval.signatures), len(terminal_eval.signatures)
    v0, h0 = stage(0.0, 0.0)
    v1, h1 = stage(0.0, 3.5)
    assert v1 - v0 == pytest.approx(params.c_y * 3.5**2, rel=1e-9)
    assert h1[1] - h0[1] == pytest.approx(-2.0 * params.c_y * 3.5, rel=1e-9)
    v2, h2 = stage(0.0, 3.5, c_y=20.0)
    assert v2 - v0 == pytest.approx(20.0 * 3.5**2, rel=1e-9)
    g = np.empty(3)
    x_n = np.array([s, 3.5, float(spiral.gamma(s))])
    terminal_eval(x_n, pack_params(params, 24.0, 3.5), meta, coef, g)
    assert g[1] == 0.0  # terminal (y_N - yr)²: no pull at y_N = yr
    assert (len(stage_eval.signatures), len(terminal_eval.signatures)) == n_sig
