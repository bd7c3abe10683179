"""The failures list: what a reader of a nightly report looks at first.

One row per run that fails the night (errors and timeouts first, then failures by
severity): status, scenario (linked to its page's failures), variant, its worst failed
criterion (the largest relative excess, :func:`severity`) with its value against the
limit (units), when, and that excess — one criterion per row, so the excess beside a
criterion is its own (an off-road failure also names the boundary crossed and by how
much) — how many more failed, and the run's ``.rrd``. An error or timeout row carries
the exception's last line instead of a criterion; a strict known failure that passed
says "fixed: remove the xfail".

Known failures (``xfail``, :mod:`reports.expectation`) that failed as expected are not
in that list: they are in their own section under it (:func:`known_failures_section`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from reports.charts import esc, fmt
from reports.expectation import XPASSED
from reports.html.links import Links
from reports.record import Failure, MetricValue
from reports.tables import RunEntry

STATUS_ORDER = {"error": 0, "timeout": 1, "fail": 2, "pass": 3}


def badge(status: str) -> str:
    """Coloured status label."""
    return f'<span class="badge {esc(status)}">{esc(status)}</span>'


def log_link(run: RunEntry, links: Links, *, from_page: bool) -> str:
    """The run's Rerun log: a link when ``run.rrd`` is there; else a "no log" badge
    saying why (writing it failed: the exception's last line, the whole traceback in
    the hover text; or the run was made with ``--no-log``), never a dead link."""
    if run.has_log:
        return f'<a href="{esc(links.rrd_href(run.run_dir, from_page=from_page))}">run.rrd</a>'
    if run.log_error:
        return (f'<span class="badge nolog" title="{esc(run.log_error)}">log failed</span> '
                f'<span class="err1">{esc(last_line(run.log_error))}</span>')
    return '<span class="badge nolog">no log</span>'


def unit_text(unit: str) -> str:
    return "" if unit in ("", "-") else f" {unit.replace('^2', '²').replace('^3', '³')}"


def value_vs_limit(f: Failure) -> str:
    """``−5.31 m/s² < −4.05 m/s²`` (the failing comparison, with units)."""
    op = "&gt;" if f.bound == "max" else "&lt;"
    u = esc(unit_text(f.unit))
    return f"{fmt(f.value)}{u} {op} {fmt(f.limit)}{u}"


def failure_detail(f: Failure, metrics: Sequence[MetricValue]) -> str:
    """What the failed metric says about where it failed, '' if nothing: for an off-road
    failure the boundary crossed farthest and by how much (``right edge of lane a_0 by
    0.42 m at t = 12.30 s``; :class:`reports.record.verdict.BoundaryCrossing`)."""
    metric = next((m for m in metrics if m.name == f.metric), None)
    crossing = metric.crossing if metric is not None else None
    if crossing is None:
        return ""
    return f"{crossing.text} at t = {crossing.t_s:.2f} s"


def when(f: Failure) -> str:
    if f.t_s is None:
        return "whole run"
    return f"t = {f.t_s:.2f} s"


def last_line(text: str) -> str:
    lines = text.strip().splitlines()
    return lines[-1] if lines else ""


def severity(f: Failure) -> float:
    """How far a failure is beyond its limit, relative to the limit: |value - limit| /
    |limit|; inf for an infinite value or a limit of 0 (a count that must be zero: a
    collision is beyond any relative scale). What the failures list sorts by."""
    if not math.isfinite(f.value) or abs(f.limit) < 1e-12:
        return math.inf
    return abs(f.value - f.limit) / abs(f.limit)


def excess_text(f: Failure) -> str:
    """``36 %`` beyond a non-zero limit, ``+1`` beyond a limit of 0."""
    if abs(f.limit) < 1e-12 and math.isfinite(f.value):
        return f"+{fmt(abs(f.value - f.limit))}{unit_text(f.unit)}"
    x = severity(f)
    return "∞" if not math.isfinite(x) else f"{100 * x:.0f} %"


def _worst(r: RunEntry) -> Failure | None:
    if r.status != "fail" or not r.failures:
        return None
    return max(r.failures, key=severity)


def _run_severity(r: RunEntry) -> float:
    worst = _worst(r)
    return severity(worst) if worst is not None else 0.0


def _group(r: RunEntry) -> str:
    worst = _worst(r)
    if worst is not None:
        return worst.criterion
    return XPASSED if r.expectation == XPASSED else r.status


def triage_section(bad: Sequence[RunEntry]) -> str:
    """The failures grouped: per worst failed criterion (or error/timeout), the number
    of runs and of families, the worst relative excess, and per family the count; the
    largest groups first. A 300-run night's 90 failures read as a few groups."""
    groups: dict[str, list[RunEntry]] = {}
    for r in bad:
        key = _group(r)
        groups.setdefault(key, []).append(r)
    rows = []
    for key, members in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        families: dict[str, int] = {}
        for r in members:
            families[r.family] = families.get(r.family, 0) + 1
        worsts = [w for r in members if (w := _worst(r)) is not None]
        worst = max(worsts, key=severity) if worsts else None
        fam = ", ".join(f"{esc(name or '–')} ({n})" for name, n in
                        sorted(families.items(), key=lambda kv: (-kv[1], kv[0])))
        sort = _sort_value(severity(worst)) if worst is not None else "0"
        rows.append(f'<tr><td>{esc(key)}</td><td class="num">{len(members)}</td>'
                    f'<td class="num">{len(families)}</td>'
                    f'<td class="num" data-sort="{sort}">'
                    f"{esc(excess_text(worst)) if worst is not None else ''}</td>"
                    f"<td>{fam}</td></tr>")
    return ('<table class="triage sortable"><thead><tr><th>worst failed criterion</th>'
            "<th>runs</th><th>families</th><th>worst excess</th><th>families (runs)</th>"
            "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>")


def _failure_cells(r: RunEntry) -> str:
    """The row's criterion, value vs limit, when and how many more: of its worst failure
    (the one whose excess the row shows), or the error / the unexpected pass."""
    worst = _worst(r)
    if worst is not None:
        more = len(r.failures) - 1
        detail = failure_detail(worst, r.metrics)
        shown = f'<br><span class="meta">{esc(detail)}</span>' if detail else ""
        return (f"<td>{esc(worst.criterion)}</td><td class=\"num\">{value_vs_limit(worst)}"
                f"{shown}</td><td>{esc(when(worst))}</td><td>{f'+{more}' if more else ''}</td>")
    if r.expectation == XPASSED and r.xfail is not None:
        return (f'<td colspan="3">unexpected pass (strict xfail: {esc(r.xfail.reason)}): '
                "fixed: remove the xfail</td><td></td>")
    return (f'<td colspan="3" class="err1">{esc(last_line(r.error) or r.status)}</td>'
            f"<td>{f'+{len(r.failures)}' if r.failures else ''}</td>")


def failures_section(runs: Sequence[RunEntry], links: Links) -> str:
    """The index's failures list (module doc), the first section under the header:
    grouped by criterion and family (:func:`triage_section`), then one row per run,
    errors and timeouts first, then by severity (the worst relative excess first)."""
    bad = sorted((r for r in runs if r.fails_night),
                 key=lambda r: (STATUS_ORDER.get(r.status, 9), -_run_severity(r), r.scenario,
                                r.label))
    if not bad:
        expected = sum(1 for r in runs if r.expectation)
        tail = f" ({expected} known failures below)" if expected else ""
        return ('<section id="failures"><h2>Failures</h2><p class="allpass">every one of '
                f"the {len(runs)} runs passed or failed as expected{tail}</p></section>"
                if expected else '<section id="failures"><h2>Failures</h2><p class="allpass">'
                f"every one of the {len(runs)} runs passed</p></section>")
    rows = []
    for r in bad:
        page = links.page_href(r.run_id)
        shown = XPASSED if r.expectation == XPASSED else r.status
        head = (f"<td>{badge(shown)}</td><td><a href=\"{esc(page)}#failures\">"
                f"{esc(r.scenario)}</a></td><td>{esc(r.label)}</td>")
        w = _worst(r)
        rows.append(f'<tr class="{esc(r.status)}">{head}{_failure_cells(r)}'
                    f'<td class="num" data-sort="{_sort_value(_run_severity(r))}">'
                    f"{esc(excess_text(w)) if w is not None else ''}</td>"
                    f"<td>{log_link(r, links, from_page=False)}</td></tr>")
    triage = triage_section(bad) if len(bad) > 1 else ""
    return ('<section id="failures"><h2>Failures <span class="meta">'
            f"({len(bad)} of {len(runs)} runs fail the night)</span></h2>{triage}"
            '<table class="failures sortable"><thead><tr><th>status</th><th>scenario</th>'
            "<th>controller variant</th><th>worst failed criterion</th><th>value vs limit</th>"
            "<th>when</th><th>more</th><th>its excess</th><th>Rerun log</th></tr></thead>"
            "<tbody>" + "".join(rows) + "</tbody></table></section>")


def known_failures_section(runs: Sequence[RunEntry], links: Links) -> str:
    """The known failures (xfail) of the night, apart from the failures: each with its
    reason, whether strict, and what it did (failed as expected: its worst criterion; or
    passed: fixed, remove the xfail). '' when none is marked."""
    known = sorted((r for r in runs if r.xfail is not None), key=lambda r: r.scenario)
    if not known:
        return ""
    rows = []
    for r in known:
        mark = r.xfail
        w = _worst(r)
        did = ("passed: fixed, remove the xfail" if r.expectation == XPASSED else
               f"{w.criterion}: {value_vs_limit(w)}" if w is not None else
               esc(last_line(r.error) or r.status))
        rows.append(f'<tr><td>{badge(r.expectation or r.status)}</td><td><a href="'
                    f'{esc(links.page_href(r.run_id))}">{esc(r.scenario)}</a></td>'
                    f"<td>{esc(mark.reason if mark else '')}</td>"
                    f"<td>{'strict' if mark is not None and mark.strict else ''}</td>"
                    f"<td>{did}</td></tr>")
    return ('<section id="known-failures"><h2>Known failures (xfail) <span class="meta">('
            f"{len(known)})</span></h2><table class=\"failures\"><thead><tr><th>status</th>"
            "<th>scenario</th><th>reason</th><th></th><th>this night</th></tr></thead><tbody>"
            + "".join(rows) + "</tbody></table></section>")


def _sort_value(x: float) -> str:
    return repr(x) if math.isfinite(x) else "1e308"
