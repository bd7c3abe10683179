"""The paper's findings, each stated, tested on our runs and explained, and the table of
numbers (one row per quantity) that the page, the JSON/CSV files and the README show.

A :class:`Finding` holds (True), does not (False) or cannot be judged (None: the runs
it needs are missing). Its ``evidence`` quotes our numbers; ``why`` says, from the runs,
why it does not hold (or what qualifies it when it does). Nothing here is a stored
result: every number comes from the results of :mod:`reports.paper.results`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from reports.paper.measures import ENERGY_SHARE, STEER_CUTOFF_HZ
from reports.paper.reference import PAPER
from reports.paper.results import (
    Analysed,
    CostResult,
    CourseResult,
    PreviewResult,
    SolverResult,
)

FAR_MORE = 10.0
"""Our reading of the paper's "far more variable": a variance at least ten times larger."""


def num(value: float, digits: int = 3) -> str:
    """``digits`` significant digits, in plain notation from 0.001 to below 10 000 (whole
    numbers keep all their digits there: 1319, not 1.32e+03), else as 5.07e-6 or
    1.42e5; '–' for NaN, '∞' for infinity."""
    if not math.isfinite(value):
        return "–" if math.isnan(value) else ("∞" if value > 0 else "−∞")
    if value == 0:
        return "0"
    mag = math.floor(math.log10(abs(value)))
    if 1e-3 <= abs(value) < 1e4:
        decimals = max(0, digits - 1 - mag)
        text = f"{round(value, decimals):.{decimals}f}"
        if "." in text:
            text = text.rstrip("0").rstrip(".")
        return text
    mantissa, _, exponent = f"{value:.{digits - 1}e}".partition("e")
    if "." in mantissa:
        mantissa = mantissa.rstrip("0").rstrip(".")
    return f"{mantissa}e{int(exponent)}"


def ratio(a: float, b: float) -> float:
    """a / b (NaN unless both are finite and b > 0)."""
    return a / b if math.isfinite(a) and math.isfinite(b) and b > 0 else math.nan


@dataclass(frozen=True)
class Finding:
    """One of the paper's findings on our runs: ``key`` (stable id), ``figure``,
    ``claim`` (the paper's statement, in our words), ``holds``, ``evidence`` (our
    numbers), ``why`` (why it does not hold, or what qualifies it) and ``timing`` (it is
    judged on wall-clock times, so its verdict may change from run to run)."""

    key: str
    figure: str
    claim: str
    holds: bool | None
    evidence: str
    why: str = ""
    timing: bool = False

    @property
    def verdict(self) -> str:
        return {True: "holds", False: "does not hold", None: "not measured"}[self.holds]


@dataclass(frozen=True)
class NumberRow:
    """One quantity of the results table: ``key`` (stable id), ``figure``,
    ``quantity`` (with the variants it lists, in order), ``unit``, ``values`` (ours,
    one per variant, in ``unit``), ``joiner`` (' / ' between variants, '–' for a
    from–to interval), ``paper`` (the paper's value as text, '–' where it gives
    none), ``timing`` (a wall-clock measurement: it changes from run to run and with
    the machine's load)."""

    key: str
    figure: str
    quantity: str
    unit: str
    values: tuple[float, ...]
    joiner: str = " / "
    paper: str = "–"
    timing: bool = False

    @property
    def ours(self) -> str:
        """The values as the table shows them (3 significant digits)."""
        return self.joiner.join(num(v) for v in self.values) if self.values else "–"


# ------------------------------------------------------------------------ selection


def _cost(costs: Sequence[CostResult], name: str) -> CostResult | None:
    return next((c for c in costs if c.cost == name), None)


def _preview(results: Sequence[PreviewResult], preview: bool, ff: bool
             ) -> PreviewResult | None:
    return next((r for r in results if r.preview == preview and r.feedforward == ff), None)


def _solver(results: Sequence[SolverResult], name: str) -> SolverResult | None:
    return next((r for r in results if r.solver == name), None)


def _missing(key: str, figure: str, claim: str, what: str) -> Finding:
    return Finding(key, figure, claim, None, f"no {what} in this directory")


# ------------------------------------------------------------------- Figs. 9 and 10


def _versus(j1: CostResult, others: Sequence[CostResult],
            value: Callable[[CostResult], float], unit: str) -> tuple[bool, str, str]:
    """(J1 above every other, the evidence text, the costs J1 is not above)."""
    v1 = value(j1)
    parts = [f"J1 {num(v1)}{unit}"]
    not_above = []
    for o in others:
        vo = value(o)
        parts.append(f"{o.cost} {num(vo)}{unit} (J1 ×{num(ratio(v1, vo), 2)})")
        if not v1 > vo:
            not_above.append(o.cost)
    return not not_above, ", ".join(parts), ", ".join(not_above)


def cost_findings(costs: Sequence[CostResult]) -> list[Finding]:
    """Figs. 9-10: J1's residual larger and slower to decay, its steering rougher."""
    claims = (("fig9_residual", "Fig. 9", "J1's residual E is larger than J2's and J3's "
               "while the obstacle is in the problem"),
              ("fig9_decay", "Fig. 9", "J1's residual decays more slowly"),
              ("fig10_steering", "Fig. 10", "J1 steers with more high-frequency content "
               "(chatter) than J2 and J3"))
    j1 = _cost(costs, "J1")
    others = [c for c in (_cost(costs, "J2"), _cost(costs, "J3")) if c is not None]
    if j1 is None or not others:
        return [_missing(k, f, c, "J1 run and J2/J3 run of paper_costs") for k, f, c in claims]
    out = []
    ok, text, which = _versus(j1, others, lambda c: c.residual.rms, "")
    window = f"{num(j1.entry_m)}–{num(j1.exit_m)} m travelled"
    out.append(Finding(*claims[0], ok, f"RMS of E over the obstacle window ({window}): {text}",
                       "" if ok else f"J1's RMS is not above {which}'s: the obstacle window "
                       f"lasts only until the car is in the next lane ({window}), the "
                       "behaviour's lane change reference then takes it out of the problem"))
    ok, text, which = _versus(j1, others, lambda c: c.residual.decay_s, " s")
    peaks = ", ".join(f"{c.cost} {num(c.residual.peak_after_s)} s" for c in (j1, *others))
    out.append(Finding(*claims[1], ok, f"decay time τ_E: {text}; E peaks after entry: {peaks}",
                       "" if ok else f"τ_E of J1 is not above {which}'s: the window ends "
                       f"when the car has changed lane ({num(j1.exit_m)} m), before a "
                       "residual that stays up can show it"))
    ok, text, which = _versus(j1, others, lambda c: c.steer_hf_rad2, " rad²")
    where = (f"J1's high-frequency steering lies at {num(j1.hf_from_m)}–{num(j1.hf_to_m)} m "
             f"travelled; the obstacle entered the problem at {num(j1.entry_m)} m (the "
             f"paper: {num(PAPER.chatter_from_m)}–{num(PAPER.chatter_to_m)} m, after its "
             f"obstacle entered the horizon at ≈ {num(PAPER.window_entry_m)} m)")
    out.append(Finding(*claims[2], ok, f"mean square above {num(STEER_CUTOFF_HZ)} Hz: {text}",
                       where if ok else f"J1 is not rougher than {which}. {where}"))
    return out


# ------------------------------------------------------------------- Figs. 12 and 13


def _preview_pair(results: Sequence[PreviewResult], ff: bool, key: str, figure: str,
                  claim: str, value: Callable[[PreviewResult], float], unit: str,
                  why_not: Callable[[PreviewResult, PreviewResult], str]) -> Finding:
    on, off = _preview(results, True, ff), _preview(results, False, ff)
    if on is None or off is None:
        return _missing(key, figure, claim, "preview on/off pair of paper_preview with "
                        f"feed-forward {'on' if ff else 'off'}")
    a, b = value(on), value(off)
    ok = bool(a < b)
    text = f"preview on {num(a)} {unit}, off {num(b)} {unit} (on/off ×{num(ratio(a, b))})"
    return Finding(key, figure, claim, ok, text, "" if ok else why_not(on, off))


def _why_ff(on: PreviewResult, off: PreviewResult) -> str:
    return (f"with our cornering feed-forward the car already follows each plan to "
            f"{num(off.error_rms_m)} m RMS without the preview; its corrections act on "
            f"what is left (δ_c RMS {num(on.steer_corr_rms_rad)} rad, of which the integral "
            f"of PE_n {num(on.steer_corr_i_rms_rad)} rad and the proportional part "
            f"{num(on.steer_corr_p_rms_rad)} rad) and did not lower it here")


def _why_ff_lat(on: PreviewResult, off: PreviewResult) -> str:
    return (f"the preview's corrections (δ_c RMS {num(on.steer_corr_rms_rad)} rad, "
            f"{num(on.steer_corr_i_rms_rad)} rad of it from the integral of PE_n) add to "
            "the feed-forward's steering where the car already follows the plan")


def _why_paper(on: PreviewResult, off: PreviewResult) -> str:
    return (f"with the paper's conversion the preview's corrections (δ_c RMS "
            f"{num(on.steer_corr_rms_rad)} rad) did not lower it here")


def _why_paper_lat(on: PreviewResult, off: PreviewResult) -> str:
    """Fig. 13 with the paper's conversion: the car without the preview has the lower
    peak by not following its plans (measured: its error to them, where it settles and
    its lateral acceleration's RMS beside the preview's)."""
    return (f"without the preview the car does not follow its plans (RMS error "
            f"{num(off.error_rms_m)} m against {num(on.error_rms_m)} m with it) and settles "
            f"{num(abs(off.final_offset_m))} m from its lane's centre on the curve "
            f"({num(abs(on.final_offset_m))} m with it): its lower peak comes with not doing "
            f"what its plans ask; the lateral acceleration's RMS is "
            f"{num(off.lat_acc_rms_mps2)} m/s² without the preview and "
            f"{num(on.lat_acc_rms_mps2)} m/s² with it")


def preview_findings(results: Sequence[PreviewResult]) -> list[Finding]:
    """Figs. 12-13 with the paper's conversion, and again with our feed-forward."""
    out = []
    for ff, label, why, why_lat in (
            (False, "the paper's conversion (13)-(14)", _why_paper, _why_paper_lat),
            (True, "our conversion with the cornering feed-forward", _why_ff, _why_ff_lat)):
        suffix = "_ff" if ff else ""
        out.append(_preview_pair(
            results, ff, f"fig12_error{suffix}", "Fig. 12",
            f"the preview lowers the lateral error between plan and car on the curve, "
            f"with {label}", lambda r: r.error_rms_m, "m", why))
        out.append(_preview_pair(
            results, ff, f"fig13_lat_acc{suffix}", "Fig. 13",
            f"the preview lowers the peak lateral acceleration on the curve, with {label}",
            lambda r: r.lat_acc_peak_mps2, "m/s²", why_lat))
    return out


# ------------------------------------------------------------------- Figs. 14 and 15


def solver_findings(results: Sequence[SolverResult]) -> list[Finding]:
    """Fig. 14: both avoid the obstacle; Fig. 15: Ipopt slower, far more variable, and
    slower while the obstacle is in the problem."""
    cg, ip = _solver(results, "C/GMRES"), _solver(results, "Ipopt")
    claims = (("fig14_avoid", "Fig. 14", "both planners avoid the obstacle"),
              ("fig15_mean", "Fig. 15", "Ipopt's time per step is larger than C/GMRES's"),
              ("fig15_variance", "Fig. 15", "Ipopt's time per step is far more variable "
               f"(our reading: a variance ≥ {num(FAR_MORE)}× C/GMRES's)"),
              ("fig15_rise", "Fig. 15", "Ipopt's time rises while the obstacle is in its "
               "horizon"))
    if cg is None or ip is None:
        return [_missing(k, f, c, "two_loop/ipopt_nmpc pair of paper_solvers")
                for k, f, c in claims]
    out = [_avoid(claims[0], cg, ip)]
    out += [replace(f, timing=True) for f in _timing_findings(claims[1:], cg, ip)]
    return out


def _avoid(claim: tuple[str, str, str], cg: SolverResult, ip: SolverResult) -> Finding:
    avoid = cg.at_fault_collisions == 0 and ip.at_fault_collisions == 0
    return Finding(*claim, avoid, f"at-fault collisions C/GMRES {num(cg.at_fault_collisions)}"
                   f", Ipopt {num(ip.at_fault_collisions)}; smallest gap {num(cg.min_gap_m)} m "
                   f"/ {num(ip.min_gap_m)} m", "" if avoid else "a planner hit the stalled car")


def _timing_findings(claims: Sequence[tuple[str, str, str]], cg: SolverResult,
                     ip: SolverResult) -> list[Finding]:
    out = []
    r_mean = ratio(ip.outer.mean, cg.outer.mean)
    out.append(Finding(*claims[0], bool(r_mean > 1), f"outer loop per step, mean: C/GMRES "
                       f"{num(cg.outer.mean * 1e3)} ms, Ipopt {num(ip.outer.mean * 1e3)} ms "
                       f"(×{num(r_mean)}); median ×{num(ratio(ip.outer.p50, cg.outer.p50))}",
                       "" if r_mean > 1 else "the warm-started Ipopt solved the problem "
                       "faster than C/GMRES's fixed update on this run"))
    r_var = ratio(ip.outer.var, cg.outer.var)
    r_rob = ratio(ip.outer.var_robust, cg.outer.var_robust)
    far = bool(r_rob >= FAR_MORE)
    preempted = (f"the raw variances hold the steps on which the operating system preempted "
                 f"the process (C/GMRES: median {num(cg.outer.p50 * 1e3)} ms, largest "
                 f"{num(cg.outer.max * 1e3)} ms), which do not depend on the solver; the "
                 "judgement uses the spread of the solvers' own times (from the median "
                 "absolute deviation)")
    out.append(Finding(
        *claims[1], far, f"variance C/GMRES {num(cg.outer.var)} s², Ipopt {num(ip.outer.var)}"
        f" s² (×{num(r_var)}); from the median absolute deviation ×{num(r_rob)} (the paper: "
        f"{num(PAPER.cgmres_var_s2)} s² and {num(PAPER.ipopt_var_s2)} s², ×{num(PAPER.var_ratio)})",
        preempted if far else f"Ipopt's spread is only ×{num(r_rob)} C/GMRES's"))
    r_ip = ratio(ip.outer.p50_obstacle, ip.outer.p50_free)
    r_cg = ratio(cg.outer.p50_obstacle, cg.outer.p50_free)
    # A rise counts when it exceeds C/GMRES's: C/GMRES does a fixed number of operations
    # per update, so its rise is what an active obstacle adds to every evaluation.
    rise = bool(r_ip > 1 and r_ip > r_cg)
    out.append(Finding(
        *claims[2], rise, f"median with / without the obstacle in the problem: Ipopt "
        f"{num(ip.outer.p50_obstacle * 1e3)} / {num(ip.outer.p50_free * 1e3)} ms (×{num(r_ip)}), "
        f"C/GMRES (a fixed number of operations per update) ×{num(r_cg)}",
        "" if rise else f"Ipopt's rise (×{num(r_ip)}) is no larger than C/GMRES's "
        f"(×{num(r_cg)}), whose work per update is fixed: what both show is what an active "
        "obstacle adds to every evaluation of the problem, or a change of the machine's "
        "load during the run (the steps with the obstacle come first); the trace records "
        "no Ipopt iteration count that would tell extra iterations apart"))
    return out


def course_findings(results: Sequence[CourseResult]) -> list[Finding]:
    """The experiments' spirit: every stalled car along the curve avoided."""
    claim = ("every obstacle along a curved road is avoided: passed, no collision, no "
             "fallback")
    if not results:
        return [_missing("course", "experiments", claim, "paper_obstacles run")]
    out = []
    for r in results:
        ok = r.passed == r.obstacles and r.at_fault_collisions == 0 and r.fallbacks == 0
        out.append(Finding(
            "course", "experiments", claim, ok, f"{r.passed} of {r.obstacles} stalled cars "
            f"passed, {num(r.at_fault_collisions)} at-fault collisions, {num(r.fallbacks)} "
            f"fallback steps, smallest gap {num(r.min_gap_m)} m, peak lateral acceleration "
            f"{num(r.lat_acc_peak_mps2)} m/s²",
            "" if ok else f"the run ended {r.status} with {r.passed} of {r.obstacles} passed"))
    return out


def findings(a: Analysed) -> list[Finding]:
    """Every finding, in the paper's order."""
    return (cost_findings([r for r, _ in a.costs]) + preview_findings([r for r, _ in a.preview])
            + solver_findings([r for r, _ in a.solvers])
            + course_findings([r for r, _ in a.course]))


# ------------------------------------------------------------------------ the table


def _cost_rows(costs: Sequence[CostResult]) -> list[NumberRow]:
    names = " / ".join(c.cost for c in costs)

    def row(key: str, fig: str, what: str, unit: str, f: Callable[[CostResult], float],
            paper: str = "–") -> NumberRow:
        return NumberRow(key, fig, f"{what} ({names})", unit, tuple(f(c) for c in costs),
                         paper=paper)

    j1 = _cost(costs, "J1")
    rows = [row("fig9.horizon_entry", "9", "distance travelled when the horizon's end reaches "
                "the obstacle", "m", lambda c: c.horizon_entry_m,
                f"≈ {num(PAPER.window_entry_m)}"),
            row("fig9.residual_rms", "9", "E RMS, obstacle in the problem", "–",
                lambda c: c.residual.rms, "J1 larger"),
            row("fig9.residual_peak", "9", "E peak, obstacle in the problem", "–",
                lambda c: c.residual.peak),
            row("fig9.residual_decay", "9", "E decay time τ_E", "s",
                lambda c: c.residual.decay_s, "J1 slower"),
            row("fig9.residual_run_max", "9", "largest E in the whole run", "–",
                lambda c: c.run_max_residual),
            row("fig10.steer_hf", "10", f"steering mean square above {num(STEER_CUTOFF_HZ)} Hz, "
                "obstacle in the problem", "rad²", lambda c: c.steer_hf_rad2,
                "J1 high-frequency"),
            row("fig10.steer_d2", "10", "RMS of the steering's second difference / dt², "
                "obstacle in the problem", "rad/s²", lambda c: c.steer_d2_rms_radps2)]
    if j1 is not None:
        rows.append(NumberRow("fig10.hf_interval", "10", f"where J1's high-frequency steering "
                              f"lies (central {num(100 * ENERGY_SHARE)} % of its energy)", "m",
                              (j1.hf_from_m, j1.hf_to_m), joiner="–",
                              paper=f"{num(PAPER.chatter_from_m)}–{num(PAPER.chatter_to_m)}"))
    return rows


def _preview_rows(results: Sequence[PreviewResult]) -> list[NumberRow]:
    rows = []
    for ff, label in ((False, "paper's conversion"), (True, "with feed-forward")):
        pair = [r for r in (_preview(results, True, ff), _preview(results, False, ff))
                if r is not None]
        if not pair:
            continue
        names = " / ".join("on" if r.preview else "off" for r in pair)
        tau = num(pair[0].tau_s)
        sfx = ".ff" if ff else ""
        rows.append(NumberRow(f"fig12.error_rms{sfx}", "12", f"RMS lateral error plan − car at "
                              f"τ = {tau} s, {label} (preview {names})", "m",
                              tuple(r.error_rms_m for r in pair), paper="lower with preview"))
        rows.append(NumberRow(f"fig13.lat_acc_peak{sfx}", "13", f"peak lateral acceleration, "
                              f"{label} (preview {names})", "m/s²",
                              tuple(r.lat_acc_peak_mps2 for r in pair),
                              paper="lower with preview"))
    return rows


def _solver_rows(results: Sequence[SolverResult]) -> list[NumberRow]:
    if not results:
        return []
    names = " / ".join(r.solver for r in results)
    cg, ip = _solver(results, "C/GMRES"), _solver(results, "Ipopt")
    rows = [NumberRow("fig14.collisions", "14", f"at-fault collisions ({names})", "–",
                      tuple(r.at_fault_collisions for r in results), paper="both avoid"),
            NumberRow("fig15.mean", "15", f"outer loop per step, mean ({names})", "ms",
                      tuple(r.outer.mean * 1e3 for r in results), timing=True),
            NumberRow("fig15.max", "15", f"outer loop per step, max ({names})", "ms",
                      tuple(r.outer.max * 1e3 for r in results), timing=True),
            NumberRow("fig15.var", "15", f"outer loop per step, variance ({names})", "s²",
                      tuple(r.outer.var for r in results),
                      paper=f"{num(PAPER.cgmres_var_s2)} / {num(PAPER.ipopt_var_s2)}",
                      timing=True)]
    if cg is not None and ip is not None:
        for key, what, a, b, paper in (
                ("mean", "mean", ip.outer.mean, cg.outer.mean, "–"),
                ("p50", "median", ip.outer.p50, cg.outer.p50, "–"),
                ("var", "variance", ip.outer.var, cg.outer.var, num(PAPER.var_ratio)),
                ("var_robust", "variance from the median absolute deviation",
                 ip.outer.var_robust, cg.outer.var_robust, "–"),
                ("max", "max", ip.outer.max, cg.outer.max, "–")):
            rows.append(NumberRow(f"fig15.ratio_{key}", "15", f"Ipopt ÷ C/GMRES: {what}", "–",
                                  (ratio(a, b),), paper=paper, timing=True))
        rows.append(NumberRow("fig15.ipopt_obstacle", "15", "Ipopt median with / without the "
                              "obstacle in the problem", "ms",
                              (ip.outer.p50_obstacle * 1e3, ip.outer.p50_free * 1e3),
                              paper="rises", timing=True))
    return rows


def _course_rows(results: Sequence[CourseResult]) -> list[NumberRow]:
    rows = []
    for r in results:
        rows += [NumberRow("course.passed", "exp.", "stalled cars passed / in the scenario, "
                           "several along a curve", "–", (float(r.passed), float(r.obstacles)),
                           paper="all avoided"),
                 NumberRow("course.collisions", "exp.", "at-fault collisions / fallback steps",
                           "–", (r.at_fault_collisions, r.fallbacks)),
                 NumberRow("course.lat_acc_peak", "exp.", "peak lateral acceleration", "m/s²",
                           (r.lat_acc_peak_mps2,)),
                 NumberRow("course.step", "exp.", "outer + inner loop per step, mean", "ms",
                           (r.step_mean_s * 1e3,),
                           paper=f"{num(PAPER.experiment_step_s * 1e3)} (i3-3220)",
                           timing=True)]
    return rows


def number_rows(a: Analysed) -> list[NumberRow]:
    """The results table, in the paper's order."""
    return (_cost_rows([r for r, _ in a.costs]) + _preview_rows([r for r, _ in a.preview])
            + _solver_rows([r for r, _ in a.solvers]) + _course_rows([r for r, _ in a.course]))
