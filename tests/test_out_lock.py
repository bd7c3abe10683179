"""One writer per output directory (suite.exec.out_lock): a second ``hwyeval run`` into
an --out another one is writing to exits 2 having written nothing, and the lock goes
with its holder."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from suite.exec.out_lock import OutDirBusy, lock_path, out_dir_lock

ROOT = Path(__file__).resolve().parents[1]
CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 20.0
step_s = 0.05
[[scenario]]
name = "slow_one"
net = "straight_2lane"
ego = { lane = 0, pos_m = 60.0, speed_mps = 25.0 }
"""


def test_a_held_lock_is_refused_and_released_with_its_holder(tmp_path: Path) -> None:
    out = tmp_path / "night"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from pathlib import Path; "
        "from suite.exec.out_lock import out_dir_lock\n"
        f"with out_dir_lock(Path({str(out)!r})):\n"
        "    print('held', flush=True); time.sleep(30)")],
        cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(OutDirBusy) as info:
            with out_dir_lock(out):
                pass
        assert str(holder.pid) in str(info.value)
    finally:
        holder.kill()
        holder.wait()
    with out_dir_lock(out) as path:  # the kernel dropped it with the process
        assert path == lock_path(out) and path.parent == tmp_path
    assert not out.exists()  # the lock lives beside the output, never in it


@pytest.mark.parametrize("other", ["night/sub", "night/a/b", ".", "night_sibling"])
def test_a_directory_inside_or_around_one_being_written_is_refused(tmp_path: Path,
                                                                   other: str) -> None:
    """X being written: X/sub, X/a/b and X's parent are refused (an --overwrite of one
    would empty the other's files); a sibling is not. Then the other way round."""
    out = tmp_path / "night"
    out.mkdir()
    (out / "a").mkdir()
    target = (tmp_path / other).resolve()
    nested = other != "night_sibling"
    holder = _Holder(out)
    try:
        if nested:
            with pytest.raises(OutDirBusy):
                with out_dir_lock(target):
                    pass
        else:
            with out_dir_lock(target):
                pass
    finally:
        holder.stop()
    with out_dir_lock(target):  # released with its holder
        pass
    holder = _Holder(target)  # the other way round
    try:
        if nested:
            with pytest.raises(OutDirBusy):
                with out_dir_lock(out):
                    pass
        else:
            with out_dir_lock(out):
                pass
    finally:
        holder.stop()


def test_one_process_may_write_inside_a_directory_it_holds(tmp_path: Path) -> None:
    out = tmp_path / "night"
    out.mkdir()
    with out_dir_lock(out), out_dir_lock(out / "runs"), out_dir_lock(out):
        pass


@pytest.mark.slow
@pytest.mark.sumo
def test_a_second_run_into_the_same_out_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    catalog = tmp_path / "cat.toml"
    catalog.write_text(CATALOG)
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                              str(out), "--no-log"], cwd=ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60.0
        while not (out / "manifest.json").is_file() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert (out / "manifest.json").is_file()
        manifest = (out / "manifest.json").read_bytes()
        second = subprocess.run([sys.executable, "-m", "suite", "run", str(catalog), "--out",
                                 str(out), "--no-log", "--overwrite"], cwd=ROOT,
                                capture_output=True, text=True, timeout=120)
        assert second.returncode == 2, second.stdout + second.stderr
        assert (out / "manifest.json").read_bytes() == manifest
    finally:
        stdout, stderr = first.communicate(timeout=300)
    assert first.returncode == 0, stdout + stderr
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "junit.xml", "manifest.json", "report-runs", "report.html", "results.csv",
        "slow_one", "summary.csv"]


# --- one lock for every command that writes a directory, keyed on the real path --------

SEARCH_CATALOG = """
[defaults]
controller = "lane_keep"
duration_s = 2.0
step_s = 0.05
[[scenario]]
name = "fam"
net = "straight_3lane"
ego = { lane = 1, pos_m = 50.0, speed_mps = 25.0 }
stalled = [ { lane = 1, pos_m = 400.0 } ]
[scenario.search]
"stalled.0.pos_m" = { min = 100.0, max = 900.0 }
"""


class _Holder:
    """Another process holding the lock of ``out`` (as a running command does)."""

    def __init__(self, out: Path) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", (
            "import time; from pathlib import Path; "
            "from suite.exec.out_lock import out_dir_lock\n"
            f"with out_dir_lock(Path({str(out)!r})):\n"
            "    print('held', flush=True); time.sleep(120)")],
            cwd=ROOT, stdout=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None and self.proc.stdout.readline().strip() == "held"

    def stop(self) -> None:
        self.proc.kill()
        self.proc.wait()


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def _published(root: Path) -> dict[str, bytes]:
    """The files of ``root`` outside the staging directories of runs in flight."""
    return {k: v for k, v in _snapshot(root).items() if not k.startswith(".")}


def _commonroad_file(tmp_path: Path) -> Path:
    pytest.importorskip("commonroad.common.writer.file_writer_xml")
    from tests.test_import_commonroad_synthetic import Car, Lane, W, straight, write_file

    ref = straight()
    lanes = [Lane(100, ref, 0.0, 500.0, 0.0, left=101),
             Lane(101, ref, 0.0, 500.0, W, right=100)]
    return write_file(tmp_path / "DEU_Lock-1_1_T-1.xml", lanes,
                      [Car(1001, ref, 150.0, 0.0, 27.0, 0, 50)],
                      Car(9000, ref, 100.0, 0.0, 25.0, k1=50), 0.1)


def _command(kind: str, tmp_path: Path, out: str) -> list[str]:
    """The arguments of a command of ``kind`` that, if it ran, would write ``out`` (a
    finished synthetic catalog output)."""
    import tests.synthetic_runs as sr

    if kind in ("run", "search", "search_compare"):
        catalog = tmp_path / "cat.toml"
        catalog.write_text(SEARCH_CATALOG)
        if kind == "run":
            return ["run", str(catalog), "--out", out, "--overwrite", "--no-log"]
        extra = ["--compare", "random", "--seeds", "1"] if kind == "search_compare" else []
        return ["search", str(catalog), "--out", out, "--budget", "1", "--overwrite",
                "--no-log", *extra]
    if kind == "compare":
        base, new = sr.make_catalog(tmp_path / "base"), sr.make_catalog(tmp_path / "new")
        return ["compare", str(base), str(new), "--out", out]
    if kind == "report":
        return ["report", out]
    return ["import", "commonroad", str(_commonroad_file(tmp_path)), "--out", out]


@pytest.mark.slow
@pytest.mark.parametrize("via_link", [False, True], ids=["path", "symlink"])
@pytest.mark.parametrize("kind", ["run", "search", "search_compare", "import", "compare",
                                  "report"])
def test_every_command_that_writes_a_directory_is_refused_while_another_writes_it(
        tmp_path: Path, kind: str, via_link: bool) -> None:
    """A second search --overwrite into a running search's --out exited 0 and mixed its
    runs in, a run --overwrite too, and a command through a symbolic link to the
    directory was never refused: every writer now exits 2 naming the directory and the
    holder's pid, and the directory is left as it was."""
    import tests.synthetic_runs as sr

    out = sr.make_catalog(tmp_path / "night")
    (out / "manifest.json").write_text("{}")
    link = tmp_path / "alias"
    link.symlink_to(out, target_is_directory=True)
    args = _command(kind, tmp_path, str(link if via_link else out))
    before = _snapshot(out)
    holder = _Holder(out)
    try:
        proc = subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT,
                              capture_output=True, text=True, timeout=300)
    finally:
        holder.stop()
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert str(holder.proc.pid) in proc.stderr and str(out) in proc.stderr
    assert "Traceback" not in proc.stderr
    assert _snapshot(out) == before


def test_the_lock_is_the_real_directorys_and_reentrant_in_one_process(tmp_path: Path) -> None:
    real = tmp_path / "real"
    real.mkdir()
    link = tmp_path / "link"
    link.symlink_to(real, target_is_directory=True)
    assert lock_path(link) == lock_path(real) == tmp_path / ".real.lock"
    assert lock_path(tmp_path / "link" / ".." / "real") == lock_path(real)
    with out_dir_lock(real), out_dir_lock(link):  # paper --run holds it around run
        holder = subprocess.run([sys.executable, "-c", (
            "from pathlib import Path; from suite.exec.out_lock import OutDirBusy, "
            "out_dir_lock\n"
            "try:\n"
            f"    with out_dir_lock(Path({str(link)!r})): print('free')\n"
            "except OutDirBusy: print('busy')")], cwd=ROOT, capture_output=True, text=True,
            timeout=60)
        assert holder.stdout.strip() == "busy"
    with out_dir_lock(link):  # released when the outer block ended
        pass


@pytest.mark.slow
@pytest.mark.sumo
def test_a_running_search_keeps_its_out_from_a_search_a_run_and_a_link(tmp_path: Path) -> None:
    """The probe's three cases against a real search (its run held up by a step hung in C):
    search --overwrite and run --overwrite into its --out, and run through a symbolic link
    to it, exit 2; the search's directory holds nothing of theirs."""
    from tests.reliability_support import Background, wait_for

    catalog = tmp_path / "hang.toml"
    catalog.write_text(SEARCH_CATALOG.replace('controller = "lane_keep"',
                                              'controller = "hang_at_step_20"'))
    other = tmp_path / "other.toml"
    other.write_text(CATALOG)
    plugin = str(ROOT / "tests" / "hang_plugin.py")
    out = tmp_path / "search"
    link = tmp_path / "alias"
    link.symlink_to(out, target_is_directory=True)
    first = Background("search", str(catalog), "--out", str(out), "--budget", "1",
                       "--no-log", "--timeout", "60", "--plugin", plugin)
    try:
        wait_for(lambda: any(p.name.startswith(".partial-") for p in out.iterdir())
                 if out.is_dir() else False, 120.0, "the search's run to start")
        before = _published(out)
        seconds = [
            ["search", str(catalog), "--out", str(out), "--budget", "1", "--overwrite",
             "--no-log", "--plugin", plugin],
            ["run", str(other), "--out", str(out), "--overwrite", "--no-log"],
            ["run", str(other), "--out", str(link), "--overwrite", "--no-log"],
        ]
        codes = [subprocess.run([sys.executable, "-m", "suite", *args], cwd=ROOT,
                                capture_output=True, text=True, timeout=300).returncode
                 for args in seconds]
        assert codes == [2, 2, 2]
        assert _published(out) == before
    finally:
        first.proc.send_signal(2)  # SIGINT: the search stops in order
        code = first.wait(120.0)
    assert code == 130, first.out + first.err
    assert not (out / "slow_one").exists()
