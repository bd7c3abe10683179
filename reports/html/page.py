"""report.html, the index of a catalog output: it reads in ten seconds and scales.

Top to bottom: a header (status counts, catalog, git revision, host, load, when); the
failures list (:mod:`reports.html.failures`) right under it; pass/fail matrices
(families × controller variants and scenarios × variants, cells linked to the run
pages); per-variant summary tables with units; timing CDFs per loop from the pooled
histograms; a filterable table of every run. Each run's plots and bird's-eye views
are on its own page (:mod:`reports.html.run_page`), so the index stays small for
thousands of runs. Everything is read from the stored verdicts; nothing loads from
the network.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from reports.charts import PALETTE, Series, esc, fmt, line_chart
from reports.html.failures import (
    STATUS_ORDER,
    badge,
    failures_section,
    known_failures_section,
    log_link,
)
from reports.html.links import Links
from reports.html.style import CSS
from reports.manifest import Manifest, not_run
from reports.record.meta import STATUSES
from reports.tables import Pools, RunEntry, summary_frame
from reports.variants import matrix_row


def _variants(runs: Sequence[RunEntry]) -> list[str]:
    return sorted({r.label for r in runs})


def matrix_tables(runs: Sequence[RunEntry], links: Links) -> str:
    """Family × variant pass-rate matrix and scenario × variant status matrix."""
    variants = _variants(runs)
    families = sorted({r.family for r in runs})
    head = "".join(f"<th>{esc(v)}</th>" for v in variants)
    out = ['<h2 id="matrix">Pass/fail matrix</h2><table class="matrix"><thead><tr>'
           f"<th>family</th>{head}</tr></thead><tbody>"]
    for fam in families:
        cells = []
        for variant in variants:
            members = [r for r in runs if r.family == fam and r.label == variant]
            if not members:
                cells.append('<td class="empty">–</td>')
                continue
            n_pass = sum(r.status == "pass" for r in members)
            hue = int(120 * n_pass / len(members))
            cells.append(f'<td class="rate" style="background:hsl({hue},65%,82%)" '
                         f'title="{n_pass} of {len(members)} pass">{n_pass}/{len(members)}</td>')
        out.append(f"<tr><th>{esc(fam)}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    rows = {r.run_id: matrix_row(r.info, r.scenario, r.controller) for r in runs}
    by_key = {(rows[r.run_id], r.label): r for r in runs}
    scenarios = sorted({(r.family, rows[r.run_id]) for r in runs})
    out.append(f'<table class="matrix" id="scenario-matrix"><thead><tr><th>scenario</th>{head}'
               "</tr></thead><tbody>")
    last_family = None
    for fam, scn in scenarios:
        if fam != last_family:
            out.append(f'<tr class="famrow"><th colspan="{len(variants) + 1}">{esc(fam)}'
                       "</th></tr>")
            last_family = fam
        cells = []
        for variant in variants:
            run = by_key.get((scn, variant))
            if run is None:
                cells.append('<td class="empty">–</td>')
                continue
            tip = "; ".join(f.text for f in run.failures) or (
                run.error.strip().splitlines()[-1] if run.error.strip() else run.status)
            cells.append(f'<td class="cell {esc(run.status)}" title="{esc(tip)}">'
                         f'<a href="{esc(links.page_href(run.run_id))}">{esc(run.status)}</a></td>')
        out.append(f"<tr><th>{esc(scn)}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    return "".join(out)


# (summary.csv column, heading with unit)
SUMMARY_COLUMNS = (("runs", "runs"), ("pass", "pass"), ("fail", "fail"), ("error", "error"),
                   ("timeout", "timeout"), ("pass_rate", "pass rate [%]"),
                   ("sum_collision", "collisions"), ("min_min_gap_m", "min gap [m]"),
                   ("min_min_ttc_s", "min TTC [s]"),
                   ("mean_progress_ratio", "progress ratio [-]"),
                   ("max_max_abs_lat_acc_mps2", "max |lat acc| [m/s²]"),
                   ("max_max_abs_jerk_mps3", "max |jerk| [m/s³]"),
                   ("mean_rms_lat_dev_m", "RMS lat dev [m]"),
                   ("step_ms_p50", "step p50 [ms]"), ("step_ms_p99", "step p99 [ms]"),
                   ("outer_ms_p99", "outer p99 [ms]"), ("inner_ms_p99", "inner p99 [ms]"),
                   ("sum_deadline_misses", "deadline misses"), ("sum_fallbacks", "fallbacks"))


def summary_tables(summary: pd.DataFrame) -> str:
    """One table: a row per variant (all families), then its families indented."""
    if summary.empty:
        return ""
    head = "".join(f"<th>{esc(label)}</th>" for _, label in SUMMARY_COLUMNS)
    out = ['<h2 id="summary">Summary per controller variant</h2><table class="summary">'
           f"<thead><tr><th>variant / family</th>{head}</tr></thead><tbody>"]
    for variant, grp in summary.groupby("variant", sort=True):
        grp = pd.concat([grp[grp["family"] == "ALL"], grp[grp["family"] != "ALL"]])
        for _, row in grp.iterrows():
            is_all = row["family"] == "ALL"
            name = esc(variant) if is_all else f"&nbsp;&nbsp;{esc(row['family'])}"
            cells = []
            for key, _ in SUMMARY_COLUMNS:
                value = row.get(key, math.nan)
                text = f"{100 * value:.0f}" if key == "pass_rate" and pd.notna(value) \
                    else fmt(value)
                cells.append(f"<td>{text}</td>")
            cls = ' class="all"' if is_all else ""
            out.append(f"<tr{cls}><th>{name}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def timing_section(runs: Sequence[RunEntry], pools: Pools) -> str:
    """CDF per loop (whole step, outer, inner, SUMO), one line per variant, from the
    pooled histograms (:mod:`reports.pool`)."""
    periods = [r.info.step_s * 1e3 for r in runs
               if r.info is not None and math.isfinite(r.info.step_s)]
    deadline = float(np.median(periods)) if periods else None
    charts = []
    for loop, title in (("step", "whole controller step"), ("outer", "outer loop"),
                        ("inner", "inner loop"), ("sumo", "SUMO step")):
        series = []
        for i, variant in enumerate(_variants(runs)):
            pool = pools.get((variant, "ALL"), {}).get(loop)
            if pool is None or pool.n == 0:
                continue
            t, frac = pool.cdf()
            if t.size == 0:  # every sample below the pool's first bin (e.g. no outer loop)
                continue
            series.append(Series(variant, t * 1e3, frac, PALETTE[i % len(PALETTE)]))
        if not series:
            charts.append(f'<div class="nodata">CDF: {esc(title)}: no data</div>')
            continue
        cat = np.concatenate([s.x for s in series])
        xlog = bool(cat.max() / max(cat.min(), 1e-9) > 10)
        vl = [(deadline, "#dc2626", "control period")] if deadline and loop == "step" else []
        charts.append(line_chart(series, title=f"CDF: {title}", ylabel="fraction of steps",
                                 xlabel="time per step [ms]", width=330, height=230,
                                 xlog=xlog, vlines=vl, legend_inside="upper-left"))
    return ('<h2 id="timing">Timing distributions</h2><div class="cdfs">' + "".join(charts)
            + "</div>")


RUN_COLUMNS = (("collision", "collision", ""), ("min_gap_m", "min gap", "m"),
               ("min_ttc_s", "min TTC", "s"), ("progress_ratio", "progress", "-"),
               ("max_abs_lat_acc_mps2", "max |lat acc|", "m/s²"),
               ("min_long_acc_mps2", "min long acc", "m/s²"),
               ("max_abs_jerk_mps3", "max |jerk|", "m/s³"),
               ("rms_lat_dev_m", "RMS lat dev", "m"), ("step_ms_p99", "step p99", "ms"))


def runs_table(runs: Sequence[RunEntry], links: Links) -> str:
    """Every run, one row (failed ones first), filterable by text and status."""
    ordered = sorted(runs, key=lambda r: (STATUS_ORDER.get(r.status, 9), r.family, r.scenario,
                                          r.label))
    checks = "".join(f'<label><input type="checkbox" value="{s}" checked> {s}</label>'
                     for s in STATUSES)
    head = "".join(f"<th>{esc(label)}{f' [{unit}]' if unit else ''}</th>"
                   for _, label, unit in RUN_COLUMNS)
    rows = []
    for r in ordered:
        failed = {f.metric for f in r.failures}
        cells = "".join(f'<td{" class=bad" if name in failed else ""}>{fmt(r.value(name))}</td>'
                        for name, _, _ in RUN_COLUMNS)
        text = f"{r.scenario} {r.label} {r.family}".lower()
        rows.append(f'<tr data-status="{esc(r.status)}" data-text="{esc(text)}">'
                    f"<td>{badge(r.status)}</td><td><a href=\"{esc(links.page_href(r.run_id))}\">"
                    f"{esc(r.scenario)}</a></td><td>{esc(r.label)}</td><td>{esc(r.family)}</td>"
                    f"{cells}<td>{fmt(r.wall_s, 3)}</td>"
                    f"<td>{log_link(r, links, from_page=False)}</td></tr>")
    return ('<h2 id="runs">Runs</h2><div class="controls"><input type="search" id="filter" '
            f'placeholder="filter scenario / variant / family">{checks} <span class="meta">'
            f'<span id="shown">{len(runs)}</span> shown</span></div><table class="runs">'
            "<thead><tr><th>status</th><th>scenario</th><th>variant</th><th>family</th>"
            f"{head}<th>wall [s]</th><th>Rerun log</th></tr></thead><tbody>{''.join(rows)}"
            "</tbody></table>")


def provenance_line(manifest: Manifest | None) -> str:
    if manifest is None:
        return "<span>provenance unknown (no manifest.json)</span>"
    p = manifest.provenance
    load = f"load {p.load:.2f}/core" if math.isfinite(p.load) else "load –"
    return (f"<span>git {esc(p.short_sha)}</span><span>hwyeval {esc(p.hwyeval_version)} · "
            f"SUMO {esc(p.sumo_version)} · rerun {esc(p.rerun_version)}</span>"
            f"<span>{esc(p.host)} ({esc(p.cpu_model)}, {p.cpu_count} cores, {load})</span>"
            f"<span>ran {esc(manifest.started)}</span>")


JS = """
(function(){
  var q=document.getElementById('filter');
  var boxes=document.querySelectorAll('.controls input[type=checkbox]');
  var rows=document.querySelectorAll('table.runs tbody tr');
  function apply(){
    var text=(q&&q.value||'').toLowerCase(), allowed={}, shown=0;
    boxes.forEach(function(b){allowed[b.value]=b.checked;});
    rows.forEach(function(r){
      var ok=allowed[r.dataset.status]!==false&&r.dataset.text.indexOf(text)>=0;
      r.style.display=ok?'':'none'; if(ok){shown++;}
    });
    document.getElementById('shown').textContent=shown;
  }
  if(q){q.addEventListener('input',apply);}
  boxes.forEach(function(b){b.addEventListener('change',apply);});
  // click a column head of a sortable table: sort by it (numbers by value), again: reverse
  document.querySelectorAll('table.sortable, table.runs').forEach(function(t){
    t.querySelectorAll('thead th').forEach(function(th, col){
      th.style.cursor='pointer'; th.title='sort';
      th.addEventListener('click', function(){
        var body=t.tBodies[0], rows=Array.prototype.slice.call(body.rows);
        var dir=th.dataset.dir==='asc'?-1:1; th.dataset.dir=dir===1?'asc':'desc';
        function key(r){var c=r.cells[col]; if(!c){return '';}
          var v=c.dataset.sort!==undefined?c.dataset.sort:c.textContent.trim();
          var n=parseFloat(v); return isNaN(n)?v.toLowerCase():n;}
        rows.sort(function(a,b){var x=key(a),y=key(b);
          if(typeof x==='number'&&typeof y==='number'){return dir*(x-y);}
          return dir*String(x).localeCompare(String(y));});
        rows.forEach(function(r){body.appendChild(r);});
      });
    });
  });
})();
"""


def not_run_section(names: Sequence[str]) -> str:
    """The banner of an interrupted run: which scenarios of the catalog were not run
    ('' when every one was), above the failures list, so the page never reads as a
    complete, green night."""
    if not names:
        return ""
    shown = ", ".join(names[:20]) + (f" (+{len(names) - 20} more)" if len(names) > 20 else "")
    return ('<section id="not-run" class="notrun"><h2>Interrupted: '
            f"{len(names)} scenario{'' if len(names) == 1 else 's'} not run</h2>"
            f"<p>{esc(shown)}. <code>hwyeval run CATALOG --out DIR --resume</code> runs "
            "them; the runs below are the ones that finished.</p></section>")


def render_index(runs: Sequence[RunEntry], pools: Pools, links: Links, title: str,
                 manifest: Manifest | None = None) -> str:
    """The index page as a string (module doc)."""
    counts = {s: sum(1 for r in runs if r.status == s) for s in STATUSES}
    catalogs = sorted({r.info.catalog_name or r.info.catalog for r in runs
                       if r.info is not None})
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    count_html = " ".join(f"<span>{badge(s)} {counts[s]}</span>" for s in STATUSES)
    unlogged = sum(1 for r in runs if r.log_error)
    if unlogged:
        count_html += (f' <span id="log-failures"><span class="badge nolog">log failed</span> '
                       f"{unlogged} run{'' if unlogged == 1 else 's'} without a Rerun log</span>")
    parts = [
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        '<link rel="icon" href="data:,">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f'<header><h1>{esc(title)}</h1><div class="counts"><span><b>{len(runs)}</b> runs'
        f"</span>{count_html}<span>catalog: {esc(', '.join(catalogs) or '–')}</span>"
        f"{provenance_line(manifest)}<span>report {esc(now)}</span></div>"
        '<nav><a href="#failures">failures</a> · <a href="#matrix">matrix</a> · '
        '<a href="#summary">summary</a> · <a href="#timing">timing</a> · '
        '<a href="#runs">runs</a></nav></header><main>',
        not_run_section(not_run(manifest, [n for r in runs for n in (r.scenario, r.run_id)])),
        failures_section(runs, links),
        known_failures_section(runs, links),
        matrix_tables(runs, links),
        summary_tables(summary_frame(runs, pools)),
        timing_section(runs, pools),
        runs_table(runs, links),
        f"</main><script>{JS}</script></body></html>",
    ]
    return "\n".join(parts)
