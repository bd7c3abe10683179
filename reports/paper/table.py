"""The results as text: the Markdown tables the README shows (printed by ``hwyeval paper``
in exactly that form), ``paper.csv`` (one row per quantity) and ``paper.json``
(everything: rows, findings, every result, where the runs were timed)."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from dataclasses import dataclass

from reports.paper.findings import Finding, NumberRow
from reports.paper.results import Analysed
from reports.paper.runs import Machine
from reports.record.codec import to_plain

TIMING_MARK = "†"
TIMING_NOTE = (f"{TIMING_MARK} wall-clock time on the machine that ran the catalog (or a finding "
               "judged on it): it changes from run to run and with the machine's load; "
               "compare the ratios, measured within one run.")
BEGIN = "<!-- paper-results:begin -->"
END = "<!-- paper-results:end -->"


@dataclass(frozen=True)
class PaperReport:
    """Everything ``hwyeval paper`` found in one output directory: ``source`` (the
    directory), ``machine`` (where it ran), ``results`` (per experiment, with curves),
    ``findings``, ``rows`` (the numbers table) and the runs it could not read."""

    source: str
    machine: Machine
    results: Analysed
    findings: tuple[Finding, ...]
    rows: tuple[NumberRow, ...]
    unreadable: tuple[tuple[str, str], ...] = ()


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def numbers_markdown(rows: Sequence[NumberRow]) -> list[str]:
    """The numbers as a Markdown table, timing rows marked with :data:`TIMING_MARK`."""
    out = ["| fig. | quantity | unit | ours | paper |", "|---|---|---|---|---|"]
    for r in rows:
        mark = f" {TIMING_MARK}" if r.timing else ""
        out.append(f"| {r.figure} | {_cell(r.quantity)}{mark} | {r.unit} | {r.ours} | "
                   f"{_cell(r.paper)} |")
    return out


def findings_markdown(items: Sequence[Finding]) -> list[str]:
    """The findings as a Markdown table: the claim and whether it holds; the reason
    beside a finding that does not."""
    out = ["| fig. | the paper's finding | in our runs |", "|---|---|---|"]
    for f in items:
        fig = f.figure.removeprefix("Fig. ")
        verdict = f.verdict if f.holds is not False else f"**does not hold**: {f.why}"
        mark = f" {TIMING_MARK}" if f.timing else ""
        out.append(f"| {fig} | {_cell(f.claim)}{mark} | {_cell(verdict)} |")
    return out


def results_markdown(report: PaperReport) -> str:
    """The README's Results block (between its markers), as ``hwyeval paper`` prints it."""
    lines = [BEGIN, *numbers_markdown(report.rows), "", TIMING_NOTE, "",
             *findings_markdown(report.findings), END]
    return "\n".join(lines)


def rows_csv(rows: Sequence[NumberRow]) -> str:
    """``paper.csv``: key, figure, quantity, unit, ours (as shown), values (full
    precision, ';'-separated), paper, timing."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["key", "figure", "quantity", "unit", "ours", "values", "paper", "timing"])
    for r in rows:
        w.writerow([r.key, r.figure, r.quantity, r.unit, r.ours,
                    ";".join(repr(float(v)) for v in r.values), r.paper, int(r.timing)])
    return buf.getvalue()


def report_json(report: PaperReport) -> str:
    """``paper.json``: the rows (with the text shown), the findings (with their
    verdict), every experiment's results (numbers only, no curves) and the machine."""
    a = report.results
    doc = {
        "source": report.source, "machine": to_plain(report.machine),
        "rows": [{**to_plain(r), "ours": r.ours} for r in report.rows],
        "findings": [{**to_plain(f), "verdict": f.verdict} for f in report.findings],
        "results": {"costs": [to_plain(r) for r, _ in a.costs],
                    "preview": [to_plain(r) for r, _ in a.preview],
                    "solvers": [to_plain(r) for r, _ in a.solvers],
                    "course": [to_plain(r) for r, _ in a.course]},
        "unreadable": [list(u) for u in report.unreadable],
    }
    return json.dumps(doc, indent=1, allow_nan=True)
