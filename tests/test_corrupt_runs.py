"""Corrupt inputs are errors everywhere (#35 item 7): a run directory that cannot be read
(its trace.parquet overwritten in place at the same size, run.json garbage, its
series.parquet gone) is an 'error' run with the file named in ``compare`` (an
``unreadable`` finding: it gates on the new side, is reported on the base side),
``view --failed`` (listed), ``report`` (an error row), ``history add`` (recorded as
error) and ``run --resume`` (run again). All of them read through
:func:`reports.record.load_run`, which checks every file run.json lists against its
size and SHA-256 (a run written before run.json listed them: its parquet files read
whole)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from reports import write_reports
from reports.compare import compare_runs
from reports.history import add_night, read_night, run_sql
from reports.record import RUN_JSON, SERIES, TRACE, DamagedRun, RecordError, load_run
from suite.cli import main as hwyeval_main
from suite.rerun.viewer import failed_entries, failed_runs, unreadable_reason
from tests.reliability_support import scenario_toml, write_catalog

pytestmark = [pytest.mark.sumo, pytest.mark.slow]  # one real catalog run, ~6 s
ROOT = Path(__file__).resolve().parents[1]
VICTIM, INTACT = "tiny_a", "tiny_b"


def run_catalog(catalog: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                           str(out), "--no-log", "--jobs", "1", *extra], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


@pytest.fixture(scope="module")
def night(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(the catalog, its output: two passing 2 s runs of lane_keep), made once."""
    root = tmp_path_factory.mktemp("corrupt")
    catalog = write_catalog(root / "tiny.toml", [scenario_toml(VICTIM),
                                                 scenario_toml(INTACT, lane=1)])
    out = root / "clean"
    proc = run_catalog(catalog, out)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return catalog, out


def overwrite_in_place(path: Path) -> None:
    """Flip 64 bytes in the middle of ``path``: same size, other content."""
    data = bytearray(path.read_bytes())
    size, middle = len(data), len(data) // 2
    data[middle:middle + 64] = bytes(b ^ 0xFF for b in data[middle:middle + 64])
    path.write_bytes(bytes(data))
    assert path.stat().st_size == size


def trace_in_place(run_dir: Path) -> None:
    overwrite_in_place(run_dir / TRACE)


def run_json_garbage(run_dir: Path) -> None:
    (run_dir / RUN_JSON).write_bytes(b"\x00garbage{")


def series_missing(run_dir: Path) -> None:
    (run_dir / SERIES).unlink()


# damage -> the file its reason names
DAMAGE: dict[str, tuple[Callable[[Path], None], str]] = {
    "trace_in_place": (trace_in_place, TRACE),
    "run_json_garbage": (run_json_garbage, RUN_JSON),
    "series_missing": (series_missing, SERIES),
}


def damaged_copy(clean: Path, dest: Path, case: str) -> Path:
    """A copy of the clean output (its results.csv and manifest too: what a night
    holds) whose run VICTIM has the damage ``case``."""
    shutil.copytree(clean, dest)
    DAMAGE[case][0](dest / VICTIM)
    return dest


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_compare_gates_an_unreadable_new_run_and_reports_an_unreadable_base_run(
        night: tuple[Path, Path], tmp_path: Path, case: str,
        capsys: pytest.CaptureFixture[str]) -> None:
    _, clean = night
    bad = damaged_copy(clean, tmp_path / "bad", case)
    named = DAMAGE[case][1]
    new_side = compare_runs(clean, bad, tmp_path / "cmp_new")
    assert new_side.exit_code == 1
    (row,) = new_side.regressions
    assert (row.kind, row.category, row.gate) == ("unreadable", "unreadable", True)
    assert row.note.startswith("new: ") and named in row.note
    assert row.key == f"{VICTIM} [lane_keep]"  # matched to its base run, never lost
    assert not new_side.of_kind("new_failure", "fixed")  # no behaviour finding from it
    # the CLI: exit 1, the finding in the JSON by its category (JSON's "kind")
    capsys.readouterr()
    argv = ["compare", str(clean), str(bad), "--out", str(tmp_path / "cli"), "--json"]
    assert hwyeval_main(argv) == 1
    doc = json.loads(capsys.readouterr().out)
    (found,) = doc["regressions"]
    assert (found["kind"], found["finding"], doc["exit_code"]) == ("unreadable", "unreadable", 1)
    assert doc["counts"]["unreadable"] == 1 and "unreadable" in doc["gating_kinds"]
    # on the base side: reported, does not gate, crashes nothing
    base_side = compare_runs(bad, clean, tmp_path / "cmp_base")
    assert base_side.exit_code == 0
    (row,) = base_side.of_category("unreadable")
    assert not row.gate and row.note.startswith("base: ") and named in row.note
    assert not base_side.fixed  # an unreadable base run is no fix either
    assert "cannot be read" in base_side.summary_text()


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_view_failed_lists_the_unreadable_run(night: tuple[Path, Path], tmp_path: Path,
                                              case: str) -> None:
    _, clean = night
    assert failed_runs(clean) == []
    bad = damaged_copy(clean, tmp_path / "bad", case)
    (entry,) = failed_entries(bad)
    assert entry.run_dir == bad / VICTIM and entry.status == "error"
    assert DAMAGE[case][1] in entry.unreadable
    assert failed_runs(bad) == [bad / VICTIM]
    # viewing the damaged run alone says why it is unreadable; a clean one says nothing
    assert unreadable_reason(clean / VICTIM) is None
    why = unreadable_reason(bad / VICTIM)
    assert why is not None and DAMAGE[case][1] in why


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_report_and_history_call_it_an_error(night: tuple[Path, Path], tmp_path: Path,
                                             case: str) -> None:
    _, clean = night
    bad = damaged_copy(clean, tmp_path / "bad", case)
    # history first: the results.csv the run wrote (before the damage) still says pass
    before = pd.read_csv(bad / "results.csv").set_index("run")
    assert before.loc[VICTIM, "status"] == "pass"
    db = tmp_path / "history.duckdb"
    record = read_night(bad)
    add_night(db, record)
    rows = dict(run_sql(db, "SELECT scenario, status FROM runs").rows)
    assert rows == {VICTIM: "error", INTACT: "pass"}
    paths = write_reports(bad)
    results = pd.read_csv(paths.results_csv).set_index("run")
    assert results.loc[VICTIM, "status"] == "error"
    assert results.loc[INTACT, "status"] == "pass"
    assert DAMAGE[case][1] in paths.junit_xml.read_text()


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_resume_runs_an_unreadable_run_again(night: tuple[Path, Path], tmp_path: Path,
                                             case: str) -> None:
    catalog, clean = night
    bad = damaged_copy(clean, tmp_path / "bad", case)
    proc = run_catalog(catalog, bad, "--resume")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    (line,) = [li for li in proc.stdout.splitlines() if li.strip().startswith(f"{VICTIM}:")]
    assert "runs again: unreadable" in line and DAMAGE[case][1] in line, line
    assert load_run(bad / VICTIM).status == "pass"  # whole again
    results = pd.read_csv(bad / "results.csv").set_index("run")
    assert list(results["status"]) == ["pass", "pass"]


def test_the_loader_checks_every_listed_file_and_older_runs_by_their_parquet(
        night: tuple[Path, Path], tmp_path: Path) -> None:
    _, clean = night
    bad = damaged_copy(clean, tmp_path / "bad", "trace_in_place")
    with pytest.raises(DamagedRun, match="trace.parquet: content differs"):
        load_run(bad / VICTIM, trace=False, neighbours=False, arrays=False, series=False)
    assert load_run(bad / VICTIM, verify=False, trace=False).status == "pass"  # as stored
    # a run written before run.json listed its files: read, its parquet files read whole
    old = tmp_path / "old"
    shutil.copytree(clean / VICTIM, old)
    doc = json.loads((old / RUN_JSON).read_text())
    del doc["files"]
    (old / RUN_JSON).write_text(json.dumps(doc))
    assert load_run(old, trace=False).status == "pass"
    (old / TRACE).write_bytes(b"PAR1 not a parquet file PAR1")
    with pytest.raises(DamagedRun, match="trace.parquet: not a readable parquet file"):
        load_run(old, trace=False)
    (old / TRACE).unlink()
    with pytest.raises(DamagedRun, match="trace.parquet: missing"):
        load_run(old, trace=False)
    with pytest.raises(RecordError):  # DamagedRun is a RecordError: old callers catch it
        load_run(old)
