"""``paper.html``: the paper's figures redrawn from our runs, each with its numbers, the
paper's value beside ours and whether its finding holds.

One self-contained page (inline SVG from :mod:`reports.charts`, the report's
stylesheet, no script, nothing from the network). Sections follow the paper: the
findings and the numbers first, then Figs. 9-10 (J1/J2/J3 on the straight road),
12-13 (preview on the curve), 14-15 (C/GMRES against Ipopt) and the obstacles along a
curve. Every x axis is the distance travelled from the run's start [m].
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Callable, Sequence

import numpy as np

from reports.charts import PALETTE, Line, Series, cdf_chart, esc, line_chart
from reports.html.birdseye import birdseye_svg
from reports.html.style import CSS
from reports.paper.findings import Finding, NumberRow, num
from reports.paper.measures import STEER_CUTOFF_HZ
from reports.paper.reference import PAPER
from reports.paper.results import Analysed, CostResult, Curves, PreviewResult, SolverResult
from reports.paper.runs import Machine, PaperRun
from reports.paper.table import TIMING_MARK, TIMING_NOTE, PaperReport

OURS = "#dc2626"  # our event markers
THEIRS = "#64748b"  # the paper's values
COST_COLOURS = {"J1": PALETTE[1], "J2": PALETTE[0], "J3": PALETTE[2]}
PAGE_CSS = """
.finding td{text-align:left}.finding td.v{white-space:nowrap;font-weight:600}
.finding tr.yes td.v{color:var(--pass)}.finding tr.no td.v{color:var(--fail)}
.finding tr.na td.v{color:#64748b}table.nums td{text-align:right}
table.nums td.q,table.nums td.p{text-align:left}p.note{max-width:900px;color:#334155}
section.fig{background:#fff;border:1px solid #e2e8f0;border-radius:6px;padding:4px 14px;
margin:14px 0}
"""
X_LABEL = "distance travelled [m]"


def _series(label: str, curves: Curves, y: np.ndarray, colour: str, dash: bool = False,
            up_to_m: float = math.inf) -> Series:
    """A line over the distance travelled, up to ``up_to_m`` [m]."""
    keep = curves.dist_m <= up_to_m
    return Series(label, curves.dist_m[keep], y[keep], colour, dash=dash)


def _chart(series: list[Series], title: str, unit: str, vlines: Sequence[Line] = (),
           ylog: bool = False, min_span: float = 0.0) -> str:
    return line_chart(series, title=title, ylabel=unit, xlabel=X_LABEL, vlines=vlines,
                      ylog=ylog, min_span=min_span, height=200)


def findings_table(items: Sequence[Finding]) -> str:
    rows = []
    for f in items:
        cls = {True: "yes", False: "no", None: "na"}[f.holds]
        rows.append(f'<tr class="{cls}"><td>{esc(f.figure)}</td><td>{esc(f.claim)}</td>'
                    f'<td class="v">{esc(f.verdict)}</td><td>{esc(f.evidence)}'
                    f'{"<br><i>" + esc(f.why) + "</i>" if f.why else ""}</td></tr>')
    return ('<h2 id="findings">The paper\'s findings in our runs</h2><table class="finding">'
            "<thead><tr><th>figure</th><th>the paper's finding</th><th>here</th>"
            "<th>our numbers, and why</th></tr></thead><tbody>" + "".join(rows)
            + "</tbody></table>")


def numbers_table(rows: Sequence[NumberRow]) -> str:
    body = "".join(
        f'<tr><td>{esc(r.figure)}</td><td class="q">{esc(r.quantity)}'
        f'{" " + TIMING_MARK if r.timing else ""}</td><td>{esc(r.unit)}</td>'
        f'<td>{esc(r.ours)}</td><td class="p">{esc(r.paper)}</td></tr>' for r in rows)
    return ('<h2 id="numbers">The numbers</h2><table class="nums"><thead><tr><th>fig.</th>'
            "<th>quantity</th><th>unit</th><th>ours</th><th>the paper</th></tr></thead>"
            f'<tbody>{body}</tbody></table><p class="note">{esc(TIMING_NOTE)}</p>')


def _table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    h = "".join(f"<th>{esc(c)}</th>" for c in head)
    b = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="nums"><thead><tr>{h}</tr></thead><tbody>{b}</tbody></table>'


# ------------------------------------------------------------------------- sections


def _cost_events(costs: Sequence[tuple[CostResult, Curves]]) -> list[Line]:
    if not costs:
        return []
    first = costs[0][0]
    return [(first.entry_m, OURS, f"obstacle enters the problem ({num(first.entry_m)} m)"),
            (first.horizon_entry_m, OURS, f"horizon's end reaches it ({num(first.horizon_entry_m)}"
             " m)"),
            (PAPER.window_entry_m, THEIRS, f"the paper: enters the window ≈ "
             f"{num(PAPER.window_entry_m)} m")]


def costs_section(costs: Sequence[tuple[CostResult, Curves]]) -> str:
    if not costs:
        return '<section class="fig"><h2 id="fig9">Figs. 9-10</h2><div class="nodata">no ' \
               "paper_costs runs</div></section>"
    ev = _cost_events(costs)
    # the approach and the pass: to the window's end plus the fade-out, or the paper's
    # obstacle, whichever is further (the charts have ~100 points per line)
    span = max(max(r.exit_m for r, _ in costs) + 20.0, PAPER.obstacle_ahead_m + 10.0)

    def lines(pick: Callable[[Curves], np.ndarray]) -> list[Series]:
        return [_series(r.cost, c, pick(c), COST_COLOURS.get(r.cost, PALETTE[3]),
                        dash=r.cost == "J3", up_to_m=span) for r, c in costs]

    resid = lines(lambda c: c.residual)
    steer = lines(lambda c: c.steer_rad)
    hf = lines(lambda c: c.steer_hf_rad)
    paper_hf = [(PAPER.chatter_from_m, THEIRS,
                 f"the paper's J1 chatter from {num(PAPER.chatter_from_m)} m"),
                (PAPER.chatter_to_m, THEIRS, f"… to {num(PAPER.chatter_to_m)} m")]
    table = _table(["cost", "obstacle window [m]", "E RMS [-]", "E peak [-]",
                    "peak after entry [s]", "τ_E [s]", "largest E in the run [-] (at m)",
                    f"steering > {num(STEER_CUTOFF_HZ)} Hz [rad²]", "RMS δ'' [rad/s²]",
                    "HF steering lies at [m]", "max |lateral offset| [m]"],
                   [[r.cost, f"{num(r.entry_m)}–{num(r.exit_m)}", num(r.residual.rms),
                     num(r.residual.peak), num(r.residual.peak_after_s), num(r.residual.decay_s),
                     f"{num(r.run_max_residual)} ({num(r.run_max_at_m)})", num(r.steer_hf_rad2),
                     num(r.steer_d2_rms_radps2), f"{num(r.hf_from_m)}–{num(r.hf_to_m)}",
                     num(r.max_abs_lat_dev_m)] for r, _ in costs])
    return (
        '<section class="fig"><h2 id="fig9">Figs. 9-10: J1, J2 and J3 on a straight road, '
        'stalled car 110 m ahead</h2><p class="note">E = ‖F‖∞ of the plan each step (log '
        "axis). The obstacle window runs from the stalled car's entry into the planning "
        "problem to its exit, once the car is in the next lane; τ_E = 2 ∫ (t − t₀) E² dt / ∫ E² dt "
        "over it (the time constant of an exponential decay). The steering's high-frequency "
        f"part is a zero-phase Butterworth high-pass at {num(STEER_CUTOFF_HZ)} Hz (the "
        "plant's yaw mode is near 0.9 Hz).</p>"
        + _chart(resid, "Fig. 9: residual E", "E [-]", ev, ylog=True)
        + _chart(steer, "Fig. 10: steering angle", "δ [rad]", ev, min_span=0.02)
        + _chart(hf, f"Fig. 10: steering above {num(STEER_CUTOFF_HZ)} Hz", "δ [rad]",
                 [*ev[:1], *paper_hf], min_span=1e-3)
        + table + "</section>")


def preview_section(results: Sequence[tuple[PreviewResult, Curves]]) -> str:
    if not results:
        return '<section class="fig"><h2 id="fig12">Figs. 12-13</h2><div class="nodata">no ' \
               "paper_preview runs</div></section>"
    colours = {(False, True): PALETTE[0], (False, False): PALETTE[1],
               (True, True): PALETTE[2], (True, False): PALETTE[3]}

    def label(r: PreviewResult) -> str:
        return f"preview {'on' if r.preview else 'off'}{', ff' if r.feedforward else ''}"

    err = [_series(label(r), c, c.plan_error_m, colours[(r.feedforward, r.preview)],
                   dash=r.feedforward) for r, c in results]
    lat = [_series(label(r), c, c.lat_acc_mps2, colours[(r.feedforward, r.preview)],
                   dash=r.feedforward) for r, c in results]
    tau = num(results[0][0].tau_s)
    table = _table(["conversion", "preview", "RMS error [m]", "max |error| [m]",
                    "peak |a_y| [m/s²]", "RMS a_y [m/s²]", "δ_c RMS [rad]",
                    "of which integral [rad]", "offset from its lane, last 5 s [m]",
                    "at-fault collisions"],
                   [["with feed-forward" if r.feedforward else "paper's (13)-(14)",
                     "on" if r.preview else "off", num(r.error_rms_m), num(r.error_max_m),
                     num(r.lat_acc_peak_mps2), num(r.lat_acc_rms_mps2),
                     num(r.steer_corr_rms_rad), num(r.steer_corr_i_rms_rad),
                     num(r.final_offset_m), num(r.at_fault_collisions)] for r, _ in results])
    return (
        '<section class="fig"><h2 id="fig12">Figs. 12-13: preview on and off, J3, curve '
        f'(R = 400 m) with a stalled car</h2><p class="note">Lateral error between plan and '
        f"car: the car's CG τ = {tau} s after each plan was made (the preview's horizon), "
        "its signed distance from that plan's path, left positive. Solid: the paper's "
        "conversion (13)-(14); dashed (ff): ours, with the cornering feed-forward.</p>"
        + _chart(err, "Fig. 12: lateral error plan − car", "error [m]", min_span=0.1)
        + _chart(lat, "Fig. 13: lateral acceleration", "a_y [m/s²]", min_span=1.0)
        + table + "</section>")


def solvers_section(results: Sequence[tuple[SolverResult, Curves]]) -> str:
    if not results:
        return '<section class="fig"><h2 id="fig15">Figs. 14-15</h2><div class="nodata">no ' \
               "paper_solvers runs</div></section>"
    colours = {"C/GMRES": PALETTE[0], "Ipopt": PALETTE[1]}
    series = [_series(r.solver, c, c.outer_ms, colours.get(r.solver, PALETTE[3]))
              for r, c in results]
    paths = [_series(r.solver, c, c.lat_dev_m, colours.get(r.solver, PALETTE[3]))
             for r, c in results]
    cdf = cdf_chart({r.solver: c.outer_ms for r, c in results},
                    title="outer loop per step: CDF", width=420, height=230)
    table = _table(["planner", "mean [ms]", "median [ms]", "p99 [ms]", "max [ms]",
                    "variance [s²]", "variance from MAD [s²]", "median with / without obstacle "
                    "[ms]", "whole step mean [ms]", "at-fault collisions", "min gap [m]"],
                   [[r.solver, num(r.outer.mean * 1e3), num(r.outer.p50 * 1e3),
                     num(r.outer.p99 * 1e3), num(r.outer.max * 1e3), num(r.outer.var),
                     num(r.outer.var_robust),
                     f"{num(r.outer.p50_obstacle * 1e3)} / {num(r.outer.p50_free * 1e3)}",
                     num(r.step_mean_s * 1e3), num(r.at_fault_collisions), num(r.min_gap_m)]
                    for r, _ in results])
    return (
        '<section class="fig"><h2 id="fig15">Figs. 14-15: C/GMRES against Ipopt on the same '
        f'OCP</h2><p class="note">Both planners ran in the same catalog run, on the same '
        f"scenario as Fig. 9 with J3; the times are the outer loop's wall-clock time per "
        f"control step. The paper's variances: {num(PAPER.cgmres_var_s2)} s² (C/GMRES) and "
        f"{num(PAPER.ipopt_var_s2)} s² (Ipopt). {esc(TIMING_NOTE)}</p>"
        + _chart(paths, "Fig. 14: lateral offset from the lane centre", "y [m]", min_span=1.0)
        + _chart(series, "Fig. 15: outer loop time per step", "time [ms]", ylog=True)
        + f'<div class="cdfs">{cdf}</div>' + table + "</section>")


def course_section(runs: Sequence[PaperRun], results: Analysed) -> str:
    if not results.course:
        return '<section class="fig"><h2 id="course">Several obstacles</h2><div ' \
               'class="nodata">no paper_obstacles run</div></section>'
    parts = []
    for (r, c), run in zip(results.course, runs, strict=True):
        rec = run.record
        parts.append(birdseye_svg(rec, rec.verdict, []))
        parts.append(_chart([_series("lateral offset", c, c.lat_dev_m, PALETTE[0])],
                            "lateral offset from the reference lane's centre", "y [m]",
                            min_span=1.0))
        parts.append(_chart([_series("E", c, c.residual, PALETTE[2])], "residual E", "E [-]",
                            ylog=True))
        parts.append(_table(
            ["run", "passed / stalled cars", "at-fault collisions", "min gap [m]",
             "peak |a_y| [m/s²]", "RMS error plan − car [m]", "max E [-]", "fallback steps",
             f"outer + inner per step [ms] {TIMING_MARK}", "status"],
            [[r.run, f"{r.passed} / {r.obstacles}", num(r.at_fault_collisions),
              num(r.min_gap_m), num(r.lat_acc_peak_mps2), num(r.error_rms_m),
              num(r.residual_max), num(r.fallbacks), num(r.step_mean_s * 1e3), r.status]]))
    return ('<section class="fig"><h2 id="course">Several obstacles along a curve (the '
            'experiments\' spirit)</h2><p class="note">The paper\'s scaled-vehicle '
            "experiments pass several obstacles on a winding track; here stalled cars in "
            "alternating lanes along the R = 400 m curve. The paper's whole control step "
            f"on its bench: {num(PAPER.experiment_step_s * 1e3)} ms.</p>" + "".join(parts)
            + "</section>")


def _machine_line(m: Machine) -> str:
    loads = [v for v in (m.load_start, m.load_end) if math.isfinite(v)]
    load = f"load {num(max(loads), 2)}/core" if loads else "load unknown"
    sha = (m.git_sha[:10] + ("+dirty" if m.git_dirty else "")) if m.git_sha else "unknown"
    return (f"<span>git {esc(sha)}</span><span>{esc(m.host or '?')} ({esc(m.cpu_model or '?')}, "
            f"{m.cpu_count or '?'} cores, {esc(load)})</span>")


def render_page(report: PaperReport, course_runs: Sequence[PaperRun]) -> str:
    """The whole page (module doc); ``course_runs`` are the obstacle course's runs
    (their records draw the bird's-eye view)."""
    held = sum(f.holds is True for f in report.findings)
    failed = sum(f.holds is False for f in report.findings)
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    unread = "".join(f"<li>{esc(n)}: {esc(w)}</li>" for n, w in report.unreadable)
    return "\n".join([
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        '<link rel="icon" href="data:,">',
        f"<title>hwyeval: the paper's findings</title><style>{CSS}{PAGE_CSS}</style></head>"
        "<body>",
        "<header><h1>The paper's findings, reproduced in SUMO</h1><div class=\"counts\">"
        f"<span><b>{held}</b> hold</span><span><b>{failed}</b> do not</span>"
        f"<span>runs: {esc(report.source)}</span>{_machine_line(report.machine)}"
        f"<span>page {esc(now)}</span></div><nav><a href=\"#findings\">findings</a> · "
        '<a href="#numbers">numbers</a> · <a href="#fig9">Figs. 9-10</a> · '
        '<a href="#fig12">Figs. 12-13</a> · <a href="#fig15">Figs. 14-15</a> · '
        '<a href="#course">obstacles</a></nav></header><main>',
        findings_table(report.findings), numbers_table(report.rows),
        costs_section(report.results.costs), preview_section(report.results.preview),
        solvers_section(report.results.solvers),
        course_section(course_runs, report.results),
        f"<h2>Runs not read</h2><ul>{unread}</ul>" if unread else "",
        "</main></body></html>"])
