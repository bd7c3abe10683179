"""The search's table, ``search.csv``: one typed row per run of a search.

Written by the search (:mod:`suite.search.found`), read by its page
(:mod:`reports.html.search`). This module imports nothing of hwyeval but the record codec.

``search.csv`` has one row per trial (and per line-search run of the shrinking,
``kind`` = shrink): family, kind (trial | shrink), trial (the trial number; a shrink
run carries its origin's), run (the run directory, '' when refused), status (pass |
fail | error | timeout | refused), robustness [-] (:mod:`reports.metrics.robustness`;
empty when not judged), robustness_criterion, failure_mode (failed criteria
'+'-joined, '@', the manoeuvre phase), found (the ``found.toml`` scenario this row's
point became, '' if none), reason (why refused), then one column per searched key
(its dotted path) holding the value as JSON ('' when the family has no such key).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from reports.record.codec import write_text_atomic

__all__ = ["KINDS", "LEAD", "SEARCH_CSV", "SearchRow", "read_search_csv", "write_search_csv"]

SEARCH_CSV = "search.csv"
LEAD = ("family", "kind", "trial", "run", "status", "robustness", "robustness_criterion",
        "failure_mode", "found", "reason")
KINDS = ("trial", "shrink")


@dataclass(frozen=True)
class SearchRow:
    """One row of search.csv (module doc); ``params``: (dotted path, value as JSON)."""

    family: str
    kind: str
    trial: int
    run: str
    status: str
    robustness: float
    robustness_criterion: str
    failure_mode: str
    found: str
    reason: str
    params: tuple[tuple[str, str], ...]

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"SearchRow.kind must be one of {KINDS}, got {self.kind!r}")
        if self.trial < 0:
            raise ValueError(f"SearchRow.trial must be >= 0, got {self.trial}")

    def number(self, path: str) -> float:
        """The value of ``path`` as a number (NaN when absent or not a number)."""
        for key, text in self.params:
            if key == path:
                try:
                    value = json.loads(text)
                except ValueError:
                    return math.nan
                return float(value) if isinstance(value, int | float) \
                    and not isinstance(value, bool) else math.nan
        return math.nan


def write_search_csv(rows: Sequence[SearchRow], path: Path) -> Path:
    """Write search.csv atomically (columns: module doc)."""
    paths: list[str] = []
    for row in rows:
        for key, _ in row.params:
            if key not in paths:
                paths.append(key)
    lines: list[list[str]] = [[*LEAD, *paths]]
    for row in rows:
        values = dict(row.params)
        rob = "" if math.isnan(row.robustness) else repr(row.robustness)
        lines.append([row.family, row.kind, str(row.trial), row.run, row.status, rob,
                      row.robustness_criterion, row.failure_mode, row.found, row.reason,
                      *(values.get(k, "") for k in paths)])
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(lines)
    write_text_atomic(path, buf.getvalue())
    return path


def read_search_csv(path: Path) -> list[SearchRow]:
    """The rows of a search.csv (ValueError naming the file and row when malformed)."""
    with path.open(newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None or tuple(header[:len(LEAD)]) != LEAD:
            raise ValueError(f"{path}: expected a search.csv header starting {list(LEAD)}")
        paths = header[len(LEAD):]
        rows = []
        for i, cells in enumerate(reader, start=2):
            if len(cells) != len(header):
                raise ValueError(f"{path}: row {i}: expected {len(header)} cells")
            rob = float(cells[5]) if cells[5] else math.nan
            rows.append(SearchRow(cells[0], cells[1], int(cells[2]), cells[3], cells[4], rob,
                                  cells[6], cells[7], cells[8], cells[9],
                                  tuple((k, v) for k, v in zip(paths, cells[len(LEAD):],
                                                               strict=True) if v != "")))
    return rows
