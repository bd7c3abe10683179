"""The forkserver dying mid-run loses no result: the scenario it leaves running is
tracked by its pid and keeps its verdict, the next scenarios start on a new forkserver
(real runs, real libsumo)."""

from __future__ import annotations

import os
import signal
import uuid
from pathlib import Path

import pytest
from reliability_support import (
    Background,
    marked_env,
    marked_pids,
    results,
    scenario_toml,
    staging,
    wait_for,
    write_catalog,
)

pytestmark = [pytest.mark.sumo, pytest.mark.slow]


def _forkservers(marker: str, parent: int) -> list[int]:
    """The forkserver: the command's child running multiprocessing's forkserver (the
    scenario processes it forks carry the same command line, as its children)."""
    found = []
    for pid in marked_pids(marker):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
            ppid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if b"multiprocessing.forkserver" in cmd and ppid == parent:
            found.append(pid)
    return found


def test_a_forkserver_killed_mid_run_loses_no_result(tmp_path: Path) -> None:
    marker = uuid.uuid4().hex
    names = [f"free_{i}" for i in range(3)]
    catalog = write_catalog(tmp_path / "c.toml", [scenario_toml(n) for n in names],
                            duration_s=600.0)
    out = tmp_path / "out"
    run = Background("run", str(catalog), "--out", str(out), "--no-log", "--jobs", "1",
                     env=marked_env(marker))
    try:
        wait_for(lambda: len(staging(out)) == 1, 300, "the first scenario running")
        [server] = _forkservers(marker, run.proc.pid)
        os.kill(server, signal.SIGKILL)
        code = run.wait(300)
    finally:
        run.kill()
    assert code == 0, run.out + run.err
    frame = results(out)
    assert sorted(frame.index) == names
    assert set(frame.status) == {"pass"}, frame[["scenario", "status"]]
    assert "Traceback" not in run.err, run.err
    assert not marked_pids(marker)  # nothing left running untracked
