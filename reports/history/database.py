"""The history database's lock and its readers.

Writers are serialised by a lock file next to the database (``DB.lock``, an exclusive
``flock``); readers take it shared. A writer waits up to ``wait_s`` for it and then
raises :class:`HistoryLocked` naming the file: the database is never opened by two
writers, so it is never half-written. Reading: :func:`reading` (a read-only
connection under the shared lock), :func:`run_sql`, :func:`night_infos`.
"""

from __future__ import annotations

import datetime as _dt
import fcntl
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from reports.history.night import NightInfo, parse_started
from reports.history.schema import (
    SCHEMA_VERSION,
    HistoryError,
    identify,
    schema_version,
)

DEFAULT_WAIT_S = 60.0


class HistoryLocked(HistoryError):
    """Another process held the database's lock longer than the wait (exit 2)."""


# ----------------------------------------------------------------------- the lock


def lock_path(db: Path) -> Path:
    return db.with_name(db.name + ".lock")


@contextmanager
def locked(db: Path, wait_s: float = DEFAULT_WAIT_S, shared: bool = False) -> Iterator[None]:
    """Hold ``DB.lock`` (exclusive for a writer, shared for a reader), waiting up to
    ``wait_s`` [s] for it; :class:`HistoryLocked` when it does not come."""
    path = lock_path(db)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        mode = fcntl.LOCK_SH if shared else fcntl.LOCK_EX
        deadline = time.monotonic() + wait_s
        while True:
            try:
                fcntl.flock(fd, mode | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    raise HistoryLocked(
                        f"{db}: another hwyeval process holds {path} (waited {wait_s:g} s); "
                        "try again when it has finished, or raise --wait") from None
                time.sleep(0.05)
        yield
    finally:
        os.close(fd)  # releases the lock


def connect(db: Path, read_only: bool) -> Any:
    """A DuckDB connection (its own errors, e.g. a file another program holds, become
    :class:`HistoryError` naming the file)."""
    import duckdb

    try:
        return duckdb.connect(str(db), read_only=read_only)
    except duckdb.Error as exc:
        raise HistoryError(f"{db}: cannot open the history database ({exc})") from exc


# ----------------------------------------------------------------------- reading


@contextmanager
def reading(db: str | Path, wait_s: float = DEFAULT_WAIT_S) -> Iterator[Any]:
    """A read-only connection to an existing, current-schema database, under the
    shared lock."""
    db = Path(db)
    if not db.is_file():
        raise HistoryError(f"{db}: no such history database (hwyeval history add DB RUNDIR "
                           "creates it)")
    with locked(db, wait_s, shared=True):
        con = connect(db, read_only=True)
        try:
            identify(con, str(db))  # another program's file: said so, not "version 0"
            version = schema_version(con)
            if version != SCHEMA_VERSION:
                raise HistoryError(
                    f"{db}: schema_version {version}, this hwyeval reads {SCHEMA_VERSION} "
                    "(adding a night migrates an older file)")
            yield con
        finally:
            con.close()


@dataclass(frozen=True)
class QueryResult:
    """Columns and rows of an ad-hoc query."""

    columns: tuple[str, ...]
    rows: tuple[tuple[Any, ...], ...]


def run_sql(db: str | Path, sql: str, wait_s: float = DEFAULT_WAIT_S) -> QueryResult:
    """The result of ``sql`` on a read-only connection without file access (a write,
    or reading or writing another file, is refused by DuckDB); a bad query is a
    :class:`HistoryError` with DuckDB's message."""
    import duckdb

    with reading(db, wait_s) as con:
        # nor does it touch other files (COPY ... TO, ATTACH, read_csv): read-only means
        # read-only, and the setting cannot be switched back from the query
        con.execute("SET enable_external_access = false")
        con.execute("SET lock_configuration = true")
        try:
            cur = con.execute(sql)
            rows = cur.fetchall()
        except duckdb.Error as exc:
            raise HistoryError(f"--sql: {exc}") from exc
        columns = tuple(d[0] for d in (cur.description or ()))
    return QueryResult(columns, tuple(tuple(r) for r in rows))


def night_infos(con: Any, catalog: str | None = None, exact: bool = False
                ) -> list[NightInfo]:
    """The nights (of ``catalog``: see :func:`catalog_matches`), in start order."""
    rows = con.execute("SELECT night_id, started_at, git_revision, hwyeval_version, host, "
                       "catalog, catalog_sha256, out_dir, git_dirty, catalog_id, "
                       "catalog_origin FROM nights ORDER BY started_at, night_id").fetchall()
    infos = [NightInfo(night_id=r[0], started_at=_aware(r[1]), git_revision=r[2],
                       hwyeval_version=r[3], host=r[4], catalog=r[5], catalog_sha256=r[6],
                       out_dir=r[7], git_dirty=r[8], catalog_id=r[9], catalog_origin=r[10])
             for r in rows]
    if catalog is None:
        return infos
    return [i for i in infos if catalog_matches(i, catalog, exact)]


def catalog_matches(night: NightInfo, wanted: str, exact: bool = False) -> bool:
    """``wanted`` names the night's catalog: its identity, or (``--catalog``'s
    conveniences, unless ``exact``) the path it was run from (resolved) or its stem."""
    if night.catalog_key == wanted:
        return True
    if exact:
        return False
    stored = night.catalog
    if stored == wanted or Path(stored).stem == wanted:
        return True
    try:
        return Path(stored).resolve() == Path(wanted).resolve()
    except OSError:
        return False


def _aware(t: Any) -> _dt.datetime:
    if isinstance(t, _dt.datetime):
        return t if t.tzinfo is not None else t.replace(tzinfo=_dt.UTC)
    return parse_started(str(t), "nights.started_at")


def night_passed(con: Any, night_id: str) -> bool:
    """Whether every run of the night passed."""
    row = con.execute("SELECT count(*) FILTER (WHERE status <> 'pass'), count(*) FROM runs "
                      "WHERE night_id = ?", [night_id]).fetchone()
    return row is not None and row[1] > 0 and row[0] == 0
