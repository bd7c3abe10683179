"""What many nights say about each scenario: its status now, the night and revision it
started failing and why (the failed criteria, what changed that night), the last good
revision, whether it is flaky, the failing criterion's metric over the nights.

The computations (:func:`scenario_trend`) are pure functions of one scenario's
observations over the nights of a window; :func:`load_trends` reads those from the
database.

**Failing** means a status that fails the night (:func:`reports.expectation.fails_night`):
any status other than ``pass``, except a known failure that failed as expected
(``xfail``), and a strict known failure that passed. For a scenario failing in the last
night, ``first_failing_night`` is the first night of its current run of failing nights
(nights it is absent from are skipped), ``first_failures`` its failed criteria with
values and limits, ``first_changes`` what changed that night (the test, the limits, the
system under test: :mod:`reports.identity`; the code revision), and ``last_good_*`` the
last night before that in which it did not fail (None: never in the window).

**Changes**: per night, which of the kinds of :data:`reports.identity.CHANGE_KINDS`
differ from the night before that the scenario ran in (a digest unknown on either
side, e.g. a night added before schema v3, is no change).

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
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from reports.expectation import XFAILED, XPASSED, Xfail, expectation, fails_night
from reports.history.schema import METRIC_NAME, HistoryError, metric_columns
from reports.history.store import DEFAULT_WAIT_S, NightInfo, night_infos, reading
from reports.identity import CHANGE_KINDS, Setup, flatten_options, setup_change
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


def scenario_trend(scenario: str, nights: Sequence[NightInfo],
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


# ----------------------------------------------------------------------- loading


def _pick_catalog(infos: list[NightInfo], catalog: str | None, db: str) -> str:
    """The catalog identity to show (module doc of :func:`load_trends`)."""
    if not infos:
        raise HistoryError(f"{db}: holds no night (hwyeval history add DB RUNDIR)")
    if catalog is None:
        return infos[-1].catalog_key
    from reports.history.store import catalog_matches

    for info in reversed(infos):
        if catalog_matches(info, catalog):
            return info.catalog_key
    known = sorted({i.catalog_key for i in infos})
    raise HistoryError(f"{db}: --catalog {catalog!r}: no night of it; the database holds "
                       f"{', '.join(known)}")


def _digest_changed(column: str) -> str:
    """SQL: the digest in ``column`` differs from the night before (unknown: no)."""
    prev = f"lag({column}) OVER p"
    return f"coalesce({column} <> '' AND {prev} <> '' AND {column} <> {prev}, false)"


# the bulk of the window, one row per run: cheap columns only (the failures and the
# options are read for the few scenarios that need them, :func:`_first_failing_facts`)
_WINDOW_SQL = """
WITH r AS (
  SELECT w.k, r.scenario || CASE WHEN count(*) OVER (PARTITION BY r.night_id, r.scenario) > 1
           THEN ' (' || r.controller || ')' ELSE '' END AS label,
         r.status, r.scenario_hash, r."{metric}" AS v,
         map_extract_value(r.limits, '{metric}') AS lim, r.test_hash, r.test_spec_hash,
         r.limits_hash, r.sut_hash, r.xfail, r.xfail_strict, r.failure_modes[1] AS mode,
         r.run_dir
  FROM runs r JOIN window_nights w USING (night_id))
SELECT k, label, status, scenario_hash, v, lim,
  CASE WHEN test_hash <> '' AND lag(test_hash) OVER p <> ''
       THEN test_hash <> lag(test_hash) OVER p
       ELSE {test_spec} END AS test_changed,
  {limits} AS limits_changed, {sut} AS sut_changed, xfail, xfail_strict, mode, run_dir
FROM r WINDOW p AS (PARTITION BY label ORDER BY k) ORDER BY label, k
"""


def load_trends(db: str | Path, metric: str = DEFAULT_METRIC, catalog: str | None = None,
                window: int | None = None, wait_s: float = DEFAULT_WAIT_S) -> Trends:
    """The trends of ``catalog`` (its identity, or a path or stem it was run from;
    default: the catalog of the newest night) over its last ``window`` nights (default:
    all). ``metric`` is the sparklines' default; a scenario that failed in the window
    plots its failing criterion's metric instead. An unknown ``metric`` is a
    :class:`HistoryError` naming the metrics there are."""
    if window is not None and window < 1:
        raise HistoryError(f"--nights {window}: expected a whole number >= 1")
    with reading(db, wait_s) as con:
        infos = night_infos(con)
        chosen = _pick_catalog(infos, catalog, str(db))
        nights = [i for i in infos if i.catalog_key == chosen]
        if window is not None:
            nights = nights[-window:]
        metrics = metric_columns(con)
        if metric not in metrics or not METRIC_NAME.match(metric):
            raise HistoryError(f"--metric {metric!r}: no such metric column in {db}; there "
                               f"are {', '.join(sorted(metrics))}")
        con.execute("CREATE TEMP TABLE window_nights (night_id VARCHAR, k INTEGER)")
        con.executemany("INSERT INTO window_nights VALUES (?, ?)",
                        [[n.night_id, k] for k, n in enumerate(nights)])
        cols = con.execute(_WINDOW_SQL.format(
            metric=metric, test_spec=_digest_changed("test_spec_hash"),
            limits=_digest_changed("limits_hash"), sut=_digest_changed("sut_hash"))
        ).fetchnumpy()
        summaries, rows = _assemble(nights, cols, metric)
        rows = _own_metrics(con, rows, set(metrics), metric)
        trends = _with_first_failures(con, nights, rows)
    return Trends(str(db), chosen, metric, summaries,
                  tuple(sorted(trends, key=lambda t: t.sort_key)))


def _column(cols: Mapping[str, Any], name: str) -> np.ndarray:
    arr = cols[name]
    if isinstance(arr, np.ma.MaskedArray):
        if arr.dtype.kind in "fiu":
            return np.asarray(np.ma.filled(arr.astype(np.float64), np.nan))
        if arr.dtype.kind == "b":
            return np.asarray(np.ma.filled(arr, False))
        return np.asarray(np.ma.filled(arr, None))
    return np.asarray(arr)


@dataclass
class _Rows:
    """One scenario's rows of the window, aligned with the nights (being assembled)."""

    label: str
    statuses: list[str | None]
    hashes: list[str]
    values: list[float]
    marks: list[Xfail | None]
    changes: list[tuple[str, ...]]
    run_dirs: list[str]
    modes: list[str]
    limit: float = math.nan
    metric: str = DEFAULT_METRIC


def _mark(reason: Any, strict: Any) -> Xfail | None:
    return Xfail(str(reason), bool(strict)) if reason else None


def _assemble(nights: list[NightInfo], cols: Mapping[str, Any], metric: str
              ) -> tuple[tuple[NightSummary, ...], list[_Rows]]:
    k = _column(cols, "k").astype(np.int64)
    names, statuses = _column(cols, "label"), _column(cols, "status")
    n = len(nights)
    c = {name: _column(cols, name) for name in ("scenario_hash", "v", "lim", "test_changed",
                                                "limits_changed", "sut_changed", "xfail",
                                                "xfail_strict", "mode", "run_dir")}
    passed_w = (statuses == "pass").astype(np.float64)
    expected_w = ((statuses == "fail") & (c["xfail"] != "")).astype(np.float64)
    runs = np.bincount(k, minlength=n) if k.size else np.zeros(n, np.int64)
    passed = np.bincount(k, weights=passed_w, minlength=n) if k.size else np.zeros(n)
    expected = np.bincount(k, weights=expected_w, minlength=n) if k.size else np.zeros(n)
    summaries = tuple(NightSummary(info, int(runs[j]), int(passed[j]), int(expected[j]))
                      for j, info in enumerate(nights))
    out: list[_Rows] = []
    starts: list[int] = (np.flatnonzero(np.r_[True, names[1:] != names[:-1]]).tolist()
                         if names.size else [])
    bounds = [*starts, int(names.size)]
    for a, b in zip(bounds, bounds[1:], strict=False):
        rows = _Rows(str(names[a]), [None] * n, [""] * n, [math.nan] * n, [None] * n,
                     [NO_CHANGE] * n, [""] * n, [""] * n, metric=metric)
        for row in range(a, b):
            j = int(k[row])
            rows.statuses[j], rows.hashes[j] = str(statuses[row]), str(c["scenario_hash"][row]
                                                                       or "")
            rows.values[j] = float(c["v"][row])
            rows.limit = float(c["lim"][row])
            rows.marks[j] = _mark(c["xfail"][row], c["xfail_strict"][row])
            rows.changes[j] = tuple(kind for kind, col in zip(
                CHANGE_KINDS, ("test_changed", "limits_changed", "sut_changed"), strict=True)
                if bool(c[col][row]))
            rows.run_dirs[j] = str(c["run_dir"][row] or "")
            rows.modes[j] = str(c["mode"][row] or "")
        out.append(rows)
    return summaries, out


def _failing_metric(rows: _Rows, metrics: set[str]) -> str:
    """The metric of the scenario's failing criterion in the window: its latest
    failure's first failure mode ('' when it never failed a criterion)."""
    for status, mode in zip(reversed(rows.statuses), reversed(rows.modes), strict=True):
        if status == "fail" and mode in metrics:
            return mode
    return ""


def _own_metrics(con: Any, rows: list[_Rows], metrics: set[str], default: str
                 ) -> list[_Rows]:
    """Each scenario that failed a criterion in the window plots that criterion's
    metric: its values and limit read per metric for those scenarios only."""
    wanted: dict[str, list[_Rows]] = {}
    for r in rows:
        m = _failing_metric(r, metrics)
        if m and m != default and METRIC_NAME.match(m):
            wanted.setdefault(m, []).append(r)
    for m, group in wanted.items():
        by_label = {r.label: r for r in group}
        con.execute("CREATE OR REPLACE TEMP TABLE wanted_labels (label VARCHAR)")
        con.executemany("INSERT INTO wanted_labels VALUES (?)", [[lb] for lb in by_label])
        found = con.execute(
            "WITH r AS (SELECT w.k, r.scenario || CASE WHEN count(*) OVER (PARTITION BY "
            "r.night_id, r.scenario) > 1 THEN ' (' || r.controller || ')' ELSE '' END AS "
            f'label, r."{m}" AS v, map_extract_value(r.limits, \'{m}\') AS lim FROM runs r '
            "JOIN window_nights w USING (night_id)) SELECT label, k, v, lim FROM r "
            "WHERE label IN (SELECT label FROM wanted_labels) ORDER BY label, k").fetchall()
        for r in group:
            r.metric, r.values, r.limit = m, [math.nan] * len(r.values), math.nan
        for label, j, v, lim in found:
            target = by_label[label]
            target.values[int(j)] = math.nan if v is None else float(v)
            target.limit = math.nan if lim is None else float(lim)
    return rows


# ------------------------------------------------------- the first failing night's facts


def _setup(row: tuple[Any, ...]) -> Setup:
    """A :class:`reports.identity.Setup` from a run's stored columns (controller,
    params JSON, code, limits map, test and test-spec digests)."""
    controller, params, code, limits, test, test_spec = row
    try:
        flat = json.loads(params) if params else {}
    except ValueError:
        flat = {}
    return Setup(test=test or "", test_spec=test_spec or "unknown",
                 limits=tuple(sorted((str(m), float(v)) for m, v in (limits or {}).items())),
                 controller=str(controller),
                 params=tuple(sorted(flatten_options(flat).items())) if flat else (),
                 code=code or "")


def _failure(d: Mapping[str, Any]) -> Failure:
    return Failure(criterion=str(d.get("criterion") or ""), metric=str(d["metric"]),
                   value=math.nan if d["value"] is None else float(d["value"]),
                   limit=math.nan if d["limit_value"] is None else float(d["limit_value"]),
                   bound=str(d["bound"]), unit=str(d.get("unit") or ""))


def _change_texts(base: Setup | None, new: Setup, before: NightInfo | None,
                  night: NightInfo) -> tuple[str, ...]:
    """What changed at a night against the night before that the scenario ran in."""
    texts: list[str] = []
    if base is not None:
        change = setup_change(base, new)
        if change.test:
            texts.append("test changed")
        if change.limits:
            texts.append("limits: " + ", ".join(c.text for c in change.limits))
        if change.sut is not None:
            texts.append(f"system under test: {change.sut.text}")
    if before is not None and before.git_revision != night.git_revision:
        texts.append(f"code revision {before.short_revision} → {night.short_revision}")
    return tuple(texts) or ("nothing recorded changed",)


def _with_first_failures(con: Any, nights: list[NightInfo], rows: list[_Rows]
                         ) -> list[ScenarioTrend]:
    """The trends, each failing scenario with its first failing night's failures and
    what changed that night (read for those runs only)."""
    trends = [scenario_trend(r.label, nights, r.statuses, r.hashes, r.values, r.limit,
                             marks=r.marks, changes=r.changes, run_dirs=r.run_dirs,
                             metric=r.metric) for r in rows]
    index = {n.night_id: j for j, n in enumerate(nights)}
    wanted = []
    for t in trends:
        if t.first_failing_night is None:
            continue
        j = index[t.first_failing_night]
        prev = max((i for i in range(j) if t.statuses[i] is not None), default=None)
        wanted.append((t, j, prev))
    # run directories are absolute paths inside each night's output: one run each
    dirs = [d for t, j, p in wanted for d in (t.run_dirs[j], t.run_dirs[p] if p is not None
                                               else "") if d]
    if not dirs:  # nothing to read (no run directory recorded: a v1 night)
        return trends
    con.execute("CREATE OR REPLACE TEMP TABLE wanted_runs (run_dir VARCHAR)")
    con.executemany("INSERT INTO wanted_runs VALUES (?)", [[d] for d in dirs])
    facts = {r[0]: r[1:] for r in con.execute(
        "SELECT run_dir, failures, controller, controller_params, controller_code, limits, "
        "test_hash, test_spec_hash FROM runs WHERE run_dir IN (SELECT run_dir FROM "
        "wanted_runs)").fetchall()}
    out = {id(t): t for t in trends}
    for t, j, prev in wanted:
        now = facts.get(t.run_dirs[j]) if t.run_dirs[j] else None
        if now is None:
            continue
        before = facts.get(t.run_dirs[prev]) if prev is not None and t.run_dirs[prev] else None
        failures = tuple(_failure(f) for f in (now[0] or ()))
        changes = _change_texts(_setup(before[1:]) if before is not None else None,
                                _setup(now[1:]), nights[prev] if prev is not None else None,
                                nights[j])
        out[id(t)] = replace(t, first_failures=failures, first_changes=changes)
    return [out[id(t)] for t in trends]


# ----------------------------------------------------------------------- JSON


def _num(x: float) -> float | str | None:
    if math.isnan(x):
        return None
    return x if math.isfinite(x) else ("inf" if x > 0 else "-inf")


def run_page(run_dir: str) -> str:
    """The report page of a run (its night's ``report-runs/<run>.html``; '' absent)."""
    if not run_dir:
        return ""
    path = Path(run_dir)
    return str(path.parent / "report-runs" / f"{path.name}.html")


def _run_name(t: ScenarioTrend) -> str | None:
    """The run directory's name when every night's is the same (the run page of night
    j is then ``<nights[j].out_dir>/report-runs/<run>.html``), else None."""
    names = {Path(d).name for d in t.run_dirs if d}
    return names.pop() if len(names) == 1 else None


def _scenario_dict(t: ScenarioTrend) -> dict[str, Any]:
    mark = t.marks[-1] if t.marks else None
    run = _run_name(t)
    out: dict[str, Any] = {
        "scenario": t.scenario, "status_now": t.status_now, "failing_now": t.failing_now,
        "known_failure": t.known_failure,
        "xfail": {"reason": mark.reason, "strict": mark.strict} if mark is not None else None,
        "xfail_nights": [j for j, m in enumerate(t.marks) if m is not None],
        "first_failing_night": t.first_failing_night,
        "first_failing_revision": t.first_failing_revision,
        "first_failures": [{"criterion": f.criterion, "metric": f.metric,
                            "value": _num(f.value), "limit": _num(f.limit), "bound": f.bound,
                            "unit": f.unit} for f in t.first_failures],
        "first_changes": list(t.first_changes),
        "last_good_night": t.last_good_night, "last_good_revision": t.last_good_revision,
        "flaky": t.flaky, "flaky_reasons": list(t.flaky_reasons),
        "alternations": t.alternations, "statuses": list(t.statuses),
        # one string per night: the kinds that changed, joined by '+' ('' none)
        "changes": ["+".join(c) for c in t.changes], "run": run,
        "metric": t.metric, "metric_values": [_num(v) for v in t.values],
        "metric_limit": _num(t.limit)}
    if run is None:  # the run directory's name varies: each night's page spelt out
        out["run_pages"] = [run_page(d) or None for d in t.run_dirs]
    return out


def trends_dict(trends: Trends) -> dict[str, Any]:
    """The trends as plain JSON data (``hwyeval history DB --json``; docs/history.md)."""
    return {
        "db": trends.db, "catalog": trends.catalog, "metric": trends.metric,
        "flaky_rule": {"same_hash_and_revision": True,
                       "min_alternations": FLAKY_ALTERNATIONS},
        "change_kinds": list(CHANGE_KINDS),
        "nights": [{"night_id": s.info.night_id, "started_at": s.info.started_at.isoformat(),
                    "git_revision": s.info.git_revision, "git_dirty": s.info.git_dirty,
                    "hwyeval_version": s.info.hwyeval_version, "host": s.info.host,
                    "catalog_sha256": s.info.catalog_sha256, "out_dir": s.info.out_dir,
                    "report": s.info.report or None, "runs": s.runs, "passed": s.passed,
                    "expected_failures": s.expected, "pass_rate": _num(s.pass_rate)}
                   for s in trends.nights],
        "scenarios": [_scenario_dict(t) for t in trends.scenarios],
    }


def trends_json(trends: Trends) -> str:
    return json.dumps(trends_dict(trends), indent=1)
