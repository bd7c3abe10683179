"""``ipopt_nmpc``: the two-loop controller with the Ipopt outer loop (docs/method.md §8).

The same :class:`controllers.two_loop.controller.TwoLoopController` (Frenet
projection, lateral-reference shaper, launch supervisor, preview inner loop, obstacle
policy) with :class:`controllers.two_loop.outer.ipopt_planner.IpoptOuter` as its planner: the
same Euler-discretised J3 problem solved to convergence by Ipopt at every control
period (one update per period).

Options: :class:`controllers.two_loop.params.IpoptNmpcParams`, i.e. ``two_loop``'s
sections with ``outer`` = :class:`controllers.two_loop.outer.params.IpoptParams`: the
OCP (J3 only) plus ``formulation`` ("barrier": C/GMRES's slack + log barrier, plans
comparable to C/GMRES; "hard": the paper's hard ellipse inequality c_j >= 0, no
barrier, see docs/two_loop.md "Ipopt baseline"), ``max_iter`` and ``tol``. The
C/GMRES-only options (k_max, zeta_s, fd_step, sub_updates, horizon_growth_rate,
z_guard, row_scaling, obstacle_fade_s, fallback_residual, fallback_hold_s) are unknown
keys here. Flat aliases: :data:`controllers.two_loop.params.IPOPT_FLAT_ALIASES`.

The factory is cheap (validation only: no CasADi import, no NLP); the NLPs are built
at ``reset``, for K = 0..max_obstacles obstacles, and cached per path. It needs
CasADi (the 'baselines' extra) to run; ``controllers.builtin`` lists it only then.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controllers.two_loop.controller import TwoLoopController, ipopt_planner
from controllers.two_loop.params import ipopt_nmpc_params

NAME = "ipopt_nmpc"


def make_ipopt_nmpc(options: Mapping[str, Any]) -> TwoLoopController:
    """``ipopt_nmpc`` from catalog options; raises ConfigError naming the dotted key."""
    params = ipopt_nmpc_params(options)
    return TwoLoopController(params, ipopt_planner(params), name=NAME)
