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
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from reports.expectation import Xfail
from reports.history.schema import METRIC_NAME, HistoryError, metric_columns
from reports.history.store import DEFAULT_WAIT_S, NightInfo, night_infos, reading
from reports.history.trend_json import run_page, trends_dict, trends_json
from reports.history.trend_model import (
    ABSENT,
    DEFAULT_METRIC,
    FLAKY_ALTERNATIONS,
    NO_CHANGE,
    NightSummary,
    ScenarioTrend,
    Trends,
    flaky_reasons,
    scenario_trend,
)
from reports.identity import CHANGE_KINDS, Setup, flatten_options, setup_change
from reports.record import Failure

__all__ = ["ABSENT", "DEFAULT_METRIC", "FLAKY_ALTERNATIONS", "NO_CHANGE", "NightSummary",
           "ScenarioTrend", "Trends", "flaky_reasons", "load_trends", "run_page",
           "scenario_trend", "trends_dict", "trends_json"]


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
