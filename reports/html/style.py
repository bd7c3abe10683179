"""The report's stylesheet (index inline; run pages share it as report.css)."""

from reports.charts import CHART_CSS

CSS = CHART_CSS + """
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
.badge.nolog{background:#718096}.badge.xfail{background:#9f7a77}
.badge.xpass{background:#2b7bb9}
section.notrun{background:#fffbeb;border:1px solid #f59e0b;border-radius:6px;padding:4px 14px}
details.run{background:#fff;border:1px solid #e2e8f0;border-radius:6px;margin:8px 0;
padding:6px 12px}
details.run>summary{cursor:pointer;padding:4px 0}
.why{color:#b91c1c;font-size:12px;margin-left:8px}.ctrl{color:#1d4ed8}.fam{color:#64748b}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(210px,1fr));gap:2px 12px;
margin:8px 0;font-size:12px}
.grid div{display:flex;justify-content:space-between;border-bottom:1px dotted #e2e8f0}
.grid div.bad{color:#b91c1c;font-weight:600}
.grid span{color:#475569}.grid div.bad span{color:#b91c1c}
.cdfs{display:flex;flex-wrap:wrap;gap:8px}
pre.err{background:#1e1b4b;color:#e0e7ff;padding:8px;overflow:auto;max-height:260px;
font-size:12px}
.nodata{color:#94a3b8;font-style:italic;margin:4px 0}.meta{color:#475569;font-size:12px}
.controls{margin:10px 0}.controls input[type=search]{padding:3px 6px;width:240px}
.controls label{margin-left:10px}.controls button{margin-left:8px}
code{font-size:12px}
section#failures{margin-top:6px}
table.failures td{text-align:left}table.failures td.num{text-align:right;
font-variant-numeric:tabular-nums;white-space:nowrap}
table.failures tr.fail td{background:#fef2f2}table.failures tr.error td,
table.failures tr.timeout td{background:#f5f3ff}
td.err1{font-family:ui-monospace,monospace;font-size:12px;color:#4c1d95}
p.allpass{color:#15803d;font-weight:600}
header nav{margin-top:4px;font-size:13px}header nav a{color:#bfdbfe}
table.runs td{font-variant-numeric:tabular-nums}table.runs td.bad,td.bad{color:#b91c1c;
font-weight:600}
table.metrics td{text-align:right;font-variant-numeric:tabular-nums}
table.metrics td.name{text-align:left}table.metrics tr.bad td{color:#b91c1c;font-weight:600}
.kindrow th{background:#e2e8f0;text-align:left}
"""
