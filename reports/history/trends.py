"""What many nights say about each scenario: its status now, the night and revision it
started failing, the last good revision, whether it is flaky, a metric's trend.

The computations (:func:`scenario_trend`) are pure functions of one scenario's
observations over the nights of a window; :func:`load_trends` reads those from the
database.

**Failing** means any status other than ``pass`` (fail, error, timeout). For a
scenario failing in the last night, ``first_failing_night`` is the first night of its
current run of failing nights (nights it is absent from are skipped), and
``last_good_*`` the last night before that in which it passed (None: never passed in
the window).

**Flaky** (docs/history.md), within the window:

* *same code, different status*: two nights with the same scenario content hash and
  the same git revision (both known, neither checkout dirty) gave different statuses;
* or *alternations*: the pass/not-pass outcome changed at least
  :data:`FLAKY_ALTERNATIONS` times from one night the scenario ran in to the next (a
  regression and its fix are two changes, not flaky).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from reports.history.schema import METRIC_NAME, HistoryError, metric_columns
from reports.history.store import DEFAULT_WAIT_S, NightInfo, night_infos, reading

FLAKY_ALTERNATIONS = 3
ABSENT = "absent"
DEFAULT_METRIC = "min_ttc_s"


@dataclass(frozen=True)
class ScenarioTrend:
    """One scenario over the nights of a window (tuples aligned with them).

    statuses: the status each night (None: not run that night); hashes: its content
    hash each night ('' unknown or absent); values: the chosen metric (NaN absent);
    limit: the criterion's limit on that metric in the last night it ran (NaN: none).
    status_now: the status in the last night, or 'absent'. alternations: changes of
    the pass/not-pass outcome between consecutive nights it ran in."""

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

    def __post_init__(self) -> None:
        if not (len(self.statuses) == len(self.hashes) == len(self.values)):
            raise ValueError(f"ScenarioTrend {self.scenario}: statuses, hashes and values "
                             "must have one entry per night")
        if self.alternations < 0:
            raise ValueError("ScenarioTrend.alternations must be >= 0")

    @property
    def failing_now(self) -> bool:
        return self.status_now not in ("pass", ABSENT)

    @property
    def sort_key(self) -> tuple[int, str]:
        """Failing now first, then flaky, then the others; by name within."""
        return (0 if self.failing_now else 1 if self.flaky else 2, self.scenario)


@dataclass(frozen=True)
class NightSummary:
    """A night of the window: its row of ``nights``, how many runs, how many passed."""

    info: NightInfo
    runs: int
    passed: int

    def __post_init__(self) -> None:
        if not 0 <= self.passed <= self.runs:
            raise ValueError(f"NightSummary {self.info.night_id}: passed {self.passed} of "
                             f"{self.runs} runs")

    @property
    def pass_rate(self) -> float:
        """passed / runs (NaN for a night without runs)."""
        return self.passed / self.runs if self.runs else math.nan


@dataclass(frozen=True)
class Trends:
    """The trend of a catalog's nights: the nights in start order and every scenario
    (failing now first, then flaky, then by name)."""

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


def _failing_since(nights: Sequence[NightInfo], statuses: Sequence[str | None]
                   ) -> tuple[NightInfo | None, NightInfo | None]:
    """The first night of the current failing streak and the last pass before it."""
    first: NightInfo | None = None
    for night, status in zip(reversed(nights), reversed(statuses), strict=True):
        if status is None:
            continue
        if status == "pass":
            return first, night
        first = night
    return first, None


def scenario_trend(scenario: str, nights: Sequence[NightInfo],
                   statuses: Sequence[str | None], hashes: Sequence[str] | None = None,
                   values: Sequence[float] | None = None, limit: float = math.nan
                   ) -> ScenarioTrend:
    """The trend of one scenario from its observations, aligned with ``nights`` (in
    start order; None where it did not run)."""
    n = len(nights)
    hashes = tuple(hashes) if hashes is not None else ("",) * n
    vals = tuple(float(v) for v in values) if values is not None else (math.nan,) * n
    if len(statuses) != n:
        raise ValueError(f"{scenario}: {len(statuses)} statuses for {n} nights")
    now = statuses[-1] if n and statuses[-1] is not None else ABSENT
    first = good = None
    if now not in ("pass", ABSENT):
        first, good = _failing_since(nights, statuses)
    reasons, alternations = flaky_reasons(nights, statuses, hashes)
    return ScenarioTrend(
        scenario=scenario, statuses=tuple(statuses), hashes=hashes, values=vals,
        limit=limit, status_now=now,
        first_failing_night=first.night_id if first else None,
        first_failing_revision=first.git_revision if first else None,
        last_good_night=good.night_id if good else None,
        last_good_revision=good.git_revision if good else None,
        flaky=bool(reasons), flaky_reasons=reasons, alternations=alternations)


# ----------------------------------------------------------------------- loading


def _pick_catalog(infos: list[NightInfo], catalog: str | None, db: str) -> str:
    if not infos:
        raise HistoryError(f"{db}: holds no night (hwyeval history add DB RUNDIR)")
    if catalog is None:
        return infos[-1].catalog
    from reports.history.store import catalog_matches

    for info in reversed(infos):
        if catalog_matches(info.catalog, catalog):
            return info.catalog
    known = sorted({i.catalog for i in infos})
    raise HistoryError(f"{db}: --catalog {catalog!r}: no night of it; the database holds "
                       f"{', '.join(known)}")


def load_trends(db: str | Path, metric: str = DEFAULT_METRIC, catalog: str | None = None,
                window: int | None = None, wait_s: float = DEFAULT_WAIT_S) -> Trends:
    """The trends of ``catalog`` (default: the catalog of the newest night) over its
    last ``window`` nights (default: all). An unknown ``metric`` is a
    :class:`HistoryError` naming the metrics there are."""
    if window is not None and window < 1:
        raise HistoryError(f"--nights {window}: expected a whole number >= 1")
    with reading(db, wait_s) as con:
        infos = night_infos(con)
        chosen = _pick_catalog(infos, catalog, str(db))
        nights = [i for i in infos if i.catalog == chosen]
        if window is not None:
            nights = nights[-window:]
        metrics = metric_columns(con)
        if metric not in metrics or not METRIC_NAME.match(metric):
            raise HistoryError(f"--metric {metric!r}: no such metric column in {db}; there "
                               f"are {', '.join(sorted(metrics))}")
        con.execute("CREATE TEMP TABLE window_nights (night_id VARCHAR, k INTEGER)")
        con.executemany("INSERT INTO window_nights VALUES (?, ?)",
                        [[n.night_id, k] for k, n in enumerate(nights)])
        cols = con.execute(
            "SELECT w.k, r.scenario || CASE WHEN count(*) OVER (PARTITION BY r.night_id, "
            "r.scenario) > 1 THEN ' (' || r.controller || ')' ELSE '' END AS label, "
            f'r.status, r.scenario_hash, r."{metric}", '
            f"map_extract_value(r.limits, '{metric}') FROM runs r JOIN window_nights w "
            "USING (night_id) ORDER BY label, w.k").fetchnumpy()
    return Trends(str(db), chosen, metric, *_assemble(nights, cols))


def _column(cols: dict[str, Any], index: int) -> np.ndarray:
    arr = list(cols.values())[index]
    if isinstance(arr, np.ma.MaskedArray):
        if arr.dtype.kind in "fiu":
            return np.asarray(np.ma.filled(arr.astype(np.float64), np.nan))
        return np.asarray(np.ma.filled(arr, None))
    return np.asarray(arr)


def _assemble(nights: list[NightInfo], cols: dict[str, Any]
              ) -> tuple[tuple[NightSummary, ...], tuple[ScenarioTrend, ...]]:
    k = _column(cols, 0).astype(np.int64)
    names, statuses, hashes = _column(cols, 1), _column(cols, 2), _column(cols, 3)
    values = _column(cols, 4).astype(np.float64)
    limits = _column(cols, 5).astype(np.float64)
    n = len(nights)
    runs = np.bincount(k, minlength=n) if k.size else np.zeros(n, np.int64)
    passed = (np.bincount(k, weights=(statuses == "pass").astype(np.float64), minlength=n)
              if k.size else np.zeros(n))
    summaries = tuple(NightSummary(info, int(runs[j]), int(passed[j]))
                      for j, info in enumerate(nights))
    trends = []
    starts: list[int] = (np.flatnonzero(np.r_[True, names[1:] != names[:-1]]).tolist()
                         if names.size else [])
    bounds = [*starts, int(names.size)]
    for a, b in zip(bounds, bounds[1:], strict=False):
        st: list[str | None] = [None] * n
        hs = [""] * n
        vs = [math.nan] * n
        limit = math.nan
        for row in range(a, b):
            j = int(k[row])
            st[j], hs[j] = str(statuses[row]), str(hashes[row] or "")
            vs[j] = float(values[row])
            limit = float(limits[row])
        trends.append(scenario_trend(str(names[a]), nights, st, hs, vs, limit))
    return summaries, tuple(sorted(trends, key=lambda t: t.sort_key))


# ----------------------------------------------------------------------- JSON


def _num(x: float) -> float | str | None:
    if math.isnan(x):
        return None
    return x if math.isfinite(x) else ("inf" if x > 0 else "-inf")


def trends_dict(trends: Trends) -> dict[str, Any]:
    """The trends as plain JSON data (``hwyeval history DB --json``; docs/history.md)."""
    return {
        "db": trends.db, "catalog": trends.catalog, "metric": trends.metric,
        "flaky_rule": {"same_hash_and_revision": True,
                       "min_alternations": FLAKY_ALTERNATIONS},
        "nights": [{"night_id": s.info.night_id, "started_at": s.info.started_at.isoformat(),
                    "git_revision": s.info.git_revision, "git_dirty": s.info.git_dirty,
                    "hwyeval_version": s.info.hwyeval_version, "host": s.info.host,
                    "catalog_sha256": s.info.catalog_sha256, "out_dir": s.info.out_dir,
                    "runs": s.runs, "passed": s.passed, "pass_rate": _num(s.pass_rate)}
                   for s in trends.nights],
        "scenarios": [{"scenario": t.scenario, "status_now": t.status_now,
                       "failing_now": t.failing_now,
                       "first_failing_night": t.first_failing_night,
                       "first_failing_revision": t.first_failing_revision,
                       "last_good_night": t.last_good_night,
                       "last_good_revision": t.last_good_revision,
                       "flaky": t.flaky, "flaky_reasons": list(t.flaky_reasons),
                       "alternations": t.alternations, "statuses": list(t.statuses),
                       "metric_values": [_num(v) for v in t.values],
                       "metric_limit": _num(t.limit)}
                      for t in trends.scenarios],
    }


def trends_json(trends: Trends) -> str:
    return json.dumps(trends_dict(trends), indent=1)
