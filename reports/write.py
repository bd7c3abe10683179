"""``write_reports``: the four report files of a catalog output directory."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from reports.html import write_html
from reports.junit import write_junit
from reports.tables import EVERYTHING, collect_runs, write_results_csv, write_summary_csv


@dataclass(frozen=True)
class ReportPaths:
    """Files written by :func:`write_reports`."""

    results_csv: Path
    summary_csv: Path
    junit_xml: Path
    report_html: Path


def write_reports(out_dir: str | Path, dest_dir: str | Path | None = None) -> ReportPaths:
    """Write results.csv, summary.csv, junit.xml and report.html for every run directory
    under ``out_dir`` into ``dest_dir`` (default ``out_dir``), from the stored verdicts
    and series (nothing is re-evaluated). Raises FileNotFoundError if ``out_dir`` is not
    a directory; an unreadable run directory is an 'error' row."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"{out_dir}: not a directory")
    dest = Path(dest_dir) if dest_dir is not None else out_dir
    dest.mkdir(parents=True, exist_ok=True)
    # report.html draws every run, so every part is loaded once and shared by the four
    runs = collect_runs(out_dir, EVERYTHING)
    return ReportPaths(
        results_csv=write_results_csv(runs, dest / "results.csv"),
        summary_csv=write_summary_csv(runs, dest / "summary.csv"),
        junit_xml=write_junit(runs, dest / "junit.xml"),
        report_html=write_html(runs, dest / "report.html",
                               title=f"hwyeval report — {out_dir.resolve().name}"),
    )
