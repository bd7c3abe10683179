"""Adding nights to the history database and reading them back.

A *night* is one catalog output directory (``hwyeval run --out DIR``): its
``manifest.json`` (who ran what, where, when) and its run directories, read with the
reports' own reader (:func:`reports.tables.collect_runs`, the checks of
:func:`reports.record.load_run` included: a run directory that cannot be read is an
'error' run; the rows are those of results.csv). :func:`read_night` turns it into a
:class:`NightRecord`, :func:`add_night` writes that into the database in one transaction.

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

from reports.expectation import Xfail, xfail_of
from reports.history.schema import (
    METRIC_NAME,
    SCHEMA_VERSION,
    HistoryError,
    add_metric_columns,
    ensure_schema,
    identify,
    metric_columns,
    schema_version,
)
from reports.identity import (
    CODE_KEY,
    CONTENT_KEY,
    CONTROLLER_KEY,
    SetupDigests,
    digests_of_run_json,
)
from reports.manifest import MANIFEST, read_manifest
from reports.metrics.catalogue import CRITERIA_METRICS
from reports.record import RUN_JSON, Failure, iter_run_dirs
from reports.record.codec import RecordError, decode_dataclass
from reports.record.meta import STATUSES
from reports.tables import collect_runs, results_frame

RESULTS_CSV = "results.csv"
DEFAULT_WAIT_S = 60.0


class HistoryLocked(HistoryError):
    """Another process held the database's lock longer than the wait (exit 2)."""


class NightConflict(HistoryError):
    """A night of that id is in the database with other content (exit 2)."""


class CatalogClash(HistoryError):
    """Another catalog of the same name (another origin) is in the database (exit 2)."""


class NoBaseline(HistoryError):
    """No earlier night of the catalog: nothing to compare against (not an error: the
    first night of a history)."""


@dataclass(frozen=True)
class NightInfo:
    """One row of ``nights``. started_at: when the run started (timezone-aware);
    git_revision: '' when unknown; git_dirty: None when unknown; catalog: the catalog
    file as the manifest names it; catalog_id / catalog_origin: its identity
    (:func:`reports.manifest.catalog_identity`: what nights are grouped by; '' only
    before a database is migrated); catalog_sha256: digest of the night's scenarios
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
    catalog_id: str = ""
    catalog_origin: str = ""

    def __post_init__(self) -> None:
        if not self.night_id:
            raise ValueError("NightInfo.night_id must not be empty")
        if self.started_at.tzinfo is None:
            raise ValueError(f"NightInfo.started_at must carry a timezone, got "
                             f"{self.started_at.isoformat()}")

    @property
    def short_revision(self) -> str:
        return self.git_revision[:10] if self.git_revision else "unknown"

    @property
    def catalog_key(self) -> str:
        """What the night's catalog is known by: its identity (its path before a
        database is migrated)."""
        return self.catalog_id or self.catalog

    @property
    def report(self) -> str:
        """The night's report.html ('' when its output directory is unknown)."""
        return str(Path(self.out_dir) / "report.html") if self.out_dir else ""


@dataclass(frozen=True)
class RunFacts:
    """What the history keeps of a run beyond results.csv, read from its run.json:
    ``scenario_hash`` (the content hash, '' unknown), ``limits`` (metric -> limit in
    force), the set-up digests (:class:`reports.identity.SetupDigests`),
    ``controller_code`` (its code hash) and ``controller_params`` (its resolved options,
    canonical JSON), the typed ``failures`` and the known-failure mark."""

    scenario_hash: str = ""
    limits: tuple[tuple[str, float], ...] = ()
    digests: SetupDigests = field(default_factory=lambda: SetupDigests("", "", "", ""))
    controller_code: str = ""
    controller_params: str = ""
    failures: tuple[Failure, ...] = ()
    xfail: Xfail | None = None


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
    facts: tuple[RunFacts, ...] = ()  # per run (empty: none known, e.g. built by hand)

    def __post_init__(self) -> None:
        n = len(self.scenarios)
        if not self.facts:
            object.__setattr__(self, "facts", (RunFacts(),) * n)
        for name in ("scenario_hashes", "controllers", "statuses", "failed_criteria",
                     "failure_modes", "run_dirs", "facts"):
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
        marks = [f.xfail.text if f.xfail is not None else "" for f in self.facts]
        if any(marks):  # a night without marks keeps the digest it had before v3
            h.update("\x1e".join(marks).encode())
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


def _failures(raw: Any, path: Path) -> tuple[Failure, ...]:
    if not isinstance(raw, list):
        return ()
    try:
        return tuple(decode_dataclass(Failure, f, path, "verdict.failures") for f in raw)
    except RecordError:
        return ()


def run_facts(run_dir: Path) -> RunFacts:
    """:class:`RunFacts` of a run directory, read from its run.json directly (these
    fields only: the typed reader takes ~20 ms a run, this well under 1 ms); an
    unreadable file gives empty facts (results.csv already reports that run as
    'error')."""
    path = run_dir / RUN_JSON
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        info = data["info"]
        spec = info.get("scenario_spec") or {}
        verdict = data.get("verdict") or {}
        criteria = verdict.get("criteria") or {}
        content = spec.get(CONTENT_KEY, "")
        params = info.get("controller_params") or info.get("controller_options") or {}
        code = spec.get(CONTROLLER_KEY) or spec.get(CODE_KEY) or ""
        digests = digests_of_run_json(info, criteria)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return RunFacts()
    limits = tuple((CRITERIA_METRICS[c][0], float(v)) for c, v in criteria.items()
                   if c in CRITERIA_METRICS and isinstance(v, int | float)
                   and not isinstance(v, bool))
    return RunFacts(scenario_hash=content if isinstance(content, str) else "", limits=limits,
                    digests=digests, controller_code=str(code),
                    controller_params=json.dumps(params, sort_keys=True, allow_nan=True,
                                                 default=str),
                    failures=_failures(verdict.get("failures"), path),
                    xfail=xfail_of(spec if isinstance(spec, dict) else None))


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
    """The night's results.csv rows, one per run directory. Every run directory is
    read with the reports' reader (:func:`reports.tables.collect_runs`, through
    :func:`reports.record.load_run`: a directory that cannot be read, a file changed
    or corrupt since the run wrote it, is an 'error' run). When every one can be read,
    the file the run wrote is used if it covers exactly these run directories and is
    newer than every run.json; otherwise the rows are rebuilt from the entries
    (:func:`reports.tables.results_frame`, as ``hwyeval report``)."""
    entries = collect_runs(out)
    frame = _written_results(out, run_dirs)
    if frame is not None and not any(e.unreadable for e in entries):
        return frame
    return results_frame(entries)


def _written_results(out: Path, run_dirs: Sequence[Path]) -> pd.DataFrame | None:
    """results.csv as the run wrote it, when it covers exactly ``run_dirs`` and is newer
    than every run.json (None otherwise)."""
    path = out / RESULTS_CSV
    if not path.is_file():
        return None
    try:
        # only an empty cell is missing: a scenario named "NA" stays a name
        frame = pd.read_csv(path, keep_default_na=False, na_values=[""])
    except (OSError, ValueError, pd.errors.ParserError):
        return None
    if "run" not in frame.columns:
        return None
    newest = max((d / RUN_JSON).stat().st_mtime for d in run_dirs)
    if (sorted(frame["run"].astype(str)) == sorted(d.name for d in run_dirs)
            and path.stat().st_mtime >= newest):
        return frame
    return None


def _metric_matrix(frame: pd.DataFrame) -> tuple[tuple[str, ...], np.ndarray]:
    names = tuple(c for c in frame.columns if c not in NOT_METRICS)
    if not names:
        return (), np.zeros((len(frame), 0))
    values = frame[list(names)].apply(pd.to_numeric, errors="coerce")
    return names, values.to_numpy(dtype=np.float64, na_value=np.nan)


def read_night(out_dir: str | Path, night_id: str | None = None,
               catalog_name: str | None = None) -> NightRecord:
    """The night in ``out_dir``: its manifest, its results.csv rows (see
    :func:`results_of`) and each run's :class:`RunFacts`. ``night_id`` defaults to
    ``<catalog name>@<started>``; ``catalog_name`` (``--catalog-name``) replaces the
    catalog's identity (the manifest's). Raises :class:`HistoryError` when ``out_dir``
    is not a directory, has no readable manifest, has not finished, or holds no run."""
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
    facts = tuple(run_facts(d) for d in dirs)
    names, values = _metric_matrix(frame)
    index = {m: j for j, m in enumerate(names)}
    limits = np.full(values.shape, np.nan)
    for i, k in enumerate(facts):
        for metric, limit in k.limits:
            if metric in index:
                limits[i, index[metric]] = limit
    failed = tuple("" if pd.isna(f) else str(f) for f in frame["failed_criteria"])
    scenarios = tuple(str(s) for s in frame["scenario"])
    controllers = tuple(str(c) for c in frame["controller"])
    hashes = tuple(k.scenario_hash for k in facts)
    prov = manifest.provenance
    identity = manifest.identity()
    info = NightInfo(
        night_id=night_id or f"{manifest.catalog_name}@{manifest.started}",
        started_at=parse_started(manifest.started, str(out / MANIFEST)),
        git_revision=prov.git_sha, git_dirty=prov.git_dirty,
        hwyeval_version=prov.hwyeval_version, host=prov.host, catalog=manifest.catalog,
        catalog_sha256=catalog_digest(scenarios, controllers, hashes), out_dir=str(out),
        catalog_id=catalog_name or identity.name, catalog_origin=identity.origin)
    try:
        return NightRecord(
            info=info, scenarios=scenarios, scenario_hashes=hashes, controllers=controllers,
            statuses=tuple(str(s) for s in frame["status"]), failed_criteria=failed,
            failure_modes=tuple(failure_modes_of(f) for f in failed),
            run_dirs=tuple(str(d) for d in dirs), metric_names=names, values_2d=values,
            limits_2d=limits, facts=facts)
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
