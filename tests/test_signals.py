"""Real signals to a real ``python -m suite run`` (W3, W4): Ctrl-C then ``--resume`` gives
the results of one uninterrupted run; SIGTERM (and even SIGKILL) of the parent leaves no
process of the run behind."""

from __future__ import annotations

import os
import re
import shlex
import signal
import time
import uuid
from pathlib import Path

import pandas as pd
import pytest

from tests.reliability_support import (
    Background,
    hwyeval,
    marked_env,
    marked_pids,
    results,
    scenario_toml,
    staging,
    wait_for,
    without_timing,
    write_catalog,
)

# serial: a stop races the scenario processes' own ends; a busy second core (another test
# worker) once left a staging directory behind (docs/architecture.md, Tests)
pytestmark = [pytest.mark.sumo, pytest.mark.serial, pytest.mark.slow]

N_SHORT = 6


def _six(tmp_path: Path) -> Path:
    # 2000 steps each (2 km of the 2.5 km road): one is running when the signal comes
    return write_catalog(tmp_path / "six.toml",
                         [scenario_toml(f"run_{i}", lane=i % 2, pos_m=60.0 + 10 * i)
                          for i in range(N_SHORT)], duration_s=100.0)


@pytest.mark.parametrize(("sig", "expected"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)],
                         ids=["ctrl-c", "sigterm-to-the-group"])
def test_a_stop_then_resume_gives_the_results_of_one_uninterrupted_run(
        tmp_path: Path, sig: int, expected: int) -> None:
    """Ctrl-C, or SIGTERM to the whole process group (a CI cancel: it reaches the
    forkserver and the scenario processes too): the runs in flight are dropped, never
    recorded as errors, and --resume runs them."""
    catalog = _six(tmp_path)
    reference = tmp_path / "reference"
    proc = hwyeval("run", str(catalog), "--out", str(reference), "--no-log", "--jobs", "1")
    assert proc.returncode == 0, proc.stdout + proc.stderr

    out = tmp_path / "interrupted"
    run = Background("run", str(catalog), "--out", str(out), "--no-log", "--jobs", "1")
    try:
        wait_for(lambda: "[2/6]" in run.out and staging(out), 300,
                  "two finished scenarios and a third one running")
        os.killpg(run.proc.pid, sig)  # the whole job, as a terminal or a CI cancel does
        code = run.wait(60)
    finally:
        run.kill()
    assert code == expected, run.out + run.err
    assert "Traceback" not in run.err, run.err
    line = next(x for x in run.out.splitlines() if x.startswith("interrupted: "))
    match = re.fullmatch(r"interrupted: (\d+) of 6 done; resume with: (.*)", line)
    assert match, line
    done = int(match.group(1))
    assert 2 <= done < N_SHORT
    # what finished is kept and reported, exactly that; nothing half-written is left
    assert not staging(out)
    partial = results(out)
    assert len(partial) == done and set(partial["status"]) == {"pass"}
    assert sorted(p.name for p in out.iterdir() if p.name.startswith("run_")) == \
        sorted(partial.index)

    command = shlex.split(match.group(2))
    assert command[:2] == ["hwyeval", "run"] and "--resume" in command
    resumed = hwyeval(*command[1:])
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    assert sum(" kept: pass" in line for line in resumed.stdout.splitlines()) == done
    pd.testing.assert_frame_equal(without_timing(results(out)),
                                  without_timing(results(reference)))


def _two_long(tmp_path: Path) -> Path:
    # stopped egos that never reach the end of the route: 200000 steps each
    return write_catalog(tmp_path / "long.toml",
                         [scenario_toml(f"stopped_{i}", lane=i, speed_mps=0.0) for i in (0, 1)],
                         duration_s=10000.0)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL], ids=["SIGTERM", "SIGKILL"])
def test_signal_to_the_parent_leaves_no_process_after_5_s(tmp_path: Path, sig: int) -> None:
    marker = uuid.uuid4().hex
    out = tmp_path / "out"
    run = Background("run", str(_two_long(tmp_path)), "--out", str(out), "--no-log", "--jobs",
                     "2", env=marked_env(marker))
    try:
        wait_for(lambda: len(staging(out)) == 2, 300, "both scenario processes running")
        before = marked_pids(marker)
        assert len(before) >= 3, before  # the parent, its forkserver, the two workers
        os.kill(run.proc.pid, sig)  # a CI cancel signals the parent only
        t0 = time.monotonic()
        code = run.wait(30)
        wait_for(lambda: not marked_pids(marker), 5.0 - (time.monotonic() - t0),
                  f"every process of the run to end (left: {marked_pids(marker)})")
    finally:
        run.kill()
    if sig == signal.SIGTERM:
        assert code == 143, run.out + run.err
        assert "interrupted: 0 of 2 done; resume with: " in run.out
        assert "Traceback" not in run.err, run.err
        assert (out / "report.html").is_file() and (out / "results.csv").is_file()
        assert not staging(out)
    else:
        assert code == -signal.SIGKILL
    assert not (out / "stopped_0").exists() and not (out / "stopped_1").exists()
