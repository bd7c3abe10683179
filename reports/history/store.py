"""Adding nights to the history database and reading them back.

A *night* is one catalog output directory (``hwyeval run --out DIR``): its
``manifest.json`` (who ran what, where, when) and its run directories, read with the
reports' own reader (:func:`reports.tables.collect_runs`, the checks of
:func:`reports.record.load_run` included: a run directory that cannot be read is an
'error' run). :func:`read_night` turns their typed records into a :class:`NightRecord`
(the rows results.csv has, built from the verdicts, not read back from the file);
:func:`add_night` writes that into the database in one transaction.

Writers are serialised by a lock file next to the database (``DB.lock``, an exclusive
``flock``); readers take it shared. A writer waits up to ``wait_s`` for it and then
raises :class:`HistoryLocked` naming the file: the database is never opened by two
writers, so it is never half-written.

Reading a night is :mod:`reports.history.night`, the lock and the readers
:mod:`reports.history.database`; this module adds nights and finds the baseline, and
re-exports their names.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from reports.history.database import (
    DEFAULT_WAIT_S,
    HistoryLocked,
    QueryResult,
    catalog_matches,
    connect,
    lock_path,
    locked,
    night_infos,
    night_passed,
    reading,
    run_sql,
)
from reports.history.night import (
    NOT_METRICS,
    NightInfo,
    NightRecord,
    RunFacts,
    catalog_digest,
    entry_facts,
    parse_started,
    read_night,
    run_facts,
)
from reports.history.schema import (
    HistoryError,
    add_metric_columns,
    ensure_schema,
    metric_columns,
)
from reports.manifest import MANIFEST, read_manifest

__all__ = ["AddResult", "BASELINES", "Baseline", "CatalogClash", "DEFAULT_WAIT_S",
           "HistoryLocked", "NOT_METRICS", "NightConflict", "NightInfo", "NightRecord",
           "NoBaseline", "QueryResult", "RunFacts", "add_night", "baseline_night",
           "catalog_digest", "catalog_matches", "connect", "entry_facts", "lock_path",
           "locked", "night_infos", "night_passed", "parse_started", "read_night", "reading",
           "run_facts", "run_sql"]


class NightConflict(HistoryError):
    """A night of that id is in the database with other content (exit 2)."""


class CatalogClash(HistoryError):
    """Another catalog of the same name (another origin) is in the database (exit 2)."""


class NoBaseline(HistoryError):
    """No earlier night of the catalog: nothing to compare against (not an error: the
    first night of a history)."""


# ----------------------------------------------------------------------- adding


@dataclass(frozen=True)
class AddResult:
    """What :func:`add_night` did: ``added`` False when the same night was there
    already (nothing changed); migrated_from: the schema version the file had
    (0: new file; equal to the current version: no migration)."""

    night_id: str
    added: bool
    n_runs: int
    migrated_from: int
    new_metric_columns: tuple[str, ...] = ()


_FAILURE_TYPE_FIELDS = (("criterion", "string"), ("metric", "string"), ("value", "float64"),
                        ("limit_value", "float64"), ("bound", "string"), ("unit", "string"))


def _runs_table(night: NightRecord, columns: Sequence[str]) -> Any:
    import pyarrow as pa

    index = {m: j for j, m in enumerate(night.metric_names)}
    n = night.n_runs
    limits = []
    for i in range(n):
        row = night.limits_2d[i]
        keys = [m for m, j in index.items() if not math.isnan(row[j])]
        limits.append(list(zip(keys, [float(row[index[k]]) for k in keys], strict=True)))
    facts = night.facts
    failure = pa.struct([(name, getattr(pa, kind)()) for name, kind in _FAILURE_TYPE_FIELDS])
    data: dict[str, Any] = {
        "night_id": pa.array([night.info.night_id] * n, pa.string()),
        "scenario": pa.array(night.scenarios, pa.string()),
        "scenario_hash": pa.array(night.scenario_hashes, pa.string()),
        "controller": pa.array(night.controllers, pa.string()),
        "status": pa.array(night.statuses, pa.string()),
        "failed_criteria": pa.array(night.failed_criteria, pa.string()),
        "failure_modes": pa.array([list(f) for f in night.failure_modes],
                                  pa.list_(pa.string())),
        "limits": pa.array(limits, pa.map_(pa.string(), pa.float64())),
        "run_dir": pa.array(night.run_dirs, pa.string()),
        "test_hash": pa.array([f.digests.test for f in facts], pa.string()),
        "test_spec_hash": pa.array([f.digests.test_spec for f in facts], pa.string()),
        "limits_hash": pa.array([f.digests.limits for f in facts], pa.string()),
        "sut_hash": pa.array([f.digests.sut for f in facts], pa.string()),
        "controller_code": pa.array([f.controller_code for f in facts], pa.string()),
        "controller_params": pa.array([f.controller_params for f in facts], pa.string()),
        "failures": pa.array([[{"criterion": x.criterion, "metric": x.metric, "value": x.value,
                                "limit_value": x.limit, "bound": x.bound, "unit": x.unit}
                               for x in f.failures] for f in facts], pa.list_(failure)),
        "xfail": pa.array([f.xfail.reason if f.xfail is not None else "" for f in facts],
                          pa.string()),
        "xfail_strict": pa.array([bool(f.xfail is not None and f.xfail.strict)
                                  for f in facts], pa.bool_()),
    }
    for name in columns:
        j = index.get(name)
        col = night.values_2d[:, j] if j is not None else np.full(n, np.nan)
        data[name] = pa.array(col, pa.float64(), mask=np.isnan(col))
    return pa.table(data)


def add_night(db: str | Path, night: NightRecord, wait_s: float = DEFAULT_WAIT_S,
              named: bool = False) -> AddResult:
    """Add ``night`` to ``db`` (created, or migrated to the current schema, first). A
    file that is not hwyeval's raises :class:`~reports.history.schema.ForeignDatabase`
    before anything is written into it.

    The same night (same id, same content digest) a second time changes nothing and
    says so (``added`` False); the same id with other content raises
    :class:`NightConflict`. A night whose catalog identity is already in the database
    from another origin (another repository, or another file outside git) raises
    :class:`CatalogClash`, unless the identity was ``named`` explicitly
    (``--catalog-name``). Everything of a night is written in one transaction."""
    import duckdb

    db = Path(db)
    with locked(db, wait_s):
        con = connect(db, read_only=False)
        try:
            return _add(con, db, night, named)
        except duckdb.Error as exc:
            raise HistoryError(f"{db}: adding night {night.info.night_id!r} failed, nothing "
                               f"of it was written ({type(exc).__name__}: {exc})") from exc
        finally:
            con.close()


def _check_origin(con: Any, db: Path, info: NightInfo) -> None:
    """:class:`CatalogClash` when the catalog's identity is in the database from another
    known origin."""
    if not info.catalog_origin:
        return
    row = con.execute("SELECT catalog, catalog_origin FROM nights WHERE catalog_id = ? AND "
                      "catalog_origin <> '' AND catalog_origin <> ? ORDER BY started_at DESC "
                      "LIMIT 1", [info.catalog_id, info.catalog_origin]).fetchone()
    if row is not None:
        raise CatalogClash(
            f"{db}: catalog {info.catalog_id!r} of {info.catalog} (origin "
            f"{info.catalog_origin[:24]}) is another catalog than the {info.catalog_id!r} "
            f"in the database (from {row[0]}, origin {row[1][:24]}); nothing was added: give "
            "--catalog-name OTHER to keep it apart, or --catalog-name "
            f"{info.catalog_id} to file it with them")


def _add(con: Any, db: Path, night: NightRecord, named: bool = False) -> AddResult:
    """:func:`add_night` on an open connection, under the lock."""
    before = ensure_schema(con, str(db), night.info.catalog_key)
    if not named:
        _check_origin(con, db, night.info)
    row = con.execute("SELECT night_sha256 FROM nights WHERE night_id = ?",
                      [night.info.night_id]).fetchone()
    if row is not None:
        if row[0] == night.sha256:
            return AddResult(night.info.night_id, False, night.n_runs, before)
        raise NightConflict(
            f"{db}: night {night.info.night_id!r} is in the database with other "
            f"content (from {night.info.out_dir}); nothing was changed (give "
            "another --night-id to keep both)")
    con.execute("BEGIN TRANSACTION")
    try:
        added = add_metric_columns(con, list(night.metric_names))
        con.register("incoming_runs", _runs_table(night, metric_columns(con)))
        i = night.info
        con.execute(
            "INSERT INTO nights (night_id, started_at, git_revision, hwyeval_version, "
            "host, catalog, git_dirty, catalog_sha256, out_dir, night_sha256, "
            "added_at, catalog_id, catalog_origin) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
            "current_timestamp, ?, ?)",
            [i.night_id, i.started_at, i.git_revision, i.hwyeval_version, i.host,
             i.catalog, i.git_dirty, i.catalog_sha256, i.out_dir, night.sha256,
             i.catalog_key, i.catalog_origin])
        con.execute("INSERT INTO runs BY NAME SELECT * FROM incoming_runs")
        con.unregister("incoming_runs")
    except Exception:
        con.execute("ROLLBACK")
        raise
    con.execute("COMMIT")
    return AddResult(i.night_id, True, night.n_runs, before, tuple(added))


BASELINES = ("last", "last-pass")


@dataclass(frozen=True)
class Baseline:
    """The night ``compare --history`` compares against and its output directory."""

    night: NightInfo
    out_dir: Path
    mode: str


def baseline_night(db: str | Path, new_dir: str | Path, mode: str = "last",
                   wait_s: float = DEFAULT_WAIT_S) -> Baseline:
    """The last night of NEW's catalog (its identity, :meth:`Manifest.identity`) that
    started before NEW (``last``), or the last such night in which every run passed
    (``last-pass``); NEW itself is never its own baseline. :class:`NoBaseline` when the
    catalog has no earlier night at all (its first night); :class:`HistoryError` when
    NEW has no manifest, no earlier night passed (``last-pass``), or the night's
    directory no longer exists."""
    if mode not in BASELINES:
        raise HistoryError(f"--baseline {mode!r}: expected one of {', '.join(BASELINES)}")
    new = Path(new_dir).resolve()
    manifest = read_manifest(new)
    if manifest is None:
        raise HistoryError(f"{new / MANIFEST}: missing or unreadable (the catalog of NEW "
                           "picks the baseline night)")
    started = parse_started(manifest.started, str(new / MANIFEST))
    catalog = manifest.identity().name
    with reading(db, wait_s) as con:
        earlier = [n for n in night_infos(con, catalog, exact=True)
                   if n.started_at < started and Path(n.out_dir) != new]
        nights = [n for n in earlier if night_passed(con, n.night_id)] \
            if mode == "last-pass" else earlier
    if not earlier:
        raise NoBaseline(f"{db}: no earlier night of catalog {catalog!r} before "
                         f"{manifest.started}: nothing to compare against")
    if not nights:  # earlier nights, none passed: a gate on last-pass has no baseline
        raise HistoryError(f"{db}: no earlier night of catalog {catalog!r} in which every "
                           f"run passed ({len(earlier)} earlier nights): nothing to compare "
                           "against (--baseline last compares with the night before)")
    night = nights[-1]
    out = Path(night.out_dir)
    if not night.out_dir or not out.is_dir():
        raise HistoryError(f"{db}: night {night.night_id!r} ({mode}) was read from "
                           f"{night.out_dir or '(unknown)'}, which no longer exists: compare "
                           "needs its run directories (compare BASE NEW with a kept copy)")
    return Baseline(night, out, mode)
