"""``ipopt_nmpc``: the two-loop controller with the Ipopt outer loop (METHOD.md §8, result 3).

Same conversion, preview inner loop, Frenet projection and obstacle policy as
``two_loop`` (:class:`controllers.two_loop.controller.TwoLoopController`, reused through its
``outer_factory``); only the outer solver differs:
:class:`controllers.two_loop.outer.ipopt.IpoptOuter`, which solves the same
Euler-discretised J3 problem to convergence with Ipopt at every control period
(one update per period; the C/GMRES-only keys k_max, zeta_s, fd_step, sub_updates,
horizon_growth_rate, z_guard, fallback_residual are accepted and ignored).

Options: every ``two_loop`` key (``outer`` must be "ipopt" if given) plus

* ``formulation``: "barrier" (default; C/GMRES's slack + log barrier, plans
  comparable to C/GMRES) or "hard" (the paper's hard ellipse inequality c_j >= 0,
  no barrier). The hard plans ride on the ellipse boundary: with the plan followed
  exactly the SPMM deadlocks there (METHOD §9); on the STVM plant the CG dips
  inside (infeasible NLP -> fallbacks) and, since the offset OS (0.3 m) eats into
  the lateral margin (0.4 m) on the pass side, the boxes touched in our runs.
* ``max_iter`` (int >= 1, default 100): Ipopt's iteration limit per update.
* ``ipopt_tol`` (float in (0, 1), default 1e-6): Ipopt's ``tol``.

The factory is cheap (validation only); the NLPs are built at ``reset``, for
K = 0..max_obstacles obstacles, and cached per path.
"""

from __future__ import annotations

import importlib.util
from collections.abc import Mapping
from typing import Any

from controllers.path.frenet import FrenetPath
from controllers.protocol import ConfigError
from controllers.registry import check_options
from controllers.two_loop.controller import _OPTION_TYPES, TwoLoopController, TwoLoopParams
from controllers.two_loop.outer.ipopt import FORMULATIONS
from controllers.two_loop.outer.ocp import OuterParams

if importlib.util.find_spec("casadi") is None:  # builtin.py registers us only with CasADi
    raise ImportError("ipopt_nmpc needs CasADi (pip install 'hwyeval[baselines]')")

NAME = "ipopt_nmpc"
_DEFAULTS: dict[str, Any] = {"formulation": "barrier", "max_iter": 100, "ipopt_tol": 1e-6}
_OWN_TYPES: dict[str, type | tuple[type, ...]] = {
    "formulation": str, "max_iter": int, "ipopt_tol": (int, float)}


class IpoptNmpcController(TwoLoopController):
    """TwoLoopController whose outer solver is IpoptOuter (see the module docstring)."""

    name = NAME

    def __init__(self, params: TwoLoopParams | None = None, *, formulation: str = "barrier",
                 max_iter: int = 100, ipopt_tol: float = 1e-6) -> None:
        self.formulation = formulation
        self.max_iter = max_iter
        self.ipopt_tol = ipopt_tol
        super().__init__(params or TwoLoopParams(outer="ipopt"),
                         outer_factory=self._make_outer)

    def _make_outer(self, path: FrenetPath, outer_params: OuterParams) -> Any:
        from controllers.two_loop.outer.ipopt import IpoptOuter

        outer = IpoptOuter(path, outer_params, formulation=self.formulation,
                           max_iter=self.max_iter, tol=self.ipopt_tol)
        outer.prepare(self.params.max_obstacles)  # NLPs built at reset, not mid-run
        return outer

    def parameters(self) -> dict[str, Any]:
        out = super().parameters()
        out.update({"name": NAME, "formulation": self.formulation, "max_iter": self.max_iter,
                    "ipopt_tol": self.ipopt_tol})
        return out


def make_ipopt_nmpc(options: Mapping[str, Any]) -> IpoptNmpcController:
    """Validate flat options (cheap: no CasADi import, no NLP) and build the controller."""
    allowed = dict(_OPTION_TYPES)
    allowed.update(_OWN_TYPES)
    check_options(options, allowed)
    opts = dict(options)
    name = opts.pop("name", NAME)
    if name != NAME:
        raise ConfigError("controller.name", f"'{NAME}'", name)
    if opts.get("outer", "ipopt") != "ipopt":
        raise ConfigError("controller.outer", "'ipopt' (or leave it out)", opts["outer"])
    own = {key: opts.pop(key, default) for key, default in _DEFAULTS.items()}
    if own["formulation"] not in FORMULATIONS:
        raise ConfigError("controller.formulation", f"one of {list(FORMULATIONS)}",
                          own["formulation"])
    if own["max_iter"] < 1:
        raise ConfigError("controller.max_iter", "an integer >= 1", own["max_iter"])
    if not 0 < own["ipopt_tol"] < 1:
        raise ConfigError("controller.ipopt_tol", "a number in (0, 1)", own["ipopt_tol"])
    opts["outer"] = "ipopt"
    params = TwoLoopParams(**opts)
    if params.cost != "J3":
        raise ConfigError("controller.cost", "'J3' (the Ipopt baseline solves J3)", params.cost)
    return IpoptNmpcController(params, formulation=str(own["formulation"]),
                               max_iter=int(own["max_iter"]),
                               ipopt_tol=float(own["ipopt_tol"]))
