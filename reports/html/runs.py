"""One collapsible section per run in report.html: the stored metrics (failed ones
highlighted), where the run failed, its bird's-eye views and time series.

Plotted signals are the trace's (speed, lateral deviation, steering, gap, residual) and
the stored series the metrics are extremes of (SG-smoothed accelerations, TTC); the
limits drawn are the verdict's criteria. Nothing is recomputed here.
"""

from __future__ import annotations

import numpy as np

from reports.html.birdseye import birdseye_svg
from reports.html.charts import PALETTE, Line, Series, esc, fmt, line_chart
from reports.html.marks import Mark, failure_marks
from reports.metrics.evaluate import REQUIRED_METRICS
from reports.record import RunRecord, Verdict
from reports.tables import RunEntry

# shown after the required metrics when the verdict has them
EXTRA_GRID_METRICS = ("progress_ratio", "max_offroad_m", "shoulder_s", "min_ttc_rear_s",
                      "ssm_ttc_min_s", "outer_ms_p99", "inner_ms_p99", "guards", "steps")
TTC_PLOT_CAP_S = 10.0


def run_anchor(run: RunEntry) -> str:
    """The element id of a run's section."""
    safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in run.run_id)
    return f"run-{safe}"


def badge(status: str) -> str:
    """Coloured status label."""
    return f'<span class="badge {esc(status)}">{esc(status)}</span>'


def zoom_focus(run: RunEntry, marks: list[Mark]) -> tuple[int, str] | None:
    """Where to zoom the bird's-eye view: the first mark, else the closest approach (the
    stored worst step of ``min_gap_m``) when one was recorded."""
    if marks:
        return marks[0].row, marks[0].name
    gap = run.verdict.metric("min_gap_m") if run.verdict is not None else None
    if gap is None or gap.worst_step is None:
        return None
    return gap.worst_step, f"closest approach ({fmt(gap.value, 3)} m)"


def _limit_lines(verdict: Verdict | None, names: tuple[tuple[str, str], ...]) -> list[Line]:
    limits = verdict.criteria if verdict is not None else {}
    out: list[Line] = []
    for name, label in names:
        limit = limits.get(name)
        if limit is not None:
            out.append((float(limit), "#fca5a5", label))
    return out


def _steering(rec: RunRecord, t: np.ndarray, vl: list[Line]) -> str:
    steer = [Series("steer", t, rec.trace.ego.steer_rad, PALETTE[3])]
    # the two-loop controller's split of the command, when it declares it
    for name, label, colour in (("steer_outer_rad", "outer", PALETTE[5]),
                                ("steer_corr_rad", "inner corr", PALETTE[4])):
        values = rec.trace.extra.get(name)
        if values is not None and np.any(np.isfinite(values) & (values != 0)):
            steer.append(Series(label, t, values, colour, dash=True, width=1.2))
    return line_chart(steer, title="steering (front-wheel angle)", ylabel="rad", vlines=vl)


def _gap_ttc(rec: RunRecord, verdict: Verdict | None, t: np.ndarray, vl: list[Line]) -> str:
    gap = rec.trace.safety.min_gap_m
    ttc = np.minimum(rec.series.ttc_s, TTC_PLOT_CAP_S) if rec.series is not None \
        else np.full(len(t), np.nan)
    if not (np.any(np.isfinite(gap)) or np.any(ttc < TTC_PLOT_CAP_S)):
        return ""
    return line_chart([Series("gap [m]", t, np.where(np.isfinite(gap), gap, np.nan),
                              PALETTE[6]),
                       Series(f"TTC ahead [s] (≤{TTC_PLOT_CAP_S:g})", t, ttc, PALETTE[4])],
                      title="gap and time to collision", ylabel="m / s", vlines=vl,
                      hlines=_limit_lines(verdict, (("min_ttc_s", "TTC limit"),)))


def _residual(rec: RunRecord, t: np.ndarray, vl: list[Line]) -> str:
    residual = rec.trace.controller.residual
    if not np.any(np.isfinite(residual)):
        return ""
    pos = residual[np.isfinite(residual) & (residual > 0)]
    ylog = bool(pos.size and pos.max() / max(pos.min(), 1e-300) > 100)
    return line_chart([Series("residual E", t, residual, PALETTE[7])],
                      title="outer-loop residual E = ‖F‖∞", ylabel="E", ylog=ylog, vlines=vl)


def time_series(run: RunEntry, marks: list[Mark]) -> str:
    """The per-run time-series charts."""
    rec = run.record
    if rec is None or len(rec.trace) == 0:
        return '<div class="nodata">no trace</div>'
    t = rec.trace.t_s
    vl: list[Line] = [(float(t[m.row]), m.colour, m.label) for m in marks if 0 <= m.row < len(t)]
    charts = [line_chart([Series("speed", t, rec.trace.ego.speed_mps, PALETTE[0]),
                          Series("set-point", t, rec.trace.decision.target_speed_mps,
                                 "#64748b", dash=True)], title="speed", ylabel="m/s",
                         vlines=vl),
              line_chart([Series("lateral deviation", t, rec.trace.ego.lat_dev_m, PALETTE[2])],
                         title="lateral deviation from reference", ylabel="m", vlines=vl,
                         hlines=[(0.0, "#94a3b8", "reference")])]
    if rec.series is not None:
        charts.append(line_chart(
            [Series("long acc", t, rec.series.long_acc_mps2, PALETTE[0]),
             Series("lat acc", t, rec.series.lat_acc_mps2, PALETTE[1])],
            title="accelerations (SG-smoothed)", ylabel="m/s²", vlines=vl,
            hlines=_limit_lines(run.verdict, (("min_long_acc_mps2", "long acc min"),
                                              ("max_long_acc_mps2", "long acc max")))))
    charts += [_steering(rec, t, vl), _gap_ttc(rec, run.verdict, t, vl), _residual(rec, t, vl)]
    return "".join(charts)


def metrics_grid(run: RunEntry) -> str:
    """The stored key metrics of a run (unit and kind as tooltip), failed ones highlighted."""
    verdict = run.verdict
    if verdict is None or not verdict.metrics:
        return ""
    failed = {f.metric for f in verdict.failures}
    cells = []
    for name in (*REQUIRED_METRICS, *EXTRA_GRID_METRICS):
        m = verdict.metric(name)
        if m is None:
            continue
        cls = ' class="bad"' if name in failed else ""
        tip = esc(f"{m.unit} · {m.kind}" + (f" · {m.better} is better" if m.better != "none"
                                            else ""))
        cells.append(f'<div{cls} title="{tip}"><span>{esc(name)}</span><b>{fmt(m.value)}</b>'
                     "</div>")
    return f'<div class="grid">{"".join(cells)}</div>'


def run_section(run: RunEntry) -> str:
    """One collapsible run section."""
    marks = failure_marks(run)
    is_open = " open" if run.status != "pass" else ""
    failed = "; ".join(f.text for f in run.failures)
    head = (f'<summary>{badge(run.status)} <b>{esc(run.scenario)}</b> · '
            f'<span class="ctrl">{esc(run.controller)}</span> · '
            f'<span class="fam">{esc(run.family)}</span>'
            + (f' <span class="why">{esc(failed)}</span>' if failed else "")
            + "</summary>")
    seed = run.info.seed if run.info is not None else "–"
    body = [f'<p class="meta">run dir <code>{esc(run.run_dir)}</code> · sim '
            f"{fmt(run.sim_time_s)} s · wall {fmt(run.wall_s)} s · seed {esc(seed)}</p>"]
    if run.error:
        body.append(f"<pre class=\"err\">{esc(run.error)}</pre>")
    if marks:
        body.append("<p class=\"marks\">" + " · ".join(
            f'<span style="color:{m.colour}">✖ {esc(m.label)}</span>' for m in marks) + "</p>")
    body.append(metrics_grid(run))
    body.append(birdseye_svg(run.record, run.verdict, marks))
    focus = zoom_focus(run, marks)
    if focus is not None:
        body.append(birdseye_svg(run.record, run.verdict, marks, zoom=focus))
    body.append(time_series(run, marks))
    text = (run.scenario + " " + run.controller + " " + run.family).lower()
    return (f'<details class="run" id="{run_anchor(run)}" data-status="{esc(run.status)}" '
            f'data-text="{esc(text)}"{is_open}>{head}{"".join(body)}</details>')

