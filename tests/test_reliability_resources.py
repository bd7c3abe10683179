"""Bounded resources (issue 35): a run's memory is capped in its own process (a run over
the cap is that run's error, the others go on), a full disk under the Rerun log ends the
run's log at once with the file named instead of hanging until the run's budget, and the
summary's last line says the exit code the process returns."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import tests.synthetic_runs as sr
from suite.exec.catalog_run import exit_of
from suite.exec.executors import RunJob
from suite.exec.memory import (
    ENV,
    MIB,
    MIN_CAP_MIB,
    MemoryCap,
    machine_memory_bytes,
    memory_cap_from,
    ran_out_of_memory,
)
from suite.exec.progress import short_summary
from suite.run.runner import RunOptions
from tests.reliability_support import ROOT, hwyeval, results, scenario_toml, write_catalog

CAP_MIB = 6144  # above a healthy run's address space (2.9-4.3 GiB), below the plug-in's 8 GiB


# --- the memory cap ---------------------------------------------------------------------

def test_the_cap_is_the_option_else_the_variable_else_a_share_of_the_machine() -> None:
    assert memory_cap_from(512, {ENV: "1024"}) == MemoryCap(512)
    assert memory_cap_from(None, {ENV: "1024"}) == MemoryCap(1024)
    assert memory_cap_from(None, {}) == MemoryCap()
    assert MemoryCap(0).limit_bytes() is None  # 0: no cap
    assert MemoryCap(100).limit_bytes() == 100 * MIB
    memory = machine_memory_bytes()
    default = MemoryCap().limit_bytes()
    assert default is not None and default >= MIN_CAP_MIB * MIB
    if memory is not None:
        assert default == max(memory // 2, MIN_CAP_MIB * MIB)
    for bad in ("-1", "lots", "1.5"):
        with pytest.raises(ValueError, match=ENV):
            memory_cap_from(None, {ENV: bad})
    for wrong in (-1, True, 1.5):
        with pytest.raises(ValueError):
            MemoryCap(wrong)  # type: ignore[arg-type]


def test_a_job_carries_a_memory_cap_or_refuses(tmp_path: Path) -> None:
    from suite.catalog import load_catalog

    catalog = write_catalog(tmp_path / "c.toml", [scenario_toml("one")])
    scenario = load_catalog(catalog).scenarios[0]
    assert RunJob(scenario, tmp_path, RunOptions()).memory == MemoryCap()
    with pytest.raises(TypeError):
        RunJob(scenario, tmp_path, RunOptions(), memory=4096)  # type: ignore[arg-type]


def test_out_of_memory_is_told_from_the_error_text() -> None:
    assert ran_out_of_memory("Traceback ...\n  File x\nMemoryError: Unable to allocate 8 GiB\n")
    assert ran_out_of_memory("Traceback ...\nMemoryError\n")
    assert ran_out_of_memory("numpy._core._exceptions._ArrayMemoryError: Unable to allocate")
    assert ran_out_of_memory("libsumo: std::bad_alloc")
    assert not ran_out_of_memory("Traceback ...\nRuntimeError: deliberate crash at step 50")
    assert not ran_out_of_memory(None)


@pytest.mark.slow
def test_a_bad_memory_variable_or_option_exits_2_before_anything_runs(tmp_path: Path) -> None:
    catalog = write_catalog(tmp_path / "c.toml", [scenario_toml("one")])
    out = tmp_path / "out"
    env = {**os.environ, ENV: "a lot"}
    assert hwyeval("run", str(catalog), "--out", str(out), env=env).returncode == 2
    assert hwyeval("run", str(catalog), "--out", str(out), "--max-memory-mb",
                   "-5").returncode == 2
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.sumo
def test_a_run_over_its_memory_cap_is_its_own_error_and_the_others_run(tmp_path: Path) -> None:
    """A controller that asks for 8 GiB under a 6 GiB cap: its run is an error that names
    the cap, the scenario beside it passes; without the cap the allocation (never
    touched) went through, and a touched one would have met the OOM killer instead."""
    catalog = write_catalog(tmp_path / "mem.toml", [
        scenario_toml("hog", extra='controller = "allocate_at_step_20"\n'),
        scenario_toml("calm", pos_m=300.0)], duration_s=2.0)
    out = tmp_path / "out"
    env = {**os.environ, ENV: str(CAP_MIB)}
    proc = hwyeval("run", str(catalog), "--out", str(out), "--no-log", "--jobs", "1",
                   "--plugin", str(ROOT / "tests" / "memory_plugin.py"), env=env)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    status = results(out)["status"]
    assert status["hog"] == "error" and status["calm"] == "pass"
    error = json.loads((out / "hog" / "run.json").read_text())["outcome"]["error"]
    assert str(CAP_MIB) in error and "Unable to allocate" in error  # numpy's own line kept
    assert str(CAP_MIB) in (out / "hog" / "traceback.txt").read_text()
    assert hwyeval("report", str(out)).returncode == 0  # the rewritten record reads back


# --- a full disk under the Rerun log ------------------------------------------------------

@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 2 MiB tmpfs (root only; skipped where mounting is not permitted)."""
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def _fill(disk: Path, leave_bytes: int) -> None:
    """Fill ``disk`` until about ``leave_bytes`` are free."""
    stat = os.statvfs(disk)
    free = stat.f_bavail * stat.f_frsize
    (disk / "filler").write_bytes(b"\0" * max(0, free - leave_bytes))


def _sizes(run_dir: Path) -> tuple[int, int]:
    """(bytes of the run directory without its log, bytes of run.rrd)."""
    files = [p for p in run_dir.rglob("*") if p.is_file()]
    rrd = sum(p.stat().st_size for p in files if p.name == "run.rrd")
    return sum(p.stat().st_size for p in files) - rrd, rrd


@pytest.fixture(scope="module")
def full_catalog(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, int]:
    """A 20 s run's catalog, its run directory's bytes without the log and the log's."""
    tmp = tmp_path_factory.mktemp("full")
    catalog = write_catalog(tmp / "full.toml", [scenario_toml("one")], duration_s=20.0)
    roomy = tmp / "roomy"
    assert hwyeval("run", str(catalog), "--out", str(roomy)).returncode == 0
    other, rrd = _sizes(roomy / "one")
    assert rrd > 0
    return catalog, other, rrd


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize("share", [0.3, 0.6, 0.9])
def test_a_full_disk_under_the_rerun_log_ends_it_at_once_naming_the_file(
        small_disk: Path, full_catalog: tuple[Path, int, int], share: float) -> None:
    """The disk fills part way through run.rrd (``share`` of it fits): Rerun's file sink
    hung its flush until the run's budget (a timeout) or failed without naming a file,
    and the summary could say 'exit 0' while the command exited 1. Now the log fails at
    once naming run.rrd.partial, the run keeps its verdict, and the summary's exit code
    is the process's."""
    catalog, other, rrd = full_catalog
    _fill(small_disk, other + int(share * rrd))
    out = small_disk / "out"
    proc = hwyeval("run", str(catalog), "--out", str(out), "--timeout", "60",
                   timeout_s=300.0)
    assert proc.returncode in (0, 1, 2), proc.stdout + proc.stderr
    doc = json.loads((out / "one" / "run.json").read_text())
    assert doc["outcome"]["end"] != "timeout"
    assert "run.rrd.partial" in (doc["outcome"].get("log_error") or "")
    assert not (out / "one" / "run.rrd").exists()
    if proc.returncode in (0, 1):  # the summary ran to its end: it says this code
        assert f"exit {proc.returncode}" in proc.stdout.strip().splitlines()[-1]


@pytest.mark.slow
@pytest.mark.sumo
def test_a_run_whose_own_record_does_not_fit_says_why(
        small_disk: Path, full_catalog: tuple[Path, int, int]) -> None:
    """A third of the run's files fit, so its record hardly does: the reason reached the
    terminal without the file that did not fit (here), or not at all ("exited with code
    0 without a valid record", by hand with a little more room); now the file is named,
    by the run's error or by the scenario process itself (exit 3)."""
    catalog, other, _ = full_catalog
    _fill(small_disk, other // 3)
    out = small_disk / "out"
    proc = hwyeval("run", str(catalog), "--out", str(out), "--no-log", "--timeout", "60",
                   timeout_s=300.0)
    assert proc.returncode in (1, 2), proc.stdout + proc.stderr
    said = proc.stdout + proc.stderr
    assert "code 0 without" not in said
    assert f"{out}/" in said.split("No space left on device", 1)[-1][:200]


LOG_ON_FULL_DISK = """
import sys
from pathlib import Path
from reports.record import load_run
from suite.rerun.log import log_record
record = load_run(Path(sys.argv[1]))
try:
    log_record(record, Path(sys.argv[2]))
    print("written")
except OSError as exc:
    print("OSError", exc.filename)
"""


@pytest.mark.slow
@pytest.mark.sumo
@pytest.mark.parametrize("free_kib", [100, 300, 500])
def test_a_log_on_a_full_disk_raises_at_once_naming_the_file(
        small_disk: Path, full_catalog: tuple[Path, int, int], free_kib: int) -> None:
    """log_record alone with ``free_kib`` left: Rerun's file sink blocked a log call, its
    flush or its disconnect for good (here: 100 and 500 KiB; 300 KiB raised without a
    file name); now every case raises an OSError naming run.rrd.partial."""
    catalog, _, _ = full_catalog
    run_dir = catalog.parent / "roomy" / "one"
    _fill(small_disk, free_kib * 1024)
    target = small_disk / "run.rrd"
    done = subprocess.run([sys.executable, "-c", LOG_ON_FULL_DISK, str(run_dir), str(target)],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.stdout.split() == ["OSError", f"{target}.partial"], done.stdout + done.stderr
    assert not target.exists() and not Path(f"{target}.partial").exists()


def test_the_summary_says_the_exit_code_the_process_returns(tmp_path: Path) -> None:
    """Every run passed but the reports could not be written (or the night not added to
    --history, or --no-fail): the last line names the code exit_of returns."""
    records = [sr.judge(r) for _, r in sr.catalog_records(("ctrl_a",))]
    passed = [r for r in records if r.status == "pass"]
    cases = [
        (passed, {"reports_written": False, "history_ok": True, "no_fail": False}, 1),
        (passed, {"reports_written": True, "history_ok": False, "no_fail": False}, 2),
        (passed, {"reports_written": True, "history_ok": True, "no_fail": False}, 0),
        (records, {"reports_written": True, "history_ok": True, "no_fail": True}, 0),
        (records, {"reports_written": True, "history_ok": True, "no_fail": False}, 1),
    ]
    assert passed and len(passed) < len(records)
    for runs, flags, expected in cases:
        code, meaning = exit_of(runs, out=tmp_path, **flags)  # type: ignore[arg-type]
        assert code == expected
        last = short_summary(runs, 1.0, meaning)[-1]
        assert f"exit {code}" in last
