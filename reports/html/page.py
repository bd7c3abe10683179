"""report.html: one self-contained page (inline CSS, JS and SVG; no network request).

Contents: header with status counts; pass/fail matrices (families × controllers and
scenarios × controllers, cells linked to the runs); per-controller summary tables;
timing CDFs per loop (total, outer, inner, SUMO) with one line per controller; then one
collapsible section per run (failed/errored first and open, see
:mod:`reports.html.runs`). Everything shown is read from the stored verdicts, series
and traces.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from reports.html.charts import cdf_chart, esc, fmt
from reports.html.runs import badge, run_anchor, run_section
from reports.record.meta import STATUSES
from reports.tables import RunEntry, pooled_times_s, summary_frame

STATUS_ORDER = {"error": 0, "timeout": 1, "fail": 2, "pass": 3}


def matrix_row(run: RunEntry) -> str:
    """Scenario name without the controller part a controller sweep adds
    (``s3_stall__two_loop`` -> ``s3_stall``), so a row holds the same case for every
    controller."""
    ctrl = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in run.controller.lower())
    parts = [p for p in run.scenario.split("__") if p != ctrl]
    return "__".join(parts) or run.scenario


def matrix_tables(runs: Sequence[RunEntry]) -> str:
    """Family × controller pass-rate matrix and scenario × controller status matrix."""
    controllers = sorted({r.controller for r in runs})
    families = sorted({r.family for r in runs})
    out = ['<h2 id="matrix">Pass/fail matrix</h2><table class="matrix"><thead><tr>'
           "<th>family</th>" + "".join(f"<th>{esc(c)}</th>" for c in controllers)
           + "</tr></thead><tbody>"]
    for fam in families:
        cells = []
        for ctrl in controllers:
            members = [r for r in runs if r.family == fam and r.controller == ctrl]
            if not members:
                cells.append('<td class="empty">–</td>')
                continue
            n_pass = sum(r.status == "pass" for r in members)
            rate = n_pass / len(members)
            hue = int(120 * rate)
            cells.append(f'<td class="rate" style="background:hsl({hue},65%,82%)" '
                         f'title="{n_pass} of {len(members)} pass">{n_pass}/{len(members)}</td>')
        out.append(f"<tr><th>{esc(fam)}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    by_key = {(matrix_row(r), r.controller): r for r in runs}
    scenarios = sorted({(r.family, matrix_row(r)) for r in runs})
    out.append('<table class="matrix" id="scenario-matrix"><thead><tr><th>scenario</th>'
               + "".join(f"<th>{esc(c)}</th>" for c in controllers) + "</tr></thead><tbody>")
    last_family = None
    for fam, scn in scenarios:
        if fam != last_family:
            out.append(f'<tr class="famrow"><th colspan="{len(controllers) + 1}">{esc(fam)}'
                       "</th></tr>")
            last_family = fam
        cells = []
        for ctrl in controllers:
            run = by_key.get((scn, ctrl))
            if run is None:
                cells.append('<td class="empty">–</td>')
                continue
            err_lines = run.error.strip().splitlines()
            tip = "; ".join(f.text for f in run.failures) or (err_lines[-1] if err_lines
                                                              else run.status)
            cells.append(f'<td class="cell {esc(run.status)}" title="{esc(tip)}">'
                         f'<a href="#{run_anchor(run)}">{esc(run.status)}</a></td>')
        out.append(f"<tr><th>{esc(scn)}</th>{''.join(cells)}</tr>")
    out.append("</tbody></table>")
    return "".join(out)


SUMMARY_COLUMNS = (("runs", "runs"), ("pass", "pass"), ("fail", "fail"), ("error", "error"),
                   ("timeout", "timeout"), ("pass_rate", "pass rate"),
                   ("sum_collision", "collisions"), ("min_min_gap_m", "min gap [m]"),
                   ("min_min_ttc_s", "min TTC [s]"), ("mean_progress_ratio", "progress ratio"),
                   ("max_max_abs_lat_acc_mps2", "max |lat acc|"),
                   ("max_max_abs_jerk_mps3", "max |jerk|"), ("mean_rms_lat_dev_m", "RMS lat dev"),
                   ("step_ms_p50", "step p50 [ms]"), ("step_ms_p99", "step p99 [ms]"),
                   ("outer_ms_p99", "outer p99 [ms]"), ("inner_ms_p99", "inner p99 [ms]"),
                   ("sum_deadline_misses", "deadline misses"), ("sum_fallbacks", "fallbacks"))


def summary_tables(summary: pd.DataFrame) -> str:
    """Per-controller summary tables (all runs, then per family)."""
    if summary.empty:
        return ""
    out = ['<h2 id="summary">Per-controller summary</h2>']
    for controller, grp in summary.groupby("controller", sort=True):
        grp = pd.concat([grp[grp["family"] == "ALL"], grp[grp["family"] != "ALL"]])
        out.append(f"<h3>{esc(controller)}</h3><table class=\"summary\"><thead><tr>"
                   "<th>family</th>" + "".join(f"<th>{esc(label)}</th>"
                                               for _, label in SUMMARY_COLUMNS)
                   + "</tr></thead><tbody>")
        for _, row in grp.iterrows():
            cls = ' class="all"' if row["family"] == "ALL" else ""
            cells = []
            for key, _ in SUMMARY_COLUMNS:
                value = row.get(key, math.nan)
                text = f"{100 * value:.0f}%" if key == "pass_rate" and pd.notna(value) \
                    else fmt(value)
                cells.append(f"<td>{text}</td>")
            out.append(f"<tr{cls}><th>{esc(row['family'])}</th>{''.join(cells)}</tr>")
        out.append("</tbody></table>")
    return "".join(out)


def timing_section(runs: Sequence[RunEntry]) -> str:
    """CDF per loop (total, outer, inner, SUMO), one line per controller."""
    controllers = sorted({r.controller for r in runs})
    periods = [r.info.step_s * 1e3 for r in runs
               if r.info is not None and math.isfinite(r.info.step_s)]
    deadline = float(np.median(periods)) if periods else None
    charts = []
    for loop, title in (("step", "whole controller step"), ("outer", "outer loop"),
                        ("inner", "inner loop"), ("sumo", "SUMO step")):
        samples = {}
        for ctrl in controllers:
            samples[ctrl] = pooled_times_s([r for r in runs if r.controller == ctrl],
                                           loop) * 1e3
        charts.append(cdf_chart(samples, title=f"CDF: {title}",
                                deadline_ms=deadline if loop == "step" else None))
    return ('<h2 id="timing">Timing distributions</h2><div class="cdfs">' + "".join(charts)
            + "</div>")


CSS = """
:root{--pass:#15803d;--fail:#dc2626;--error:#7c3aed;--timeout:#d97706}
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;
color:#0f172a;background:#f1f5f9}
header{background:#0f172a;color:#f8fafc;padding:14px 24px;position:sticky;top:0;z-index:5}
header h1{font-size:19px;margin:0 0 6px}
header .counts span{margin-right:12px}
main{padding:10px 24px 40px;max-width:1400px}
h2{margin:26px 0 8px;font-size:17px}h3{margin:14px 0 6px;font-size:15px}
table{border-collapse:collapse;background:#fff;margin:6px 0 12px}
th,td{border:1px solid #e2e8f0;padding:3px 8px;text-align:center;font-size:13px}
th{background:#f8fafc}tbody th{text-align:left}
.matrix td.cell a{color:#fff;text-decoration:none;display:block}
td.cell.pass{background:var(--pass)}td.cell.fail{background:var(--fail)}
td.cell.error{background:var(--error)}td.cell.timeout{background:var(--timeout)}
td.empty{color:#94a3b8}tr.famrow th{background:#e2e8f0;font-weight:600}
tr.all{font-weight:600;background:#f8fafc}
.badge{display:inline-block;min-width:54px;text-align:center;border-radius:4px;color:#fff;
padding:0 6px;font-size:12px;font-weight:600}
.badge.pass{background:var(--pass)}.badge.fail{background:var(--fail)}
.badge.error{background:var(--error)}.badge.timeout{background:var(--timeout)}
details.run{background:#fff;border:1px solid #e2e8f0;border-radius:6px;margin:8px 0;
padding:6px 12px}
details.run>summary{cursor:pointer;padding:4px 0}
.why{color:#b91c1c;font-size:12px;margin-left:8px}.ctrl{color:#1d4ed8}.fam{color:#64748b}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(210px,1fr));gap:2px 12px;
margin:8px 0;font-size:12px}
.grid div{display:flex;justify-content:space-between;border-bottom:1px dotted #e2e8f0}
.grid div.bad{color:#b91c1c;font-weight:600}
.grid span{color:#475569}.grid div.bad span{color:#b91c1c}
svg{display:block;margin:6px 0;background:#fff}
svg .ct{font-size:12px;font-weight:600;fill:#0f172a}
svg .tick{font-size:10px;fill:#475569}svg .legend{font-size:11px;font-weight:600}
svg .grid{stroke:#eef2f7}svg .frame{fill:none;stroke:#cbd5e1}
.cdfs{display:flex;flex-wrap:wrap;gap:8px}
pre.err{background:#1e1b4b;color:#e0e7ff;padding:8px;overflow:auto;max-height:260px;
font-size:12px}
.nodata{color:#94a3b8;font-style:italic;margin:4px 0}.meta{color:#475569;font-size:12px}
.controls{margin:10px 0}.controls input[type=search]{padding:3px 6px;width:240px}
.controls label{margin-left:10px}.controls button{margin-left:8px}
code{font-size:12px}
"""

JS = """
(function(){
  function openHash(){
    var id=decodeURIComponent(location.hash.slice(1));
    if(!id){return;}
    var el=document.getElementById(id);
    if(el&&el.tagName==='DETAILS'){el.open=true;el.scrollIntoView();}
  }
  window.addEventListener('hashchange',openHash);
  openHash();
  var q=document.getElementById('filter');
  var boxes=document.querySelectorAll('.controls input[type=checkbox]');
  function apply(){
    var text=(q&&q.value||'').toLowerCase();
    var allowed={};
    boxes.forEach(function(b){allowed[b.value]=b.checked;});
    var shown=0;
    document.querySelectorAll('details.run').forEach(function(d){
      var ok=allowed[d.dataset.status]!==false&&d.dataset.text.indexOf(text)>=0;
      d.style.display=ok?'':'none';
      if(ok){shown++;}
    });
    var c=document.getElementById('shown');
    if(c){c.textContent=shown;}
  }
  if(q){q.addEventListener('input',apply);}
  boxes.forEach(function(b){b.addEventListener('change',apply);});
  function setAll(v){document.querySelectorAll('details.run').forEach(function(d){d.open=v;});}
  var ex=document.getElementById('expand');
  if(ex){ex.addEventListener('click',function(){setAll(true);});}
  var co=document.getElementById('collapse');
  if(co){co.addEventListener('click',function(){setAll(false);});}
  apply();
})();
"""


def render_report(runs: Sequence[RunEntry], title: str = "hwyeval report") -> str:
    """The whole HTML page as a string."""
    counts = {s: sum(1 for r in runs if r.status == s) for s in STATUSES}
    ordered = sorted(runs, key=lambda r: (STATUS_ORDER.get(r.status, 9), r.family, r.scenario,
                                          r.controller))
    catalogs = sorted({r.info.catalog for r in runs if r.info is not None and r.info.catalog})
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    count_html = " ".join(f'<span>{badge(s)} {counts[s]}</span>' for s in STATUSES)
    checks = "".join(f'<label><input type="checkbox" value="{s}" checked> {s}</label>'
                     for s in STATUSES)
    parts = [
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        '<link rel="icon" href="data:,">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<header><h1>{esc(title)}</h1><div class=\"counts\"><span><b>{len(runs)}</b> runs"
        f"</span>{count_html}<span>catalog: {esc(', '.join(catalogs) or '–')}</span>"
        f"<span>generated {esc(now)}</span></div></header><main>",
        '<nav><a href="#matrix">matrix</a> · <a href="#summary">summary</a> · '
        '<a href="#timing">timing</a> · <a href="#runs">runs</a></nav>',
        matrix_tables(runs),
        summary_tables(summary_frame(runs)),
        timing_section(runs),
        '<h2 id="runs">Runs</h2><div class="controls">'
        '<input type="search" id="filter" placeholder="filter scenario / controller / family">'
        f'{checks}<button type="button" id="expand">expand all</button>'
        '<button type="button" id="collapse">collapse all</button> '
        f'<span class="meta"><span id="shown">{len(runs)}</span> shown</span></div>',
        "".join(run_section(r) for r in ordered),
        f"</main><script>{JS}</script></body></html>",
    ]
    return "\n".join(parts)


def write_html(runs: Sequence[RunEntry], path: str | Path, title: str | None = None) -> Path:
    """Write report.html; returns its path."""
    path = Path(path)
    name = title or f"hwyeval report — {path.parent.name}"
    path.write_text(render_report(runs, name), encoding="utf-8")
    return path

