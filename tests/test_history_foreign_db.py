"""Issue #35, "a history file is hwyeval's or it is refused": a DuckDB file of another
program is never written into by ``history add`` or ``run --history``; hwyeval's own
files, new or older and unmarked, carry the marker and keep working."""

from __future__ import annotations

import io
from pathlib import Path

import duckdb
import pytest
from test_history_store import hwyeval, output_dir, synthetic_night

from reports.history import add_night, run_sql
from reports.history.schema import APPLICATION_ID, META_TABLE, ForeignDatabase
from suite.cli.common import Output
from suite.cli.history import add_run_to_history

STARTED = "2026-11-01T03:00:00+00:00"


def foreign_db(path: Path) -> Path:
    """Another program's DuckDB file: a ``customers`` table with a row."""
    with duckdb.connect(str(path)) as con:
        con.execute("CREATE TABLE customers (id INTEGER PRIMARY KEY, name VARCHAR)")
        con.execute("INSERT INTO customers VALUES (1, 'Ada')")
    return path


def contents(path: Path) -> tuple[tuple[str, ...], tuple[tuple[object, ...], ...]]:
    """The file's tables (every schema) and the customers' rows."""
    with duckdb.connect(str(path), read_only=True) as con:
        tables = tuple(sorted(f"{r[0]}.{r[1]}" for r in con.execute(
            "SELECT schema_name, table_name FROM duckdb_tables()").fetchall()))
        rows = tuple(con.execute("SELECT * FROM customers ORDER BY id").fetchall())
    return tables, rows


def test_history_add_refuses_another_programs_database_and_writes_nothing(
        tmp_path: Path) -> None:
    db = foreign_db(tmp_path / "shop.duckdb")
    before = contents(db)
    out = output_dir(tmp_path / "night1", STARTED)
    proc = hwyeval("history", "add", str(db), str(out))
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr and str(db) in proc.stderr
    assert contents(db) == before == (("main.customers",), ((1, "Ada"),))
    # reading it is refused too (not "an older schema")
    assert hwyeval("history", str(db), "--json").returncode == 2


def test_run_history_refuses_it_and_the_library_call_raises(tmp_path: Path) -> None:
    db = foreign_db(tmp_path / "shop.duckdb")
    before = contents(db)
    out = output_dir(tmp_path / "night1", STARTED)
    text = Output(io.StringIO())
    assert add_run_to_history(str(db), out, text) is False
    with pytest.raises(ForeignDatabase):
        add_night(db, synthetic_night(1, ["pass"]))
    assert contents(db) == before


def test_hwyeval_tables_beside_foreign_ones_are_not_adopted(tmp_path: Path) -> None:
    """What the bug left behind: hwyeval's tables created next to a foreign table,
    without the marker."""
    db = foreign_db(tmp_path / "shop.duckdb")
    with duckdb.connect(str(db)) as con:
        con.execute("CREATE TABLE schema_version (version INTEGER, applied_at TIMESTAMPTZ)")
        con.execute("CREATE TABLE nights (night_id VARCHAR)")
        con.execute("CREATE TABLE runs (night_id VARCHAR)")
    before = contents(db)
    with pytest.raises(ForeignDatabase):
        add_night(db, synthetic_night(1, ["pass"]))
    assert contents(db) == before


def test_a_foreign_marker_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "other.duckdb"
    with duckdb.connect(str(db)) as con:
        con.execute(f"CREATE TABLE {META_TABLE} (key VARCHAR PRIMARY KEY, value VARCHAR)")
        con.execute(f"INSERT INTO {META_TABLE} VALUES ('application_id', 'someone.else')")
    with pytest.raises(ForeignDatabase):
        add_night(db, synthetic_night(1, ["pass"]))
    with duckdb.connect(str(db), read_only=True) as con:
        assert con.execute("SELECT count(*) FROM duckdb_tables()").fetchone() == (1,)


def test_a_new_database_is_marked_and_an_unmarked_old_one_is_adopted(tmp_path: Path) -> None:
    new = tmp_path / "new.duckdb"
    add_night(new, synthetic_night(1, ["pass"]))
    marker = run_sql(new, f"SELECT value FROM {META_TABLE} WHERE key = 'application_id'")
    assert marker.rows == ((APPLICATION_ID,),)
    # an hwyeval file from before the marker: its three tables only
    old = tmp_path / "old.duckdb"
    add_night(old, synthetic_night(1, ["pass"]))
    with duckdb.connect(str(old)) as con:
        con.execute(f"DROP TABLE {META_TABLE}")
    assert run_sql(old, "SELECT count(*) FROM nights").rows == ((1,),)  # still readable
    result = add_night(old, synthetic_night(2, ["pass"]))
    assert result.added
    assert run_sql(old, f"SELECT value FROM {META_TABLE}").rows == ((APPLICATION_ID,),)
    assert run_sql(old, "SELECT count(*) FROM nights").rows == ((2,),)

