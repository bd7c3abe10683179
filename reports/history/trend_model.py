"""The history's trends as values (:mod:`reports.history.trends` loads them): one
scenario's trend over the nights, a night's summary, and the rules that name a scenario
flaky or failing since a night."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from reports.expectation import XFAILED, XPASSED, Xfail, expectation, fails_night
from reports.history.store import NightInfo
from reports.identity import CHANGE_KINDS
from reports.metrics.catalogue import DEFAULT_SPARKLINE
from reports.record import Failure

FLAKY_ALTERNATIONS = 3


ABSENT = "absent"


DEFAULT_METRIC = DEFAULT_SPARKLINE  # the catalogue's sparkline entry (min_ttc_s)


NO_CHANGE: tuple[str, ...] = ()


@dataclass(frozen=True)
class ScenarioTrend:
    """One scenario over the nights of a window (tuples aligned with them).

    statuses: the status each night (None: not run that night); hashes: its content
    hash each night ('' unknown or absent); values: the chosen ``metric`` (NaN absent);
    limit: the criterion's limit on that metric in the last night it ran (NaN: none).
    marks: its known-failure mark each night (None: none, or absent); changes: the
    kinds that changed that night (:data:`reports.identity.CHANGE_KINDS`); run_dirs:
    its run directory each night ('' absent). status_now: the status in the last night
    ('xfail' / 'xpass' for a known failure's, :mod:`reports.expectation`), or 'absent'.
    alternations: changes of the pass/not-pass outcome between consecutive nights it
    ran in. first_failures / first_changes: at the first failing night (module doc)."""

    scenario: str
    statuses: tuple[str | None, ...]
    hashes: tuple[str, ...]
    values: tuple[float, ...]
    limit: float
    status_now: str
    first_failing_night: str | None
    first_failing_revision: str | None
    last_good_night: str | None
    last_good_revision: str | None
    flaky: bool
    flaky_reasons: tuple[str, ...]
    alternations: int
    metric: str = DEFAULT_METRIC
    marks: tuple[Xfail | None, ...] = ()
    changes: tuple[tuple[str, ...], ...] = ()
    run_dirs: tuple[str, ...] = ()
    first_failures: tuple[Failure, ...] = ()
    first_changes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.statuses)
        for name in ("marks", "changes", "run_dirs"):
            if not getattr(self, name):
                fill: Any = {"marks": None, "changes": NO_CHANGE, "run_dirs": ""}[name]
                object.__setattr__(self, name, (fill,) * n)
        if not all(len(getattr(self, f)) == n for f in ("hashes", "values", "marks",
                                                        "changes", "run_dirs")):
            raise ValueError(f"ScenarioTrend {self.scenario}: statuses, hashes, values, "
                             "marks, changes and run_dirs must have one entry per night")
        if any(k not in CHANGE_KINDS for night in self.changes for k in night):
            raise ValueError(f"ScenarioTrend {self.scenario}: changes must be of "
                             f"{CHANGE_KINDS}, got {self.changes}")
        if self.alternations < 0:
            raise ValueError("ScenarioTrend.alternations must be >= 0")

    @property
    def failing_now(self) -> bool:
        """The last night's run fails the night (module doc)."""
        if self.status_now == ABSENT:
            return False
        return fails_night(self.statuses[-1] or "", self.marks[-1])

    @property
    def known_failure(self) -> bool:
        """Marked xfail in the last night (an expected failure or an unexpected pass)."""
        return self.status_now in (XFAILED, XPASSED)

    @property
    def sort_key(self) -> tuple[int, str]:
        """Failing now first, then flaky, then known failures, then the others; by name
        within."""
        rank = 0 if self.failing_now else 1 if self.flaky else 2 if self.known_failure else 3
        return (rank, self.scenario)


@dataclass(frozen=True)
class NightSummary:
    """A night of the window: its row of ``nights``, how many runs, how many passed,
    how many were expected failures (xfail)."""

    info: NightInfo
    runs: int
    passed: int
    expected: int = 0

    def __post_init__(self) -> None:
        if not 0 <= self.passed <= self.runs or not 0 <= self.expected <= self.runs:
            raise ValueError(f"NightSummary {self.info.night_id}: passed {self.passed} and "
                             f"expected {self.expected} of {self.runs} runs")

    @property
    def pass_rate(self) -> float:
        """passed / runs (NaN for a night without runs)."""
        return self.passed / self.runs if self.runs else math.nan


@dataclass(frozen=True)
class Trends:
    """The trend of a catalog's nights: the nights in start order and every scenario
    (failing now first, then flaky, then known failures, then by name). ``metric``: the
    sparklines' default (a failing scenario's is its failing criterion's)."""

    db: str
    catalog: str
    metric: str
    nights: tuple[NightSummary, ...]
    scenarios: tuple[ScenarioTrend, ...]

    @property
    def failing(self) -> tuple[ScenarioTrend, ...]:
        return tuple(s for s in self.scenarios if s.failing_now)

    @property
    def flaky(self) -> tuple[ScenarioTrend, ...]:
        return tuple(s for s in self.scenarios if s.flaky)

    @property
    def known_failures(self) -> tuple[ScenarioTrend, ...]:
        return tuple(s for s in self.scenarios if s.known_failure)


def _revision_key(night: NightInfo) -> str:
    """The code a night ran ('' when not a single known state: unknown or dirty)."""
    return night.git_revision if night.git_revision and night.git_dirty is not True else ""


def flaky_reasons(nights: Sequence[NightInfo], statuses: Sequence[str | None],
                  hashes: Sequence[str]) -> tuple[tuple[str, ...], int]:
    """Why a scenario is flaky (empty: it is not) and its number of alternations."""
    reasons: list[str] = []
    seen: dict[tuple[str, str], tuple[str, int]] = {}
    for i, (night, status, h) in enumerate(zip(nights, statuses, hashes, strict=True)):
        rev = _revision_key(night)
        if status is None or not rev or not h:
            continue
        first = seen.setdefault((h, rev), (status, i))
        if first[0] != status:
            reasons.append(f"{first[0]} in {nights[first[1]].night_id} and {status} in "
                           f"{night.night_id} with the same scenario hash and revision "
                           f"{night.short_revision}")
            seen[(h, rev)] = (status, i)
    outcomes = [s == "pass" for s in statuses if s is not None]
    alternations = sum(1 for a, b in zip(outcomes, outcomes[1:], strict=False) if a != b)
    if alternations >= FLAKY_ALTERNATIONS:
        reasons.append(f"{alternations} pass/fail alternations in {len(nights)} nights")
    return tuple(reasons), alternations


def _failing_since(nights: Sequence[NightInfo], statuses: Sequence[str | None],
                   marks: Sequence[Xfail | None]) -> tuple[int | None, int | None]:
    """Indices of the first night of the current failing streak and of the last night
    before it that did not fail."""
    first: int | None = None
    for j in range(len(nights) - 1, -1, -1):
        status = statuses[j]
        if status is None:
            continue
        if not fails_night(status, marks[j]):
            return first, j
        first = j
    return first, None


def scenario_trend(scenario: str, nights: Sequence[NightInfo],  # noqa: PLR0913 - one observation series per keyword, aligned with nights
                   statuses: Sequence[str | None], hashes: Sequence[str] | None = None,
                   values: Sequence[float] | None = None, limit: float = math.nan, *,
                   marks: Sequence[Xfail | None] | None = None,
                   changes: Sequence[tuple[str, ...]] | None = None,
                   run_dirs: Sequence[str] | None = None, metric: str = DEFAULT_METRIC
                   ) -> ScenarioTrend:
    """The trend of one scenario from its observations, aligned with ``nights`` (in
    start order; None where it did not run). The first failing night's failures and
    changes are filled in by :func:`load_trends` (they need the database)."""
    n = len(nights)
    hashes = tuple(hashes) if hashes is not None else ("",) * n
    vals = tuple(float(v) for v in values) if values is not None else (math.nan,) * n
    marks = tuple(marks) if marks is not None else (None,) * n
    if len(statuses) != n or len(marks) != n:
        raise ValueError(f"{scenario}: {len(statuses)} statuses, {len(marks)} marks for "
                         f"{n} nights")
    last = statuses[-1] if n else None
    now = ABSENT if last is None else (expectation(last, marks[-1]) or last)
    first = good = None
    if last is not None and fails_night(last, marks[-1]):
        first, good = _failing_since(nights, statuses, marks)
    reasons, alternations = flaky_reasons(nights, statuses, hashes)
    return ScenarioTrend(
        scenario=scenario, statuses=tuple(statuses), hashes=hashes, values=vals,
        limit=limit, status_now=now,
        first_failing_night=nights[first].night_id if first is not None else None,
        first_failing_revision=nights[first].git_revision if first is not None else None,
        last_good_night=nights[good].night_id if good is not None else None,
        last_good_revision=nights[good].git_revision if good is not None else None,
        flaky=bool(reasons), flaky_reasons=reasons, alternations=alternations,
        metric=metric, marks=marks, changes=tuple(changes) if changes is not None else (),
        run_dirs=tuple(run_dirs) if run_dirs is not None else ())
