"""Parameters of the outer loop: the OCP both planners solve, and each solver's own.

:class:`OcpParams` is the discretised problem of :mod:`controllers.two_loop.outer.ocp`
(docs/method.md §2-§4): cost, horizon and stages, weights, barrier, target-speed ramp
and terminal weights, plus the deceleration of the brake-along-the-lane plan every
planner falls back on. :class:`CgmresParams` adds what only C/GMRES has (continuation,
Krylov size, growing horizon, guard, row scaling, obstacle fade, its fallback test);
:class:`IpoptParams` what only the Ipopt baseline has. Each is the ``outer`` section
of its controller (``two_loop`` / ``ipopt_nmpc``), so an option of the other solver
is an unknown key there, never accepted and ignored.

The number of obstacle slots K is not an OCP option: it is the obstacle policy's
``max_obstacles`` (one knob), handed to the planners as ``n_slots``.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Literal

from controllers.params import ParamError, check_leaves, check_range, param

Cost = Literal["J1", "J2", "J3"]
Formulation = Literal["barrier", "hard"]
COSTS: tuple[Cost, ...] = ("J1", "J2", "J3")
FORMULATIONS: tuple[Formulation, ...] = ("barrier", "hard")


@dataclass(frozen=True)
class OcpParams:
    """The outer-loop OCP shared by C/GMRES and Ipopt (docs/method.md §2-§4, §9).

    Running costs (e = theta - gamma(s), f1 = ds/dt, f2 = dy/dt):
    J1 = Cy (y - yr)² + Ctheta e² + CV (V - Vt)², J2 = Cy (y - yr)² + Cyd f2² +
    Csd (f1 - Vt)², J3 = J2 + Cthd omega², each minus sigma Cz sum_j ln(Z_j + zeta) and
    plus Cvn min(V, 0)² and C_lane (max(0, y - y_hi)² + max(0, y_lo - y)²) (the lane
    corridor [y_lo, y_hi] of the update, docs/two_loop.md "Lane corridor").
    sigma = clip(v / barrier_speed_mps, barrier_min_scale, 1), v the
    problem's speed scale (the larger of Vt and the planned speed now).
    Terminal: CyT (y_N - yr)² + CeT e_N² (CeT for J3 only).

    Target speed Vt: the set-point through the jerk-limited ramp
    (:class:`controllers.two_loop.outer.target_ramp.TargetSpeedRamp`), from the measured speed at
    a (re)start: acceleration up to ``target_accel_mps2``, deceleration up to
    ``set_speed_decel_mps2`` toward the run's cruise set-point and ``target_decel_mps2``
    toward a set-point the behaviour lowered below it (following), jerk up to
    ``target_jerk_mps3``.
    """

    cost: Cost = param("J3", "-", "running cost: J1, J2 or J3 (docs/method.md §3)")
    horizon_s: float = param(2.4, "s", "prediction horizon T")
    n_stages: int = param(20, "-", "stages N of the horizon")
    chebyshev: bool = param(False, "-", "Chebyshev stage spacing instead of uniform")
    c_y: float = param(1.0, "1/(m² s)", "Cy: lateral offset from the reference")
    c_ydot: float = param(1.0, "s/m²", "Cyd: lateral speed f2 (J2, J3)")
    c_sdot: float = param(3.0, "s/m²", "Csd: progress speed f1 - Vt (J2, J3)")
    c_thetadot: float = param(60.0, "s/rad²", "Cthd: heading rate omega (J3)")
    c_theta: float = param(20.0, "1/(rad² s)", "Ctheta: heading error e (J1)")
    c_v: float = param(1.0, "s/m²", "CV: speed error V - Vt (J1)")
    c_z: float = param(30.0, "1/s", "Cz: weight of the log barrier on the slacks")
    zeta: float = param(0.2, "-", "barrier offset: ln(Z + zeta)")
    barrier_speed_mps: float = param(10.0, "m/s", "speed scale from which the barrier has "
                                     "its full weight Cz (below: Cz v / barrier_speed_mps)")
    barrier_min_scale: float = param(0.03, "-", "the barrier weight's least fraction of Cz "
                                     "(at standstill)")
    c_v_negative: float = param(300.0, "s/m²", "Cvn: penalty Cvn min(V, 0)² on a negative "
                                "planned speed")
    c_lane: float = param(200.0, "1/(m² s)", "C_lane: exterior penalty C_lane d² on the "
                          "distance d of y outside the lane corridor")
    c_y_terminal: float = param(0.0, "1/m²", "CyT: terminal lateral offset")
    c_e_terminal: float = param(2.0, "1/rad²", "CeT: terminal heading error (J3)")
    target_accel_mps2: float = param(1.5, "m/s²", "target-speed ramp: acceleration limit")
    target_decel_mps2: float = param(3.0, "m/s²", "target-speed ramp: deceleration limit "
                                     "toward a set-point lowered to follow")
    set_speed_decel_mps2: float = param(1.5, "m/s²", "target-speed ramp: deceleration limit "
                                        "toward the cruise set-point")
    target_jerk_mps3: float = param(2.0, "m/s³", "target-speed ramp: jerk limit")
    fallback_decel_mps2: float = param(3.0, "m/s²",
                                       "deceleration of the brake-along-the-lane plan")

    def __post_init__(self) -> None:
        check_leaves(self)
        check_range(self, "barrier_min_scale", gt=0.0, le=1.0)
        for name in ("horizon_s", "c_z", "zeta", "barrier_speed_mps", "target_accel_mps2",
                     "target_decel_mps2", "set_speed_decel_mps2", "target_jerk_mps3",
                     "fallback_decel_mps2"):
            check_range(self, name, gt=0.0)
        for name in ("c_y", "c_ydot", "c_sdot", "c_thetadot", "c_theta", "c_v",
                     "c_y_terminal", "c_e_terminal", "c_v_negative", "c_lane"):
            check_range(self, name, ge=0.0)
        check_range(self, "n_stages", ge=2, le=400)
        if self.cost == "J3" and self.c_thetadot <= 0:
            raise ParamError("c_thetadot", "a number > 0 for J3 (H_omega is linear in it)",
                             self.c_thetadot)
        if self.cost in ("J2", "J3"):
            for name in ("c_sdot", "c_ydot"):
                check_range(self, name, gt=0.0)
        if self.cost == "J1":
            for name in ("c_theta", "c_v"):
                check_range(self, name, gt=0.0)

    @property
    def cost_id(self) -> int:
        """1, 2 or 3 (the compiled kernels' cost switch)."""
        return COSTS.index(self.cost) + 1


@dataclass(frozen=True)
class CgmresParams(OcpParams):
    """``two_loop``'s outer loop: the OCP plus the C/GMRES solver (docs/method.md §5, §9)."""

    k_max: int = param(12, "-", "GMRES (Krylov) iterations per update")
    zeta_s: float = param(50.0, "1/s", "continuation gain: dF/dt = -zeta_s F")
    fd_step: float = param(1e-6, "s", "forward-difference step h (also along U)")
    sub_updates: int = param(3, "-", "continuation updates per control period")
    horizon_growth_rate: float = param(2.0, "1/s",
                                       "growing horizon T (1 - exp(-rate (t - t_init)))")
    z_guard: float = param(0.05, "-", "guard: Z + zeta kept >= z_guard after each update")
    row_scaling: bool = param(True, "-", "GMRES on D(U) F (diagonal row scaling)")
    obstacle_fade_s: float = param(0.5, "s", "barrier weight fade of an obstacle in and out")
    fallback_residual: float = param(50.0, "-",
                                     "residual E (largest entry of F) above which it restarts")
    diverging_residual: float = param(5.0, "-", "residual E that, held for diverging_s, is a "
                                      "diverging continuation: it restarts too")
    diverging_s: float = param(0.2, "s", "how long E may stay above diverging_residual")
    fallback_hold_s: float = param(1.0, "s", "duration of the braking plan after a restart")

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("zeta_s", "horizon_growth_rate", "z_guard", "obstacle_fade_s",
                     "fallback_residual", "diverging_residual", "diverging_s"):
            check_range(self, name, gt=0.0)
        if self.diverging_residual > self.fallback_residual:
            raise ParamError("diverging_residual",
                             f"a number <= fallback_residual = {self.fallback_residual}",
                             self.diverging_residual)
        check_range(self, "fd_step", gt=0.0, lt=1e-2)
        check_range(self, "fallback_hold_s", ge=0.0)
        check_range(self, "k_max", ge=1, le=200)
        check_range(self, "sub_updates", ge=1, le=100)
        if self.z_guard >= self.zeta:
            raise ParamError("z_guard", f"a number < zeta = {self.zeta}", self.z_guard)


@dataclass(frozen=True)
class IpoptParams(OcpParams):
    """``ipopt_nmpc``'s outer loop: the OCP (J3 only) solved by Ipopt every period."""

    formulation: Formulation = param(
        "barrier", "-", "'barrier': C/GMRES's slack + log barrier; 'hard': c_j >= 0")
    max_iter: int = param(100, "-", "Ipopt's iteration limit per update")
    tol: float = param(1e-6, "-", "Ipopt's convergence tolerance 'tol'")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.cost != "J3":
            raise ParamError("cost", "'J3' (the Ipopt baseline solves J3)", self.cost)
        check_range(self, "max_iter", ge=1)
        check_range(self, "tol", gt=0.0, lt=1.0)


def ocp_part(params: OcpParams) -> dict[str, object]:
    """The :class:`OcpParams` fields of ``params`` (of any outer-loop class), by name."""
    return {f.name: getattr(params, f.name) for f in fields(OcpParams)}


def ipopt_params(ocp: OcpParams, **solver: Any) -> IpoptParams:
    """Ipopt's outer loop on the same OCP as ``ocp`` (e.g. a C/GMRES one); ``solver``
    sets :class:`IpoptParams`' own fields (formulation, max_iter, tol)."""
    return IpoptParams(**ocp_part(ocp), **solver)  # type: ignore[arg-type]
