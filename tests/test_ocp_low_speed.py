"""The OCP at a crawl (issue #33): the barrier's weight scaled with the problem's speed
(sigma Cz) and the penalty Cvn min(V, 0)² on negative planned speeds, both in the
hand-derived residual exactly as in the objective (central finite differences)."""

from __future__ import annotations

import numpy as np
import pytest
from ocp_gradient import assert_residual_is_objective_gradient

from controllers.path.frenet import FrenetPath
from controllers.two_loop.outer.ocp_layout import (
    _P_CZS,
    barrier_scale,
    obstacle_table,
    pack_params,
    stage_width,
)
from controllers.two_loop.outer.params import OcpParams
from controllers.two_loop.outer.spmm_problem import SpmmProblem

K_OBS = 1


def test_barrier_scale_saturates_at_speed() -> None:
    p = OcpParams()
    assert barrier_scale(p, 25.0) == 1.0
    assert barrier_scale(p, p.barrier_speed_mps) == 1.0
    assert barrier_scale(p, 0.9) == pytest.approx(0.09)
    assert barrier_scale(p, 0.0) == p.barrier_min_scale
    assert pack_params(p, 0.9)[_P_CZS] == pytest.approx(0.09)
    assert pack_params(p, 0.9, barrier_weight_scale=0.5)[_P_CZS] == 0.5


@pytest.mark.parametrize("cost", ["J1", "J2", "J3"])
def test_residual_with_negative_speeds_is_the_objective_gradient(cost: str) -> None:
    """At 0.9 m/s target with some stages' V negative (the penalty active) and the
    barrier at sigma < 1: dtau_i F_i = d/du_i of the reduced Lagrangian."""
    path = FrenetPath.from_polyline(np.column_stack([np.linspace(0.0, 300.0, 301),
                                                     np.zeros(301)]))
    params = OcpParams(cost=cost, n_stages=10)
    prob = SpmmProblem(path, params)
    obs = obstacle_table(K_OBS)
    obs[0] = [64.0, 0.0, 0.0, 0.0, 10.2, 2.55, 1.0, 1.0, 0.0]
    x0 = np.array([48.5, 0.0, 0.0])
    u = prob.initial_guess(x0, obs, 0.9)
    m = stage_width(K_OBS)
    vcol = 0 if cost == "J3" else 1
    rng = np.random.default_rng(5)
    u = u + rng.normal(0.0, 0.02, u.shape)
    u.reshape(params.n_stages, m)[::2, vcol] = -0.3  # every other stage backwards
    assert_residual_is_objective_gradient(prob, params, u, x0, obs, 0.9, 2.0, 0.1, m, cost)
