"""The trend page (``hwyeval history DB --out DIR`` writes ``DIR/history.html``).

One self-contained HTML file, inline CSS and SVG, no script and nothing fetched: the
pass rate per night; the scenarios failing now (since which night and revision, the
last good revision); the flaky ones and why; and the status strip, one row per
scenario (failing now first, then flaky), one cell per night, beside a sparkline of the
chosen metric with its criterion's limit dashed.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path

from reports.history.trends import ScenarioTrend, Trends

PAGE = "history.html"
STRIP_W_PX = 640.0  # width of the status strip (cells are 2-14 px wide)
SPARK_W_PX, SPARK_H_PX = 180.0, 26.0

CSS = """
body{font:13px/1.4 system-ui,sans-serif;margin:0;color:#1d2733;background:#fff}
header{padding:12px 20px;background:#1d2733;color:#fff}header h1{margin:0;font-size:18px}
header p{margin:4px 0 0;color:#c9d3de}main{padding:8px 20px 40px}
h2{font-size:15px;margin:20px 0 6px}table{border-collapse:collapse}
td,th{padding:2px 8px;text-align:left;vertical-align:middle;white-space:nowrap}
thead th{border-bottom:1px solid #99a;font-weight:600}tbody tr:nth-child(even){background:#f4f6f8}
code{font-size:12px}.badge{display:inline-block;padding:0 5px;border-radius:3px;font-size:11px;
margin-left:4px;color:#fff}.badge.flaky{background:#b36b00}.badge.failing{background:#c0392b}
svg rect.pass{fill:#2e9d50}svg rect.fail{fill:#d64541}svg rect.error{fill:#7d3c98}
svg rect.timeout{fill:#e67e22}svg rect.absent{fill:#e3e6ea}svg rect.rate{fill:#2e9d50}
svg rect.rate.low{fill:#d64541}svg .axis{stroke:#99a;stroke-width:1}
svg .spark{fill:none;stroke:#1f5fa8;stroke-width:1.3}svg .limit{stroke:#c0392b;
stroke-dasharray:3 2;stroke-width:1}svg text{font-size:10px;fill:#556}
#flaky-table td:last-child{white-space:normal;max-width:900px}
.legend span{display:inline-block;width:10px;height:10px;margin:0 3px 0 10px;
vertical-align:-1px}.none{color:#667}
"""


def _e(text: object) -> str:
    return html.escape(str(text), quote=True)


def _fmt(x: float) -> str:
    if math.isnan(x):
        return "–"
    if math.isinf(x):
        return "∞" if x > 0 else "−∞"
    return f"{x:.4g}"


def pass_rate_svg(trends: Trends) -> str:
    """Bars of the pass rate per night [%] (red below 100 %), each with its night."""
    n = max(1, len(trends.nights))
    w, h, left = 900.0, 120.0, 34.0
    bw = (w - left) / n
    parts = [f'<svg id="pass-rate-chart" width="{w:.0f}" height="{h + 16:.0f}" '
             f'viewBox="0 0 {w:.0f} {h + 16:.0f}" role="img">',
             f'<line class="axis" x1="{left}" y1="{h}" x2="{w}" y2="{h}"/>',
             f'<text x="0" y="10">100%</text><text x="0" y="{h}">0%</text>']
    for j, s in enumerate(trends.nights):
        rate = s.pass_rate if not math.isnan(s.pass_rate) else 0.0
        bh = max(1.0, rate * (h - 4))
        cls = "rate" if rate >= 1.0 else "rate low"
        parts.append(f'<rect class="{cls}" x="{left + j * bw + bw * 0.1:.1f}" '
                     f'y="{h - bh:.1f}" width="{max(1.0, bw * 0.8):.1f}" height="{bh:.1f}">'
                     f"<title>{_e(s.info.night_id)}: {rate:.0%} ({s.passed}/{s.runs}), "
                     f"revision {_e(s.info.short_revision)}</title></rect>")
    if trends.nights:
        parts.append(f'<text x="{left}" y="{h + 13}">{_e(trends.nights[0].info.night_id)}'
                     f'</text><text x="{w}" y="{h + 13}" text-anchor="end">'
                     f"{_e(trends.nights[-1].info.night_id)}</text>")
    parts.append("</svg>")
    return "".join(parts)


def strip_svg(trend: ScenarioTrend, night_ids: Sequence[str]) -> str:
    """One scenario's statuses, a cell per night, runs of one status merged."""
    n = max(1, len(trend.statuses))
    cw = min(14.0, max(2.0, STRIP_W_PX / n))
    parts = [f'<svg class="strip" width="{cw * n:.0f}" height="14">']
    j = 0
    while j < len(trend.statuses):
        status = trend.statuses[j]
        k = j
        while k + 1 < len(trend.statuses) and trend.statuses[k + 1] == status:
            k += 1
        cls = status or "absent"
        span = night_ids[j] if j == k else f"{night_ids[j]} … {night_ids[k]}"
        parts.append(f'<rect class="{cls}" x="{j * cw:.1f}" y="1" width="{(k - j + 1) * cw:.1f}"'
                     f' height="12"><title>{_e(span)}: {cls}</title></rect>')
        j = k + 1
    parts.append("</svg>")
    return "".join(parts)


def spark_svg(trend: ScenarioTrend) -> str:
    """The metric per night (a line through the finite values) and its limit (dashed);
    ±∞ and absent nights leave a gap."""
    finite = [v for v in trend.values if math.isfinite(v)]
    lim = trend.limit if math.isfinite(trend.limit) else None
    span = finite + ([lim] if lim is not None else [])
    parts = [f'<svg class="sparkline" width="{SPARK_W_PX:.0f}" height="{SPARK_H_PX:.0f}">']
    if span:
        lo, hi = min(span), max(span)
        if hi - lo < 1e-12:
            lo, hi = lo - 1.0, hi + 1.0
        n = max(1, len(trend.values) - 1)

        def y(v: float) -> float:
            return 2 + (SPARK_H_PX - 4) * (1 - (v - lo) / (hi - lo))

        segment: list[str] = []
        segments: list[list[str]] = [segment]
        for j, v in enumerate(trend.values):
            if math.isfinite(v):
                segment.append(f"{j * SPARK_W_PX / n:.1f},{y(v):.1f}")
            elif segment:
                segment = []
                segments.append(segment)
        for seg in segments:
            if len(seg) == 1:
                x_, y_ = seg[0].split(",")
                parts.append(f'<circle cx="{x_}" cy="{y_}" r="1.5" fill="#1f5fa8"/>')
            elif seg:
                parts.append(f'<polyline class="spark" points="{" ".join(seg)}"/>')
        if lim is not None:
            parts.append(f'<line class="limit" x1="0" x2="{SPARK_W_PX:.0f}" y1="{y(lim):.1f}" '
                         f'y2="{y(lim):.1f}"><title>limit {_fmt(lim)}</title></line>')
    parts.append("</svg>")
    return "".join(parts)


def _failing_table(trends: Trends) -> str:
    rows = [t for t in trends.scenarios if t.failing_now]
    if not rows:
        return '<p class="none">No scenario is failing in the last night.</p>'
    body = "".join(
        f"<tr><td>{_e(t.scenario)}</td><td>{_e(t.status_now)}</td>"
        f"<td>{_e(t.first_failing_night or '–')}</td>"
        f"<td><code>{_e((t.first_failing_revision or 'unknown')[:10])}</code></td>"
        f"<td>{_e(t.last_good_night or 'never in the window')}</td>"
        f"<td><code>{_e((t.last_good_revision or '–')[:10])}</code></td></tr>"
        for t in rows)
    return ('<table id="failing-table"><thead><tr><th>scenario</th><th>now</th>'
            "<th>failing since night</th><th>revision</th><th>last good night</th>"
            f"<th>last good revision</th></tr></thead><tbody>{body}</tbody></table>")


def _flaky_table(trends: Trends) -> str:
    rows = [t for t in trends.scenarios if t.flaky]
    if not rows:
        return '<p class="none">No flaky scenario in the window.</p>'
    def why(t: ScenarioTrend) -> str:
        more = len(t.flaky_reasons) - 2
        return "; ".join(t.flaky_reasons[:2]) + (f"; and {more} more" if more > 0 else "")

    body = "".join(f"<tr><td>{_e(t.scenario)}</td><td>{t.alternations}</td>"
                   f"<td>{_e(why(t))}</td></tr>" for t in rows)
    return ('<table id="flaky-table"><thead><tr><th>scenario</th><th>alternations</th>'
            f"<th>why</th></tr></thead><tbody>{body}</tbody></table>")


def _strip_table(trends: Trends) -> str:
    ids = [s.info.night_id for s in trends.nights]
    rows = []
    for t in trends.scenarios:
        badges = ('<span class="badge failing">failing</span>' if t.failing_now else "") + (
            '<span class="badge flaky">flaky</span>' if t.flaky else "")
        last = next((v for v in reversed(t.values) if not math.isnan(v)), math.nan)
        rows.append(f'<tr data-scenario="{_e(t.scenario)}"><td>{_e(t.scenario)}{badges}</td>'
                    f"<td>{strip_svg(t, ids)}</td><td>{spark_svg(t)}</td>"
                    f"<td>{_fmt(last)}</td><td>{_fmt(t.limit)}</td></tr>")
    legend = "".join(f'<span style="background:{c}"></span>{s}' for s, c in (
        ("pass", "#2e9d50"), ("fail", "#d64541"), ("error", "#7d3c98"),
        ("timeout", "#e67e22"), ("not run", "#e3e6ea")))
    return (f'<p class="legend">{legend}; the sparkline: {_e(trends.metric)} per night, the '
            "criterion's limit dashed (±∞, e.g. no conflict, leaves a gap)</p>"
            '<table id="status-strip"><thead><tr><th>scenario</th>'
            f"<th>status per night (oldest left)</th><th>{_e(trends.metric)}</th>"
            "<th>last</th><th>limit</th></tr></thead><tbody>" + "".join(rows)
            + "</tbody></table>")


def history_html(trends: Trends) -> str:
    """The whole page as one string."""
    n = len(trends.nights)
    span = (f"{trends.nights[0].info.started_at:%Y-%m-%d} … "
            f"{trends.nights[-1].info.started_at:%Y-%m-%d}" if n else "")
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f"<title>hwyeval history: {_e(Path(trends.catalog).stem)}</title>"
        f"<style>{CSS}</style></head><body><header><h1>hwyeval history: "
        f"{_e(Path(trends.catalog).stem)}</h1><p>{n} nights {span} · {len(trends.scenarios)} "
        f"scenarios · {len(trends.failing)} failing now · {len(trends.flaky)} flaky · "
        f"{_e(trends.db)}</p></header><main>"
        f'<section id="pass-rate"><h2>Pass rate per night</h2>{pass_rate_svg(trends)}'
        "</section>"
        f'<section id="failing"><h2>Failing now</h2>{_failing_table(trends)}</section>'
        f'<section id="flaky"><h2>Flaky</h2>{_flaky_table(trends)}</section>'
        f'<section id="strip"><h2>Scenarios × nights</h2>{_strip_table(trends)}</section>'
        "</main></body></html>")


def write_history_page(trends: Trends, out_dir: str | Path) -> Path:
    """Write ``out_dir/history.html`` (atomically: a reader never sees half a page);
    returns its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / PAGE
    tmp = path.with_name(path.name + ".partial")
    tmp.write_text(history_html(trends), encoding="utf-8")
    tmp.replace(path)
    return path
