"""Ipopt NMPC baseline (controllers.baselines): the C/GMRES OCP solved by Ipopt.

The fixed problem: a straight path along +X, the ego at s = 0 on the centreline at
25 m/s, one stalled car in the lane ahead (ellipse A = 6.8 m, B = 2.3 m, offset
0.3 m to the right so the plan passes on the left).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

pytest.importorskip("casadi")

from controllers.params import ParamError  # noqa: E402
from controllers.protocol import ConfigError, Obstacles  # noqa: E402
from controllers.two_loop.outer.ipopt_nlp import ellipse_values, pack_obstacles  # noqa: E402
from controllers.two_loop.outer.ipopt_planner import IpoptOuter  # noqa: E402
from controllers.two_loop.outer.ocp_layout import obstacle_table  # noqa: E402
from controllers.two_loop.outer.params import (  # noqa: E402
    CgmresParams,
    IpoptParams,
    ipopt_params,
)
from controllers.two_loop.outer.spmm_problem import SpmmProblem  # noqa: E402
from suite.bench.solvers import StraightPath, benchmark_outer  # noqa: E402

VT = 25.0
PERIOD = 0.02


_SOLVER_KEYS = ("formulation", "max_iter", "tol")


def _outer(path: Any = None, params: IpoptParams | None = None, **kw: Any) -> IpoptOuter:
    """IpoptOuter on ``params`` (default IpoptParams()); formulation, max_iter and tol in
    ``kw`` replace the params' own, the rest goes to the constructor."""
    base = params if params is not None else IpoptParams()
    solver = {k: kw.pop(k) for k in _SOLVER_KEYS if k in kw}
    if solver:
        from dataclasses import replace

        base = replace(base, **solver)
    return IpoptOuter(path if path is not None else StraightPath(2000.0), base, **kw)


def _obstacle(s: float = 40.0, y: float = -0.3, vs: float = 0.0) -> Obstacles:
    return Obstacles(np.array([s]), np.array([y]), np.array([vs]), np.zeros(1),
                     np.array([6.8]), np.array([2.3]))


class CirclePath:
    """Local stand-in for a curved FrenetPath: a left-hand circle of radius R."""

    def __init__(self, radius_m: float, length_m: float) -> None:
        self.radius = radius_m
        self.length_m = length_m

    def gamma(self, s: Any) -> Any:
        return np.asarray(s, dtype=np.float64) / self.radius

    def kappa(self, s: Any) -> Any:
        return np.full_like(np.asarray(s, dtype=np.float64), 1.0 / self.radius)


def _euler_defect(outer: IpoptOuter, plan: Any) -> float:
    """max |x_{i+1} - x_i - f(x_i, u_i) dtau_i| with the path's *exact* gamma, kappa."""
    x = plan.states
    om = np.diff(x[:, 2]) / outer.dtau
    gam = outer.lookup.gamma_np(x[:-1, 0])
    kap = outer.lookup.kappa_np(x[:-1, 0])
    e = x[:-1, 2] - gam
    v = plan.speeds_mps
    f = np.stack([v * np.cos(e) / (1 - x[:-1, 1] * kap), v * np.sin(e), om], axis=1)
    return float(np.abs(x[1:] - x[:-1] - f * outer.dtau[:, None]).max())


# ---------------------------------------------------------------- open loop

def test_barrier_converges_and_avoids_the_ellipse() -> None:
    outer = _outer()
    outer.reset(np.zeros(3), VT)
    obs = _obstacle()
    plan = outer.update(0.0, np.zeros(3), obs, VT, PERIOD)
    assert not plan.fallback
    assert outer.last_status == "Solve_Succeeded"
    assert plan.residual < 1e-6
    assert plan.states.shape == (outer.n + 1, 3) and plan.speeds_mps.shape == (outer.n,)
    assert np.all(np.isfinite(plan.states))
    c = ellipse_values(plan.states, plan.stage_times_s, pack_obstacles(obs))[:, 0]
    # The barrier form constrains nodes 1..N-1 (as C/GMRES); all stay outside, with margin.
    assert c[1:-1].min() > 0.05
    assert plan.states[:, 1].max() > 1.5  # passes on the left (offset pushes it there)
    assert 0.0 <= plan.speeds_mps.min() and plan.speeds_mps.max() <= 1.5 * VT
    assert _euler_defect(outer, plan) < 1e-6


def test_hard_formulation_also_avoids() -> None:
    outer = _outer(formulation="hard")
    outer.reset(np.zeros(3), VT)
    obs = _obstacle()
    plan = outer.update(0.0, np.zeros(3), obs, VT, PERIOD)
    assert not plan.fallback and plan.residual < 1e-6
    c = ellipse_values(plan.states, plan.stage_times_s, pack_obstacles(obs))[:, 0]
    assert c[1:].min() > -1e-6
    # Without a barrier the plan touches the ellipse (active constraint).
    assert c[1:].min() < 1e-3


def test_warm_start_cuts_iterations() -> None:
    outer = _outer()
    outer.reset(np.zeros(3), VT)
    obs = _obstacle()
    plan = outer.update(0.0, np.zeros(3), obs, VT, PERIOD)
    first = outer.last_iterations
    x1 = np.array([np.interp(PERIOD, plan.stage_times_s, plan.states[:, c]) for c in range(3)])
    plan2 = outer.update(PERIOD, x1, obs, VT, PERIOD)
    assert not plan2.fallback
    assert outer.last_iterations < first
    assert outer.last_iterations <= 6


def test_curved_path_tracks_lane_and_matches_exact_geometry() -> None:
    path = CirclePath(400.0, 3000.0)
    outer = _outer(path)
    x0 = np.array([100.0, 0.0, 100.0 / 400.0])
    outer.reset(x0, VT)
    plan = outer.update(0.0, x0, Obstacles.empty(), VT, PERIOD)
    assert not plan.fallback
    # On the lane: J3 trades a little y and e against the omega^2 cost of turning
    # (omega = kappa V = 0.06 rad/s), mostly at the free end of the horizon (how much
    # depends on the tuned weights, hence the loose bound there).
    half = outer.n // 2
    assert np.abs(plan.states[:half, 1]).max() < 0.05
    assert np.abs(plan.states[:, 1]).max() < 0.3
    e = plan.states[:, 2] - path.gamma(plan.states[:, 0])
    assert np.abs(e).max() < 0.05
    assert np.allclose(plan.speeds_mps, VT, atol=0.5)
    # The bspline lookup of gamma/kappa reproduces the exact path in the dynamics.
    assert _euler_defect(outer, plan) < 1e-5


def test_moving_obstacle_is_predicted() -> None:
    """A slower car (15 m/s) 30 m ahead: the plan avoids its *predicted* ellipse."""
    outer = _outer()
    outer.reset(np.zeros(3), VT)
    obs = _obstacle(30.0, -0.3, vs=15.0)
    plan = outer.update(0.0, np.zeros(3), obs, VT, PERIOD)
    assert not plan.fallback
    c = ellipse_values(plan.states, plan.stage_times_s, pack_obstacles(obs))[:, 0]
    assert c[1:-1].min() > 0.0
    # A stationary-obstacle reading of the same car would not be satisfied by this plan
    # at the end of the horizon (the ego is past s = 30 m but beside it in time).
    still = ellipse_values(plan.states, np.zeros(outer.n + 1), pack_obstacles(obs))[:, 0]
    assert not np.allclose(still, c)


def test_fallback_when_ipopt_fails_is_counted_and_finite() -> None:
    outer = _outer(max_iter=1)
    outer.reset(np.zeros(3), VT)
    plan = outer.update(0.0, np.zeros(3), _obstacle(), VT, PERIOD)
    assert plan.fallback
    assert outer.fallback_count == 1
    assert np.all(np.isfinite(plan.states)) and np.all(np.isfinite(plan.speeds_mps))
    # No previous plan: brake along the lane.
    assert np.all(np.diff(plan.speeds_mps) <= 1e-12)
    assert abs(plan.states[0, 0]) < 1e-12 and np.all(np.diff(plan.states[:, 0]) >= 0)


def test_repeated_failures_fall_back_to_braking_along_the_lane() -> None:
    """A successful plan is shifted while young; after half a horizon of failures, brake."""
    outer = _outer()
    outer.reset(np.zeros(3), VT)
    obs = _obstacle()
    plan = outer.update(0.0, np.zeros(3), obs, VT, PERIOD)
    assert not plan.fallback
    outer._cold_opts["max_iter"] = outer._warm_opts["max_iter"] = 0  # every solve now fails
    t, x = 0.0, np.zeros(3)
    shifted_y = None
    for _ in range(int(0.5 * outer.tau[-1] / PERIOD) + 5):
        t += PERIOD
        x = np.array([np.interp(PERIOD, plan.stage_times_s, plan.states[:, c]) for c in range(3)])
        plan = outer.update(t, x, obs, VT, PERIOD)
        assert plan.fallback and np.all(np.isfinite(plan.states))
        if shifted_y is None:
            shifted_y = plan.states[:, 1].max()
    assert shifted_y is not None and shifted_y > 1.5  # first fallbacks: the avoiding plan
    assert np.all(np.diff(plan.speeds_mps) <= 1e-12)  # later: braking along the lane
    assert outer.fallback_count == int(0.5 * outer.tau[-1] / PERIOD) + 5


def test_bad_formulation_is_refused_naming_it() -> None:
    with pytest.raises(ParamError) as err:
        _outer(formulation="soft")
    assert err.value.field == "formulation"
    with pytest.raises(TypeError):  # C/GMRES's parameters are not Ipopt's
        IpoptOuter(StraightPath(100.0), CgmresParams())  # type: ignore[arg-type]


# ---------------------------------------------------------------- vs C/GMRES

def _frenet_path(kind: str) -> Any:
    from controllers.path.frenet import FrenetPath

    if kind == "straight":
        xy = np.array([[0.0, 0.0], [3000.0, 0.0]])
    else:  # 200 m straight, then a left arc of radius 400 m
        th = np.linspace(0.0, 1.0, 101)
        arc = np.stack([200.0 + 400.0 * np.sin(th), 400.0 - 400.0 * np.cos(th)], axis=1)
        xy = np.vstack([[[0.0, 0.0]], arc])
    return FrenetPath.from_polyline(xy)


def test_path_lookup_reproduces_the_frenet_path_exactly() -> None:
    """The CasADi B-splines re-express FrenetPath's C² quintic gamma and its kappa."""
    from controllers.two_loop.outer.ipopt_nlp import PathLookup

    path = _frenet_path("curved")
    lookup = PathLookup(path)
    s = np.linspace(-40.0, path.length_m + 250.0, 3001)
    gam = np.array([float(lookup.gamma_ca(v)) for v in s])
    kap = np.array([float(lookup.kappa_ca(v)) for v in s])
    assert np.abs(gam - path.gamma(s)).max() < 1e-10
    assert np.abs(kap - path.kappa(s)).max() < 1e-10
    assert np.abs(path.kappa(s)).max() > 2e-3  # the test path does curve


@pytest.mark.parametrize(("kind", "x0", "obs_s", "y_ref", "c_y"), [
    ("straight", (0.0, 0.0, 0.0), 40.0, 0.0, None),
    ("curved", (190.0, 0.2, 0.01), 235.0, 0.0, None),
    ("straight", (0.0, 2.8, 0.0), 40.0, 3.5, 20.0),
    ("curved", (190.0, 2.8, 0.01), 235.0, 3.5, 20.0),
])
def test_ipopt_solution_zeroes_the_cgmres_residual(kind: str, x0: tuple[float, ...],
                                                    obs_s: float, y_ref: float,
                                                    c_y: float | None) -> None:
    """Ipopt's KKT point is a root of C/GMRES's hand-derived F: the same discretised OCP.

    U = (V, omega, Z, mu = lam_g / dtau) from Ipopt, fed to spmm_ocp's residual with
    the real FrenetPath tables: ||F||inf at Ipopt's tolerance, not at the bspline
    lookup's accuracy or a formulation mismatch (those would leave O(1e-3..1)).
    Also with a lateral reference yr and a per-update Cy (``lateral_weight``) in
    Ipopt, and the same values as data of spmm_ocp's residual (started in the
    target lane's direction so that Ipopt's |omega| bound stays inactive: from y = 0
    it is active at stage 0 and F_omega != 0 there, by construction).
    """
    params = IpoptParams(c_y_terminal=0.5)
    path = _frenet_path(kind)
    x = np.asarray(x0)
    obs = _obstacle(obs_s)
    outer = _outer(path, params, tol=1e-10)
    outer.reset(x, VT)
    plan = outer.update(0.0, x, obs, VT, PERIOD, lateral_reference_m=y_ref, lateral_weight=c_y)
    assert not plan.fallback
    table = obstacle_table(outer.n_slots)
    table[0, :6] = pack_obstacles(obs)[0]
    table[0, 6] = 1.0
    ref_params = params if c_y is None else IpoptParams(c_y_terminal=0.5, c_y=c_y)
    f, xs, _ = SpmmProblem(path, ref_params).residual(outer.stage_unknowns(), x, table, VT,
                                                      lateral_reference_m=y_ref)
    if y_ref:
        assert abs(plan.states[-1, 1] - y_ref) < 0.3  # the plan settles on the reference
    assert np.abs(xs - plan.states).max() < 1e-6  # same Euler rollout (exact geometry)
    assert np.abs(f).max() < 1e-6, np.abs(f).max()
    c = ellipse_values(plan.states, plan.stage_times_s, pack_obstacles(obs))[:, 0]
    assert c[1:-1].min() > 0.05



@pytest.mark.slow
def test_plan_matches_cgmres_converged_plan() -> None:
    """From the other side: C/GMRES, run to convergence at a fixed state, lands on Ipopt's plan.

    The state and the (stalled) obstacle are held while t advances 4 s, so the
    continuation drives F -> 0 on an (almost) constant problem; its horizon has then
    grown to T (1 - e^-8). Ipopt solves the same OCP on C/GMRES's current stage grid.
    """
    cg_mod = pytest.importorskip("controllers.two_loop.outer.cgmres")
    params = CgmresParams()
    path = _frenet_path("straight")
    obs = _obstacle(40.0)
    x0 = np.zeros(3)
    cg = cg_mod.CgmresOuter(path, params, 3)
    cg.reset(x0, VT)
    cplan = None
    for k in range(200):
        cplan = cg.update(k * PERIOD, x0, obs, VT, PERIOD)
    assert cplan is not None and not cplan.fallback
    assert cplan.residual < 0.05
    ip = _outer(path, ipopt_params(params), tol=1e-10, stage_times_s=cplan.stage_times_s)
    ip.reset(x0, VT)
    iplan = ip.update(0.0, x0, obs, VT, PERIOD)
    assert not iplan.fallback
    dy = np.abs(iplan.states[:, 1] - cplan.states[:, 1]).max()
    dv = np.abs(iplan.speeds_mps - cplan.speeds_mps).max()
    # Measured: 2.5 mm and 5 mm/s with C/GMRES's E = 0.014 (GMRES-limited).
    assert dy < 0.02 and dv < 0.05, (dy, dv)


# ---------------------------------------------------------------- timing

@pytest.mark.slow
def test_hard_constraint_deadlocks_where_the_barrier_passes() -> None:
    """docs/method.md §9: with the hard ellipse inequality the SPMM stalls at the boundary.

    The ego follows its own plan (benchmark_outer). Once its state touches the ellipse
    with the heading pointing into it, the first Euler step can only be feasible with
    V_0 ~ 0 (x_1 = x_0 + V_0 dtau_0 (cos e_0, sin e_0), e_0 fixed by the measurement),
    so the car crawls. The barrier form keeps a distance and passes.
    """
    res = {}
    for form in ("barrier", "hard"):
        outer = _outer(formulation=form)
        outer.prepare(1)
        res[form] = benchmark_outer(outer, duration_s=4.0, obstacle_s_m=60.0)
        assert res[form]["fallbacks"] == 0
        assert res[form]["min_ellipse_value"] > -1e-6
    assert res["barrier"]["final_s_m"] > 60.0 + 6.8
    assert res["hard"]["final_s_m"] < 60.0


def test_benchmark_more_iterations_once_the_obstacle_enters() -> None:
    """Paper §8 result 3: Ipopt's work rises when the obstacle enters the horizon.

    Counted in iterations (deterministic), not seconds (machine-load dependent).
    """
    outer = _outer()
    outer.prepare(1)
    res = benchmark_outer(outer, duration_s=3.0, obstacle_s_m=100.0,
                          iterations=lambda: outer.last_iterations)
    assert res["updates"] == 150 and res["fallbacks"] == 0
    assert 30 < res["obstacle_entered_step"] < 50
    assert res["min_ellipse_value"] > 0.0
    assert res["iter_mean_after_entry"] > res["iter_mean_before_entry"]
    assert res["p50_s"] > 0 and math.isfinite(res["var_s2"])


# ---------------------------------------------------------------- controller

def test_factory_validates_options() -> None:
    from controllers.baselines.ipopt_nmpc import make_ipopt_nmpc

    ctrl = make_ipopt_nmpc({"formulation": "hard", "max_iter": 30, "ipopt_tol": 1e-7,
                            "c_z": 25.0})
    assert ctrl.name == "ipopt_nmpc"
    params = ctrl.parameters()
    outer = params["outer"]
    assert params["name"] == "ipopt_nmpc" and outer["formulation"] == "hard"
    assert outer["c_z"] == 25.0 and outer["max_iter"] == 30 and outer["tol"] == 1e-7
    assert "k_max" not in outer and "sub_updates" not in outer  # Ipopt's, not C/GMRES's
    assert make_ipopt_nmpc(params).parameters() == params  # round trip
    for bad, key in (({"formulation": "soft"}, "controller.outer.formulation"),
                     ({"max_iter": 0}, "controller.outer.max_iter"),
                     ({"ipopt_tol": 2.0}, "controller.outer.tol"),
                     ({"outer": "cgmres"}, "controller.outer"),
                     ({"name": "two_loop"}, "controller.name"),
                     ({"cost": "J2"}, "controller.outer.cost"),
                     ({"outer": {"cost": "J1"}}, "controller.outer.cost"),
                     ({"bogus": 1}, "controller.bogus"),
                     ({"max_iter": 1.5}, "controller.outer.max_iter"),
                     # No option is accepted and ignored: C/GMRES's are unknown here.
                     ({"outer": {"k_max": 16}}, "controller.outer.k_max"),
                     ({"k_max": 16}, "controller.outer.k_max"),
                     ({"sub_updates": 2}, "controller.outer.sub_updates"),
                     ({"outer": {"row_scaling": False}}, "controller.outer.row_scaling")):
        with pytest.raises(ConfigError) as err:
            make_ipopt_nmpc(bad)
        assert err.value.key == key, (bad, err.value)


@pytest.mark.slow
def test_closed_loop_passes_a_stalled_car() -> None:
    """Two-loop controller with the Ipopt outer loop on the STVM plant (no SUMO).

    A stalled car in the lane 110 m ahead at 25 m/s (the paper's scenario), the left
    lane free (production's behaviour, suite.run.scripted): the ego passes on the left,
    its CG never enters the car's ellipse (with the policy's
    margins, no offset: stricter than the controller's own offset ellipse on the
    pass side), the boxes never overlap, Ipopt never fails.
    """
    from controllers.baselines.ipopt_nmpc import make_ipopt_nmpc
    from suite.run.scripted import run_plant
    from suite.world.scripted import ScriptedRoad, ScriptedVehicle

    road = ScriptedRoad(np.array([[0.0, 0.0], [600.0, 0.0]]), lane_count=2)
    run = run_plant(make_ipopt_nmpc({}), road, (ScriptedVehicle("stalled", 110.0),),
                    duration_s=7.0)
    trace = run.trace
    assert not trace.safety.geom_collision.any()
    assert run.ellipse_values(margins=True)[:, 0].min() > 0.0
    assert trace.ego.s_m[-1] > 110.0 + 20.0
    assert trace.ego.lat_dev_m.max() > 2.0
    assert trace.controller.fallback.sum() == 0
    residual = trace.controller.residual
    assert np.all(np.isfinite(residual)) and residual.max() < 1e-5
    assert trace.ego.speed_mps.min() > 20.0
