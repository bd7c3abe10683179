"""A comparison for people and machines: terminal lines, JSON, compare.csv, compare.html.

Terminal: a header (both sides with their revision, host and load), the verdict, the
regressions as ``run  metric  base → new unit``, warnings (timing per metric as the
catalog's median ratio with its range, then the slowest runs), provenance
differences, the metrics stored on one side only ("not in base": a metric added since;
never a regression), fixed and missing runs. ``--json`` prints :func:`as_json` instead.
"""

from __future__ import annotations

import csv
import datetime as _dt
import html
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from reports.charts import CHART_CSS
from reports.compare.findings import GOOD_KINDS, NOT_IN_BASE, NOT_IN_NEW, CompareRow
from reports.compare.kinds import GATING_CATEGORIES
from reports.compare.overlay import overlays_html
from reports.manifest import Manifest
from reports.record.codec import to_plain, write_text_atomic
from reports.tables import RunEntry, find_entry

if TYPE_CHECKING:
    from reports.compare import CompareResult

MAX_LISTED = 12  # rows of one kind listed in the terminal before "... and N more"


def num(value: float, unit: str = "") -> str:
    """4 significant digits with the unit ('–' for NaN, ∞ spelled)."""
    if math.isnan(value):
        return "–"
    if math.isinf(value):
        text = "∞" if value > 0 else "−∞"
    else:
        text = f"{value:.4g}"
    return f"{text} {unit}" if unit and unit not in ("-", "0/1") else text


def _side(label: str, path: Path, manifest: Manifest | None) -> str:
    if manifest is None:
        return f"{label} {path} (no manifest.json: provenance unknown)"
    p = manifest.provenance
    load = f", load {p.load:.2f}/core" if math.isfinite(p.load) else ""
    return (f"{label} {path} ({manifest.catalog_name}, {p.short_sha}, hwyeval "
            f"{p.hwyeval_version or '?'}, {p.host or '?'}{load}, {manifest.started})")


def row_line(row: CompareRow) -> str:
    """``kind  run  metric base → new unit (note)``."""
    if row.metric and not (math.isnan(row.base) and math.isnan(row.new)):
        change = f"{row.metric} {num(row.base, row.unit)} → {num(row.new, row.unit)}"
        if math.isfinite(row.ratio):
            change += f" (×{row.ratio:.2f})"
        elif row.note:
            change += f" ({row.note})"
        return f"{row.kind:<17} {row.key}: {change}"
    return f"{row.kind:<17} {row.key}: {row.note}"


# The labelled categories, each with its heading (which says whether it gates).
CHANGED_TESTS = (
    ("known_failure", "known failures (xfail; an unexpected pass gates when strict)"),
    ("sut_changed", "system under test changed (controller, options or code; its runs "
                    "are compared and gate)"),
    ("limits_changed", "limits changed: each value judged under both limits (the change "
                       "does not gate; behaviour under the old limits does)"),
    ("waived", "waived: a criterion switched off — a limit change, not a fix (does not "
               "gate)"),
    ("test_changed", "test changed: not comparable run for run (does not gate)"))


UNREADABLE_BASE = "base run directories that cannot be read (reported; do not gate)"


def _listed(rows: Sequence[CompareRow], indent: str = "  ") -> list[str]:
    lines = [indent + row_line(r) for r in rows[:MAX_LISTED]]
    if len(rows) > MAX_LISTED:
        lines.append(f"{indent}... and {len(rows) - MAX_LISTED} more (compare.csv)")
    return lines


def _timing_block(result: CompareResult) -> list[str]:
    if not result.timing and not result.of_kind("timing_slower"):
        return []
    gate = "fails with --timing-gate" if not result.timing_gate else "gated: --timing-gate"
    lines = [f"timing (wall clock; warns, {gate}):"]
    if result.load:
        lines.append(f"  note: {result.load}: machine noise likely")
    for t in result.timing:
        mark = "SLOWER" if t.slower else "ok    "
        lines.append(f"  {mark} {t.metric:<16} median ×{t.median_ratio:.2f} over {t.runs} "
                     f"run(s) (×{t.min_ratio:.2f} … ×{t.max_ratio:.2f}; {t.over_limit} beyond "
                     f"×{t.limit:g})")
    counts = [r for r in result.of_kind("timing_slower") if not math.isfinite(r.ratio)]
    slow = sorted((r for r in result.of_kind("timing_slower") if math.isfinite(r.ratio)),
                  key=lambda r: -r.ratio)
    lines += _listed(counts)
    if slow:
        lines.append(f"  slowest runs ({len(slow)} timing finding(s)):")
        lines += _listed(slow[:5], "    ")
    return lines


def _unpaired_block(result: CompareResult) -> list[str]:
    """One line for the metrics stored on one side only (a metric added to the catalogue
    since base ran is "not in base"): per metric, the runs; never a regression."""
    runs: dict[tuple[str, str], int] = {}
    for r in result.of_kind(NOT_IN_BASE, NOT_IN_NEW):
        side = "not in base" if r.kind == NOT_IN_BASE else "not in new"
        runs[(r.metric, side)] = runs.get((r.metric, side), 0) + 1
    if not runs:
        return []
    listed = ", ".join(f"{metric} {side} ({n} run(s))"
                       for (metric, side), n in sorted(runs.items()))
    return [f"metrics on one side only (not compared, do not gate): {listed}"]


def _verdict(result: CompareResult) -> str:
    """The terminal's last line: why the comparison fails, or that it does not."""
    if result.timing_failures:
        return "FAIL: timing slower than allowed (--timing-gate)"
    if result.regressions and all(r.kind == "xpass" for r in result.regressions):
        return "FAIL: a strict known failure passed (remove its xfail)"
    if result.regressions and all(r.kind == "unreadable" for r in result.regressions):
        return "FAIL: run directories of new cannot be read"
    if result.regressions:
        return "FAIL: behaviour regressed"
    return "OK: no behaviour regression" + (
        f" ({len(result.warnings)} warning(s) do not gate)" if result.warnings else "")


def summary_text(result: CompareResult) -> str:
    """The terminal report (module doc)."""
    lines = [_side("base", result.base_dir, result.base_manifest),
             _side("new ", result.new_dir, result.new_manifest),
             f"matched {result.matched} run(s): {len(result.regressions)} regression(s), "
             f"{len(result.warnings)} warning(s), {len(result.fixed)} fixed, "
             f"{len(result.missing)} missing, {len(result.added)} new"]
    if result.provenance_differences:
        lines.append("provenance differs (behaviour should not; timing may):")
        lines += [f"  {d.field}: {d.base} → {d.new}" for d in result.provenance_differences]
    if result.regressions:
        lines.append(f"REGRESSIONS ({len(result.regressions)}):")
        lines += _listed(result.regressions)
    for category, title in CHANGED_TESTS:
        rows = result.of_category(category)
        if rows:
            lines.append(f"{title} ({len(rows)}):")
            lines += _listed(rows)
    unreadable_base = [r for r in result.of_category("unreadable") if not r.gate]
    if unreadable_base:
        lines.append(f"{UNREADABLE_BASE} ({len(unreadable_base)}):")
        lines += _listed(unreadable_base)
    lines += _timing_block(result)
    health = result.of_kind("health_change")
    if health:
        lines.append(f"health (warns, {len(health)}):")
        lines += _listed(health)
    lines += _unpaired_block(result)
    if result.fixed:
        lines.append(f"fixed ({len(result.fixed)}):")
        lines += _listed(result.fixed_rows)
    if result.added:
        lines.append(f"new runs ({len(result.added)}): " + ", ".join(result.added[:MAX_LISTED]))
    lines.append(f"{_verdict(result)} (exit {result.exit_code})")
    if result.csv_path is not None:
        lines.append(f"details: {result.csv_path}  {result.html_path}")
    return "\n".join(lines)


def as_json(result: CompareResult) -> str:
    """Everything of the comparison as one JSON document (numbers NaN/Infinity allowed)."""
    doc: dict[str, Any] = {
        "exit_code": result.exit_code, "matched": result.matched,
        "base_dir": str(result.base_dir), "new_dir": str(result.new_dir),
        "timing_gate": result.timing_gate,
        "gating_kinds": list(GATING_CATEGORIES),
        "counts": result.category_counts,
        "regressions": [_row_plain(r) for r in result.regressions],
        "warnings": [_row_plain(r) for r in result.warnings],
        "timing": to_plain(result.timing),
        "load_note": result.load,
        "provenance_differences": to_plain(result.provenance_differences),
        "base_manifest": to_plain(result.base_manifest),
        "new_manifest": to_plain(result.new_manifest),
        "rows": [_row_plain(r) for r in result.rows],
    }
    return json.dumps(doc, indent=1, allow_nan=True)


def _row_plain(row: CompareRow) -> dict[str, Any]:
    """A finding for JSON: ``kind`` is its category (why it differs:
    :data:`reports.compare.kinds.CATEGORIES`), ``finding`` what was found (new_failure,
    metric_regression, ...)."""
    plain: dict[str, Any] = to_plain(row)
    plain["finding"] = plain.pop("kind")
    plain["kind"] = plain.pop("category")
    plain["regression"] = row.regression
    plain["warning"] = row.warning
    return plain


CSV_COLUMNS = ("key", "scenario", "controller", "category", "kind", "regression", "warning",
               "metric", "unit", "metric_kind", "base", "new", "delta", "ratio", "limit",
               "base_limit", "note")


def _csv_num(value: float) -> str:
    if math.isnan(value):
        return ""
    return repr(float(value)) if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def write_compare_csv(result: CompareResult, path: Path) -> Path:
    """compare.csv: one row per finding (columns :data:`CSV_COLUMNS`), written
    atomically."""
    fh = io.StringIO(newline="")
    writer = csv.writer(fh)
    writer.writerow(CSV_COLUMNS)
    for r in result.rows:
        writer.writerow([r.key, r.scenario, r.controller, r.category, r.kind, int(r.regression),
                         int(r.warning), r.metric, r.unit, r.metric_kind, _csv_num(r.base),
                         _csv_num(r.new), _csv_num(r.delta), _csv_num(r.ratio),
                         _csv_num(r.limit), _csv_num(r.base_limit), r.note])
    write_text_atomic(path, fh.getvalue())
    return path


_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;
background:#f1f5f9;color:#0f172a}
header{padding:14px 24px;color:#fff}header.bad{background:#b91c1c}header.ok{background:#15803d}
header h1{margin:0 0 4px;font-size:19px}main{padding:8px 24px 40px;max-width:1400px}
table{border-collapse:collapse;background:#fff;margin:6px 0 14px}
th,td{border:1px solid #e2e8f0;padding:3px 8px;font-size:13px;text-align:left}
th{background:#f8fafc}td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.reg td{background:#fef2f2}tr.warn td{background:#fffbeb}tr.good td{background:#f0fdf4}
h2{font-size:16px;margin:22px 0 6px}.none{color:#94a3b8;font-style:italic}
.overlay{background:#fff;display:inline-block;margin:4px 8px 4px 0}
""" + CHART_CSS


RunLinks = dict[str, tuple[str, str]]  # finding key -> (base page href, new page href)


def run_links(result: CompareResult, page: Path, base: Sequence[RunEntry],
              new: Sequence[RunEntry]) -> RunLinks:
    """For each finding's key, the hrefs (relative to ``page``) of the run's page in the
    base and the new report ('' where that page does not exist)."""
    import os

    def href(side_dir: Path, runs: Sequence[RunEntry], scenario: str, controller: str) -> str:
        r = find_entry(runs, scenario, controller)
        if r is None:
            return ""
        target = side_dir / "report-runs" / f"{r.run_id}.html"
        return os.path.relpath(target.absolute(), page.parent.absolute()) \
            if target.is_file() else ""

    return {row.key: (href(result.base_dir, base, row.scenario, row.controller),
                      href(result.new_dir, new, row.scenario, row.controller))
            for row in result.rows}


def _run_cell(row: CompareRow, links: RunLinks | None) -> str:
    esc = html.escape
    b, n = (links or {}).get(row.key, ("", ""))
    parts = [f'<a href="{esc(h)}">{label}</a>' for h, label in ((b, "base"), (n, "new")) if h]
    return esc(row.key) + (f" <small>({' · '.join(parts)})</small>" if parts else "")


def _table(rows: Sequence[CompareRow], title: str, links: RunLinks | None = None) -> str:
    esc = html.escape
    if not rows:
        return f"<h2>{esc(title)}</h2><p class=\"none\">none</p>"
    head = ("<tr><th>run</th><th>category</th><th>finding</th><th>metric</th><th>base</th>"
            "<th>new</th><th>Δ</th><th>ratio new/base</th><th>limit</th><th>note</th></tr>")
    body = []
    for r in rows:
        cls = "reg" if r.regression else "warn" if r.warning else (
            "good" if r.kind in GOOD_KINDS else "")
        ratio = f"×{r.ratio:.3g}" if math.isfinite(r.ratio) else "–"
        limit_unit = "" if math.isfinite(r.ratio) else r.unit
        limit = num(r.limit, limit_unit)
        if r.kind in ("limit_changed", "criterion_off"):  # both limits, off spelt out
            limit = (f"{num(r.base_limit, limit_unit) if math.isfinite(r.base_limit) else 'off'}"
                     f" → {limit if math.isfinite(r.limit) else 'off'}")
        body.append(f'<tr class="{cls}"><td>{_run_cell(r, links)}</td>'
                    f"<td>{esc(r.category)}</td><td>{esc(r.kind)}</td>"
                    f"<td>{esc(r.metric)}</td><td class=\"num\">{esc(num(r.base, r.unit))}</td>"
                    f"<td class=\"num\">{esc(num(r.new, r.unit))}</td>"
                    f"<td class=\"num\">{esc(num(r.delta, r.unit))}</td>"
                    f"<td class=\"num\">{ratio}</td>"
                    f"<td class=\"num\">{esc(limit)}</td>"
                    f"<td>{esc(r.note)}</td></tr>")
    return f"<h2>{esc(title)} ({len(rows)})</h2><table>{head}{''.join(body)}</table>"


def _timing_table(result: CompareResult) -> str:
    esc = html.escape
    if not result.timing:
        return ""
    rows = "".join(
        f"<tr class=\"{'warn' if t.slower else ''}\"><td>{esc(t.metric)} [{esc(t.unit)}]</td>"
        f"<td class=\"num\">×{t.median_ratio:.3g}</td><td class=\"num\">×{t.min_ratio:.3g} … "
        f"×{t.max_ratio:.3g}</td><td class=\"num\">{t.over_limit} / {t.runs}</td>"
        f"<td class=\"num\">×{t.limit:g}</td></tr>" for t in result.timing)
    note = f"<p>{esc(result.load)}: machine noise likely</p>" if result.load else ""
    return ("<h2>Timing, catalog-wide (ratio new/base; &gt; 1 is slower)</h2>" + note +
            "<table><tr><th>metric</th><th>median ratio</th><th>range</th>"
            f"<th>runs beyond limit</th><th>limit</th></tr>{rows}</table>")


def _status_counts(runs: Sequence[RunEntry]) -> dict[str, dict[str, int]]:
    out: dict[str, dict[str, int]] = {}
    for r in runs:
        out.setdefault(r.controller, {}).setdefault(r.status, 0)
        out[r.controller][r.status] += 1
    return out


def _controller_code_rows(result: CompareResult) -> list[str]:
    """One row per controller the manifests name: its code hash on each side (the
    system under test's code; '–' where a side did not run it)."""
    esc = html.escape
    codes = [{c.name: c.sha256 for c in m.controllers} if m is not None else {}
             for m in (result.base_manifest, result.new_manifest)]
    rows = []
    for name in sorted(set(codes[0]) | set(codes[1])):
        b, n = (c.get(name, "") for c in codes)
        cls = "warn" if b and n and b != n else ""
        rows.append(f'<tr class="{cls}"><td>controller {esc(name)} code</td>'
                    f"<td><code>{esc(b[:10] or '–')}</code></td>"
                    f"<td><code>{esc(n[:10] or '–')}</code></td></tr>")
    return rows


def _provenance_table(result: CompareResult) -> str:
    esc = html.escape
    sides = [(m.provenance if m is not None else None) for m in (result.base_manifest,
                                                                  result.new_manifest)]
    if sides[0] is None and sides[1] is None:
        return "<h2>Provenance</h2><p class=\"none\">no manifest.json on either side</p>"
    changed = {d.field for d in result.provenance_differences}
    fields = ("short_sha", "hwyeval_version", "sumo_version", "numba_version", "rerun_version",
              "python_version", "host", "cpu_model", "cpu_count", "load_start", "load_end",
              "plugins")
    rows = []
    for name in fields:
        cells = [esc(str(getattr(p, name))) if p is not None else "–" for p in sides]
        bad = name in changed or (name == "short_sha" and "git_sha" in changed)
        rows.append(f"<tr class=\"{'warn' if bad else ''}\"><td>{esc(name)}</td>"
                    f"<td>{cells[0]}</td><td>{cells[1]}</td></tr>")
    rows += _controller_code_rows(result)
    return ("<h2>Provenance</h2><table><tr><th></th><th>base</th><th>new</th></tr>"
            + "".join(rows) + "</table>")


def write_compare_html(result: CompareResult, path: Path, base: Sequence[RunEntry] = (),
                       new: Sequence[RunEntry] = ()) -> Path:
    """compare.html: one self-contained page (inline CSS, no scripts, no network)."""
    esc = html.escape
    bad = result.exit_code != 0
    verdict = (f"REGRESSION: {len(result.regressions) + len(result.timing_failures)} "
               "finding(s)" if bad else "no regression")
    counts_b, counts_n = _status_counts(base), _status_counts(new)
    ctrl_rows = []
    for ctrl in sorted(set(counts_b) | set(counts_n)):
        cells = [" / ".join(f"{c.get(s, 0)} {s}" for s in ("pass", "fail", "error", "timeout"))
                 for c in (counts_b.get(ctrl, {}), counts_n.get(ctrl, {}))]
        ctrl_rows.append(f"<tr><td>{esc(ctrl)}</td><td>{esc(cells[0])}</td>"
                         f"<td>{esc(cells[1])}</td></tr>")
    now = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    links = run_links(result, path, base, new)
    unreadable_base = [r for r in result.of_category("unreadable") if not r.gate]
    parts = [
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        '<link rel="icon" href="data:,">'
        f"<title>hwyeval compare</title><style>{_CSS}</style></head><body>",
        f'<header class="{"bad" if bad else "ok"}"><h1>hwyeval compare — {esc(verdict)}</h1>'
        f"<div>base <code>{esc(str(result.base_dir))}</code> · new "
        f"<code>{esc(str(result.new_dir))}</code> · {result.matched} matched · "
        f"{len(result.new_failures)} new failures · {len(result.fixed)} fixed · "
        f"{len(result.missing)} missing · {len(result.added)} new · "
        f"{len(result.warnings)} warnings · generated {esc(now)}</div></header><main>",
        _table(result.regressions, "Regressions (behaviour; gate)", links),
        overlays_html([*result.regressions,
                       *(r for c, _ in CHANGED_TESTS for r in result.of_category(c))],
                      base, new),
        *(_table(result.of_category(c), f"{t} (do not gate)", links) for c, t in CHANGED_TESTS),
        _table(unreadable_base, UNREADABLE_BASE, links) if unreadable_base else "",
        _timing_table(result),
        _table(result.warnings, "Warnings (timing, health)", links),
        _provenance_table(result),
        "<h2>Status per controller</h2><table><tr><th>controller</th><th>base</th><th>new</th>"
        f"</tr>{''.join(ctrl_rows)}</table>",
        _table(result.fixed_rows, "Fixed", links),
        _table(result.of_kind("missing", "new"), "Missing / new runs", links),
        _table(result.of_kind("status_change", "metric_nan"), "Other status / metric changes",
               links),
        _table(result.of_kind("metric_improvement", "timing_faster"), "Improvements", links),
        "</main></body></html>",
    ]
    write_text_atomic(path, "\n".join(parts))
    return path
