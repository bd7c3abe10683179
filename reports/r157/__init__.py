"""An R157 pack's runs judged by the regulation's acceptance logic (``hwyeval r157``).

From the runs of a pack imported with ``hwyeval import openscenario --r157`` (each
scenario labelled with its Annex 5 section): the system under test's runs in one
folder, the reference driver's (``r157_reference``) in the same folder or another.
Writes ``r157.html`` (:mod:`reports.r157.page`) and ``r157.csv`` (a row per concrete
scenario and controller, :data:`CSV_COLUMNS`) into the system's folder
(docs/r157.md).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from reports.r157.outcome import (
    REFERENCE_CONTROLLER,
    SECTION_TITLES,
    PackRow,
    RunOutcome,
    SectionSummary,
    pack_rows,
    summarise,
)
from reports.r157.page import render_page
from reports.record.codec import write_text_atomic
from reports.tables import RunEntry, collect_runs

__all__ = ["CSV_COLUMNS", "PAGE", "REFERENCE_CONTROLLER", "SECTION_TITLES", "TABLE",
           "PackRow", "R157Error", "R157Report", "summary_markdown", "write_r157"]

PAGE = "r157.html"
TABLE = "r157.csv"
CSV_COLUMNS = ("section", "scenario", "controller", "ego_speed_kmh", "acceptance",
               "reasons", "status", "collisions", "at_fault_collisions", "min_ttc_s",
               "r157_gap_shortfall_s", "reference_status", "reference_collisions",
               "reference_at_fault_collisions", "reference_min_ttc_s")


class R157Error(Exception):
    """The folders hold no run of an R157 pack (or cannot be read)."""


@dataclass(frozen=True)
class R157Report:
    """What :func:`write_r157` judged and wrote."""

    rows: tuple[PackRow, ...]
    summaries: tuple[SectionSummary, ...]
    page: Path
    table: Path

    @property
    def met(self) -> bool:
        """Whether every run meets the acceptance logic."""
        return all(r.acceptance.met for r in self.rows)


def _num(x: float) -> str:
    return "" if not math.isfinite(x) else f"{x:.6g}"


def _outcome_fields(o: RunOutcome | None) -> list[str]:
    if o is None:
        return ["", "", "", ""]
    return [o.status, str(o.collisions), str(o.at_fault_collisions), _num(o.min_ttc_s)]


def rows_csv(rows: Sequence[PackRow]) -> str:
    """The rows as CSV text (:data:`CSV_COLUMNS`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in rows:
        acc = r.acceptance
        w.writerow([r.section, r.scenario, r.controller, _num(r.ego_speed_kmh),
                    "met" if acc.met else "not met", "; ".join(acc.reasons),
                    *_outcome_fields(r.system), _num(r.system.gap_shortfall_s),
                    *_outcome_fields(r.reference)])
    return buf.getvalue()


def summary_markdown(summaries: Sequence[SectionSummary]) -> str:
    """The summaries as a Markdown table (what ``hwyeval r157`` prints)."""
    lines = ["| controller | section | scenarios | acceptance met | pass | contacts | "
             "caused | contacts the reference avoids | reference pass | reference "
             "contacts |", "|---|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        ref = (f"{s.reference_passed}/{s.with_reference} | {s.reference_collided}"
               if s.with_reference else "not run | not run")
        lines.append(f"| {s.controller} | {s.section} | {s.scenarios} | {s.met} | "
                     f"{s.passed} | {s.collided} | {s.at_fault} | {s.preventable} | {ref} |")
    return "\n".join(lines)


def _runs(folder: Path) -> list[RunEntry]:
    if not folder.is_dir():
        raise R157Error(f"{folder}: no such run folder")
    return collect_runs(folder)


def write_r157(system_dir: str | Path, reference_dir: str | Path | None = None) -> R157Report:
    """Judge the pack's runs in ``system_dir`` (with the reference driver's runs there
    or in ``reference_dir``) and write :data:`PAGE` and :data:`TABLE` into
    ``system_dir``. Raises :class:`R157Error` when no run there is of a scenario with an
    R157 section label."""
    system = Path(system_dir)
    runs = _runs(system)
    reference = None if reference_dir is None else Path(reference_dir)
    if reference is not None:
        runs += [e for e in _runs(reference) if e.controller == REFERENCE_CONTROLLER]
    rows = pack_rows(runs)
    if not rows:
        raise R157Error(f"{system}: no run of a scenario labelled with an R157 section "
                        "(import the pack with hwyeval import openscenario --r157)")
    summaries = summarise(rows)
    page, table = system / PAGE, system / TABLE
    write_text_atomic(table, rows_csv(rows))
    write_text_atomic(page, render_page(rows, summaries, system, system,
                                        reference if reference is not None else system))
    return R157Report(tuple(rows), tuple(summaries), page, table)
