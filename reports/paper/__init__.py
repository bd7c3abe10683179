"""The paper's simulation results redrawn from our runs (``hwyeval paper DIR``).

From the runs of catalogs/paper.toml in an output directory: E(t) and the steering for
J1/J2/J3 (Figs. 9-10), the plan-car lateral error and the lateral acceleration with
and without the preview (Figs. 12-13), the time per step of C/GMRES and Ipopt (Figs.
14-15) and several obstacles along a curve (the experiments), each with the numbers
that summarise it, the paper's value beside ours and whether its finding holds
(docs/paper.md).

Stages: :mod:`~reports.paper.runs` (which run is which), :mod:`~reports.paper.measures`
(the formulas), :mod:`~reports.paper.results` (per run), :mod:`~reports.paper.findings`
(the findings and the numbers table), :mod:`~reports.paper.table` (Markdown, CSV,
JSON), :mod:`~reports.paper.page` (HTML).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from reports.paper.findings import Finding, NumberRow, findings, number_rows
from reports.paper.page import render_page
from reports.paper.results import analyse
from reports.paper.runs import PaperError, PaperRuns, find_paper_runs
from reports.paper.table import BEGIN, END, PaperReport, report_json, results_markdown, rows_csv

PAGE = "paper.html"
NUMBERS_JSON = "paper.json"
NUMBERS_CSV = "paper.csv"


@dataclass(frozen=True)
class PaperPaths:
    """What :func:`write_paper` wrote."""

    page: Path
    json: Path
    csv: Path


def build_paper(out_dir: str | Path) -> tuple[PaperReport, PaperRuns]:
    """Read the paper's runs of ``out_dir`` and reduce them (PaperError when it holds
    none); the runs are returned too (the page draws the course's bird's-eye view)."""
    runs = find_paper_runs(Path(out_dir))
    analysed = analyse(runs.costs, runs.preview, runs.solvers, runs.obstacles)
    report = PaperReport(source=str(out_dir), machine=runs.machine, results=analysed,
                         findings=tuple(findings(analysed)), rows=tuple(number_rows(analysed)),
                         unreadable=runs.unreadable)
    return report, runs


def write_paper(out_dir: str | Path, dest: str | Path | None = None
                ) -> tuple[PaperReport, PaperPaths]:
    """:func:`build_paper`, then ``paper.html``, ``paper.json`` and ``paper.csv`` into
    ``dest`` (default: ``out_dir``)."""
    report, runs = build_paper(out_dir)
    target = Path(dest) if dest is not None else Path(out_dir)
    target.mkdir(parents=True, exist_ok=True)
    paths = PaperPaths(target / PAGE, target / NUMBERS_JSON, target / NUMBERS_CSV)
    paths.page.write_text(render_page(report, runs.obstacles), encoding="utf-8")
    paths.json.write_text(report_json(report), encoding="utf-8")
    paths.csv.write_text(rows_csv(report.rows), encoding="utf-8")
    return report, paths


__all__ = ["BEGIN", "END", "Finding", "NumberRow", "PaperError", "PaperPaths", "PaperReport",
           "build_paper", "results_markdown", "write_paper"]
