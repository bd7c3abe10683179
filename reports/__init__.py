"""Reports regenerated from a catalog output directory (``DIR/<run>/run.json`` …).

``write_reports(out_dir)`` writes results.csv, summary.csv, junit.xml and report.html
into ``out_dir`` (only reading the run records); ``compare_runs`` diffs two outputs.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from reports.compare import CompareResult, MetricTolerance, Tolerances, compare_runs
from reports.html import write_html
from reports.junit import write_junit
from reports.tables import RunEval, collect_runs, write_results_csv, write_summary_csv


@dataclass(frozen=True)
class ReportPaths:
    """Files written by :func:`write_reports`."""

    results_csv: Path
    summary_csv: Path
    junit_xml: Path
    report_html: Path


def write_reports(out_dir: str | Path, criteria_overrides: Mapping[str, Any] | None = None,
                  dest_dir: str | Path | None = None) -> ReportPaths:
    """Evaluate every run under ``out_dir`` and write the four reports into ``dest_dir``
    (default ``out_dir``). ``criteria_overrides`` apply on top of each run's own criteria."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"{out_dir}: not a directory")
    dest = Path(dest_dir) if dest_dir is not None else out_dir
    dest.mkdir(parents=True, exist_ok=True)
    runs = collect_runs(out_dir, criteria_overrides)
    return ReportPaths(
        results_csv=write_results_csv(runs, dest / "results.csv"),
        summary_csv=write_summary_csv(runs, dest / "summary.csv"),
        junit_xml=write_junit(runs, dest / "junit.xml"),
        report_html=write_html(runs, dest / "report.html",
                               title=f"hwyeval report — {out_dir.resolve().name}"),
    )


__all__ = ["CompareResult", "MetricTolerance", "ReportPaths", "RunEval", "Tolerances",
           "collect_runs", "compare_runs", "write_reports"]
