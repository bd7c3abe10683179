"""The lane corridor of the OCP (issue #33, "Lanes kept, not pushed"): the exterior
penalty C_lane (max(0, y - y_hi)² + max(0, y_lo - y)²) in the hand-derived residual
exactly as in the objective (central finite differences), zero inside the corridor, and
the controller's corridor: the lane kept, the union of the lanes of a change until the
car has settled in the target lane."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ocp_gradient import assert_residual_is_objective_gradient

from controllers.path.frenet import FrenetPath
from controllers.two_loop.lateral import LaneCorridor, LateralRefParams
from controllers.two_loop.outer.ocp_layout import (
    _P_CLANE,
    _P_YHI,
    _P_YLO,
    obstacle_table,
    pack_params,
    stage_width,
)
from controllers.two_loop.outer.params import OcpParams
from controllers.two_loop.outer.spmm_problem import SpmmProblem

K_OBS = 1


def test_pack_params_carries_the_corridor() -> None:
    p = OcpParams()
    prm = pack_params(p, 20.0)
    assert prm[_P_YLO] == -math.inf and prm[_P_YHI] == math.inf
    prm = pack_params(p, 20.0, lane_corridor_m=(-0.6, 4.1))
    assert (prm[_P_YLO], prm[_P_YHI], prm[_P_CLANE]) == (-0.6, 4.1, p.c_lane)
    with pytest.raises(ValueError):
        pack_params(p, 20.0, lane_corridor_m=(1.0, -1.0))


def _problem(cost: str, path_curved: bool) -> tuple[SpmmProblem, OcpParams]:
    s = np.linspace(0.0, 300.0, 301)
    if path_curved:  # R = 400 m arc
        xy = np.column_stack([400.0 * np.sin(s / 400.0), 400.0 * (1.0 - np.cos(s / 400.0))])
    else:
        xy = np.column_stack([s, np.zeros(301)])
    params = OcpParams(cost=cost, n_stages=10)
    return SpmmProblem(FrenetPath.from_polyline(xy), params), params


@pytest.mark.parametrize("curved", [False, True])
@pytest.mark.parametrize("cost", ["J1", "J2", "J3"])
def test_residual_with_the_plan_outside_the_corridor_is_the_objective_gradient(
        cost: str, curved: bool) -> None:
    """A plan pushed left by an ellipse reaching into the lane, its stages on both sides
    of y_hi (the penalty active on some, zero on others): dtau_i F_i = d/du_i of the
    reduced Lagrangian."""
    prob, params = _problem(cost, curved)
    obs = obstacle_table(K_OBS)
    obs[0] = [70.0, -2.4, 0.0, 0.0, 9.0, 2.1, 1.0, 1.0, 0.0]
    x0 = np.array([48.5, 0.55, 0.0])
    if curved:
        x0[2] = float(prob.path.gamma(48.5))
    corridor = (-0.65, 0.65)
    u = prob.initial_guess(x0, obs, 20.0)
    m = stage_width(K_OBS)
    thcol = 1 if cost == "J3" else 0
    rng = np.random.default_rng(7)
    u = u + rng.normal(0.0, 0.01, u.shape)
    u.reshape(params.n_stages, m)[:, thcol] += 0.08 if cost == "J3" else 0.02  # y crosses 0.65
    _, xs, _ = prob.residual(u, x0, obs, 20.0, horizon=2.4, tshift=0.1,
                             lane_corridor_m=corridor)
    assert np.any(xs[1:, 1] > corridor[1]) and np.any(xs[1:, 1] < corridor[1])
    assert_residual_is_objective_gradient(prob, params, u, x0, obs, 20.0, 2.4, 0.1, m,
                                          cost, lane_corridor_m=corridor)


def test_the_penalty_is_zero_inside_the_corridor() -> None:
    prob, _ = _problem("J3", False)
    obs = obstacle_table(K_OBS)
    x0 = np.array([48.5, 0.1, 0.0])
    u = prob.initial_guess(x0, obs, 20.0)
    f0, _, _ = prob.residual(u, x0, obs, 20.0, 2.4, 0.0)
    f1, xs, _ = prob.residual(u, x0, obs, 20.0, 2.4, 0.0, lane_corridor_m=(-0.65, 0.65))
    assert np.all(np.abs(xs[:, 1]) < 0.65)
    np.testing.assert_array_equal(f0, f1)
    assert prob.objective(u, x0, obs, 20.0, 2.4) == prob.objective(
        u, x0, obs, 20.0, 2.4, lane_corridor_m=(-0.65, 0.65))


def test_the_corridor_is_the_lane_kept_and_spans_a_change_until_settled() -> None:
    c = LaneCorridor(LateralRefParams(corridor_margin_m=0.15))
    c.reset(3.5, 1.9)
    h = 1.75 - 0.95 - 0.15
    assert c.update(0.0, 0.0, 0.0) == pytest.approx((-h, h))
    # the barrier pushes, the corridor stays
    assert c.update(0.0, 0.4, 0.0) == pytest.approx((-h, h))
    # a pass to the left lane (the behaviour's decision): both lanes
    assert c.update(3.5, 0.1, 0.05) == pytest.approx((-h, 3.5 + h))
    assert c.changing
    assert c.update(3.5, 2.5, 3.0) == pytest.approx((-h, 3.5 + h))
    # an abort back, then forward again: still both lanes
    assert c.update(0.0, 1.5, 2.0) == pytest.approx((-h, 3.5 + h))
    assert c.update(3.5, 3.2, 3.3) == pytest.approx((-h, 3.5 + h))
    # settled in the left lane: that lane only
    assert c.update(3.5, 3.45, 3.48) == pytest.approx((3.5 - h, 3.5 + h))
    assert not c.changing
    # and the return: both again, then the home lane
    assert c.update(0.0, 3.45, 3.4) == pytest.approx((-h, 3.5 + h))
    assert c.update(0.0, 0.02, 0.01) == pytest.approx((-h, h))


def test_the_corridor_starts_around_the_car_and_can_be_turned_off() -> None:
    c = LaneCorridor(LateralRefParams())
    c.reset(3.5, 1.9)
    lo, hi = c.update(0.0, 1.2, 1.2)  # starting off its lane: the car is inside
    assert lo < 0.0 and hi >= 1.2 and c.changing
    off = LaneCorridor(LateralRefParams(corridor=False))
    off.reset(3.5, 1.9)
    assert off.update(0.0, 0.0, 0.0) == (-math.inf, math.inf)
