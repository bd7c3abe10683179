"""``write_reports``: results.csv, summary.csv, junit.xml, report.html and a page per run.

Streaming: the controller and options of every run are read first (from run.json, for
the variant labels), then each run is loaded with its per-step files one at a time, its page
written, its per-step times added to the timing pools (:mod:`reports.pool`) and the
run dropped before the next is read. Memory is one run plus the verdicts, whatever
the number of runs. A run whose per-step files cannot be read becomes an 'error'
entry with the reason (its page says it).
"""

from __future__ import annotations

import dataclasses
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from reports.html import Links, render_index, render_run_page
from reports.html.style import CSS
from reports.junit import write_junit
from reports.manifest import read_manifest
from reports.record import (
    RUN_JSON,
    ControllerArrays,
    NeighbourColumns,
    RecordError,
    Trace,
    iter_run_dirs,
)
from reports.record.codec import read_json, write_text_atomic
from reports.tables import (
    EVERYTHING,
    Pools,
    RunEntry,
    add_to_pools,
    read_entry,
    write_results_csv,
    write_summary_csv,
)
from reports.variants import variant_labels


@dataclass(frozen=True)
class ReportPaths:
    """Files written by :func:`write_reports`."""

    results_csv: Path
    summary_csv: Path
    junit_xml: Path
    report_html: Path
    run_pages: Path


def light(entry: RunEntry) -> RunEntry:
    """The entry without its per-step parts (what the index and tables keep)."""
    if entry.record is None:
        return entry
    record = dataclasses.replace(entry.record, trace=Trace.empty(),
                                 neighbours=NeighbourColumns.allocate(0),
                                 arrays=ControllerArrays(), series=None)
    return dataclasses.replace(entry, record=record)


def controller_of(run_dir: Path) -> tuple[str, dict[str, Any]] | None:
    """(controller, controller_options) from run.json without decoding the rest (the
    variant labels need every run's before the first page is written); None when
    unreadable (the run is then reported as an error by :func:`read_entry`)."""
    try:
        doc = read_json(run_dir / RUN_JSON)
    except RecordError:
        return None
    info = doc.get("info") if isinstance(doc, dict) else None
    if not isinstance(info, dict) or not isinstance(info.get("controller"), str):
        return None  # a malformed run.json: read_entry reports it
    options = info.get("controller_options")
    return info["controller"], options if isinstance(options, dict) else {}


def _pages(runs: list[tuple[Path, str]], links: Links, title: str, pools: Pools
           ) -> list[RunEntry]:
    """Write every run's page, one run in memory at a time; returns the light entries
    (a run whose files are unreadable comes back as its error entry)."""
    links.pages.mkdir(parents=True, exist_ok=True)
    write_text_atomic(links.pages / "report.css", CSS)
    kept = []
    for run_dir, variant in runs:
        full = dataclasses.replace(read_entry(run_dir, EVERYTHING), variant=variant)
        add_to_pools(pools, full)
        write_text_atomic(links.page_file(full.run_id), render_run_page(full, links, title))
        kept.append(light(full))
    return kept


def write_reports(out_dir: str | Path, dest_dir: str | Path | None = None) -> ReportPaths:
    """Write the reports of every run directory under ``out_dir`` into ``dest_dir``
    (default ``out_dir``), from the stored verdicts and series (nothing is
    re-evaluated). Raises FileNotFoundError if ``out_dir`` is not a directory."""
    out_dir = Path(out_dir)
    if not out_dir.is_dir():
        raise FileNotFoundError(f"{out_dir}: not a directory")
    dest = Path(dest_dir) if dest_dir is not None else out_dir
    dest.mkdir(parents=True, exist_ok=True)
    links = Links(dest)
    if links.pages.is_dir():
        shutil.rmtree(links.pages)  # pages of runs that are gone must not linger
    run_dirs = iter_run_dirs(out_dir)
    labels = variant_labels([controller_of(d) for d in run_dirs])
    title = f"hwyeval report — {out_dir.resolve().name}"
    pools: Pools = {}
    runs = _pages(list(zip(run_dirs, labels, strict=True)), links, title, pools)
    index = dest / "report.html"
    manifest = read_manifest(out_dir)
    write_text_atomic(index, render_index(runs, pools, links, title, manifest))
    return ReportPaths(
        results_csv=write_results_csv(runs, dest / "results.csv"),
        summary_csv=write_summary_csv(runs, dest / "summary.csv", pools),
        junit_xml=write_junit(runs, dest / "junit.xml", manifest),
        report_html=index,
        run_pages=links.pages,
    )
