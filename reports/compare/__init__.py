"""``hwyeval compare BASE NEW``: did the new catalog output regress against the base?

Only stored verdicts are read (``run.json``, through :func:`reports.record.load_run`,
which checks every file run.json lists against its checksum) and each side's
``manifest.json`` (provenance, load). A run directory that cannot be read (run.json
malformed, a file missing, changed or corrupt) is an ``unreadable`` finding naming the
file: it gates on the new side and is reported on the base side; its pair is not
compared otherwise (its 'error' status says nothing of behaviour).

* **Behaviour gates** (exit 1): a run that passed and no longer does, a worse status,
  a newly failed criterion, a safety/comfort/tracking metric worse beyond its tolerance,
  a run missing from new, a strict known failure that passed. Same code on the same
  catalog gives the same behaviour: these do not depend on the machine. A changed
  system under test (controller, options, code) is what the gate is for: its runs gate;
  a changed test does not; a changed limit is judged both ways
  (:mod:`~reports.compare.kinds`).
* **Timing warns**: wall-clock metrics (kind ``timing``, ``deadline_misses`` included)
  are reported as ratios new/base, per run and as the catalog's median, with the load
  of both sides; with ``--timing-gate`` (``timing_gate = true``) a median ratio beyond
  its limit, or a deadline-miss count up, fails too. Health metrics warn.
* **Provenance**: differences in git revision, versions, host and CPU are listed.
* **Nothing to compare** — no run directory on a side, or no run of new matching one of
  base — raises :class:`NothingToCompare` (the CLI exits 2): an empty baseline must
  never pass a night.

Modules: :mod:`~reports.compare.tolerances` (TOML), :mod:`~reports.compare.findings`
(matching, rows), :mod:`~reports.compare.kinds` (why a pair differs: the test, the
limits, the system under test, known failures), :mod:`~reports.compare.timing`
(catalog-wide ratios, load), :mod:`~reports.compare.render` (terminal, JSON, CSV,
HTML).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from reports.compare.findings import CompareRow, DuplicateRuns, match_runs, metric_rows
from reports.compare.kinds import CATEGORIES, pair_findings, unreadable_rows
from reports.compare.timing import TimingLine, load_note, timing_lines
from reports.compare.tolerances import MetricTolerance, Tolerances
from reports.manifest import Manifest, read_manifest
from reports.provenance import Difference, differences
from reports.tables import RunEntry, collect_runs

__all__ = ["CompareResult", "CompareRow", "DuplicateRuns", "MetricTolerance", "NothingToCompare",
           "TimingLine", "Tolerances", "UnknownTolerance", "compare_evaluated", "compare_runs"]


class NothingToCompare(ValueError):
    """A side holds no run, or no run matches: the comparison means nothing (exit 2)."""


class UnknownTolerance(ValueError):
    """The tolerances name a metric no compared run has (a typo; exit 2)."""


@dataclass
class CompareResult:
    """Outcome of :func:`compare_runs`."""

    rows: list[CompareRow]
    matched: int
    base_dir: Path
    new_dir: Path
    timing: list[TimingLine] = field(default_factory=list)
    base_manifest: Manifest | None = None
    new_manifest: Manifest | None = None
    provenance_differences: list[Difference] = field(default_factory=list)
    load: str = ""
    timing_gate: bool = False
    csv_path: Path | None = None
    html_path: Path | None = None

    def of_kind(self, *kinds: str) -> list[CompareRow]:
        return [r for r in self.rows if r.kind in kinds]

    def of_category(self, category: str) -> list[CompareRow]:
        """Findings of one category (:data:`reports.compare.findings.CATEGORIES`)."""
        return [r for r in self.rows if r.category == category]

    @property
    def category_counts(self) -> dict[str, int]:
        """Findings per category, every category listed (0 where none)."""
        return {c: len(self.of_category(c)) for c in CATEGORIES}

    @property
    def regressions(self) -> list[CompareRow]:
        """Findings that fail the comparison."""
        return [r for r in self.rows if r.gate]

    @property
    def warnings(self) -> list[CompareRow]:
        """Timing and health findings that do not fail it."""
        return [r for r in self.rows if r.warning]

    @property
    def timing_failures(self) -> list[TimingLine]:
        """Catalog-wide timing slowdowns that fail (only with the timing gate)."""
        return [t for t in self.timing if t.gate]

    @property
    def new_failures(self) -> list[str]:
        return [r.key for r in self.of_kind("new_failure")]

    @property
    def fixed(self) -> list[str]:
        """Runs fixed: passing now under the same limits (a waiver is not a fix), and
        known failures that passed ("fixed: remove the xfail")."""
        return [r.key for r in self.fixed_rows]

    @property
    def fixed_rows(self) -> list[CompareRow]:
        return [r for r in self.rows if (r.kind == "fixed" and r.category == "improvement")
                or r.kind == "xpass"]

    @property
    def missing(self) -> list[str]:
        return [r.key for r in self.of_kind("missing")]

    @property
    def added(self) -> list[str]:
        return [r.key for r in self.of_kind("new")]

    @property
    def exit_code(self) -> int:
        """1 on any regression (or gated timing slowdown), else 0."""
        return 1 if self.regressions or self.timing_failures else 0

    def summary_text(self) -> str:
        """The terminal report (see :mod:`reports.compare.render`)."""
        from reports.compare.render import summary_text

        return summary_text(self)


def compare_evaluated(base: list[RunEntry], new: list[RunEntry],
                      tolerances: Tolerances | None = None
                      ) -> tuple[list[CompareRow], int, list[tuple[RunEntry, RunEntry]]]:
    """Findings for two lists of runs, the number matched and the matched pairs."""
    tol = tolerances or Tolerances()
    rows: list[CompareRow] = []
    pairs: list[tuple[RunEntry, RunEntry]] = []
    for m in match_runs(base, new):
        b, n = m.base, m.new
        rows += unreadable_rows(m.key, b, n)
        if n is None and b is not None:
            rows.append(CompareRow(m.key, b.scenario, b.controller, "missing",
                                   note="in base only", gate=tol.missing_is_regression,
                                   category="removed_scenario"))
            continue
        if b is None or n is None:
            if n is not None:
                rows.append(CompareRow(m.key, n.scenario, n.controller, "new",
                                       note=f"in new only ({n.status})",
                                       category="new_scenario"))
            continue
        pairs.append((b, n))
        if b.unreadable or n.unreadable:
            continue  # said by its unreadable row
        both_judged = b.status in ("pass", "fail") and n.status in ("pass", "fail")
        metrics = metric_rows(m.key, b, n, tol) if both_judged else []
        rows.extend(pair_findings(m.key, b, n, metrics))
    return rows, len(pairs), pairs


def compare_runs(base_dir: str | Path, new_dir: str | Path, out_dir: str | Path | None = None,
                 tolerances: Tolerances | None = None) -> CompareResult:
    """Compare two catalog outputs; writes ``compare.csv`` and ``compare.html`` into
    ``out_dir`` (when given). Raises FileNotFoundError for a missing directory and
    :class:`NothingToCompare` when a side is empty or nothing matches."""
    tol = tolerances or Tolerances()
    base_dir, new_dir = Path(base_dir), Path(new_dir)
    for d in (base_dir, new_dir):
        if not d.is_dir():
            raise FileNotFoundError(f"{d}: not a directory")
    base, new = collect_runs(base_dir), collect_runs(new_dir)
    for side, d, runs in (("base", base_dir, base), ("new", new_dir, new)):
        if not runs:
            raise NothingToCompare(f"{side} {d} holds no run directory (DIR/<scenario>/"
                                   "run.json): nothing to compare against")
    unknown = tol.unknown_names({m.name for r in (*base, *new) for m in r.metrics})
    if unknown:
        raise UnknownTolerance("the tolerances set metrics that no run of either side has: "
                               + ", ".join(unknown))
    rows, matched, pairs = compare_evaluated(base, new, tol)
    if matched == 0:
        raise NothingToCompare(f"no run of {new_dir} matches a run of {base_dir} (by scenario "
                               "and controller): are these outputs of the same catalog?")
    bm, nm = read_manifest(base_dir), read_manifest(new_dir)
    bp = bm.provenance if bm is not None else None
    np_ = nm.provenance if nm is not None else None
    result = CompareResult(
        rows, matched, base_dir, new_dir, timing=timing_lines(pairs, tol), base_manifest=bm,
        new_manifest=nm,
        provenance_differences=differences(bp, np_) if bp is not None and np_ is not None
        else [],
        load=load_note(bp, np_), timing_gate=tol.timing_gate)
    if out_dir is not None:
        from reports.compare.render import write_compare_csv, write_compare_html

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        result.csv_path = write_compare_csv(result, out / "compare.csv")
        result.html_path = write_compare_html(result, out / "compare.html", base, new)
    return result
