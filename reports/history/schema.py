"""The history database's schema: its versions and the migrations between them.

Every database records the versions applied in ``schema_version`` (one row per
version, the newest is the schema of the file). :func:`ensure_schema` creates an empty
file at version 1 and applies each migration in order up to :data:`SCHEMA_VERSION`, in
one transaction per step, so a file is always at a whole version. A file written by a
newer hwyeval (a version above :data:`SCHEMA_VERSION`) is refused, never altered.

Version 1 (the first release): ``nights`` (one row per night: id, start, git revision,
hwyeval version, host, catalog path) and ``runs`` (one row per scenario of a night:
scenario, its content hash, controller, status, results.csv's ``failed_criteria`` text,
and one DOUBLE column per metric of results.csv, added as nights bring new metrics).

Version 2: ``nights`` gains ``git_dirty``, ``catalog_sha256``, ``out_dir`` (where the
night's run directories are: ``compare --history`` reads them), ``night_sha256`` (the
content digest that tells a repeated add from a conflicting one) and ``added_at``;
``runs`` gains ``failure_modes`` (the failed criteria's metric names, a list; filled
from ``failed_criteria`` for version-1 rows), ``limits`` (metric -> limit in force,
a MAP) and ``run_dir``.

Version 3: ``nights`` gains ``catalog_id`` (the catalog's identity, which survives a new
checkout: :func:`reports.manifest.catalog_identity`; filled for older nights by
:func:`backfill_catalog_ids`) and ``catalog_origin``; ``runs`` gains the set-up digests
``test_hash``, ``test_spec_hash``, ``limits_hash``, ``sut_hash``
(:mod:`reports.identity`), ``controller_code`` and ``controller_params`` (the SUT's
code hash and resolved options, JSON), ``failures`` (the failed criteria, typed: filled
from ``failed_criteria`` for older rows) and the known-failure mark ``xfail`` /
``xfail_strict``. docs/history.md describes every column.

**Whose file it is.** A database hwyeval creates carries a marker, the table
``hwyeval_meta`` (``key``, ``value``) with ``application_id`` =
:data:`APPLICATION_ID`, written in the transaction that creates its tables. Before any
write (and before reading) :func:`identify` says whose the file is: marked, empty, or an
older unmarked hwyeval file (exactly the tables ``schema_version``, ``nights``,
``runs``), which gets its marker in a transaction of its own before it is migrated.
Anything else (another program's tables, or hwyeval's tables beside them without the
marker) is not hwyeval's: :class:`ForeignDatabase`, and nothing is written into it.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

SCHEMA_VERSION = 3

APPLICATION_ID = "hwyeval.history"
"""``hwyeval_meta.application_id`` of a history database (the marker)."""
META_TABLE = "hwyeval_meta"
# The tables of an hwyeval history database before the marker existed (versions 1-3).
KNOWN_TABLES = frozenset({"schema_version", "nights", "runs"})
MARKER_DDL = (
    f"CREATE TABLE {META_TABLE} (key VARCHAR PRIMARY KEY, value VARCHAR NOT NULL)",
    f"INSERT INTO {META_TABLE} VALUES ('application_id', '{APPLICATION_ID}')",
)

# The columns of ``runs`` that are not metrics (a metric of that name is refused).
RUN_KEY_COLUMNS = ("night_id", "scenario", "scenario_hash", "controller", "status",
                   "failed_criteria", "failure_modes", "limits", "run_dir", "test_hash",
                   "test_spec_hash", "limits_hash", "sut_hash", "controller_code",
                   "controller_params", "failures", "xfail", "xfail_strict")
# The type of ``runs.failures``: one entry per failed criterion (reports.record.Failure)
FAILURE_STRUCT = ("STRUCT(criterion VARCHAR, metric VARCHAR, value DOUBLE, limit_value DOUBLE, "
                  "bound VARCHAR, unit VARCHAR)")
METRIC_NAME = re.compile(r"^[a-z][a-z0-9_]{0,62}$")

V1_DDL = (
    "CREATE TABLE schema_version (version INTEGER NOT NULL PRIMARY KEY, "
    "applied_at TIMESTAMPTZ NOT NULL DEFAULT current_timestamp)",
    "CREATE TABLE nights (night_id VARCHAR PRIMARY KEY, started_at TIMESTAMPTZ NOT NULL, "
    "git_revision VARCHAR NOT NULL, hwyeval_version VARCHAR NOT NULL, host VARCHAR NOT NULL, "
    "catalog VARCHAR NOT NULL)",
    "CREATE TABLE runs (night_id VARCHAR NOT NULL, scenario VARCHAR NOT NULL, "
    "scenario_hash VARCHAR NOT NULL, controller VARCHAR NOT NULL, status VARCHAR NOT NULL, "
    "failed_criteria VARCHAR NOT NULL, PRIMARY KEY (night_id, scenario, controller))",
    "INSERT INTO schema_version (version) VALUES (1)",
)

# version -> the statements that take a file from version - 1 to it
MIGRATIONS: dict[int, tuple[str, ...]] = {
    2: (
        "ALTER TABLE nights ADD COLUMN git_dirty BOOLEAN",
        "ALTER TABLE nights ADD COLUMN catalog_sha256 VARCHAR NOT NULL DEFAULT ''",
        "ALTER TABLE nights ADD COLUMN out_dir VARCHAR NOT NULL DEFAULT ''",
        "ALTER TABLE nights ADD COLUMN night_sha256 VARCHAR NOT NULL DEFAULT ''",
        "ALTER TABLE nights ADD COLUMN added_at TIMESTAMPTZ",
        "ALTER TABLE runs ADD COLUMN failure_modes VARCHAR[]",
        "UPDATE runs SET failure_modes = CASE WHEN failed_criteria = '' THEN []::VARCHAR[] "
        "ELSE list_transform(string_split(failed_criteria, ';'), "
        "lambda f: regexp_extract(f, '^[^=<>]+')) END",
        "ALTER TABLE runs ADD COLUMN limits MAP(VARCHAR, DOUBLE)",
        "ALTER TABLE runs ADD COLUMN run_dir VARCHAR NOT NULL DEFAULT ''",
        "INSERT INTO schema_version (version) VALUES (2)",
    ),
    3: (
        "ALTER TABLE nights ADD COLUMN catalog_id VARCHAR NOT NULL DEFAULT ''",
        "ALTER TABLE nights ADD COLUMN catalog_origin VARCHAR NOT NULL DEFAULT ''",
        *(f"ALTER TABLE runs ADD COLUMN {c} VARCHAR NOT NULL DEFAULT ''"
          for c in ("test_hash", "test_spec_hash", "limits_hash", "sut_hash",
                    "controller_code", "controller_params", "xfail")),
        "ALTER TABLE runs ADD COLUMN xfail_strict BOOLEAN NOT NULL DEFAULT false",
        f"ALTER TABLE runs ADD COLUMN failures {FAILURE_STRUCT}[]",
        # rows stored before v3 keep only failed_criteria's text (metric=value>limit, or
        # <, per failed criterion): only the migrations parse it; a night being added
        # brings its typed failures (reports.history.night)
        "UPDATE runs SET failures = CASE WHEN failed_criteria = '' THEN [] ELSE "
        "list_transform(string_split(failed_criteria, ';'), lambda f: struct_pack("
        "criterion := '', metric := regexp_extract(f, '^[^=]+'), "
        "value := TRY_CAST(regexp_extract(f, '=([^<>]+)[<>]', 1) AS DOUBLE), "
        "limit_value := TRY_CAST(regexp_extract(f, '[<>](.*)$', 1) AS DOUBLE), "
        "bound := CASE WHEN contains(f, '>') THEN 'max' ELSE 'min' END, unit := '')) END",
        "INSERT INTO schema_version (version) VALUES (3)",
    ),
}


def backfill_catalog_ids(con: Any, incoming: str = "") -> None:
    """Version 3's ``nights.catalog_id`` for nights added before it, from their stored
    catalog path: the file's identity when it is still there
    (:func:`reports.manifest.catalog_identity`); else ``incoming`` (the identity of the
    night being added) when the stored path ends with it (the same catalog from a
    checkout since moved or removed); else the file's name. Their origin stays unknown
    ('': never refused as another catalog)."""
    from reports.manifest import catalog_identity

    for (path,) in con.execute("SELECT DISTINCT catalog FROM nights WHERE catalog_id = ''"
                               ).fetchall():
        stored = Path(path)
        if stored.is_file():
            name = catalog_identity(stored).name
        elif incoming and stored.as_posix().endswith("/" + incoming.lstrip("/")):
            name = incoming
        else:
            name = stored.name or str(path)
        con.execute("UPDATE nights SET catalog_id = ? WHERE catalog = ? AND catalog_id = ''",
                    [name, path])


# version -> what is done in Python after its statements, in the same transaction
AFTER_MIGRATION: dict[int, Callable[[Any, str], None]] = {3: backfill_catalog_ids}


class HistoryError(ValueError):
    """A history database or night that cannot be used (the CLI exits 2); the message
    names the file and what was expected."""


class ForeignDatabase(HistoryError):
    """The file is a database of another program (module docstring: whose file it is);
    nothing was written into it (exit 2)."""


EMPTY, MARKED, UNMARKED = "empty", "marked", "unmarked"
"""What :func:`identify` finds: no table at all, hwyeval's marker, or an older hwyeval
file without it."""


def _user_tables(con: Any) -> list[str]:
    """Every table and view of the file, ``schema.name`` outside ``main``; DuckDB's own
    catalog views are not counted."""
    rows = con.execute(
        "SELECT schema_name, table_name FROM duckdb_tables() WHERE database_name = "
        "current_database() UNION ALL SELECT schema_name, view_name FROM duckdb_views() "
        "WHERE database_name = current_database() AND NOT internal").fetchall()
    return sorted(name if schema == "main" else f"{schema}.{name}" for schema, name in rows)


def _marker(con: Any) -> str | None:
    """``hwyeval_meta.application_id`` (None: no such row)."""
    row = con.execute(f"SELECT value FROM {META_TABLE} WHERE key = 'application_id'"
                      ).fetchone()
    return None if row is None else str(row[0])


def identify(con: Any, where: str = "") -> str:
    """Whose file ``con`` is (:data:`EMPTY`, :data:`MARKED`, :data:`UNMARKED`); raises
    :class:`ForeignDatabase` naming ``where`` and the tables found when it is not
    hwyeval's. Reads only."""
    tables = _user_tables(con)
    if not tables:
        return EMPTY
    if META_TABLE in tables:
        found = _marker(con)
        if found == APPLICATION_ID:
            return MARKED
        raise ForeignDatabase(f"{where}: not an hwyeval history database "
                              f"({META_TABLE}.application_id is {found!r}, expected "
                              f"{APPLICATION_ID!r}); nothing was written into it")
    if set(tables) == KNOWN_TABLES:
        return UNMARKED
    shown = ", ".join(tables[:10]) + (f" and {len(tables) - 10} more" if len(tables) > 10
                                      else "")
    raise ForeignDatabase(f"{where}: not an hwyeval history database (it has the tables "
                          f"{shown} and no {META_TABLE} marker); nothing was written into "
                          "it: give hwyeval a file of its own")


def schema_version(con: Any) -> int:
    """The schema version of an open database (0: an empty file)."""
    tables = {row[0] for row in con.execute(
        "SELECT table_name FROM information_schema.tables WHERE table_schema = 'main'"
    ).fetchall()}
    if "schema_version" not in tables:
        if tables & {"nights", "runs"}:
            raise ForeignDatabase("the database has tables nights/runs but no schema_version: "
                                  "not an hwyeval history database")
        return 0
    row = con.execute("SELECT max(version) FROM schema_version").fetchone()
    return int(row[0]) if row is not None and row[0] is not None else 0


def ensure_schema(con: Any, where: str = "", incoming_catalog: str = "") -> int:
    """Bring an open read-write database to :data:`SCHEMA_VERSION`, one transaction per
    version; returns the version it had before (0: it was empty). Raises
    :class:`HistoryError` for a newer file and :class:`ForeignDatabase` for another
    program's (checked before anything is written). ``incoming_catalog``: the catalog
    identity of the night about to be added (:func:`backfill_catalog_ids`)."""
    owner = identify(con, where)
    before = schema_version(con)
    if before > SCHEMA_VERSION:
        raise HistoryError(f"{where}: schema_version {before} was written by a newer hwyeval "
                           f"(this one reads up to {SCHEMA_VERSION}); nothing was changed")
    steps: list[tuple[int, tuple[str, ...]]] = []
    if owner == EMPTY:
        steps.append((1, (*MARKER_DDL, *V1_DDL)))
    elif owner == UNMARKED:  # an older hwyeval file: marked first, then migrated
        steps.append((0, MARKER_DDL))
    steps.extend((v, MIGRATIONS[v]) for v in range(max(before, 1) + 1, SCHEMA_VERSION + 1))
    _apply(con, steps, incoming_catalog)
    return before


def _apply(con: Any, steps: list[tuple[int, tuple[str, ...]]], incoming_catalog: str
           ) -> None:
    """Run each step's statements (and :data:`AFTER_MIGRATION`'s for its version) in one
    transaction per step."""
    for version, statements in steps:
        con.execute("BEGIN TRANSACTION")
        try:
            for sql in statements:
                con.execute(sql)
            after = AFTER_MIGRATION.get(version)
            if after is not None:
                after(con, incoming_catalog)
        except Exception:
            con.execute("ROLLBACK")
            raise
        con.execute("COMMIT")


def metric_columns(con: Any) -> list[str]:
    """The metric columns of ``runs`` (every column that is not a key column), in table
    order."""
    rows = con.execute("SELECT column_name FROM information_schema.columns "
                       "WHERE table_schema = 'main' AND table_name = 'runs' "
                       "ORDER BY ordinal_position").fetchall()
    return [r[0] for r in rows if r[0] not in RUN_KEY_COLUMNS]


def add_metric_columns(con: Any, names: list[str]) -> list[str]:
    """Add a DOUBLE column to ``runs`` for every name not there yet; returns those
    added. Names must match :data:`METRIC_NAME` (results.csv's metric names do)."""
    have = set(metric_columns(con))
    added = []
    for name in names:
        if name in have:
            continue
        if not METRIC_NAME.match(name) or name in RUN_KEY_COLUMNS:
            raise HistoryError(f"metric {name!r}: expected a lower-case identifier "
                               "([a-z][a-z0-9_]*) that is not a key column of runs")
        con.execute(f'ALTER TABLE runs ADD COLUMN "{name}" DOUBLE')
        added.append(name)
    return added
