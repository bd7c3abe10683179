"""Each experiment's runs reduced to the numbers of the paper's figures, and the curves
the page draws.

One frozen result per run, numbers only (:class:`CostResult`, :class:`PreviewResult`,
:class:`SolverResult`, :class:`CourseResult`), each carrying its curves separately
(:class:`Curves`: arrays for the charts, never written to the JSON). The x axis of
every curve is the distance travelled from the run's start along the reference path,
``s − s(0)`` [m], as in the paper's figures (its obstacle stands 110 m from the start).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from reports.paper.measures import (
    FloatArray,
    ResidualStats,
    TimingStats,
    energy_interval,
    highpass,
    horizon_reach_row,
    mean_square,
    obstacle_window,
    peak_abs,
    plan_lateral_error,
    residual_stats,
    rms,
    second_difference_rms,
    timing_stats,
)
from reports.paper.runs import PaperRun
from reports.record import RunRecord

NAN = math.nan
FINAL_S = 5.0  # the end of a run over which a settled offset is averaged [s]


@dataclass(frozen=True)
class Curves:
    """Per-row arrays of one run for the charts (T,) each: ``dist_m`` distance travelled
    [m]; the others in the unit their name says (NaN: not defined at that row)."""

    dist_m: FloatArray
    residual: FloatArray
    steer_rad: FloatArray
    steer_hf_rad: FloatArray
    plan_error_m: FloatArray
    lat_acc_mps2: FloatArray
    outer_ms: FloatArray
    lat_dev_m: FloatArray


def distance_travelled(record: RunRecord) -> FloatArray:
    """s − s(0) along the reference path [m], (T,)."""
    s = record.trace.ego.s_m
    return s - s[0] if s.size else s


def _at(dist_m: FloatArray, row: int) -> float:
    return float(dist_m[row]) if 0 <= row < dist_m.size else NAN


def curves_of(run: PaperRun) -> Curves:
    """The :class:`Curves` of a run (the high-pass and the plan error computed here)."""
    rec = run.record
    tr = rec.trace
    step = rec.info.step_s
    series_lat = rec.series.lat_acc_mps2 if rec.series is not None \
        else np.full(len(tr), NAN)
    err = plan_lateral_error(tr.t_s, tr.ego.x_m, tr.ego.y_m, rec.arrays.plan_xy_m, step,
                             run.variant.preview_horizon_s)
    return Curves(dist_m=distance_travelled(rec), residual=tr.controller.residual,
                  steer_rad=tr.ego.steer_rad, steer_hf_rad=highpass(tr.ego.steer_rad, step),
                  plan_error_m=err, lat_acc_mps2=series_lat,
                  outer_ms=tr.controller.outer_s * 1e3, lat_dev_m=tr.ego.lat_dev_m)


def final_offset(record: RunRecord, final_s: float = FINAL_S) -> float:
    """mean(lat_dev − lat_ref) over the trace rows of the last ``final_s`` seconds [m]:
    the CG's offset from the centre of the lane the behaviour asked for (NaN if none)."""
    tr = record.trace
    if len(tr) == 0:
        return NAN
    last = tr.t_s >= tr.t_s[-1] - final_s
    off = (tr.ego.lat_dev_m - tr.decision.lat_ref_m)[last]
    off = off[np.isfinite(off)]
    return float(np.mean(off)) if off.size else NAN


def _collisions(record: RunRecord) -> float:
    v = record.verdict
    return v.value("at_fault_collisions") if v is not None else NAN


# ----------------------------------------------------------------- (a) costs, Figs. 9-10


@dataclass(frozen=True)
class CostResult:
    """One cost's run on the straight road (Figs. 9, 10).

    ``entry_m`` / ``exit_m``: distance travelled when the stalled car enters / leaves
    the planning problem [m] (the obstacle window); ``horizon_entry_m``: when the
    horizon's far end first reaches its ellipse [m]; ``residual``: E over the window;
    ``run_max_residual`` [-] and ``run_max_at_m`` [m]: E's largest value anywhere in
    the run and where; ``steer_hf_rad2``: mean square of the steering above the
    cut-off over the window [rad²]; ``steer_d2_rms_radps2``: RMS of its second
    difference over the window [rad/s²]; ``hf_from_m`` / ``hf_to_m``: where the
    central 80 % of the window's high-frequency steering energy lies [m];
    ``max_abs_lat_dev_m``: largest lateral offset from the lane centre [m] (the car's
    path, Fig. 8); ``at_fault_collisions`` [-]."""

    run: str
    cost: str
    entry_m: float
    exit_m: float
    horizon_entry_m: float
    residual: ResidualStats
    run_max_residual: float
    run_max_at_m: float
    steer_hf_rad2: float
    steer_d2_rms_radps2: float
    hf_from_m: float
    hf_to_m: float
    max_abs_lat_dev_m: float
    at_fault_collisions: float


def analyse_cost(run: PaperRun) -> tuple[CostResult, Curves]:
    rec = run.record
    window = obstacle_window(rec.trace.decision.n_obstacles)
    c = curves_of(run)
    e = c.residual
    k_max = int(np.nanargmax(e)) if np.isfinite(e).any() else -1
    lat = peak_abs(c.lat_dev_m)
    if window is None:
        nan_stats = ResidualStats(NAN, NAN, NAN, NAN)
        return CostResult(run.name, run.variant.cost, NAN, NAN, NAN, nan_stats,
                          _at(e, k_max), _at(c.dist_m, k_max), NAN, NAN, NAN, NAN, lat,
                          _collisions(rec)), c
    hf_from, hf_to = energy_interval(c.dist_m, c.steer_hf_rad ** 2, window)
    reach = horizon_reach_row(rec.arrays.plan_xy_m, rec.arrays.ellipses)
    return CostResult(
        run=run.name, cost=run.variant.cost, entry_m=_at(c.dist_m, window.start),
        exit_m=_at(c.dist_m, window.stop - 1), horizon_entry_m=_at(c.dist_m, reach),
        residual=residual_stats(rec.trace.t_s, e, window),
        run_max_residual=_at(e, k_max), run_max_at_m=_at(c.dist_m, k_max),
        steer_hf_rad2=mean_square(c.steer_hf_rad, window),
        steer_d2_rms_radps2=second_difference_rms(c.steer_rad, rec.info.step_s, window),
        hf_from_m=hf_from, hf_to_m=hf_to, max_abs_lat_dev_m=lat,
        at_fault_collisions=_collisions(rec)), c


# -------------------------------------------------------------- (b) preview, Figs. 12-13


@dataclass(frozen=True)
class PreviewResult:
    """J3 on the curve with the preview's corrections on or off, with the paper's
    conversion (``feedforward`` False) or ours (True) (Figs. 12, 13).

    ``tau_s``: where the plan and the car are compared [s] (the preview horizon Np dt_p);
    ``error_rms_m`` / ``error_max_m``: RMS / largest |lateral error| between each plan
    and the car τ later [m] (:func:`reports.paper.measures.plan_lateral_error`), over
    the run; ``lat_acc_peak_mps2`` / ``lat_acc_rms_mps2``: largest |lateral
    acceleration| and its RMS [m/s²] (the smoothed signal the verdict judges);
    ``steer_corr_rms_rad``: RMS of the preview's steering correction δ_c [rad] (0 when
    off), split into its proportional part K_Psc PE_n (``steer_corr_p_rms_rad``) and
    its integral part δ_c − K_Psc PE_n (``steer_corr_i_rms_rad``), both [rad];
    ``final_offset_m``: mean offset of the CG from the lane the behaviour asked for
    over the run's last :data:`FINAL_S` seconds [m] (how far from its lane the car
    settles on the curve, whatever the plan); ``at_fault_collisions`` [-]."""

    run: str
    preview: bool
    feedforward: bool
    tau_s: float
    error_rms_m: float
    error_max_m: float
    lat_acc_peak_mps2: float
    lat_acc_rms_mps2: float
    steer_corr_rms_rad: float
    steer_corr_p_rms_rad: float
    steer_corr_i_rms_rad: float
    final_offset_m: float
    at_fault_collisions: float


def analyse_preview(run: PaperRun) -> tuple[PreviewResult, Curves]:
    rec = run.record
    c = curves_of(run)
    nan_col = np.full(len(rec.trace), NAN)
    corr = rec.trace.extra.get("steer_corr_rad", nan_col)
    # the integral's part as the tracker logged it (older runs: K_Psc PE_n taken as the
    # proportional part, the law before the lane-holding weight)
    if "steer_corr_integral_rad" in rec.trace.extra:
        prop = corr - rec.trace.extra["steer_corr_integral_rad"]
    else:
        prop = run.variant.k_psc_radpm * rec.trace.extra.get("preview_err_n_m", nan_col) \
            if run.variant.preview else np.zeros(len(rec.trace))

    return PreviewResult(
        run=run.name, preview=run.variant.preview, feedforward=run.variant.feedforward,
        tau_s=run.variant.preview_horizon_s, error_rms_m=rms(c.plan_error_m),
        error_max_m=peak_abs(c.plan_error_m), lat_acc_peak_mps2=peak_abs(c.lat_acc_mps2),
        lat_acc_rms_mps2=rms(c.lat_acc_mps2),
        steer_corr_rms_rad=rms(corr), steer_corr_p_rms_rad=rms(prop),
        steer_corr_i_rms_rad=rms(corr - prop), final_offset_m=final_offset(rec),
        at_fault_collisions=_collisions(rec)), c


# ------------------------------------------------------------------ (c) solvers, Fig. 15


@dataclass(frozen=True)
class SolverResult:
    """One planner on the straight road (Figs. 14, 15): ``outer`` the outer loop's time
    per step (:class:`TimingStats`, [s]); ``step_mean_s``: the whole behaviour +
    controller step, mean [s]; ``at_fault_collisions`` and ``min_gap_m`` [m]: did it
    avoid the stalled car."""

    run: str
    solver: str
    outer: TimingStats
    step_mean_s: float
    at_fault_collisions: float
    min_gap_m: float


def analyse_solver(run: PaperRun) -> tuple[SolverResult, Curves]:
    rec = run.record
    c = curves_of(run)
    with_obstacle = rec.trace.decision.n_obstacles > 0
    step = rec.trace.timing.controller_s
    step = step[np.isfinite(step)]
    v = rec.verdict
    return SolverResult(
        run=run.name, solver=run.variant.solver,
        outer=timing_stats(rec.trace.controller.outer_s, with_obstacle),
        step_mean_s=float(np.mean(step)) if step.size else NAN,
        at_fault_collisions=_collisions(rec),
        min_gap_m=v.value("min_gap_m") if v is not None else NAN), c


# ------------------------------------------------------------ (d) obstacles on a curve


@dataclass(frozen=True)
class CourseResult:
    """Several stalled cars along a curved road (the experiments' spirit).

    ``obstacles``: stalled cars in the scenario; ``passed``: those whose position along
    the reference the car's CG got beyond [-]; ``at_fault_collisions``, ``min_gap_m``
    [m], ``lat_acc_peak_mps2`` [m/s²], ``error_rms_m`` (plan vs car, as in
    :class:`PreviewResult`) [m], ``residual_max`` [-], ``fallbacks`` (steps) [-];
    ``step_mean_s``: the controller's outer + inner loop per step, mean [s] (the
    paper's experiment quotes the same sum); ``status``: the run's verdict."""

    run: str
    obstacles: int
    passed: int
    at_fault_collisions: float
    min_gap_m: float
    lat_acc_peak_mps2: float
    error_rms_m: float
    residual_max: float
    fallbacks: float
    step_mean_s: float
    status: str


def arc_length_along(points_xy: FloatArray, polyline_xy: FloatArray) -> FloatArray:
    """Arc length [m] of each point's nearest point on the polyline, (P,) from (P, 2)
    and (M, 2) [m]; NaN for a polyline of fewer than two points."""
    if polyline_xy.shape[0] < 2 or points_xy.shape[0] == 0:
        return np.full(points_xy.shape[0], NAN)
    start = polyline_xy[:-1]
    seg = np.diff(polyline_xy, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    s0 = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    rel = points_xy[:, None, :] - start[None, :, :]
    frac = np.clip(np.sum(rel * seg, axis=2) / np.where(length > 0, length ** 2, 1.0), 0, 1)
    near = start + frac[:, :, None] * seg
    dist = np.hypot(points_xy[:, None, 0] - near[:, :, 0], points_xy[:, None, 1] - near[:, :, 1])
    j = np.argmin(dist, axis=1)
    rows = np.arange(points_xy.shape[0])
    out: FloatArray = s0[j] + frac[rows, j] * length[j]
    return out


def analyse_course(run: PaperRun) -> tuple[CourseResult, Curves]:
    rec = run.record
    c = curves_of(run)
    stalled = np.array([[v.x_m, v.y_m] for v in rec.outcome.stalled]).reshape(-1, 2)
    s_stalled = arc_length_along(stalled, rec.road.reference_xy_m)
    s_end = float(np.nanmax(rec.trace.ego.s_m)) if len(rec.trace) else NAN
    loops = rec.trace.controller.outer_s + rec.trace.controller.inner_s
    loops = loops[np.isfinite(loops)]
    v = rec.verdict
    return CourseResult(
        run=run.name, obstacles=int(stalled.shape[0]),
        passed=int(np.sum(np.isfinite(s_stalled) & (s_stalled < s_end))),
        at_fault_collisions=_collisions(rec),
        min_gap_m=v.value("min_gap_m") if v is not None else NAN,
        lat_acc_peak_mps2=peak_abs(c.lat_acc_mps2), error_rms_m=rms(c.plan_error_m),
        residual_max=v.value("residual_max") if v is not None else NAN,
        fallbacks=v.value("fallbacks") if v is not None else NAN,
        step_mean_s=float(np.mean(loops)) if loops.size else NAN, status=rec.status), c


@dataclass(frozen=True)
class Analysed:
    """Every experiment's results with their curves, in the directory's run order."""

    costs: tuple[tuple[CostResult, Curves], ...]
    preview: tuple[tuple[PreviewResult, Curves], ...]
    solvers: tuple[tuple[SolverResult, Curves], ...]
    course: tuple[tuple[CourseResult, Curves], ...]


def analyse(costs: Sequence[PaperRun], preview: Sequence[PaperRun],
            solvers: Sequence[PaperRun], course: Sequence[PaperRun]) -> Analysed:
    """Results of each experiment's runs (the costs sorted J1, J2, J3; the preview runs
    by conversion then preview on first; C/GMRES before Ipopt)."""
    cost_order = sorted(costs, key=lambda r: r.variant.cost)
    prev_order = sorted(preview, key=lambda r: (r.variant.feedforward, not r.variant.preview))
    solver_order = sorted(solvers, key=lambda r: r.variant.controller != "two_loop")
    return Analysed(costs=tuple(analyse_cost(r) for r in cost_order),
                    preview=tuple(analyse_preview(r) for r in prev_order),
                    solvers=tuple(analyse_solver(r) for r in solver_order),
                    course=tuple(analyse_course(r) for r in course))
