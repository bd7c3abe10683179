"""The search's page (``search.html``), self-contained, drawn from ``search.csv``
(its rows: :mod:`reports.record.search`).

The page (:func:`write_search_page`) reads only ``search.csv`` and the run directories
beside it (whether ``run.rrd`` and the report's run page exist): per family, the
robustness of every run over the trials with the best so far (a step line; the zero
line is the pass/fail boundary); the searched space as pair plots, every run a dot
coloured by its robustness (red < 0 failed, blue > 0, white at 0; refused points grey
crosses); the failure modes, each with its runs linked to their report pages and
Rerun logs, and its ``found.toml`` case.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

from reports.charts import esc, fmt
from reports.html.links import RUN_PAGES, Links
from reports.html.style import CSS
from reports.record import RRD
from reports.record.codec import write_text_atomic
from reports.record.search import SEARCH_CSV, SearchRow, read_search_csv

__all__ = ["SEARCH_HTML", "write_search_page"]

SEARCH_HTML = "search.html"
ROB_CLIP = 2.0  # colour saturates at |robustness| >= this
PLOT_PX = 170
MAX_PAIR_PARAMS = 6


# ------------------------------------------------------------------ drawing
def colour(rob: float) -> str:
    """Diverging colour of a robustness: red (failed) .. white (0) .. blue (robust)."""
    if math.isnan(rob):
        return "#94a3b8"
    x = max(-1.0, min(1.0, rob / ROB_CLIP))
    lo, hi = (220, 38, 38), (37, 99, 235)
    end = lo if x < 0 else hi
    a = abs(x)
    r, g, b = (int(255 + (c - 255) * a) for c in end)
    return f"#{r:02x}{g:02x}{b:02x}"


def _scale(values: Sequence[float], lo_px: float, hi_px: float
           ) -> tuple[float, float, Callable[[float], float]]:
    finite = [v for v in values if math.isfinite(v)]
    lo, hi = (min(finite), max(finite)) if finite else (0.0, 1.0)
    if hi <= lo:
        lo, hi = lo - 0.5, hi + 0.5

    def to_px(v: float) -> float:
        return lo_px + (v - lo) / (hi - lo) * (hi_px - lo_px)

    return lo, hi, to_px


def robustness_chart(rows: Sequence[SearchRow]) -> str:
    """Robustness of each run over the trial number, with the best so far."""
    runs = [r for r in rows if r.kind == "trial" and math.isfinite(r.robustness)]
    if not runs:
        return "<p>No judged run.</p>"
    w, h, m = 640, 240, 46
    xs = [float(r.trial) for r in runs]
    ys = [max(-5 * ROB_CLIP, min(5 * ROB_CLIP, r.robustness)) for r in runs]
    _, _, px = _scale([*xs, 0.0], m, w - 10)
    ylo, yhi, py0 = _scale([*ys, 0.0], h - 30, 10)

    def py(v: float) -> float:
        return py0(v)

    parts = [f'<svg class="chart" width="{w}" height="{h}" viewBox="0 0 {w} {h}">',
             f'<line x1="{m}" x2="{w - 10}" y1="{py(0):.1f}" y2="{py(0):.1f}" '
             'stroke="#64748b" stroke-dasharray="4 3"/>',
             f'<text x="4" y="{py(yhi) + 4:.0f}" font-size="11">{fmt(yhi, 3)}</text>',
             f'<text x="4" y="{py(ylo):.0f}" font-size="11">'
             f'{fmt(ylo, 3) if ylo < 0 else ""}</text>',
             f'<text x="4" y="{py(0) + 4:.0f}" font-size="11">0</text>',
             f'<text x="{w / 2:.0f}" y="{h - 6}" font-size="11">trial</text>']
    best = math.inf
    path: list[str] = []
    for x, y in sorted(zip(xs, ys, strict=True)):
        best = min(best, y)
        path.append(f"{'M' if not path else 'L'}{px(x):.1f},{py(best):.1f}")
    parts.append(f'<path d="{" ".join(path)}" fill="none" stroke="#0f172a" '
                 'stroke-width="1.5"/>')
    for r, x, y in zip(runs, xs, ys, strict=True):
        parts.append(f'<circle cx="{px(x):.1f}" cy="{py(y):.1f}" r="3.5" '
                     f'fill="{colour(r.robustness)}" stroke="#334155" stroke-width="0.5">'
                     f'<title>{esc(r.run)}: {fmt(r.robustness, 4)} '
                     f'({esc(r.robustness_criterion)})</title></circle>')
    parts.append("</svg>")
    return "".join(parts)


def _pair(rows: Sequence[SearchRow], xp: str, yp: str) -> str:
    s = PLOT_PX
    xs = [r.number(xp) for r in rows]
    ys = [r.number(yp) for r in rows]
    xlo, xhi, px = _scale(xs, 6, s - 6)
    ylo, yhi, py = _scale(ys, s - 18, 6)
    parts = [f'<svg width="{s}" height="{s}" viewBox="0 0 {s} {s}">'
             f'<rect width="{s}" height="{s}" fill="#fff" stroke="#cbd5e1"/>'
             f'<text x="3" y="{s - 3}" font-size="9" fill="#64748b">x {fmt(xlo, 3)}'
             f'..{fmt(xhi, 3)}, y {fmt(ylo, 3)}..{fmt(yhi, 3)}</text>']
    order = sorted(range(len(rows)), key=lambda i: -abs(rows[i].robustness)
                   if math.isfinite(rows[i].robustness) else math.inf)
    for i in order:  # the points nearest the boundary drawn last, on top
        x, y, r = xs[i], ys[i], rows[i]
        if not (math.isfinite(x) and math.isfinite(y)):
            continue
        if r.status == "refused":
            parts.append(f'<text x="{px(x) - 3:.1f}" y="{py(y) + 3:.1f}" font-size="9" '
                         'fill="#94a3b8">×</text>')
            continue
        parts.append(f'<circle cx="{px(x):.1f}" cy="{py(y):.1f}" r="3" '
                     f'fill="{colour(r.robustness)}" stroke="#475569" stroke-width="0.4">'
                     f'<title>{esc(r.run)}: {fmt(r.robustness, 4)}</title></circle>')
    parts.append("</svg>")
    return "".join(parts)


def pair_plots(rows: Sequence[SearchRow], paths: Sequence[str]) -> str:
    """Lower-triangle pair plots of the numeric searched keys, coloured by robustness."""
    numeric = [p for p in paths if any(math.isfinite(r.number(p)) for r in rows)]
    numeric = numeric[:MAX_PAIR_PARAMS]
    if len(numeric) < 2:
        if len(numeric) == 1:
            return (f"<p>{esc(numeric[0])} (x) against robustness is the only "
                    "numeric key.</p>")
        return "<p>No numeric searched key to plot.</p>"
    cells = ["<table class='pairs'>"]
    for j, yp in enumerate(numeric[1:], start=1):
        cells.append(f"<tr><th>{esc(yp)}</th>")
        for i, xp in enumerate(numeric[:-1]):
            cells.append(f"<td>{_pair(rows, xp, yp)}</td>" if i < j else "<td></td>")
        cells.append("</tr>")
    cells.append("<tr><th></th>" + "".join(f"<th>{esc(p)}</th>" for p in numeric[:-1])
                 + "</tr></table>")
    return "".join(cells)


def _run_links(out: Path, run: str) -> str:
    if not run:
        return ""
    links = Links(out)
    page = links.page_file(run)
    text = f"<a href='{RUN_PAGES}/{esc(page.name)}'>{esc(run)}</a>" if page.is_file() \
        else esc(run)
    if (out / run / RRD).is_file():
        text += f" (<a href='{esc(run)}/{RRD}'>{RRD}</a>)"
    return text


def modes_table(out: Path, rows: Sequence[SearchRow]) -> str:
    """The failure modes: how many runs, the runs (linked) and the found.toml case."""
    modes: dict[str, list[SearchRow]] = {}
    for r in rows:
        if r.status == "fail" and r.failure_mode:
            modes.setdefault(r.failure_mode, []).append(r)
    if not modes:
        return "<p>No failure found.</p>"
    out_rows = ["<table><tr><th>failure mode</th><th>runs</th><th>worst robustness</th>"
                "<th>found.toml case</th><th>its run</th><th>runs of this mode</th></tr>"]
    for mode, members in sorted(modes.items()):
        found = [r for r in members if r.found]
        worst = min(r.robustness for r in members)
        case = found[0] if found else None
        listed = ", ".join(_run_links(out, r.run) for r in members[:12])
        more = f" (+{len(members) - 12} more)" if len(members) > 12 else ""
        out_rows.append(
            f"<tr><th>{esc(mode)}</th><td>{len(members)}</td><td>{fmt(worst, 4)}</td>"
            f"<td>{esc(case.found) if case else ''}</td>"
            f"<td>{_run_links(out, case.run) if case else ''}</td>"
            f"<td style='text-align:left;max-width:520px;word-break:break-all'>"
            f"{listed}{more}</td></tr>")
    out_rows.append("</table>")
    return "".join(out_rows)


def _family_section(out: Path, family: str, rows: Sequence[SearchRow]) -> str:
    trials = [r for r in rows if r.kind == "trial"]
    ran = [r for r in trials if r.status != "refused"]
    failed = [r for r in ran if r.status == "fail"]
    paths = [k for k, _ in trials[0].params] if trials else []
    first = next((i + 1 for i, r in enumerate(ran) if r.status == "fail"), None)
    best = min((r for r in ran if math.isfinite(r.robustness)),
               key=lambda r: r.robustness, default=None)
    best_text = (f"{fmt(best.robustness, 4)} ({esc(best.robustness_criterion)}, "
                 f"{esc(best.run)})") if best else "—"
    summary = (f"{len(ran)} runs, {len(trials) - len(ran)} refused points, {len(failed)} "
               f"failed; first failure at run {first if first else '—'}; best robustness "
               f"{best_text}")
    return (f"<h2>{esc(family)}</h2><p>{summary}</p>"
            f"<h3>Robustness over the trials (line: best so far)</h3>{robustness_chart(trials)}"
            f"<h3>The searched space (red: failed, blue: passed with margin)</h3>"
            f"{pair_plots(trials, paths)}"
            f"<h3>Failure modes</h3>{modes_table(out, [*rows])}")


def render_search_page(out: Path, rows: Sequence[SearchRow], title: str) -> str:
    families: dict[str, list[SearchRow]] = {}
    for r in rows:
        families.setdefault(r.family, []).append(r)
    body = "".join(_family_section(out, f, members) for f, members in families.items())
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{esc(title)}</title>"
            f"<style>{CSS}</style></head><body><header><h1>{esc(title)}</h1></header>"
            f"<main>{body or '<p>No trial.</p>'}</main></body></html>")


def write_search_page(out: Path, title: str = "hwyeval search") -> Path:
    """Write ``out/search.html`` from ``out/search.csv`` and the run directories."""
    rows = read_search_csv(out / SEARCH_CSV)
    path = out / SEARCH_HTML
    write_text_atomic(path, render_search_page(out, rows, title))
    return path
