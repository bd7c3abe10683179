"""The trend page (``hwyeval history DB --out DIR`` writes ``DIR/history.html``).

One self-contained HTML file, inline CSS and SVG, no script and nothing fetched: the
pass rate per night (each bar links to that night's report); the scenarios failing now
(since which night and revision, the failed criteria with values and limits and what
changed that night, the last good revision); the known failures (xfail); the flaky
ones and why; and the status strip, one row per scenario (failing now first, then
flaky, then known failures), one cell per night linked to that night's run page, a
mark above a cell where the test (T), the limits (L) or the system under test (S)
changed that night, beside a sparkline of the failing criterion's metric (the chosen
metric for a scenario that did not fail) with its limit dashed.

Links are relative to the page (the nights' output directories are where the history
recorded them). A strip with more cells than :data:`MAX_LINKED_CELLS` merges a run of
nights with the same status and no change into one cell linked to its first night, so
the page of 2 000 scenarios × 100 nights stays a few MB.
"""

from __future__ import annotations

import html
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path

from reports.history.trends import ScenarioTrend, Trends, run_page

PAGE = "history.html"
STRIP_W_PX = 640.0  # width of the status strip (cells are 2-14 px wide)
SPARK_W_PX, SPARK_H_PX = 180.0, 26.0
MAX_LINKED_CELLS = 20_000  # scenarios x nights up to which every night is its own cell
CHANGE_LETTERS = {"test": "T", "limits": "L", "sut": "S"}

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
svg rect.xfail{fill:#c9a3a1}svg rect.xpass{fill:#7fb8e0}svg text.chg{font-size:8px;fill:#1d2733}
.badge.known{background:#8a6d6b}td.why{white-space:normal;max-width:520px}
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


class Hrefs:
    """Relative links from the page's folder to the nights' reports and run pages."""

    def __init__(self, page_dir: Path | None) -> None:
        self.page_dir = page_dir.absolute() if page_dir is not None else None

    def to(self, target: str) -> str:
        """``target`` (a path) relative to the page ('' when unknown)."""
        if not target:
            return ""
        if self.page_dir is None:
            return Path(target).as_posix()
        return Path(os.path.relpath(target, self.page_dir)).as_posix()


def pass_rate_svg(trends: Trends, hrefs: Hrefs | None = None) -> str:
    """Bars of the pass rate per night [%] (red below 100 %), each with its night and
    a link to its report."""
    hrefs = hrefs or Hrefs(None)
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
        bar = (f'<rect class="{cls}" x="{left + j * bw + bw * 0.1:.1f}" '
               f'y="{h - bh:.1f}" width="{max(1.0, bw * 0.8):.1f}" height="{bh:.1f}">'
               f"<title>{_e(s.info.night_id)}: {rate:.0%} ({s.passed}/{s.runs}"
               + (f", {s.expected} expected failures" if s.expected else "")
               + f"), revision {_e(s.info.short_revision)}</title></rect>")
        href = hrefs.to(s.info.report)
        parts.append(f'<a href="{_e(href)}">{bar}</a>' if href else bar)
    if trends.nights:
        parts.append(f'<text x="{left}" y="{h + 13}">{_e(trends.nights[0].info.night_id)}'
                     f'</text><text x="{w}" y="{h + 13}" text-anchor="end">'
                     f"{_e(trends.nights[-1].info.night_id)}</text>")
    parts.append("</svg>")
    return "".join(parts)


def _cell_class(status: str | None, mark: object) -> str:
    if status is None:
        return "absent"
    if mark is not None and status in ("pass", "fail"):
        return "xpass" if status == "pass" else "xfail"
    return status


def strip_svg(trend: ScenarioTrend, night_ids: Sequence[str], hrefs: Hrefs | None = None,
              merge: bool = False) -> str:
    """One scenario's statuses, a cell per night linked to that night's run page, a
    letter above a night whose test (T), limits (L) or system under test (S) changed;
    with ``merge``, runs of one status without a change are one cell (module doc)."""
    hrefs = hrefs or Hrefs(None)
    n = max(1, len(trend.statuses))
    cw = min(14.0, max(2.0, STRIP_W_PX / n))
    parts = [f'<svg class="strip" width="{cw * n:.0f}" height="24">']
    classes = [_cell_class(s, m) for s, m in zip(trend.statuses, trend.marks, strict=True)]
    j = 0
    while j < len(classes):
        k = j
        while merge and k + 1 < len(classes) and classes[k + 1] == classes[j] \
                and not trend.changes[k + 1]:
            k += 1
        span = night_ids[j] if j == k else f"{night_ids[j]} … {night_ids[k]}"
        changed = ", ".join(trend.changes[j])
        tip = f"{span}: {classes[j]}" + (f"; changed: {changed}" if changed else "")
        cell = (f'<rect class="{classes[j]}" x="{j * cw:.1f}" y="11" '
                f'width="{(k - j + 1) * cw:.1f}" height="12"><title>{_e(tip)}</title></rect>')
        href = hrefs.to(run_page(trend.run_dirs[j]))
        parts.append(f'<a href="{_e(href)}">{cell}</a>' if href else cell)
        if trend.changes[j]:
            letters = "".join(CHANGE_LETTERS[c] for c in trend.changes[j])
            parts.append(f'<text class="chg" x="{j * cw:.1f}" y="9">{letters}</text>')
        j = k + 1
    parts.append("</svg>")
    return "".join(parts)


def _segments(values: Sequence[float], y: Callable[[float], float]) -> list[list[str]]:
    """The ``x,y`` points [px] of each run of finite values (a gap at ±∞ or absent)."""
    n = max(1, len(values) - 1)
    segment: list[str] = []
    segments: list[list[str]] = [segment]
    for j, v in enumerate(values):
        if math.isfinite(v):
            segment.append(f"{j * SPARK_W_PX / n:.1f},{y(v):.1f}")
        elif segment:
            segment = []
            segments.append(segment)
    return [seg for seg in segments if seg]


def spark_svg(trend: ScenarioTrend) -> str:
    """The metric per night (a line through the finite values) and its limit (dashed);
    ±∞ and absent nights leave a gap. y [px] = 2 + (h - 4)(1 - (v - lo)/(hi - lo)) over
    the values' and the limit's range [lo, hi]."""
    finite = [v for v in trend.values if math.isfinite(v)]
    lim = trend.limit if math.isfinite(trend.limit) else None
    span = finite + ([lim] if lim is not None else [])
    parts = [f'<svg class="sparkline" width="{SPARK_W_PX:.0f}" height="{SPARK_H_PX:.0f}">']
    if span:
        lo, hi = min(span), max(span)
        if hi - lo < 1e-12:
            lo, hi = lo - 1.0, hi + 1.0

        def y(v: float) -> float:
            return 2 + (SPARK_H_PX - 4) * (1 - (v - lo) / (hi - lo))

        for seg in _segments(trend.values, y):
            if len(seg) == 1:
                x_, y_ = seg[0].split(",")
                parts.append(f'<circle cx="{x_}" cy="{y_}" r="1.5" fill="#1f5fa8"/>')
            else:
                parts.append(f'<polyline class="spark" points="{" ".join(seg)}"/>')
        if lim is not None:
            parts.append(f'<line class="limit" x1="0" x2="{SPARK_W_PX:.0f}" y1="{y(lim):.1f}" '
                         f'y2="{y(lim):.1f}"><title>limit {_fmt(lim)}</title></line>')
    parts.append("</svg>")
    return "".join(parts)


def failure_text(t: ScenarioTrend) -> str:
    """The first failing night's failed criteria, ``metric value > limit unit``."""
    parts = []
    for f in t.first_failures:
        op = ">" if f.bound == "max" else "<"
        unit = f" {f.unit}" if f.unit not in ("", "-") else ""
        parts.append(f"{f.criterion or f.metric}: {f.metric} {_fmt(f.value)}{unit} {op} "
                     f"{_fmt(f.limit)}{unit}")
    return "; ".join(parts) or "–"


def _failing_table(trends: Trends) -> str:
    rows = [t for t in trends.scenarios if t.failing_now]
    if not rows:
        return '<p class="none">No scenario is failing in the last night.</p>'
    body = "".join(
        f"<tr><td>{_e(t.scenario)}</td><td>{_e(t.status_now)}</td>"
        f"<td>{_e(t.first_failing_night or '–')}</td>"
        f"<td><code>{_e((t.first_failing_revision or 'unknown')[:10])}</code></td>"
        f'<td class="why">{_e(failure_text(t))}</td>'
        f'<td class="why">{_e("; ".join(t.first_changes) or "–")}</td>'
        f"<td>{_e(t.last_good_night or 'never in the window')}</td>"
        f"<td><code>{_e((t.last_good_revision or '–')[:10])}</code></td></tr>"
        for t in rows)
    return ('<table id="failing-table"><thead><tr><th>scenario</th><th>now</th>'
            "<th>failing since night</th><th>revision</th><th>failed then</th>"
            "<th>changed that night</th><th>last good night</th>"
            f"<th>last good revision</th></tr></thead><tbody>{body}</tbody></table>")


def _known_table(trends: Trends) -> str:
    rows = trends.known_failures
    if not rows:
        return '<p class="none">No scenario is marked xfail in the last night.</p>'
    body = []
    for t in rows:
        mark = t.marks[-1]
        now = ("fixed: remove the xfail" + (" (strict: fails the night)"
                                            if mark is not None and mark.strict else "")
               if t.status_now == "xpass" else "fails as expected")
        body.append(f"<tr><td>{_e(t.scenario)}</td><td>{_e(now)}</td>"
                    f'<td class="why">{_e(mark.reason if mark is not None else "")}</td>'
                    f"<td>{'strict' if mark is not None and mark.strict else ''}</td></tr>")
    return ('<table id="known-table"><thead><tr><th>scenario</th><th>last night</th>'
            "<th>reason</th><th></th></tr></thead><tbody>" + "".join(body)
            + "</tbody></table>")


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


def _badges(t: ScenarioTrend) -> str:
    return (('<span class="badge failing">failing</span>' if t.failing_now else "")
            + ('<span class="badge flaky">flaky</span>' if t.flaky else "")
            + ('<span class="badge known">xfail</span>' if t.known_failure else ""))


def _strip_table(trends: Trends, hrefs: Hrefs) -> str:
    ids = [s.info.night_id for s in trends.nights]
    merge = len(trends.scenarios) * len(ids) > MAX_LINKED_CELLS
    rows = []
    for t in trends.scenarios:
        last = next((v for v in reversed(t.values) if not math.isnan(v)), math.nan)
        rows.append(f'<tr data-scenario="{_e(t.scenario)}"><td>{_e(t.scenario)}{_badges(t)}'
                    f"</td><td>{strip_svg(t, ids, hrefs, merge)}</td><td>{spark_svg(t)}</td>"
                    f"<td>{_e(t.metric)}</td><td>{_fmt(last)}</td><td>{_fmt(t.limit)}</td></tr>")
    legend = "".join(f'<span style="background:{c}"></span>{s}' for s, c in (
        ("pass", "#2e9d50"), ("fail", "#d64541"), ("error", "#7d3c98"),
        ("timeout", "#e67e22"), ("expected failure (xfail)", "#c9a3a1"),
        ("unexpected pass (xpass)", "#7fb8e0"), ("not run", "#e3e6ea")))
    cells = ("a run of nights with one status is one cell, linked to its first night"
             if merge else "each cell links to that night's run page")
    return (f'<p class="legend">{legend}; {cells}; above a cell: T the test, L the limits, '
            "S the system under test changed that night; the sparkline: the failing "
            f"criterion's metric (else {_e(trends.metric)}) per night, its limit dashed (±∞, "
            "e.g. no conflict, leaves a gap)</p>"
            '<table id="status-strip"><thead><tr><th>scenario</th>'
            "<th>status per night (oldest left)</th><th>metric per night</th><th>metric</th>"
            "<th>last</th><th>limit</th></tr></thead><tbody>" + "".join(rows)
            + "</tbody></table>")


def history_html(trends: Trends, page_dir: Path | None = None) -> str:
    """The whole page as one string; links relative to ``page_dir`` (None: as stored)."""
    hrefs = Hrefs(page_dir)
    n = len(trends.nights)
    span = (f"{trends.nights[0].info.started_at:%Y-%m-%d} … "
            f"{trends.nights[-1].info.started_at:%Y-%m-%d}" if n else "")
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f"<title>hwyeval history: {_e(trends.catalog)}</title>"
        f"<style>{CSS}</style></head><body><header><h1>hwyeval history: "
        f"{_e(trends.catalog)}</h1><p>{n} nights {span} · {len(trends.scenarios)} "
        f"scenarios · {len(trends.failing)} failing now · {len(trends.flaky)} flaky · "
        f"{len(trends.known_failures)} known failures · {_e(trends.db)}</p></header><main>"
        f'<section id="pass-rate"><h2>Pass rate per night</h2>{pass_rate_svg(trends, hrefs)}'
        "</section>"
        f'<section id="failing"><h2>Failing now</h2>{_failing_table(trends)}</section>'
        f'<section id="known"><h2>Known failures (xfail)</h2>{_known_table(trends)}</section>'
        f'<section id="flaky"><h2>Flaky</h2>{_flaky_table(trends)}</section>'
        f'<section id="strip"><h2>Scenarios × nights</h2>{_strip_table(trends, hrefs)}'
        "</section></main></body></html>")


def write_history_page(trends: Trends, out_dir: str | Path) -> Path:
    """Write ``out_dir/history.html`` (atomically: a reader never sees half a page);
    returns its path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / PAGE
    tmp = path.with_name(path.name + ".partial")
    tmp.write_text(history_html(trends, out), encoding="utf-8")
    tmp.replace(path)
    return path
