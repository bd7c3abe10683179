"""Adding nights to the history database and reading them back.

A *night* is one catalog output directory (``hwyeval run --out DIR``): its
``manifest.json`` (who ran what, where, when) and its run directories, read with the
reports' own reader (:func:`reports.tables.collect_runs`; the rows are those of
results.csv). :func:`read_night` turns it into a :class:`NightRecord`,
:func:`add_night` writes that into the database in one transaction.

Writers are serialised by a lock file next to the database (``DB.lock``, an exclusive
``flock``); readers take it shared. A writer waits up to ``wait_s`` for it and then
raises :class:`HistoryLocked` naming the file: the database is never opened by two
writers, so it is never half-written.
"""

from __future__ import annotations

import datetime as _dt
import fcntl
import hashlib
import json
import math
import os
import re
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from reports.history.schema import (
    METRIC_NAME,
    SCHEMA_VERSION,
    HistoryError,
    add_metric_columns,
    ensure_schema,
    metric_columns,
    schema_version,
)
from reports.manifest import MANIFEST, read_manifest
from reports.metrics.criteria import CRITERIA_METRICS
from reports.record import RUN_JSON, iter_run_dirs
from reports.record.meta import STATUSES
from reports.tables import collect_runs, results_frame

RESULTS_CSV = "results.csv"
CONTENT_KEY = "content_sha256"  # RunInfo.scenario_spec key of the scenario content hash
DEFAULT_WAIT_S = 60.0


class HistoryLocked(HistoryError):
    """Another process held the database's lock longer than the wait (exit 2)."""


class NightConflict(HistoryError):
    """A night of that id is in the database with other content (exit 2)."""


@dataclass(frozen=True)
class NightInfo:
    """One row of ``nights``. started_at: when the run started (timezone-aware);
    git_revision: '' when unknown; git_dirty: None when unknown; catalog: the catalog
    file as the manifest names it; catalog_sha256: digest of the night's scenarios
    (name, controller, content hash; see :func:`catalog_digest`); out_dir: the output
    directory (absolute) the night was read from."""

    night_id: str
    started_at: _dt.datetime
    git_revision: str
    hwyeval_version: str
    host: str
    catalog: str
    catalog_sha256: str = ""
    out_dir: str = ""
    git_dirty: bool | None = None

    def __post_init__(self) -> None:
        if not self.night_id:
            raise ValueError("NightInfo.night_id must not be empty")
        if self.started_at.tzinfo is None:
            raise ValueError(f"NightInfo.started_at must carry a timezone, got "
                             f"{self.started_at.isoformat()}")

    @property
    def short_revision(self) -> str:
        return self.git_revision[:10] if self.git_revision else "unknown"


@dataclass(frozen=True)
class NightRecord:
    """A night as the database stores it: ``info`` and one entry per run, aligned.

    metric_names: the metric columns (results.csv's order); values_2d[i, j]: run i's
    value of metric j (NaN absent; ±inf as stored); limits_2d[i, j]: the limit in force
    on metric j for run i (NaN: none). failure_modes[i]: the metric names of run i's
    failed criteria."""

    info: NightInfo
    scenarios: tuple[str, ...]
    scenario_hashes: tuple[str, ...]
    controllers: tuple[str, ...]
    statuses: tuple[str, ...]
    failed_criteria: tuple[str, ...]
    failure_modes: tuple[tuple[str, ...], ...]
    run_dirs: tuple[str, ...]
    metric_names: tuple[str, ...]
    values_2d: np.ndarray = field(repr=False)
    limits_2d: np.ndarray = field(repr=False)

    def __post_init__(self) -> None:
        n = len(self.scenarios)
        for name in ("scenario_hashes", "controllers", "statuses", "failed_criteria",
                     "failure_modes", "run_dirs"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"NightRecord.{name}: {len(getattr(self, name))} entries "
                                 f"for {n} scenarios")
        if len(set(zip(self.scenarios, self.controllers, strict=True))) != n:
            raise ValueError(f"NightRecord {self.info.night_id}: a (scenario, controller) "
                             "appears twice")
        bad = sorted(set(self.statuses) - set(STATUSES))
        if bad:
            raise ValueError(f"NightRecord.statuses: expected one of {STATUSES}, got {bad}")
        shape = (n, len(self.metric_names))
        for name in ("values_2d", "limits_2d"):
            arr = getattr(self, name)
            if arr.shape != shape:
                raise ValueError(f"NightRecord.{name}: shape {arr.shape}, expected {shape}")
        for m in self.metric_names:
            if not METRIC_NAME.match(m):
                raise ValueError(f"NightRecord.metric_names: {m!r} is not an identifier")

    @property
    def n_runs(self) -> int:
        return len(self.scenarios)

    @property
    def sha256(self) -> str:
        """Digest of the night's content (identity, statuses, hashes, values): two adds
        of the same night agree on it, a changed directory does not."""
        h = hashlib.sha256()
        i = self.info
        h.update("\x1f".join([i.night_id, i.started_at.isoformat(), i.git_revision,
                              i.catalog]).encode())
        for cols in (self.scenarios, self.scenario_hashes, self.controllers, self.statuses,
                     self.failed_criteria, self.metric_names):
            h.update("\x1e".join(cols).encode())
        h.update(np.ascontiguousarray(self.values_2d, dtype=np.float64).tobytes())
        return h.hexdigest()


def catalog_digest(scenarios: Sequence[str], controllers: Sequence[str],
                   hashes: Sequence[str]) -> str:
    """sha256 of the sorted ``scenario controller content-hash`` lines: the same for
    two nights that ran the same scenarios with the same content."""
    lines = sorted(f"{s}\t{c}\t{h}" for s, c, h in zip(scenarios, controllers, hashes,
                                                      strict=True))
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()


# results.csv columns that are not metrics (every other column is one, as a DOUBLE)
NOT_METRICS = ("scenario", "controller", "variant", "status", "failed_criteria", "family",
               "run", "robustness_criterion")


@dataclass(frozen=True)
class RunKeys:
    """What a night's row needs from a run's run.json beyond results.csv: the
    scenario's content hash ('' unknown) and the limits in force per metric."""

    scenario_hash: str = ""
    limits: tuple[tuple[str, float], ...] = ()


def run_keys(run_dir: Path) -> RunKeys:
    """:class:`RunKeys` of a run directory, read from its run.json directly (the two
    fields only: the typed reader takes ~20 ms a run, this ~0.3 ms); an unreadable
    file gives empty keys (results.csv already reports that run as 'error')."""
    try:
        data = json.loads((run_dir / RUN_JSON).read_text(encoding="utf-8"))
        spec = data["info"].get("scenario_spec") or {}
        criteria = (data.get("verdict") or {}).get("criteria") or {}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return RunKeys()
    content = spec.get(CONTENT_KEY, "") if isinstance(spec, dict) else ""
    limits = tuple((CRITERIA_METRICS[c][0], float(v)) for c, v in criteria.items()
                   if c in CRITERIA_METRICS and isinstance(v, int | float)
                   and not isinstance(v, bool))
    return RunKeys(content if isinstance(content, str) else "", limits)


def failure_modes_of(failed_criteria: str) -> tuple[str, ...]:
    """The metric names of results.csv's ``failed_criteria`` (``metric=value>limit;…``)."""
    return tuple(re.split(r"[=<>]", f, maxsplit=1)[0] for f in failed_criteria.split(";")
                 if f)


def parse_started(text: str, where: str) -> _dt.datetime:
    """A manifest's ``started`` (ISO 8601) as an aware datetime (naive: UTC)."""
    try:
        t = _dt.datetime.fromisoformat(text)
    except ValueError as exc:
        raise HistoryError(f"{where}: key 'started': expected an ISO 8601 time, got "
                           f"{text!r}") from exc
    return t if t.tzinfo is not None else t.replace(tzinfo=_dt.UTC)


def results_of(out: Path, run_dirs: Sequence[Path]) -> pd.DataFrame:
    """The night's results.csv rows, one per run directory. The file the run wrote is
    read when it covers exactly these run directories and is newer than every
    run.json; otherwise the rows are rebuilt from the run directories with the
    reports' reader (:func:`reports.tables.results_frame`, as ``hwyeval report``)."""
    path = out / RESULTS_CSV
    if path.is_file():
        try:
            # only an empty cell is missing: a scenario named "NA" stays a name
            frame = pd.read_csv(path, keep_default_na=False, na_values=[""])
        except (OSError, ValueError, pd.errors.ParserError):
            frame = None
        if frame is not None and "run" in frame.columns:
            newest = max((d / RUN_JSON).stat().st_mtime for d in run_dirs)
            if (sorted(frame["run"].astype(str)) == sorted(d.name for d in run_dirs)
                    and path.stat().st_mtime >= newest):
                return frame
    return results_frame(collect_runs(out))


def _metric_matrix(frame: pd.DataFrame) -> tuple[tuple[str, ...], np.ndarray]:
    names = tuple(c for c in frame.columns if c not in NOT_METRICS)
    if not names:
        return (), np.zeros((len(frame), 0))
    values = frame[list(names)].apply(pd.to_numeric, errors="coerce")
    return names, values.to_numpy(dtype=np.float64, na_value=np.nan)


def read_night(out_dir: str | Path, night_id: str | None = None) -> NightRecord:
    """The night in ``out_dir``: its manifest, its results.csv rows (see
    :func:`results_of`) and each run's :class:`RunKeys`. ``night_id`` defaults to
    ``<catalog name>@<started>``. Raises :class:`HistoryError` when ``out_dir`` is not
    a directory, has no readable manifest, has not finished, or holds no run."""
    out = Path(out_dir).resolve()
    if not out.is_dir():
        raise HistoryError(f"{out_dir}: no such output directory")
    manifest = read_manifest(out)
    if manifest is None:
        raise HistoryError(f"{out / MANIFEST}: missing or unreadable (expected the manifest "
                           "hwyeval run writes)")
    if not manifest.finished:
        raise HistoryError(f"{out / MANIFEST}: key 'finished' is empty: the run has not "
                           "finished (or was interrupted); add it once it has")
    run_dirs = iter_run_dirs(out)
    if not run_dirs:
        raise HistoryError(f"{out_dir}: holds no run directory (DIR/<scenario>/run.json)")
    frame = results_of(out, run_dirs)
    by_name = {d.name: d for d in run_dirs}
    dirs = [by_name[str(r)] for r in frame["run"]]
    keys = [run_keys(d) for d in dirs]
    names, values = _metric_matrix(frame)
    index = {m: j for j, m in enumerate(names)}
    limits = np.full(values.shape, np.nan)
    for i, k in enumerate(keys):
        for metric, limit in k.limits:
            if metric in index:
                limits[i, index[metric]] = limit
    failed = tuple("" if pd.isna(f) else str(f) for f in frame["failed_criteria"])
    scenarios = tuple(str(s) for s in frame["scenario"])
    controllers = tuple(str(c) for c in frame["controller"])
    hashes = tuple(k.scenario_hash for k in keys)
    prov = manifest.provenance
    info = NightInfo(
        night_id=night_id or f"{manifest.catalog_name}@{manifest.started}",
        started_at=parse_started(manifest.started, str(out / MANIFEST)),
        git_revision=prov.git_sha, git_dirty=prov.git_dirty,
        hwyeval_version=prov.hwyeval_version, host=prov.host, catalog=manifest.catalog,
        catalog_sha256=catalog_digest(scenarios, controllers, hashes), out_dir=str(out))
    try:
        return NightRecord(
            info=info, scenarios=scenarios, scenario_hashes=hashes, controllers=controllers,
            statuses=tuple(str(s) for s in frame["status"]), failed_criteria=failed,
            failure_modes=tuple(failure_modes_of(f) for f in failed),
            run_dirs=tuple(str(d) for d in dirs), metric_names=names, values_2d=values,
            limits_2d=limits)
    except ValueError as exc:
        raise HistoryError(f"{out / RESULTS_CSV}: {exc}") from exc


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


def _runs_table(night: NightRecord, columns: Sequence[str]) -> Any:
    import pyarrow as pa

    index = {m: j for j, m in enumerate(night.metric_names)}
    n = night.n_runs
    limits = []
    for i in range(n):
        row = night.limits_2d[i]
        keys = [m for m, j in index.items() if not math.isnan(row[j])]
        limits.append(list(zip(keys, [float(row[index[k]]) for k in keys], strict=True)))
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
    }
    for name in columns:
        j = index.get(name)
        col = night.values_2d[:, j] if j is not None else np.full(n, np.nan)
        data[name] = pa.array(col, pa.float64(), mask=np.isnan(col))
    return pa.table(data)


def add_night(db: str | Path, night: NightRecord, wait_s: float = DEFAULT_WAIT_S) -> AddResult:
    """Add ``night`` to ``db`` (created, or migrated to the current schema, first).

    The same night (same id, same content digest) a second time changes nothing and
    says so (``added`` False); the same id with other content raises
    :class:`NightConflict`. Everything of a night is written in one transaction."""
    import duckdb

    db = Path(db)
    with locked(db, wait_s):
        con = connect(db, read_only=False)
        try:
            return _add(con, db, night)
        except duckdb.Error as exc:
            raise HistoryError(f"{db}: adding night {night.info.night_id!r} failed, nothing "
                               f"of it was written ({type(exc).__name__}: {exc})") from exc
        finally:
            con.close()


def _add(con: Any, db: Path, night: NightRecord) -> AddResult:
    """:func:`add_night` on an open connection, under the lock."""
    before = ensure_schema(con, str(db))
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
            "added_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, current_timestamp)",
            [i.night_id, i.started_at, i.git_revision, i.hwyeval_version, i.host,
             i.catalog, i.git_dirty, i.catalog_sha256, i.out_dir, night.sha256])
        con.execute("INSERT INTO runs BY NAME SELECT * FROM incoming_runs")
        con.unregister("incoming_runs")
    except Exception:
        con.execute("ROLLBACK")
        raise
    con.execute("COMMIT")
    return AddResult(i.night_id, True, night.n_runs, before, tuple(added))


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
    """The nights (of ``catalog``: its path as the manifest names it, or — unless
    ``exact`` — its stem), in start order."""
    rows = con.execute("SELECT night_id, started_at, git_revision, hwyeval_version, host, "
                       "catalog, catalog_sha256, out_dir, git_dirty FROM nights "
                       "ORDER BY started_at, night_id").fetchall()
    infos = [NightInfo(night_id=r[0], started_at=_aware(r[1]), git_revision=r[2],
                       hwyeval_version=r[3], host=r[4], catalog=r[5], catalog_sha256=r[6],
                       out_dir=r[7], git_dirty=r[8]) for r in rows]
    if catalog is None:
        return infos
    return [i for i in infos if catalog_matches(i.catalog, catalog, exact)]


def catalog_matches(stored: str, wanted: str, exact: bool = False) -> bool:
    """``wanted`` names the stored catalog: the same path (resolved) or, unless
    ``exact``, the same stem."""
    if stored == wanted or (not exact and Path(stored).stem == wanted):
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


BASELINES = ("last", "last-pass")


@dataclass(frozen=True)
class Baseline:
    """The night ``compare --history`` compares against and its output directory."""

    night: NightInfo
    out_dir: Path
    mode: str


def baseline_night(db: str | Path, new_dir: str | Path, mode: str = "last",
                   wait_s: float = DEFAULT_WAIT_S) -> Baseline:
    """The last night of NEW's catalog that started before NEW (``last``), or the last
    such night in which every run passed (``last-pass``); NEW itself is never its own
    baseline. :class:`HistoryError` when NEW has no manifest, no night qualifies, or
    the night's directory no longer exists."""
    if mode not in BASELINES:
        raise HistoryError(f"--baseline {mode!r}: expected one of {', '.join(BASELINES)}")
    new = Path(new_dir).resolve()
    manifest = read_manifest(new)
    if manifest is None:
        raise HistoryError(f"{new / MANIFEST}: missing or unreadable (the catalog of NEW "
                           "picks the baseline night)")
    started = parse_started(manifest.started, str(new / MANIFEST))
    with reading(db, wait_s) as con:
        nights = [n for n in night_infos(con, manifest.catalog, exact=True)
                  if n.started_at < started and Path(n.out_dir) != new]
        if mode == "last-pass":
            nights = [n for n in nights if night_passed(con, n.night_id)]
    if not nights:
        what = "night in which every run passed" if mode == "last-pass" else "night"
        raise HistoryError(f"{db}: no {what} of catalog {manifest.catalog} before "
                           f"{manifest.started}: nothing to compare against")
    night = nights[-1]
    out = Path(night.out_dir)
    if not night.out_dir or not out.is_dir():
        raise HistoryError(f"{db}: night {night.night_id!r} ({mode}) was read from "
                           f"{night.out_dir or '(unknown)'}, which no longer exists: compare "
                           "needs its run directories (compare BASE NEW with a kept copy)")
    return Baseline(night, out, mode)
