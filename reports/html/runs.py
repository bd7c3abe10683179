"""The plots of one run: one quantity per chart, its unit on the axis, its limit drawn.

Every chart plots the trace's signals or the stored series the metrics are extremes
of (SG-smoothed accelerations, jerk, yaw rate, TTC); the limits drawn are the
verdict's criteria in force (both signs for a bound on an absolute value). Each
quantity has a smallest y range (:data:`MIN_SPAN`) so that noise never fills an axis
(0.015 m/s of speed ripple is drawn as the ripple it is).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reports.charts import PALETTE, Line, Series, esc, fmt, line_chart
from reports.html.marks import Mark
from reports.metrics.evaluate import REQUIRED_METRICS
from reports.record import RunRecord, Verdict
from reports.record.verdict import SUMO_ONLY, CollisionDisagreement
from reports.tables import RunEntry

TTC_PLOT_CAP_S = 10.0
LIMIT_COLOUR = "#dc2626"
# smallest y range shown per quantity, in its unit
MIN_SPAN = {"m/s": 2.0, "m": 0.5, "m/s²": 1.0, "m/s³": 2.0, "rad/s": 0.1, "rad": 0.02,
            "gap m": 5.0, "s": 2.0}


@dataclass(frozen=True)
class Limit:
    """A criterion drawn as a horizontal line: its name, label, and whether it bounds
    an absolute value (drawn at ±limit)."""

    criterion: str
    label: str
    symmetric: bool = False


def limit_lines(verdict: Verdict | None, limits: tuple[Limit, ...]) -> list[Line]:
    """The limits in force of ``limits`` as reference lines."""
    criteria = verdict.criteria if verdict is not None else {}
    out: list[Line] = []
    for lim in limits:
        value = criteria.get(lim.criterion)
        if value is None:
            continue
        out.append((float(value), LIMIT_COLOUR, f"{lim.label} {fmt(value)}"))
        if lim.symmetric:
            out.append((-float(value), LIMIT_COLOUR, f"{lim.label} −{fmt(value)}"))
    return out


def _chart(series: list[Series], title: str, unit: str, vl: list[Line], hl: list[Line],
           span_key: str = "") -> str:
    return line_chart(series, title=title, ylabel=unit, vlines=vl, hlines=hl,
                      min_span=MIN_SPAN.get(span_key or unit, 0.0))


def _speed_and_path(rec: RunRecord, t: np.ndarray, vl: list[Line]) -> list[str]:
    ego = rec.trace.ego
    return [
        _chart([Series("speed", t, ego.speed_mps, PALETTE[0]),
                Series("set-point", t, rec.trace.decision.target_speed_mps, "#64748b",
                       dash=True)], "speed", "m/s", vl, []),
        _chart([Series("lateral deviation", t, ego.lat_dev_m, PALETTE[2])],
               "lateral deviation from the reference (left +)", "m", vl,
               [(0.0, "#94a3b8", "reference")]),
    ]


def _failed(verdict: Verdict | None, *metrics: str) -> bool:
    return verdict is not None and any(f.metric in metrics for f in verdict.failures)


def _comfort(rec: RunRecord, verdict: Verdict | None, t: np.ndarray, vl: list[Line]
             ) -> list[str]:
    """Accelerations always; jerk and yaw rate when one of their criteria failed (the
    Rerun log has them all)."""
    se = rec.series
    if se is None:
        return []
    charts = [
        _chart([Series("long acc (smoothed)", t, se.long_acc_mps2, PALETTE[0])],
               "longitudinal acceleration", "m/s²", vl, limit_lines(verdict, (
                   Limit("min_long_acc_mps2", "min"), Limit("max_long_acc_mps2", "max")))),
        _chart([Series("lat acc (smoothed)", t, se.lat_acc_mps2, PALETTE[1])],
               "lateral acceleration", "m/s²", vl,
               limit_lines(verdict, (Limit("max_abs_lat_acc_mps2", "|lat acc| ≤", True),)))]
    if _failed(verdict, "max_abs_long_jerk_mps3", "max_abs_jerk_mps3"):
        charts.append(_chart(
            [Series("long jerk", t, se.long_jerk_mps3, PALETTE[3]),
             Series("|jerk|", t, se.jerk_mps3, PALETTE[5], dash=True)], "jerk", "m/s³", vl,
            limit_lines(verdict, (Limit("max_abs_long_jerk_mps3", "|long jerk| ≤", True),
                                  Limit("max_abs_jerk_mps3", "|jerk| ≤")))))
    if _failed(verdict, "max_abs_yaw_rate_radps", "max_abs_yaw_acc_radps2"):
        charts.append(_chart(
            [Series("yaw rate (smoothed)", t, se.yaw_rate_radps, PALETTE[4])], "yaw rate",
            "rad/s", vl,
            limit_lines(verdict, (Limit("max_abs_yaw_rate_radps", "|yaw rate| ≤", True),))))
    return charts


def _steering(rec: RunRecord, t: np.ndarray, vl: list[Line]) -> str:
    """The front-wheel angle in degrees, as the Rerun log shows it (one unit for
    steering everywhere a person reads it; the records keep radians)."""
    steer = [Series("steer", t, np.degrees(rec.trace.ego.steer_rad), PALETTE[3])]
    for name, label, colour in (("steer_outer_rad", "outer", PALETTE[5]),
                                ("steer_corr_rad", "inner corr", PALETTE[4])):
        values = rec.trace.extra.get(name)
        if values is not None and np.any(np.isfinite(values) & (values != 0)):
            steer.append(Series(label, t, np.degrees(values), colour, dash=True, width=1.2))
    return _chart(steer, "steering (front-wheel angle)", "deg", vl, [])


def _safety(rec: RunRecord, verdict: Verdict | None, t: np.ndarray, vl: list[Line]
            ) -> list[str]:
    out = []
    gap = rec.trace.safety.min_gap_m
    if np.any(np.isfinite(gap)):
        out.append(_chart([Series("gap to the nearest vehicle", t,
                                  np.where(np.isfinite(gap), gap, np.nan), PALETTE[6])],
                          "gap (box to box)", "m", vl,
                          limit_lines(verdict, (Limit("min_gap_m", "min"),)), "gap m"))
    if rec.series is not None:
        ttc = np.where(np.isposinf(rec.series.ttc_s), TTC_PLOT_CAP_S,
                       np.minimum(rec.series.ttc_s, TTC_PLOT_CAP_S))
        if _failed(verdict, "min_ttc_s") or np.any(ttc < TTC_PLOT_CAP_S):
            out.append(_chart([Series(f"TTC ahead (none = {TTC_PLOT_CAP_S:g})", t, ttc,
                                      PALETTE[4])], "time to collision ahead", "s", vl,
                              limit_lines(verdict, (Limit("min_ttc_s", "min"),))))
    return out


def _residual(rec: RunRecord, t: np.ndarray, vl: list[Line]) -> str:
    residual = rec.trace.controller.residual
    if not np.any(np.isfinite(residual)):
        return ""
    pos = residual[np.isfinite(residual) & (residual > 0)]
    ylog = bool(pos.size and pos.max() / max(pos.min(), 1e-300) > 100)
    return line_chart([Series("residual E", t, residual, PALETTE[7])],
                      title="outer-loop residual E = ‖F‖∞", ylabel="-", ylog=ylog, vlines=vl)


def time_series(run: RunEntry, marks: list[Mark]) -> str:
    """Every chart of a run (module doc), failure marks as vertical lines."""
    rec = run.record
    if rec is None or len(rec.trace) == 0:
        return '<div class="nodata">no trace</div>'
    t = rec.trace.t_s
    vl: list[Line] = [(float(t[m.row]), m.colour, m.label) for m in marks if 0 <= m.row < len(t)]
    charts = (_speed_and_path(rec, t, vl) + _safety(rec, run.verdict, t, vl)
              + _comfort(rec, run.verdict, t, vl) + [_steering(rec, t, vl), _residual(rec, t, vl)])
    return "".join(charts)


KIND_ORDER = ("safety", "comfort", "tracking", "health", "timing")
# shown beside the collision verdict: SUMO's report and where it disagrees with the boxes
COLLISION_BESIDE = ("sumo_collisions_reported", "collision_disagreements")


def metrics_table(run: RunEntry) -> str:
    """The run's key metrics by kind — the required ones, every one a criterion bounds
    and every failed one — with value, unit and the limit in force; failed ones
    highlighted (every metric is in results.csv and run.json)."""
    verdict = run.verdict
    if verdict is None or not verdict.metrics:
        return ""
    from reports.metrics.criteria import CRITERIA_METRICS

    limit_of = {metric: (crit, bound) for crit, (metric, bound) in CRITERIA_METRICS.items()}
    failed = {f.metric for f in verdict.failures}
    shown = set(REQUIRED_METRICS) | set(limit_of) | failed | set(COLLISION_BESIDE)
    rows = []
    for kind in KIND_ORDER:
        members = [m for m in verdict.metrics if m.kind == kind and m.name in shown]
        if not members:
            continue
        rows.append(f'<tr class="kindrow"><th colspan="4">{esc(kind)}</th></tr>')
        for m in members:
            crit = limit_of.get(m.name)
            limit = verdict.criteria.get(crit[0]) if crit is not None else None
            lim = f"{'≤' if crit[1] == 'max' else '≥'} {fmt(limit)}" \
                if crit is not None and limit is not None else ""
            unit = "" if m.unit in ("-", "") else m.unit.replace("^2", "²").replace("^3", "³")
            cls = ' class="bad"' if m.name in failed else ""
            rows.append(f'<tr{cls}><td class="name">{esc(m.name)}</td><td>{fmt(m.value)}</td>'
                        f"<td>{esc(unit)}</td><td>{esc(lim)}</td></tr>")
    return ('<table class="metrics"><thead><tr><th>metric</th><th>value</th><th>unit</th>'
            f"<th>limit</th></tr></thead><tbody>{''.join(rows)}</tbody></table>")


def _disagreement_row(d: CollisionDisagreement) -> str:
    sumo_only = d.kind == SUMO_ONLY
    what = "SUMO only (not counted)" if sumo_only else "boxes only (counted)"
    role = f"{d.sumo_role} ({d.sumo_type})" if d.sumo_role else "–"
    lanes = "/".join("?" if k < 0 else str(k) for k in (d.ego_lane_index, d.other_lane_index))
    return (f'<tr data-kind="{esc(d.kind)}"><td class="name">{esc(what)}</td>'
            f'<td class="name">{esc(d.other_id or "?")}</td><td>{fmt(d.t_s)}–{fmt(d.last_t_s)}'
            f"</td><td>{d.step}</td><td>{d.sumo_reports}</td><td>{esc(role)}</td>"
            f"<td>{fmt(d.min_gap_m, 3)}</td><td>{esc(lanes)}</td></tr>")


def collision_disagreements(run: RunEntry) -> str:
    """The collisions SUMO's report and the 2-D box test disagree on (``id=
    "collision-disagreements"``; '' when they agree): SUMO-only reports are not counted,
    contacts of the boxes SUMO did not report are (docs/metrics.md)."""
    verdict = run.verdict
    found = verdict.collision_disagreements if verdict is not None else ()
    if not found:
        return ""
    head = "".join(f"<th>{h}</th>" for h in (
        "disagreement", "vehicle", "t [s]", "step", "SUMO reports", "SUMO: the ego is",
        "min box gap [m]", "lane ego/other"))
    return ('<section id="collision-disagreements"><h2>Collisions: SUMO and the boxes '
            "disagree</h2><p>The collision verdict rests on the 2-D boxes of the ego and the "
            "other vehicle. SUMO, without its sublane model, judges collisions along the "
            "lane only; its report stands beside the verdict.</p>"
            f'<table class="metrics"><thead><tr>{head}</tr></thead><tbody>'
            f"{''.join(_disagreement_row(d) for d in found)}</tbody></table></section>")
