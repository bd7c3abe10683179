"""``hwyeval history``: many nights in one DuckDB database (docs/history.md).

    hwyeval history add DB RUNDIR... [--night-id ID] [--catalog-name NAME] [--wait SECONDS]
    hwyeval history DB [--out DIR] [--json] [--metric NAME] [--catalog C] [--nights N]
    hwyeval history DB --sql "SELECT ..."

``add`` adds each RUNDIR (a finished ``hwyeval run --out`` directory) as one night,
creating the database or migrating it to the current schema first; a night that is
there already with the same content is left as it is (said so, exit 0), one with the
same id and other content is refused (exit 2), and so is a night of another catalog
that has the same name as one in the database (another repository, or another file
outside git) unless ``--catalog-name`` names its catalog. The second form writes the trend page
``DIR/history.html`` and/or prints its content as JSON; ``--sql`` prints the result
of a query on a read-only connection. Exit codes: 0 done, 2 bad input (a missing or
unfinished directory, a conflicting night, a database locked longer than ``--wait``,
an unknown metric or catalog, a bad query); nothing already in the database is lost.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from suite.cli.common import (
    EXIT_OK,
    Output,
    UsageError,
    plain_help,
    positive_int,
    positive_seconds,
    writing_to,
)

DEFAULT_WAIT_S = 60.0
USAGE = ("hwyeval history add DB RUNDIR... [--night-id ID] [--catalog-name NAME] [--wait S]\n"
         "       hwyeval history DB [--out DIR] [--json] [--metric M] [--catalog C] "
         "[--nights N]\n       hwyeval history DB --sql QUERY")


def add_history_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``history`` sub-command's arguments."""
    s = sub.add_parser("history", help="many nights in a DuckDB database: 'history add DB "
                                       "RUNDIR...', the trend page, --json, --sql",
                       description=plain_help(__doc__),
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       usage=USAGE)
    s.add_argument("words", nargs="+", metavar="DB",
                   help="the database file; 'add DB RUNDIR...' adds nights to it")
    s.add_argument("--out", default=None, help="write the trend page DIR/history.html")
    s.add_argument("--json", action="store_true", help="print the trends as JSON")
    s.add_argument("--sql", default=None, help="print the result of a read-only query")
    s.add_argument("--metric", default=None,
                   help="the metric of the sparklines (default min_ttc_s)")
    s.add_argument("--catalog", default=None,
                   help="the catalog (path or name) to show (default: the newest night's)")
    s.add_argument("--nights", type=positive_int, default=None,
                   help="only the last N nights (default: all)")
    s.add_argument("--night-id", default=None,
                   help="add: the night's id (default: <catalog name>@<started>; one RUNDIR)")
    s.add_argument("--catalog-name", default=None, metavar="NAME",
                   help="add: the catalog the nights belong to (default: the catalog's "
                        "[catalog] name, else its path in its git repository, else its "
                        "file name); given, another catalog of that name is not refused")
    s.add_argument("--wait", type=positive_seconds, default=DEFAULT_WAIT_S, metavar="SECONDS",
                   help="how long to wait for another writer (default 60 s)")
    s.set_defaults(func=cmd_history)


def add_nights(db: Path, out_dirs: list[Path], night_id: str | None, wait_s: float,
               text: Output, catalog_name: str | None = None) -> None:
    """Add each output directory as a night, one line per night saying what was done;
    the first that cannot be added stops with a UsageError (those before it stay)."""
    from reports.history import HistoryError, add_night, read_night

    if catalog_name is not None and not catalog_name.strip():
        raise UsageError("--catalog-name: expected a non-empty name")
    for out in out_dirs:
        try:
            result = add_night(db, read_night(out, night_id, catalog_name), wait_s,
                               named=catalog_name is not None)
        except HistoryError as exc:
            raise UsageError(str(exc)) from exc
        if result.migrated_from == 0:
            text.line(f"{db}: new history database")
        elif result.migrated_from != _schema():
            text.line(f"{db}: schema migrated from v{result.migrated_from} to v{_schema()}")
        if result.added:
            extra = (f", new metric columns: {', '.join(result.new_metric_columns)}"
                     if result.new_metric_columns and result.migrated_from else "")
            text.line(f"added night {result.night_id} ({result.n_runs} runs from {out}){extra}")
        else:
            text.line(f"night {result.night_id} is in {db} already with the same content: "
                      "unchanged")


def _schema() -> int:
    from reports.history import SCHEMA_VERSION

    return SCHEMA_VERSION


def _cell(value: Any) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    return "NULL" if value is None else str(value)


def print_query(db: Path, sql: str, wait_s: float, text: Output) -> None:
    """The query's columns and rows, tab-separated; no statement at all ("", ";", a
    comment) is a UsageError."""
    import duckdb

    from reports.history import HistoryError, run_sql

    try:
        empty = not duckdb.extract_statements(sql)
    except duckdb.Error:  # a syntax error: run_sql reports it with DuckDB's message
        empty = False
    if empty:
        raise UsageError(f"--sql {sql!r}: no SQL statement; give a query (SELECT ...)")
    try:
        result = run_sql(db, sql, wait_s)
    except HistoryError as exc:
        raise UsageError(str(exc)) from exc
    text.line("\t".join(result.columns))
    for row in result.rows:
        text.line("\t".join(_cell(v) for v in row))
        if text.closed:
            break


def cmd_history(args: argparse.Namespace) -> int:
    words: list[str] = args.words
    text = Output()
    if words[0] == "add":
        if len(words) < 3:
            raise UsageError("history add: expected DB RUNDIR... (the database file and at "
                             "least one output directory)")
        if args.night_id and len(words) > 3:
            raise UsageError("history add: --night-id names one night; give one RUNDIR")
        add_nights(Path(words[1]), [Path(w) for w in words[2:]], args.night_id, args.wait,
                   text, args.catalog_name)
        return EXIT_OK
    if len(words) != 1:
        raise UsageError(f"history: expected one DB (or 'add DB RUNDIR...'), got {words}")
    db = Path(words[0])
    if args.sql is not None:
        print_query(db, args.sql, args.wait, text)
        return EXIT_OK
    if not args.out and not args.json:
        raise UsageError("history DB: give --out DIR (the trend page), --json or --sql")
    show_trends(db, args, text)
    return EXIT_OK


def show_trends(db: Path, args: argparse.Namespace, text: Output) -> None:
    """The trend page (``--out``) and/or its JSON (``--json``)."""
    from reports.history import DEFAULT_METRIC, HistoryError, load_trends, trends_json
    from reports.history import write_history_page as write_page

    try:
        trends = load_trends(db, args.metric or DEFAULT_METRIC, args.catalog, args.nights,
                             args.wait)
    except HistoryError as exc:
        raise UsageError(str(exc)) from exc
    if args.out:
        with writing_to(Path(args.out)):  # one writer per directory (suite.exec.out_lock)
            page = write_page(trends, Path(args.out))
        if not args.json:
            text.line(f"page: {page} ({len(trends.nights)} nights, {len(trends.failing)} "
                      f"failing now, {len(trends.known_failures)} known failures, "
                      f"{len(trends.flaky)} flaky)")
    if args.json:
        text.line(trends_json(trends))


def add_run_to_history(db: str, out: Path, text: Output) -> bool:
    """``run --history DB``: add the finished run's night; False (and the reason on
    stderr) when it cannot be added: the run's output is complete, ``hwyeval history
    add DB OUT`` retries."""
    from suite.cli.common import err

    try:
        add_nights(Path(db), [out], None, DEFAULT_WAIT_S, text)
    except UsageError as exc:
        err(f"--history {db}: {exc} (the run's output is complete; 'hwyeval history add "
            f"{db} {out}' tries again)")
        return False
    return True


__all__ = ["add_history_parser", "add_run_to_history", "cmd_history"]
