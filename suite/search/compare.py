"""The search against random sampling: runs to the first failure, distinct failure modes.

For each family, sampler and seed one search of the same budget (``hwyeval search
CATALOG --out DIR --compare tpe,random --seeds 5``); per search the *runs to the first
failure* (the 1-based index among the runs, refused points not counted, of the first
run that failed; ``budget + 1`` when none failed: a censored value, shown as ``>N``)
and the number of distinct failure modes. Per family and sampler the table gives the
median runs to the first failure over the seeds, how many seeds found one, the mean
count of distinct modes, and the fraction of all its runs that failed (for the random
sampler an estimate of the failure region's share of the space).
"""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from suite.search.loop import FamilyResult

__all__ = ["CompareRow", "SearchOutcome", "compare_rows", "compare_table", "outcome_of"]


@dataclass(frozen=True)
class SearchOutcome:
    """One search of one family: ``first_failure_run`` (budget + 1 when none), the
    distinct modes, the runs and failed runs."""

    family: str
    sampler: str
    seed: int
    budget_runs: int
    first_failure_run: int
    modes: tuple[str, ...]
    runs: int
    failed_runs: int

    @property
    def found(self) -> bool:
        return self.first_failure_run <= self.budget_runs


def outcome_of(result: FamilyResult, sampler: str, seed: int, budget: int) -> SearchOutcome:
    runs = result.runs
    first = next((i + 1 for i, t in enumerate(runs) if t.is_failure), budget + 1)
    modes = tuple(sorted({t.mode for t in runs if t.is_failure}))
    return SearchOutcome(result.family.name, sampler, seed, budget, first, modes, len(runs),
                         sum(1 for t in runs if t.is_failure))


@dataclass(frozen=True)
class CompareRow:
    family: str
    sampler: str
    seeds: int
    median_first_failure: float
    found_in: int
    mean_modes: float
    failed_fraction: float
    firsts: tuple[int, ...]


def compare_rows(outcomes: Sequence[SearchOutcome]) -> list[CompareRow]:
    groups: dict[tuple[str, str], list[SearchOutcome]] = {}
    for o in outcomes:
        groups.setdefault((o.family, o.sampler), []).append(o)
    rows = []
    for (family, sampler), members in groups.items():
        firsts = tuple(o.first_failure_run for o in members)
        runs = sum(o.runs for o in members)
        rows.append(CompareRow(family, sampler, len(members), float(statistics.median(firsts)),
                               sum(o.found for o in members),
                               statistics.fmean(len(o.modes) for o in members),
                               sum(o.failed_runs for o in members) / max(runs, 1), firsts))
    return rows


def _first(value: float, budget: int) -> str:
    return f">{budget}" if value > budget else f"{value:g}"


def compare_table(rows: Sequence[CompareRow], budget: int) -> str:
    """The comparison as a Markdown table (runs to first failure per seed in brackets)."""
    lines = ["| family | sampler | seeds | median runs to 1st failure | per seed | "
             "seeds that found one | mean distinct modes | runs failed |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        per = ", ".join(_first(f, budget) for f in r.firsts)
        lines.append(f"| {r.family} | {r.sampler} | {r.seeds} | "
                     f"{_first(r.median_first_failure, budget)} | {per} | {r.found_in}/{r.seeds} "
                     f"| {r.mean_modes:.1f} | {100 * r.failed_fraction:.1f} % |")
    return "\n".join(lines)
