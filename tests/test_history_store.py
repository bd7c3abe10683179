"""The history database: adding nights (idempotent, conflicts refused, nothing lost),
the migration from schema v1, two writers at once, read-only queries, the CLI's exit
codes and ``compare --history``. Real DuckDB files; nights are synthetic run
directories (tests/synthetic_runs.py) with a manifest, or NightRecords built here."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import math
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import duckdb
import numpy as np
import pytest
import synthetic_runs as sr

from reports.history import (
    SCHEMA_VERSION,
    HistoryError,
    HistoryLocked,
    NightConflict,
    NightInfo,
    NightRecord,
    add_night,
    load_trends,
    read_night,
    run_sql,
)
from reports.history.store import locked
from reports.manifest import Manifest, write_manifest
from reports.provenance import Provenance

ROOT = Path(__file__).resolve().parents[1]
T0 = dt.datetime(2026, 11, 1, 3, 0, tzinfo=dt.UTC)
CATALOG = "/ci/catalogs/nightly.toml"


def hwyeval(*args: str, timeout_s: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout_s)


def synthetic_night(k: int, statuses: Sequence[str], revision: str = "a" * 40,
                    hashes: Sequence[str] | None = None, values: Sequence[float] | None = None,
                    metrics: Sequence[str] = ("min_ttc_s", "max_abs_jerk_mps3"),
                    catalog: str = CATALOG, out_dir: str = "") -> NightRecord:
    """Night ``k`` (id n<k>, a day after night k-1) of scenarios s0, s1, ...; metric j of
    scenario i is ``values[i]`` (first metric) or i + j."""
    n, m = len(statuses), len(metrics)
    vals = np.array([[float(i + j) for j in range(m)] for i in range(n)], dtype=np.float64)
    if values is not None:
        vals[:, 0] = values
    limits = np.full((n, m), np.nan)
    limits[:, 0] = 0.95
    info = NightInfo(night_id=f"n{k:03d}", started_at=T0 + dt.timedelta(days=k),
                     git_revision=revision, hwyeval_version="0.1.0", host="ci",
                     catalog=catalog, out_dir=out_dir, git_dirty=False)
    return NightRecord(
        info=info, scenarios=tuple(f"s{i}" for i in range(n)),
        scenario_hashes=tuple(hashes) if hashes is not None else ("h",) * n,
        controllers=("two_loop",) * n, statuses=tuple(statuses),
        failed_criteria=tuple("" if s == "pass" else "min_ttc_s=0.5<0.95" for s in statuses),
        failure_modes=tuple(() if s == "pass" else ("min_ttc_s",) for s in statuses),
        run_dirs=tuple(f"/runs/n{k}/s{i}" for i in range(n)), metric_names=tuple(metrics),
        values_2d=vals, limits_2d=limits)


def output_dir(path: Path, started: str, sha: str = "b" * 40) -> Path:
    """A finished synthetic catalog output (5 runs, one controller) with a manifest."""
    out = sr.make_catalog(path, controllers=("ctrl_a",))
    names = tuple(sorted(p.name for p in out.iterdir() if p.is_dir()))
    write_manifest(out, Manifest(catalog=CATALOG, catalog_name="nightly", scenarios=names,
                                 started=started, jobs=1, executor="local",
                                 finished=started,
                                 provenance=Provenance(git_sha=sha, git_dirty=False,
                                                       hwyeval_version="0.1.0", host="ci")))
    return out


def counts(db: Path) -> tuple[int, int]:
    with duckdb.connect(str(db), read_only=True) as con:
        nights = con.execute("SELECT count(*) FROM nights").fetchone()
        runs = con.execute("SELECT count(*) FROM runs").fetchone()
    assert nights is not None and runs is not None
    return int(nights[0]), int(runs[0])


def test_a_night_is_added_once_and_read_back_as_it_was(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    out = output_dir(tmp_path / "night1", "2026-11-02T03:00:00+00:00")
    night = read_night(out)
    first = add_night(db, night)
    assert first.added and first.migrated_from == 0 and first.n_runs == 5
    again = add_night(db, read_night(out))  # the same night: idempotent, says so
    assert not again.added and again.migrated_from == SCHEMA_VERSION
    assert counts(db) == (1, 5)
    q = run_sql(db, "SELECT scenario, status, failure_modes, max_abs_lat_acc_mps2, "
                    "limits['max_abs_lat_acc_mps2'] FROM runs ORDER BY scenario")
    rows = {r[0]: r for r in q.rows}
    assert {r[1] for r in q.rows} == {"pass", "fail"}
    # the rows are those of the run directories' verdicts (results.csv)
    for i, scenario in enumerate(night.scenarios):
        j = night.metric_names.index("max_abs_lat_acc_mps2")
        assert rows[scenario][3] == pytest.approx(night.values_2d[i, j])
        assert list(rows[scenario][2]) == list(night.failure_modes[i])
    assert rows["sharp_curve"][1] == "fail" and "max_abs_lat_acc_mps2" in rows["sharp_curve"][2]
    assert rows["sharp_curve"][4] == pytest.approx(4.89)
    info = run_sql(db, "SELECT night_id, git_revision, catalog, out_dir FROM nights").rows[0]
    assert info == ("nightly@2026-11-02T03:00:00+00:00", "b" * 40, CATALOG, str(out.resolve()))


def test_the_same_id_with_other_content_is_refused_and_nothing_changes(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    add_night(db, synthetic_night(1, ["pass", "pass"]))
    before = run_sql(db, "SELECT * FROM runs ORDER BY scenario").rows
    with pytest.raises(NightConflict):
        add_night(db, synthetic_night(1, ["pass", "fail"]))
    assert run_sql(db, "SELECT * FROM runs ORDER BY scenario").rows == before
    assert counts(db) == (1, 2)


def test_a_night_with_a_new_metric_adds_its_column_and_old_rows_read_null(
        tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    add_night(db, synthetic_night(1, ["pass"]))
    r = add_night(db, synthetic_night(2, ["pass"], metrics=("min_ttc_s", "new_metric_m")))
    assert r.new_metric_columns == ("new_metric_m",)
    rows = run_sql(db, "SELECT night_id, new_metric_m, max_abs_jerk_mps3 FROM runs "
                       "ORDER BY night_id").rows
    assert rows == (("n001", None, 1.0), ("n002", 1.0, None))


# The schema as version 1 defined it (the first release), frozen here.
V1 = (
    "CREATE TABLE schema_version (version INTEGER NOT NULL PRIMARY KEY, "
    "applied_at TIMESTAMPTZ NOT NULL DEFAULT current_timestamp)",
    "CREATE TABLE nights (night_id VARCHAR PRIMARY KEY, started_at TIMESTAMPTZ NOT NULL, "
    "git_revision VARCHAR NOT NULL, hwyeval_version VARCHAR NOT NULL, host VARCHAR NOT NULL, "
    "catalog VARCHAR NOT NULL)",
    "CREATE TABLE runs (night_id VARCHAR NOT NULL, scenario VARCHAR NOT NULL, "
    "scenario_hash VARCHAR NOT NULL, controller VARCHAR NOT NULL, status VARCHAR NOT NULL, "
    "failed_criteria VARCHAR NOT NULL, PRIMARY KEY (night_id, scenario, controller))",
    "INSERT INTO schema_version (version) VALUES (1)",
    'ALTER TABLE runs ADD COLUMN "min_ttc_s" DOUBLE',
    'ALTER TABLE runs ADD COLUMN "max_abs_jerk_mps3" DOUBLE',
)


def test_a_v1_database_is_migrated_to_the_current_schema_keeping_its_rows(
        tmp_path: Path) -> None:
    db = tmp_path / "v1.duckdb"
    with duckdb.connect(str(db)) as con:
        for sql in V1:
            con.execute(sql)
        con.execute("INSERT INTO nights VALUES ('old', '2026-10-01 03:00:00+00', 'c0ffee', "
                    "'0.0.9', 'ci', ?)", [CATALOG])
        con.execute("INSERT INTO runs VALUES ('old', 's0', 'h', 'two_loop', 'pass', '', "
                    "2.5, 1.0), ('old', 's1', 'h', 'two_loop', 'fail', "
                    "'min_ttc_s=0.5<0.95;max_abs_jerk_mps3=11.07>8.37', 0.5, 11.07)")
    # reading an old file refuses (adding migrates); nothing is changed by the refusal
    with pytest.raises(HistoryError):
        run_sql(db, "SELECT 1")
    result = add_night(db, synthetic_night(40, ["pass", "fail"]))
    assert result.added and result.migrated_from == 1
    rows = run_sql(db, "SELECT night_id, scenario, status, failure_modes, min_ttc_s, "
                       "max_abs_jerk_mps3, limits, run_dir FROM runs ORDER BY night_id, "
                       "scenario").rows
    assert rows[0] == ("n040", "s0", "pass", [], 0.0, 1.0, {"min_ttc_s": 0.95}, "/runs/n40/s0")
    assert rows[2] == ("old", "s0", "pass", [], 2.5, 1.0, None, "")
    assert rows[3][:6] == ("old", "s1", "fail", ["min_ttc_s", "max_abs_jerk_mps3"], 0.5, 11.07)
    versions = run_sql(db, "SELECT version FROM schema_version ORDER BY version").rows
    assert versions == tuple((v,) for v in range(1, SCHEMA_VERSION + 1))
    old = run_sql(db, "SELECT git_revision, catalog_sha256, out_dir FROM nights "
                      "WHERE night_id = 'old'").rows
    assert old == (("c0ffee", "", ""),)
    trends = load_trends(db)  # the old night and the new one are one catalog's history
    assert [s.info.night_id for s in trends.nights] == ["old", "n040"]


def test_a_newer_schema_is_refused_untouched(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    add_night(db, synthetic_night(1, ["pass"]))
    with duckdb.connect(str(db)) as con:
        con.execute(f"INSERT INTO schema_version (version) VALUES ({SCHEMA_VERSION + 1})")
    size = db.stat().st_size
    with pytest.raises(HistoryError):
        add_night(db, synthetic_night(2, ["pass"]))
    assert db.stat().st_size == size
    with duckdb.connect(str(db), read_only=True) as con:
        assert con.execute("SELECT count(*) FROM nights").fetchone() == (1,)


def test_sql_is_read_only(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    add_night(db, synthetic_night(1, ["pass", "fail"]))
    with pytest.raises(HistoryError):
        run_sql(db, "DELETE FROM runs")
    with pytest.raises(HistoryError):
        run_sql(db, "SELECT nope FROM runs")
    with pytest.raises(HistoryError):  # nor other files
        run_sql(db, f"COPY (SELECT * FROM runs) TO '{tmp_path / 'out.csv'}'")
    with pytest.raises(HistoryError):
        run_sql(db, "SET enable_external_access = true")
    assert not (tmp_path / "out.csv").exists()
    assert counts(db) == (1, 2)


@pytest.mark.slow
def test_two_history_add_processes_at_once_both_land_whole(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    outs = [output_dir(tmp_path / f"night{k}", f"2026-11-0{k}T03:00:00+00:00")
            for k in (1, 2)]
    procs = [subprocess.Popen([sys.executable, "-m", "suite", "history", "add", str(db),
                               str(out)], cwd=ROOT, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for out in outs]
    results = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], results
    assert counts(db) == (2, 10)
    per_night = run_sql(db, "SELECT night_id, count(*) FROM runs GROUP BY night_id "
                            "ORDER BY night_id").rows
    assert [n for _, n in per_night] == [5, 5]
    assert run_sql(db, "SELECT count(*) FROM schema_version").rows == ((SCHEMA_VERSION,),)


@pytest.mark.slow
def test_a_writer_waits_for_the_lock_and_gives_up_with_exit_2(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    add_night(db, synthetic_night(1, ["pass"]))
    out = output_dir(tmp_path / "night2", "2026-11-02T03:00:00+00:00")
    with locked(db):
        proc = hwyeval("history", "add", str(db), str(out), "--wait", "0.5")
        assert proc.returncode == 2 and "Traceback" not in proc.stderr
        with pytest.raises(HistoryLocked):
            add_night(db, synthetic_night(3, ["pass"]), wait_s=0.2)
    assert counts(db) == (1, 1)
    assert hwyeval("history", "add", str(db), str(out)).returncode == 0
    assert counts(db) == (2, 6)


@pytest.mark.slow
def test_cli_exit_codes_and_json(tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    missing = hwyeval("history", "add", str(db), str(tmp_path / "nope"))
    assert missing.returncode == 2 and "Traceback" not in missing.stderr
    assert not db.exists()
    unfinished = output_dir(tmp_path / "unfinished", "2026-11-01T03:00:00+00:00")
    manifest = json.loads((unfinished / "manifest.json").read_text())
    manifest["finished"] = ""
    (unfinished / "manifest.json").write_text(json.dumps(manifest))
    assert hwyeval("history", "add", str(db), str(unfinished)).returncode == 2
    out = output_dir(tmp_path / "night1", "2026-11-01T03:00:00+00:00")
    assert hwyeval("history", "add", str(db), str(out)).returncode == 0
    assert hwyeval("history", "add", str(db), str(out)).returncode == 0  # unchanged
    assert hwyeval("history", str(db), "--json", "--metric", "nope").returncode == 2
    assert hwyeval("history", str(db), "--sql", "DROP TABLE runs").returncode == 2
    proc = hwyeval("history", str(db), "--json", "--metric", "max_abs_lat_acc_mps2")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    by = {s["scenario"]: s for s in data["scenarios"]}
    assert len(data["nights"]) == 1 and data["nights"][0]["runs"] == 5
    assert by["sharp_curve"]["status_now"] == "fail"
    assert by["sharp_curve"]["first_failing_revision"] == "b" * 40
    assert by["sharp_curve"]["metric_limit"] == pytest.approx(4.89)
    assert by["cruise_straight"]["status_now"] == "pass"
    sql = hwyeval("history", str(db), "--sql", "SELECT count(*) AS n FROM runs")
    assert sql.returncode == 0 and sql.stdout.split() == ["n", "5"]


@pytest.mark.slow
def test_compare_against_the_last_night_of_the_catalog_or_the_last_pass(
        tmp_path: Path) -> None:
    db = tmp_path / "h.duckdb"
    one = output_dir(tmp_path / "n1", "2026-11-01T03:00:00+00:00", sha="1" * 40)
    two = output_dir(tmp_path / "n2", "2026-11-02T03:00:00+00:00", sha="2" * 40)
    new = output_dir(tmp_path / "n3", "2026-11-03T03:00:00+00:00", sha="3" * 40)
    assert hwyeval("history", "add", str(db), str(one), str(two), str(new)).returncode == 0
    proc = hwyeval("compare", "--history", str(db), str(new), "--json")
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    assert Path(result["base_dir"]).resolve() == two.resolve()
    # every synthetic night has failures: no last-pass night -> nothing to compare (2)
    assert hwyeval("compare", "--history", str(db), str(new), "--baseline",
                   "last-pass").returncode == 2
    # the baseline night's directory is gone: exit 2, nothing compared
    import shutil

    shutil.rmtree(two)
    gone = hwyeval("compare", "--history", str(db), str(new))
    assert gone.returncode == 2 and "Traceback" not in gone.stderr
    assert hwyeval("compare", str(one), str(new), "--baseline", "last").returncode == 2


def test_trends_of_synthetic_nights_known_answers(tmp_path: Path) -> None:
    """s0 passes throughout; s1 breaks at night 6 with revision b; s2 flips at night 3
    with the same hash and revision (flaky) and passes now."""
    db = tmp_path / "h.duckdb"
    for k in range(1, 11):
        rev = "a" * 40 if k < 6 else "b" * 40
        st = ["pass", "pass" if k < 6 else "fail", "fail" if k == 3 else "pass"]
        add_night(db, synthetic_night(k, st, rev, values=[2.0, 1.0 - 0.1 * k, math.inf]))
    t = load_trends(db)
    by = {s.scenario: s for s in t.scenarios}
    assert [s.scenario for s in t.scenarios] == ["s1", "s2", "s0"]  # failing, flaky, rest
    assert (by["s1"].first_failing_night, by["s1"].first_failing_revision) == ("n006", "b" * 40)
    assert (by["s1"].last_good_night, by["s1"].last_good_revision) == ("n005", "a" * 40)
    assert by["s2"].flaky and not by["s1"].flaky and not by["s0"].flaky
    assert [round(s.pass_rate, 3) for s in t.nights][:6] == [1, 1, 0.667, 1, 1, 0.667]
    assert by["s1"].values[0] == pytest.approx(0.9) and by["s1"].limit == 0.95
    assert load_trends(db, window=4).nights[0].info.night_id == "n007"
    assert not load_trends(db, window=4).scenarios[1].flaky  # its flip is outside the window


def test_a_night_record_refuses_misaligned_or_unknown_input() -> None:
    good = synthetic_night(1, ["pass", "fail"])
    with pytest.raises(ValueError):
        dataclasses.replace(good, statuses=("pass",))
    with pytest.raises(ValueError):
        dataclasses.replace(good, statuses=("pass", "maybe"))
    with pytest.raises(ValueError):
        dataclasses.replace(good, values_2d=np.zeros((2, 5)))
    with pytest.raises(ValueError):
        dataclasses.replace(good, metric_names=("min_ttc_s", "DROP TABLE"))
    with pytest.raises(ValueError):
        dataclasses.replace(good.info, started_at=dt.datetime(2026, 1, 1))


def test_results_csv_and_the_run_directories_give_the_same_night(tmp_path: Path) -> None:
    """A night is read from its run directories' typed records, never from results.csv:
    with or without the results.csv the run wrote, the same night."""
    from reports import write_reports

    out = output_dir(tmp_path / "night1", "2026-11-01T03:00:00+00:00")
    write_reports(out)
    fast = read_night(out)
    (out / "results.csv").unlink()
    slow = read_night(out)
    assert fast.sha256 == slow.sha256
    assert fast.metric_names == slow.metric_names and fast.statuses == slow.statuses
    np.testing.assert_array_equal(fast.limits_2d, slow.limits_2d)
    assert all(h for h in fast.scenario_hashes) or not any(fast.scenario_hashes)
