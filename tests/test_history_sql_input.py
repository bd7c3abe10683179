"""``history DB --sql`` with no statement at all ("", blanks, ";", a comment) was a
traceback with exit 1 (DuckDB returns no result to fetch); it is exit 2 with the reason
(issue 35)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from reports.history import add_night, read_night
from tests.reliability_support import ROOT


@pytest.mark.slow
def test_sql_without_a_statement_exits_2(tmp_path: Path) -> None:
    from tests.test_history_store import output_dir

    db = tmp_path / "h.duckdb"
    add_night(db, read_night(output_dir(tmp_path / "night", "2026-11-02T03:00:00+00:00")))
    for sql in ("", "   ", ";", "-- nothing"):
        proc = subprocess.run([sys.executable, "-m", "suite", "history", str(db), "--sql", sql],
                              cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, (sql, proc.stdout + proc.stderr)
        assert "Traceback" not in proc.stderr
    ok = subprocess.run([sys.executable, "-m", "suite", "history", str(db), "--sql",
                         "SELECT count(*) AS n FROM runs"], cwd=ROOT, capture_output=True,
                        text=True, timeout=120)
    assert ok.returncode == 0 and ok.stdout.split() == ["n", "5"]
