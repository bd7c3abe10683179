"""``r157.html``: an R157 pack's runs grouped by Annex 5 section, the reference driver's
outcome beside the system's for every concrete scenario, and the acceptance logic's
verdict (:mod:`reports.r157.outcome`).

One self-contained page (the report's stylesheet, no script, nothing from the network):
the speed scope first (the templates cap the ego at 60 km/h), then per controller a
summary table by section, then one table per section with a row per scenario.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from collections.abc import Sequence
from pathlib import Path

from reports.charts import esc
from reports.html.style import CSS
from reports.r157.outcome import (
    SECTION_TITLES,
    PackRow,
    RunOutcome,
    SectionSummary,
)

__all__ = ["CAP_KMH", "render_page", "speed_scope"]

CAP_KMH = 60.0  # the templates' (and the regulation's original) ego speed limit
PAGE_CSS = """
td.l{text-align:left}.badge a{color:#fff}tr.met td.v{color:var(--pass);font-weight:600}
tr.notmet td.v{color:var(--fail);font-weight:600}p.note{max-width:900px;color:#334155}
section.scope{background:#fff;border:1px solid #e2e8f0;border-radius:6px;padding:4px 14px}
"""


def speed_scope(rows: Sequence[PackRow]) -> str:
    """One sentence on the ego speeds of the runs against the templates' 60 km/h cap."""
    speeds = [r.ego_speed_kmh for r in rows if math.isfinite(r.ego_speed_kmh)]
    if not speeds:
        return "No run records the ego's set speed."
    lo, hi = min(speeds), max(speeds)
    span = f"{lo:.0f} km/h" if hi - lo < 0.5 else f"{lo:.0f} to {hi:.0f} km/h"
    if hi <= CAP_KMH + 0.5:  # 16.666667 m/s is 60.000001 km/h
        return (f"The ego's set speeds here: {span}. The templates cap the ego at "
                f"{CAP_KMH:.0f} km/h, the regulation's original scope (its 01 series of "
                "amendments allows up to 130 km/h). To run the pack at motorway speeds, "
                "import it again with --param Ego_InitSpeed_Ve0_kph=130 "
                "--ignore-constraints (docs/r157.md).")
    return (f"The ego's set speeds here: {span}, beyond the templates' {CAP_KMH:.0f} km/h "
            "cap (imported with the cap lifted): the templates' other values (gaps, "
            "trigger distances, speeds relative to the ego) are as declared, so some "
            "scenarios are harsher than the regulation's.")


def _outcome_cells(o: RunOutcome | None, base: Path, run_root: Path | None) -> str:
    if o is None:
        return '<td class="empty" colspan="4">not run</td>'
    link = esc(o.status)
    if run_root is not None:
        href = os.path.relpath(run_root / o.run, base)
        link = f'<a href="{esc(href)}/">{esc(o.status)}</a>'
    ttc = "–" if not math.isfinite(o.min_ttc_s) else f"{o.min_ttc_s:.2f}"
    dv = "" if not (o.at_fault_collisions and math.isfinite(o.at_fault_delta_v_mps)) \
        else f" (Δv {o.at_fault_delta_v_mps:.1f} m/s)"
    why = f' title="failed: {esc(", ".join(o.failed))}"' if o.failed else ""
    return (f'<td><span class="badge {esc(o.status)}"{why}>{link}</span></td>'
            f"<td>{o.collisions}</td><td>{o.at_fault_collisions}{dv}</td><td>{ttc}</td>")


def _section_table(section: str, rows: Sequence[PackRow], base: Path,
                   system_root: Path, reference_root: Path | None) -> str:
    title = SECTION_TITLES.get(section, "")
    head = ("<tr><th rowspan=2>scenario</th><th rowspan=2>ego km/h</th>"
            "<th colspan=4>system under test</th><th colspan=4>reference driver</th>"
            "<th rowspan=2>acceptance</th></tr><tr>"
            + "<th>status</th><th>contacts</th><th>caused</th><th>min TTC s</th>" * 2
            + "</tr>")
    body = []
    for r in rows:
        acc = r.acceptance
        verdict = "met" if acc.met else "not met: " + "; ".join(acc.reasons)
        if acc.met and acc.unpreventable:
            verdict += " (the reference driver collides too)"
        body.append(
            f'<tr class="{"met" if acc.met else "notmet"}"><td class="l">{esc(r.scenario)}'
            f"</td><td>{r.ego_speed_kmh:.0f}</td>"
            + _outcome_cells(r.system, base, system_root)
            + _outcome_cells(r.reference, base, reference_root)
            + f'<td class="l v">{esc(verdict)}</td></tr>')
    name = f"§{section} {title}" if section else "no section"
    return (f'<h3 id="s{esc(section)}">{esc(name)}</h3><table><thead>{head}</thead>'
            f"<tbody>{''.join(body)}</tbody></table>")


def _summary_table(summaries: Sequence[SectionSummary]) -> str:
    head = ("<tr><th>section</th><th>scenarios</th><th>acceptance met</th><th>pass</th>"
            "<th>contacts</th><th>caused</th><th>contacts the reference avoids</th>"
            "<th>reference: pass</th><th>reference: contacts</th></tr>")
    body = []
    for s in summaries:
        ref = (f"<td>{s.reference_passed}/{s.with_reference}</td>"
               f"<td>{s.reference_collided}</td>") if s.with_reference else \
            '<td class="empty" colspan="2">not run</td>'
        label = "all" if s.section == "all" else \
            f"§{s.section} {SECTION_TITLES.get(s.section, '')}"
        body.append(f'<tr class="{"all" if s.section == "all" else ""}"><td class="l">'
                    f"{esc(label)}</td><td>{s.scenarios}</td><td>{s.met}</td>"
                    f"<td>{s.passed}</td><td>{s.collided}</td><td>{s.at_fault}</td>"
                    f"<td>{s.preventable}</td>{ref}</tr>")
    return f"<table><thead>{head}</thead><tbody>{''.join(body)}</tbody></table>"


def render_page(rows: Sequence[PackRow], summaries: Sequence[SectionSummary], base: Path,
                system_root: Path, reference_root: Path | None) -> str:
    """The page's HTML; ``base`` is the folder it is written to (links are relative to
    it), ``system_root``/``reference_root`` the folders holding the runs."""
    parts = [f'<section class="scope"><p class="note">{esc(speed_scope(rows))}</p>'
             '<p class="note">Acceptance (UN R157 Annex 5): no collision caused by the '
             "system, the minimum following time gap kept (when the pack was imported "
             "with --r157), and no collision where the regulation's reference driver "
             "(r157_reference) avoids one on the same test.</p></section>"]
    for controller in sorted({r.controller for r in rows}):
        mine = [r for r in rows if r.controller == controller]
        parts.append(f"<h2>{esc(controller)}</h2>")
        parts.append(_summary_table([s for s in summaries if s.controller == controller]))
        for section in sorted({r.section for r in mine}):
            parts.append(_section_table(section, [r for r in mine if r.section == section],
                                        base, system_root, reference_root))
    met = sum(r.acceptance.met for r in rows)
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>UN R157 "
            f"pack</title><style>{CSS}{PAGE_CSS}</style></head><body><header><h1>UN R157 "
            f"(ALKS) pack: acceptance met in {met} of {len(rows)} runs</h1><div>{stamp}"
            f"</div></header><main>{''.join(parts)}</main></body></html>")
